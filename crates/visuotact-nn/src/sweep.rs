//! Architecture sweeps (seed 001 Figs. 4.8/4.11/4.13): networks of many hidden sizes, several
//! times each on other seeds, trained in parallel on every core; mean and best performance per
//! size, and the networks ranked.
//!
//! Performance is reported in target units (the mean over targets of each target's test or
//! validation MSE) and, for choosing, on scaled targets ([`scaled_mse`]: each target's MSE over
//! its half range squared), so a target in degrees does not drown one in millimetres.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::fit::{fit, FitConfig, FitData, FitError, FitProgress, Progress};
use crate::model::Model;

/// A hidden-size spec that does not parse.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("hidden sizes {spec:?}: {why}")]
pub struct SpecError {
    /// The spec given.
    pub spec: String,
    /// What is wrong.
    pub why: &'static str,
}

/// A shard spec that does not parse.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("shard {spec:?}: expected K/N with 1 ≤ K ≤ N, e.g. 3/10")]
pub struct ShardError {
    /// The spec given.
    pub spec: String,
}

fn range(spec: &str, s: &str) -> Result<Vec<usize>, SpecError> {
    let bad = |why| SpecError {
        spec: spec.to_string(),
        why,
    };
    let (a, b) = s
        .split_once("..")
        .ok_or_else(|| bad("not a range like 1..40"))?;
    let parse = |v: &str| v.trim().parse::<usize>().map_err(|_| bad("not a number"));
    let (a, b) = (parse(a)?, parse(b)?);
    if a == 0 || b < a {
        return Err(bad("a range must be 1 ≤ start ≤ end"));
    }
    Ok((a..=b).collect())
}

/// The architectures a spec names: `1..40` (one layer), `1..20x1..20` (two layers) or a list
/// `5,10,20`.
pub fn architectures(spec: &str) -> Result<Vec<Vec<usize>>, SpecError> {
    if let Some((l, r)) = spec.split_once('x') {
        let (a, b) = (range(spec, l)?, range(spec, r)?);
        return Ok(a
            .iter()
            .flat_map(|&i| b.iter().map(move |&j| vec![i, j]))
            .collect());
    }
    if spec.contains("..") {
        return Ok(range(spec, spec)?.into_iter().map(|n| vec![n]).collect());
    }
    let v: Result<Vec<usize>, _> = spec.split(',').map(|p| p.trim().parse::<usize>()).collect();
    match v {
        Ok(v) if !v.is_empty() && !v.contains(&0) => Ok(v.into_iter().map(|n| vec![n]).collect()),
        _ => Err(SpecError {
            spec: spec.to_string(),
            why: "not a range (1..40, 1..20x1..20) or a list of sizes",
        }),
    }
}

fn mean_of(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

fn best_of(v: &[f64]) -> f64 {
    v.iter().copied().fold(f64::INFINITY, f64::min)
}

/// Mean over targets of a subset's MSE (0 train, 1 validation, 2 test) in target units.
pub fn mse(m: &Model, subset: usize) -> f64 {
    mean_of(&m.training.mse[subset])
}

/// Mean over targets of a subset's MSE in mapminmax space (each target's MSE over its half
/// range squared): every target counts alike whatever its unit.
pub fn scaled_mse(m: &Model, subset: usize) -> f64 {
    let ts = &m.target_scaling;
    let v: Vec<f64> = m.training.mse[subset]
        .iter()
        .enumerate()
        .map(|(j, e)| {
            let half = 0.5 * (ts.max[j] - ts.min[j]);
            if half > 0.0 {
                e / (half * half)
            } else {
                *e
            }
        })
        .collect();
    mean_of(&v)
}

/// One architecture's figures over its repeats.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepRow {
    /// Hidden layer sizes.
    pub hidden: Vec<usize>,
    /// Trainings.
    pub repeats: usize,
    /// Test MSE in target units: mean and best over repeats.
    pub test_mse: (f64, f64),
    /// Validation MSE in target units: mean and best.
    pub validation_mse: (f64, f64),
    /// Epochs, mean.
    pub mean_epochs: f64,
    /// Test MSE scaled: mean and best.
    pub test_mse_scaled: (f64, f64),
    /// Validation MSE scaled: mean and best.
    pub validation_mse_scaled: (f64, f64),
}

/// A finished sweep.
#[derive(Clone, Debug)]
pub struct Sweep {
    /// Per architecture, in the order given.
    pub rows: Vec<SweepRow>,
    /// Every network trained, with its architecture's index.
    pub models: Vec<(usize, Model)>,
}

