//! Sparse minimum-cost assignment with an opt-out per row.
//!
//! Each row (a marker) may take one of its candidate columns (blobs) at the candidate's cost,
//! or stay unassigned at its own `unassigned_cost`; each column goes to at most one row. The
//! total cost is minimised exactly by successive shortest augmenting paths (Dijkstra on reduced
//! costs with dual potentials, as in the Hungarian method), visiting only the candidate edges:
//! when most rows have a clear best column, each augmentation touches a handful of nodes.
//!
//! With costs `|blob − prediction|²` this is optimal transport with a quadratic cost: it prefers
//! many small displacements to one long one, so a region dragged by nearly a marker pitch is
//! matched to its own blobs instead of its neighbours' (which would leave a hole and a long jump
//! at the region's edge).
//!
//! ```
//! use visuotact_vision::assign::{assign_min_cost, Candidates};
//! // Two rows competing for column 0; row 1 can also take column 1 at a higher cost.
//! let mut c = Candidates::default();
//! c.push_row(&[(0, 1.0)], 5.0);
//! c.push_row(&[(0, 0.5), (1, 2.0)], 5.0);
//! let a = assign_min_cost(&c, 2);
//! assert_eq!(a.columns, vec![Some(0), Some(1)]);
//! assert!((a.cost - 3.0).abs() < 1e-12);
//! ```

use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// The candidate edges of every row, in compressed form.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Candidates {
    starts: Vec<usize>,
    edges: Vec<(usize, f64)>,
    unassigned: Vec<f64>,
}

impl Candidates {
    /// Clears every row, keeping the buffers.
    pub fn clear(&mut self) {
        self.starts.clear();
        self.edges.clear();
        self.unassigned.clear();
    }

    /// Adds a row with its `(column, cost)` candidates and the cost of leaving it unassigned.
    /// Costs are finite and non-negative; a candidate cost that is not finite is never taken,
    /// and an opt-out cost that is not finite counts as twice the largest finite cost plus one.
    pub fn push_row(&mut self, candidates: &[(usize, f64)], unassigned_cost: f64) {
        self.begin_row();
        self.edges.extend_from_slice(candidates);
        self.end_row(unassigned_cost);
    }

    /// Starts a row whose candidates follow with [`Candidates::push_edge`].
    pub fn begin_row(&mut self) {
        if self.starts.is_empty() {
            self.starts.push(0);
        }
    }

    /// Adds a candidate to the row begun last.
    pub fn push_edge(&mut self, column: usize, cost: f64) {
        self.edges.push((column, cost));
    }

    /// Ends the row begun last.
    pub fn end_row(&mut self, unassigned_cost: f64) {
        self.starts.push(self.edges.len());
        self.unassigned.push(unassigned_cost);
    }

    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.unassigned.len()
    }

    fn row(&self, i: usize) -> &[(usize, f64)] {
        &self.edges[self.starts[i]..self.starts[i + 1]]
    }

    /// What an opt-out cost that is not finite counts as (`None` when every one is finite, the
    /// usual case: nothing to scan). Such costs (a garbled sensor file's numbers give them)
    /// must not break the search: twice the largest finite cost plus one (capped far from
    /// overflow) keeps every row's private node reachable.
    fn opt_out_cap(&self) -> Option<f64> {
        if self.unassigned.iter().all(|x| x.is_finite()) {
            return None;
        }
        let largest = self
            .edges
            .iter()
            .map(|e| e.1)
            .chain(self.unassigned.iter().copied())
            .filter(|x| x.is_finite())
            .fold(0.0f64, |a, x| a.max(x.abs()));
        Some(2.0 * largest.min(1e300) + 1.0)
    }

    /// Row `i`'s opt-out cost as the search takes it: its own, or `cap` where that is not finite.
    fn opt_out(&self, i: usize, cap: Option<f64>) -> f64 {
        match cap {
            Some(cap) if !self.unassigned[i].is_finite() => cap,
            _ => self.unassigned[i],
        }
    }
}

/// An optimal assignment.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Assignment {
    /// The column of each row, `None` when it is left unassigned.
    pub columns: Vec<Option<usize>>,
    /// The total cost.
    pub cost: f64,
}

