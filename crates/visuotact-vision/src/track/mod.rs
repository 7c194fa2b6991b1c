//! Matching reference markers to the blobs of a frame: every frame on its own (order-free), or
//! starting from the last frame's positions (followed, for video).
//!
//! One model, one energy, one assignment:
//! - `predict`: every marker is predicted from a local affine fit of its matched lattice
//!   neighbours' motion (the skin's motion is smooth; the layout's topology carries the
//!   prediction across a field stretched by pitches).
//! - `energy`: a marker taking a blob costs its residual to the prediction (in spacings)
//!   plus how unlike its expected size and shape the blob is and a weak motion prior; a
//!   marker without a blob costs the lost cost, scaled by how visible it should be, and a
//!   blob without a marker the same as clutter.
//! - `solve`: seeds, growth and a global minimum-cost assignment minimise the energy;
//!   order-free on a lattice, the reading shifted by whole lattice steps is compared too. A
//!   multi-start search: a reading that leaves a blob or a marker unexplained is searched
//!   again from a firmer motion prior, then from seeds judged each on its own, the lowest
//!   energy kept; the other starts are searched side by side, and beside the first where the
//!   last frame of a video needed them (the same reading, sooner). Followed, a reading torn
//!   from the reference that leaves something unexplained (carried a lattice step off by an
//!   earlier frame) is compared with the frame read on its own, on the energy from the
//!   reference (test `a_block_followed_a_row_off_is_read_right_again`).
//! - `regrow`: a reading torn where lattice neighbours disagree by about a step is grown again
//!   from a patch of itself (its largest smooth parts, its centre shifted by each step: a
//!   dome's rings each read turned a step, test `tactip331_rings_are_not_read_turned_a_step`).
//! - `slide`: the runner-ups a lattice tracker must compare — regions read a lattice step
//!   off (chains from markers without a blob) and smooth parts shifted by a step or two —
//!   kept when they lower the energy by the margin.
//! - `pieces`: a marker's dot broken in pieces (by the threshold, or a line drawn across it) is
//!   measured on its pieces together when that lowers the energy; order-free, every reading
//!   the search compares is charged so (a broken dot is one marker's, not two markers' a step
//!   apart).
//! - `sites`: a numbered array's lattice sites where the reference saw no pin (hidden under a
//!   reference in contact) are followed as markers absent for free and never reported, so
//!   that the pin's blob, once it shows, has an owner (test
//!   `a_pin_hidden_at_rest_is_an_unseen_site_not_a_neighbours_blob`). Pins the reference
//!   showed but the numbering skipped (a seam in a reference in contact) are followed the same
//!   way, their absence charged as any marker's (test
//!   `pins_the_numbering_left_out_are_followed_not_taken`).
//! - `ambiguity`, `split`: a blob may hold two markers (a hypothesis on the energy, split by
//!   its moments when they are two discs'); a marker is ambiguous when a runner-up reading
//!   costs less than one margin more than the best. Before tracking, a blob of markers packed
//!   together is parted where the grey image dips between them when every part comes down
//!   to one marker's size ([`crate::separate`]).
//!
//! All tuning is [`TrackParams`] (stored in the sensor file). No marker is ever given a blob
//! just because it is the nearest one to its rest position; markers left without a blob are
//! reported [`MarkerStatus::Lost`], [`MarkerStatus::Merged`] (their blob holds a neighbour
//! too) or [`MarkerStatus::Ambiguous`]; their feature cells stay empty and other markers'
//! columns never shift. Two merged markers whose blob has about their two areas are split by
//! the blob's second moments ([`MarkerStatus::Split`]: a position, no area; under 0.6 px from
//! the truth for two discs of radius 10 px overlapping by a pixel; touching, the grey image
//! parts them first; test `a_merged_pair_is_parted_or_split_by_its_moments`).

mod ambiguity;
mod energy;
mod index;
mod pieces;
mod predict;
mod regrow;
mod rings;
mod sites;
mod slide;
mod solve;
mod split;
#[cfg(test)]
mod testkit;

use serde::{Deserialize, Serialize};

use crate::blobs::Blob;
use crate::layout::k_nearest_all;

pub(crate) use energy::ellipse_fill;
pub use sites::unseen_sites;

