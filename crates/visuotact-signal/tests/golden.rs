//! scipy `firwin`, `lfilter`, `lfilter_zi` and `filtfilt` reproduced to 1e−12 on
//! `testdata/reference/golden/scipy_firwin_filtfilt.json` (scipy 1.17.1, in the repository:
//! the test always runs).

use std::path::PathBuf;

use serde_json::Value;
use visuotact_signal::fir::{
    filtfilt, firwin, lfilter, lfilter_zi, FiltFiltOptions, FirSpec, PadLen, Padding, Window,
};

const TOL: f64 = 1e-12;

fn golden() -> Value {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../testdata/reference/golden/scipy_firwin_filtfilt.json");
    let text = std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    serde_json::from_str(&text).unwrap()
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

fn max_rel_diff(got: &[f64], want: &[f64]) -> f64 {
    assert_eq!(got.len(), want.len());
    let scale = want.iter().fold(1e-300f64, |m, v| m.max(v.abs()));
    got.iter()
        .zip(want)
        .map(|(g, w)| (g - w).abs() / scale)
        .fold(0.0, f64::max)
}

/// The design a golden `args` object describes.
fn spec_of(args: &Value) -> FirSpec {
    let cutoff = match &args["cutoff"] {
        Value::Array(_) => floats(&args["cutoff"]),
        c => vec![c.as_f64().unwrap()],
    };
    let window = match &args["window"] {
        Value::Null => Window::Hamming,
        Value::String(s) => Window::parse(s).unwrap(),
        Value::Array(a) => {
            assert_eq!(a[0], "kaiser");
            Window::Kaiser {
                beta: a[1].as_f64().unwrap(),
            }
        }
        other => panic!("window {other}"),
    };
    FirSpec {
        numtaps: args["numtaps"].as_u64().unwrap() as usize,
        cutoff,
        fs_hz: args["fs"].as_f64(),
        pass_zero: args["pass_zero"].as_bool().unwrap_or(true),
        window,
        scale: true,
    }
}

#[test]
fn firwin_designs() {
    let g = golden();
    let designs = g["firwin"].as_array().unwrap();
    assert_eq!(designs.len(), 8);
    for d in designs {
        let taps = firwin(&spec_of(&d["args"])).unwrap();
        let e = max_rel_diff(&taps, &floats(&d["taps"]));
        assert!(e < TOL, "{}: {e:e}", d["args"]);
    }
}

#[test]
fn filtfilt_cases() {
    let g = golden();
    let cases = g["filtfilt"].as_array().unwrap();
    assert_eq!(cases.len(), 10);
    let mut worst = 0.0f64;
    for c in cases {
        let x = floats(&g["signals"][c["signal"].as_str().unwrap()]["x"]);
        let fi = c["firwin_index"].as_u64().unwrap() as usize;
        let b = floats(&g["firwin"][fi]["taps"]);
        let a = [1.0];
        let name = format!("{} / firwin[{fi}]", c["signal"]);
        let check = |what: &str, got: &[f64], key: &str| {
            let e = max_rel_diff(got, &floats(&c[key]));
            assert!(e < TOL, "{name} {what}: {e:e}");
            e
        };
        worst = worst.max(check(
            "lfilter_zi",
            &lfilter_zi(&b, &a).unwrap(),
            "lfilter_zi",
        ));
        worst = worst.max(check(
            "lfilter",
            &lfilter(&b, &a, &x, None).unwrap().0,
            "lfilter",
        ));
        for (key, opt) in [
            ("filtfilt_default", FiltFiltOptions::default()),
            ("filtfilt_padlen_3nm1", FiltFiltOptions::MATLAB),
            (
                "filtfilt_padtype_even",
                FiltFiltOptions {
                    padding: Padding::Even,
                    padlen: PadLen::Scipy,
                },
            ),
            (
                "filtfilt_nopad",
                FiltFiltOptions {
                    padding: Padding::None,
                    padlen: PadLen::Scipy,
                },
            ),
        ] {
            worst = worst.max(check(key, &filtfilt(&b, &a, &x, &opt).unwrap(), key));
        }
    }
    eprintln!("worst relative difference over all filtfilt cases: {worst:.2e}");
}

#[test]
fn scipy_testsuite_iir_cases() {
    let g = golden();
    for (name, c) in g["scipy_testsuite_cases"].as_object().unwrap() {
        let y = filtfilt(
            &floats(&c["b"]),
            &floats(&c["a"]),
            &floats(&c["x"]),
            &FiltFiltOptions::default(),
        );
        let e = max_rel_diff(&y.unwrap(), &floats(&c["expected"]));
        eprintln!("{name}: {e:e}");
        assert!(e < 1e-10, "{name}: {e:e}");
    }
}
