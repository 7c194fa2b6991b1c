//! Fits all 27 NIST StRD nonlinear regression problems from both starting points and prints
//! the certified digits reached (log relative error of the parameters, worst one, and of the
//! residual sum of squares):
//! `cargo run --release -p visuotact-nn --example nist [-- DIR]`

use visuotact_nn::lm::{minimize, Control, LmConfig};
use visuotact_nn::nist::{certified_digits, Dataset, NistProblem};

fn main() {
    let dir = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "testdata/reference/nist_strd".into());
    let mut names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{dir}: {e}"))
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "dat"))
        .collect();
    names.sort();
    println!(
        "{:<10} {:>5} {:>6} {:>8} {:>8} {:>12}",
        "problem", "start", "iters", "params", "rss", "stop"
    );
    let mut four = 0;
    let mut total = 0;
    for path in names {
        let name = path
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("")
            .to_string();
        let text = std::fs::read_to_string(&path).expect("read");
        let data = Dataset::parse(&name, &text).expect("parse");
        for start in 0..2 {
            let mut prob = NistProblem::new(&data).expect("known model");
            let out = minimize(&mut prob, &data.starts[start], &LmConfig::PRECISE, |_| {
                Control::Continue
            });
            let lre_p = out
                .params
                .iter()
                .zip(&data.certified)
                .map(|(e, c)| certified_digits(*e, *c))
                .fold(f64::INFINITY, f64::min);
            let lre_r = certified_digits(out.cost, data.certified_rss);
            total += 1;
            if lre_p >= 4.0 && lre_r >= 4.0 {
                four += 1;
            }
            println!(
                "{name:<10} {:>5} {:>6} {lre_p:>8.1} {lre_r:>8.1} {:>12?}",
                start + 1,
                out.iterations,
                out.reason
            );
        }
    }
    println!("{four} of {total} fits reach 4+ certified digits in every parameter and the RSS");
}
