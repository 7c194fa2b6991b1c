//! `visuotact record`: a frame source plus an optional force source → a session folder, written
//! as it goes.
//!
//! Sources: `frames:DIR` or `video:FILE` (or bare paths), and the simulated rigs `sim:cone`
//! (seed 001's link pressed and released, its JR3 streaming over UDP to `--force`) and
//! `sim:iats` (random touches), paced in real time. Force: `udp:HOST:PORT` (packed
//! little-endian f64, `--force-layout`) or `csv:FILE`.
//!
//! Every table row is written and flushed as it is produced and files are `fsync`ed every
//! `--sync-every-s`: a crash or SIGKILL leaves every completed row readable, and `--resume`
//! continues a stopped session (an unfinished last line is cut off first). Ctrl-C stops
//! cleanly. An unwritable folder or a full disk is reported before recording starts.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use visuotact_image::RgbImage;
use visuotact_io::force::{ForceLayout, ForceReceiver, ForceSample, ForceTable, ReceiveStats};
use visuotact_io::frames::{write_png, FrameStream};
use visuotact_io::session::{probe_writable, AppendLog, SESSION_FORMAT, SESSION_VERSION};
use visuotact_io::source::SourceSpec;
use visuotact_io::table::{format_number, push_csv_row};
use visuotact_sim::jr3::{Jr3, Jr3Config};

use crate::extract::{feature_row_into, flags_of, LEAD_COLUMNS};
use visuotact_sim::rig::{frame_seed, SimRig};

#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Session folder to write.
    #[arg(short, long)]
    output: PathBuf,
    /// Frame source: camera:/dev/videoN, frames:DIR, video:FILE, sim:cone, sim:iats, or
    /// image/video paths.
    #[arg(long)]
    source: String,
    /// Frame rate of image folders and of the simulated camera, frames per second.
    #[arg(long, default_value_t = 25.0)]
    fps: f64,
    /// Stop after this many seconds.
    #[arg(long)]
    duration_s: Option<f64>,
    /// Stop after this many frames.
    #[arg(long)]
    max_frames: Option<usize>,
    /// Force source: udp:HOST:PORT (listen there) or csv:FILE.
    #[arg(long)]
    force: Option<String>,
    /// Fields of a force packet, in order (packed little-endian f64).
    #[arg(long, default_value = "timestamp_s,fx,fy,fz,tx,ty,tz")]
    force_layout: String,
    /// The force sensor's sample rate, Hz (counts lost packets; converts a counter field).
    #[arg(long, default_value_t = 1000.0)]
    force_rate_hz: f64,
    /// Sensor file: also write each frame's features (features.csv).
    #[arg(long)]
    sensor: Option<PathBuf>,
    /// Frames are in order (video, camera): start each frame's tracking from the last one's
    /// marker positions (the reference stays the fallback).
    #[arg(long)]
    temporal: bool,
    /// Model: also estimate live (estimates.csv); uses the model's calibration without --sensor.
    #[arg(long)]
    model: Option<PathBuf>,
    /// Keep every frame as PNG in frames/ (for replay and re-extraction).
    #[arg(long)]
    save_frames: bool,
    /// fsync the session files this often, seconds.
    #[arg(long, default_value_t = 1.0)]
    sync_every_s: f64,
    /// Continue a stopped session in the output folder.
    #[arg(long)]
    resume: bool,
    /// sim sources: random seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// sim:cone: press-and-release time, seconds.
    #[arg(long, default_value_t = 20.0)]
    press_s: f64,
    /// sim:cone: no-contact time before and after the press, seconds.
    #[arg(long, default_value_t = 2.0)]
    rest_s: f64,
    /// sim:cone: peak force, N.
    #[arg(long, default_value_t = 10.0)]
    max_force_n: f64,
    /// sim sources: no-contact reference frames written to reference/ first.
    #[arg(long, default_value_t = 10)]
    references: usize,
}

/// A frame the recorder writes: from a simulated rig (with its labels), a file or a camera,
/// on the recorder's clock.
struct RecordedFrame {
    id: String,
    timestamp_s: f64,
    image: RgbImage,
    labels: Vec<f64>,
}

