//! MCAP bags with the ROS 2 profile: schemas in `ros2msg`, messages in CDR, one channel per
//! topic, log and publish time the message's stamp.
//!
//! A path ending in `.mcap` is written as that one file (what Foxglove, the `mcap` tools and
//! `ros2 bag` on a file read); any other path as a rosbag2 bag folder — `NAME/NAME_0.mcap` and
//! the `metadata.yaml` that `ros2 bag play`/`info` and the `rosbags` library need. The file is
//! chunked and a chunk is closed and flushed every [`BagConfig::flush_every_s`] of stamps, so a
//! killed run leaves a bag readable up to its last chunk (`mcap recover` rebuilds its index).
//!
//! A bag is written under a temporary name beside its own (`OUT.mcap.part~`, `NAME.part~/`)
//! and takes its name at [`Bag::finish`], so a bag under its final name is always whole. A
//! killed run's bag stays under the temporary name (what was recorded is not lost) and a new
//! bag of that name is refused until it is moved; [`Bag::discard`] removes an unfinished one.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use crate::msg::RosMessage;
use crate::RosError;

/// How a bag is written.
#[derive(Clone, Debug, PartialEq)]
pub struct BagConfig {
    /// Close a chunk (and flush it to the disk) when the stamps have moved on this much.
    pub flush_every_s: f64,
}

impl Default for BagConfig {
    fn default() -> Self {
        Self { flush_every_s: 1.0 }
    }
}

struct Topic {
    channel: u16,
    msgtype: &'static str,
    count: u64,
}

/// An open bag.
pub struct Bag {
    writer: mcap::Writer<BufWriter<File>>,
    /// The MCAP file being written (inside [`Bag::part`] for a folder).
    file: PathBuf,
    /// The bag's temporary name (a file or a folder) until it is finished.
    part: PathBuf,
    /// The bag's name once finished.
    target: PathBuf,
    /// The bag folder (rosbag2 layout) when not a lone `.mcap`.
    folder: Option<PathBuf>,
    topics: BTreeMap<String, Topic>,
    first_ns: Option<u64>,
    last_ns: u64,
    /// The latest stamp when a chunk was last closed (the first stamp before that).
    flushed_ns: Option<u64>,
    flush_every_ns: u64,
    messages: u64,
    /// The CDR buffer, reused from message to message.
    cdr: Vec<u8>,
}

impl Bag {
    /// Creates the bag at `path` (see the module's documentation); refuses to replace one.
    pub fn create(path: &Path, cfg: &BagConfig) -> Result<Self, RosError> {
        let io = |p: &Path, e: std::io::Error| RosError::Io(p.to_path_buf(), e);
        if path.exists() {
            return Err(RosError::Exists(path.to_path_buf()));
        }
        let part = visuotact_io::guard::part_path(path);
        // Anything under the temporary name, a link included (never followed), is an earlier
        // run's or another writer's: refused, and both the folder and the file are created
        // exclusively, so a second writer racing for the name is refused too.
        let taken = |e: &std::io::Error| e.kind() == std::io::ErrorKind::AlreadyExists;
        if std::fs::symlink_metadata(&part).is_ok() {
            return Err(RosError::Unfinished(part));
        }
        let (file, folder) = if path.extension().is_some_and(|e| e == "mcap") {
            (part.clone(), None)
        } else {
            if let Some(parent) = part.parent().filter(|p| !p.as_os_str().is_empty()) {
                std::fs::create_dir_all(parent).map_err(|e| io(parent, e))?;
            }
            std::fs::create_dir(&part).map_err(|e| {
                if taken(&e) {
                    RosError::Unfinished(part.clone())
                } else {
                    io(&part, e)
                }
            })?;
            let name = path
                .file_name()
                .map_or_else(|| "bag".into(), |n| n.to_string_lossy().into_owned());
            (part.join(format!("{name}_0.mcap")), Some(part.clone()))
        };
        let out = File::options()
            .write(true)
            .create_new(true)
            .open(&file)
            .map_err(|e| {
                if taken(&e) {
                    RosError::Unfinished(part.clone())
                } else {
                    io(&file, e)
                }
            })?;
        let writer = mcap::WriteOptions::new()
            .profile("ros2")
            .library(concat!("visuotact ", env!("CARGO_PKG_VERSION")))
            .compression(None)
            .create(BufWriter::new(out))
            .map_err(|e| RosError::Mcap(file.clone(), e.to_string()))?;
        Ok(Self {
            writer,
            file,
            part,
            target: path.to_path_buf(),
            folder,
            topics: BTreeMap::new(),
            first_ns: None,
            last_ns: 0,
            flushed_ns: None,
            flush_every_ns: (cfg.flush_every_s.max(0.0) * 1e9) as u64,
            messages: 0,
            cdr: Vec::new(),
        })
    }

