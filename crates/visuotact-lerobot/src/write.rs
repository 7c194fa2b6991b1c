//! The export itself: sessions read, checked against each other, and written as the data
//! set's files (see the crate's documentation for the layout).

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

use serde_json::{json, Value};

use crate::episode::{Aligned, Episode};
use crate::stats::Stats;
use crate::table::{write_table, Column, Values};
use crate::video::Encoder;
use crate::{LeRobotConfig, LeRobotError, LeRobotSummary, CODEBASE_VERSION, IMAGE_KEY};

const FORCE_NAMES: [&str; 6] = ["fx_n", "fy_n", "fz_n", "tx_nm", "ty_nm", "tz_nm"];
const DATA_PATH: &str = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet";
const VIDEO_PATH: &str = "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4";
const FILE_000: &str = "chunk-000/file-000";

/// A numeric feature of the data table: every frame's values, row after row, as f64.
struct Feature {
    key: String,
    dtype: &'static str,
    /// Names of a vector's dimensions (`None`: a scalar).
    names: Option<Vec<String>>,
    width: usize,
    data: Vec<f64>,
}

impl Feature {
    fn scalar(key: &str, dtype: &'static str, data: Vec<f64>) -> Self {
        Self {
            key: key.into(),
            dtype,
            names: None,
            width: 1,
            data,
        }
    }

    fn info(&self) -> Value {
        json!({"dtype": self.dtype, "shape": [self.width], "names": self.names})
    }

    fn column(&self) -> Column {
        let values = match self.dtype {
            "int64" => Values::I64(self.data.iter().map(|&v| v as i64).collect()),
            "float64" => Values::F64(self.data.clone()),
            _ => Values::F32(self.data.iter().map(|&v| v as f32).collect()),
        };
        if self.names.is_some() {
            Column::list(&self.key, &[self.width], values)
        } else {
            Column::scalar(&self.key, values)
        }
    }

    /// Statistics of the values as stored (a float32 feature's rounded to float32, as
    /// LeRobot computes them from the data).
    fn stats(&self, rows: std::ops::Range<usize>) -> Stats {
        let mut s = Stats::new(self.width);
        let mut row = vec![0.0; self.width];
        for r in rows {
            for (o, &v) in row
                .iter_mut()
                .zip(&self.data[r * self.width..(r + 1) * self.width])
            {
                *o = if self.dtype == "float32" {
                    f64::from(v as f32)
                } else {
                    v
                };
            }
            s.push(&row);
        }
        s
    }
}

/// The columns every episode shares: a table present in some sessions only is left out.
fn shared(
    eps: &[Episode],
    name: &str,
    get: impl Fn(&Episode) -> Option<&Aligned>,
    notes: &mut Vec<String>,
) -> Result<Option<Vec<String>>, LeRobotError> {
    let have: Vec<&Aligned> = eps.iter().filter_map(&get).collect();
    if have.is_empty() {
        notes.push(format!("no {name} in any session"));
        return Ok(None);
    }
    if have.len() < eps.len() {
        let missing = eps
            .iter()
            .find(|e| get(e).is_none())
            .map(|e| e.dir.display());
        notes.push(format!(
            "{name} left out: {} has none",
            missing.map(|d| d.to_string()).unwrap_or_default()
        ));
        return Ok(None);
    }
    let first = &have[0].columns;
    for (e, a) in eps.iter().zip(&have) {
        if &a.columns != first {
            return Err(LeRobotError::Invalid(format!(
                "{}: {name} has other columns than {} ({} against {}); export sessions of one \
                 sensor and model together",
                e.dir.display(),
                eps[0].dir.display(),
                a.columns.len(),
                first.len()
            )));
        }
    }
    Ok(Some(first.clone()))
}

fn vector(key: &str, names: Vec<String>, rows: impl Iterator<Item = Vec<f64>>) -> Feature {
    let width = names.len();
    Feature {
        key: key.into(),
        dtype: "float32",
        names: Some(names),
        width,
        data: rows.flatten().collect(),
    }
}

