//! `visuotact slip fit | detect`: slip over time from the marker field of videos.

use std::path::PathBuf;

use visuotact_pipeline::slip::{
    cross_validate, cv_table, detect, evidence_of, fit_detector, fuse_grasps, fused_scores,
    grasps_of, labels_of, read_labels, sequences_in, track_sequences, verdicts_csv, Label, Scores,
    SlipConfig, SlipDetector, SlipSettings, SlipTruth, TrackedSequence,
};

use crate::progress::Reporter;

#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    #[command(subcommand)]
    which: Which,
}

#[derive(clap::Subcommand, Debug)]
enum Which {
    /// Fit a detector on labelled videos → slip.json (`--cv-by object`: held-out figures).
    Fit(FitArgs),
    /// Each video's verdict (`video,slip,onset_s,score`), or with `--frames` each frame's state.
    Detect(DetectArgs),
}

#[derive(clap::Args, Debug)]
struct Common {
    /// Videos, folders of images (one sequence each), or folders searched for both.
    #[arg(required = true)]
    videos: Vec<PathBuf>,
    /// Sensor file for every video (default: each calibrates from its first frames).
    #[arg(long)]
    sensor: Option<PathBuf>,
    /// Frames each video calibrates its reference from.
    #[arg(long, default_value_t = 5)]
    calibration_frames: usize,
    /// Track each frame from the last one's positions (as `extract --temporal`).
    #[arg(long)]
    temporal: bool,
    /// The videos in one folder are one grasp filmed by several sensors at once (a gripper's
    /// fingers): each takes the grasp's verdict, the sensors' scores fused (their log-odds add).
    #[arg(long)]
    grasp_per_folder: bool,
    /// Also measure the object's imprint sliding against the markers, an eleventh signal, on
    /// sensors whose image shows the imprint (GelSight-type); about half the tracking's
    /// time again. `detect` measures it whenever the detector reads it.
    #[arg(long)]
    imprint: bool,
    /// No progress lines.
    #[arg(long, short)]
    quiet: bool,
}

#[derive(clap::Args, Debug)]
struct FitArgs {
    #[command(flatten)]
    common: Common,
    /// CSV with columns `video,slip` (paths relative to the current folder, or absolute), and
    /// optionally `onset_s`: when each slip began (seconds; empty where not known).
    #[arg(long)]
    labels: PathBuf,
    /// Detector file to write.
    #[arg(short, long)]
    output: PathBuf,
    /// Also cross-validate leaving one value of this labels column out at a time (e.g. object).
    #[arg(long, value_name = "COLUMN")]
    cv_by: Option<String>,
    /// With --cv-by: write one row per video — its label, group, frames, held-out score and
    /// the 33 statistics the detector reads — to this CSV.
    #[arg(long, value_name = "FILE.csv", requires = "cv_by")]
    cv_table: Option<PathBuf>,
}

#[derive(clap::Args, Debug)]
struct DetectArgs {
    #[command(flatten)]
    common: Common,
    /// Detector file, or `builtin` (fitted on real GelSight Mini grasps).
    #[arg(long, default_value = "builtin")]
    detector: PathBuf,
    /// CSV to write.
    #[arg(short, long)]
    output: PathBuf,
    /// One row per frame instead of one per video.
    #[arg(long)]
    frames: bool,
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    match &a.which {
        Which::Fit(f) => fit(f),
        Which::Detect(d) => detect_videos(d),
    }
}

/// The videos' tracked markers (and the imprint's slide when `c.imprint` or `imprint`), with
/// progress lines.
fn tracked(c: &Common, imprint: bool) -> anyhow::Result<(Vec<PathBuf>, Vec<TrackedSequence>)> {
    let videos = sequences_in(&c.videos)?;
    let sensor = c.sensor.as_deref().map(crate::load_sensor).transpose()?;
    let cfg = SlipConfig {
        calibration_frames: c.calibration_frames.max(1),
        temporal: c.temporal,
        imprint: c.imprint || imprint,
    };
    let r = Reporter::new(c.quiet);
    r.stage("tracking");
    let seqs = track_sequences(&videos, sensor.as_ref(), &cfg, &|d, t| {
        r.items(d, Some(t), "videos")
    })?;
    Ok((videos, seqs))
}