/// What happened to one reference marker in one frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MarkerStatus {
    /// Matched to exactly one blob.
    Ok,
    /// No blob near where the marker should be.
    Lost,
    /// Its blob merged with a neighbour's.
    Merged,
    /// Two or more blobs equally plausible.
    Ambiguous,
    /// Its blob merged with one neighbour's, and the pair was split by the blob's moments: the
    /// position is estimated ([`TrackResult::split_px`]), area and eccentricity are unknown.
    Split,
}

impl MarkerStatus {
    /// Every status.
    pub const ALL: [MarkerStatus; 5] = [
        MarkerStatus::Ok,
        MarkerStatus::Lost,
        MarkerStatus::Merged,
        MarkerStatus::Ambiguous,
        MarkerStatus::Split,
    ];

    /// Name used in tables.
    pub fn name(self) -> &'static str {
        match self {
            MarkerStatus::Ok => "ok",
            MarkerStatus::Lost => "lost",
            MarkerStatus::Merged => "merged",
            MarkerStatus::Ambiguous => "ambiguous",
            MarkerStatus::Split => "split",
        }
    }

    /// Whether the marker has a measured position this frame ([`MarkerStatus::Ok`] or
    /// [`MarkerStatus::Split`]).
    pub fn has_position(self) -> bool {
        matches!(self, MarkerStatus::Ok | MarkerStatus::Split)
    }
}

/// All the tracker's tuning: the energy's scales, its margin and the order-free search's
/// reach. Distances are in units of each marker's spacing to its nearest neighbour, scaled
/// by the local magnification.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct TrackParams {
    /// How far the order-free search shifts the whole reading, in lattice steps: a field
    /// moved by this many pitches everywhere is still read right. 5: a TacTip tilted 25° and
    /// slid 5 mm from a reference itself tilted and slid the other way moves its pins about
    /// four pitches.
    pub reach_pitches: f64,
    /// The typical motion of a marker from where the starting motion puts it (the reference
    /// after the registration's overall shift, or its last position when followed), in
    /// spacings: the scale of the weak motion prior, which decides between readings the rest
    /// of the energy cannot tell apart. 4: a TacTip's pins stray up to three pitches from the
    /// overall shift under tilt and slide; a third of a grid, all 39 markers at rest, read a
    /// row off costs more than the margin.
    pub motion_spacings: f64,
    /// How far from its prediction a blob may lie and still be the marker's, in spacings (a
    /// blob at the gate costs as much as the marker lost and the blob left over). 0.6: a
    /// prediction from neighbours that lag a drag falls up to about half a spacing short.
    pub gate_spacings: f64,
    /// Typical error of a prediction from the neighbours, in spacings: the scale of the
    /// position term. 0.2: the residual of a local affine fit under a deep press or a drag of
    /// a pitch.
    pub sigma_spacings: f64,
    /// How far the neighbours' disagreement (the spread of their displacements about one
    /// affine motion) may widen the position's scale, in multiples of
    /// [`TrackParams::sigma_spacings`]. 3: a drag shears a large dot a pitch and a half
    /// against the neighbours that lag it (the simulator's dots); 1 suits a sensor whose
    /// skin moves smoothly between sparse markers (real GelSight Mini video 5 under large
    /// slides: marker-frames read over 10 px off the vendor's, 82 → 49), where a wider bound
    /// excuses a region read a lattice step off.
    pub spread_sigmas: f64,
    /// Typical relative change of a marker's blob area from its expected size: the scale of
    /// the area term (widened by the pixel noise of a small marker's outline). 0.35: binarised
    /// pins swell and shrink by about a third with the light.
    pub area_sigma: f64,
    /// The energy gap under which a runner-up reading makes a marker ambiguous, in the
    /// energy's units (a squared residual of one sigma costs 1). 2: a reading about 1.4 sigma
    /// worse is still plausible.
    pub margin: f64,
}

impl TrackParams {
    /// The defaults.
    pub const DEFAULT: Self = Self {
        reach_pitches: 5.0,
        motion_spacings: 4.0,
        gate_spacings: 0.6,
        sigma_spacings: 0.2,
        spread_sigmas: 3.0,
        area_sigma: 0.35,
        margin: 2.0,
    };