/// Every numeric feature of the data table, in column order.
fn features_of(
    eps: &[Episode],
    fps: u32,
    notes: &mut Vec<String>,
) -> Result<Vec<Feature>, LeRobotError> {
    let mut ts = Vec::new();
    let mut frame_index = Vec::new();
    let mut episode_index = Vec::new();
    for (e, ep) in eps.iter().enumerate() {
        for k in 0..ep.frames.len() {
            ts.push(k as f64 / f64::from(fps));
            frame_index.push(k as f64);
            episode_index.push(e as f64);
        }
    }
    let n = ts.len();
    let mut out = vec![
        Feature::scalar("timestamp", "float32", ts),
        Feature::scalar("frame_index", "int64", frame_index),
        Feature::scalar("episode_index", "int64", episode_index),
        Feature::scalar("index", "int64", (0..n).map(|i| i as f64).collect()),
        Feature::scalar("task_index", "int64", vec![0.0; n]),
        Feature::scalar(
            "observation.tactile.capture_time_s",
            "float64",
            eps.iter()
                .flat_map(|e| e.frames.iter().map(|f| f.timestamp_s))
                .collect(),
        ),
    ];
    if let Some(cols) = shared(eps, "features.csv", |e| e.features.as_ref(), notes)? {
        let rows = eps
            .iter()
            .flat_map(|e| e.features.iter().flat_map(|a| a.rows.clone()));
        out.push(vector("observation.tactile.features", cols, rows));
    }
    if let Some(cols) = shared(eps, "estimates.csv", |e| e.estimates.as_ref(), notes)? {
        let rows = eps
            .iter()
            .flat_map(|e| e.estimates.iter().flat_map(|a| a.rows.clone()));
        out.push(vector("observation.tactile.estimate", cols, rows));
    }
    if eps.iter().all(|e| e.force.is_some()) {
        let names = FORCE_NAMES.iter().map(|s| s.to_string()).collect();
        let rows = eps
            .iter()
            .flat_map(|e| e.force.iter().flatten().map(|v| v.to_vec()));
        out.push(vector("observation.force", names, rows));
    } else {
        notes.push("observation.force left out: a session has no force.csv".into());
    }
    Ok(out)
}

/// A session's own rate: `session.json`'s, else its median frame interval's.
fn rate_of(e: &Episode) -> Option<f64> {
    e.fps.or_else(|| e.median_rate_hz())
}

/// The data set's rate: the one given, else the first session's, every session's within 10 %
/// of it (a data set has one rate: a session at another would play at the wrong speed).
fn fps_of(cfg: &LeRobotConfig, eps: &[Episode]) -> Result<u32, LeRobotError> {
    let first = &eps[0];
    let fps = match cfg.fps {
        Some(f) => f64::from(f),
        None => {
            let fps = rate_of(first).ok_or_else(|| {
                LeRobotError::Invalid(format!(
                    "{}: one frame and no fps in session.json; give the rate",
                    first.dir.display()
                ))
            })?;
            for e in &eps[1..] {
                if let Some(r) = rate_of(e).filter(|r| (r / fps - 1.0).abs() > 0.1) {
                    return Err(LeRobotError::Invalid(format!(
                        "{} runs at {r:.3} fps, {} at {fps:.3}: a data set has one rate; export \
                         them apart, or give the rate to play every episode at it",
                        e.dir.display(),
                        first.dir.display()
                    )));
                }
            }
            fps
        }
    };
    let rounded = fps.round();
    if !(1.0..=10_000.0).contains(&rounded) {
        return Err(LeRobotError::Invalid(format!(
            "fps {fps}: expected 1 to 10000 frames per second"
        )));
    }
    Ok(rounded as u32)
}

