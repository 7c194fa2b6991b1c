//! The assignment: which blob each marker takes, minimising the energy ([`super::energy`]).
//!
//! 1. **Seeds**: markers whose blob near where they are expected is unmistakable (within half
//!    the gate, no other blob within the gate), keeping only the largest set whose
//!    displacements agree with their seeded neighbours. Expected: from the seeds already
//!    taken (chained), or from the starting motion alone (independent; one of the starts
//!    [`super`] compares).
//! 2. **Growth**, best supported first: a marker predicted from its matched neighbours takes
//!    the free blob of least cost when that costs less than being lost and the next blob costs
//!    at least the margin more; otherwise it waits for more neighbours.
//! 3. **Global refinement**: every marker's prediction is refitted from its neighbours' blobs
//!    and all markers are matched at once by minimum total cost (one blob per marker, lost at
//!    its lost cost), until nothing changes: a greedy step taken in the wrong order is undone.
//! 4. **Lattice offset** (order-free, lattices): a field moved by pitches can be read whole a
//!    lattice step off; the whole reading shifted by each lattice step is compared by energy
//!    (read a step off, a row of markers at the layout's edge has no blob) and the lowest
//!    kept, repeated up to [`TrackParams::reach_pitches`](super::TrackParams) steps.

use std::cell::Cell;
use std::collections::BinaryHeap;
use std::sync::Arc;

use super::energy::fill_short;
use super::energy::Energy;
use super::index::{dist, dist_sq, parts, BlobIndex};
use super::predict::{local_motion, Around, Prediction};
use super::TrackReference;
use crate::assign::{assign_min_cost, Candidates};
use crate::blobs::Blob;

/// The working state of one frame's matching.
#[derive(Clone)]
pub(super) struct Matching<'a> {
    pub reference: &'a TrackReference,
    pub blobs: &'a [Blob],
    /// Blobs from this index on are markers cut by the border.
    pub usable: usize,
    /// Shared by the copies a side-by-side measurement makes (fixed for the frame).
    pub index: Arc<BlobIndex>,
    pub energy: Energy<'a>,
    /// Where each marker was before the motion being followed (reference or prior).
    pub anchors: Vec<(f64, f64)>,
    /// The anchors' neighbours, offsets and weights for the affine fits.
    around: Arc<Around>,
    /// Per blob, how far under 1 it fills its moments' ellipse (the shape term's misfit).
    fill_short: Arc<[f64]>,
    /// The starting motion added to the anchors (registration; zero when followed).
    pub shift: (f64, f64),
    /// Whether the energy measures a marker on its dot's pieces together: order-free only.
    /// Followed, the last frame's positions decide, and a sliver squeezed off a dot dragged
    /// onto a neighbour would pass for the neighbour's piece.
    pub charge_pieces: bool,
    pub assignment: Vec<Option<usize>>,
    /// The marker holding each blob.
    pub owner: Vec<Option<usize>>,
    pub disp: Vec<(f64, f64)>,
    /// How many of each marker's neighbours hold a blob.
    pub support: Vec<u32>,
    /// Each marker's prediction from its neighbours as last computed (`None`: to compute),
    /// cleared when a neighbour takes or leaves a blob.
    predicted: Vec<Cell<Option<Option<Prediction>>>>,
    /// Each marker's term of the energy as last computed (`None`: to compute), cleared with
    /// its prediction and when it takes or leaves a blob.
    terms: Vec<Cell<Option<f64>>>,
    /// Each marker's candidates ([`Matching::each_candidate`]) as last computed (`None`: to
    /// compute, or more than a row holds), cleared with its prediction.
    rows: Vec<Cell<Option<Row>>>,
}

/// The cached predictions and energy terms of some markers, with the blobs they held
/// ([`Matching::save_caches`]).
pub(super) struct SavedCaches {
    held: Vec<Option<usize>>,
    predicted: Vec<Option<Option<Prediction>>>,
    terms: Vec<Option<f64>>,
}

/// The most candidates a marker's cached row holds (a marker has one or two blobs within its
/// gate; a crowd of more is computed each time it is asked).
const ROW_CAP: usize = 6;

