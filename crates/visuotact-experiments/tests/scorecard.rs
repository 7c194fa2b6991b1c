//! The tracking scorecard holds its baseline: on seeds no other test uses, every family's drawn
//! variants through random, shear and drag (order-free and followed) have no more wrong
//! identities in any motion band than the checked-in table, and no more lost or ambiguous
//! marker-frames than it plus 0.2 % of the visible ones (at least two). Regenerate the table
//! with `visuotact check-tracking --scorecard --seed 101 > testdata/scorecard/zoo.tsv` when a
//! change is meant to move it, and say why in the commit.

use visuotact_experiments::scorecard::{scorecard, Scorecard, ScorecardConfig, BASELINE_TOLERANCE};

#[test]
fn scorecard_holds_its_baseline() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../testdata/scorecard/zoo.tsv"
    );
    let baseline = Scorecard::from_tsv(&std::fs::read_to_string(path).unwrap(), path).unwrap();
    let card = scorecard(&ScorecardConfig::default()).unwrap();
    eprintln!("{}", card.to_tsv());
    let worse = card.regressions(&baseline, BASELINE_TOLERANCE);
    assert!(worse.is_empty(), "worse than {path}: {worse:#?}");
    // The contract: no wrong identity in a frame moved under 1.5 pitches.
    for (name, bands) in &card.rows {
        let wrong: usize = bands[..3].iter().map(|b| b.wrong).sum();
        assert_eq!(wrong, 0, "{name}: wrong identities under 1.5 pitches");
    }
}

#[test]
fn a_scorecard_reads_back_what_it_writes() {
    let mut card = Scorecard::default();
    let mut bands = [visuotact_experiments::trackcheck::BandCounts::default(); 4];
    bands[2].visible = 120;
    bands[2].wrong = 1;
    bands[3].lost = 7;
    card.rows.insert("tactip followed".into(), bands);
    let back = Scorecard::from_tsv(&card.to_tsv(), "table").unwrap();
    assert_eq!(back, card);
    assert!(back.regressions(&card, 0.0).is_empty());
    let mut worse = card.clone();
    worse.rows.get_mut("tactip followed").unwrap()[2].wrong = 2;
    assert_eq!(worse.regressions(&card, 0.0).len(), 1);
    assert!(Scorecard::from_tsv("family\tband\nx\t<0.5\t1", "t").is_err());
}
