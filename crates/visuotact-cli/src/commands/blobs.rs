//! `visuotact blobs`: the raw detection, one row per blob (no calibration needed).

use std::path::PathBuf;

use visuotact_io::frames::FrameStream;
use visuotact_io::table::TableFormat;
use visuotact_pipeline::extract::blobs_table;
use visuotact_vision::blobs::MomentConvention;
use visuotact_vision::detect::Detector;
use visuotact_vision::options::Purpose;

use crate::args::DetectorArgs;
use crate::progress::{pass_error, FramePass, Reporter};

#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Frames: image files, folders of images, or videos.
    #[arg(required = true)]
    frames: Vec<PathBuf>,
    /// Output table (`-` for standard output); one row per blob, `frame` repeated.
    #[arg(short, long)]
    output: PathBuf,
    #[command(flatten)]
    detector: DetectorArgs,
    /// Shape convention: pixel (scikit-image, OpenCV) or matlab (regionprops, +1/12).
    #[arg(long, default_value = "pixel", value_parser = crate::args::choice::<MomentConvention>(MomentConvention::NAMES))]
    moments: MomentConvention,
    /// Table format: csv or jsonl.
    #[arg(long, default_value = "csv", value_parser = crate::args::choice::<TableFormat>(TableFormat::NAMES))]
    format: TableFormat,
    /// No progress lines (by default one every 2 s on stderr, also when it is not a terminal).
    #[arg(long, short)]
    quiet: bool,
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    let inputs: Vec<&std::path::Path> = a.frames.iter().map(PathBuf::as_path).collect();
    visuotact_io::guard::refuse_output_over_input(&a.output, &inputs)?;
    // The pixel-mean centroid and whole-frame Otsu of OpenCV, scikit-image and MATLAB by
    // default.
    let (cfg, _, _) = a.detector.config_for_frames(Purpose::BlobAnalysis, || {
        FrameStream::open(&a.frames, 25.0)
            .ok()?
            .next()?
            .ok()
            .map(|f| f.image)
    })?;
    let mut det = Detector::new(cfg).map_err(anyhow::Error::msg)?;
    let conv = a.moments;
    let format = a.format;
    let reporter = Reporter::new(a.quiet);
    reporter.stage("blobs");
    let mut pass = FramePass::new(&reporter, usize::MAX);
    let done = blobs_table(&mut det, conv, &a.frames, (&a.output, format), &mut pass)
        .map_err(|e| pass_error(e, &a.output))?;
    note!(
        "{} frames, {} blobs, {} frames skipped",
        done.frames,
        done.blobs,
        done.skipped
    );
    if done.frames == 0 {
        anyhow::bail!("no frame could be read");
    }
    Ok(())
}
