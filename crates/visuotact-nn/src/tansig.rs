//! The hidden layers' transfer function, MATLAB's `tansig` (the hyperbolic tangent), computed
//! over whole slices in a form the compiler vectorises.
//!
//! Contract: [`tansig`] equals `f64::tanh` to within 4·10⁻¹⁶ absolute everywhere (tested on a
//! dense grid and at the edges), is odd, exactly ±1 beyond |x| = 40, exactly 0 at 0 and NaN
//! for NaN. It is built as `(1 − e)/(1 + e)` with `e = exp(−2|x|)` and the exponential's own
//! range reduction (`e = 2ᵏ·exp(r)`, |r| ≤ ln 2 / 2, a degree-13 Taylor polynomial whose
//! remainder is below 10⁻¹⁷), with no branch and no call: the C library's `tanh` (through
//! `expm1`) was half of the wide network's training time (perf, 5 000 simulated TacTip
//! touches), while its forward and backward products together were a quarter.
//!
//! Near 0 the error is absolute, not relative (`1 − e` cancels): the transfer function's
//! output feeds weighted sums, where an absolute 10⁻¹⁶ is below their rounding.

/// ln 2 split so that `k·LN2_HI` is exact (its low 21 bits are zero) for the |k| ≤ 116 used here.
const LN2_HI: f64 = 0.693_147_180_369_123_8;
/// The rest of ln 2.
const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;
/// Adding and subtracting it rounds a float of magnitude below 2⁵¹ to an integer (1.5·2⁵²);
/// the sum's low bits hold that integer.
const ROUNDER: f64 = 6_755_399_441_055_744.0;
/// 1/n! for n = 13 down to 0: exp's Taylor coefficients, highest first.
const TAYLOR: [f64; 14] = [
    1.0 / 6_227_020_800.0,
    1.0 / 479_001_600.0,
    1.0 / 39_916_800.0,
    1.0 / 3_628_800.0,
    1.0 / 362_880.0,
    1.0 / 40_320.0,
    1.0 / 5_040.0,
    1.0 / 720.0,
    1.0 / 120.0,
    1.0 / 24.0,
    1.0 / 6.0,
    0.5,
    1.0,
    1.0,
];
/// Beyond this |x| tanh is 1 in double precision (1 − 2e⁻⁸⁰ rounds to 1).
const SATURATED: f64 = 40.0;

/// `exp(y)` for `y` in [−2·[`SATURATED`], 0] (NaN stays NaN), branch-free.
#[inline(always)]
fn exp_nonpositive(y: f64) -> f64 {
    let shifted = y * std::f64::consts::LOG2_E + ROUNDER;
    let k = shifted - ROUNDER;
    let r = (y - k * LN2_HI) - k * LN2_LO;
    // Taylor to r¹³/13! by Horner.
    let mut p = TAYLOR[0];
    for c in &TAYLOR[1..] {
        p = p * r + c;
    }
    // 2ᵏ from the integer in `shifted`'s low bits (k in [−116, 0]: a normal power of two).
    let scale = f64::from_bits(shifted.to_bits().wrapping_add(1023) << 52);
    p * scale
}

/// tanh(x), as [`f64::tanh`] to within 4·10⁻¹⁶ (module doc), without a branch.
///
/// ```
/// use visuotact_nn::tansig::tansig;
/// assert_eq!(tansig(0.0), 0.0);
/// assert!((tansig(0.5) - 0.5f64.tanh()).abs() < 4e-16);
/// assert_eq!(tansig(-50.0), -1.0);
/// ```
#[inline(always)]
pub fn tansig(x: f64) -> f64 {
    let y = -2.0 * x.abs();
    // A select, not a branch; NaN fails the test and stays NaN.
    let y = if y < -2.0 * SATURATED {
        -2.0 * SATURATED
    } else {
        y
    };
    let e = exp_nonpositive(y);
    ((1.0 - e) / (1.0 + e)).copysign(x)
}

/// [`tansig`] of every value of `v`, in place.
pub fn tansig_in_place(v: &mut [f64]) {
    tansig_of_sum_in_place(v, 0.0);
}

/// [`tansig`] of every value of `v` plus `bias`, in place (a layer's pre-activations),
/// vectorised for the widest SIMD the CPU has (pulp's run-time dispatch; the same results on
/// every path: no fused multiply-add is formed where the baseline has none).
pub fn tansig_of_sum_in_place(v: &mut [f64], bias: f64) {
    pulp::Arch::new().dispatch(
        #[inline(always)]
        || {
            for x in v {
                *x = tansig(*x + bias);
            }
        },
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_the_c_library_tanh_on_a_dense_grid() {
        let mut worst = (0.0f64, 0.0f64);
        for i in -2_000_000..=2_000_000 {
            let x = f64::from(i) * 2.5e-5; // [−50, 50]
            let e = (tansig(x) - x.tanh()).abs();
            if e > worst.0 {
                worst = (e, x);
            }
        }
        assert!(worst.0 <= 4e-16, "worst error {:e} at {}", worst.0, worst.1);
    }

    #[test]
    fn is_exact_at_the_edges_and_keeps_nan() {
        assert_eq!(tansig(0.0).to_bits(), 0.0f64.to_bits());
        assert_eq!(tansig(-0.0).to_bits(), (-0.0f64).to_bits());
        for x in [40.0, 41.0, 700.0, 1e300, f64::INFINITY] {
            assert_eq!(tansig(x), 1.0, "{x}");
            assert_eq!(tansig(-x), -1.0, "{x}");
        }
        assert!(tansig(f64::NAN).is_nan());
        for x in [1e-300, 1e-20, 1e-9, 1e-5] {
            assert!((tansig(x) - x).abs() <= 4e-16, "{x}");
        }
    }

    #[test]
    fn is_odd_and_the_slices_agree_with_it() {
        let xs: Vec<f64> = (0..1000).map(|i| f64::from(i) * 0.0371 - 18.0).collect();
        let mut v = xs.clone();
        tansig_in_place(&mut v);
        let mut w = xs.clone();
        tansig_of_sum_in_place(&mut w, 0.25);
        for ((x, a), b) in xs.iter().zip(&v).zip(&w) {
            assert_eq!(*a, -tansig(-x));
            assert_eq!(*a, tansig(*x));
            assert_eq!(*b, tansig(x + 0.25));
        }
    }
}
