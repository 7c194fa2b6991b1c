//! Forward-mode automatic differentiation with up to [`MAX_PARTIALS`] partial derivatives:
//! exact Jacobians for closed-form models (the NIST StRD problems).
//!
//! ```
//! use visuotact_nn::dual::Dual;
//! let x = Dual::var(2.0, 0);
//! let y = x * x.exp();
//! assert!((y.d[0] - 3.0 * 2f64.exp()).abs() < 1e-12); // d/dx x eˣ = (1 + x) eˣ
//! ```

use std::ops::{Add, Div, Mul, Neg, Sub};

/// Most partial derivatives a [`Dual`] carries.
pub const MAX_PARTIALS: usize = 9;

/// A value and its partial derivatives.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dual {
    /// The value.
    pub v: f64,
    /// ∂/∂pᵢ.
    pub d: [f64; MAX_PARTIALS],
}

impl Dual {
    /// A constant (all partials zero).
    pub fn constant(v: f64) -> Self {
        Self {
            v,
            d: [0.0; MAX_PARTIALS],
        }
    }

    /// The `i`-th variable with value `v`.
    pub fn var(v: f64, i: usize) -> Self {
        let mut d = [0.0; MAX_PARTIALS];
        d[i] = 1.0;
        Self { v, d }
    }

    /// Applies `f` with derivative `df` at the value (chain rule).
    fn chain(self, f: f64, df: f64) -> Self {
        let mut d = self.d;
        d.iter_mut().for_each(|x| *x *= df);
        Self { v: f, d }
    }

    /// eˣ.
    pub fn exp(self) -> Self {
        let e = self.v.exp();
        self.chain(e, e)
    }

    /// ln x.
    pub fn ln(self) -> Self {
        self.chain(self.v.ln(), 1.0 / self.v)
    }

    /// sin x.
    pub fn sin(self) -> Self {
        self.chain(self.v.sin(), self.v.cos())
    }

    /// cos x.
    pub fn cos(self) -> Self {
        self.chain(self.v.cos(), -self.v.sin())
    }

    /// atan x.
    pub fn atan(self) -> Self {
        self.chain(self.v.atan(), 1.0 / (1.0 + self.v * self.v))
    }

    /// xᵏ for a constant exponent.
    pub fn powf(self, k: f64) -> Self {
        self.chain(self.v.powf(k), k * self.v.powf(k - 1.0))
    }

    /// xʸ for a variable exponent, `exp(y ln x)`.
    pub fn pow(self, y: Dual) -> Self {
        (y * self.ln()).exp()
    }
}

impl Add for Dual {
    type Output = Dual;
    fn add(self, o: Dual) -> Dual {
        let mut d = self.d;
        d.iter_mut().zip(o.d).for_each(|(a, b)| *a += b);
        Dual { v: self.v + o.v, d }
    }
}

impl Sub for Dual {
    type Output = Dual;
    fn sub(self, o: Dual) -> Dual {
        self + (-o)
    }
}

impl Neg for Dual {
    type Output = Dual;
    fn neg(self) -> Dual {
        self.chain(-self.v, -1.0)
    }
}

impl Mul for Dual {
    type Output = Dual;
    fn mul(self, o: Dual) -> Dual {
        let mut d = [0.0; MAX_PARTIALS];
        for (i, x) in d.iter_mut().enumerate() {
            *x = self.d[i] * o.v + self.v * o.d[i];
        }
        Dual { v: self.v * o.v, d }
    }
}

impl Div for Dual {
    type Output = Dual;
    fn div(self, o: Dual) -> Dual {
        let inv = 1.0 / o.v;
        let mut d = [0.0; MAX_PARTIALS];
        for (i, x) in d.iter_mut().enumerate() {
            *x = (self.d[i] - self.v * inv * o.d[i]) * inv;
        }
        Dual { v: self.v * inv, d }
    }
}

macro_rules! with_f64 {
    ($($tr:ident $f:ident),*) => {$(
        impl $tr<f64> for Dual {
            type Output = Dual;
            fn $f(self, o: f64) -> Dual { self.$f(Dual::constant(o)) }
        }
        impl $tr<Dual> for f64 {
            type Output = Dual;
            fn $f(self, o: Dual) -> Dual { Dual::constant(self).$f(o) }
        }
    )*};
}
with_f64!(Add add, Sub sub, Mul mul, Div div);