    /// Each setting: its name (as the field's), where it is held and the largest value it
    /// may take.
    fn settings(&mut self) -> [(&'static str, &mut f64, f64); 7] {
        [
            ("reach_pitches", &mut self.reach_pitches, 100.0),
            ("motion_spacings", &mut self.motion_spacings, 100.0),
            ("gate_spacings", &mut self.gate_spacings, 100.0),
            ("sigma_spacings", &mut self.sigma_spacings, 100.0),
            ("spread_sigmas", &mut self.spread_sigmas, 1e6),
            ("area_sigma", &mut self.area_sigma, 100.0),
            ("margin", &mut self.margin, 1e6),
        ]
    }

    /// The defaults with the settings of `text` over them: `name=value` pairs separated by
    /// commas (`margin=3,gate_spacings=0.45`), names as the fields; checked.
    pub fn parse_over(mut self, text: &str) -> Result<Self, crate::ConfigError> {
        for pair in text.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            let (name, value) = pair.split_once('=').ok_or_else(|| {
                crate::ConfigError::unknown("tracker setting", pair, "name=value")
            })?;
            let v: f64 = value
                .trim()
                .parse()
                .map_err(|_| crate::ConfigError::NotANumber {
                    name: format!("tracker {name}"),
                    value: value.to_string(),
                })?;
            let mut settings = self.settings();
            let Some(slot) = settings.iter_mut().find(|s| s.0 == name.trim()) else {
                let mut defaults = Self::DEFAULT;
                let names = defaults.settings().map(|s| s.0);
                let (last, rest) = (names[names.len() - 1], &names[..names.len() - 1]);
                return Err(crate::ConfigError::unknown(
                    "tracker setting",
                    name.trim(),
                    format!("{} or {last}", rest.join(", ")),
                ));
            };
            *slot.1 = v;
        }
        self.validate()?;
        Ok(self)
    }

    /// Checks the settings: each positive, finite and at most its largest value.
    pub fn validate(&self) -> Result<(), crate::ConfigError> {
        let mut copy = *self;
        for (name, v, hi) in copy.settings() {
            if !(v.is_finite() && *v > 0.0 && *v <= hi) {
                return Err(crate::ConfigError::out_of_range(
                    name,
                    *v,
                    format!("in (0, {hi}] (a tracker setting)"),
                ));
            }
        }
        Ok(())
    }
}

