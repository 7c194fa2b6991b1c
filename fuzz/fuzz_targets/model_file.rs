//! A model file: loaded or refused with the file's name, never a panic; one that loads
//! estimates from any row of its input width (or says why) with one finite value per target
//! (weights that overflow are refused as such, never an estimate of NaN or infinity).
#![no_main]

use libfuzzer_sys::fuzz_target;
use visuotact_nn::model::Model;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    match Model::from_json(&text, "fuzzed.json") {
        Ok(m) => {
            let n = m.feature_columns.len();
            for row in [vec![0.0; n], vec![1e300; n], vec![f64::NAN; n]] {
                if let Ok(e) = m.estimate(&row) {
                    assert_eq!(e.values.len(), m.target_columns.len());
                    assert!(e.values.iter().all(|v| v.is_finite()), "{:?}", e.values);
                }
            }
        }
        Err(e) => assert!(e.to_string().contains("fuzzed.json"), "{e}"),
    }
});
