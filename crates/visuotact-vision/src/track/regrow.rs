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
    use crate::track::testkit::{hex_array, ring};
    use crate::track::TrackParams;

    /// A 91-pin hexagonal array slid 0.3 and 0.2 pitches, read with every ring turned one
    /// step: the reading is torn, and regrown it is the right one, every pin on its own blob.
    #[test]
    fn rings_read_turned_a_step_are_regrown_whole() {
        let pitch = 12.0;
        let array = hex_array(5, pitch);
        let (sites, n) = (&array.sites, array.positions.len());
        let blobs = array.blobs_slid(0.3 * pitch, 0.2 * pitch);
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
        let mut m = array.matching(&blobs, &params);
        m.set_assignment(&turned);
        assert!(m.torn());
        let e_turned = m.total_energy();
        assert!(regrow(&mut m).is_some());
        let right: Vec<Option<usize>> = (0..n).map(Some).collect();
        assert_eq!(m.assignment, right);
        assert!(m.total_energy() < e_turned - params.margin);
    }
}
