//! `visuotact run`: live estimates from the simulator as JSON lines (contact and no contact,
//! latency, health), a UDP target that does not exist, the GelSight Mini video (no contact
//! before the press, contact during it), and the dashboard driven by headless Chromium.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

mod common;
use common::*;

/// A small IATS model: 150 random touches, 351 → 8 → 3.
fn iats_model(d: &Path) -> PathBuf {
    let (sess, _, _) = iats_features(d, "150", "1");
    ok(&vt(&[
        "train",
        "--features",
        s(&d.join("f.csv")),
        "--labels",
        s(&sess.join("labels.csv")),
        "--targets",
        "x_mm,y_mm,depth_mm",
        "--hidden",
        "8",
        // One network per file: the test below makes its own ensemble of two equal ones.
        "--ensemble",
        "1",
        "--drop-incomplete",
        "--sensor",
        s(&d.join("sensor.json")),
        "-o",
        s(&d.join("model.json")),
    ]));
    d.join("model.json")
}

/// Starts `visuotact run --model MODEL --source sim:iats --sim-frames 20 --serve 127.0.0.1:0
/// EXTRA…` and waits for the dashboard's address; returns the child, its standard error (for
/// the rest of the output) and `http://HOST:PORT/`.
fn serving(
    model: &Path,
    extra: &[&str],
) -> (
    std::process::Child,
    BufReader<std::process::ChildStderr>,
    String,
) {
    let mut args = vec![
        "run",
        "--model",
        s(model),
        "--source",
        "sim:iats",
        "--sim-frames",
        "20",
        "--quiet",
        "--serve",
        "127.0.0.1:0",
    ];
    args.extend_from_slice(extra);
    let mut child = Command::new(env!("CARGO_BIN_EXE_visuotact"))
        .args(&args)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut err = BufReader::new(child.stderr.take().unwrap());
    let url = word_after(&mut err, "dashboard on ");
    (child, err, url)
}

/// Reads standard error up to the line starting with `prefix`: the word after it.
fn word_after(err: &mut BufReader<std::process::ChildStderr>, prefix: &str) -> String {
    let mut line = String::new();
    loop {
        line.clear();
        assert!(err.read_line(&mut line).unwrap() > 0, "run ended early");
        if let Some(rest) = line.trim().strip_prefix(prefix) {
            return rest.split_whitespace().next().unwrap().to_string();
        }
    }
}

