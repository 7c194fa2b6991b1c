//! Bounded fuzzing on stable Rust (proptest, seeded, a few hundred cases per parser): every
//! parser that takes outside bytes — force packets, CSV tables and force tables from disk, the
//! MJPEG stream splitter, the V4L2 format listing, raw YUYV and JPEG frames, `ffprobe`'s
//! answer and session descriptions — returns a value
//! or an error for any input, never panics, and keeps its promises on what it returns.

use std::path::Path;

use proptest::prelude::*;
use visuotact_io::camera::{parse_formats, rgb_from_mjpeg, rgb_from_yuyv, MjpegSplitter};
use visuotact_io::force::{plausible, ForceLayout, ForceTable};
use visuotact_io::frames::video_info_from_probe;
use visuotact_io::read::MAX_IMAGE_PIXELS;
use visuotact_io::session::SessionDescription;
use visuotact_io::table::KeyedTable;

/// The cases' seed: fixed, so every run (CI's too) tries the same cases, unless
/// `PROPTEST_RNG_SEED` names another one for a long run (docs/failure.md; proptest reads it).
fn seed() -> proptest::test_runner::RngSeed {
    use proptest::test_runner::RngSeed;
    match ProptestConfig::default().rng_seed {
        RngSeed::Random => RngSeed::Fixed(17),
        named => named,
    }
}

fn config() -> ProptestConfig {
    // 256 cases unless PROPTEST_CASES says otherwise (the long run: docs/failure.md).
    ProptestConfig {
        failure_persistence: None,
        rng_seed: seed(),
        ..ProptestConfig::default()
    }
}

/// Bytes biased towards what parsers look for: digits, separators, line ends, JPEG markers.
fn table_bytes() -> impl Strategy<Value = Vec<u8>> {
    let token = prop_oneof![
        Just(b"frame".to_vec()),
        Just(b"timestamp_s".to_vec()),
        Just(b"fz_n".to_vec()),
        Just(b",".to_vec()),
        Just(b"\n".to_vec()),
        Just(b"\r\n".to_vec()),
        Just(b"\"".to_vec()),
        Just(b"NaN".to_vec()),
        Just(b"1e308".to_vec()),
        Just(b"-0.5".to_vec()),
        prop::collection::vec(any::<u8>(), 0..4),
    ];
    prop::collection::vec(token, 0..60).prop_map(|t| t.concat())
}