fn fit(a: &FitArgs) -> anyhow::Result<()> {
    let videos = sequences_in(&a.common.videos)?;
    let labels = labels_of(
        &videos,
        &read_labels(&a.labels, a.cv_by.as_deref())?,
        &a.labels,
    )?;
    let (_, seqs) = tracked(&a.common, false)?;
    let like = SlipSettings::default();
    let y: Vec<SlipTruth> = labels.iter().map(Label::truth).collect();
    let ev: Vec<_> = seqs
        .iter()
        .zip(&y)
        .map(|(s, t)| evidence_of(s, &like, t.onset_s.filter(|_| t.slip)))
        .collect();
    let det = fit_detector(&ev, &y, &like)?;
    crate::write_atomically(&a.output, &det.to_json())?;
    let slips = y.iter().filter(|t| t.slip).count();
    note!(
        "fitted on {} videos ({slips} slip); wrote {}",
        y.len(),
        a.output.display()
    );
    if a.cv_by.is_some() {
        let groups: Vec<String> = labels
            .iter()
            .map(|l| l.group.clone().unwrap_or_default())
            .collect();
        let shipped = SlipDetector::try_default();
        let cv = cross_validate(&ev, &y, &groups, &like, shipped.as_ref())?;
        if let Some(p) = &a.cv_table {
            let rows: Vec<_> = videos
                .iter()
                .zip(&y)
                .zip(&groups)
                .zip(&seqs)
                .map(|(((v, t), g), s)| (v.as_path(), t, g.as_str(), s.frames.len()))
                .collect();
            crate::write_atomically(p, &cv_table(&rows, &cv, &ev))?;
        }
        say!(
            "cross-validated by {} ({} folds, {} videos):",
            a.cv_by.as_deref().unwrap_or(""),
            cv.folds,
            y.len()
        );
        say!("classifier\taccuracy\tbalanced_accuracy\tanswered");
        let line = |name: &str, s: Scores| {
            say!(
                "{name}\t{:.3}\t{:.3}\t{}",
                s.accuracy,
                s.balanced_accuracy,
                s.answered
            );
        };
        line("fitted detector (held out)", cv.fitted);
        line("largest mean displacement, threshold", cv.largest_shift);
        line("displacement entropy and its rate", cv.entropy);
        say!(
            "held-out no-slip grasps, every second: {:.1} % scored as slip",
            100.0 * cv.false_alarms
        );
        say!(
            "held-out grasps, their first {} frames: {:.1} % scored as slip",
            visuotact_pipeline::slip::START_FRAMES,
            100.0 * cv.start_alarms
        );
        if a.common.grasp_per_folder {
            line(
                "fitted detector, each folder's sensors fused (held out)",
                fused_scores(&cv, &y, &grasps_of(&videos), det.threshold),
            );
        }
        if let Some(s) = cv.default {
            line(
                "built-in detector (as shipped, fitted on the GelSight set)",
                s,
            );
        }
    }
    Ok(())
}

fn detect_videos(a: &DetectArgs) -> anyhow::Result<()> {
    let det = crate::load_slip(&a.detector)?;
    let (videos, seqs) = tracked(&a.common, det.reads_imprint())?;
    let mut each: Vec<_> = seqs.iter().map(|s| detect(s, &det)).collect();
    if a.common.grasp_per_folder {
        each = fuse_grasps(&each, &grasps_of(&videos), &det);
    }
    let verdicts: Vec<_> = videos
        .into_iter()
        .zip(&seqs)
        .zip(each)
        .map(|((v, s), d)| (v, s, d))
        .collect();
    let slips = verdicts.iter().filter(|(_, _, v)| v.slip).count();
    crate::write_atomically(&a.output, &verdicts_csv(&verdicts, a.frames))?;
    note!(
        "{} videos, {slips} slipping; wrote {}",
        verdicts.len(),
        a.output.display()
    );
    Ok(())
}