fn sim_of(a: &Args, kind: &str) -> anyhow::Result<SimRig> {
    Ok(match kind {
        "cone" => {
            if !(a.rest_s.is_finite() && a.rest_s >= 0.0) {
                bail!("--rest-s must be ≥ 0");
            }
            SimRig::cone(a.press_s, a.max_force_n, a.rest_s)?
        }
        "iats" => SimRig::iats(a.max_frames.unwrap_or(200).max(1), a.seed),
        other => bail!("--source sim:{other}: expected sim:cone or sim:iats"),
    })
}

/// Where and when the simulated JR3 streams.
struct Jr3Stream<'a> {
    /// Destination address.
    addr: &'a str,
    layout: ForceLayout,
    rate_hz: f64,
    seed: u64,
    /// Time zero of the rig.
    clock: Instant,
    /// First and last sample times, s.
    t_from: f64,
    t_end: f64,
}

/// Sends the simulated JR3 stream of the cone rig, paced in real time, until `stop`.
fn spawn_jr3(
    sim: &SimRig,
    j: Jr3Stream<'_>,
    stop: Arc<AtomicBool>,
) -> anyhow::Result<Option<std::thread::JoinHandle<u64>>> {
    let Jr3Stream {
        addr,
        layout,
        rate_hz,
        seed,
        clock,
        t_from,
        t_end,
    } = j;
    let SimRig::Cone { cfg, press, rest_s } = sim else {
        return Ok(None);
    };
    let (cfg, press, rest_s) = (*cfg, *press, *rest_s);
    let sock = std::net::UdpSocket::bind("127.0.0.1:0").context("cannot open a UDP socket")?;
    sock.connect(addr)
        .with_context(|| format!("simulated force sensor: cannot address {addr}"))?;
    let jr3_cfg = Jr3Config {
        rate_hz,
        ..Jr3Config::JR3_1KHZ
    };
    jr3_cfg.validate().map_err(anyhow::Error::msg)?;
    Ok(Some(std::thread::spawn(move || {
        let mut jr3 = Jr3::new(jr3_cfg, seed ^ 0x4A33);
        let mut sent = 0u64;
        let mut i = (t_from * rate_hz).ceil() as u64;
        loop {
            let t = i as f64 / rate_hz;
            if t > t_end || stop.load(Ordering::Relaxed) {
                break;
            }
            let due = Duration::from_secs_f64(t);
            let now = clock.elapsed();
            if due > now + Duration::from_micros(300) {
                std::thread::sleep(due - now);
            }
            let load = SimRig::cone_load(&cfg, &press, rest_s, t);
            let s = ForceSample {
                timestamp_s: t,
                values: jr3.sample(load.components_n()),
            };
            if sock.send(&layout.encode(&s, i)).is_ok() {
                sent += 1;
            }
            i += 1;
        }
        sent
    })))
}

/// Receives force packets into force.csv until `stop`.
fn spawn_receiver(
    mut rx: ForceReceiver,
    mut log: AppendLog,
    clock: Instant,
    t_offset: f64,
    stop: Arc<AtomicBool>,
) -> std::thread::JoinHandle<anyhow::Result<ReceiveStats>> {
    std::thread::spawn(move || {
        let mut line = String::new();
        loop {
            let got = rx.recv(Duration::from_millis(50), || {
                t_offset + clock.elapsed().as_secs_f64()
            })?;
            match got {
                Some(r) => {
                    line.clear();
                    line.push_str(&format!("{:.6}", r.sample.timestamp_s));
                    for v in r.sample.values {
                        line.push_str(&format!(",{v:.6}"));
                    }
                    line.push_str(&format!(",{:.6}", r.recv_s));
                    log.line(&line)?;
                }
                None if stop.load(Ordering::Relaxed) => break,
                None => {}
            }
        }
        log.sync()?;
        Ok(rx.stats())
    })
}

