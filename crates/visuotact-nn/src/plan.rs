//! The default training policy, in one place: given a table's columns and size and what the
//! user set explicitly, which input sets are compared, how they are compared, the network's
//! size, the trainer and the ensemble — and why, in words.
//!
//! `visuotact train`, the Python package and the demo all train through a [`Plan`], so the same
//! table and the same wishes give the same model. What the user set is an `Option` in
//! [`Wanted`]: a value equal to the default, set explicitly, is still the user's choice (`--hidden
//! 20` trains 20 hidden neurons and nothing else; left out, a large table may also try the wide
//! network).
//!
//! ```
//! use visuotact_nn::plan::{Plan, Wanted};
//! let columns: Vec<String> = (0..30).map(|i| format!("m{i:03}_dx_px")).collect();
//! let plan = Plan::new(&columns, 200, &Wanted::default());
//! assert_eq!(plan.cfg.components, Some(10));
//! assert_eq!(plan.sets.len(), 1);
//! let set = plan.sets[0].clone();
//! assert_eq!(plan.networks(&set, 200), 5);
//! ```

use visuotact_image::{is_marker_column, FIELD_COLUMNS, FIELD_COLUMNS_MM};

use crate::fit::{
    auto_components, candidate_inputs, column_kinds, components_from_name, ensemble_for,
    fit_choosing_ensemble, FieldInputs, FitConfig, FitData, FitError, InputSet, Progress,
    LARGE_TABLE, SELECTION_FOLDS,
};
use crate::mlp::Algorithm;
use crate::model::Model;

/// What the user set explicitly; `None` leaves it to the policy.
#[derive(Clone, Debug, PartialEq)]
pub struct Wanted {
    /// Hidden layer sizes (default: [`FitConfig::default`]'s one layer of 20).
    pub hidden: Option<Vec<usize>>,
    /// The trainer (default: trainbr; the wide network trains with Adam).
    pub algorithm: Option<Algorithm>,
    /// Principal components of the markers' features: `Some(None)` none, `Some(Some(k))` k
    /// (default: [`auto_components`] of the markers' features).
    pub components: Option<Option<usize>>,
    /// The field summary as inputs.
    pub field: FieldInputs,
    /// Networks in the ensemble (default: [`ensemble_for`] the table's size and the set chosen).
    pub ensemble: Option<usize>,
    /// Seed of the splits and the initial weights.
    pub seed: u64,
    /// Most epochs (default: [`FitConfig::default`]'s).
    pub max_epochs: Option<usize>,
    /// Folds the input sets are compared by (default: [`SELECTION_FOLDS`]).
    pub folds: Option<usize>,
}

impl Default for Wanted {
    fn default() -> Self {
        Self {
            hidden: None,
            algorithm: None,
            components: None,
            field: FieldInputs::Auto,
            ensemble: None,
            seed: FitConfig::default().seed,
            max_epochs: None,
            folds: None,
        }
    }
}

/// [`Wanted::components`] from its name as `train --components` and Python take it: `auto`
/// leaves it to the policy (`None`); `0` or a count is the user's ([`components_from_name`]).
pub fn wanted_components(
    name: &str,
    marker_inputs: usize,
) -> Result<Option<Option<usize>>, FitError> {
    if name.trim() == "auto" {
        Ok(None)
    } else {
        components_from_name(name, marker_inputs).map(Some)
    }
}

/// A training decided: the settings, the input sets compared and by how many folds.
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    /// The settings (its `ensemble` is the user's, or the default's before a set is chosen:
    /// [`Plan::networks`] gives the number trained).
    pub cfg: FitConfig,
    /// The input sets compared (one: nothing to choose).
    pub sets: Vec<InputSet>,
    /// Folds they are compared by.
    pub folds: usize,
    /// Networks the user asked for.
    ensemble: Option<usize>,
    /// Why, one line per decision.
    pub why: Vec<String>,
}

