//! A session folder as one episode: its frames in `frames.csv` order with their tables'
//! rows aligned (a frame a table has no row for: NaN), and the force sensor at each frame's
//! time.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use visuotact_io::force::ForceTable;
use visuotact_io::session::{frame_index, IndexedFrame, SessionDescription};
use visuotact_io::table::KeyedTable;

use crate::LeRobotError;

/// A per-frame table's value columns and its rows aligned to the frames.
#[derive(Clone, Debug, PartialEq)]
pub struct Aligned {
    /// Value columns.
    pub columns: Vec<String>,
    /// One row per frame.
    pub rows: Vec<Vec<f64>>,
}

/// One session, read.
#[derive(Clone, Debug, PartialEq)]
pub struct Episode {
    /// The session folder.
    pub dir: PathBuf,
    /// The frames, in `frames.csv` order, with their times on the session clock.
    pub frames: Vec<IndexedFrame>,
    /// `features.csv` without its `timestamp_s` column.
    pub features: Option<Aligned>,
    /// `estimates.csv`.
    pub estimates: Option<Aligned>,
    /// The force sensor at each frame's time, interpolated linearly between its samples (NaN
    /// before the first and after the last).
    pub force: Option<Vec<[f64; 6]>>,
    /// The session's frame rate as `session.json` gives it.
    pub fps: Option<f64>,
    /// What the episode is missing, one line each: the recording did not complete
    /// (`session.json`), a table's unfinished last line was left out.
    pub notes: Vec<String>,
}

fn aligned(
    dir: &Path,
    name: &str,
    frames: &[IndexedFrame],
    drop: &[&str],
    notes: &mut Vec<String>,
) -> Result<Option<Aligned>, LeRobotError> {
    let path = dir.join(name);
    if !path.is_file() {
        return Ok(None);
    }
    let t = KeyedTable::read_noting(&path, &["flags"], notes)?;
    let keep: Vec<usize> = (0..t.columns.len())
        .filter(|&i| !drop.contains(&t.columns[i].as_str()))
        .collect();
    let index: HashMap<&str, usize> = t
        .keys
        .iter()
        .enumerate()
        .map(|(i, k)| (k.as_str(), i))
        .collect();
    let rows = frames
        .iter()
        .map(|f| match index.get(f.name.as_str()) {
            Some(&r) => keep.iter().map(|&i| t.rows[r][i]).collect(),
            None => vec![f64::NAN; keep.len()],
        })
        .collect();
    Ok(Some(Aligned {
        columns: keep.iter().map(|&i| t.columns[i].clone()).collect(),
        rows,
    }))
}

/// Sorts the samples by time (a table in arrival order may not be).
fn sort_by_time(f: &mut ForceTable) {
    if f.timestamp_s.windows(2).all(|w| w[0] <= w[1]) {
        return;
    }
    let mut order: Vec<usize> = (0..f.timestamp_s.len()).collect();
    order.sort_by(|&a, &b| f.timestamp_s[a].total_cmp(&f.timestamp_s[b]));
    f.timestamp_s = order.iter().map(|&i| f.timestamp_s[i]).collect();
    f.values = order.iter().map(|&i| f.values[i]).collect();
}

/// The force table at `t`, linearly interpolated (NaN outside its samples).
fn force_at(f: &ForceTable, t: f64) -> [f64; 6] {
    let ts = &f.timestamp_s;
    let k = ts.partition_point(|&x| x < t);
    if k < ts.len() && ts[k] == t {
        return f.values[k];
    }
    if k == 0 || k == ts.len() {
        return [f64::NAN; 6];
    }
    let w = (t - ts[k - 1]) / (ts[k] - ts[k - 1]);
    std::array::from_fn(|i| f.values[k - 1][i] * (1.0 - w) + f.values[k][i] * w)
}