/// A marker's blobs within its gate with their costs.
#[derive(Clone, Copy)]
struct Row {
    len: u8,
    items: [(u32, f64); ROW_CAP],
}

impl<'a> Matching<'a> {
    pub fn new(
        reference: &'a TrackReference,
        blobs: &'a [Blob],
        usable: usize,
        energy: Energy<'a>,
        anchors: Vec<(f64, f64)>,
        shift: (f64, f64),
    ) -> Self {
        let n = reference.positions.len();
        Self {
            reference,
            blobs,
            usable,
            index: Arc::new(BlobIndex::new(blobs, reference.pitch_px.max(1.0))),
            energy,
            around: Around::new(reference, &anchors),
            fill_short: blobs.iter().map(fill_short).collect(),
            anchors,
            shift,
            charge_pieces: true,
            assignment: vec![None; n],
            owner: vec![None; blobs.len()],
            disp: vec![(0.0, 0.0); n],
            support: vec![0; n],
            predicted: vec![Cell::new(None); n],
            terms: vec![Cell::new(None); n],
            rows: vec![Cell::new(None); n],
        }
    }

    pub fn take(&mut self, i: usize, j: usize) {
        if let Some(old) = self.assignment[i] {
            self.owner[old] = None;
        } else {
            for &k in &self.reference.neighbours[i] {
                self.support[k] += 1;
            }
        }
        self.forget_around(i);
        self.assignment[i] = Some(j);
        self.owner[j] = Some(i);
        let a = self.anchors[i];
        self.disp[i] = (self.blobs[j].x_px - a.0, self.blobs[j].y_px - a.1);
    }

    pub fn release(&mut self, i: usize) {
        if let Some(j) = self.assignment[i].take() {
            self.owner[j] = None;
            for &k in &self.reference.neighbours[i] {
                self.support[k] -= 1;
            }
            self.forget_around(i);
        }
    }

    /// Clears what `i` taking or leaving a blob changes: its own energy term, and its
    /// neighbours' predictions and terms (the layout's neighbours are mutual).
    fn forget_around(&self, i: usize) {
        self.terms[i].set(None);
        for &k in &self.reference.neighbours[i] {
            self.predicted[k].set(None);
            self.terms[k].set(None);
            self.rows[k].set(None);
        }
    }

    /// The cached predictions and terms of the markers of `area`, to restore after moves that
    /// change markers of `area` only ([`Matching::restore_caches`]).
    pub(super) fn save_caches(&self, area: &[usize]) -> SavedCaches {
        SavedCaches {
            held: area.iter().map(|&i| self.assignment[i]).collect(),
            predicted: area.iter().map(|&i| self.predicted[i].get()).collect(),
            terms: area.iter().map(|&i| self.terms[i].get()).collect(),
        }
    }

    /// Puts back what [`Matching::save_caches`] saved of `area` where it is still true, the
    /// markers outside `area` holding the blobs they held then: a marker's prediction
    /// and term depend only on its own blob and its neighbours' (their displacements, and
    /// whether they hold one), so a marker that holds the blob it held then, among neighbours
    /// that do too, has them as they were, however many moves were made and undone between.
    pub(super) fn restore_caches(&self, area: &[usize], saved: &SavedCaches) {
        // The markers whose own or a neighbour's blob changed.
        let mut touched = vec![false; self.assignment.len()];
        for (&i, &held) in area.iter().zip(&saved.held) {
            if self.assignment[i] != held {
                touched[i] = true;
                for &n in &self.reference.neighbours[i] {
                    touched[n] = true;
                }
            }
        }
        for (k, &i) in area.iter().enumerate() {
            if touched[i] {
                continue;
            }
            if self.predicted[i].get().is_none() {
                self.predicted[i].set(saved.predicted[k]);
            }
            if self.terms[i].get().is_none() {
                self.terms[i].set(saved.terms[k]);
            }
        }
    }

