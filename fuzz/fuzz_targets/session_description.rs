//! A `session.json`: read into its typed fields or refused naming the file, never a panic; a
//! description that reads has only possible values (a positive finite frame rate, a plausible
//! UNIX start).
#![no_main]

use libfuzzer_sys::fuzz_target;
use visuotact_io::session::SessionDescription;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    match SessionDescription::from_json(&text, "fuzzed.json") {
        Ok(d) => {
            assert!(d.fps.is_none_or(|f| f.is_finite() && f > 0.0));
            assert!(d.started_unix_s.is_none_or(|t| t.is_finite() && t >= 0.0));
            let _ = d.incomplete_note();
        }
        Err(e) => assert!(e.to_string().contains("fuzzed.json"), "{e}"),
    }
});
