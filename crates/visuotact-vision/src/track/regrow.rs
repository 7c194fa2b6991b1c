//! Regrowing a torn reading: the runner-up no local move reaches.
//!
//! A reading can be torn where lattice neighbours' displacements differ by about a step, its
//! parts each smooth: a dome whose every ring of pins is read turned one step about the centre
//! (the tears along the rays where the sides of its hexagonal rings meet) costs more than the
//! right reading, yet no region or part shift mends it, as both sides of each tear hold whole
//! rings (the real 331-pin TacTip's deep, slid frames: test
//! `tactip331_rings_are_not_read_turned_a_step`). Grown again from one patch of itself, the
//! whole field follows that patch's motion, and the offset search puts a field read a whole
//! step off back.

use super::slide::RunnerUp;
use super::solve::Matching;

/// Order-free, readings regrown from a patch of the one found, for a reading torn where
/// lattice neighbours disagree by about a step: the largest two parts that move smoothly (a
/// reading torn into parts read a step apart), and the central marker with its lattice
/// neighbours as read shifted by each lattice step (rings each read turned a step about the
/// centre, the tears along the rays where their sides meet). Each start is grown, refined
/// and offset-searched; the lowest is slid as a search is, and kept when its energy is lower
/// by the margin; then returns the runner-ups of the reading kept.
pub(super) fn regrow(m: &mut Matching<'_>) -> Option<Vec<RunnerUp>> {
    let (saved, e0) = (m.assignment.clone(), m.total_energy());
    let mut starts: Vec<Vec<Option<usize>>> = Vec::new();
    let parts = m.smooth_parts();
    if parts.len() >= 2 {
        for part in parts.iter().take(2) {
            let mut only = vec![None; saved.len()];
            for &i in part {
                only[i] = saved[i];
            }
            starts.push(only);
        }
    }
    let r = m.reference;
    if let Some(centre) = r.central_marker() {
        let patch: Vec<usize> = std::iter::once(centre)
            .chain(r.lattice_steps[centre].iter().flatten().copied())
            .collect();
        for d in 0..r.lattice_dirs {
            let mut only = vec![None; saved.len()];
            for &i in &patch {
                only[i] = r.lattice_steps[i][d].and_then(|k| saved[k]);
            }
            if only.iter().flatten().count() >= 3 {
                starts.push(only);
            }
        }
    }
    let mut best: Option<(f64, Vec<Option<usize>>)> = None;
    for only in starts {
        m.set_assignment(&only);
        m.grow();
        m.refine(6);
        if m.assignment == saved {
            continue;
        }
        super::search_offset(m);
        let e = m.total_energy();
        if best.as_ref().is_none_or(|b| e < b.0) {
            best = Some((e, m.assignment.clone()));
        }
    }
    if let Some((_, a)) = best {
        m.set_assignment(&a);
        let runner_ups = super::settle(m, true);
        if m.total_energy() < e0 - m.energy.params.margin {
            return Some(runner_ups);
        }
    }
    m.set_assignment(&saved);
    None
}

#[cfg(test)]
mod tests {
    use super::regrow;
    use crate::blobs::{BBox, Blob};
    use crate::track::energy::Energy;
    use crate::track::solve::Matching;
    use crate::track::{TrackParams, TrackReference};

    /// The six axial steps of a hexagonal lattice, in turn around the circle.
    const HEX: [(i64, i64); 6] = [(1, 0), (0, 1), (-1, 1), (-1, 0), (0, -1), (1, -1)];

    /// Ring `k`'s sites of a hexagonal array in turn around it (the centre for `k = 0`).
    fn ring(k: i64) -> Vec<(i64, i64)> {
        if k == 0 {
            return vec![(0, 0)];
        }
        let mut at = (HEX[4].0 * k, HEX[4].1 * k);
        let mut out = Vec::new();
        for d in HEX {
            for _ in 0..k {
                out.push(at);
                at = (at.0 + d.0, at.1 + d.1);
            }
        }
        out
    }

    fn disc(x: f64, y: f64, area_px: u32) -> Blob {
        let r = (f64::from(area_px) / std::f64::consts::PI).sqrt();
        Blob {
            area_px,
            x_px: x,
            y_px: y,
            mu20_px2: r * r / 4.0,
            mu11_px2: 0.0,
            mu02_px2: r * r / 4.0,
            bbox: BBox {
                x0: (x - r) as u32,
                y0: (y - r) as u32,
                x1: (x + r) as u32 + 1,
                y1: (y + r) as u32 + 1,
            },
            touches_border: false,
        }
    }

    /// A 91-pin hexagonal array slid 0.3 and 0.2 pitches, read with every ring turned one
    /// step: the reading is torn, and regrown it is the right one, every pin on its own blob.
    #[test]
    fn rings_read_turned_a_step_are_regrown_whole() {
        let pitch = 12.0;
        let sites: Vec<(i64, i64)> = (0..=5).flat_map(ring).collect();
        let at = |s: (i64, i64)| {
            let (q, r) = (s.0 as f64, s.1 as f64);
            (
                100.0 + pitch * (q + 0.5 * r),
                100.0 + pitch * r * 0.75_f64.sqrt(),
            )
        };
        let positions: Vec<(f64, f64)> = sites.iter().map(|&s| at(s)).collect();
        let n = positions.len();
        let mut reference = TrackReference::new(positions.clone(), vec![50.0; n]);
        reference.take_lattice(&sites, &HEX);
        let blobs: Vec<Blob> = positions
            .iter()
            .map(|p| disc(p.0 + 0.3 * pitch, p.1 + 0.2 * pitch, 50))
            .collect();
        // Each ring's pin takes the blob of the next pin around it.
        let index = |s: (i64, i64)| sites.iter().position(|&t| t == s).unwrap();
        let mut turned = vec![None; n];
        for k in 0..=5 {
            let r = ring(k);
            for (j, &s) in r.iter().enumerate() {
                turned[index(s)] = Some(index(r[(j + 1) % r.len()]));
            }
        }
        let params = TrackParams::default();
        let energy = Energy {
            reference: &reference,
            params: &params,
            view: None,
        };
        let mut m = Matching::new(&reference, &blobs, n, energy, positions, (0.0, 0.0));
        m.set_assignment(&turned);
        assert!(m.torn());
        let e_turned = m.total_energy();
        assert!(regrow(&mut m).is_some());
        let right: Vec<Option<usize>> = (0..n).map(Some).collect();
        assert_eq!(m.assignment, right);
        assert!(m.total_energy() < e_turned - params.margin);
    }
}