impl Sweep {
    /// The table as CSV, one row per architecture (`hidden` as `20x10`).
    pub fn to_csv(&self) -> String {
        let mut out = String::from("hidden,repeats,mean_test_mse,best_test_mse,mean_validation_mse,best_validation_mse,mean_epochs,mean_test_mse_scaled,best_test_mse_scaled,mean_validation_mse_scaled,best_validation_mse_scaled\n");
        for r in &self.rows {
            let name: Vec<String> = r.hidden.iter().map(usize::to_string).collect();
            out.push_str(&format!(
                "{},{},{},{},{},{},{},{},{},{},{}\n",
                name.join("x"),
                r.repeats,
                r.test_mse.0,
                r.test_mse.1,
                r.validation_mse.0,
                r.validation_mse.1,
                r.mean_epochs,
                r.test_mse_scaled.0,
                r.test_mse_scaled.1,
                r.validation_mse_scaled.0,
                r.validation_mse_scaled.1
            ));
        }
        out
    }

    /// The networks best first, by scaled validation MSE.
    pub fn ranked(&self) -> Vec<&Model> {
        let mut ranked: Vec<&Model> = self.models.iter().map(|r| &r.1).collect();
        ranked.sort_by(|p, q| scaled_mse(p, 1).total_cmp(&scaled_mse(q, 1)));
        ranked
    }

    /// (hidden neurons, mean test MSE, best test MSE) per architecture, for the plot.
    pub fn points(&self) -> Vec<(f64, f64, f64)> {
        self.rows
            .iter()
            .map(|r| {
                (
                    r.hidden.iter().sum::<usize>() as f64,
                    r.test_mse.0,
                    r.test_mse.1,
                )
            })
            .collect()
    }
}

/// The sweep's trainings in their fixed order: (architecture index, repeat).
pub fn jobs(n_archs: usize, repeats: usize) -> Vec<(usize, usize)> {
    (0..n_archs)
        .flat_map(|k| (0..repeats).map(move |r| (k, r)))
        .collect()
}

/// One slice of a sweep's trainings: shard `index` (1-based) of `count` takes every
/// `count`-th training from the `index`-th on (round robin, so each shard gets small and large
/// networks alike).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shard {
    /// This shard, 1..=count.
    pub index: usize,
    /// Shards in all.
    pub count: usize,
}

visuotact_image::from_str_by_parse!(Shard, ShardError);

impl Shard {
    /// The whole sweep as one shard.
    pub const ALL: Self = Self { index: 1, count: 1 };

    /// Parses `K/N` (1 ≤ K ≤ N).
    pub fn parse(s: &str) -> Result<Self, ShardError> {
        let bad = || ShardError {
            spec: s.to_string(),
        };
        let (k, n) = s.split_once('/').ok_or_else(bad)?;
        let parse = |v: &str| v.trim().parse::<usize>().ok();
        match (parse(k), parse(n)) {
            (Some(index), Some(count)) if index >= 1 && index <= count => Ok(Self { index, count }),
            _ => Err(bad()),
        }
    }

    /// Whether training number `job` (in [`jobs`] order) is this shard's.
    pub fn takes(&self, job: usize) -> bool {
        job % self.count == self.index - 1
    }
}

/// A trained network of a sweep, with where it belongs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Trained {
    /// Architecture index.
    pub arch: usize,
    /// Repeat.
    pub repeat: usize,
    /// The network.
    pub model: Model,
}

/// Trains `shard`'s part of the sweep (see [`sweep`]) on every core; `progress` numbers the
/// networks over the shard's trainings (a training it stops keeps the weights it had).
pub fn sweep_shard(
    data: &FitData<'_>,
    archs: &[Vec<usize>],
    repeats: usize,
    base: &FitConfig,
    shard: Shard,
    progress: impl Progress,
) -> Result<Vec<Trained>, FitError> {
    let mine: Vec<(usize, usize)> = jobs(archs.len(), repeats)
        .into_iter()
        .enumerate()
        .filter(|(j, _)| shard.takes(*j))
        .map(|(_, job)| job)
        .collect();
    mine.par_iter()
        .enumerate()
        .map(|(job, &(k, r))| {
            let cfg = FitConfig {
                hidden: archs[k].clone(),
                seed: base.seed.wrapping_add(1000 * r as u64 + k as u64),
                hold_out: true,
                ensemble: 1,
                ..base.clone()
            };
            let m = fit(data, &cfg, |p: &FitProgress| {
                progress(&FitProgress {
                    network: job,
                    networks: mine.len(),
                    ..*p
                })
            });
            m.map(|model| Trained {
                arch: k,
                repeat: r,
                model,
            })
        })
        .collect()
}