#[derive(Clone, Copy, PartialEq)]
struct Entry(f64, usize);

impl Eq for Entry {}

impl Ord for Entry {
    fn cmp(&self, other: &Self) -> Ordering {
        // Min-heap on the distance, ties to the lower node.
        other.0.total_cmp(&self.0).then(other.1.cmp(&self.1))
    }
}

impl PartialOrd for Entry {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// Dijkstra state of one augmentation, reset between rows by visiting only what it touched.
struct Search {
    dist: Vec<f64>,
    from: Vec<usize>,
    done: Vec<bool>,
    touched: Vec<usize>,
    finalized: Vec<usize>,
    heap: BinaryHeap<Entry>,
}

impl Search {
    fn new(nodes: usize) -> Self {
        Self {
            dist: vec![f64::INFINITY; nodes],
            from: vec![usize::MAX; nodes],
            done: vec![false; nodes],
            touched: Vec::new(),
            finalized: Vec::new(),
            heap: BinaryHeap::new(),
        }
    }

    /// Offers every node of row `i`'s edges a path through `i` of length `base` plus the
    /// reduced edge cost.
    fn relax(
        &mut self,
        edges: impl Iterator<Item = (usize, f64)>,
        i: usize,
        base: f64,
        u: &[f64],
        v: &[f64],
    ) {
        for (j, cost) in edges {
            if self.done[j] {
                continue;
            }
            let d = base + (cost - u[i] - v[j]).max(0.0);
            if d < self.dist[j] {
                if self.dist[j].is_infinite() {
                    self.touched.push(j);
                }
                self.dist[j] = d;
                self.from[j] = i;
                self.heap.push(Entry(d, j));
            }
        }
    }

