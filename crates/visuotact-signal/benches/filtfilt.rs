//! filtfilt of 100 000 samples with a 51-tap low-pass (the peer's case, shared/peers/filtfilt_ref.py).

use criterion::{criterion_group, criterion_main, Criterion};
use visuotact_signal::fir::{filtfilt_into, firwin, FiltFiltOptions, FiltFiltScratch, FirSpec};

fn bench(c: &mut Criterion) {
    let b = firwin(&FirSpec::lowpass(51, 5.0, 1000.0)).unwrap();
    let x: Vec<f64> = (0..100_000)
        .map(|i| (i as f64 * 0.003).sin() + 0.05 * ((i * 7919 % 1009) as f64 / 1009.0 - 0.5))
        .collect();
    let mut scratch = FiltFiltScratch::default();
    let mut out = Vec::new();
    c.bench_function("filtfilt 100k x 51 taps", |bch| {
        bch.iter(|| {
            filtfilt_into(
                &b,
                &[1.0],
                &x,
                &FiltFiltOptions::default(),
                &mut scratch,
                &mut out,
            )
            .unwrap();
            out[0]
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
