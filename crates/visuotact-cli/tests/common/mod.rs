//! Helpers the command-line test binaries share: run `visuotact`, check its outcome, paths.
#![allow(dead_code)] // reason: each test binary uses its own subset of these helpers

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs the `visuotact` binary with `args`.
pub fn vt(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_visuotact"))
        .args(args)
        .output()
        .expect("run visuotact")
}

/// Asserts success; returns standard error.
pub fn ok(o: &Output) -> String {
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{err}");
    err
}

/// Asserts exit code 1 (a reported error); returns standard error.
pub fn fails(o: &Output) -> String {
    assert_eq!(
        o.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A path as an argument.
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A fresh, empty folder under the system's temporary folder, unique to this process.
pub fn fresh_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("visuotact-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Seed 000's simulated membrane under `touches` random touches (session seed `seed`) in
/// `dir/session`, calibrated into `dir/sensor.json` and extracted into `dir/f.csv`, all with
/// the defaults; returns (session, sensor file, feature table).
pub fn iats_features(dir: &Path, touches: &str, seed: &str) -> (PathBuf, PathBuf, PathBuf) {
    let (session, sensor, features) = (
        dir.join("session"),
        dir.join("sensor.json"),
        dir.join("f.csv"),
    );
    ok(&vt(&[
        "simulate",
        "--sensor",
        "iats",
        "--protocol",
        "random",
        "--touches",
        touches,
        "--seed",
        seed,
        "-o",
        s(&session),
    ]));
    ok(&vt(&[
        "calibrate",
        s(&session.join("reference")),
        "-o",
        s(&sensor),
    ]));
    ok(&vt(&[
        "extract",
        "--sensor",
        s(&sensor),
        s(&session.join("frames")),
        "-o",
        s(&features),
    ]));
    (session, sensor, features)
}