impl Plan {
    /// The plan for a table of `samples` rows whose input columns are `columns` (markers'
    /// features first, then the rest), given `wanted`.
    pub fn new(columns: &[String], samples: usize, wanted: &Wanted) -> Self {
        let default = FitConfig::default();
        let markers = columns.iter().filter(|c| is_marker_column(c)).count();
        let folds = wanted.folds.unwrap_or(SELECTION_FOLDS);
        // The policy's projection fits every fold's training rows: a fold leaves out up to
        // ⌈samples / folds⌉ of them, and k components need k rows.
        let fold_rows = samples
            .saturating_sub(samples.div_ceil(folds.max(1)))
            .max(1);
        let components = wanted
            .components
            .unwrap_or_else(|| auto_components(markers).map(|k| k.min(fold_rows)));
        let cfg = FitConfig {
            hidden: wanted.hidden.clone().unwrap_or(default.hidden.clone()),
            seed: wanted.seed,
            max_epochs: wanted.max_epochs.unwrap_or(default.max_epochs),
            algorithm: wanted.algorithm.unwrap_or(default.algorithm),
            components,
            passthrough: columns.len() - markers,
            ensemble: wanted.ensemble.unwrap_or(default.ensemble),
            ..default
        };
        let mut why = Vec::new();
        if wanted.components.is_none() {
            why.push(match components {
                Some(k) if k == fold_rows => format!(
                    "{markers} markers' features: projected on {k} components (as many as a fold's training rows)"
                ),
                Some(k) => format!("{markers} markers' features: projected on {k} components"),
                None => format!("{markers} markers' features: read as they are"),
            });
        }
        // The wide network is the policy's own candidate: only when the user chose neither the
        // network's size nor its trainer.
        let wide = samples >= LARGE_TABLE && wanted.hidden.is_none() && wanted.algorithm.is_none();
        if wide {
            why.push(format!(
                "{samples} samples (at least {LARGE_TABLE}), size and trainer left open: the wide network is a candidate"
            ));
        }
        let field_names = [FIELD_COLUMNS, FIELD_COLUMNS_MM].concat();
        let sets = candidate_inputs(
            &column_kinds(columns, &field_names),
            components,
            wanted.field,
            wide,
        );
        Self {
            cfg,
            sets,
            folds,
            ensemble: wanted.ensemble,
            why,
        }
    }

    /// Networks trained on `samples` samples once `set` is chosen: the user's number, or
    /// [`ensemble_for`] the table's size and the set.
    pub fn networks(&self, set: &InputSet, samples: usize) -> usize {
        self.ensemble
            .unwrap_or_else(|| ensemble_for(samples, set, &self.cfg))
    }

    /// Trains on `data`: the input sets compared by [`Plan::folds`], then the ensemble on the
    /// set chosen; `progress` follows the final training.
    pub fn fit(&self, data: &FitData<'_>, progress: impl Progress) -> Result<Model, FitError> {
        let samples = data.x.len();
        fit_choosing_ensemble(
            data,
            &self.cfg,
            (&self.sets, self.folds),
            |set| self.networks(set, samples),
            progress,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn columns(markers: usize, field: bool) -> Vec<String> {
        let mut c: Vec<String> = (0..markers)
            .flat_map(|i| [format!("m{i:03}_dx_px"), format!("m{i:03}_dy_px")])
            .collect();
        if field {
            c.extend(FIELD_COLUMNS.iter().map(|s| s.to_string()));
        }
        c
    }

    /// A large table left to the policy also tries the wide network; the same table with the
    /// default size or trainer set explicitly does not (the user chose).
    #[test]
    fn the_wide_network_is_tried_only_when_size_and_trainer_are_left_open() {
        let c = columns(127, true);
        let open = Plan::new(&c, LARGE_TABLE, &Wanted::default());
        assert!(open.sets.iter().any(|s| s.wide), "{:?}", open.why);
        for wanted in [
            Wanted {
                hidden: Some(FitConfig::default().hidden),
                ..Wanted::default()
            },
            Wanted {
                algorithm: Some(FitConfig::default().algorithm),
                ..Wanted::default()
            },
        ] {
            let chosen = Plan::new(&c, LARGE_TABLE, &wanted);
            assert!(!chosen.sets.iter().any(|s| s.wide));
            assert_eq!(chosen.cfg, open.cfg);
        }
        let small = Plan::new(&c, LARGE_TABLE - 1, &Wanted::default());
        assert!(!small.sets.iter().any(|s| s.wide));
    }

    /// A table too short for the default projection gets as many components as a
    /// cross-validation fold has training rows (was: an error, "asked for 10 components of
    /// 351 inputs and 9 samples", on a 12-frame table the user set nothing for); the user's
    /// own count is left as it is, to be refused when it cannot fit.
    #[test]
    fn the_policys_projection_fits_a_short_tables_folds() {
        let c = columns(127, true);
        assert_eq!(
            Plan::new(&c, 300, &Wanted::default()).cfg.components,
            Some(10)
        );
        let short = Plan::new(&c, 12, &Wanted::default());
        assert_eq!(short.cfg.components, Some(9), "{:?}", short.why);
        assert!(short.why[0].contains("as many as a fold's training rows"));
        let asked = Wanted {
            components: Some(Some(10)),
            ..Wanted::default()
        };
        assert_eq!(Plan::new(&c, 12, &asked).cfg.components, Some(10));
    }

    /// The ensemble: the user's number whatever the set, else by the table's size.
    #[test]
    fn networks_are_the_users_or_by_the_tables_size() {
        let c = columns(4, false);
        let plan = Plan::new(&c, 300, &Wanted::default());
        assert_eq!(plan.cfg.components, None);
        assert_eq!(plan.networks(&plan.sets[0], 300), 5);
        assert_eq!(plan.networks(&plan.sets[0], LARGE_TABLE), 3);
        let two = Plan::new(
            &c,
            300,
            &Wanted {
                ensemble: Some(2),
                ..Wanted::default()
            },
        );
        assert_eq!(two.networks(&two.sets[0], LARGE_TABLE), 2);
        assert_eq!(two.cfg.ensemble, 2);
    }
}
