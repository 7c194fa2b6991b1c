//! What the slip detector adds to a live frame: `SlipMonitor::update` on a GelSight Mini's
//! 63 dots (7 × 9) and on a 331-pin TacTip's, the field's signals, the evidence and the score;
//! and what measuring the imprint's slide adds (`ImprintFollower::update`, a GelSight Mini's
//! 320 × 240 frame), for a detector fitted with `slip fit --imprint`.

use criterion::{criterion_group, criterion_main, Criterion};
use std::hint::black_box;
use visuotact_image::RgbImage;
use visuotact_pipeline::slip::{SlipDetector, SlipMonitor};
use visuotact_vision::imprint::{ImprintFollower, ImprintParams};

fn grid(rows: usize, cols: usize, pitch: f64) -> Vec<(f64, f64)> {
    (0..rows)
        .flat_map(|r| (0..cols).map(move |c| (pitch * c as f64, pitch * r as f64)))
        .collect()
}

fn slip(c: &mut Criterion) {
    for (name, rows, cols) in [("63 markers", 7, 9), ("331 markers", 19, 18)] {
        let markers = grid(rows, cols, 30.0);
        let mut m = SlipMonitor::new(SlipDetector::default(), &markers, 30.0);
        // A shaken field: every frame moves, one marker in ten missing.
        let frames: Vec<Vec<Option<(f64, f64)>>> = (0..50)
            .map(|k| {
                let s = (k as f64 * 0.4).sin();
                markers
                    .iter()
                    .enumerate()
                    .map(|(i, &(x, y))| (i % 10 != 3).then_some((s + 0.01 * x, 0.5 * s - 0.01 * y)))
                    .collect()
            })
            .collect();
        let mut k = 0;
        c.bench_function(&format!("slip monitor update, {name}"), |b| {
            b.iter(|| {
                k = (k + 1) % frames.len();
                black_box(m.update(black_box(&frames[k]), k as f64 / 25.0))
            });
        });
    }
}

/// A 320 × 240 frame: dark dots 40 px apart moved by `dots`, a bright imprint at `imprint`.
fn frame(dots: f64, imprint: f64) -> RgbImage {
    RgbImage::from_fn(320, 240, |x, y| {
        let (x, y) = (x as f64, y as f64);
        let (ix, iy) = ((x - 160.0 - imprint) / 50.0, (y - 120.0) / 50.0);
        let mut v = 100.0 + 60.0 * (-2.0 * (ix * ix + iy * iy)).exp();
        let (u, w) = (x - dots, y);
        let (du, dw) = (u - 40.0 * (u / 40.0).round(), w - 40.0 * (w / 40.0).round());
        if du * du + dw * dw < 36.0 {
            v -= 70.0;
        }
        let g = v as u8;
        [g, g, g]
    })
}

fn imprint(c: &mut Criterion) {
    let frames: Vec<RgbImage> = (0..10)
        .map(|k| frame(0.3 * f64::from(k), 0.8 * f64::from(k)))
        .collect();
    let mut f = ImprintFollower::new(ImprintParams::DEFAULT, 1);
    f.update(&frame(0.0, -1000.0));
    let mut k = 0;
    c.bench_function("imprint slide, 320 x 240", |b| {
        b.iter(|| {
            k = (k + 1) % frames.len();
            black_box(f.update(black_box(&frames[k])))
        });
    });
}

criterion_group!(benches, slip, imprint);
criterion_main!(benches);