    /// Replaces the whole assignment (only the markers whose blob changes are moved).
    pub fn set_assignment(&mut self, a: &[Option<usize>]) {
        for (i, col) in a.iter().enumerate() {
            if self.assignment[i] != *col {
                self.release(i);
            }
        }
        for (i, col) in a.iter().enumerate() {
            if let Some(j) = *col {
                if self.assignment[i] != Some(j) {
                    self.take(i, j);
                }
            }
        }
    }

    /// The gate of marker `i` at rest (no magnification, no spread), pixels.
    pub fn params_gate_px(&self, i: usize) -> f64 {
        self.energy.params.gate_spacings * self.reference.spacing_px[i]
    }

    pub fn is_cut(&self, j: usize) -> bool {
        j >= self.usable
    }

    /// Whether blob `j`'s outline is cut by the border: dropped as cut by the detector, or
    /// kept whole though it touches the border (`keep_border`). Its area and shape then say
    /// nothing of the marker's.
    pub fn outline_cut(&self, j: usize) -> bool {
        self.is_cut(j) || self.blobs[j].touches_border
    }

    /// Where `i` should be according to its matched neighbours, and the local magnification.
    pub fn predict(&self, i: usize) -> Option<Prediction> {
        if let Some(p) = self.predicted[i].get() {
            return p;
        }
        let p = self.predict_afresh(i);
        self.predicted[i].set(Some(p));
        p
    }

    fn predict_afresh(&self, i: usize) -> Option<Prediction> {
        let a = &self.assignment;
        local_motion(
            i,
            self.reference,
            &self.around,
            |k| a[k].is_some(),
            &self.disp,
        )
        .map(|m| {
            let p = self.anchors[i];
            Prediction {
                at: (p.0 + m.disp.0, p.1 + m.disp.1),
                scale: m.scale,
                spread_px: m.spread_px,
                start: (p.0 + self.shift.0, p.1 + self.shift.1),
            }
        })
    }

    /// [`Matching::predict`], or the starting motion when no neighbour holds a blob.
    pub fn predict_or_start(&self, i: usize) -> Prediction {
        self.predict(i).unwrap_or_else(|| self.start_of(i))
    }

    /// Where the starting motion alone puts `i`: its anchor moved by the shift.
    fn start_of(&self, i: usize) -> Prediction {
        let a = self.anchors[i];
        let start = (a.0 + self.shift.0, a.1 + self.shift.1);
        Prediction {
            at: start,
            scale: 1.0,
            spread_px: 0.0,
            start,
        }
    }

    /// The cost of `i` (predicted `pred`) taking blob `j`.
    pub fn cost(&self, i: usize, pred: Prediction, j: usize) -> f64 {
        let cut = self.outline_cut(j);
        let short = if cut { 0.0 } else { self.fill_short[j] };
        let cap = || {
            if self.lobe_of_another(i) {
                f64::INFINITY
            } else {
                self.energy.speck_cost()
            }
        };
        self.energy
            .cost_with(i, &pred, &self.blobs[j], cut, (short, cap))
    }

    /// Whether a neighbour of `i` has no blob: it may be hidden under `i`'s blob (a drag
    /// carries a dot onto its neighbour, and the hidden one's prediction lags), so a blob of
    /// two lobes there is evidence of two markers, not of a speck.
    fn lobe_of_another(&self, i: usize) -> bool {
        self.reference.neighbours[i]
            .iter()
            .any(|&k| self.assignment[k].is_none())
    }

    /// The blobs within the gate of `pred` with their cost for `i`, those `skip` refuses left
    /// out.
    pub(super) fn candidates(
        &self,
        i: usize,
        pred: Prediction,
        skip: impl Fn(usize) -> bool,
        out: &mut Vec<(usize, f64)>,
    ) {
        out.clear();
        let gate = self.energy.gate_px(i, &pred);
        self.index.near(pred.at, gate, |j, _| {
            if !skip(j) {
                out.push((j, self.cost(i, pred, j)));
            }
        });
    }

