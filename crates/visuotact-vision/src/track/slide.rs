//! Regions read a lattice step off: the runner-up every lattice tracker must compare.
//!
//! A patch dragged by about a pitch can be read one lattice step off: each marker of a row
//! takes the blob of the next one along the drag, leaving a hole (a marker in view without a
//! blob) at one end of the row and a blob without a marker at the other. Shifting the reading
//! back marker by marker raises the energy (each marker alone then shears against its
//! neighbours): the region has to move as one. So for every cluster of holes (holes within
//! two lattice steps of each other) and every lattice direction `d`, the **region** is the
//! holes' chains along `d` — the hole takes the blob of its neighbour one step along `d`,
//! that neighbour the next one's, and so on to the first marker whose next one holds no
//! blob, which takes the free blob of least cost near its new prediction (or none) — and the
//! whole reading with those chains shifted is refined and compared by energy. The holes of
//! one region may lie far apart (at the back of each row): the chains along `d` of holes in
//! different clusters that touch make a region too. A move that lowers the energy by the
//! margin is kept (and the search repeated); the others are the runner-ups: a region whose
//! shift costs less than the margin more leaves its markers ambiguous.

use super::index::parts;
use super::solve::Matching;

/// A runner-up within the margin of the reading kept: the markers whose blob the move changed.
pub(super) struct RunnerUp {
    pub markers: Vec<usize>,
}

impl Matching<'_> {
    /// Markers without a blob where they should be seen (at least half their lost cost).
    fn holes(&self) -> Vec<usize> {
        let half_lost = 0.25 * self.energy.gate_cost();
        (0..self.assignment.len())
            .filter(|&i| {
                if self.assignment[i].is_some() || self.support[i] == 0 {
                    return false;
                }
                let p = self.predict_or_start(i);
                self.energy.lost_cost_at(i, &p) >= half_lost
            })
            .collect()
    }

    /// The chain from hole `h` along direction `d`: `h`, then each next marker one step along
    /// `d` while it holds a blob (at most `max_len` markers); and its length up to the first
    /// marker whose blob has a free blob one lattice step beyond it (where it would go once
    /// shifted), or its whole length.
    fn chain(&self, h: usize, d: usize, max_len: usize) -> (Vec<usize>, usize) {
        let steps = &self.reference.lattice_steps;
        let mut path = vec![h];
        let mut end = None;
        while path.len() < max_len {
            let last = path[path.len() - 1];
            let Some(next) = steps[last].get(d).copied().flatten() else {
                break;
            };
            let Some(j) = self.assignment[next].filter(|_| !path.contains(&next)) else {
                break;
            };
            path.push(next);
            // One lattice step beyond the blob, as the blobs before it are spaced (the
            // reference's step, scaled, for the first).
            let b = (self.blobs[j].x_px, self.blobs[j].y_px);
            let back = self.assignment[last].map_or_else(
                || {
                    let (p, q) = (
                        self.reference.positions[last],
                        self.reference.positions[next],
                    );
                    (b.0 - (q.0 - p.0), b.1 - (q.1 - p.1))
                },
                |k| (self.blobs[k].x_px, self.blobs[k].y_px),
            );
            let beyond = (2.0 * b.0 - back.0, 2.0 * b.1 - back.1);
            let gate = self.params_gate_px(next);
            let mut free = false;
            self.index.near(beyond, gate, |k, _| {
                free |= k < self.usable && self.owner[k].is_none()
            });
            if free && end.is_none() {
                end = Some(path.len());
            }
        }
        let len = end.unwrap_or(path.len());
        (path, len)
    }

    /// The chain from hole `h` that follows costs: `h`, then the holder of the blob that
    /// suits the last marker best (other than its own, within its gate), while that blob is
    /// held, at most `max_len` markers (its whole length to start from).
    fn chain_by_cost(&self, h: usize, max_len: usize) -> (Vec<usize>, usize) {
        let mut path = vec![h];
        let mut cands = Vec::new();
        while path.len() < max_len {
            let last = path[path.len() - 1];
            let pred = self.predict_or_start(last);
            let own = self.assignment[last];
            self.candidates(last, pred, |j| Some(j) == own, &mut cands);
            let Some(&(j, _)) = cands.iter().min_by(|a, b| a.1.total_cmp(&b.1)) else {
                break;
            };
            match self.owner[j] {
                Some(k) if !path.contains(&k) => path.push(k),
                _ => break,
            }
        }
        let len = path.len();
        (path, len)
    }

    /// The energy of the markers in `area` and the clutter among `blobs`.
    fn local_energy(&self, area: &[usize], blobs: &[usize]) -> f64 {
        let clutter = blobs
            .iter()
            .filter(|&&j| j < self.usable && self.owner[j].is_none())
            .count() as f64
            * self.energy.clutter_cost();
        clutter + area.iter().map(|&i| self.term(i)).sum::<f64>()
    }

    /// The markers a change of `path` can affect (it and its neighbours) and the blobs it
    /// may take or leave.
    fn reach_of(&self, path: &[usize]) -> (Vec<usize>, Vec<usize>) {
        let mut area: Vec<usize> = Vec::new();
        let mut blobs: Vec<usize> = Vec::new();
        for &i in path {
            area.push(i);
            area.extend(self.reference.neighbours[i].iter().copied());
            blobs.extend(self.assignment[i]);
            let pred = self.predict_or_start(i);
            self.index
                .near(pred.at, 1.5 * self.energy.gate_px(i, &pred), |j, _| {
                    blobs.push(j)
                });
        }
        area.sort_unstable();
        area.dedup();
        blobs.sort_unstable();
        blobs.dedup();
        (area, blobs)
    }
}

