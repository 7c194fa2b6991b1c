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

/// `visuotact train` of `target` on the tables `features` and `labels` into `model`, one
/// network, with `extra` options.
pub fn train(features: &Path, labels: &Path, target: &str, model: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "train",
        "--features",
        s(features),
        "--labels",
        s(labels),
        "--targets",
        target,
        "--ensemble",
        "1",
        "-o",
        s(model),
    ];
    args.extend_from_slice(extra);
    vt(&args)
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
    Command::new(chromium)
        .args(chromium_args(profile, extra, url))
        .stderr(Stdio::null())
        .output()
        .expect("run chromium")
}

/// Headless Chromium's arguments: no sandbox, GPU, network chatter or first-run screens, the
/// profile in `profile`, then `extra` and `url`.
fn chromium_args(profile: &Path, extra: &[&str], url: &str) -> Vec<String> {
    let mut args: Vec<String> = [
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
    ]
    .map(String::from)
    .to_vec();
    args.push(format!("--user-data-dir={}", profile.display()));
    args.extend(extra.iter().map(|a| a.to_string()));
    args.push(url.to_string());
    args
}

/// Opens `url` in headless Chromium and evaluates the JavaScript expression `expr` (which must
/// give a string) in the page every 200 ms of real time, through the DevTools protocol, until
/// `done` holds for its value or `limit` passes; returns the last value. Real time, not
/// `--virtual-time-budget`: a page fed by a WebSocket sees as many messages as the server sent
/// in that time, however loaded the machine.
pub fn headless_watch(
    chromium: &str,
    profile: &Path,
    url: &str,
    expr: &str,
    done: impl Fn(&str) -> bool,
    limit: std::time::Duration,
) -> String {
    let _ = std::fs::remove_file(profile.join("DevToolsActivePort"));
    let mut browser = Command::new(chromium)
        .args(chromium_args(profile, &["--remote-debugging-port=0"], url))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("run chromium");
    let start = std::time::Instant::now();
    let mut last = String::new();
    let outcome = (|| -> Result<(), String> {
        let page = devtools_page(profile, start, limit)?;
        let (mut ws, _) = tungstenite::connect(page.as_str()).map_err(|e| e.to_string())?;
        for id in 1.. {
            let ask = serde_json::json!({
                "id": id,
                "method": "Runtime.evaluate",
                "params": {"expression": expr, "returnByValue": true},
            });
            ws.send(tungstenite::Message::text(ask.to_string()))
                .map_err(|e| e.to_string())?;
            // Events may come first; the answer carries our id.
            let reply = loop {
                let m = ws.read().map_err(|e| e.to_string())?;
                let Ok(v) = serde_json::from_str::<serde_json::Value>(m.to_text().unwrap_or(""))
                else {
                    continue;
                };
                if v["id"] == id {
                    break v;
                }
            };
            if let Some(v) = reply["result"]["result"]["value"].as_str() {
                last = v.to_string();
            }
            if done(&last) || start.elapsed() > limit {
                // Closed this way Chromium ends all its processes before it exits, so the
                // profile folder is no longer written once `wait` returns.
                let close = serde_json::json!({"id": 0, "method": "Browser.close"});
                let _ = ws.send(tungstenite::Message::text(close.to_string()));
                return Ok(());
            }
            std::thread::sleep(std::time::Duration::from_millis(200));
        }
        Ok(())
    })();
    // A browser that did not close within 10 s is killed.
    let closing = std::time::Instant::now();
    while matches!(browser.try_wait(), Ok(None)) && closing.elapsed().as_secs() < 10 {
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let _ = browser.kill();
    let _ = browser.wait();
    if let Err(e) = outcome {
        panic!("DevTools: {e} (last value {last:?})");
    }
    last
}

/// The DevTools WebSocket address of the page Chromium opened (from the port it writes into
/// its profile and its `/json/list`).
fn devtools_page(
    profile: &Path,
    start: std::time::Instant,
    limit: std::time::Duration,
) -> Result<String, String> {
    use std::io::{Read, Write};
    while start.elapsed() < limit {
        let port = std::fs::read_to_string(profile.join("DevToolsActivePort"))
            .ok()
            .and_then(|t| t.lines().next().and_then(|p| p.trim().parse::<u16>().ok()));
        if let Some(port) = port {
            if let Ok(mut tcp) = std::net::TcpStream::connect(("127.0.0.1", port)) {
                // HTTP/1.1 (Chromium drops 1.0 requests) on a connection it keeps open: the
                // body ends at its Content-Length.
                // The page addresses it answers are built from the Host header.
                let ask = format!("GET /json/list HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n");
                let _ = tcp.write_all(ask.as_bytes());
                let _ = tcp.set_read_timeout(Some(std::time::Duration::from_secs(2)));
                let mut bytes = Vec::new();
                let mut chunk = [0u8; 4096];
                let body = loop {
                    let text = String::from_utf8_lossy(&bytes).into_owned();
                    if let Some((head, body)) = text.split_once("\r\n\r\n") {
                        let length = head.lines().find_map(|l| {
                            let (k, v) = l.split_once(':')?;
                            k.eq_ignore_ascii_case("content-length")
                                .then(|| v.trim().parse::<usize>().ok())?
                        });
                        if length.is_some_and(|n| body.len() >= n) {
                            break body.to_string();
                        }
                    }
                    match tcp.read(&mut chunk) {
                        Ok(n) if n > 0 => bytes.extend_from_slice(&chunk[..n]),
                        _ => break String::new(),
                    }
                };
                let body = body.as_str();
                if let Ok(serde_json::Value::Array(targets)) = serde_json::from_str(body) {
                    if let Some(ws) = targets
                        .iter()
                        .find(|t| t["type"] == "page")
                        .and_then(|t| t["webSocketDebuggerUrl"].as_str())
                    {
                        return Ok(ws.to_string());
                    }
                }
            }
        }
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    Err("Chromium opened no page with a DevTools address in time".into())
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

/// Waits for `child` up to `limit_s` seconds; a child still running then is killed and the
/// test fails naming `what` (a hang fails instead of stalling the suite).
pub fn finished_within(mut child: std::process::Child, limit_s: u64, what: &str) -> Output {
    let start = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > std::time::Duration::from_secs(limit_s) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{what}: still running after {limit_s} s");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}