/// The frames into the video, episode after episode: the frame size and each episode's
/// pixel statistics.
fn encode_video(
    eps: &[Episode],
    dir: &Path,
    cfg: &crate::VideoConfig,
    fps: u32,
    progress: &mut dyn FnMut(usize, usize) -> ControlFlow<()>,
) -> Result<((u32, u32), Vec<Stats>), LeRobotError> {
    let total: usize = eps.iter().map(|e| e.frames.len()).sum();
    let path = dir.join(format!("videos/{IMAGE_KEY}/{FILE_000}.mp4"));
    mkdir_for(&path)?;
    let (mut enc, mut size, mut per_episode, mut done) = (None::<Encoder>, (0, 0), Vec::new(), 0);
    for ep in eps {
        let mut stats = Stats::new(3);
        for k in 0..ep.frames.len() {
            let p = ep.frame_path(k);
            // Decoded within the project's limits on pixels and memory.
            let img = visuotact_io::frames::read_image(&p).map_err(|e| {
                LeRobotError::Frame(
                    p.clone(),
                    format!("{e} (export needs the frames: record --save-frames, or no video)"),
                )
            })?;
            let dims = (img.width() as u32, img.height() as u32);
            let e = match enc.as_mut() {
                Some(e) if dims == size => e,
                Some(_) => {
                    return Err(LeRobotError::Frame(
                        p,
                        format!(
                            "{}×{}, the video's frames are {}×{}",
                            dims.0, dims.1, size.0, size.1
                        ),
                    ))
                }
                None => {
                    size = dims;
                    enc.insert(Encoder::start(cfg, &path, dims, fps)?)
                }
            };
            e.push(img.as_slice())?;
            stats.push_rgb(img.as_slice());
            done += 1;
            if progress(done, total).is_break() {
                return Err(LeRobotError::Stopped(done));
            }
        }
        per_episode.push(stats);
    }
    if let Some(e) = enc {
        e.finish()?;
    }
    Ok((size, per_episode))
}

fn mkdir_for(path: &Path) -> Result<(), LeRobotError> {
    let parent = path.parent().unwrap_or(Path::new("."));
    std::fs::create_dir_all(parent).map_err(|e| LeRobotError::Io(parent.into(), e))
}

fn write_json(path: &Path, v: &Value) -> Result<(), LeRobotError> {
    mkdir_for(path)?;
    let text = serde_json::to_string_pretty(v).map_err(|e| LeRobotError::Invalid(e.to_string()))?;
    std::fs::write(path, text + "\n").map_err(|e| LeRobotError::Io(path.into(), e))
}

/// The data set's pieces that the metadata files describe.
struct Written<'a> {
    eps: &'a [Episode],
    features: &'a [Feature],
    /// Per feature, each episode's statistics.
    stats: Vec<Vec<Stats>>,
    /// Frame size and per-episode pixel statistics, with video.
    video: Option<((u32, u32), Vec<Stats>)>,
    fps: u32,
}

impl Written<'_> {
    fn ranges(&self) -> Vec<std::ops::Range<usize>> {
        let mut from = 0;
        self.eps
            .iter()
            .map(|e| {
                let r = from..from + e.frames.len();
                from = r.end;
                r
            })
            .collect()
    }
}

/// The `stats/KEY/…` columns of the episodes table: each statistic's figures per episode,
/// shaped `[dims]` (an image: `[3, 1, 1]`).
fn stats_columns(key: &str, per_episode: &[Stats], image: bool, cols: &mut Vec<Column>) {
    let figures: Vec<[Vec<f64>; 4]> = per_episode.iter().map(Stats::figures).collect();
    let width = figures.first().map_or(1, |f| f[0].len());
    let shape = if image { vec![3, 1, 1] } else { vec![width] };
    for (i, stat) in ["min", "max", "mean", "std"].iter().enumerate() {
        let values = figures.iter().flat_map(|f| f[i].iter().copied()).collect();
        cols.push(Column::list(
            &format!("stats/{key}/{stat}"),
            &shape,
            Values::F64(values),
        ));
    }
    let counts = per_episode.iter().map(|s| s.count as i64).collect();
    cols.push(Column::list(
        &format!("stats/{key}/count"),
        &[1],
        Values::I64(counts),
    ));
}

/// The data set's statistics from its episodes'.
fn merged(per_episode: &[Stats]) -> Stats {
    let mut all = Stats::new(per_episode.first().map_or(0, |s| s.figures()[0].len()));
    for s in per_episode {
        all.merge(s);
    }
    all
}