/// The region moves measured so far: the best lowering the energy by the margin (with its
/// energy change), and the runner-ups within it.
#[derive(Default)]
struct Moves {
    best: Option<(f64, Vec<Vec<usize>>)>,
    runner_ups: Vec<RunnerUp>,
}

/// One chain of a move: its markers, their blobs before the move, the length it starts at and
/// the length applied now (1: as before).
struct Chain {
    path: Vec<usize>,
    held: Vec<Option<usize>>,
    start: usize,
    len: usize,
    area: Vec<usize>,
    blobs: Vec<usize>,
}

impl Matching<'_> {
    /// Sets `c` to be shifted cut to `len`: each of its first `len - 1` markers takes the
    /// next one's blob, the `len`-th the free blob of least cost within its gate (or none),
    /// the rest their blobs from before the move (all of them for `len < 2`). Only the
    /// markers whose blob changes are moved.
    fn set_chain_len(&mut self, c: &mut Chain, len: usize) {
        let target = |k: usize| {
            if k + 1 < len {
                c.held[k + 1]
            } else {
                c.held[k]
            }
        };
        let last = (len >= 2).then(|| c.path[len - 1]);
        for (k, &i) in c.path.iter().enumerate() {
            // Every blob the chain held is another marker's now: the last leaves it too.
            let moves = if Some(i) == last {
                self.assignment[i].is_some_and(|j| c.held.contains(&Some(j)))
            } else {
                self.assignment[i] != target(k)
            };
            if moves {
                self.release(i);
            }
        }
        for (k, &i) in c.path.iter().enumerate() {
            if Some(i) != last && self.assignment[i] != target(k) {
                if let Some(j) = target(k) {
                    self.take(i, j);
                }
            }
        }
        c.len = len;
        let Some(last) = last else {
            return;
        };
        // Its own blob aside (a marker's prediction never uses its own blob), the free blob
        // that suits it best.
        let pred = self.predict_or_start(last);
        let own = self.assignment[last];
        let mut cands = Vec::new();
        self.candidates(
            last,
            pred,
            |j| self.owner[j].is_some() && Some(j) != own,
            &mut cands,
        );
        let best = cands
            .iter()
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .filter(|b| b.1 < self.energy.unmatched_cost_at(last, &pred))
            .map(|b| b.0);
        if best != own {
            self.release(last);
            if let Some(j) = best {
                self.take(last, j);
            }
        }
    }

    /// Sets every chain's length (all back first, then each in turn), returning the energy
    /// of `area`/`blobs`.
    fn set_lengths(
        &mut self,
        chains: &mut [Chain],
        lens: &[usize],
        area: (&[usize], &[usize]),
    ) -> f64 {
        // The chains change markers of the area only: where the lengths leave a marker and its
        // neighbours as they were, its prediction and term are kept.
        let saved = self.save_caches(area.0);
        for c in chains.iter_mut() {
            self.set_chain_len(c, 1);
        }
        for (c, &l) in chains.iter_mut().zip(lens) {
            self.set_chain_len(c, l);
        }
        self.restore_caches(area.0, &saved);
        self.local_energy(area.0, area.1)
    }

    /// Coordinate descent over each chain's length from the lengths applied now (one shorter,
    /// one longer, none, or its start; at least one chain moving), each change measured over
    /// the markers it can affect; at most three sweeps.
    fn descend(&mut self, chains: &mut [Chain]) {
        for _ in 0..3 {
            let mut changed = false;
            for k in 0..chains.len() {
                let cur = chains[k].len;
                let (ar, bl) = (chains[k].area.clone(), chains[k].blobs.clone());
                // The energy of the chain's reach as it stands (changed only by a kept move).
                let mut before: Option<f64> = None;
                for len in [1, cur.saturating_sub(1), cur + 1, chains[k].start] {
                    if len == 0 || len > chains[k].path.len() || len == chains[k].len {
                        continue;
                    }
                    if len < 2 && chains.iter().enumerate().all(|(q, c)| q == k || c.len < 2) {
                        continue;
                    }
                    let e0 = *before.get_or_insert_with(|| self.local_energy(&ar, &bl));
                    let old = chains[k].len;
                    // The chain changes markers of its reach only: undone, the reach's
                    // predictions and terms are as they were.
                    let saved = self.save_caches(&ar);
                    self.set_chain_len(&mut chains[k], len);
                    let e = self.local_energy(&ar, &bl);
                    if e < e0 - 1e-9 {
                        changed = true;
                        before = Some(e);
                    } else {
                        self.set_chain_len(&mut chains[k], old);
                        self.restore_caches(&ar, &saved);
                    }
                }
            }
            if !changed {
                break;
            }
        }
    }

    /// The best lengths of `chains` shifted together and the energy change. Two starts —
    /// every chain to where a free blob lies beyond it, and every chain cut to the one common
    /// length that costs least — each followed by coordinate descent over each chain's length
    /// (one shorter, one longer, none, or its start), the change of one chain measured over
    /// the markers it can affect. A chain cut to length 1 leaves its hole as it is; at least
    /// one chain must move. Leaves the matching as it was.
    fn best_lengths(&mut self, paths: Vec<(Vec<usize>, usize)>) -> (Vec<Vec<usize>>, f64) {
        let mut chains: Vec<Chain> = Vec::new();
        for (path, start) in paths {
            // Chains must not share markers.
            if chains
                .iter()
                .any(|c| c.path.iter().any(|i| path.contains(i)))
            {
                continue;
            }
            let (area, blobs) = self.reach_of(&path);
            let held = path.iter().map(|&i| self.assignment[i]).collect();
            chains.push(Chain {
                path,
                held,
                start,
                len: 1,
                area,
                blobs,
            });
        }
        let mut area: Vec<usize> = chains.iter().flat_map(|c| c.area.iter().copied()).collect();
        let mut blobs: Vec<usize> = chains
            .iter()
            .flat_map(|c| c.blobs.iter().copied())
            .collect();
        area.sort_unstable();
        area.dedup();
        blobs.sort_unstable();
        blobs.dedup();
        let e0 = self.local_energy(&area, &blobs);
        let at_start = self.save_caches(&area);
        let longest = chains.iter().map(|c| c.path.len()).max().unwrap_or(1);
        let mut common: Option<(f64, Vec<usize>)> = None;
        for l in 2..=longest {
            let lens: Vec<usize> = chains.iter().map(|c| c.path.len().min(l)).collect();
            let e = self.set_lengths(&mut chains, &lens, (&area, &blobs));
            if common.as_ref().is_none_or(|c| e < c.0) {
                common = Some((e, lens));
            }
        }
        let mut starts = vec![chains.iter().map(|c| c.start).collect::<Vec<_>>()];
        starts.extend(common.map(|c| c.1));
        let mut best: Option<(f64, Vec<usize>)> = None;
        for lens in starts {
            self.set_lengths(&mut chains, &lens, (&area, &blobs));
            self.descend(&mut chains);
            // Measured over the whole region: the chains' areas overlap.
            let e_all = self.local_energy(&area, &blobs);
            if best.as_ref().is_none_or(|b| e_all < b.0) {
                best = Some((e_all, chains.iter().map(|c| c.len).collect()));
            }
        }
        for c in chains.iter_mut() {
            self.set_chain_len(c, 1);
        }
        self.restore_caches(&area, &at_start);
        let Some((e, lens)) = best else {
            return (Vec::new(), 0.0);
        };
        let moved = chains
            .iter()
            .zip(&lens)
            .filter(|(_, &l)| l >= 2)
            .map(|(c, &l)| c.path[..l].to_vec())
            .collect();
        (moved, e - e0)
    }

    /// Applies `moved` chains (each cut to its moving part) as a move.
    fn apply_moved(&mut self, moved: &[Vec<usize>]) {
        let mut chains: Vec<Chain> = moved
            .iter()
            .map(|p| Chain {
                held: p.iter().map(|&i| self.assignment[i]).collect(),
                start: p.len(),
                len: 1,
                path: p.clone(),
                area: Vec::new(),
                blobs: Vec::new(),
            })
            .collect();
        for c in &mut chains {
            let l = c.path.len();
            self.set_chain_len(c, l);
        }
    }

    /// Applies every region shift that lowers the whole reading's energy by the margin (at
    /// most eight times), each refined when that lowers the energy further (the refinement
    /// matches against fixed predictions and may undo a move the energy prefers); returns the
    /// runner-ups within the margin of the reading kept.
    pub fn slide_regions(&mut self) -> Vec<RunnerUp> {
        let margin = self.energy.params.margin;
        for _ in 0..8 {
            let (best, mut runner_ups) = self.region_moves();
            let Some(moved) = best else {
                return runner_ups;
            };
            let (before, e_before) = (self.assignment.clone(), self.total_energy());
            self.apply_moved(&moved);
            let (moved_to, e_moved) = (self.assignment.clone(), self.total_energy());
            self.refine(3);
            let mut e_after = self.total_energy();
            if e_after > e_moved {
                self.set_assignment(&moved_to);
                e_after = e_moved;
            }
            // The move is chosen on the energy of its own reach; it is kept only when it
            // lowers the whole reading's energy by the margin too (moved markers change their
            // neighbours' predictions, and theirs of further markers).
            if e_after > e_before - margin {
                self.set_assignment(&before);
                if e_after < e_before + margin {
                    let markers = moved.iter().flat_map(|p| p[1..].iter().copied()).collect();
                    runner_ups.push(RunnerUp { markers });
                }
                return runner_ups;
            }
        }
        self.region_moves().1
    }

    /// The best region shift lowering the energy by the margin, and the runner-ups within it.
    /// A region is the chains of one cluster of holes along one direction, or the chains of
    /// holes in different clusters that touch (a region read a step off may have holes far
    /// apart: at the back of each row). Each region is measured on its own copy of the
    /// matching, side by side; the outcome is as if measured one after another.
    fn region_moves(&mut self) -> (Option<Vec<Vec<usize>>>, Vec<RunnerUp>) {
        let mut moves = Moves::default();
        for (moved, de) in self.measure(self.regions()) {
            self.consider(moved, de, &mut moves);
        }
        (moves.best.map(|b| b.1), moves.runner_ups)
    }

    /// Every region a move may shift, in a fixed order (see [`Matching::region_moves`]).
    fn regions(&self) -> Vec<Vec<(Vec<usize>, usize)>> {
        let holes = self.holes();
        let mut regions = Vec::new();
        if holes.is_empty() {
            return regions;
        }
        // Each hole's chain along each lattice direction, and the chain that follows each
        // marker's best other blob (any layout, random dots included): the moves leave the
        // matching as it was, so each is found once.
        let max_len = 2 * self.energy.params.reach_pitches.ceil() as usize + 2;
        let n_dirs = self.reference.lattice_dirs;
        let chains: Vec<Vec<(Vec<usize>, usize)>> = (0..=n_dirs)
            .map(|d| {
                holes
                    .iter()
                    .map(|&h| {
                        if d < n_dirs {
                            self.chain(h, d, max_len)
                        } else {
                            self.chain_by_cost(h, max_len)
                        }
                    })
                    .collect()
            })
            .collect();
        let clusters = self.clusters(&holes);
        let mut slot = vec![0; self.assignment.len()];
        for (a, &h) in holes.iter().enumerate() {
            slot[h] = a;
        }
        let of = |along: &[(Vec<usize>, usize)], members: &[usize]| -> Vec<(Vec<usize>, usize)> {
            members
                .iter()
                .map(|&h| &along[slot[h]])
                .filter(|c| c.0.len() > 1)
                .cloned()
                .collect()
        };
        for cluster in &clusters {
            for along in &chains {
                regions.push(of(along, cluster));
            }
        }
        if clusters.len() > 1 {
            let mut cluster_of = vec![0; self.assignment.len()];
            for (c, cluster) in clusters.iter().enumerate() {
                for &h in cluster {
                    cluster_of[h] = c;
                }
            }
            for along in &chains {
                let paths = of(along, &holes);
                for part in self.touching(&paths) {
                    let c0 = cluster_of[paths[part[0]].0[0]];
                    if part.iter().any(|&a| cluster_of[paths[a].0[0]] != c0) {
                        regions.push(part.into_iter().map(|a| paths[a].clone()).collect());
                    }
                }
            }
        }
        regions.retain(|r| !r.is_empty());
        regions
    }

    /// Each region's best shift ([`Matching::best_lengths`]): the chains' moving parts and
    /// the energy change, in the regions' order. Several regions are measured side by side,
    /// each worker on its own copy of the matching (a measurement leaves it as it was).
    fn measure(&mut self, regions: Vec<Vec<(Vec<usize>, usize)>>) -> Vec<(Vec<Vec<usize>>, f64)> {
        use rayon::prelude::*;
        if regions.len() < 2 || rayon::current_num_threads() < 2 {
            return regions
                .into_iter()
                .map(|paths| self.best_lengths(paths))
                .collect();
        }
        regions
            .into_par_iter()
            .map_with(self.clone(), |m, paths| m.best_lengths(paths))
            .collect()
    }

    /// The chains that touch (share a marker, or one's marker is the other's neighbour), in
    /// connected parts.
    fn touching(&self, paths: &[(Vec<usize>, usize)]) -> Vec<Vec<usize>> {
        let r = self.reference;
        // Per chain, its markers and their neighbours.
        let reach: Vec<Vec<bool>> = paths
            .iter()
            .map(|(path, _)| {
                let mut near = vec![false; self.assignment.len()];
                for &i in path {
                    near[i] = true;
                    for &k in &r.neighbours[i] {
                        near[k] = true;
                    }
                }
                near
            })
            .collect();
        let linked = |a: usize, b: usize| paths[b].0.iter().any(|&k| reach[a][k]);
        parts(paths.len(), |_| true, |_| 0..paths.len(), linked)
    }

    /// Counts a measured region shift: the best so far when it lowers the energy by the
    /// margin, a runner-up when it costs less than the margin more.
    fn consider(&self, moved: Vec<Vec<usize>>, de: f64, moves: &mut Moves) {
        let margin = self.energy.params.margin;
        if moved.is_empty() {
            return;
        }
        if de <= -margin {
            if moves.best.as_ref().is_none_or(|b| de < b.0) {
                moves.best = Some((de, moved));
            }
        } else if de < margin {
            let markers = moved.iter().flat_map(|p| p[1..].iter().copied()).collect();
            moves.runner_ups.push(RunnerUp { markers });
        }
    }

    /// Groups holes lying within two lattice steps of each other.
    fn clusters(&self, holes: &[usize]) -> Vec<Vec<usize>> {
        let r = self.reference;
        let at = |a: usize| r.positions[holes[a]];
        let groups = parts(
            holes.len(),
            |_| true,
            |_| 0..holes.len(),
            |a, b| {
                let (pa, pb) = (at(a), at(b));
                (pa.0 - pb.0).hypot(pa.1 - pb.1) <= 2.2 * r.spacing_px[holes[a]]
            },
        );
        groups
            .into_iter()
            .map(|g| g.into_iter().map(|a| holes[a]).collect())
            .collect()
    }
}