impl Episode {
    /// Reads the session in `dir`.
    pub fn read(dir: &Path) -> Result<Self, LeRobotError> {
        let mut notes = Vec::new();
        let frames = frame_index(dir, &mut notes)?;
        if frames.is_empty() {
            return Err(LeRobotError::Invalid(format!(
                "{}: no frames",
                dir.join("frames.csv").display()
            )));
        }
        let force_path = dir.join("force.csv");
        let force = if force_path.is_file() {
            let mut f = ForceTable::read_noting(&force_path, &mut notes)?;
            // Interpolated at the frames' times, on their clock, not the sender's.
            f.onto_recorder_clock();
            f.check_meets_frames(&force_path, visuotact_io::session::frames_span_s(&frames))?;
            sort_by_time(&mut f);
            Some(
                frames
                    .iter()
                    .map(|fr| force_at(&f, fr.timestamp_s))
                    .collect(),
            )
        } else {
            None
        };
        let described =
            SessionDescription::read(dir).map_err(|e| LeRobotError::Invalid(e.to_string()))?;
        let fps = described.as_ref().and_then(|d| d.fps);
        notes.extend(
            described
                .and_then(|d| d.incomplete_note())
                .map(|n| format!("{}: {n}", dir.display())),
        );
        Ok(Self {
            dir: dir.to_path_buf(),
            features: aligned(dir, "features.csv", &frames, &["timestamp_s"], &mut notes)?,
            estimates: aligned(dir, "estimates.csv", &frames, &[], &mut notes)?,
            frames,
            force,
            fps,
            notes,
        })
    }

    /// The median interval between frames as a rate, Hz (`None` with one frame).
    pub fn median_rate_hz(&self) -> Option<f64> {
        let mut d: Vec<f64> = self
            .frames
            .windows(2)
            .map(|w| w[1].timestamp_s - w[0].timestamp_s)
            .filter(|x| x.is_finite() && *x > 0.0)
            .collect();
        if d.is_empty() {
            return None;
        }
        d.sort_by(f64::total_cmp);
        Some(1.0 / d[d.len() / 2])
    }

    /// The PNG of frame `k`: under `frames/`, or `reference/` for the no-contact frames a
    /// simulated session lists first.
    pub fn frame_path(&self, k: usize) -> PathBuf {
        let f = &self.frames[k];
        let folder = if f.reference { "reference" } else { "frames" };
        self.dir.join(folder).join(&f.name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn force_is_interpolated_between_samples_and_nan_outside() {
        let f = ForceTable {
            timestamp_s: vec![0.0, 1.0, 2.0],
            values: vec![[0.0; 6], [2.0; 6], [4.0; 6]],
            present: [true; 6],
            recv_s: None,
            dropped_partial_line: false,
        };
        assert_eq!(force_at(&f, 0.25)[2], 0.5);
        assert_eq!(force_at(&f, 1.0)[0], 2.0);
        assert_eq!(force_at(&f, 1.5)[5], 3.0);
        assert!(force_at(&f, -0.1)[0].is_nan() && force_at(&f, 2.1)[0].is_nan());
    }

    /// A force sender on its own clock (a real F/T box's starts at 1 000 s) is put on the
    /// frames' clock by its receive times: every frame gets its force, not NaN.
    #[test]
    fn force_on_the_senders_clock_meets_the_frames() {
        let dir = std::env::temp_dir().join(format!("vt-episode-clock-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("frames")).unwrap();
        std::fs::write(
            dir.join("frames.csv"),
            "frame,index,timestamp_s,kind\na.png,0,0.2,touch\nb.png,1,0.6,touch\n",
        )
        .unwrap();
        // Received 10 ms after sending (the least delay), one packet late by 30 ms more.
        std::fs::write(
            dir.join("force.csv"),
            "timestamp_s,recv_s,fz_n\n1000.0,0.01,0\n1000.5,0.54,5\n1001.0,1.01,10\n",
        )
        .unwrap();
        let e = Episode::read(&dir).unwrap();
        let force = e.force.unwrap();
        assert!((force[0][2] - 1.9).abs() < 1e-9, "{:?}", force[0]);
        assert!((force[1][2] - 5.9).abs() < 1e-9, "{:?}", force[1]);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