impl Default for TrackParams {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// The least [`TrackReference::fill_sigma`]: the shortfall of a pixelated disc of a few
/// pixels' radius, and what a reference of clean discs gets.
pub const FILL_SIGMA_FLOOR: f64 = 0.03;

/// [`TrackReference::fill_sigma`] from the markers' shapes at rest, each `(area_px, λ1·λ2)`
/// (the covariance's determinant, each variance counting the pixel as a unit square): twice
/// the RMS of how far under 1 they fill their moments' ellipse, at least
/// [`FILL_SIGMA_FLOOR`]. Twice: a contact frays blobs about twice as far as rest does
/// (GelSight Mini: the 5th percentile shortfall 0.29 in contact, 0.14–0.22 at rest).
pub fn fill_sigma_from_rest(shapes: impl IntoIterator<Item = (f64, f64)>) -> f64 {
    let (mut sum, mut count) = (0.0, 0usize);
    for (area_px, det_px4) in shapes {
        let fill = energy::fill_of(area_px, det_px4);
        if fill.is_finite() {
            sum += (1.0 - fill).max(0.0).powi(2);
            count += 1;
        }
    }
    if count == 0 {
        return FILL_SIGMA_FLOOR;
    }
    (2.0 * (sum / count as f64).sqrt()).max(FILL_SIGMA_FLOOR)
}

/// The reference markers as the tracker needs them.
#[derive(Clone, Debug)]
pub struct TrackReference {
    /// Marker positions `(x, y)` in pixels.
    pub positions: Vec<(f64, f64)>,
    /// Reference areas in pixels.
    pub areas_px: Vec<f64>,
    /// Neighbours of each marker (indices): its 12 nearest within 2.5 × its spacing, plus every
    /// marker that counts it among theirs (the relation is symmetric).
    pub neighbours: Vec<Vec<usize>>,
    /// Each marker's distance to its nearest neighbour, pixels (the local pitch: a dome's or a
    /// wide-angle lens's pitch varies across the image).
    pub spacing_px: Vec<f64>,
    /// Median spacing, pixels.
    pub pitch_px: f64,
    /// How loosely the markers' blobs fill the ellipse of their second moments at rest: the RMS
    /// of the reference markers' shortfall under 1 ([`FILL_SIGMA_FLOOR`] at least; an ideal
    /// disc fills it, printed dots under an adaptive threshold 0.75–0.99). The tolerance of the
    /// shape term, which tells one marker from two lobes: a sensor whose single markers are
    /// ragged gets no evidence from a ragged blob.
    pub fill_sigma: f64,
    /// For concentric rings, each ring's major axis in pixels: rings share a centre, so they
    /// are matched by size near the reference centre instead of by position.
    pub ring_sizes_px: Option<Vec<f64>>,
    /// How many step directions the lattice has (0 for fewer than 3 markers).
    lattice_dirs: usize,
    /// Per marker, its neighbour one step along each of the `lattice_dirs` directions.
    lattice_steps: Vec<Vec<Option<usize>>>,
    /// How many of the positions are markers; those after them are followed but never
    /// reported: pins the numbering left out, then unseen lattice sites ([`unseen_sites`]).
    markers: usize,
    /// Where the unseen lattice sites begin (after the markers and the unnumbered pins).
    unseen_from: usize,
    /// The neighbours' offsets and weights at rest, for the affine fits of a frame read on its
    /// own (computed with the neighbours, once).
    rest_around: std::sync::Arc<predict::Around>,
}

impl TrackReference {
    /// Builds neighbourhoods, spacings and lattice steps from positions and areas.
    pub fn new(positions: Vec<(f64, f64)>, areas_px: Vec<f64>) -> Self {
        let n = positions.len();
        let knn = if n > 1 {
            k_nearest_all(&positions, 12.min(n - 1))
        } else {
            vec![Vec::new(); n]
        };
        let spacing: Vec<f64> = knn
            .iter()
            .map(|v| v.first().map_or(f64::NAN, |x| x.1))
            .collect();
        let mut sorted: Vec<f64> = spacing.iter().copied().filter(|s| s.is_finite()).collect();
        sorted.sort_by(f64::total_cmp);
        let pitch_px = if sorted.is_empty() {
            // One marker: use its size as the scale.
            areas_px.first().map_or(10.0, |a| 2.0 * a.sqrt())
        } else {
            sorted[sorted.len() / 2]
        };
        let spacing_px: Vec<f64> = spacing
            .iter()
            .map(|s| if s.is_finite() { *s } else { pitch_px })
            .collect();
        let mut neighbours: Vec<Vec<usize>> = knn
            .iter()
            .enumerate()
            .map(|(i, v)| {
                v.iter()
                    .filter(|&&(_, d)| d < 2.5 * spacing_px[i])
                    .map(|&(j, _)| j)
                    .collect()
            })
            .collect();
        for i in 0..n {
            for k in 0..neighbours[i].len() {
                let j = neighbours[i][k];
                if !neighbours[j].contains(&i) {
                    neighbours[j].push(i);
                }
            }
        }
        let (lattice_dirs, lattice_steps) =
            predict::lattice_steps(&positions, &neighbours, &spacing_px);
        let rest_around = std::sync::Arc::new(predict::Around::from_parts(
            &positions,
            &neighbours,
            &spacing_px,
        ));
        Self {
            positions,
            areas_px,
            neighbours,
            spacing_px,
            pitch_px,
            fill_sigma: FILL_SIGMA_FLOOR,
            ring_sizes_px: None,
            lattice_dirs,
            lattice_steps,
            markers: n,
            unseen_from: n,
            rest_around,
        }
    }

    /// As [`TrackReference::new`], followed by unseen lattice sites ([`unseen_sites`]) at
    /// `unseen_px`, each of `unseen_area_px`: the tracker follows them as markers whose absence
    /// costs nothing (their pins were hidden at rest), so that a pin showing there is not
    /// clutter a neighbour may take; results report the markers only.
    pub fn with_unseen(
        mut positions: Vec<(f64, f64)>,
        mut areas_px: Vec<f64>,
        unseen_px: &[(f64, f64)],
        unseen_area_px: f64,
    ) -> Self {
        let markers = positions.len();
        positions.extend_from_slice(unseen_px);
        areas_px.extend(std::iter::repeat_n(unseen_area_px, unseen_px.len()));
        let mut r = Self::new(positions, areas_px);
        r.markers = markers;
        r.unseen_from = markers;
        r
    }

    /// Takes the last `count` of the markers as pins the numbering left out: followed and
    /// never reported, as the unseen sites after them, but seen at rest, so absent at the cost
    /// of any marker.
    pub(crate) fn set_unnumbered(&mut self, count: usize) {
        self.markers -= count.min(self.markers);
    }

    /// How many markers the reference has (its positions less the unnumbered pins and the
    /// unseen sites).
    pub fn markers(&self) -> usize {
        self.markers
    }