    /// Calls `f(blob, cost)` for each blob within the gate of marker `i`'s prediction
    /// ([`Matching::predict_or_start`]), in the index's order: [`Matching::candidates`] with
    /// nothing skipped, computed once for each prediction (the refinement and the runner-ups
    /// ask the same).
    pub(super) fn each_candidate(&self, i: usize, mut f: impl FnMut(usize, f64)) {
        if let Some(row) = self.rows[i].get() {
            for &(j, c) in &row.items[..usize::from(row.len)] {
                f(j as usize, c);
            }
            return;
        }
        let pred = self.predict_or_start(i);
        let mut row = Row {
            len: 0,
            items: [(0, 0.0); ROW_CAP],
        };
        let mut fits = true;
        self.index
            .near(pred.at, self.energy.gate_px(i, &pred), |j, _| {
                let c = self.cost(i, pred, j);
                match row.items.get_mut(usize::from(row.len)) {
                    Some(slot) => {
                        *slot = (j as u32, c);
                        row.len += 1;
                    }
                    None => fits = false,
                }
                f(j, c);
            });
        if fits {
            self.rows[i].set(Some(row));
        }
    }

    /// Seeds: markers whose blob near where they are expected is unmistakable. Expected:
    /// `independent`, where the starting motion puts each; otherwise from the seeds already
    /// taken among its neighbours (in marker order), the starting motion for the first.
    pub fn seed(&mut self, independent: bool) {
        let n = self.anchors.len();
        let gate_cost = self.energy.gate_cost();
        let mut cands = Vec::new();
        for i in 0..n {
            let pred = if independent {
                self.start_of(i)
            } else {
                self.predict_or_start(i)
            };
            self.candidates(i, pred, |j| self.owner[j].is_some(), &mut cands);
            let Some(&(j, c)) = cands.iter().min_by(|a, b| a.1.total_cmp(&b.1)) else {
                continue;
            };
            // Within half the gate in position (a quarter of the lost cost), nothing else in it.
            if c > 0.25 * gate_cost || cands.len() > 1 {
                continue;
            }
            let bj = (self.blobs[j].x_px, self.blobs[j].y_px);
            let d = dist(bj, pred.at);
            let mutual = self.reference.neighbours[i].iter().all(|&k| {
                let a = self.anchors[k];
                dist_sq((a.0 + self.shift.0, a.1 + self.shift.1), bj) > d * d
            });
            if mutual {
                self.take(i, j);
            }
        }
        self.keep_largest_agreeing_seeds();
    }

    /// Keeps the largest set of seeds whose displacements agree (within a quarter spacing)
    /// with their seeded neighbours.
    fn keep_largest_agreeing_seeds(&mut self) {
        let r = self.reference;
        let seeds = parts(
            self.anchors.len(),
            |i| self.assignment[i].is_some(),
            |i| r.neighbours[i].iter().copied(),
            |i, k| {
                let s = r.spacing_px[i].min(r.spacing_px[k]);
                dist_sq(self.disp[i], self.disp[k]) < (0.25 * s).powi(2)
            },
        );
        // The largest; of equal ones, the first.
        let keep = (0..seeds.len()).max_by_key(|&c| (seeds[c].len(), usize::MAX - c));
        for (c, part) in seeds.iter().enumerate() {
            if Some(c) != keep {
                for &i in part {
                    self.release(i);
                }
            }
        }
    }

    /// Grows the matched set into the neighbours of matched markers, most supported first.
    pub fn grow(&mut self) {
        let n = self.assignment.len();
        let margin = self.energy.params.margin;
        let mut failed_at: Vec<Option<u32>> = vec![None; n];
        let mut heap: BinaryHeap<(u32, std::cmp::Reverse<usize>)> = (0..n)
            .filter(|&i| self.assignment[i].is_none() && self.support[i] > 0)
            .map(|i| (self.support[i], std::cmp::Reverse(i)))
            .collect();
        let mut cands = Vec::new();
        while let Some((support, std::cmp::Reverse(i))) = heap.pop() {
            if self.assignment[i].is_some()
                || support != self.support[i]
                || failed_at[i].is_some_and(|f| support <= f)
            {
                continue;
            }
            let Some(pred) = self.predict(i) else {
                continue;
            };
            self.candidates(i, pred, |j| self.owner[j].is_some(), &mut cands);
            cands.sort_by(|a, b| a.1.total_cmp(&b.1));
            let lost = self.energy.unmatched_cost_at(i, &pred);
            let runner_up = cands.get(1).map_or(lost, |c| c.1.min(lost));
            match cands.first() {
                Some(&(j, c)) if c < lost && runner_up - c >= margin => {
                    self.take(i, j);
                    for &k in &self.reference.neighbours[i] {
                        if self.assignment[k].is_none() {
                            heap.push((self.support[k], std::cmp::Reverse(k)));
                        }
                    }
                }
                _ => failed_at[i] = Some(support),
            }
        }
    }

