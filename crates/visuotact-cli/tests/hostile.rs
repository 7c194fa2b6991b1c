//! Hostile inputs (issue 15): every case exits with a reported error (code 1, never a panic's
//! 101), names what is wrong, creates nothing it should not and changes no input.

mod common;

use common::{fails, fresh_dir, s, vt};

/// `run`'s and `record`'s durations, rates and counts are checked before anything starts:
/// negative, NaN and astronomically large values were panics in `Duration::from_secs_f64`.
#[test]
fn durations_rates_and_counts_are_checked_first() {
    let d = fresh_dir("hostile-durations");
    for bad in ["-1", "NaN", "1e300"] {
        let arg = format!("--duration-s={bad}");
        let err = fails(&vt(&[
            "run",
            "--source",
            "sim:iats",
            "--sensor",
            "none.json",
            &arg,
        ]));
        // Checked before any file is read.
        assert!(err.contains("duration_s"), "{bad}: {err}");
    }
    let session = d.join("rec");
    for (flag, bad, names) in [
        ("--sync-every-s", "1e300", "sync_every_s"),
        ("--duration-s", "-1", "duration_s"),
        ("--duration-s", "NaN", "duration_s"),
        ("--fps", "0", "fps"),
        ("--fps", "1e-300", "fps"),
        ("--force-rate-hz", "inf", "force_rate_hz"),
        ("--max-frames", "0", "max_frames"),
    ] {
        let arg = format!("{flag}={bad}");
        let err = fails(&vt(&[
            "record",
            "--source",
            "sim:iats",
            "-o",
            s(&session),
            &arg,
        ]));
        assert!(err.contains(names), "{flag} {bad}: {err}");
        // Nothing was created: the corrected run is not refused as "already holds a session".
        assert!(!session.exists(), "{flag} {bad} left {}", session.display());
    }
    std::fs::remove_dir_all(&d).unwrap();
}

/// A busy force port or a bad force table is reported before the session folder exists.
#[test]
fn force_sources_are_opened_before_the_session_folder() {
    let d = fresh_dir("hostile-force");
    let busy = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let port = busy.local_addr().unwrap().port();
    let session = d.join("rec");
    let udp = format!("udp:127.0.0.1:{port}");
    let err = fails(&vt(&[
        "record",
        "--source",
        "sim:iats",
        "--force",
        &udp,
        "-o",
        s(&session),
    ]));
    assert!(err.contains(&port.to_string()), "{err}");
    assert!(!session.exists());
    let table = d.join("force.csv");
    std::fs::write(&table, "timestamp_s,fx_n\n0.0,1.0\n0.1,abc\n").unwrap();
    let csv = format!("csv:{}", table.display());
    let err = fails(&vt(&[
        "record",
        "--source",
        "sim:iats",
        "--force",
        &csv,
        "-o",
        s(&session),
    ]));
    assert!(err.contains("line 3, column `fx_n`"), "{err}");
    assert!(!session.exists());
    assert_eq!(
        std::fs::read_to_string(&table).unwrap(),
        "timestamp_s,fx_n\n0.0,1.0\n0.1,abc\n"
    );
    std::fs::remove_dir_all(&d).unwrap();
}

/// Doing nothing is not success: a source with no readable frame fails `run` and `record`.
#[test]
fn nothing_done_is_an_error() {
    let d = fresh_dir("hostile-nothing");
    let frames = d.join("frames");
    std::fs::create_dir_all(&frames).unwrap();
    std::fs::write(frames.join("a.png"), b"\x89PNG not really").unwrap();
    let err = fails(&vt(&[
        "record",
        "--source",
        s(&frames),
        "-o",
        s(&d.join("rec")),
    ]));
    assert!(err.contains("nothing recorded"), "{err}");
    assert!(
        err.contains("a.png"),
        "the unreadable frame is named: {err}"
    );
    std::fs::remove_dir_all(&d).unwrap();
}