/// Whether displacements `a` and `b` differ by under `within_px`.
fn together(a: (f64, f64), b: (f64, f64), within_px: f64) -> bool {
    (a.0 - b.0).powi(2) + (a.1 - b.1).powi(2) < within_px * within_px
}

impl Matching<'_> {
    /// The matched markers in connected parts whose displacements agree: lattice neighbours
    /// (one step apart) whose displacements differ by under half a spacing share a part. A
    /// region read a lattice step off is a part of its own (its displacements differ by a step
    /// from its neighbours' across its sides). Parts of three or more markers, largest first.
    pub fn smooth_parts(&self) -> Vec<Vec<usize>> {
        let r = self.reference;
        let mut out = parts(
            self.assignment.len(),
            |i| self.assignment[i].is_some(),
            |i| r.lattice_steps[i].iter().flatten().copied(),
            |i, k| self.move_together(i, k, 0.5),
        );
        out.retain(|p| p.len() >= 3);
        out.sort_by_key(|p| std::cmp::Reverse(p.len()));
        out
    }

    /// Whether the displacements of markers `i` and `k` (both matched) differ by under
    /// `spacings` of their spacing.
    fn move_together(&self, i: usize, k: usize, spacings: f64) -> bool {
        together(self.disp[i], self.disp[k], self.together_px(i, k, spacings))
    }

    /// `spacings` of the smaller spacing of markers `i` and `k`, pixels.
    fn together_px(&self, i: usize, k: usize, spacings: f64) -> f64 {
        spacings * self.reference.spacing_px[i].min(self.reference.spacing_px[k])
    }

    /// Whether the reading is torn: two matched lattice neighbours' displacements differ by
    /// more than the spread the energy allows a prediction (`spread_sigmas · σ`): a skin
    /// strains that far, it does not tear.
    pub fn torn(&self) -> bool {
        self.torn_by(|i| self.disp[i])
    }

    /// [`Matching::torn`] for the displacements from the reference rather than from the
    /// anchors (which, followed, are the last frame's positions, as torn as its reading).
    pub fn torn_from_rest(&self) -> bool {
        self.torn_by(|i| match self.assignment[i] {
            Some(j) => {
                let p = self.reference.positions[i];
                (self.blobs[j].x_px - p.0, self.blobs[j].y_px - p.1)
            }
            None => (0.0, 0.0),
        })
    }

    /// [`Matching::torn`] for the displacements `disp(i)` of the matched markers.
    fn torn_by(&self, disp: impl Fn(usize) -> (f64, f64)) -> bool {
        let r = self.reference;
        let p = self.energy.params;
        let spread = p.spread_sigmas * p.sigma_spacings;
        (0..self.assignment.len()).any(|i| {
            self.assignment[i].is_some()
                && r.lattice_steps[i].iter().flatten().any(|&k| {
                    self.assignment[k].is_some()
                        && !together(disp(i), disp(k), self.together_px(i, k, spread))
                })
        })
    }

    /// The lattice offsets a part may be read off by: `a` steps along one direction and `b`
    /// along the next one around (`a ≥ 1`, `a + b ≤ 2`), as lists of directions. A part is
    /// grown into from its neighbours, so it is read off them by a step or two, not more.
    fn offsets(&self) -> Vec<Vec<usize>> {
        let n = self.reference.lattice_dirs;
        let reach = 2;
        let mut out = Vec::new();
        for d in 0..n {
            for a in 1..=reach {
                for b in 0..=reach - a {
                    let mut steps = vec![d; a];
                    steps.extend(std::iter::repeat_n((d + 1) % n, b));
                    out.push(steps);
                }
            }
        }
        out
    }

    /// The marker `steps` lattice steps from `i` (`None` off the layout).
    fn stepped(&self, i: usize, steps: &[usize]) -> Option<usize> {
        steps
            .iter()
            .try_fold(i, |k, &d| self.reference.lattice_steps[k][d])
    }

    /// Shifts each part but the largest by each lattice offset within reach (its markers take
    /// the blobs of the markers that far along; a marker outside it whose blob it takes is left
    /// without one), refines, and keeps a move that lowers the energy by the margin; repeated
    /// while one does (at most eight times). Returns the runner-ups within the margin of the
    /// reading kept.
    pub fn shift_parts(&mut self) -> Vec<RunnerUp> {
        for _ in 0..8 {
            let (best, runner_ups) = self.part_moves();
            match best {
                Some(a) => self.set_assignment(&a),
                None => return runner_ups,
            }
        }
        self.part_moves().1
    }

    /// The best part shift lowering the energy by the margin (the whole new assignment), and
    /// the runner-ups within it.
    fn part_moves(&mut self) -> (Option<Vec<Option<usize>>>, Vec<RunnerUp>) {
        let margin = self.energy.params.margin;
        let mut runner_ups = Vec::new();
        let offsets = self.offsets();
        let parts = self.smooth_parts();
        if offsets.is_empty() || parts.len() < 2 {
            return (None, runner_ups);
        }
        let e0 = self.total_energy();
        let saved = self.assignment.clone();
        let mut best: Option<(f64, Vec<Option<usize>>)> = None;
        for p in &parts[1..] {
            for steps in &offsets {
                let moved: Vec<(usize, Option<usize>)> = p
                    .iter()
                    .map(|&i| (i, self.stepped(i, steps).and_then(|k| saved[k])))
                    .collect();
                for &(i, _) in &moved {
                    self.release(i);
                }
                for &(i, to) in &moved {
                    if let Some(j) = to {
                        if let Some(k) = self.owner[j] {
                            self.release(k);
                        }
                        self.take(i, j);
                    }
                }
                self.refine(3);
                let e = self.total_energy();
                if e <= e0 - margin {
                    if best.as_ref().is_none_or(|b| e < b.0) {
                        best = Some((e, self.assignment.clone()));
                    }
                } else if e < e0 + margin {
                    let changed: Vec<usize> = p
                        .iter()
                        .copied()
                        .filter(|&i| self.assignment[i] != saved[i] && saved[i].is_some())
                        .collect();
                    if !changed.is_empty() {
                        runner_ups.push(RunnerUp { markers: changed });
                    }
                }
                self.set_assignment(&saved);
            }
        }
        (best.map(|b| b.1), runner_ups)
    }
}