    /// Every marker's prediction from its neighbours' current blobs (the starting motion for
    /// a marker none of whose neighbours holds one).
    pub fn predictions(&self) -> Vec<Prediction> {
        (0..self.assignment.len())
            .map(|i| self.predict_or_start(i))
            .collect()
    }

    /// Matches every marker at once by minimum total cost from its neighbours' predictions,
    /// until nothing changes (at most `rounds` times). A marker no neighbour of which holds a
    /// blob may only keep its own.
    pub fn refine(&mut self, rounds: usize) {
        let n = self.assignment.len();
        let mut cands = Candidates::default();
        let mut row = Vec::new();
        for _ in 0..rounds {
            let preds = self.predictions();
            cands.clear();
            for (i, &pred) in preds.iter().enumerate() {
                if self.support[i] > 0 {
                    row.clear();
                    self.each_candidate(i, |j, c| row.push((j, c)));
                } else {
                    row.clear();
                    if let Some(j) = self.assignment[i] {
                        row.push((j, self.cost(i, pred, j)));
                    }
                }
                cands.push_row(&row, self.energy.unmatched_cost_at(i, &pred));
            }
            let a = assign_min_cost(&cands, self.blobs.len());
            if (0..n).all(|i| a.columns[i] == self.assignment[i]) {
                break;
            }
            self.set_assignment(&a.columns);
        }
    }

    /// The energy of the current assignment: each matched marker's cost against its
    /// neighbours' prediction (with [`Matching::charge_pieces`], measured on its pieces
    /// together where that costs less, [`super::pieces`]), each unmatched marker's lost cost
    /// and each unclaimed blob's clutter cost. A dot broken in two by a line drawn across it is
    /// one marker's, not two markers' read a step apart.
    pub fn total_energy(&self) -> f64 {
        let plain = self.energy_without_pieces();
        if self.charge_pieces {
            // The predictions are cached by `energy_without_pieces`.
            plain - super::pieces::pieces_and_gain(self, &self.predictions()).1
        } else {
            plain
        }
    }

    /// [`Matching::total_energy`] with every piece of a dot counted as clutter.
    fn energy_without_pieces(&self) -> f64 {
        let clutter = (0..self.usable)
            .filter(|&j| self.owner[j].is_none())
            .count() as f64
            * self.energy.clutter_cost();
        clutter
            + (0..self.assignment.len())
                .map(|i| self.term(i))
                .sum::<f64>()
    }

    /// Marker `i`'s term of the energy: its blob's cost against its prediction, or its lost
    /// cost.
    pub fn term(&self, i: usize) -> f64 {
        if let Some(t) = self.terms[i].get() {
            return t;
        }
        let pred = self.predict_or_start(i);
        let t = match self.assignment[i] {
            Some(j) => self.cost(i, pred, j),
            None => self.energy.lost_cost_at(i, &pred),
        };
        self.terms[i].set(Some(t));
        t
    }

    /// Whether the reading leaves anything unexplained: a usable blob no marker takes, or a
    /// marker without a blob where it should be seen. A reading a lattice step off always
    /// does (a row of markers at one edge without blobs, a row of blobs at the other without
    /// markers), unless the view's edge hides both, where the energy cannot tell them apart.
    pub fn leaves_unexplained(&self) -> bool {
        (0..self.usable).any(|j| self.owner[j].is_none())
            || (0..self.assignment.len()).any(|i| {
                self.assignment[i].is_none()
                    && self.energy.lost_cost_at(i, &self.predict_or_start(i)) > 0.0
            })
    }