    fn reset(&mut self) {
        for &t in &self.touched {
            self.dist[t] = f64::INFINITY;
            self.from[t] = usize::MAX;
            self.done[t] = false;
        }
        self.touched.clear();
        self.finalized.clear();
        self.heap.clear();
    }
}

/// The assignment of minimum total cost of the rows of `c` to `columns` columns.
///
/// Nodes on the column side are the `columns` real columns followed by one private "stay
/// unassigned" node per row.
pub fn assign_min_cost(c: &Candidates, columns: usize) -> Assignment {
    let n = c.rows();
    let nodes = columns + n;
    // Dual potentials: reduced cost c − u[row] − v[node] ≥ 0, 0 on matched edges.
    let mut u = vec![0.0f64; n];
    let mut v = vec![0.0f64; nodes];
    let mut owner: Vec<Option<usize>> = vec![None; nodes];
    let mut matched: Vec<usize> = vec![usize::MAX; n];
    let mut s = Search::new(nodes);
    let cap = c.opt_out_cap();
    let opt_out = |i: usize| c.opt_out(i, cap);
    // Rows' edges including the private node: (node, cost).
    let edges = |i: usize| {
        c.row(i)
            .iter()
            .copied()
            .filter(|e| e.1.is_finite())
            .chain(std::iter::once((columns + i, opt_out(i))))
    };
    for r in 0..n {
        s.relax(edges(r), r, 0.0, &u, &v);
        let mut sink = usize::MAX;
        while let Some(Entry(d, j)) = s.heap.pop() {
            if s.done[j] || d > s.dist[j] {
                continue;
            }
            s.done[j] = true;
            s.finalized.push(j);
            match owner[j] {
                None => {
                    sink = j;
                    break;
                }
                Some(k) => s.relax(edges(k), k, d, &u, &v),
            }
        }
        // The private node is always reachable, so a sink exists; were it not (costs out of
        // any range), the row stays unassigned rather than the search failing.
        if sink == usize::MAX {
            s.reset();
            continue;
        }
        let big = s.dist[sink];
        // Potentials: nodes finalised before the sink move by how much shorter their path was.
        u[r] += big;
        for &j in &s.finalized {
            if j == sink {
                continue;
            }
            let delta = big - s.dist[j];
            v[j] -= delta;
            if let Some(k) = owner[j] {
                u[k] += delta;
            }
        }
        // Augment along the path back to r.
        let mut j = sink;
        loop {
            let i = s.from[j];
            let prev = matched[i];
            owner[j] = Some(i);
            matched[i] = j;
            if i == r {
                break;
            }
            j = prev;
        }
        s.reset();
    }
    let mut cost = 0.0;
    let columns_of: Vec<Option<usize>> = (0..n)
        .map(|i| {
            let j = matched[i];
            if j < columns {
                cost += c.row(i).iter().find(|e| e.0 == j).map_or(0.0, |e| e.1);
                Some(j)
            } else {
                cost += opt_out(i);
                None
            }
        })
        .collect();
    Assignment {
        columns: columns_of,
        cost,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Exhaustive minimum over every assignment (small cases).
    fn brute(c: &Candidates, columns: usize) -> f64 {
        fn go(c: &Candidates, i: usize, used: &mut Vec<bool>, acc: f64, best: &mut f64) {
            if acc >= *best {
                return;
            }
            if i == c.rows() {
                *best = acc;
                return;
            }
            go(c, i + 1, used, acc + c.unassigned[i], best);
            for &(j, cost) in c.row(i) {
                if !used[j] {
                    used[j] = true;
                    go(c, i + 1, used, acc + cost, best);
                    used[j] = false;
                }
            }
        }
        let mut best = f64::INFINITY;
        go(c, 0, &mut vec![false; columns], 0.0, &mut best);
        best
    }

    /// Costs out of range (infinite, NaN: what a garbled sensor file's numbers give) leave
    /// such candidates untaken, and every row assigned or not: no panic.
    #[test]
    fn costs_out_of_range_are_survived() {
        let mut c = Candidates::default();
        c.push_row(&[(0, f64::INFINITY), (1, f64::NAN)], f64::INFINITY);
        c.push_row(&[(0, 1.0)], f64::NAN);
        c.push_row(&[(1, 5.0)], f64::INFINITY);
        c.push_row(&[], f64::INFINITY);
        let a = assign_min_cost(&c, 2);
        assert_eq!(a.columns, vec![None, Some(0), Some(1), None]);
        // The opt-outs out of range cost twice the largest finite cost, plus one.
        assert_eq!(a.cost, 11.0 + 1.0 + 5.0 + 11.0);
    }

    #[test]
    fn matches_brute_force_on_random_sparse_problems() {
        let mut s = 7u64;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        for case in 0..400 {
            let rows = 1 + (next() * 7.0) as usize;
            let cols = 1 + (next() * 7.0) as usize;
            let mut c = Candidates::default();
            for _ in 0..rows {
                let mut e = Vec::new();
                for j in 0..cols {
                    if next() < 0.6 {
                        e.push((j, (next() * 10.0).round() / 2.0));
                    }
                }
                c.push_row(&e, 1.0 + next() * 6.0);
            }
            let a = assign_min_cost(&c, cols);
            let b = brute(&c, cols);
            assert!((a.cost - b).abs() < 1e-9, "case {case}: {} vs {b}", a.cost);
            // Feasible: each column at most once, only candidate edges.
            let mut used = vec![false; cols];
            for (i, col) in a.columns.iter().enumerate() {
                if let Some(j) = *col {
                    assert!(!used[j]);
                    used[j] = true;
                    assert!(c.row(i).iter().any(|e| e.0 == j));
                }
            }
        }
    }

    #[test]
    fn a_dragged_row_spreads_its_shift() {
        // Markers at 0..7 along a line; those at 2, 3, 4 dragged right by 0.7, 1.05, 0.7 and 5
        // by 0.2. Nearest-blob matching would give 4 the blob of 3 and leave 3 without one;
        // the quadratic cost keeps the order.
        let markers: [f64; 7] = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
        let blobs: [f64; 7] = [0.0, 1.0, 2.7, 4.05, 4.7, 5.2, 6.0];
        let mut c = Candidates::default();
        for &m in &markers {
            let e: Vec<(usize, f64)> = blobs
                .iter()
                .enumerate()
                .filter(|(_, &b)| (b - m).abs() < 1.6)
                .map(|(j, &b)| (j, (b - m) * (b - m)))
                .collect();
            c.push_row(&e, 1.6 * 1.6);
        }
        let a = assign_min_cost(&c, blobs.len());
        assert_eq!(a.columns, (0..7).map(Some).collect::<Vec<_>>());
    }
}