fn tmp_file(bytes: &[u8]) -> std::path::PathBuf {
    static N: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let k = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let d = std::env::temp_dir().join(format!("visuotact-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let p = d.join(format!("t{k}.csv"));
    std::fs::write(&p, bytes).unwrap();
    p
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn force_packets(bytes in prop::collection::vec(any::<u8>(), 0..80)) {
        let layout = ForceLayout::default();
        if let Ok(s) = layout.decode(&bytes) {
            prop_assert!(s.timestamp_s.is_finite() && s.values.iter().all(|v| v.is_finite()));
            // What the receiver keeps is plausible; decoding alone promises finite numbers.
            let _ = plausible(&s);
        }
    }

    #[test]
    fn keyed_tables(bytes in table_bytes()) {
        let p = tmp_file(&bytes);
        if let Ok(t) = KeyedTable::read(&p, &["flags"]) {
            prop_assert_eq!(t.keys.len(), t.rows.len());
            prop_assert!(t.rows.iter().all(|r| r.len() == t.columns.len()));
            prop_assert!(t.rows.iter().flatten().all(|v| !v.is_infinite()));
        }
        std::fs::remove_file(&p).unwrap();
    }

    #[test]
    fn force_tables(bytes in table_bytes()) {
        let p = tmp_file(&bytes);
        if let Ok(t) = ForceTable::read(&p) {
            prop_assert_eq!(t.timestamp_s.len(), t.values.len());
            prop_assert!(t.timestamp_s.iter().all(|v| v.is_finite() && v.abs() <= 1e10));
        }
        std::fs::remove_file(&p).unwrap();
    }

    #[test]
    fn mjpeg_streams(chunks in prop::collection::vec(
        prop::collection::vec(prop_oneof![Just(0xFFu8), Just(0xD8), Just(0xD9), any::<u8>()], 0..64),
        0..32,
    )) {
        let mut s = MjpegSplitter::default();
        for c in &chunks {
            for f in s.push(c) {
                prop_assert!(f.len() >= 4);
                prop_assert_eq!(&f[..2], &[0xFF, 0xD8]);
                prop_assert_eq!(&f[f.len() - 2..], &[0xFF, 0xD9]);
                // Decoding junk is an error, never a panic.
                let _ = rgb_from_mjpeg(&f);
            }
        }
    }

    #[test]
    fn v4l2_format_listings(text in "(\\[[a-z0-9 @]*\\] )?[A-Za-z: ]*(mjpeg|yuyv422)?[ :A-Za-z-]*( [0-9]{0,6}x[0-9]{0,6})*") {
        for f in parse_formats(&text) {
            prop_assert!((1..=16384).contains(&f.width) && (1..=16384).contains(&f.height));
        }
    }

    #[test]
    fn yuyv_frames(bytes in prop::collection::vec(any::<u8>(), 0..256), w in 0usize..20, h in 0usize..20) {
        if let Ok(img) = rgb_from_yuyv(&bytes, w, h) {
            prop_assert_eq!((img.width(), img.height()), (w, h));
        }
    }

    #[test]
    fn video_probes(text in "((width|height|avg_frame_rate|r_frame_rate|nb_frames)=(-?[0-9]{0,21}(/[0-9]{0,4})?|N/A)\n){0,6}") {
        match video_info_from_probe(Path::new("v.mp4"), &text, "") {
            Ok(v) => {
                prop_assert!(v.width > 0 && v.height > 0);
                prop_assert!((v.width as u64) * (v.height as u64) <= MAX_IMAGE_PIXELS);
                prop_assert!(v.fps.is_finite() && v.fps > 0.0);
            }
            Err(e) => prop_assert!(e.to_string().contains("v.mp4")),
        }
    }

    #[test]
    fn session_descriptions(
        keys in prop::collection::vec(
            prop_oneof![
                Just("fps"), Just("source"), Just("complete"), Just("frames"),
                Just("started_unix_s"), Just("sensor_file"), Just("format"),
            ],
            0..6,
        ),
        values in prop::collection::vec(
            prop_oneof![
                Just("0"), Just("-1"), Just("25"), Just("1e300"), Just("true"), Just("null"),
                Just("\"x\""), Just("[1]"), Just("{}"), Just("\"visuotact-session\""),
            ],
            0..6,
        ),
        cut in 0usize..200,
    ) {
        let body: Vec<String> =
            keys.iter().zip(&values).map(|(k, v)| format!("\"{k}\":{v}")).collect();
        let text = format!("{{{}}}", body.join(","));
        let text = &text[..cut.min(text.len())];
        match SessionDescription::from_json(text, "s.json") {
            Ok(d) => {
                prop_assert!(d.fps.is_none_or(|f| f.is_finite() && f > 0.0));
                prop_assert!(d.started_unix_s.is_none_or(|t| t.is_finite() && t >= 0.0));
            }
            Err(e) => prop_assert!(e.to_string().starts_with("s.json: ")),
        }
    }
}

/// A stream that opens a frame and never closes it does not grow the splitter without bound.
#[test]
fn an_unterminated_mjpeg_frame_is_dropped() {
    let mut s = MjpegSplitter::default();
    s.push(&[0xFF, 0xD8]);
    let junk = vec![0u8; 1 << 20];
    for _ in 0..(MjpegSplitter::LARGEST >> 20) + 2 {
        assert!(s.push(&junk).is_empty());
    }
    assert_eq!(s.dropped, 1);
    let frame = [0xFF, 0xD8, 1, 2, 0xFF, 0xD9];
    assert_eq!(s.push(&frame), vec![frame.to_vec()]);
}
