//! The scorecard's real half holds its baseline: every real set under `shared/reference/real`
//! (a fifth of the TacTip sets' frames) tracked as a user would, with no more marker-frames
//! missing, no more 331-pin pins read apart at 128 × 128, and no fewer GelSight marker-frames
//! reported nor farther from the vendor's than the checked-in table allows
//! ([`REAL_TOLERANCE`]). Skipped when `../shared` is absent (a failure where
//! `VISUOTACT_REQUIRE_DATA` is set). Regenerate the table with
//! `visuotact check-tracking --real ../shared/reference/real --stride 5 >
//! testdata/scorecard/real.tsv` when a change is meant to move it, and say why in the commit.

use std::path::PathBuf;

use visuotact_experiments::realcard::{real_card, RealCard, RealCardConfig, REAL_TOLERANCE};

#[test]
fn real_card_holds_its_baseline() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/reference/real");
    if !dir.is_dir() {
        assert!(
            ["VISUOTACT_REQUIRE_DATA", "VISUOTACT_REQUIRE_REAL"]
                .iter()
                .all(|v| std::env::var_os(v).is_none_or(|x| x.is_empty() || x == "0")),
            "{} absent and VISUOTACT_REQUIRE_DATA set",
            dir.display()
        );
        eprintln!("skipping: {} not found", dir.display());
        return;
    }
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../testdata/scorecard/real.tsv"
    );
    let baseline = RealCard::from_tsv(&std::fs::read_to_string(path).unwrap(), path).unwrap();
    let card = real_card(
        &RealCardConfig {
            stride: 5,
            ..RealCardConfig::new(dir)
        },
        &mut |set| eprintln!("real card: {set}"),
    )
    .unwrap();
    eprintln!("{}", card.to_tsv());
    let worse = card.regressions(&baseline);
    assert!(
        worse.is_empty(),
        "worse than {path} (tolerance {REAL_TOLERANCE}): {worse:#?}"
    );
    // What the issue asks of real frames, whatever the baseline says: the 127-pin set read
    // from one in-contact frame misses at most 0.5 % of its pin-frames, the 331-pin set from
    // its shallowest frame at most 1 %, and the 9DTact grid is found whole.
    let share = |set: &str| {
        let row = &card.rows[set];
        row["missing"] as f64 / row["marker_frames"] as f64
    };
    assert!(share("tactip127 frame_0_0") <= 0.005);
    assert!(share("tactip331 shallowest") <= 0.01);
    let grid = &card.rows["9dtact sample"];
    assert_eq!((grid["markers"], grid["rows"], grid["cols"]), (63, 7, 9));
}
