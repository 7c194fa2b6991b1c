//! `visuotact simulate`: a session folder of simulated frames with exact ground truth.

use std::net::UdpSocket;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use rayon::prelude::*;
use visuotact_image::RgbImage;
use visuotact_io::force::{ForceLayout, ForceSample};
use visuotact_io::frames::write_png;
use visuotact_io::session::{SessionWriter, TruthRow};
use visuotact_sim::cone::{ConeConfig, ConeLoad};
use visuotact_sim::iats::{IatsConfig, Touch};
use visuotact_sim::jr3::{Jr3, Jr3Config};
use visuotact_sim::protocol::{self, ConePress, PressureGauge};
use visuotact_sim::rig::{cone_labels, frame_seed, CONE_LABELS, GAUGE_SEED};
use visuotact_sim::zoo::{self, ZooConfig, ZooKind, ZooTouch};

#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Which sensor: iats (seed 000's areal touch sensor), cone (seed 001's inflatable link), or
    /// one of the zoo: tactip (hemispherical tip, hexagonal pins), gelsight (dark-dot grid on a
    /// bright gel), dots (random dot pattern).
    #[arg(long, value_parser = ["iats", "cone", "tactip", "gelsight", "dots"])]
    sensor: String,
    /// iats: grid, random, shear, line; cone: press, press-rotate; zoo sensors: grid, random,
    /// shear.
    #[arg(long)]
    protocol: String,
    /// iats and zoo sensors: draw the sensor's parameters (pitch, marker size, colours, skin,
    /// camera…) from their ranges with this seed; 0 is the preset. `--config` overrides on top.
    #[arg(long, default_value_t = 0)]
    variant: u64,
    /// Random seed: the same seed writes the same bytes.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Session folder to create (must not hold a session).
    #[arg(short, long)]
    output: PathBuf,
    /// Touches for the random and shear protocols.
    #[arg(long, default_value_t = 200)]
    touches: usize,
    /// No-contact reference frames written first.
    #[arg(long, default_value_t = 10)]
    references: usize,
    /// Camera frame rate, frames per second.
    #[arg(long, default_value_t = 25.0)]
    fps: f64,
    /// cone: press and release time, seconds.
    #[arg(long, default_value_t = 20.0)]
    duration_s: f64,
    /// cone: peak force, N.
    #[arg(long, default_value_t = 10.0)]
    max_force_n: f64,
    /// cone: force sensor sample rate, Hz.
    #[arg(long, default_value_t = 1000.0)]
    force_rate_hz: f64,
    /// cone: also send the force stream as UDP packets to this address (loopback), paced in
    /// real time, with the layout of --force-layout.
    #[arg(long, value_name = "HOST:PORT")]
    udp: Option<String>,
    /// Packet fields for --udp (packed little-endian f64).
    #[arg(long, default_value = "timestamp_s,fx,fy,fz,tx,ty,tz")]
    force_layout: String,
    /// JSON file with the sensor model's settings (any subset of the fields of the `config`
    /// object in a session.json; the rest keep the preset or `--variant`'s draw), to match your
    /// own sensor.
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
}

/// The sensor model: `base` (the preset or a variant), with the fields of `--config` over it.
fn sensor_config<T: serde::de::DeserializeOwned + serde::Serialize>(
    a: &Args,
    base: T,
) -> anyhow::Result<T> {
    let Some(p) = &a.config else {
        return Ok(base);
    };
    let text =
        std::fs::read_to_string(p).with_context(|| format!("{}: cannot read", p.display()))?;
    let bad = |e: serde_json::Error| {
        anyhow::anyhow!("{}: not a {} sensor model: {e}", p.display(), a.sensor)
    };
    let over: serde_json::Value = serde_json::from_str(&text).map_err(bad)?;
    let serde_json::Value::Object(over) = over else {
        bail!("{}: expected a JSON object of settings", p.display());
    };
    let mut merged = serde_json::to_value(base)?;
    if let serde_json::Value::Object(m) = &mut merged {
        for (k, v) in over {
            m.insert(k, v);
        }
    }
    serde_json::from_value(merged).map_err(bad)
}

/// Frames rendered and written per parallel batch.
const BATCH: usize = 64;