fn write_episodes(dir: &Path, w: &Written<'_>, task: &str) -> Result<(), LeRobotError> {
    let ranges = w.ranges();
    let n = w.eps.len();
    let ints = |f: &dyn Fn(usize) -> usize| Values::I64((0..n).map(|e| f(e) as i64).collect());
    let zeros = || Values::I64(vec![0; n]);
    let mut cols = vec![
        Column::scalar("episode_index", ints(&|e| e)),
        Column::list("tasks", &[1], Values::Str(vec![task.to_string(); n])),
        Column::scalar("length", ints(&|e| ranges[e].len())),
        Column::scalar("data/chunk_index", zeros()),
        Column::scalar("data/file_index", zeros()),
        Column::scalar("dataset_from_index", ints(&|e| ranges[e].start)),
        Column::scalar("dataset_to_index", ints(&|e| ranges[e].end)),
    ];
    if w.video.is_some() {
        let fps = f64::from(w.fps);
        let from: Vec<f64> = ranges.iter().map(|r| r.start as f64 / fps).collect();
        let to: Vec<f64> = ranges.iter().map(|r| r.end as f64 / fps).collect();
        let v = format!("videos/{IMAGE_KEY}");
        cols.push(Column::scalar(&format!("{v}/chunk_index"), zeros()));
        cols.push(Column::scalar(&format!("{v}/file_index"), zeros()));
        cols.push(Column::scalar(
            &format!("{v}/from_timestamp"),
            Values::F64(from),
        ));
        cols.push(Column::scalar(
            &format!("{v}/to_timestamp"),
            Values::F64(to),
        ));
    }
    cols.push(Column::scalar("meta/episodes/chunk_index", zeros()));
    cols.push(Column::scalar("meta/episodes/file_index", zeros()));
    for (f, per) in w.features.iter().zip(&w.stats) {
        stats_columns(&f.key, per, false, &mut cols);
    }
    if let Some((_, per)) = &w.video {
        stats_columns(IMAGE_KEY, per, true, &mut cols);
    }
    let path = dir.join(format!("meta/episodes/{FILE_000}.parquet"));
    mkdir_for(&path)?;
    write_table(&path, &cols, &[])
}

/// `meta/tasks.parquet` as pandas writes a frame indexed by task: the index column last and
/// named in the `pandas` metadata, so that `pd.read_parquet` gives the task as the index.
fn write_tasks(dir: &Path, task: &str) -> Result<(), LeRobotError> {
    let pandas = json!({
        "index_columns": ["task"],
        "column_indexes": [{"name": null, "field_name": null, "pandas_type": "unicode",
                            "numpy_type": "object", "metadata": {"encoding": "UTF-8"}}],
        "columns": [
            {"name": "task_index", "field_name": "task_index", "pandas_type": "int64",
             "numpy_type": "int64", "metadata": null},
            {"name": "task", "field_name": "task", "pandas_type": "unicode",
             "numpy_type": "object", "metadata": null},
        ],
        "creator": {"library": "visuotact", "version": env!("CARGO_PKG_VERSION")},
        "pandas_version": "2.0.0",
    });
    let cols = [
        Column::scalar("task_index", Values::I64(vec![0])),
        Column::scalar("task", Values::Str(vec![task.to_string()])),
    ];
    write_table(
        &dir.join("meta/tasks.parquet"),
        &cols,
        &[("pandas", pandas.to_string())],
    )
}

fn write_meta(dir: &Path, w: &Written<'_>, cfg: &LeRobotConfig) -> Result<(), LeRobotError> {
    let total: usize = w.eps.iter().map(|e| e.frames.len()).sum();
    let mut features = serde_json::Map::new();
    let mut stats = serde_json::Map::new();
    for (f, per) in w.features.iter().zip(&w.stats) {
        features.insert(f.key.clone(), f.info());
        stats.insert(f.key.clone(), merged(per).to_json(false));
    }
    if let (Some(((width, height), per)), Some(v)) = (&w.video, &cfg.video) {
        features.insert(
            IMAGE_KEY.into(),
            json!({
                "dtype": "video",
                "shape": [height, width, 3],
                "names": ["height", "width", "channels"],
                "info": {
                    "video.height": height, "video.width": width, "video.codec": v.codec(),
                    "video.pix_fmt": "yuv420p", "video.is_depth_map": false,
                    "video.fps": w.fps, "video.channels": 3, "has_audio": false,
                },
            }),
        );
        stats.insert(IMAGE_KEY.into(), merged(per).to_json(true));
    }
    let info = json!({
        "codebase_version": CODEBASE_VERSION,
        "robot_type": cfg.robot_type,
        "total_episodes": w.eps.len(),
        "total_frames": total,
        "total_tasks": 1,
        "chunks_size": 1000,
        "data_files_size_in_mb": 100,
        "video_files_size_in_mb": 500,
        "fps": w.fps,
        "splits": {"train": format!("0:{}", w.eps.len())},
        "data_path": DATA_PATH,
        "video_path": w.video.as_ref().map(|_| VIDEO_PATH),
        "features": features,
    });
    write_json(&dir.join("meta/info.json"), &info)?;
    write_json(&dir.join("meta/stats.json"), &Value::Object(stats))?;
    write_tasks(dir, &cfg.task)?;
    write_episodes(dir, w, &cfg.task)
}

