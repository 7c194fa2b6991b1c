//! filtfilt speed and agreement beside scipy: reads the peer's input and output
//! (`shared/peers/filtfilt_ref.py` → `$PEER_WORK/results/filtfilt_io.csv`), designs the same
//! 51-tap 5 Hz Hamming low-pass at 1 kHz, filters the 100 000 samples `REPEATS` times (default
//! 200, one thread) and prints the median time and the largest difference from scipy's output.
//!
//! `cargo run --release -p visuotact-signal --example filtfilt_speed [-- io.csv]`

use std::time::Instant;

use visuotact_signal::fir::{filtfilt_into, firwin, FiltFiltOptions, FiltFiltScratch, FirSpec};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args().nth(1).unwrap_or_else(|| {
        let work = std::env::var("PEER_WORK").unwrap_or_else(|_| "/tmp/visuotact-peers".into());
        format!("{work}/results/filtfilt_io.csv")
    });
    let text = std::fs::read_to_string(&path).map_err(|e| format!("{path}: {e}"))?;
    let (mut x, mut want) = (Vec::new(), Vec::new());
    for (i, line) in text.lines().enumerate().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != 3 {
            return Err(format!("{path}:{}: expected index,input,output", i + 1).into());
        }
        x.push(f[1].parse::<f64>()?);
        want.push(f[2].parse::<f64>()?);
    }
    let repeats: usize = std::env::var("REPEATS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(200);
    let b = firwin(&FirSpec::lowpass(51, 5.0, 1000.0))?;
    let (mut scratch, mut out) = (FiltFiltScratch::default(), Vec::new());
    let opt = FiltFiltOptions::default();
    filtfilt_into(&b, &[1.0], &x, &opt, &mut scratch, &mut out)?;
    let mut times: Vec<f64> = (0..repeats)
        .map(|_| {
            let t0 = Instant::now();
            filtfilt_into(&b, &[1.0], &x, &opt, &mut scratch, &mut out).unwrap();
            t0.elapsed().as_secs_f64() * 1e6
        })
        .collect();
    times.sort_by(f64::total_cmp);
    let dev = out
        .iter()
        .zip(&want)
        .map(|(p, q)| (p - q).abs())
        .fold(0.0, f64::max);
    println!(
        "visuotact filtfilt on {} samples, {} taps: median {:.1} us (min {:.1} us, {repeats} repeats); max |diff| vs scipy {dev:.3e}",
        x.len(),
        b.len(),
        times[times.len() / 2],
        times[0]
    );
    Ok(())
}