    /// The marker nearest the markers' centroid (`None` without markers).
    pub(crate) fn central_marker(&self) -> Option<usize> {
        index::nearest_centroid(&self.positions[..self.markers])
    }

    /// Whether position `i` is an unseen lattice site rather than a marker.
    pub(crate) fn is_unseen(&self, i: usize) -> bool {
        i >= self.unseen_from
    }
}

impl TrackReference {
    /// Takes the lattice's steps from the layout's numbering, as a person reads an array
    /// neighbour by neighbour: marker `i` sits at lattice site `sites[i]`, and its neighbour
    /// one step along direction `d` is the marker at `sites[i] + steps[d]` (`steps` in turn
    /// around the circle, so that consecutive ones span a cell). Every step is then taken both
    /// ways however the reference is stretched (a reference in contact), and the order-free
    /// search can shift a reading back along every step it can shift it forward.
    pub fn take_lattice(&mut self, sites: &[(i64, i64)], steps: &[(i64, i64)]) {
        let at: std::collections::HashMap<(i64, i64), usize> =
            sites.iter().enumerate().map(|(i, &s)| (s, i)).collect();
        self.lattice_steps = sites
            .iter()
            .map(|s| {
                steps
                    .iter()
                    .map(|d| at.get(&(s.0 + d.0, s.1 + d.1)).copied())
                    .collect()
            })
            .collect();
        self.lattice_dirs = steps.len();
    }
}

/// The outcome for one frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TrackResult {
    /// Blob index per marker (`None` unless the status is [`MarkerStatus::Ok`]).
    pub assignment: Vec<Option<usize>>,
    /// Status per marker.
    pub status: Vec<MarkerStatus>,
    /// Overall motion found by the registration, in pixels.
    pub shift_px: (f64, f64),
    /// Blobs given to no marker and no unseen lattice site ([`unseen_sites`]).
    pub spurious: usize,
    /// Estimated position of each [`MarkerStatus::Split`] marker (`None` for the others; empty
    /// when no marker was split).
    pub split_px: Vec<Option<(f64, f64)>>,
    /// Followed tracking: the centroid of the blob each [`MarkerStatus::Merged`] marker shares
    /// (`None` for the others; empty when there is none). Not a measurement: only where the
    /// next frame starts looking for it ([`TrackResult::followed_px`]).
    pub held_px: Vec<Option<(f64, f64)>>,
    /// Further pieces of a marker's blob: (the blob the marker holds, a piece). A marker's
    /// measurement is of its pieces together: apply [`TrackResult::merge_pieces`] to the blobs
    /// before reading positions and areas from them.
    pub pieces: Vec<(usize, usize)>,
    /// Order-free: whether the first start left a blob or a marker in view unexplained, so
    /// that the other starts were compared. The next frame of a video likely does too: a hint
    /// for its [`TrackHints::starts_side_by_side`].
    pub searched_again: bool,
}

impl TrackResult {
    /// Number of markers with a position: matched, or split from a merged pair.
    pub fn found(&self) -> usize {
        self.status.iter().filter(|s| s.has_position()).count()
    }

    /// Marker `i`'s position this frame: its blob's centroid, or its split estimate.
    pub fn position_px(&self, i: usize, blobs: &[Blob]) -> Option<(f64, f64)> {
        match self.assignment[i] {
            Some(j) => Some((blobs[j].x_px, blobs[j].y_px)),
            None => self.split_px.get(i).copied().flatten(),
        }
    }

    /// Merges each marker's further [`TrackResult::pieces`] into the blob it holds
    /// ([`Blob::union`]); the pieces themselves are left as they were.
    pub fn merge_pieces(&self, blobs: &mut [Blob]) {
        for &(j, j2) in &self.pieces {
            if let (Some(&b), Some(b2)) = (blobs.get(j), blobs.get(j2)) {
                blobs[j] = b.union(b2);
            }
        }
    }

    /// Leaves out the unseen lattice sites after the first `markers` (their blobs stay out of
    /// [`TrackResult::spurious`]: a pin is no clutter), `owner` the holder of each blob.
    fn keep_markers(&mut self, markers: usize, owner: &[Option<usize>]) {
        self.pieces
            .retain(|&(j, _)| owner[j].is_some_and(|i| i < markers));
        self.assignment.truncate(markers);
        self.status.truncate(markers);
        self.split_px.truncate(markers);
        self.held_px.truncate(markers);
    }