    /// The MCAP file being written (under the bag's temporary name until it is finished).
    pub fn file(&self) -> &Path {
        &self.file
    }

    /// Messages written so far.
    pub fn messages(&self) -> u64 {
        self.messages
    }

    fn mcap_err(&self, e: impl std::fmt::Display) -> RosError {
        RosError::Mcap(self.file.clone(), e.to_string())
    }

    /// The topic's channel, registered with its schema on first use.
    fn topic<M: RosMessage>(&mut self, topic: &str) -> Result<&mut Topic, RosError> {
        if !self.topics.contains_key(topic) {
            // Only on a topic's first message: the key is copied once.
            let failed = |e: mcap::McapError| RosError::Mcap(self.file.clone(), e.to_string());
            let schema = self
                .writer
                .add_schema(M::NAME, "ros2msg", M::DEFINITION.as_bytes())
                .map_err(failed)?;
            let channel = self
                .writer
                .add_channel(schema, topic, "cdr", &BTreeMap::new())
                .map_err(failed)?;
            let t = Topic {
                channel,
                msgtype: M::NAME,
                count: 0,
            };
            self.topics.insert(topic.to_string(), t);
        }
        let t = self
            .topics
            .get_mut(topic)
            .ok_or_else(|| RosError::Config(format!("topic {topic} was not registered")))?;
        if t.msgtype != M::NAME {
            return Err(RosError::TopicType {
                topic: topic.to_string(),
                was: t.msgtype,
                now: M::NAME,
            });
        }
        Ok(t)
    }

    /// Writes `msg` on `topic`, stamped `stamp_ns` (nanoseconds since the UNIX epoch).
    pub fn write<M: RosMessage>(
        &mut self,
        topic: &str,
        stamp_ns: u64,
        msg: &M,
    ) -> Result<(), RosError> {
        let t = self.topic::<M>(topic)?;
        let header = mcap::records::MessageHeader {
            channel_id: t.channel,
            sequence: u32::try_from(t.count).unwrap_or(u32::MAX),
            log_time: stamp_ns,
            publish_time: stamp_ns,
        };
        t.count += 1;
        self.cdr = msg.to_cdr_in(std::mem::take(&mut self.cdr));
        self.writer
            .write_to_known_channel(&header, &self.cdr)
            .map_err(|e| RosError::Mcap(self.file.clone(), e.to_string()))?;
        self.messages += 1;
        self.first_ns.get_or_insert(stamp_ns);
        self.last_ns = self.last_ns.max(stamp_ns);
        let flushed = *self.flushed_ns.get_or_insert(stamp_ns);
        if self.last_ns.saturating_sub(flushed) >= self.flush_every_ns {
            self.writer.flush().map_err(|e| self.mcap_err(e))?;
            self.flushed_ns = Some(self.last_ns);
        }
        Ok(())
    }

