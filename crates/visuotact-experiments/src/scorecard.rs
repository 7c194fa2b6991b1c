//! The tracking scorecard: the simulator's zoo tracked against its truth, wrong / lost /
//! ambiguous marker-frames per sensor family × motion band, and a baseline to hold it to
//! (`visuotact check-tracking --scorecard`, test `scorecard_holds_its_baseline`).
//!
//! Every family is run with drawn variants (never the preset the code was written on) through
//! the `random`, `shear` and `drag` protocols order-free, and the `drag` protocol followed
//! (each touch built up in six frames), for each seed; the domes also through `plate` (a flat
//! plate tilted up to 25° and slid up to two pitches) against a reference that is itself such
//! a press (rows `… plate`). A frame's band is the largest true motion
//! of a visible marker in it: under 0.5, 0.5–1, 1–1.5 and over 1.5 pitches
//! ([`MOTION_BANDS`](crate::trackcheck::MOTION_BANDS)).

use std::collections::BTreeMap;
use std::fmt::Write as _;

use visuotact_sim::protocol::zoo_plate;
use visuotact_sim::zoo::ZooTouch;
use visuotact_vision::track::TrackParams;

use crate::trackcheck::{check, BandCounts, CheckConfig, CheckError, SimSensor};

/// What a scorecard runs.
#[derive(Clone, Debug)]
pub struct ScorecardConfig {
    /// Seeds of the touches and noise; each family's variants are drawn from them too.
    pub seeds: Vec<u64>,
    /// Touches per run.
    pub touches: usize,
    /// The tracker's settings.
    pub track: TrackParams,
}

impl Default for ScorecardConfig {
    fn default() -> Self {
        Self {
            seeds: vec![101, 102],
            touches: 20,
            track: TrackParams::DEFAULT,
        }
    }
}

/// Why a scorecard could not be read or run.
#[derive(Debug, thiserror::Error)]
pub enum ScorecardError {
    /// A baseline table line that does not parse.
    #[error("{source_name} line {line}: expected family, band and five counts")]
    Table {
        /// The table's name (its file).
        source_name: String,
        /// The 1-based line.
        line: usize,
    },
    /// The baseline file could not be read.
    #[error("reading the baseline {path}: {source}")]
    Read {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// A check failed.
    #[error(transparent)]
    Check(#[from] CheckError),
}

/// One run of the scorecard: family, variant, protocol, followed steps.
type Case = (&'static str, u64, &'static str, usize);

/// The runs for `seed`: per family two drawn variants (from the seed), each through the
/// order-free protocols and the followed drag.
fn cases(seed: u64) -> Vec<Case> {
    let mut out = Vec::new();
    for (family, variants) in [
        ("tactip", 8),
        ("tactip-small", 5),
        ("gelsight", 3),
        ("dots", 5),
        ("iats", 0),
    ] {
        let picks: Vec<u64> = if variants == 0 {
            vec![0]
        } else {
            vec![1 + seed % variants, 1 + (seed / 3 + 1) % variants]
        };
        for v in &picks {
            for protocol in ["random", "shear", "drag"] {
                if family == "iats" && protocol == "drag" {
                    continue;
                }
                out.push((family, *v, protocol, 0));
            }
            if family != "iats" {
                out.push((family, *v, "drag", 6));
            }
        }
        if family.starts_with("tactip") {
            for v in &picks {
                out.push((family, *v, "plate", 0));
            }
        }
    }
    out.dedup();
    out
}

/// Counts per family (`tactip`, …, with ` followed` for the followed runs) and band.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Scorecard {
    /// Rows in name order.
    pub rows: BTreeMap<String, [BandCounts; 4]>,
}

/// The band names, in order.
pub const BAND_NAMES: [&str; 4] = ["<0.5", "0.5-1", "1-1.5", ">1.5"];

impl Scorecard {
    /// The table, tab-separated: family, band, frames, visible, wrong, lost, ambiguous.
    pub fn to_tsv(&self) -> String {
        let mut out = String::from("family\tband\tframes\tvisible\twrong\tlost\tambiguous\n");
        for (name, bands) in &self.rows {
            for (b, c) in bands.iter().enumerate() {
                let _ = writeln!(
                    out,
                    "{name}\t{}\t{}\t{}\t{}\t{}\t{}",
                    BAND_NAMES[b], c.frames, c.visible, c.wrong, c.lost, c.ambiguous
                );
            }
        }
        out
    }