#[cfg(test)]
mod tests {
    use crate::track::testkit::hex_array;
    use crate::track::TrackParams;

    /// Two rows of a 91-pin array, far apart, each read one step off along the row (a hole at
    /// one end, a blob without a marker at the other): the regions measured side by side give
    /// what one after another gives, and the best move shifts a row back.
    #[test]
    fn regions_measured_side_by_side_equal_one_after_another() {
        let pitch = 12.0;
        let array = hex_array(5, pitch);
        let (sites, n) = (&array.sites, array.positions.len());
        let blobs = array.blobs_slid(0.3 * pitch, 0.2 * pitch);
        let index = |s: (i64, i64)| sites.iter().position(|&t| t == s);
        let mut reading: Vec<Option<usize>> = (0..n).map(Some).collect();
        for (r, q0, q1) in [(-3, -2, 5), (3, -5, 2)] {
            for q in q0..q1 {
                reading[index((q, r)).unwrap()] = index((q + 1, r));
            }
            reading[index((q1, r)).unwrap()] = None;
        }
        let params = TrackParams::default();
        let mut m = array.matching(&blobs, &params);
        m.set_assignment(&reading);
        let regions = m.regions();
        assert!(regions.len() >= 2, "{} regions", regions.len());
        let pool = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
        };
        let alone = pool(1).install(|| m.measure(regions.clone()));
        let side_by_side = pool(3).install(|| m.measure(regions.clone()));
        assert_eq!(alone, side_by_side);
        assert_eq!(
            m.assignment, reading,
            "measuring leaves the matching as it was"
        );
        assert!(alone.iter().any(|(_, de)| *de <= -params.margin));
    }
}