struct Rendered {
    labels: Vec<f64>,
    truth: Vec<TruthRow>,
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    if !(a.fps.is_finite() && a.fps > 0.0) {
        bail!("--fps must be a positive frame rate, got {}", a.fps);
    }
    let t_start = Instant::now();
    if a.variant != 0 && a.sensor == "cone" {
        bail!("--variant applies to iats and the zoo sensors (tactip, gelsight, dots)");
    }
    let n_frames = match a.sensor.as_str() {
        "iats" => simulate_iats(a)?,
        "cone" => simulate_cone(a)?,
        zoo => simulate_zoo(a, ZooKind::from_name(zoo).context("unknown sensor")?)?,
    };
    eprintln!(
        "wrote {} reference and {n_frames} frames to {} in {:.1} s",
        a.references,
        a.output.display(),
        t_start.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Renders `count` frames with `render(k) -> (image, rendered)` in parallel batches, writing
/// PNGs as they come and the CSV rows in order.
fn write_frames(
    w: &mut SessionWriter,
    count: usize,
    first_index: usize,
    fps: f64,
    render: impl Fn(usize) -> anyhow::Result<(RgbImage, Rendered)> + Sync,
) -> anyhow::Result<()> {
    for start in (0..count).step_by(BATCH) {
        let end = (start + BATCH).min(count);
        let rows: Vec<(String, Rendered)> = (start..end)
            .into_par_iter()
            .map(|k| -> anyhow::Result<(String, Rendered)> {
                let (img, r) = render(k)?;
                let name = format!("frame_{k:06}.png");
                write_png(&w.frame_path(&name), &img)?;
                Ok((name, r))
            })
            .collect::<anyhow::Result<_>>()?;
        for (k, (name, r)) in (start..end).zip(rows) {
            let index = first_index + k;
            w.add_frame(&name, index, index as f64 / fps, &r.labels, &r.truth)?;
        }
    }
    Ok(())
}

fn write_references(
    w: &mut SessionWriter,
    n: usize,
    fps: f64,
    render: impl Fn(usize) -> anyhow::Result<(RgbImage, Vec<TruthRow>)> + Sync,
) -> anyhow::Result<()> {
    let imgs: Vec<(RgbImage, Vec<TruthRow>)> = (0..n)
        .into_par_iter()
        .map(&render)
        .collect::<anyhow::Result<_>>()?;
    for (k, (img, truth)) in imgs.iter().enumerate() {
        let name = format!("ref_{k:04}.png");
        write_png(&w.reference_path(&name), img)?;
        w.add_reference(&name, k, k as f64 / fps, truth)?;
    }
    Ok(())
}

fn iats_truth(markers: &[visuotact_sim::iats::IatsMarker]) -> Vec<TruthRow> {
    markers
        .iter()
        .map(|m| TruthRow {
            x_px: m.x_px,
            y_px: m.y_px,
            area_px: m.area_px,
            fully_in_view: m.fully_in_view,
            visible: m.visible,
        })
        .collect()
}

fn zoo_truth(markers: &[zoo::ZooMarker]) -> Vec<TruthRow> {
    markers
        .iter()
        .map(|m| TruthRow {
            x_px: m.x_px,
            y_px: m.y_px,
            area_px: m.area_px,
            fully_in_view: m.in_view,
            visible: m.visible,
        })
        .collect()
}

/// Rings are visible whenever they are wholly in view (they never crowd one another).
fn cone_truth(rings: &[visuotact_sim::cone::RingTruth]) -> Vec<TruthRow> {
    rings
        .iter()
        .map(|r| TruthRow {
            x_px: r.x_px,
            y_px: r.y_px,
            area_px: r.area_px,
            fully_in_view: r.fully_in_view,
            visible: r.fully_in_view,
        })
        .collect()
}

/// What a touch protocol's simulator gives [`write_touch_session`]: the sensor's name and
/// model, the label columns, the touch count and its two renderers.
struct TouchSession<'a, C, R, F> {
    sensor: &'a str,
    config: &'a C,
    cols: Vec<&'a str>,
    touches: usize,
    /// The rest frame and truth for a noise seed.
    reference: R,
    /// Touch `k`'s frame, labels and truth for a noise seed.
    frame: F,
}

/// Writes a touch session (references, frames, truth and the manifest) and returns its frame
/// count.
fn write_touch_session<C, R, F>(a: &Args, s: TouchSession<'_, C, R, F>) -> anyhow::Result<usize>
where
    C: serde::Serialize,
    R: Fn(u64) -> anyhow::Result<(RgbImage, Vec<TruthRow>)> + Sync,
    F: Fn(usize, u64) -> anyhow::Result<(RgbImage, Rendered)> + Sync,
{
    let mut w = SessionWriter::create(&a.output, &s.cols, true, false)?;
    write_references(&mut w, a.references, a.fps, |k| {
        (s.reference)(frame_seed(a.seed, k as u64))
    })?;
    write_frames(&mut w, s.touches, a.references, a.fps, |k| {
        (s.frame)(k, frame_seed(a.seed, (a.references + k) as u64))
            .map_err(|e| anyhow::anyhow!("touch {k}: {e}"))
    })?;
    w.finish(serde_json::json!({
        "sensor": s.sensor,
        "protocol": a.protocol,
        "seed": a.seed,
        "variant": a.variant,
        "fps": a.fps,
        "reference_frames": a.references,
        "frames": s.touches,
        "labels": s.cols,
        "config": s.config,
        "generator": format!("visuotact {}", env!("CARGO_PKG_VERSION")),
    }))?;
    Ok(s.touches)
}

fn simulate_iats(a: &Args) -> anyhow::Result<usize> {
    let cfg: IatsConfig = sensor_config(a, IatsConfig::variant(a.variant))?;
    cfg.validate()
        .map_err(|e| anyhow::anyhow!("sensor model: {e}"))?;
    let touches = protocol::iats_named(&cfg, &a.protocol, a.touches, a.seed).ok_or_else(|| {
        anyhow::anyhow!(
            "--protocol {:?} is not an iats protocol: expected {}",
            a.protocol,
            protocol::names_listed(&protocol::IATS_PROTOCOLS)
        )
    })?;
    for (k, t) in touches.iter().enumerate() {
        t.validate(&cfg)
            .map_err(|e| anyhow::anyhow!("touch {k}: {e}"))?;
    }
    let shear = a.protocol == "shear";
    let mut cols = vec!["x_mm", "y_mm", "depth_mm"];
    if shear {
        cols.extend(["shear_x_mm", "shear_y_mm"]);
    }
    let rest = Touch::default();
    write_touch_session(
        a,
        TouchSession {
            sensor: "iats",
            config: &cfg,
            cols,
            touches: touches.len(),
            reference: |seed| {
                let (img, truth) =
                    visuotact_sim::iats::render(&cfg, &rest, seed).map_err(anyhow::Error::msg)?;
                Ok((img, iats_truth(&truth)))
            },
            frame: |k, seed| {
                let t = &touches[k];
                let (img, truth) =
                    visuotact_sim::iats::render(&cfg, t, seed).map_err(anyhow::Error::msg)?;
                let mut labels = vec![t.x_mm, t.y_mm, t.depth_mm];
                if shear {
                    labels.extend([t.shear_x_mm, t.shear_y_mm]);
                }
                let truth = iats_truth(&truth);
                Ok((img, Rendered { labels, truth }))
            },
        },
    )
}

fn simulate_zoo(a: &Args, kind: ZooKind) -> anyhow::Result<usize> {
    let cfg: ZooConfig = sensor_config(a, ZooConfig::variant(kind, a.variant))?;
    cfg.validate()
        .map_err(|e| anyhow::anyhow!("sensor model: {e}"))?;
    let touches = protocol::zoo_named(&cfg, &a.protocol, a.touches, a.seed).ok_or_else(|| {
        anyhow::anyhow!(
            "--protocol {:?} is not a {} protocol: expected {}",
            a.protocol,
            kind.name(),
            protocol::names_listed(&protocol::ZOO_PROTOCOLS)
        )
    })?;
    for (k, t) in touches.iter().enumerate() {
        t.validate(&cfg)
            .map_err(|e| anyhow::anyhow!("touch {k}: {e}"))?;
    }
    let shear = a.protocol == "shear";
    let mut cols = vec!["x_mm", "y_mm", "depth_mm"];
    if shear {
        cols.extend(["shear_x_mm", "shear_y_mm", "twist_deg"]);
    }
    let rest = ZooTouch::default();
    write_touch_session(
        a,
        TouchSession {
            sensor: kind.name(),
            config: &cfg,
            cols,
            touches: touches.len(),
            reference: |seed| {
                let (img, truth) = zoo::render(&cfg, &rest, seed).map_err(anyhow::Error::msg)?;
                Ok((img, zoo_truth(&truth)))
            },
            frame: |k, seed| {
                let t = &touches[k];
                let (img, truth) = zoo::render(&cfg, t, seed).map_err(anyhow::Error::msg)?;
                let mut labels = vec![t.x_mm, t.y_mm, t.depth_mm];
                if shear {
                    labels.extend([t.shear_x_mm, t.shear_y_mm, t.twist_deg]);
                }
                let truth = zoo_truth(&truth);
                Ok((img, Rendered { labels, truth }))
            },
        },
    )
}

fn simulate_cone(a: &Args) -> anyhow::Result<usize> {
    let cfg: ConeConfig = sensor_config(a, ConeConfig::default())?;
    cfg.validate()
        .map_err(|e| anyhow::anyhow!("sensor model: {e}"))?;
    let press = ConePress {
        max_force_n: a.max_force_n,
        duration_s: a.duration_s,
        rotate: match a.protocol.as_str() {
            "press" => false,
            "press-rotate" => true,
            other => {
                bail!("--protocol {other:?} is not a cone protocol: expected press or press-rotate")
            }
        },
        ..ConePress::SEED001
    };
    press.validate().map_err(anyhow::Error::msg)?;
    let jr3_cfg = Jr3Config {
        rate_hz: a.force_rate_hz,
        ..Jr3Config::JR3_1KHZ
    };
    jr3_cfg.validate().map_err(anyhow::Error::msg)?;
    let layout =
        ForceLayout::parse(&a.force_layout).map_err(|e| anyhow::anyhow!("--force-layout: {e}"))?;
    let socket = match &a.udp {
        Some(addr) => {
            let s = UdpSocket::bind("127.0.0.1:0").context("cannot open a UDP socket")?;
            s.connect(addr)
                .with_context(|| format!("--udp {addr}: cannot address it"))?;
            Some(s)
        }
        None => None,
    };
    let t0 = a.references as f64 / a.fps;
    let n = (a.duration_s * a.fps).round() as usize;
    let cols = CONE_LABELS;
    let mut w = SessionWriter::create(&a.output, &cols, true, true)?;
    write_references(&mut w, a.references, a.fps, |k| {
        let t = k as f64 / a.fps;
        let load = ConeLoad::none(press.drift.at(cfg.pressure_kpa, t));
        let (img, rings) = visuotact_sim::cone::render(&cfg, &load, frame_seed(a.seed, k as u64))
            .map_err(anyhow::Error::msg)?;
        Ok((img, cone_truth(&rings)))
    })?;
    write_frames(&mut w, n, a.references, a.fps, |k| {
        let load = press.load_at(&cfg, k as f64 / a.fps, t0);
        let (img, rings) =
            visuotact_sim::cone::render(&cfg, &load, frame_seed(a.seed, (a.references + k) as u64))
                .map_err(|e| anyhow::anyhow!("frame {k}: {e}"))?;
        let labels = cone_labels(
            &cfg,
            &press,
            &load,
            t0 + k as f64 / a.fps,
            frame_seed(a.seed ^ GAUGE_SEED, k as u64),
        );
        let truth = cone_truth(&rings);
        Ok((img, Rendered { labels, truth }))
    })?;
    // The force stream covers the references and the press, at the sensor's own rate.
    let mut jr3 = Jr3::new(jr3_cfg, a.seed ^ 0x4A33);
    let total_s = t0 + a.duration_s;
    let n_samples = (total_s * jr3_cfg.rate_hz).round() as usize;
    let mut samples = Vec::with_capacity(n_samples);
    for i in 0..n_samples {
        let t = i as f64 / jr3_cfg.rate_hz;
        let load = if t < t0 {
            ConeLoad::none(cfg.pressure_kpa)
        } else {
            press.load_at(&cfg, t - t0, t0)
        };
        samples.push(ForceSample {
            timestamp_s: t,
            values: jr3.sample(load.components_n()),
        });
    }
    w.add_force(&samples)?;
    w.finish(serde_json::json!({
        "sensor": "cone",
        "protocol": a.protocol,
        "seed": a.seed,
        "fps": a.fps,
        "reference_frames": a.references,
        "frames": n,
        "labels": cols,
        "config": cfg,
        "press": press,
        "pressure_gauge": PressureGauge::SEED001,
        "force_sensor": jr3_cfg,
        "force_layout": layout.fields.iter().map(|f| f.name()).collect::<Vec<_>>(),
        "generator": format!("visuotact {}", env!("CARGO_PKG_VERSION")),
    }))?;
    if let Some(sock) = socket {
        send_paced(&sock, &layout, &samples, jr3_cfg.rate_hz)?;
    }
    Ok(n)
}

/// Sends samples as UDP packets at their own rate (in bursts of 1 ms of samples).
fn send_paced(
    sock: &UdpSocket,
    layout: &ForceLayout,
    samples: &[ForceSample],
    rate_hz: f64,
) -> anyhow::Result<()> {
    let start = Instant::now();
    let mut dropped = 0usize;
    for (i, s) in samples.iter().enumerate() {
        let due = Duration::from_secs_f64(i as f64 / rate_hz);
        let now = start.elapsed();
        if due > now + Duration::from_micros(500) {
            std::thread::sleep(due - now);
        }
        // A receiver that is not listening yet refuses datagrams on loopback; count, go on.
        if sock.send(&layout.encode(s, i as u64)).is_err() {
            dropped += 1;
        }
    }
    eprintln!(
        "sent {} force packets ({dropped} refused by the receiver)",
        samples.len()
    );
    Ok(())
}