    /// Where the next frame of a video starts looking for marker `i`: its
    /// [`TrackResult::position_px`], or the blob it shares while reported merged
    /// ([`TrackResult::held_px`]).
    pub fn followed_px(&self, i: usize, blobs: &[Blob]) -> Option<(f64, f64)> {
        self.position_px(i, blobs)
            .or_else(|| self.held_px.get(i).copied().flatten())
    }
}

/// The part of the image where markers can be seen: a rectangle (the image or its region of
/// interest), optionally cut to a circle (a circular view).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    /// Left edge, pixels (pixel centres at integers: the first column spans −0.5..0.5).
    pub x0: f64,
    /// Top edge, pixels.
    pub y0: f64,
    /// Right edge, pixels.
    pub x1: f64,
    /// Bottom edge, pixels.
    pub y1: f64,
    /// Centre and radius of the circular view, pixels.
    pub circle: Option<((f64, f64), f64)>,
}

impl View {
    /// How far `p` lies inside the view (distance to its nearest edge; negative outside).
    pub fn depth_px(&self, p: (f64, f64)) -> f64 {
        let mut d = (p.0 - self.x0)
            .min(self.x1 - p.0)
            .min(p.1 - self.y0)
            .min(self.y1 - p.1);
        if let Some((c, r)) = self.circle {
            d = d.min(r - index::dist(p, c));
        }
        d
    }
}

/// What the tracker may use besides the blobs.
#[derive(Clone, Copy, Debug, Default)]
pub struct TrackHints<'a> {
    /// The last `cut` blobs are markers cut by the image border (dropped by the blob filter):
    /// a marker that takes one left the view and is reported lost, never measured — unless the
    /// blob is as big as the whole marker (it touches the edge without being cut by it).
    pub cut: usize,
    /// Each marker's position in an earlier frame of the same video (`None` for markers it did
    /// not have): tracking starts from there instead of from the reference.
    pub prior: Option<&'a [Option<(f64, f64)>]>,
    /// Where markers can be seen: a marker its neighbours put outside is expected to have no
    /// blob (being lost there costs nothing).
    pub view: Option<View>,
    /// Order-free: search the other starts beside the first instead of after it, when it
    /// likely leaves something unexplained (the last frame's [`TrackResult::searched_again`]).
    /// The reading is the same either way: sooner on several cores, more work where the first
    /// start explains everything.
    pub starts_side_by_side: bool,
}

/// Where a search starts: how its seeds are judged and how firm its motion prior is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Start {
    /// Seeds judged one after another, each from the seeds already taken: a field moved
    /// far from the registration is carried from seed to seed.
    Chained,
    /// As [`Start::Chained`] with the motion prior twice as firm: a region near its start
    /// is not read a step off where the weak prior lets the search wander.
    ChainedFirm,
    /// Each seed judged from the registration alone: one wrong seed cannot carry a chain of
    /// others a step off (a twist or a tilt moves a wide layout's regions by different
    /// pitches, and a chain grown from one of them tears the field where they meet).
    Independent,
}

/// Seeds, grows and refines `m` from `start`; order-free, also searches the offset and
/// shifted parts. Returns the runner-ups within the margin of the reading kept.
fn search(m: &mut solve::Matching<'_>, order_free: bool, start: Start) -> Vec<slide::RunnerUp> {
    m.seed(start == Start::Independent);
    m.grow();
    m.refine(6);
    if order_free {
        search_offset(m);
    }
    settle(m, order_free)
}

/// Order-free, the whole reading shifted by lattice steps, up to
/// [`TrackParams::reach_pitches`].
fn search_offset(m: &mut solve::Matching<'_>) {
    m.search_offset(m.energy.params.reach_pitches.ceil() as usize);
}

/// The moves after a reading is grown: region shifts and, order-free, part shifts. Returns
/// the runner-ups within the margin of the reading kept.
fn settle(m: &mut solve::Matching<'_>, order_free: bool) -> Vec<slide::RunnerUp> {
    let mut runner_ups = m.slide_regions();
    if order_free {
        runner_ups.extend(m.shift_parts());
    }
    runner_ups
}