    /// Order-free on a lattice: shifts the whole reading by a lattice step, refined, while
    /// that lowers the energy by the margin (at most `max_steps` steps). The two directions
    /// whose plain shift costs least are refined and compared. A reading that explains every
    /// blob and every marker in view is kept as it is.
    pub fn search_offset(&mut self, max_steps: usize) {
        let n_dirs = self.reference.lattice_dirs;
        if n_dirs == 0 || !self.leaves_unexplained() {
            return;
        }
        let mut e0 = self.total_energy();
        for _ in 0..max_steps {
            let saved = self.assignment.clone();
            let mut plain: Vec<(f64, usize)> = (0..n_dirs)
                .map(|d| {
                    self.set_assignment(&self.shifted(&saved, d));
                    (self.total_energy(), d)
                })
                .collect();
            plain.sort_by(|a, b| a.0.total_cmp(&b.0));
            let mut best: Option<(f64, Vec<Option<usize>>)> = None;
            for &(_, d) in plain.iter().take(2) {
                self.set_assignment(&self.shifted(&saved, d));
                self.refine(3);
                let e = self.total_energy();
                if e < e0 - self.energy.params.margin && best.as_ref().is_none_or(|b| e < b.0) {
                    best = Some((e, self.assignment.clone()));
                }
            }
            match best {
                Some((e, a)) => {
                    self.set_assignment(&a);
                    e0 = e;
                }
                None => {
                    self.set_assignment(&saved);
                    break;
                }
            }
        }
    }

    /// `a` shifted by one lattice step along direction `d`: each marker takes the blob its
    /// neighbour one step along `d` holds.
    fn shifted(&self, a: &[Option<usize>], d: usize) -> Vec<Option<usize>> {
        let steps = &self.reference.lattice_steps;
        (0..a.len())
            .map(|i| steps[i].get(d).copied().flatten().and_then(|k| a[k]))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use crate::track::testkit::hex_array;
    use crate::track::TrackParams;

    /// Caches put back after a move and its undoing hold what computing afresh gives, and
    /// those of markers the move left changed are not put back.
    #[test]
    fn caches_put_back_after_an_undone_move_equal_fresh_ones() {
        let array = hex_array(4, 12.0);
        let n = array.positions.len();
        let blobs = array.blobs_slid(1.5, -1.0);
        let params = TrackParams::default();
        let mut m = array.matching(&blobs, &params);
        let own: Vec<Option<usize>> = (0..n).map(Some).collect();
        m.set_assignment(&own);
        let e0 = m.total_energy();
        let area: Vec<usize> = (0..n).collect();
        let saved = m.save_caches(&area);
        // Two neighbours swap blobs, then swap back: every cache is put back.
        let (a, b) = (0, m.reference.neighbours[0][0]);
        let mut swapped_pair = own.clone();
        swapped_pair.swap(a, b);
        m.set_assignment(&swapped_pair);
        let swapped = m.total_energy();
        m.set_assignment(&own);
        m.restore_caches(&area, &saved);
        assert!((0..n).all(|i| m.terms[i].get().is_some()));
        assert_eq!(m.total_energy().to_bits(), e0.to_bits());
        // Swapped again and restored from the unswapped state: the pair and its neighbours
        // keep no cache of the state they are no longer in.
        m.set_assignment(&swapped_pair);
        m.restore_caches(&area, &saved);
        for i in [a, b]
            .iter()
            .flat_map(|&x| std::iter::once(x).chain(m.reference.neighbours[x].iter().copied()))
        {
            assert!(m.terms[i].get().is_none(), "marker {i}");
        }
        let fresh = {
            let mut f = array.matching(&blobs, &params);
            f.set_assignment(&m.assignment);
            f.total_energy()
        };
        assert_eq!(m.total_energy().to_bits(), fresh.to_bits());
        assert_eq!(fresh.to_bits(), swapped.to_bits());
    }
}