#[test]
fn simulated_touches_stream_as_json_lines_with_an_ensemble() {
    let d = fresh_dir("run-sim");
    // The same model twice is an ensemble of two: the networks' spread must be zero. (The
    // model's held-out table, which would state its held-out error instead, is taken out.)
    let mut model: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(iats_model(&d)).unwrap()).unwrap();
    assert!(model.as_object_mut().unwrap().remove("held_out").is_some());
    let m = d.join("model-networks-only.json");
    std::fs::write(&m, model.to_string()).unwrap();
    let o = vt(&[
        "run",
        "--model",
        s(&m),
        "--model",
        s(&m),
        "--source",
        "sim:iats",
        "--sim-frames",
        "20",
        "--fps",
        "50",
        "--max-frames",
        "60",
        // Paced, but a queue as long as the run: a loaded 2-core test machine that stalls the
        // estimator for two frame periods (the other tests run beside this one) drops nothing.
        "--queue",
        "60",
        "--udp",
        "127.0.0.1:9",
        "--summary",
        s(&d.join("summary.json")),
    ]);
    let err = ok(&o);
    let lines: Vec<serde_json::Value> = String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 60, "{err}");
    let contact: Vec<&serde_json::Value> = lines.iter().filter(|e| e["contact"] == true).collect();
    let free: Vec<&serde_json::Value> = lines.iter().filter(|e| e["contact"] == false).collect();
    // The simulated cycle is 40 % untouched (8 of 20 frames), then touches 1–5 mm deep.
    assert_eq!(free.len(), 24, "{err}");
    assert_eq!(contact.len(), 36);
    for e in &free {
        assert_eq!(e["targets"].as_array().unwrap().len(), 0);
    }
    for e in &contact {
        let t = e["targets"].as_array().unwrap();
        assert_eq!(t.len(), 3);
        assert_eq!(t[0]["name"], "x_mm");
        assert!(t[2]["std"].as_f64().unwrap() < 1e-9);
        let depth = t[2]["value"].as_f64().unwrap();
        assert!((0.0..6.0).contains(&depth), "{depth}");
    }
    assert_eq!(lines[0]["health"]["ok"], 117);
    assert!(lines
        .iter()
        .all(|e| e["latency_ms"].as_f64().unwrap() > 0.0));
    // Nobody listens on the discard port: the run goes on and counts what it could not send.
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["frames_estimated"], 60);
    assert!(summary["processing_ms_median"].as_f64().unwrap() > 0.0);
    assert!(err.contains("UDP errors"), "{err}");
    // Frames that come but cannot be estimated (1 × 1 pixels) are no result: an error naming
    // why, not "0 estimated" and exit 0.
    let tiny = d.join("tiny");
    std::fs::create_dir_all(&tiny).unwrap();
    for k in 0..3 {
        image::GrayImage::new(1, 1)
            .save(tiny.join(format!("f{k}.png")))
            .unwrap();
    }
    let err = fails(&vt(&["run", "--model", s(&m), "--source", s(&tiny)]));
    assert!(err.contains("none of the 3 frames"), "{err}");
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn gelsight_video_contact_only_during_the_press() {
    let Some(video) = shared_real("gelsight_mini/mini_example.avi") else {
        return;
    };
    let d = fresh_dir("run-gelsight");
    ok(&vt(&[
        "calibrate",
        s(&video),
        "--first",
        "10",
        "--preset",
        "dark-markers",
        "--keep-border",
        "-o",
        s(&d.join("gs.json")),
    ]));
    let o = vt(&[
        "run",
        "--sensor",
        s(&d.join("gs.json")),
        "--source",
        &format!("video:{}", video.display()),
        "--unpaced",
        "--queue",
        "1000",
        "--slip",
        "builtin",
    ]);
    ok(&o);
    let rows: Vec<serde_json::Value> = String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(rows.len(), 219);
    let first = rows.iter().position(|r| r["contact"] == true).unwrap();
    // The press starts near frame 57 (displacements jump from 0.3 to 7 px over 8 frames).
    assert!((50..=62).contains(&first), "first contact at frame {first}");
    let during = rows[70..].iter().filter(|r| r["contact"] == true).count();
    assert_eq!(during, rows.len() - 70);
    // All 80 markers are tracked before the press; during it a few top-row slivers leave the
    // image (they are cut by its border).
    assert!(rows[..first].iter().all(|r| r["health"]["ok"] == 80));
    assert!(rows
        .iter()
        .all(|r| r["health"]["ok"].as_u64().unwrap() >= 74));
    // `--slip builtin`: every estimate carries a slip state and score, and the field's signals
    // the detector read.
    assert!(rows.iter().all(|r| {
        let score = r["slip"]["score"].as_f64().unwrap();
        ["stick", "incipient", "slip"].contains(&r["slip"]["state"].as_str().unwrap())
            && (0.0..=1.0).contains(&score)
            && r["slip"]["field"]["nonrigid"]
                .as_f64()
                .is_some_and(f64::is_finite)
            && r["slip"]["field"]["shift_pitches"].as_f64().is_some()
    }));
    // Nothing slips before the press (13 of these 57 frames were `incipient` from the noise
    // at rest when the detector read frames without contact).
    assert!(rows[..first]
        .iter()
        .all(|r| r["slip"]["state"] == "stick" && r["slip"]["score"] == 0.0));
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn dashboard_in_headless_chromium() {
    let Some(chromium) = chromium() else {
        eprintln!("skipped: no chromium (scripts/test installs Debian's)");
        return;
    };
    let d = fresh_dir("run-dash");
    let m = iats_model(&d);
    let (mut child, _err, url) = serving(&m, &["--duration-s", "60"]);
    // The page's state as "SELFTEST|RECEIVED|STATUS|FRAMES", watched until the self-test ends.
    let state = headless_watch(
        chromium,
        &d.join("profile"),
        &format!("{url}?selftest=1"),
        "[document.body.dataset.selftest, document.body.dataset.received, \
         document.getElementById('status').textContent, document.body.dataset.frames].join('|')",
        |v| v.starts_with("ok|"),
        std::time::Duration::from_secs(45),
    );
    let _ = child.kill();
    let _ = child.wait();
    // The page loaded, received estimates over the WebSocket, drew them, pressed re-zero and
    // saw the estimator apply it.
    let parts: Vec<&str> = state.split('|').collect();
    assert_eq!(parts.len(), 4, "{state}");
    assert_eq!(parts[0], "ok", "{state}");
    assert!(parts[2].contains("re-zero 1 applied"), "{state}");
    let received: usize = parts[1].parse().unwrap();
    assert!(received >= 25, "{state}");
    // The frame view showed camera frames (each fetched once, when it was new).
    let frames: usize = parts[3].parse().unwrap_or(0);
    assert!(frames >= 1, "{state}");
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn slow_and_vanishing_websocket_clients_do_not_slow_the_estimator() {
    let d = fresh_dir("run-slow");
    let m = iats_model(&d);
    let summary = d.join("summary.json");
    let (mut child, mut err, url) = serving(
        &m,
        &[
            "--unpaced",
            "--max-frames",
            "12000",
            "--summary",
            s(&summary),
        ],
    );
    let addr = url
        .trim_start_matches("http://")
        .trim_end_matches('/')
        .to_string();
    // One client reads a message and then never again; another connects and drops at once.
    let (mut slow, _) = tungstenite::connect(format!("ws://{addr}/ws")).unwrap();
    let first = slow.read().unwrap();
    assert!(first.to_text().unwrap().contains("\"estimate\""));
    let (gone, _) = tungstenite::connect(format!("ws://{addr}/ws")).unwrap();
    drop(gone);
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut err, &mut rest).unwrap();
    assert!(child.wait().unwrap().success(), "{rest}");
    drop(slow);
    let sum: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    // Every frame was estimated (the queue is only dropped from when the estimator is behind),
    // and the slow client lost messages instead of holding the estimator up.
    assert_eq!(
        sum["frames_estimated"].as_u64().unwrap() + sum["frames_dropped"].as_u64().unwrap(),
        12000,
        "{sum}"
    );
    assert!(
        sum["websocket_messages_dropped"].as_u64().unwrap() > 0,
        "{sum}"
    );
    std::fs::remove_dir_all(&d).unwrap();
}

/// A run file in `d` with two simulated IATS sensors: `left` with model `m`, `right` with
/// `d/sensor.json` only.
fn two_sensor_plan(d: &Path, m: &Path) -> PathBuf {
    let plan = d.join("run.toml");
    std::fs::write(
        &plan,
        format!(
            "[[sensor]]\nname = \"left\"\nsource = \"sim:iats\"\nmodel = [{:?}]\n\n\
             [[sensor]]\nname = \"right\"\nsource = \"sim:iats\"\nsensor = {:?}\n",
            s(m),
            s(&d.join("sensor.json"))
        ),
    )
    .unwrap();
    plan
}

/// `run --sensors run.toml`: two simulated sensors (one with a model, one with contact and
/// health only) at 25 fps each in one run: no frame dropped, each sensor's JSON lines named
/// and numbered by its own source, never mixed, its own summary, and both namespaces in the
/// bag.
#[test]
fn two_sensors_in_one_run_keep_their_own_frames_outputs_and_summaries() {
    let d = fresh_dir("run-two");
    let m = iats_model(&d);
    let plan = two_sensor_plan(&d, &m);
    let (bag, summary) = (d.join("run.mcap"), d.join("summary.json"));
    let o = vt(&[
        "run",
        "--sensors",
        s(&plan),
        "--sim-frames",
        "20",
        "--fps",
        "25",
        "--max-frames",
        "50",
        // Slack for a loaded 2-core test machine (the other tests run beside this one).
        "--queue",
        "8",
        "--mcap",
        s(&bag),
        "--summary",
        s(&summary),
    ]);
    let err = ok(&o);
    let lines: Vec<serde_json::Value> = String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    for (k, name) in ["left", "right"].iter().enumerate() {
        let sum = &summary["sensors"][k];
        assert_eq!(sum["name"], *name);
        assert_eq!(sum["frames_captured"], 50, "{err}");
        assert_eq!(sum["frames_dropped"], 0, "{err}");
        assert_eq!(sum["frames_estimated"], 50, "{err}");
        let mine: Vec<&serde_json::Value> = lines.iter().filter(|e| e["sensor"] == *name).collect();
        let index: Vec<u64> = mine.iter().map(|e| e["index"].as_u64().unwrap()).collect();
        assert_eq!(index, (0..50).collect::<Vec<u64>>(), "{name}");
        assert!(mine
            .iter()
            .all(|e| e["health"]["ok"].as_u64().unwrap() > 100));
        // Only the left sensor has a model: targets on its touches, none on the right's.
        let with_targets = mine
            .iter()
            .filter(|e| !e["targets"].as_array().unwrap().is_empty())
            .count();
        if k == 0 {
            assert!(with_targets > 10, "{with_targets}");
        } else {
            assert_eq!(with_targets, 0);
            assert!(mine.iter().any(|e| e["contact"] == true));
        }
    }
    assert_eq!(lines.len(), 100);
    let bytes = std::fs::read(&bag).unwrap();
    // A channel's topic is written as its length (u32, little-endian), then its bytes.
    let has = |t: &str| {
        let mut key = u32::try_from(t.len()).unwrap().to_le_bytes().to_vec();
        key.extend_from_slice(t.as_bytes());
        bytes.windows(key.len()).any(|w| w == key)
    };
    for topic in [
        "/visuotact/left/contact",
        "/visuotact/left/markers",
        "/visuotact/right/markers",
        "/visuotact/right/contact/active",
    ] {
        assert!(has(topic), "{topic} not in the bag");
    }
    // The right sensor estimates nothing: no contact point of its own.
    assert!(!has("/visuotact/right/contact"));
    std::fs::remove_dir_all(&d).unwrap();
}

/// A run file that names one sensor twice, a name no topic can carry, or a misspelt key is
/// refused, naming the file.
#[test]
fn run_files_with_bad_sensor_names_or_keys_are_refused() {
    let d = fresh_dir("run-file-bad");
    let plan = d.join("run.toml");
    for (text, says) in [
        (
            "[[sensor]]\nname = \"a\"\nsource = \"sim:iats\"\n[[sensor]]\nname = \"a\"\nsource = \"sim:iats\"\n",
            "given twice",
        ),
        ("[[sensor]]\nname = \"left finger\"\nsource = \"sim:iats\"\n", "letters, digits and _"),
        ("[[sensor]]\nname = \"a\"\nsorce = \"sim:iats\"\n", "unknown field"),
    ] {
        std::fs::write(&plan, text).unwrap();
        let e = fails(&vt(&["run", "--sensors", s(&plan), "--max-frames", "2"]));
        assert!(e.contains(says) && e.contains("run.toml"), "{e}");
    }
    std::fs::remove_dir_all(&d).unwrap();
}

/// Little-endian CDR reader for the two messages the Foxglove test decodes; offsets count
/// from after the 4-byte encapsulation header, as CDR alignment does.
struct Cdr<'a>(&'a [u8], usize);