/// Order-free, the reading another start from the registration finds, searched with `m`'s
/// parameters, the motion prior twice as firm for [`Start::ChainedFirm`]. It reads nothing of
/// `m`'s reading, so the starts are searched side by side.
fn restarted<'a>(
    m: &solve::Matching<'a>,
    view: Option<View>,
    start: Start,
) -> impl FnOnce() -> Vec<Option<usize>> + Send + 'a {
    let (reference, blobs, usable, shift) = (m.reference, m.blobs, m.usable, m.shift);
    let params = *m.energy.params;
    move || {
        let firmness = if start == Start::ChainedFirm {
            0.5
        } else {
            1.0
        };
        let own = TrackParams {
            motion_spacings: firmness * params.motion_spacings,
            ..params
        };
        let energy = energy::Energy {
            reference,
            params: &own,
            view,
        };
        let anchors = reference.positions.clone();
        let mut other = solve::Matching::new(reference, blobs, usable, energy, anchors, shift);
        search(&mut other, true, start);
        other.assignment
    }
}

/// The two other starts' searches ([`restarted`]): the firmer chained one, the independent one.
fn other_starts<'a>(
    m: &solve::Matching<'a>,
    view: Option<View>,
) -> (
    impl FnOnce() -> Vec<Option<usize>> + Send + 'a,
    impl FnOnce() -> Vec<Option<usize>> + Send + 'a,
) {
    (
        restarted(m, view, Start::ChainedFirm),
        restarted(m, view, Start::Independent),
    )
}

/// Order-free, another start's reading replaces `m`'s when its energy (the one energy, with
/// `m`'s own parameters) is lower by the margin; then returns the runner-ups of the reading
/// kept.
fn adopt(m: &mut solve::Matching<'_>, other: &[Option<usize>]) -> Option<Vec<slide::RunnerUp>> {
    let (first, e_first) = (m.assignment.clone(), m.total_energy());
    m.set_assignment(other);
    if m.total_energy() < e_first - m.energy.params.margin {
        Some(settle(m, true))
    } else {
        m.set_assignment(&first);
        None
    }
}

/// Matches every reference marker to at most one blob of the frame, each frame on its own.
pub fn track(reference: &TrackReference, blobs: &[Blob], params: &TrackParams) -> TrackResult {
    track_with(reference, blobs, params, TrackHints::default())
}

/// Matches every reference marker to at most one blob of the frame, with `hints`: markers cut
/// by the border, a temporal prior (without one, tracking starts from the reference after the
/// registration's overall motion) and the view.
pub fn track_with(
    reference: &TrackReference,
    blobs: &[Blob],
    params: &TrackParams,
    hints: TrackHints<'_>,
) -> TrackResult {
    let usable = blobs.len() - hints.cut.min(blobs.len());
    if let Some(sizes) = &reference.ring_sizes_px {
        return rings::track_rings(reference, sizes, &blobs[..usable]);
    }
    let n = reference.positions.len();
    // The unseen sites start from their neighbours' motion, as a marker with no prior does
    // (the prior is copied only when there are sites to add: not every frame of a video).
    let prior = hints
        .prior
        .filter(|p| p.len() == reference.markers())
        .map(|p| {
            if p.len() == n {
                std::borrow::Cow::Borrowed(p)
            } else {
                let mut all = p.to_vec();
                all.resize(n, None);
                std::borrow::Cow::Owned(all)
            }
        });
    let prior = prior.as_deref();
    let energy = energy::Energy {
        reference,
        params,
        view: hints.view,
    };
    let Some(prior) = prior else {
        let (m, runner_ups, searched_again) =
            read_order_free(reference, blobs, usable, energy, hints);
        let mut result = outcome(&m, &runner_ups);
        result.searched_again = searched_again;
        return result;
    };
    let anchors = predict::anchors_from_prior(reference, prior);
    let mut m = solve::Matching::new(reference, blobs, usable, energy, anchors, (0.0, 0.0));
    m.charge_pieces = false;
    let runner_ups = search(&mut m, false, Start::Chained);
    // Each frame starts where the last one ended, and the fits are of the motion since the
    // last frame, so a reading carried a lattice step off keeps itself: nothing in the
    // followed energy tears at its seams. Its displacements from the reference do (a skin
    // does not tear), and it leaves blobs or markers in view unexplained there. The frame is
    // then also read on its own, and its energy (the deformation from the reference) judges
    // the two readings: the frame's own is kept when lower by the margin.
    if m.torn_from_rest() && m.leaves_unexplained() {
        let (mut own, own_runner_ups, _) = read_order_free(reference, blobs, usable, energy, hints);
        let (kept, e_own) = (own.assignment.clone(), own.total_energy());
        own.set_assignment(&m.assignment);
        if e_own < own.total_energy() - params.margin {
            own.set_assignment(&kept);
            return outcome(&own, &own_runner_ups);
        }
    }
    outcome(&m, &runner_ups)
}