/// The sweep from all its trainings (any order; shards merged): the same [`Sweep`] as one
/// machine's.
pub fn sweep_of(archs: &[Vec<usize>], mut trained: Vec<Trained>) -> Sweep {
    trained.sort_by_key(|t| (t.arch, t.repeat));
    let rows = archs
        .iter()
        .enumerate()
        .map(|(k, arch)| {
            let ms: Vec<&Model> = trained
                .iter()
                .filter(|t| t.arch == k)
                .map(|t| &t.model)
                .collect();
            let figure = |f: &dyn Fn(&Model) -> f64| {
                let v: Vec<f64> = ms.iter().map(|m| f(m)).collect();
                (mean_of(&v), best_of(&v))
            };
            SweepRow {
                hidden: arch.clone(),
                repeats: ms.len(),
                test_mse: figure(&|m| mse(m, 2)),
                validation_mse: figure(&|m| mse(m, 1)),
                mean_epochs: figure(&|m| m.training.epochs as f64).0,
                test_mse_scaled: figure(&|m| scaled_mse(m, 2)),
                validation_mse_scaled: figure(&|m| scaled_mse(m, 1)),
            }
        })
        .collect();
    Sweep {
        rows,
        models: trained.into_iter().map(|t| (t.arch, t.model)).collect(),
    }
}

/// Trains every architecture of `archs` `repeats` times (seed `base.seed + 1000·repeat +
/// architecture`, validation and test subsets kept) on every core; `progress` follows the
/// trainings as in [`sweep_shard`].
pub fn sweep(
    data: &FitData<'_>,
    archs: &[Vec<usize>],
    repeats: usize,
    base: &FitConfig,
    progress: impl Progress,
) -> Result<Sweep, FitError> {
    let trained = sweep_shard(data, archs, repeats, base, Shard::ALL, progress)?;
    Ok(sweep_of(archs, trained))
}

/// One shard's trainings as a file (`sweep --shard`), to be merged with the others.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SweepPart {
    /// `visuotact-sweep-part`.
    pub format: String,
    /// What the sweep was: hidden spec, repeats, base seed and anything else that must agree
    /// between parts (the caller's words).
    pub sweep: String,
    /// The hidden-size spec ([`architectures`]).
    pub hidden: String,
    /// The target columns.
    pub targets: Vec<String>,
    /// Which shard.
    pub shard: Shard,
    /// Its networks.
    pub trained: Vec<Trained>,
}

/// The format name of a [`SweepPart`] file.
pub const PART_FORMAT: &str = "visuotact-sweep-part";

/// Sweep parts that do not make one sweep (the message names the part or the shards).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum MergeError {
    /// No part given.
    #[error("no part to merge")]
    NoParts,
    /// A file that is not a sweep part.
    #[error("{part}: not a sweep part (format {format:?})")]
    NotAPart {
        /// The part's name (its file).
        part: String,
        /// The format it names.
        format: String,
    },
    /// A part of another sweep than the first part's.
    #[error("{part}: from another sweep than {first} ({sweep} of {count} shards, {first_sweep} against {first_count})")]
    OtherSweep {
        /// The part's name.
        part: String,
        /// The first part's name.
        first: String,
        /// The part's sweep.
        sweep: String,
        /// Its shard count.
        count: usize,
        /// The first part's sweep.
        first_sweep: String,
        /// The first part's shard count.
        first_count: usize,
    },
    /// A shard given twice.
    #[error("{part}: shard {index}/{count} again (also {other})")]
    Again {
        /// The part's name.
        part: String,
        /// The shard (from 1).
        index: usize,
        /// Shards in the sweep.
        count: usize,
        /// The other part holding it.
        other: String,
    },
    /// Shards no part holds, as `k/count`.
    #[error("shards missing: {}", .0.join(", "))]
    Missing(Vec<String>),
}

