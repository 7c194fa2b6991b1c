//! What the slip detector adds to a live frame: `SlipMonitor::update` on a GelSight Mini's
//! 63 dots (7 × 9) and on a 331-pin TacTip's, the field's signals, the evidence and the score.

use criterion::{criterion_group, criterion_main, Criterion};
use std::hint::black_box;
use visuotact_pipeline::slip::{SlipDetector, SlipMonitor};

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

criterion_group!(benches, slip);
criterion_main!(benches);
