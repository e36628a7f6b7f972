//! Double-double arithmetic (about 32 significant digits): a value is the unevaluated
//! sum `hi + lo` of two doubles with `|lo| ≤ ulp(hi)/2`, after Dekker and Knuth (the
//! algorithms of Hida, Li and Bailey's `qd`, the library CFM25 computed with). Only what
//! the structural coefficients need: `+ − × ÷`, built on the error-free `two_sum` and an
//! FMA-based `two_prod`.

use std::ops::{Add, Div, Mul, Neg, Sub};

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DoubleDouble {
    pub hi: f64,
    pub lo: f64,
}

/// `a + b = s + e` exactly.
#[inline]
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    (s, (a - (s - bb)) + (b - bb))
}

/// `a + b = s + e` exactly, when `|a| ≥ |b|`.
#[inline]
fn quick_two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    (s, b - (s - a))
}

/// `a b = p + e` exactly.
#[inline]
fn two_prod(a: f64, b: f64) -> (f64, f64) {
    let p = a * b;
    (p, a.mul_add(b, -p))
}

impl DoubleDouble {
    pub const ZERO: DoubleDouble = DoubleDouble { hi: 0.0, lo: 0.0 };
    pub const ONE: DoubleDouble = DoubleDouble { hi: 1.0, lo: 0.0 };

    pub fn from_f64(x: f64) -> Self {
        DoubleDouble { hi: x, lo: 0.0 }
    }

    /// The nearest double.
    pub fn to_f64(self) -> f64 {
        self.hi + self.lo
    }

    pub fn abs(self) -> Self {
        if self.hi < 0.0 { -self } else { self }
    }

    /// `self ≥ other` in magnitude, for pivoting.
    pub fn magnitude(self) -> f64 {
        self.hi.abs()
    }
}

impl From<f64> for DoubleDouble {
    fn from(x: f64) -> Self {
        DoubleDouble::from_f64(x)
    }
}

impl Add for DoubleDouble {
    type Output = DoubleDouble;
    fn add(self, o: DoubleDouble) -> DoubleDouble {
        let (s, e) = two_sum(self.hi, o.hi);
        let (t, f) = two_sum(self.lo, o.lo);
        let (s, e) = quick_two_sum(s, e + t);
        let (hi, lo) = quick_two_sum(s, e + f);
        DoubleDouble { hi, lo }
    }
}

impl Neg for DoubleDouble {
    type Output = DoubleDouble;
    fn neg(self) -> DoubleDouble {
        DoubleDouble {
            hi: -self.hi,
            lo: -self.lo,
        }
    }
}

impl Sub for DoubleDouble {
    type Output = DoubleDouble;
    fn sub(self, o: DoubleDouble) -> DoubleDouble {
        self + (-o)
    }
}

impl Mul for DoubleDouble {
    type Output = DoubleDouble;
    fn mul(self, o: DoubleDouble) -> DoubleDouble {
        let (p, e) = two_prod(self.hi, o.hi);
        let e = e + (self.hi * o.lo + self.lo * o.hi);
        let (hi, lo) = quick_two_sum(p, e);
        DoubleDouble { hi, lo }
    }
}

impl Div for DoubleDouble {
    type Output = DoubleDouble;
    /// Long division: three quotient digits, each corrected by the exact remainder.
    fn div(self, o: DoubleDouble) -> DoubleDouble {
        let q1 = self.hi / o.hi;
        let r = self - o * DoubleDouble::from_f64(q1);
        let q2 = r.hi / o.hi;
        let r = r - o * DoubleDouble::from_f64(q2);
        let q3 = r.hi / o.hi;
        let (hi, lo) = quick_two_sum(q1, q2);
        DoubleDouble { hi, lo } + DoubleDouble::from_f64(q3)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 1/3 and 1/10 carry about 32 digits: `3 · (1/3) − 1` is below 1e-31, where a double
    /// leaves 5.6e-17 in `1/3 − 0.333…` (the representation error of 1/3).
    #[test]
    fn division_and_products_keep_about_32_digits() {
        let three = DoubleDouble::from_f64(3.0);
        let third = DoubleDouble::ONE / three;
        let residual = (third * three - DoubleDouble::ONE).abs().to_f64();
        assert!(residual < 1e-31, "{residual}");
        let ten = DoubleDouble::from_f64(10.0);
        let tenth = DoubleDouble::ONE / ten;
        let residual = (tenth * ten - DoubleDouble::ONE).abs().to_f64();
        assert!(residual < 1e-31, "{residual}");
        // (1 + 2⁻⁶⁰)² − 1 = 2⁻⁵⁹ + 2⁻¹²⁰: lost entirely in f64, kept here to 2⁻⁵⁹.
        let x = DoubleDouble::ONE + DoubleDouble::from_f64(2f64.powi(-60));
        let y = (x * x - DoubleDouble::ONE).to_f64();
        assert!((y - 2f64.powi(-59)).abs() <= 2f64.powi(-110), "{y}");
    }
}