    /// Reads a table written by [`Scorecard::to_tsv`] (`source_name` names it in errors).
    pub fn from_tsv(text: &str, source_name: &str) -> Result<Self, ScorecardError> {
        let mut rows: BTreeMap<String, [BandCounts; 4]> = BTreeMap::new();
        for (n, line) in text.lines().enumerate().skip(1) {
            if line.trim().is_empty() {
                continue;
            }
            let f: Vec<&str> = line.split('\t').collect();
            let bad = || ScorecardError::Table {
                source_name: source_name.to_string(),
                line: n + 1,
            };
            if f.len() != 7 {
                return Err(bad());
            }
            let band = BAND_NAMES.iter().position(|b| *b == f[1]).ok_or_else(bad)?;
            let num = |k: usize| f[k].parse::<usize>().map_err(|_| bad());
            let c = BandCounts {
                frames: num(2)?,
                visible: num(3)?,
                wrong: num(4)?,
                lost: num(5)?,
                ambiguous: num(6)?,
            };
            rows.entry(f[0].to_string()).or_default()[band] = c;
        }
        Ok(Self { rows })
    }

    /// Where this scorecard is worse than `baseline`: a cell with more wrong identities, or
    /// more lost and ambiguous marker-frames by over `tolerance` of its visible ones (and at
    /// least two), one line each.
    pub fn regressions(&self, baseline: &Scorecard, tolerance: f64) -> Vec<String> {
        let mut out = Vec::new();
        for (name, bands) in &self.rows {
            let Some(base) = baseline.rows.get(name) else {
                out.push(format!("{name}: not in the baseline"));
                continue;
            };
            for (b, (c, o)) in bands.iter().zip(base).enumerate() {
                if c.wrong > o.wrong {
                    out.push(format!(
                        "{name} {}: {} wrong identities, baseline {}",
                        BAND_NAMES[b], c.wrong, o.wrong
                    ));
                }
                let missing = c.lost + c.ambiguous;
                let allowed = (o.lost + o.ambiguous)
                    + ((tolerance * c.visible as f64).ceil() as usize).max(2);
                if missing > allowed {
                    out.push(format!(
                        "{name} {}: {missing} lost or ambiguous of {} visible, baseline {}",
                        BAND_NAMES[b],
                        c.visible,
                        o.lost + o.ambiguous
                    ));
                }
            }
        }
        out
    }
}

/// How much more lost and ambiguous a cell may have than its baseline: 0.2 % of its visible
/// marker-frames (at least two).
pub const BASELINE_TOLERANCE: f64 = 0.002;

/// The scorecard of seeds `seed` and `seed + 1` with `track`, as a table, and where it is
/// worse than `baseline` by over [`BASELINE_TOLERANCE`] (what `check-tracking --scorecard`
/// prints).
pub fn scorecard_table(
    seed: u64,
    track: TrackParams,
    baseline: Option<&std::path::Path>,
) -> Result<(String, Vec<String>), ScorecardError> {
    let card = scorecard(&ScorecardConfig {
        seeds: vec![seed, seed + 1],
        track,
        ..Default::default()
    })?;
    let worse = match baseline {
        Some(path) => {
            let name = path.display().to_string();
            let text = std::fs::read_to_string(path).map_err(|source| ScorecardError::Read {
                path: name.clone(),
                source,
            })?;
            card.regressions(&Scorecard::from_tsv(&text, &name)?, BASELINE_TOLERANCE)
        }
        None => Vec::new(),
    };
    Ok((card.to_tsv().trim_end().to_string(), worse))
}

/// The reference of a `plate` run: itself a plate press drawn from `seed` (as a sensor that is
/// never out of contact is calibrated); `None` (rest) for every other protocol and for a
/// sensor that is no dome. `check-tracking --reference-pressed` runs one such case alone.
pub fn touched_reference(sensor: &SimSensor, protocol: &str, seed: u64) -> Option<ZooTouch> {
    match sensor {
        SimSensor::Zoo(cfg) if protocol == "plate" => {
            zoo_plate(cfg, 1, seed ^ 0x5EF0).and_then(|t| t.first().copied())
        }
        _ => None,
    }
}

/// Runs the scorecard (runs in parallel inside each check).
pub fn scorecard(c: &ScorecardConfig) -> Result<Scorecard, CheckError> {
    let mut card = Scorecard::default();
    for &seed in &c.seeds {
        for (family, variant, protocol, followed) in cases(seed) {
            let sensor = SimSensor::named(family, variant)?;
            let touches = if followed > 0 {
                c.touches / 2
            } else {
                c.touches
            };
            let r = check(&CheckConfig {
                followed_steps: followed,
                track: c.track,
                reference_touch: touched_reference(&sensor, protocol, seed),
                ..CheckConfig::zoo(sensor, protocol, touches, seed)
            })?;
            let name = if followed > 0 {
                format!("{family} followed")
            } else if protocol == "plate" {
                format!("{family} plate")
            } else {
                family.to_string()
            };
            let row = card.rows.entry(name).or_default();
            for (acc, b) in row.iter_mut().zip(&r.bands) {
                acc.add(b);
            }
        }
    }
    Ok(card)
}