    /// Ends the bag: its index and summary, then (bag folders) `metadata.yaml`. Returns the
    /// path written.
    pub fn finish(mut self) -> Result<PathBuf, RosError> {
        self.writer.finish().map_err(|e| self.mcap_err(e))?;
        if let Some(folder) = self.folder.clone() {
            let yaml = self.metadata_yaml();
            let path = folder.join("metadata.yaml");
            visuotact_io::session::write_atomically(&path, &yaml)
                .map_err(|e| RosError::Io(path.clone(), e))?;
        }
        if self.target.exists() {
            return Err(RosError::Exists(self.target.clone()));
        }
        std::fs::rename(&self.part, &self.target)
            .map_err(|e| RosError::Io(self.target.clone(), e))?;
        Ok(self.target.clone())
    }

    /// Removes the unfinished bag (a failed or stopped export leaves nothing behind).
    pub fn discard(self) {
        let part = self.part.clone();
        drop(self);
        let _ = if part.is_dir() {
            std::fs::remove_dir_all(&part)
        } else {
            std::fs::remove_file(&part)
        };
    }

    /// rosbag2's `metadata.yaml` (version 5, the Humble layout later versions still read).
    fn metadata_yaml(&self) -> String {
        let start = self.first_ns.unwrap_or(0);
        let duration = self.last_ns.saturating_sub(start);
        let name = self
            .file
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        let mut y = String::from("rosbag2_bagfile_information:\n  version: 5\n");
        y += "  storage_identifier: mcap\n";
        y += &format!("  duration:\n    nanoseconds: {duration}\n");
        y += &format!("  starting_time:\n    nanoseconds_since_epoch: {start}\n");
        y += &format!(
            "  message_count: {}\n  topics_with_message_count:\n",
            self.messages
        );
        for (topic, t) in &self.topics {
            y += &format!(
                "    - topic_metadata:\n        name: {topic}\n        type: {}\n        \
                 serialization_format: cdr\n        offered_qos_profiles: \"\"\n      \
                 message_count: {}\n",
                t.msgtype, t.count
            );
        }
        y += "  compression_format: \"\"\n  compression_mode: \"\"\n";
        y += &format!("  relative_file_paths:\n    - {name}\n  files:\n");
        y += &format!(
            "    - path: {name}\n      starting_time:\n        nanoseconds_since_epoch: {start}\n      \
             duration:\n        nanoseconds: {duration}\n      message_count: {}\n",
            self.messages
        );
        y
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("visuotact-bag-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    /// A link left under a bag's temporary name (to a file that exists, or to none yet) is
    /// refused, never followed: nothing is written where it points.
    #[test]
    fn a_link_under_the_temporary_name_is_refused_not_followed() {
        let d = dir("link");
        let labels = d.join("labels.csv");
        std::fs::write(&labels, b"frame,x\n").unwrap();
        let elsewhere = d.join("elsewhere.mcap");
        for (out, to) in [
            (d.join("a.mcap"), &labels),
            (d.join("b.mcap"), &elsewhere),
            (d.join("c"), &elsewhere),
        ] {
            std::os::unix::fs::symlink(to, part_of(&out)).unwrap();
            let r = Bag::create(&out, &BagConfig::default());
            assert!(
                matches!(r, Err(RosError::Unfinished(_))),
                "{}",
                out.display()
            );
        }
        assert_eq!(std::fs::read(&labels).unwrap(), b"frame,x\n");
        assert!(!elsewhere.exists());
        let _ = std::fs::remove_dir_all(&d);
    }

    /// Two writers of one bag: the second is refused while the first writes, and the first
    /// finishes whole.
    #[test]
    fn a_second_writer_of_one_bag_is_refused() {
        let d = dir("two");
        for out in [d.join("s.mcap"), d.join("s")] {
            let first = Bag::create(&out, &BagConfig::default()).unwrap();
            let second = Bag::create(&out, &BagConfig::default());
            assert!(matches!(second, Err(RosError::Unfinished(_))));
            assert_eq!(first.finish().unwrap(), out);
            assert!(out.exists());
        }
        let _ = std::fs::remove_dir_all(&d);
    }

    fn part_of(p: &Path) -> PathBuf {
        visuotact_io::guard::part_path(p)
    }
}
