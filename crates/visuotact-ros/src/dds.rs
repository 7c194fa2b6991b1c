//! Live ROS 2 over DDS without ROS: the same topics and messages as the bags
//! ([`crate::topics`]), published with RustDDS (RTPS), so that a ROS 2 machine — any RMW on
//! DDS: `rmw_cyclonedds_cpp`, `rmw_fastrtps_cpp` — sees them in `ros2 topic list/echo`.
//!
//! The ROS 2 mapping: topic `/ns/name` is the DDS topic `rt/ns/name`; type
//! `pkg/msg/Name` is `pkg::msg::dds_::Name_`; the payload is the message's CDR (little-endian,
//! as the bags hold it). QoS, per topic: reliable, volatile, keep last 10 — ROS 2's default
//! profile, which both reliable and best-effort subscribers accept. Domain: `ROS_DOMAIN_ID`'s
//! role is [`DdsConfig::domain_id`] (0 by default).
//!
//! Network: loopback only unless [`DdsConfig::network`] is set — discovery is announced on
//! 127.0.0.1 (no multicast needed), and only the loopback address is advertised, so nothing
//! leaves the machine; set the interface's address to reach other machines (then multicast
//! discovery as in any ROS 2 install).

use std::collections::HashMap;
use std::net::IpAddr;

use rustdds::no_key::{DataWriter, SerializerAdapter};
use rustdds::policy::{Durability, History, Reliability};
use rustdds::{
    DomainParticipant, DomainParticipantBuilder, Publisher, QosPolicies, QosPolicyBuilder,
    RepresentationIdentifier, TopicKind,
};

use visuotact_pipeline::output::{FrameParts, FrameTarget, LiveSink, OutputConfig, OutputError};

use crate::msg::RosMessage;
use crate::topics::{declare_sensor_topics, typed_entry, write_frame, Declare, Publish};
use crate::RosError;

/// Where and how the live topics are published.
#[derive(Clone, Debug, PartialEq)]
pub struct DdsConfig {
    /// Topics and frames.
    pub ros: OutputConfig,
    /// DDS domain (ROS 2's `ROS_DOMAIN_ID`).
    pub domain_id: u16,
    /// The network interface's address to publish on (`None`: loopback only).
    pub network: Option<IpAddr>,
    /// The sensors of a run of several (topics under `NS/NAME`); empty for one sensor.
    pub sensors: Vec<String>,
}

impl Default for DdsConfig {
    fn default() -> Self {
        Self {
            ros: OutputConfig {
                images: false,
                ..OutputConfig::default()
            },
            domain_id: 0,
            network: None,
            sensors: Vec::new(),
        }
    }
}

/// A message's CDR payload without its 4-byte encapsulation header (RustDDS writes that
/// itself); a view into the encoded buffer, handed to RustDDS without a copy.
pub struct Cdr(rustdds::bytes::Bytes);

impl Cdr {
    /// `msg` encoded.
    pub fn of<M: RosMessage>(msg: &M) -> Self {
        Self(rustdds::bytes::Bytes::from(msg.to_cdr()).slice(4..))
    }
}

/// Hands RustDDS the CDR payload as it is.
pub struct RawCdr;

impl SerializerAdapter<Cdr> for RawCdr {
    type Error = std::convert::Infallible;

    fn output_encoding() -> RepresentationIdentifier {
        RepresentationIdentifier::CDR_LE
    }

    fn to_bytes(value: &Cdr) -> Result<rustdds::bytes::Bytes, Self::Error> {
        Ok(value.0.clone())
    }
}

/// The DDS type name of a ROS 2 type: `pkg/msg/Name` → `pkg::msg::dds_::Name_`.
pub fn dds_type_name(ros: &str) -> String {
    match ros.rsplit_once('/') {
        Some((pkg, name)) => format!("{}::dds_::{name}_", pkg.replace('/', "::")),
        None => ros.to_string(),
    }
}

/// The DDS topic name of a ROS 2 topic: `/ns/name` → `rt/ns/name`.
pub fn dds_topic_name(ros: &str) -> String {
    format!("rt/{}", ros.trim_start_matches('/'))
}

/// ROS 2's default QoS profile: reliable, volatile, keep last 10.
pub fn ros_default_qos() -> QosPolicies {
    QosPolicyBuilder::new()
        .reliability(Reliability::Reliable {
            max_blocking_time: rustdds::Duration::from_millis(100),
        })
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 10 })
        .build()
}