/// Exports `sessions` (one episode each, in the order given) into a new LeRobot v3.0 data set
/// at `out`; `progress(done, total)` hears of each frame encoded and may stop the export
/// ([`LeRobotError::Stopped`]). The data set is built in a folder of its own beside `out`,
/// created exclusively under a random name (`.OUT.XXXXXX.part~`: never one that is there, so
/// neither a leftover nor a link is followed, and two exports do not share it), and takes its
/// name only when whole: a failed or stopped export leaves nothing behind.
pub fn export_lerobot(
    sessions: &[PathBuf],
    out: &Path,
    cfg: &LeRobotConfig,
    progress: &mut dyn FnMut(usize, usize) -> ControlFlow<()>,
) -> Result<LeRobotSummary, LeRobotError> {
    if sessions.is_empty() {
        return Err(LeRobotError::Invalid("no session to export".into()));
    }
    if out.exists() {
        return Err(LeRobotError::Exists(out.into()));
    }
    if cfg.task.trim().is_empty() {
        return Err(LeRobotError::Invalid("the task is empty".into()));
    }
    let eps = sessions
        .iter()
        .map(|s| Episode::read(s))
        .collect::<Result<Vec<_>, _>>()?;
    let fps = fps_of(cfg, &eps)?;
    let mut notes: Vec<String> = eps.iter().flat_map(|e| e.notes.iter().cloned()).collect();
    let features = features_of(&eps, fps, &mut notes)?;
    let final_out = out;
    let building =
        visuotact_io::output::temp_dir_beside(out).map_err(|e| LeRobotError::Io(out.into(), e))?;
    let out = building.path();
    let result = (|| {
        let video = match &cfg.video {
            Some(v) => Some(encode_video(&eps, out, v, fps, progress)?),
            None => None,
        };
        let data = out.join(format!("data/{FILE_000}.parquet"));
        mkdir_for(&data)?;
        let cols: Vec<Column> = features.iter().map(Feature::column).collect();
        write_table(&data, &cols, &[])?;
        let mut w = Written {
            eps: &eps,
            features: &features,
            stats: Vec::new(),
            video,
            fps,
        };
        let ranges = w.ranges();
        w.stats = features
            .iter()
            .map(|f| ranges.iter().map(|r| f.stats(r.clone())).collect())
            .collect();
        write_meta(out, &w, cfg)?;
        // A data set that appeared under the name meanwhile is not replaced (a rename over
        // a folder that is not empty fails).
        if std::fs::symlink_metadata(final_out).is_ok() {
            return Err(LeRobotError::Exists(final_out.into()));
        }
        std::fs::rename(out, final_out).map_err(|e| LeRobotError::Io(final_out.into(), e))
    })();
    // Dropped unrenamed on an error, the building folder goes with everything in it: nothing
    // half-written stays behind to be mistaken for a data set.
    result?;
    // Renamed: nothing left to remove.
    let _ = building.keep();
    let mut names: Vec<String> = features.iter().map(|f| f.key.clone()).collect();
    if cfg.video.is_some() {
        names.push(IMAGE_KEY.into());
    }
    Ok(LeRobotSummary {
        path: final_out.into(),
        episodes: eps.len(),
        frames: eps.iter().map(|e| e.frames.len()).sum(),
        fps,
        features: names,
        notes,
    })
}
