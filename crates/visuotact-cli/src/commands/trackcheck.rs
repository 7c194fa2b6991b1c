//! `visuotact check-tracking`: [`visuotact_experiments::trackcheck`] over sensor variants, one
//! table row per variant.

use anyhow::{bail, Context};
use visuotact_experiments::realcard::{real_card_table, RealCardConfig};
use visuotact_experiments::scorecard::{scorecard_table, touched_reference};
use visuotact_experiments::trackcheck::{
    check, CheckConfig, CheckReport, SimSensor, MOTION_LIMIT_PITCHES,
};
use visuotact_vision::detect::Centroid;
use visuotact_vision::layout::LayoutChoice;
use visuotact_vision::options::ThresholdChoice;
use visuotact_vision::track::TrackParams;

#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// iats, tactip, tactip-small, gelsight or dots.
    #[arg(long, default_value = "tactip")]
    sensor: String,
    /// Sensor variants: a number or a range `A..B` (inclusive; 0 is the preset).
    #[arg(long, default_value = "0")]
    variants: String,
    /// grid, random, shear, drag, or on the domes plate (iats: grid, random, shear or line).
    #[arg(long, default_value = "shear")]
    protocol: String,
    /// Touches for every protocol but grid.
    #[arg(long, default_value_t = 200, value_parser = clap::value_parser!(u64).range(1..))]
    touches: u64,
    /// Seed of the touches and noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Rest frames averaged into the reference.
    #[arg(long, default_value_t = 10)]
    references: usize,
    /// With `--protocol plate` on a dome: calibrate on frames pressed by a plate drawn from the
    /// seed, not at rest, as the scorecard's `plate` rows do (a sensor never out of contact).
    #[arg(long)]
    reference_pressed: bool,
    /// Centroids: grey (calibrate's default), weighted or binary.
    #[arg(long, default_value = "grey", value_parser = crate::args::choice::<Centroid>(Centroid::NAMES))]
    centroid: Centroid,
    /// Threshold over the sensor's preset: otsu, otsu-sampled, adaptive or a level in 0..1.
    #[arg(long)]
    threshold: Option<String>,
    /// Binarise the zoo sensor's output (black and white frames, as published TacTip data).
    #[arg(long)]
    binarise: bool,
    /// Frames where a visible marker moves farther than this, in pitches, are also counted
    /// apart (the `beyond_*` columns).
    #[arg(long, default_value_t = MOTION_LIMIT_PITCHES)]
    motion_limit: f64,
    /// Build each touch up from rest in N frames (pressed over the first third, then dragged)
    /// and follow them with the temporal prior, as `--temporal` on a video; 0: every frame on
    /// its own.
    #[arg(long, default_value_t = 0)]
    followed: usize,
    /// Tracker settings over the defaults, name=value pairs: `margin=3,gate_spacings=0.5`.
    #[arg(long, default_value = "")]
    track: String,
    /// Print the tracking scorecard instead: seeds `--seed` and the next, wrong / lost /
    /// ambiguous marker-frames per sensor family and motion band.
    #[arg(long)]
    scorecard: bool,
    /// Print the scorecard's real half instead: the real sets in this folder
    /// (`../shared/reference/real`) tracked as a user would, with counts that need no labels.
    #[arg(long, value_name = "DIR")]
    real: Option<std::path::PathBuf>,
    /// With `--real`: every N-th frame of the TacTip sets (1: all of them).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..))]
    stride: u64,
    /// With `--scorecard` or `--real`: fail where it is worse than this baseline table.
    #[arg(long)]
    baseline: Option<std::path::PathBuf>,
    /// Print the first problems found.
    #[arg(long)]
    verbose: bool,
}

/// Parses `N` or `A..B` (inclusive).
pub(crate) fn parse_range(s: &str) -> anyhow::Result<Vec<u64>> {
    let bad = || anyhow::anyhow!("{s:?}: expected a number or a range A..B");
    if let Some((a, b)) = s.split_once("..") {
        let (a, b): (u64, u64) = (a.parse().map_err(|_| bad())?, b.parse().map_err(|_| bad())?);
        if a > b {
            return Err(bad());
        }
        Ok((a..=b).collect())
    } else {
        Ok(vec![s.parse().map_err(|_| bad())?])
    }
}

/// `--scorecard` or `--real`: the table, failing where it is worse than `--baseline`.
fn scorecards(a: &Args, track: TrackParams) -> anyhow::Result<()> {
    let (table, worse) = match &a.real {
        Some(dir) => {
            let reporter = crate::progress::Reporter::new(false);
            real_card_table(
                &RealCardConfig {
                    stride: a.stride as usize,
                    track,
                    ..RealCardConfig::new(dir)
                },
                a.baseline.as_deref(),
                &mut |set| reporter.stage(set),
            )?
        }
        None => scorecard_table(a.seed, track, a.baseline.as_deref())?,
    };
    say!("{table}");
    anyhow::ensure!(
        worse.is_empty(),
        "worse than the baseline: {}",
        worse.join("; ")
    );
    Ok(())
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    let track =
        (TrackParams::DEFAULT.parse_over(&a.track)).map_err(|e| anyhow::anyhow!("--track: {e}"))?;
    if a.scorecard || a.real.is_some() {
        return scorecards(a, track);
    }
    if !(a.motion_limit.is_finite() && a.motion_limit > 0.0) {
        bail!(
            "--motion-limit {}: expected a positive number of pitches",
            a.motion_limit
        );
    }
    let centroid = a.centroid;
    say!("{}", CheckReport::TSV_HEADER);
    let (mut lost, mut wrong) = (0, 0);
    for v in parse_range(&a.variants)? {
        let mut sensor = SimSensor::named(&a.sensor, v)?;
        if a.binarise {
            match &mut sensor {
                SimSensor::Zoo(c) => c.binarise = true,
                SimSensor::Iats(_) => bail!("--binarise applies to the zoo sensors"),
            }
        }
        let mut detector = sensor.detector(centroid);
        if let Some(t) = &a.threshold {
            let choice = ThresholdChoice::parse(t).map_err(anyhow::Error::msg)?;
            detector.preprocess.threshold = choice.over(detector.preprocess.threshold);
        }
        let reference_touch = if a.reference_pressed {
            let touch = touched_reference(&sensor, &a.protocol, a.seed).context(
                "--reference-pressed: expected --protocol plate on a dome (tactip or tactip-small)",
            )?;
            Some(touch)
        } else {
            None
        };
        let cfg = CheckConfig {
            sensor,
            protocol: a.protocol.clone(),
            touches: a.touches as usize,
            seed: a.seed,
            references: a.references,
            reference_touch,
            detector,
            layout: LayoutChoice::Auto,
            motion_limit_pitches: a.motion_limit,
            followed_steps: a.followed,
            track,
        };
        let r = check(&cfg).with_context(|| format!("{} variant {v}", a.sensor))?;
        say!("{}", r.tsv_row(&a.sensor, v));
        if a.verbose {
            for e in &r.examples {
                say!("  {e}");
            }
        }
        lost += r.lost + r.uncalibrated;
        wrong += r.wrong;
    }
    if lost + wrong > 0 {
        note!("{lost} visible marker-frames lost or uncalibrated, {wrong} wrong identities");
    }
    Ok(())
}