/// Checks that `parts` are every shard of one sweep, once each, and gives their trainings.
pub fn merge_parts(parts: Vec<(String, SweepPart)>) -> Result<Vec<Trained>, MergeError> {
    let Some((first_name, first)) = parts.first() else {
        return Err(MergeError::NoParts);
    };
    let (sweep, count) = (first.sweep.clone(), first.shard.count);
    let mut seen = vec![None::<&str>; count];
    for (name, p) in &parts {
        if p.format != PART_FORMAT {
            return Err(MergeError::NotAPart {
                part: name.clone(),
                format: p.format.clone(),
            });
        }
        if p.sweep != sweep || p.shard.count != count {
            return Err(MergeError::OtherSweep {
                part: name.clone(),
                first: first_name.clone(),
                sweep: p.sweep.clone(),
                count: p.shard.count,
                first_sweep: sweep,
                first_count: count,
            });
        }
        let slot = &mut seen[p.shard.index - 1];
        if let Some(other) = slot {
            return Err(MergeError::Again {
                part: name.clone(),
                index: p.shard.index,
                count,
                other: (*other).to_string(),
            });
        }
        *slot = Some(name);
    }
    let missing: Vec<String> = (1..=count)
        .filter(|k| seen[k - 1].is_none())
        .map(|k| format!("{k}/{count}"))
        .collect();
    if !missing.is_empty() {
        return Err(MergeError::Missing(missing));
    }
    Ok(parts.into_iter().flat_map(|(_, p)| p.trained).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hidden_specs() {
        assert_eq!(
            architectures("1..3").unwrap(),
            vec![vec![1], vec![2], vec![3]]
        );
        assert_eq!(
            architectures("1..2x3..4").unwrap(),
            vec![vec![1, 3], vec![1, 4], vec![2, 3], vec![2, 4]]
        );
        assert_eq!(architectures("5,10").unwrap(), vec![vec![5], vec![10]]);
        assert!(
            architectures("0..3").is_err()
                && architectures("4..2").is_err()
                && architectures("a").is_err()
        );
    }

    fn model(val_mse: [f64; 2]) -> Model {
        let mut m = crate::model::tests::model(&[1, 1, 2], 0);
        // Target 0 spans 0..1000 (say mN), target 1 spans 0..1 (say mm).
        m.target_scaling.max = vec![1000.0, 1.0];
        m.training.mse = [vec![], val_mse.to_vec(), vec![]];
        m
    }

    #[test]
    fn selection_weighs_every_target_alike_whatever_its_unit() {
        // A: 1 % of range off on the big target, 63 % on the small one; B: 10 % and 6 %.
        let (a, b) = (model([100.0, 0.1]), model([10_000.0, 0.001]));
        // In target units A looks 100× better: the big target's unit drowns the other.
        assert!(mse(&a, 1) < mse(&b, 1));
        // Scaled, B is better on the whole: (0.04 + 0.004) / 2 against (0.0004 + 0.4) / 2.
        assert!((scaled_mse(&b, 1) - 0.022).abs() < 1e-12);
        assert!((scaled_mse(&a, 1) - 0.2002).abs() < 1e-12);
        let s = Sweep {
            rows: Vec::new(),
            models: vec![(0, a), (1, b)],
        };
        assert_eq!(s.ranked()[0].training.mse[1][0], 10_000.0);
    }

    #[test]
    fn shards_partition_the_trainings_and_parse() {
        let all = jobs(7, 3).len();
        let mut count = vec![0; all];
        for k in 1..=4 {
            let s = Shard::parse(&format!("{k}/4")).unwrap();
            for (j, c) in count.iter_mut().enumerate() {
                *c += usize::from(s.takes(j));
            }
        }
        assert!(count.iter().all(|&c| c == 1));
        assert!(Shard::parse("0/3").is_err() && Shard::parse("4/3").is_err());
        assert!(Shard::parse("3").is_err() && Shard::parse("a/b").is_err());
    }

    #[test]
    fn parts_merge_only_when_every_shard_is_there_once() {
        let part = |k: usize, n: usize, sweep: &str| {
            let p = SweepPart {
                format: PART_FORMAT.into(),
                sweep: sweep.into(),
                hidden: "1..2".into(),
                targets: vec!["a".into(), "b".into()],
                shard: Shard { index: k, count: n },
                trained: vec![Trained {
                    arch: k,
                    repeat: 0,
                    model: model([1.0, 1.0]),
                }],
            };
            (format!("part{k}"), p)
        };
        let ok = merge_parts(vec![part(2, 2, "a"), part(1, 2, "a")]).unwrap();
        assert_eq!(ok.len(), 2);
        let e = merge_parts(vec![part(1, 3, "a"), part(3, 3, "a")]).unwrap_err();
        assert_eq!(e, MergeError::Missing(vec!["2/3".into()]));
        assert!(e.to_string().contains("shards missing: 2/3"), "{e}");
        let e = merge_parts(vec![part(1, 2, "a"), part(1, 2, "a")]).unwrap_err();
        assert!(
            matches!(
                e,
                MergeError::Again {
                    index: 1,
                    count: 2,
                    ..
                }
            ),
            "{e}"
        );
        assert!(e.to_string().contains("again"), "{e}");
        let e = merge_parts(vec![part(1, 2, "a"), part(2, 2, "b")]).unwrap_err();
        assert!(matches!(e, MergeError::OtherSweep { .. }), "{e}");
        assert!(e.to_string().contains("another sweep"), "{e}");
    }
}
