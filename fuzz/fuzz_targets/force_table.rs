//! A force CSV: read or refused with the file's name, never a panic; what reads is consistent.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::Path;
use visuotact_io::force::ForceTable;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    match ForceTable::from_text(text, Path::new("fuzzed.csv")) {
        Ok(t) => {
            assert_eq!(t.timestamp_s.len(), t.values.len());
            assert!(t
                .timestamp_s
                .iter()
                .all(|v| v.is_finite() && v.abs() <= 1e10));
        }
        Err(e) => assert!(e.to_string().contains("fuzzed.csv"), "{e}"),
    }
});
