//! A feature or label table: read or refused with the file's name, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::Path;
use visuotact_io::table::KeyedTable;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    match KeyedTable::from_text(text, Path::new("fuzzed.csv"), &["flags"]) {
        Ok(t) => {
            assert_eq!(t.keys.len(), t.rows.len());
            assert!(t.rows.iter().all(|r| r.len() == t.columns.len()));
            assert!(t.rows.iter().flatten().all(|v| !v.is_infinite()));
        }
        Err(e) => assert!(e.to_string().contains("fuzzed.csv"), "{e}"),
    }
});
