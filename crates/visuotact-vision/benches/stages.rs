//! Criterion benches for each stage of the frame → features pipeline on a 640×480 frame with
//! 117 markers (the IATS test pattern, pressed and dragged).

#![allow(
    clippy::too_many_lines,
    reason = "one benchmark group per pipeline stage, set up on the same frames"
)]

use criterion::{criterion_group, criterion_main, Criterion};
use std::hint::black_box;
use visuotact_image::GrayImage;
use visuotact_sim::pattern::{render_grid, GridPattern, Press};
use visuotact_vision::blobs::{blobs_from_gray_into, BlobScratch, Connectivity, Level, Region};
use visuotact_vision::calibration::{calibrate, track_reference, CalibrationConfig, Preset};
use visuotact_vision::detect::{Detector, DetectorConfig};
use visuotact_vision::features::{FeatureExtractor, FeatureSet, FrameFeatures};
use visuotact_vision::layout::LayoutChoice;
use visuotact_vision::preprocess::{
    gray_from_rgb_into, histogram, histogram_of, morphology_in_place, open3_from_rgb_into,
    otsu_level, Channel, HistogramPixels, MorphScratch, Open3Scratch, PreprocessConfig,
};
use visuotact_vision::track::{track, TrackParams};

fn stages(c: &mut Criterion) {
    let pattern = GridPattern::IATS;
    let rest = render_grid(&pattern, None, 1).0;
    let press = Press {
        x_px: 300.0,
        y_px: 220.0,
        sigma_px: 80.0,
        push_px: 5.0,
        shear_x_px: 20.0,
        shear_y_px: -10.0,
        grow: 0.2,
        stretch: 0.15,
    };
    let img = render_grid(&pattern, Some(&press), 2).0;
    let det_cfg = DetectorConfig {
        preprocess: PreprocessConfig::IATS,
        ..Default::default()
    };
    let (cal, _) = calibrate(
        [("rest", &rest)],
        &CalibrationConfig {
            detector: det_cfg.clone(),
            layout: LayoutChoice::Auto,
            features: FeatureSet::IATS,
            ..Default::default()
        },
    )
    .unwrap();

    let mut gray = GrayImage::new(0, 0);
    c.bench_function("green_channel", |b| {
        b.iter(|| gray_from_rgb_into(black_box(&img), Channel::Green, false, &mut gray))
    });
    c.bench_function("luma601", |b| {
        b.iter(|| gray_from_rgb_into(black_box(&img), Channel::Luma601, false, &mut gray))
    });
    gray_from_rgb_into(&img, Channel::Green, false, &mut gray);
    let mut opened = gray.clone();
    let mut ms = MorphScratch::default();
    c.bench_function("open_3x3", |b| {
        b.iter(|| {
            opened.as_mut_slice().copy_from_slice(gray.as_slice());
            morphology_in_place(&mut opened, &PreprocessConfig::IATS, &mut ms);
        })
    });
    // What the detector runs by default: green channel, 3 × 3 opening and the sampled
    // histogram in one streaming pass.
    let (mut fused, mut o3) = (GrayImage::new(0, 0), Open3Scratch::default());
    let mut hist = [0u32; 256];
    c.bench_function("green_open_3x3_eighth_histogram", |b| {
        b.iter(|| {
            open3_from_rgb_into(
                black_box(&img),
                Channel::Green,
                false,
                &mut fused,
                Some((&mut hist, HistogramPixels::Eighth)),
                &mut o3,
            )
        })
    });
    // The same on frames out of cache, as a camera delivers them: 48 distinct frames (44 MB)
    // in turn.
    let frames: Vec<_> = (0..48u64)
        .map(|k| render_grid(&pattern, Some(&press), 100 + k).0)
        .collect();
    let mut next = 0;
    c.bench_function("green_open_3x3_eighth_histogram_cold", |b| {
        b.iter(|| {
            next = (next + 1) % frames.len();
            open3_from_rgb_into(
                black_box(&frames[next]),
                Channel::Green,
                false,
                &mut fused,
                Some((&mut hist, HistogramPixels::Eighth)),
                &mut o3,
            )
        })
    });
    let mut picked = GrayImage::new(0, 0);
    c.bench_function("green_channel_cold", |b| {
        b.iter(|| {
            next = (next + 1) % frames.len();
            gray_from_rgb_into(black_box(&frames[next]), Channel::Green, false, &mut picked)
        })
    });
    c.bench_function("histogram_otsu", |b| {
        b.iter(|| otsu_level(&histogram(black_box(opened.as_slice()))))
    });
    c.bench_function("histogram_eighth_otsu", |b| {
        b.iter(|| otsu_level(&histogram_of(black_box(&opened), HistogramPixels::Eighth)))
    });
    // One marker's grey-centroid window: 20 × 20 pixels, the ellipse of a marker ~17 px wide.
    let window = visuotact_vision::kernels::EllipseWindow {
        dx0: -9.6,
        dy0: -9.4,
        q11: 1.0 / 81.0,
        q12: 0.0005,
        q22: 1.0 / 79.0,
        p0: 60.0,
        sx: 0.3,
        sy: -0.2,
    };
    let at = 200 * 640 + 280;
    c.bench_function("grey_window_sums_20x20", |b| {
        b.iter(|| {
            visuotact_vision::kernels::ellipse_window_sums(
                black_box(&opened.as_slice()[at..]),
                640,
                20,
                20,
                window,
            )
        })
    });
    let t = otsu_level(&histogram(opened.as_slice()));
    let mut bs = BlobScratch::default();
    let mut blobs = Vec::new();
    c.bench_function("fused_label_moments", |b| {
        b.iter(|| {
            blobs_from_gray_into(
                black_box(&opened),
                Level::Scalar(t),
                Region::default(),
                Connectivity::Eight,
                &mut bs,
                &mut blobs,
            )
        })
    });
    c.bench_function("fused_on_empty_frame", |b| {
        b.iter(|| {
            blobs_from_gray_into(
                black_box(&opened),
                Level::Scalar(255),
                Region::default(),
                Connectivity::Eight,
                &mut bs,
                &mut blobs,
            )
        })
    });
    let mut det = Detector::new(det_cfg).unwrap();
    let mut found = Vec::new();
    c.bench_function("detect_total", |b| {
        b.iter(|| det.detect_into(black_box(&img), &mut found))
    });
    // What `calibrate` configures by default: sampled Otsu, grey-level centroids.
    let mut grey = Detector::new(Preset::Iats.config().detector).unwrap();
    c.bench_function("detect_total_iats_preset", |b| {
        b.iter(|| grey.detect_into(black_box(&img), &mut found))
    });
    // Blobs of the pressed frame, whether or not `detect_total` ran in this invocation.
    det.detect_into(&img, &mut found);
    let reference = track_reference(&cal);
    c.bench_function("track_117", |b| {
        b.iter(|| {
            track(
                black_box(&reference),
                black_box(&found),
                &TrackParams::DEFAULT,
            )
        })
    });
    let mut ex = FeatureExtractor::new(cal, FeatureSet::IATS).unwrap();
    let mut out = FrameFeatures::default();
    c.bench_function("frame_to_features", |b| {
        b.iter(|| ex.extract_into(black_box(&img), &mut out).unwrap())
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30).warm_up_time(std::time::Duration::from_millis(500)).measurement_time(std::time::Duration::from_secs(2));
    targets = stages
}
criterion_main!(benches);
