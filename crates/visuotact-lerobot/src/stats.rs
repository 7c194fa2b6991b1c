//! Per-dimension statistics as LeRobot keeps them (`min`, `max`, `mean`, `std` — population —
//! and `count`), over rows of numbers or over the pixels of frames (channels scaled to
//! [0, 1], shape `[3, 1, 1]`). NaN values (a lost marker, a missing estimate) are left out of a
//! dimension's figures; a dimension with no number at all reads 0 throughout, so that a
//! loader's normalisation never meets NaN.

use serde_json::{json, Value};

/// Running figures of a fixed number of dimensions: per dimension the count, mean and sum of
/// squared deviations, merged by Chan et al.'s parallel formula (no cancellation when the
/// spread is small beside the mean).
#[derive(Clone, Debug, PartialEq)]
pub struct Stats {
    min: Vec<f64>,
    max: Vec<f64>,
    n: Vec<u64>,
    mean: Vec<f64>,
    m2: Vec<f64>,
    /// Rows (or frames) seen.
    pub count: u64,
}

impl Stats {
    /// Empty statistics of `dims` dimensions.
    pub fn new(dims: usize) -> Self {
        Self {
            min: vec![f64::INFINITY; dims],
            max: vec![f64::NEG_INFINITY; dims],
            n: vec![0; dims],
            mean: vec![0.0; dims],
            m2: vec![0.0; dims],
            count: 0,
        }
    }

    /// One row.
    pub fn push(&mut self, row: &[f64]) {
        for (d, &v) in row.iter().enumerate().take(self.n.len()) {
            if v.is_finite() {
                self.add(d, (v, v), 1, v, 0.0);
            }
        }
        self.count += 1;
    }

    /// One RGB frame's pixels (one row for the count).
    pub fn push_rgb(&mut self, rgb: &[u8]) {
        let n = (rgb.len() / 3) as u64;
        if n == 0 {
            return;
        }
        for c in 0..3.min(self.n.len()) {
            let (mut lo, mut hi, mut s, mut s2) = (u8::MAX, 0_u8, 0_u128, 0_u128);
            for &p in rgb.iter().skip(c).step_by(3) {
                lo = lo.min(p);
                hi = hi.max(p);
                s += u128::from(p);
                s2 += u128::from(p) * u128::from(p);
            }
            // Exact in integers: n·Σx² − (Σx)² = n² · variance.
            let k = 1.0 / 255.0;
            let m2 = (s2 * u128::from(n) - s * s) as f64 / n as f64 * k * k;
            let mean = s as f64 / n as f64 * k;
            self.add(c, (f64::from(lo) * k, f64::from(hi) * k), n, mean, m2);
        }
        self.count += 1;
    }

    fn add(&mut self, d: usize, (lo, hi): (f64, f64), n: u64, mean: f64, m2: f64) {
        self.min[d] = self.min[d].min(lo);
        self.max[d] = self.max[d].max(hi);
        let (na, nb) = (self.n[d] as f64, n as f64);
        let total = na + nb;
        let delta = mean - self.mean[d];
        self.mean[d] += delta * nb / total;
        self.m2[d] += m2 + delta * delta * na * nb / total;
        self.n[d] += n;
    }

    /// Adds another's rows.
    pub fn merge(&mut self, other: &Self) {
        for d in 0..self.n.len().min(other.n.len()) {
            if other.n[d] > 0 {
                let o = other;
                self.add(d, (o.min[d], o.max[d]), o.n[d], o.mean[d], o.m2[d]);
            }
        }
        self.count += other.count;
    }

    /// Per dimension: min, max, mean, std.
    pub fn figures(&self) -> [Vec<f64>; 4] {
        let mut out: [Vec<f64>; 4] = Default::default();
        for d in 0..self.n.len() {
            let (lo, hi, mean, std) = if self.n[d] == 0 {
                (0.0, 0.0, 0.0, 0.0)
            } else {
                let var = (self.m2[d] / self.n[d] as f64).max(0.0);
                (self.min[d], self.max[d], self.mean[d], var.sqrt())
            };
            for (o, v) in out.iter_mut().zip([lo, hi, mean, std]) {
                o.push(v);
            }
        }
        out
    }

    /// As `stats.json` holds a feature (`image`: each figure shaped `[3, 1, 1]`).
    pub fn to_json(&self, image: bool) -> Value {
        let shape = |v: Vec<f64>| {
            if image {
                json!(v.iter().map(|x| json!([[x]])).collect::<Vec<_>>())
            } else {
                json!(v)
            }
        };
        let [min, max, mean, std] = self.figures();
        json!({
            "min": shape(min),
            "max": shape(max),
            "mean": shape(mean),
            "std": shape(std),
            "count": [self.count],
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn figures_match_numpy_population_statistics_and_skip_nan() {
        let mut s = Stats::new(3);
        for row in [
            [1.0, f64::NAN, 2.0],
            [2.0, f64::NAN, 4.0],
            [6.0, f64::NAN, 6.0],
        ] {
            s.push(&row);
        }
        let [min, max, mean, std] = s.figures();
        assert_eq!((min[0], max[0], mean[0]), (1.0, 6.0, 3.0));
        // numpy.std([1, 2, 6]) = sqrt(14/3)
        assert!((std[0] - (14.0_f64 / 3.0).sqrt()).abs() < 1e-12);
        assert_eq!((min[1], max[1], mean[1], std[1]), (0.0, 0.0, 0.0, 0.0));
        assert!((std[2] - (8.0_f64 / 3.0).sqrt()).abs() < 1e-12);
        assert_eq!(s.count, 3);
    }

    #[test]
    fn pixels_are_scaled_to_one_per_channel() {
        let mut s = Stats::new(3);
        s.push_rgb(&[0, 255, 51, 255, 255, 51]);
        let [min, max, mean, std] = s.figures();
        assert_eq!((min[0], max[0], mean[0]), (0.0, 1.0, 0.5));
        assert!((std[0] - 0.5).abs() < 1e-12);
        assert_eq!((mean[1], std[1]), (1.0, 0.0));
        assert!((mean[2] - 0.2).abs() < 1e-12);
        assert_eq!(s.to_json(true)["mean"][2], json!([[mean[2]]]));
    }

    #[test]
    fn a_small_spread_beside_a_large_mean_keeps_its_digits_and_merges_exactly() {
        let (mut a, mut b, mut all) = (Stats::new(1), Stats::new(1), Stats::new(1));
        let xs: Vec<f64> = (0..1000).map(|i| 1e8 + f64::from(i % 7) * 1e-3).collect();
        for (i, &x) in xs.iter().enumerate() {
            if i < 300 {
                a.push(&[x])
            } else {
                b.push(&[x])
            }
            all.push(&[x]);
        }
        a.merge(&b);
        let mean = xs.iter().sum::<f64>() / 1000.0;
        let var = xs.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / 1000.0;
        for s in [&a, &all] {
            let [_, _, m, sd] = s.figures();
            assert!((m[0] - mean).abs() < 1e-6);
            assert!(
                (sd[0] - var.sqrt()).abs() < 1e-9 * 1e3,
                "{} vs {}",
                sd[0],
                var.sqrt()
            );
        }
        assert_eq!(a.count, 1000);
    }
}