const FORCE_HEADER: &str = "timestamp_s,fx_n,fy_n,fz_n,tx_nm,ty_nm,tz_nm,recv_s";

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    if !(a.fps.is_finite() && a.fps > 0.0) {
        bail!("--fps must be a positive frame rate, got {}", a.fps);
    }
    if !(a.sync_every_s.is_finite() && a.sync_every_s >= 0.0) {
        bail!("--sync-every-s must be ≥ 0");
    }
    let out = &a.output;
    let exists = out.join("frames.csv").exists() || out.join("session.json").exists();
    if exists && !a.resume {
        bail!(
            "{}: already holds a session; give --resume to continue it, or choose a new folder",
            out.display()
        );
    }
    if a.resume && !exists {
        bail!("{}: no session to resume", out.display());
    }
    std::fs::create_dir_all(out)
        .with_context(|| format!("cannot create the session folder {}", out.display()))?;
    probe_writable(out, 1 << 20)?;
    let sync = Duration::from_secs_f64(a.sync_every_s);

    // Sources.
    let source = SourceSpec::parse(&a.source);
    let sim = match &source {
        SourceSpec::Sim(kind) => Some(sim_of(a, kind)?),
        _ => None,
    };
    let model = a
        .model
        .as_deref()
        .map(crate::train::load_model)
        .transpose()?;
    let mut est = if a.sensor.is_some() || model.is_some() {
        let mut e = crate::live::estimator(a.sensor.as_deref(), model)?;
        e.set_temporal_prior(a.temporal);
        Some(e)
    } else {
        None
    };

    // Tables (resume keeps what is there).
    let (mut frames_log, kept) = AppendLog::open(
        &out.join("frames.csv"),
        "frame,index,timestamp_s,kind",
        a.resume,
        sync,
    )?;
    let done: std::collections::HashSet<String> = kept
        .lines()
        .skip(1)
        .filter_map(|l| l.split(',').next().map(str::to_string))
        .collect();
    let last_t = kept
        .lines()
        .skip(1)
        .filter_map(|l| l.split(',').nth(2)?.parse::<f64>().ok())
        .fold(f64::NEG_INFINITY, f64::max);
    let first_index = frames_log.lines();
    let mut features_log = match &est {
        Some(e) => {
            let mut cols: Vec<String> = LEAD_COLUMNS.iter().map(|s| s.to_string()).collect();
            cols.extend(e.feature_columns());
            let header = format!("frame,{},flags", cols.join(","));
            Some(AppendLog::open(&out.join("features.csv"), &header, a.resume, sync)?.0)
        }
        None => None,
    };
    let mut estimates_log = match est.as_ref().map(|e| e.target_columns()) {
        Some(cols) if !cols.is_empty() => {
            let header = format!("frame,{},flags", cols.join(","));
            Some(AppendLog::open(&out.join("estimates.csv"), &header, a.resume, sync)?.0)
        }
        _ => None,
    };
    let mut labels_log = match &sim {
        Some(s) => Some(
            AppendLog::open(
                &out.join("labels.csv"),
                &format!("frame,{}", s.label_columns().join(",")),
                a.resume,
                sync,
            )?
            .0,
        ),
        None => None,
    };
    if a.save_frames {
        std::fs::create_dir_all(out.join("frames"))?;
    }

    // Session description, rewritten at the end.
    let describe = |complete: bool, extra: serde_json::Value| -> anyhow::Result<()> {
        let mut v = serde_json::json!({
            "format": SESSION_FORMAT,
            "version": SESSION_VERSION,
            "recorded_by": format!("visuotact {} record", env!("CARGO_PKG_VERSION")),
            "source": a.source,
            "fps": a.fps,
            "force": a.force,
            "force_layout": a.force_layout,
            "force_rate_hz": a.force_rate_hz,
            "force_clock": "timestamp_s is the force sender's clock; recv_s the recorder's",
            "sensor_file": a.sensor,
            "model_file": a.model,
            "frames_saved": a.save_frames,
            "complete": complete,
        });
        if let (Some(o), Some(e)) = (v.as_object_mut(), extra.as_object()) {
            o.extend(e.clone());
        }
        crate::write_atomically(
            &out.join("session.json"),
            &(serde_json::to_string_pretty(&v)? + "\n"),
        )
    };
    describe(false, serde_json::json!({}))?;

    // Simulated rigs write their no-contact references first.
    if let Some(s) = &sim {
        if !a.resume && a.references > 0 {
            std::fs::create_dir_all(out.join("reference"))?;
            for k in 0..a.references {
                let img = s.reference(frame_seed(a.seed, 1_000_000 + k as u64))?;
                write_png(&out.join("reference").join(format!("ref_{k:04}.png")), &img)?;
            }
        }
    }

    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = stop.clone();
        // A second handler cannot be installed in the same process (tests); that is fine.
        let _ = ctrlc::set_handler(move || stop.store(true, Ordering::Relaxed));
    }
    // The session clock: resumed sessions continue after their last frame.
    let t_offset = if last_t.is_finite() {
        last_t + 1.0 / a.fps
    } else {
        0.0
    };
    let clock = Instant::now();
    let now_s = || t_offset + clock.elapsed().as_secs_f64();

    // Force.
    let layout =
        ForceLayout::parse(&a.force_layout).map_err(|e| anyhow::anyhow!("--force-layout: {e}"))?;
    let mut receiver = None;
    let mut jr3 = None;
    let stop_force = Arc::new(AtomicBool::new(false));
    match a.force.as_deref() {
        None => {}
        Some(f) if f.starts_with("udp:") => {
            let addr = &f[4..];
            let rx = ForceReceiver::bind(addr, layout.clone(), Some(a.force_rate_hz))?;
            let bound = rx.local_addr()?.to_string();
            let (log, _) = AppendLog::open(&out.join("force.csv"), FORCE_HEADER, a.resume, sync)?;
            receiver = Some(spawn_receiver(rx, log, clock, t_offset, stop_force.clone()));
            if let Some(s) = &sim {
                let t_end = s
                    .total_s(a.fps)
                    .min(a.duration_s.map_or(f64::INFINITY, |d| t_offset + d));
                let sim_clock = clock
                    .checked_sub(Duration::from_secs_f64(t_offset))
                    .unwrap_or(clock);
                jr3 = spawn_jr3(
                    s,
                    Jr3Stream {
                        addr: &bound,
                        layout: layout.clone(),
                        rate_hz: a.force_rate_hz,
                        seed: a.seed,
                        clock: sim_clock,
                        t_from: t_offset,
                        t_end,
                    },
                    stop.clone(),
                )?;
            }
        }
        Some(f) if f.starts_with("csv:") => {
            let p = Path::new(&f[4..]);
            let t = ForceTable::read(p).map_err(anyhow::Error::msg)?;
            let (mut log, _) =
                AppendLog::open(&out.join("force.csv"), FORCE_HEADER, a.resume, sync)?;
            for (ts, v) in t.timestamp_s.iter().zip(&t.values) {
                let cells: Vec<String> = v.iter().map(|x| format!("{x:.6}")).collect();
                log.line(&format!("{ts:.6},{},{ts:.6}", cells.join(",")))?;
            }
            log.sync()?;
        }
        Some(f) => bail!("--force {f:?}: expected udp:HOST:PORT or csv:FILE"),
    }

    // Frames.
    // A camera captures on its own thread into a drop-oldest queue, timestamped on arrival.
    let camera = match &source {
        SourceSpec::Camera(dev) => {
            let q = Arc::new(visuotact_pipeline::LatestQueue::new(4));
            let h = visuotact_io::camera::spawn(
                dev,
                visuotact_io::camera::CameraRequest::default(),
                a.fps,
                q.clone(),
                stop.clone(),
                clock,
                u64::MAX,
            )?;
            Some((q, h))
        }
        _ => None,
    };
    let mut stream = match &source {
        SourceSpec::Frames(path) => Some(FrameStream::open(std::slice::from_ref(path), a.fps)?),
        _ => None,
    };
    let (mut written, mut dropped, mut failed) = (0usize, 0usize, 0usize);
    let n_targets = est.as_ref().map_or(0, |e| e.target_columns().len());
    let mut k = first_index;
    let (mut line, mut row) = (String::new(), Vec::new());
    let result: anyhow::Result<()> = (|| {
        loop {
            if stop.load(Ordering::Relaxed)
                || a.max_frames.is_some_and(|m| written >= m)
                || a.duration_s.is_some_and(|d| now_s() - t_offset >= d)
            {
                break;
            }
            let cap = match (&sim, stream.as_mut()) {
                (Some(s), _) => {
                    let t = k as f64 / a.fps;
                    if t > s.total_s(a.fps) {
                        break;
                    }
                    let due = t - t_offset;
                    let el = clock.elapsed().as_secs_f64();
                    if el > due + 1.0 / a.fps {
                        // The simulated camera could not keep up: this frame is gone.
                        dropped += 1;
                        k += 1;
                        continue;
                    }
                    if due > el {
                        std::thread::sleep(Duration::from_secs_f64(due - el));
                    }
                    let (image, labels) = s.frame(k, t, frame_seed(a.seed, k as u64))?;
                    RecordedFrame {
                        id: format!("frame_{k:06}.png"),
                        timestamp_s: t,
                        image,
                        labels,
                    }
                }
                (None, Some(st)) => match st.next() {
                    None => break,
                    Some(Err(e)) => {
                        eprintln!("warning: {e}; skipped");
                        failed += 1;
                        continue;
                    }
                    Some(Ok(fr)) => {
                        if done.contains(&fr.id) {
                            continue;
                        }
                        RecordedFrame {
                            id: fr.id,
                            timestamp_s: fr.timestamp_s,
                            image: fr.image,
                            labels: Vec::new(),
                        }
                    }
                },
                (None, None) => match camera.as_ref().and_then(|(q, _)| q.pop()) {
                    Some(c) => RecordedFrame {
                        id: format!("frame_{k:06}.png"),
                        timestamp_s: t_offset + c.timestamp_s,
                        image: Arc::try_unwrap(c.image).unwrap_or_else(|a| (*a).clone()),
                        labels: Vec::new(),
                    },
                    None => break,
                },
            };
            if a.save_frames {
                let name = if cap.id.ends_with(".png") {
                    cap.id.clone()
                } else {
                    format!("{}.png", cap.id)
                };
                write_png(&out.join("frames").join(name), &cap.image)?;
            }
            if let Some(e) = est.as_mut() {
                let n_markers = e.n_markers();
                match e.process(&cap.image) {
                    Ok((f, estimate)) => {
                        if let Some(log) = features_log.as_mut() {
                            feature_row_into(&mut row, cap.timestamp_s, n_markers, f);
                            line.clear();
                            push_csv_row(&mut line, &cap.id, &row, &flags_of(f));
                            log.line(&line)?;
                        }
                        if let Some(log) = estimates_log.as_mut() {
                            line.clear();
                            match &estimate {
                                Some(v) => push_csv_row(&mut line, &cap.id, v, ""),
                                None => push_csv_row(
                                    &mut line,
                                    &cap.id,
                                    &vec![f64::NAN; n_targets],
                                    "missing features",
                                ),
                            }
                            log.line(&line)?;
                        }
                    }
                    Err(err) => eprintln!("warning: frame {}: {err}", cap.id),
                }
            }
            if let Some(log) = labels_log.as_mut() {
                let cells: Vec<String> = cap.labels.iter().map(|v| format_number(*v)).collect();
                log.line(&format!("{},{}", cap.id, cells.join(",")))?;
            }
            frames_log.line(&format!(
                "{},{},{},touch",
                cap.id,
                k,
                format_number(cap.timestamp_s)
            ))?;
            written += 1;
            k += 1;
        }
        Ok(())
    })();
    // Stop the camera and the force side, whatever happened to the frames.
    stop.store(true, Ordering::Relaxed);
    if let Some((q, h)) = camera {
        q.close();
        let _ = h.join();
    }
    let sent = jr3.and_then(|h| h.join().ok());
    std::thread::sleep(Duration::from_millis(100));
    stop_force.store(true, Ordering::Relaxed);
    let stats = match receiver {
        Some(h) => Some(
            h.join()
                .map_err(|_| anyhow::anyhow!("the force receiver stopped unexpectedly"))??,
        ),
        None => None,
    };
    for log in [
        Some(&mut frames_log),
        features_log.as_mut(),
        estimates_log.as_mut(),
        labels_log.as_mut(),
    ]
    .into_iter()
    .flatten()
    {
        log.sync()?;
    }
    describe(
        result.is_ok(),
        serde_json::json!({
            "frames": first_index + written,
            "frames_dropped": dropped,
            "frames_unreadable": failed,
            "force_packets": stats,
            "force_packets_sent_by_simulator": sent,
            "duration_s": clock.elapsed().as_secs_f64(),
        }),
    )?;
    result?;
    eprintln!(
        "recorded {written} frames ({dropped} dropped, {failed} unreadable) into {} in {:.1} s",
        out.display(),
        clock.elapsed().as_secs_f64()
    );
    if let Some(s) = stats {
        eprintln!(
            "force: {} packets, {} kept, {} malformed, {} duplicates, {} reordered, {} lost",
            s.packets, s.kept, s.malformed, s.duplicates, s.reordered, s.lost
        );
    }
    Ok(())
}