/// The reading of one frame on its own (order-free), with the runner-ups within the margin
/// of it and whether other starts were searched.
fn read_order_free<'a>(
    reference: &'a TrackReference,
    blobs: &'a [Blob],
    usable: usize,
    energy: energy::Energy<'a>,
    hints: TrackHints<'_>,
) -> (solve::Matching<'a>, Vec<slide::RunnerUp>, bool) {
    let anchors = reference.positions.clone();
    let mut m = solve::Matching::new(reference, blobs, usable, energy, anchors, (0.0, 0.0));
    m.shift = predict::register(reference, &m.index);
    // A multi-start search on the one energy: while a reading leaves a blob or a marker in
    // view unexplained, another start may find a lower energy. Both other starts are searched
    // side by side (the second one's reading may explain everything, and the third is not
    // needed then), beside the first too when asked, and taken in turn.
    let mut others = None;
    let mut runner_ups = if hints.starts_side_by_side {
        let (firm, independent) = other_starts(&m, hints.view);
        let (r, o) = rayon::join(
            || search(&mut m, true, Start::Chained),
            || rayon::join(firm, independent),
        );
        others = Some(o);
        r
    } else {
        search(&mut m, true, Start::Chained)
    };
    let searched_again = m.leaves_unexplained();
    if searched_again {
        let (firm, independent) = others.unwrap_or_else(|| {
            let (firm, independent) = other_starts(&m, hints.view);
            rayon::join(firm, independent)
        });
        for other in [firm, independent] {
            if m.leaves_unexplained() {
                if let Some(r) = adopt(&mut m, &other) {
                    runner_ups = r;
                }
            }
        }
    }
    // Each regrown reading kept may still be torn: regrown again while that lowers the energy
    // (at most three times).
    for _ in 0..3 {
        if !m.torn() {
            break;
        }
        match regrow::regrow(&mut m) {
            Some(r) => runner_ups = r,
            None => break,
        }
    }
    (m, runner_ups, searched_again)
}

/// The reported outcome of the reading `m` found, with the `runner_ups` within the margin of
/// it: statuses, split pairs, shared blobs and pieces, the markers only.
fn outcome(m: &solve::Matching<'_>, runner_ups: &[slide::RunnerUp]) -> TrackResult {
    let (blobs, usable, n) = (m.blobs, m.usable, m.reference.positions.len());
    let preds = m.predictions();
    let pieces = pieces::find_pieces(m, &preds);
    let ambiguity::Classified {
        mut status,
        mut on_blob,
    } = ambiguity::classify(m, &preds, &pieces);
    for r in runner_ups {
        for &i in &r.markers {
            if status[i] == MarkerStatus::Ok {
                status[i] = MarkerStatus::Ambiguous;
            }
        }
    }
    let split_px = split::split_pairs(m, &mut on_blob, &mut status);
    split::lose_cut(m, &mut status);
    let mut held_px = Vec::new();
    let mut merged_blob = vec![false; blobs.len()];
    for &(j, i, _) in &on_blob {
        merged_blob[j] = true;
        if status[i] == MarkerStatus::Merged {
            if held_px.is_empty() {
                held_px = vec![None; n];
            }
            held_px[i] = Some((blobs[j].x_px, blobs[j].y_px));
        }
    }
    let mut assignment = m.assignment.clone();
    for (a, st) in assignment.iter_mut().zip(&status) {
        if *st != MarkerStatus::Ok {
            *a = None;
        }
    }
    let mut piece = vec![false; blobs.len()];
    for &(j, j2) in &pieces {
        piece[j2] = m.owner[j].is_some_and(|i| status[i] == MarkerStatus::Ok);
    }
    let pieces: Vec<(usize, usize)> = pieces.into_iter().filter(|&(_, j2)| piece[j2]).collect();
    let taken = |j: usize| m.owner[j].is_some() || merged_blob[j] || piece[j];
    let mut result = TrackResult {
        assignment,
        status,
        shift_px: m.shift,
        spurious: (0..usable).filter(|&j| !taken(j)).count(),
        split_px,
        held_px,
        pieces,
        searched_again: false,
    };
    result.keep_markers(m.reference.markers(), &m.owner);
    result
}
