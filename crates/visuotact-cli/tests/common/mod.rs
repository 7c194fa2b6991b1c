//! Helpers the command-line test binaries share: run `visuotact`, check its outcome, paths.
#![allow(dead_code)] // reason: each test binary uses its own subset of these helpers

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

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

/// The headless browser the test command installs (Debian's `chromium`), when there is one.
pub fn chromium() -> Option<&'static str> {
    ["chromium", "chromium-browser", "google-chrome"]
        .into_iter()
        .find(|c| {
            Command::new(c)
                .arg("--version")
                .output()
                .is_ok_and(|o| o.status.success())
        })
}

/// Runs `chromium` headless on `url` with a private profile under `profile` and no network
/// side traffic, `extra` flags before the address (e.g. `--dump-dom`).
pub fn headless(chromium: &str, profile: &Path, extra: &[&str], url: &str) -> Output {
    let profile = format!("--user-data-dir={}", profile.display());
    let mut args = vec![
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        profile.as_str(),
    ];
    args.extend_from_slice(extra);
    args.push(url);
    Command::new(chromium)
        .args(&args)
        .stderr(Stdio::null())
        .output()
        .expect("run chromium")
}

/// `rel` under the shared real frames (`../shared/reference/real`, not in the repository),
/// when present; its absence fails the test where `VISUOTACT_REQUIRE_DATA` (or `VISUOTACT_REQUIRE_REAL`) is set.
pub fn shared_real(rel: &str) -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/reference/real")
        .join(rel);
    if p.exists() {
        return Some(p);
    }
    assert!(
        ["VISUOTACT_REQUIRE_DATA", "VISUOTACT_REQUIRE_REAL"]
            .iter()
            .all(|v| std::env::var_os(v).is_none_or(|x| x.is_empty() || x == "0")),
        "{} absent and VISUOTACT_REQUIRE_DATA set",
        p.display()
    );
    eprintln!("skipping: {} absent", p.display());
    None
}