/// Live DDS writers, one per topic, made on first use.
pub struct DdsPublisher {
    participant: DomainParticipant,
    publisher: Publisher,
    qos: QosPolicies,
    writers: HashMap<String, (&'static str, DataWriter<Cdr, RawCdr>)>,
    /// Messages published.
    pub messages: u64,
}

/// `ip` must be one interface's address on this machine (binding a socket to it tells): an
/// address the machine does not have would publish to nobody, in silence.
fn check_interface(ip: IpAddr) -> Result<(), RosError> {
    if ip.is_unspecified() || ip.is_multicast() {
        return Err(RosError::Config(format!(
            "network {ip}: name one network interface's address, not {}",
            if ip.is_multicast() {
                "a multicast group"
            } else {
                "the unspecified address"
            }
        )));
    }
    std::net::UdpSocket::bind((ip, 0)).map(drop).map_err(|e| {
        RosError::Config(format!(
            "network {ip}: no network interface of this machine has that address ({e})"
        ))
    })
}

fn dds_err(e: impl std::fmt::Display) -> RosError {
    RosError::Dds(e.to_string())
}

impl DdsPublisher {
    /// A participant in `cfg.domain_id` on loopback (or `cfg.network`), with a writer for
    /// every topic a frame may have ([`declare_sensor_topics`]): discovery starts at once, so
    /// a subscriber can match before the first frame (writers are volatile: what is published
    /// before a subscriber matches is not sent to it).
    pub fn new(cfg: &DdsConfig) -> Result<Self, RosError> {
        let only: IpAddr = cfg.network.unwrap_or(IpAddr::from([127, 0, 0, 1]));
        check_interface(only)?;
        let participant = DomainParticipantBuilder::new(cfg.domain_id)
            .with_only_networks([only])
            .same_host_loopback(true)
            .build()
            .map_err(dds_err)?;
        let qos = ros_default_qos();
        let publisher = participant.create_publisher(&qos).map_err(dds_err)?;
        let mut out = Self {
            participant,
            publisher,
            qos,
            writers: HashMap::new(),
            messages: 0,
        };
        declare_sensor_topics(&mut out, &cfg.ros, &cfg.sensors)?;
        Ok(out)
    }

    /// The topics it has a writer for, sorted.
    pub fn topics(&self) -> Vec<&str> {
        let mut t: Vec<&str> = self.writers.keys().map(String::as_str).collect();
        t.sort_unstable();
        t
    }

    fn writer<M: RosMessage>(&mut self, topic: &str) -> Result<&DataWriter<Cdr, RawCdr>, RosError> {
        if !self.writers.contains_key(topic) {
            let t = self
                .participant
                .create_topic(
                    dds_topic_name(topic),
                    dds_type_name(M::NAME),
                    &self.qos,
                    TopicKind::NoKey,
                )
                .map_err(dds_err)?;
            let w = self
                .publisher
                .create_datawriter_no_key::<Cdr, RawCdr>(&t, None)
                .map_err(dds_err)?;
            self.writers.insert(topic.to_string(), (M::NAME, w));
        }
        typed_entry(&self.writers, topic, M::NAME)
    }
}

impl Declare for DdsPublisher {
    fn declare<M: RosMessage>(&mut self, topic: &str) -> Result<(), RosError> {
        self.writer::<M>(topic).map(|_| ())
    }
}

impl FrameTarget for DdsPublisher {
    fn write_frame(&mut self, cfg: &OutputConfig, f: FrameParts<'_>) -> Result<(), OutputError> {
        write_frame(self, cfg, f).map_err(OutputError::target)
    }
}

impl Publish for DdsPublisher {
    fn publish<M: RosMessage>(
        &mut self,
        topic: &str,
        stamp_ns: u64,
        msg: &M,
    ) -> Result<(), RosError> {
        let _ = stamp_ns; // the message's header carries it
        let data = Cdr::of(msg);
        self.writer::<M>(topic)?
            .write(data, None)
            .map_err(|e| RosError::Dds(format!("{topic}: {e}")))?;
        self.messages += 1;
        Ok(())
    }
}

/// A live run's estimates published over DDS: a [`FrameSink`](visuotact_pipeline::sink::FrameSink)
/// of the live runner, stamped on the wall clock like [`crate::McapSink`].
pub type DdsSink = LiveSink<DdsPublisher>;

/// Joins the domain; stamps count from now.
pub fn dds_sink(cfg: &DdsConfig) -> Result<DdsSink, RosError> {
    cfg.ros.validate()?;
    Ok(LiveSink::new(DdsPublisher::new(cfg)?, cfg.ros.clone())?)
}

/// Leaves the domain: the messages published, or the run's first error.
pub fn finish_dds(sink: DdsSink) -> Result<u64, RosError> {
    sink.finish_with(|out| Ok(out.messages))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every topic a frame may have gets its writer when the participant is made, per sensor
    /// of a run of several (`/diagnostics` is shared), so discovery can match subscribers
    /// before the first frame.
    #[test]
    fn writers_are_made_for_every_topic_before_the_first_frame() {
        let cfg = DdsConfig {
            domain_id: 71,
            sensors: vec!["left".into(), "right".into()],
            ..DdsConfig::default()
        };
        let p = DdsPublisher::new(&cfg).unwrap();
        let topics = p.topics();
        assert_eq!(topics.len(), 15, "{topics:?}");
        assert_eq!(topics[0], "/diagnostics");
        for side in ["left", "right"] {
            for t in [
                "contact",
                "contact/active",
                "ft_sensor/wrench",
                "markers",
                "slip",
                "slip/state",
                "wrench",
            ] {
                let name = format!("/visuotact/{side}/{t}");
                assert!(topics.contains(&name.as_str()), "{name} in {topics:?}");
            }
        }
        let one = DdsPublisher::new(&DdsConfig {
            domain_id: 71,
            ..DdsConfig::default()
        })
        .unwrap();
        assert_eq!(one.topics().len(), 8, "{:?}", one.topics());
        assert_eq!(p.messages + one.messages, 0);
    }
}
