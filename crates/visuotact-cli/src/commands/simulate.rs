//! `visuotact simulate`: a session folder of simulated frames with exact ground truth
//! ([`visuotact_experiments::synth`]).

use std::net::UdpSocket;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context};
use visuotact_experiments::synth::{simulate, ConeSession, SimKind, SimulateConfig};
use visuotact_io::force::send_paced;
use visuotact_io::force::ForceLayout;

#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Which sensor: iats (the 117-marker membrane of the areal touch sensor paper), cone (the inflatable cone measuring force), or
    /// one of the zoo: tactip (hemispherical tip, hexagonal pins), gelsight (dark-dot grid on a
    /// bright gel), dots (random dot pattern), tactip-small (the tip on a binarised 128 × 128
    /// image, 2–4 px pins, as published data sets).
    #[arg(long, value_parser = crate::args::choice::<SimKind>(SimKind::NAMES))]
    sensor: SimKind,
    /// iats: grid, random, shear, line; cone: press, press-rotate; zoo sensors: grid, random, drag,
    /// shear, on the domes (tactip, tactip-small) plate, and one grasp: grasp-press, grasp-drag
    /// (sideways under the friction limit), grasp-twist, grasp-slip (past it) or grasp-shake
    /// (swung both ways under it; labels.csv then has the truth per frame in `slip_state`: 0
    /// stick, 1 incipient, 2 slip).
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
    /// Touches for the random and shear protocols; a grasp's frames (at least 60).
    #[arg(long, default_value_t = 200, value_parser = clap::value_parser!(u64).range(1..))]
    touches: u64,
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

/// The `--config` file's settings, a JSON object.
fn overrides(a: &Args) -> anyhow::Result<Option<serde_json::Map<String, serde_json::Value>>> {
    let Some(p) = &a.config else {
        return Ok(None);
    };
    let text = visuotact_io::read::text_of_file(p)
        .with_context(|| format!("{}: cannot read", p.display()))?;
    match serde_json::from_str(&text) {
        Ok(serde_json::Value::Object(m)) => Ok(Some(m)),
        Ok(_) => bail!("{}: expected a JSON object of settings", p.display()),
        Err(e) => bail!(
            "{}: not a {} sensor model: {e}",
            p.display(),
            a.sensor.name()
        ),
    }
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    // Beyond the fastest tactile cameras the timestamps stop meaning anything.
    if !(a.fps > 0.0 && a.fps <= 10_000.0) {
        bail!(
            "--fps must be a positive frame rate of at most 10000 per second, got {}",
            a.fps
        );
    }
    if a.variant != 0 && a.sensor == SimKind::Cone {
        bail!("--variant applies to iats and the zoo sensors (tactip, gelsight, dots)");
    }
    let t_start = Instant::now();
    let force_layout =
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
    let cfg = SimulateConfig {
        sensor: a.sensor,
        protocol: a.protocol.clone(),
        variant: a.variant,
        seed: a.seed,
        output: a.output.clone(),
        touches: a.touches as usize,
        references: a.references,
        fps: a.fps,
        cone: ConeSession {
            duration_s: a.duration_s,
            max_force_n: a.max_force_n,
            force_rate_hz: a.force_rate_hz,
        },
        force_layout,
        overrides: overrides(a)?,
    };
    let done = simulate(&cfg).map_err(|e| match (&a.config, e) {
        (Some(p), e @ visuotact_experiments::synth::SimulateError::Overrides { .. }) => {
            anyhow::anyhow!("{}: {e}", p.display())
        }
        (_, e) => e.into(),
    })?;
    note!(
        "wrote {} reference and {} frames to {} in {:.1} s",
        a.references,
        done.frames,
        a.output.display(),
        t_start.elapsed().as_secs_f64()
    );
    if let Some(sock) = socket {
        let refused = send_paced(&sock, &cfg.force_layout, &done.force, a.force_rate_hz);
        note!(
            "sent {} force packets ({refused} refused by the receiver)",
            done.force.len()
        );
    }
    Ok(())
}
