//! `visuotact bench`: times the in-memory frame → features pipeline on one thread.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::bail;
use visuotact_image::RgbImage;
use visuotact_io::frames::FrameStream;
use visuotact_vision::features::{FeatureExtractor, FrameFeatures};

#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Sensor file from `calibrate`.
    #[arg(long)]
    sensor: PathBuf,
    /// Frames to time (decoded once, before timing).
    #[arg(required = true)]
    frames: Vec<PathBuf>,
    /// Timed frames in all, cycling over the inputs (the OpenCV peer times 2000).
    #[arg(long, default_value_t = 2000)]
    passes: usize,
    /// Load at most this many frames.
    #[arg(long, default_value_t = 500)]
    max_frames: usize,
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    let cal = crate::load_sensor(&a.sensor)?;
    let features = cal.features;
    let mut ex = FeatureExtractor::new(cal, features).map_err(anyhow::Error::msg)?;
    let mut frames: Vec<RgbImage> = Vec::new();
    for f in FrameStream::open(&a.frames, 25.0)?.take_first(a.max_frames) {
        frames.push(f?.image);
    }
    if frames.is_empty() || a.passes == 0 {
        bail!("nothing to time");
    }
    let mut out = FrameFeatures::default();
    for img in frames.iter().take(50) {
        ex.extract_into(img, &mut out)?;
    }
    let mut us = Vec::with_capacity(a.passes);
    let mut found = 0usize;
    for i in 0..a.passes {
        let img = &frames[i % frames.len()];
        let t0 = Instant::now();
        ex.extract_into(img, &mut out)?;
        us.push(t0.elapsed().as_secs_f64() * 1e6);
        found += out.found;
    }
    let [median, p90] = visuotact_io::queue::percentiles(&mut us, [0.5, 0.9]);
    say!(
        "median_us={median:.1} p90_us={p90:.1} fps={:.0} frames={} passes={} size={}x{} markers_found_mean={:.1}",
        1e6 / median,
        frames.len(),
        a.passes,
        frames[0].width(),
        frames[0].height(),
        found as f64 / a.passes as f64
    );
    Ok(())
}