impl<'a> Cdr<'a> {
    fn new(data: &'a [u8]) -> Self {
        assert_eq!(&data[..2], &[0, 1], "CDR little-endian encapsulation");
        Cdr(&data[4..], 0)
    }
    fn take(&mut self, n: usize) -> &'a [u8] {
        self.1 = self.1.next_multiple_of(n.min(8));
        let out = &self.0[self.1..self.1 + n];
        self.1 += n;
        out
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take(4).try_into().unwrap())
    }
    fn f64(&mut self) -> f64 {
        f64::from_le_bytes(self.take(8).try_into().unwrap())
    }
    fn string(&mut self) -> String {
        let n = self.u32() as usize;
        let b = &self.0[self.1..self.1 + n];
        self.1 += n;
        String::from_utf8(b[..n - 1].to_vec()).unwrap()
    }
}

/// A message received from the Foxglove server: its topic, log time and CDR.
struct Received {
    topic: String,
    log_ns: u64,
    cdr: Vec<u8>,
}

/// Connects to a Foxglove WebSocket server at `url` as a client (the SDK's own protocol types),
/// subscribes to the channels of `wanted` (topic, schema) as they are advertised, checking their
/// encoding, and returns every message until the server closes.
fn foxglove_messages(url: &str, wanted: &[(&str, &str)]) -> Vec<Received> {
    use foxglove::ws_protocol::client::{Subscribe, Subscription};
    use foxglove::ws_protocol::server::ServerMessage;
    use foxglove::ws_protocol::JsonMessage;
    use tungstenite::client::IntoClientRequest;

    let mut request = url.into_client_request().unwrap();
    request
        .headers_mut()
        .insert("Sec-WebSocket-Protocol", "foxglove.sdk.v1".parse().unwrap());
    let (mut ws, _) = tungstenite::connect(request).unwrap();
    // Subscription k + 1 is `topics[k]`.
    let mut topics: Vec<String> = Vec::new();
    let mut got = Vec::new();
    let mut server_info = false;
    while let Ok(msg) = ws.read() {
        let parsed = match &msg {
            tungstenite::Message::Text(t) => ServerMessage::parse_json(t.as_str()),
            tungstenite::Message::Binary(b) => ServerMessage::parse_binary(b),
            _ => continue,
        };
        match parsed.unwrap() {
            ServerMessage::ServerInfo(_) => server_info = true,
            ServerMessage::Advertise(a) => {
                let mut subs = Vec::new();
                for c in &a.channels {
                    let Some((_, schema)) = wanted.iter().find(|w| w.0 == c.topic) else {
                        continue;
                    };
                    assert_eq!(c.schema_name, *schema);
                    assert_eq!(c.encoding, "cdr");
                    assert_eq!(c.schema_encoding.as_deref(), Some("ros2msg"));
                    // Every topic is advertised when the client connects.
                    assert!(got.is_empty(), "{} advertised after data", c.topic);
                    topics.push(c.topic.to_string());
                    let id = u32::try_from(topics.len()).unwrap();
                    // Said on failure: which channels were advertised when.
                    eprintln!(
                        "foxglove client: {} (channel {}) advertised after {} messages, subscribed as {id}",
                        c.topic,
                        c.id,
                        got.len()
                    );
                    subs.push(Subscription::new(id, c.id));
                }
                if !subs.is_empty() {
                    let text = Subscribe::new(subs).to_string();
                    ws.send(tungstenite::Message::Text(text.into())).unwrap();
                }
            }
            // The server makes every topic before a client can connect, so a subscription
            // sent at once finds each channel (foxglove 0.30 answers one to a channel made
            // while the client is connected with this status).
            ServerMessage::Status(st) if st.message.starts_with("Unknown channel ID: ") => {
                panic!("foxglove client: {}", st.message);
            }
            ServerMessage::MessageData(md) => got.push(Received {
                topic: topics[md.subscription_id as usize - 1].clone(),
                log_ns: md.log_time,
                cdr: md.data.into_owned(),
            }),
            _ => {}
        }
    }
    assert!(server_info, "no serverInfo from {url}");
    got
}

/// A decoded `geometry_msgs/msg/PointStamped` and its log time.
struct ContactPoint {
    log_ns: u64,
    stamp_ns: u64,
    frame: String,
    xyz_m: [f64; 3],
}

impl ContactPoint {
    fn decode(r: &Received) -> Self {
        let mut c = Cdr::new(&r.cdr);
        let (sec, nanosec) = (u64::from(c.u32()), u64::from(c.u32()));
        let frame = c.string();
        Self {
            log_ns: r.log_ns,
            stamp_ns: sec * 1_000_000_000 + nanosec,
            frame,
            xyz_m: [c.f64(), c.f64(), c.f64()],
        }
    }
}

/// `run --foxglove`: a WebSocket client speaking the Foxglove protocol subscribes to the
/// contact point and the contact rule, and every message it decodes equals the JSON line of
/// its frame: the stamp, the point in metres, the rule.
#[test]
fn foxglove_clients_receive_the_estimates_live() {
    let d = fresh_dir("run-foxglove");
    let m = iats_model(&d);
    let mut child = Command::new(env!("CARGO_BIN_EXE_visuotact"))
        .args([
            "run",
            "--model",
            s(&m),
            "--source",
            "sim:iats",
            "--sim-frames",
            "20",
            "--fps",
            "25",
            "--duration-s",
            "6",
            "--foxglove",
            "127.0.0.1:0",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut err = BufReader::new(child.stderr.take().unwrap());
    let url = word_after(&mut err, "foxglove: serving ");
    // Standard output is read on its own thread so that the run never blocks on it.
    let stdout = child.stdout.take().unwrap();
    let lines = std::thread::spawn(move || {
        BufReader::new(stdout)
            .lines()
            .map(|l| serde_json::from_str::<serde_json::Value>(&l.unwrap()).unwrap())
            .collect::<Vec<_>>()
    });
    let got = foxglove_messages(
        &url,
        &[
            ("/visuotact/contact", "geometry_msgs/msg/PointStamped"),
            ("/visuotact/contact/active", "std_msgs/msg/Bool"),
        ],
    );
    let status = child.wait().unwrap();
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut err, &mut rest).unwrap();
    assert!(status.success(), "{rest}");
    assert!(rest.contains("messages to Foxglove"), "{rest}");
    assert_foxglove_equals_lines(&got, &lines.join().unwrap());
    std::fs::remove_dir_all(&d).unwrap();
}

/// Every contact point and contact rule received over Foxglove equals the JSON line of its
/// frame (found by its stamp), and most frames were received.
fn assert_foxglove_equals_lines(got: &[Received], lines: &[serde_json::Value]) {
    let ns = |e: &serde_json::Value| (e["timestamp_s"].as_f64().unwrap() * 1e9).round() as u64;
    let target = |e: &serde_json::Value, name: &str| {
        e["targets"]
            .as_array()
            .unwrap()
            .iter()
            .find(|t| t["name"] == name)
            .map(|t| t["value"].as_f64().unwrap())
    };
    let points: Vec<ContactPoint> = got
        .iter()
        .filter(|g| g.topic == "/visuotact/contact")
        .map(ContactPoint::decode)
        .collect();
    let rules: Vec<&Received> = got
        .iter()
        .filter(|g| g.topic == "/visuotact/contact/active")
        .collect();
    assert!(points.len() >= 10, "{} contact points", points.len());
    assert!(rules.len() >= 50, "{} contact rules", rules.len());
    // The wall-clock origin of the stamps, from the first point and the line with its values.
    let p0 = &points[0];
    let first = lines
        .iter()
        .find(|e| {
            target(e, "x_mm") == Some(p0.xyz_m[0] * 1000.0)
                && target(e, "y_mm") == Some(p0.xyz_m[1] * 1000.0)
        })
        .expect("a JSON line with the first point's values");
    let origin = p0.log_ns - ns(first);
    let line_at = |t: u64| {
        lines
            .iter()
            .find(|e| ns(e) + origin == t)
            .unwrap_or_else(|| panic!("no JSON line stamped {t}"))
    };
    for p in &points {
        assert_eq!(p.stamp_ns, p.log_ns);
        assert_eq!(p.frame, "visuotact");
        let e = line_at(p.log_ns);
        assert_eq!(p.xyz_m[0], target(e, "x_mm").unwrap() / 1000.0);
        assert_eq!(p.xyz_m[1], target(e, "y_mm").unwrap() / 1000.0);
        assert_eq!(p.xyz_m[2], -target(e, "depth_mm").unwrap() / 1000.0);
    }
    for r in &rules {
        let e = line_at(r.log_ns);
        assert_eq!(r.cdr.len(), 5);
        assert_eq!(
            r.cdr[4] == 1,
            e["contact"].as_bool().unwrap(),
            "frame {}",
            e["index"]
        );
    }
    eprintln!(
        "foxglove: {} contact points and {} contact rules decoded, all equal to their JSON lines",
        points.len(),
        rules.len()
    );
}

/// A plain HTTP/1.1 GET on loopback: the response's head (status line and headers) and body.
fn http_get(addr: &str, path: &str) -> (String, Vec<u8>) {
    use std::io::{Read, Write};
    let mut c = std::net::TcpStream::connect(addr).unwrap();
    write!(
        c,
        "GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut all = Vec::new();
    c.read_to_end(&mut all).unwrap();
    let split = all.windows(4).position(|w| w == b"\r\n\r\n").unwrap();
    let head = String::from_utf8_lossy(&all[..split]).to_string();
    (head, all[split + 4..].to_vec())
}

/// `run --sensors … --serve`: one dashboard for both sensors. `/info` lists them with their
/// own targets, the WebSocket carries both sensors' estimates under their names (with the
/// markers once a client watches), and each sensor has its own latest frame.
#[test]
fn one_dashboard_shows_every_sensor_of_a_run_under_its_name() {
    let d = fresh_dir("run-two-dashboard");
    let m = iats_model(&d);
    let plan = two_sensor_plan(&d, &m);
    let mut child = Command::new(env!("CARGO_BIN_EXE_visuotact"))
        .args([
            "run",
            "--sensors",
            s(&plan),
            "--sim-frames",
            "20",
            "--fps",
            "25",
            "--duration-s",
            "6",
            "--quiet",
            "--serve",
            "127.0.0.1:0",
        ])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut err = BufReader::new(child.stderr.take().unwrap());
    let url = word_after(&mut err, "dashboard on ");
    let addr = url.trim_start_matches("http://").trim_end_matches('/');
    let (head, body) = http_get(addr, "/info");
    assert!(head.starts_with("HTTP/1.1 200"), "{head}");
    let info: serde_json::Value = serde_json::from_slice(&body).unwrap();
    let names: Vec<&str> = info["sensors"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["left", "right"]);
    assert_eq!(info["sensors"][0]["targets"].as_array().unwrap().len(), 3);
    assert!(info["sensors"][1]["targets"].as_array().unwrap().is_empty());
    let (mut ws, _) = tungstenite::connect(format!("ws://{addr}/ws")).unwrap();
    let mut seen = std::collections::BTreeMap::<String, usize>::new();
    for _ in 0..200 {
        let msg: serde_json::Value =
            serde_json::from_str(ws.read().unwrap().to_text().unwrap()).unwrap();
        if msg["markers"].is_array() {
            let name = msg["estimate"]["sensor"].as_str().unwrap().to_string();
            *seen.entry(name).or_default() += 1;
        }
        if seen.len() == 2 && seen.values().all(|&n| n >= 5) {
            break;
        }
    }
    assert_eq!(
        seen.keys().collect::<Vec<_>>(),
        ["left", "right"],
        "{seen:?}"
    );
    assert!(seen.values().all(|&n| n >= 5), "{seen:?}");
    for name in ["left", "right"] {
        let (head, body) = http_get(addr, &format!("/frame.jpg?after=0&sensor={name}"));
        assert!(head.starts_with("HTTP/1.1 200"), "{name}: {head}");
        assert!(
            head.contains("image/jpeg") && head.contains("x-frame"),
            "{head}"
        );
        assert_eq!(&body[..2], &[0xFF, 0xD8], "{name}: not a JPEG");
    }
    let (head, _) = http_get(addr, "/frame.jpg?sensor=middle");
    assert!(head.starts_with("HTTP/1.1 204"), "{head}");
    drop(ws);
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut err, &mut rest).unwrap();
    assert!(child.wait().unwrap().success(), "{rest}");
    std::fs::remove_dir_all(&d).unwrap();
}

/// `replay --live-rules` gives what `run` sent for the same frames: only the frames in contact
/// are estimated, from the same drifting baseline, to the last digit; plain `replay`
/// estimates every frame against the sensor's reference.
#[test]
fn replay_with_the_live_rules_gives_what_run_sent() {
    let d = fresh_dir("replay-live");
    let model = iats_model(&d);
    // Rest, touches, rest again: contact begins and ends, and the baseline follows the rest.
    let mixed = d.join("mixed");
    std::fs::create_dir_all(&mixed).unwrap();
    let pick = |from: &str, n: usize| -> Vec<PathBuf> {
        let mut v: Vec<PathBuf> = std::fs::read_dir(d.join("session").join(from))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "png"))
            .collect();
        v.sort();
        v.truncate(n);
        v
    };
    let (rest, touches) = (pick("reference", 7), pick("frames", 6));
    for (k, p) in rest[..4]
        .iter()
        .chain(&touches)
        .chain(&rest[4..])
        .enumerate()
    {
        std::fs::copy(p, mixed.join(format!("f{k:02}.png"))).unwrap();
    }
    let o = vt(&[
        "run",
        "--model",
        s(&model),
        "--source",
        s(&mixed),
        "--unpaced",
    ]);
    let err = ok(&o);
    let sent: Vec<serde_json::Value> = String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(sent.len(), 13, "{err}");
    let table = |extra: &[&str]| -> Vec<Vec<String>> {
        let out = d.join("replayed.csv");
        let mut args = vec![
            "replay",
            "--model",
            s(&model),
            s(&mixed),
            "-o",
            s(&out),
            "-q",
        ];
        args.extend_from_slice(extra);
        ok(&vt(&args));
        std::fs::read_to_string(&out)
            .unwrap()
            .lines()
            .skip(1)
            .map(|l| l.split(',').map(str::to_string).collect())
            .collect()
    };
    let live = table(&["--live-rules"]);
    assert_eq!(live.len(), 13);
    let mut in_contact = 0;
    for (row, e) in live.iter().zip(&sent) {
        assert_eq!(row[0], e["frame"].as_str().unwrap());
        let targets = e["targets"].as_array().unwrap();
        if targets.is_empty() {
            assert_eq!(row.last().unwrap(), "no contact", "{row:?} {e}");
            continue;
        }
        in_contact += 1;
        for (k, t) in targets.iter().enumerate() {
            let v: f64 = row[1 + k].parse().unwrap();
            assert_eq!(v, t["value"].as_f64().unwrap(), "{row:?} {e}");
        }
    }
    assert_eq!(in_contact, 6, "{live:?}");
    let every = table(&[]);
    assert!(
        every.iter().all(|r| r.last().unwrap().is_empty()),
        "{every:?}"
    );
}
