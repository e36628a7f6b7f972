//! Forward-mode dual numbers `a + b ε` (ε² = 0).
//!
//! Evaluating a gradient at `q + ε v` gives `∇V(q) + ε ∇²V(q) v`: the exact
//! Hessian-vector product of terms whose Hessian is tedious by hand (angles, torsions),
//! from the same code as their gradient, at about twice its cost.

use std::ops::{Add, Div, Mul, Neg, Sub};

/// The arithmetic a force kernel needs, for `f64` and for [`Dual`].
pub trait Scalar:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    fn constant(x: f64) -> Self;
    /// `value + tangent·ε`; a real scalar drops the tangent.
    fn seeded(value: f64, tangent: f64) -> Self;
    fn real(self) -> f64;
    fn sqrt(self) -> Self;
    fn sin(self) -> Self;
    fn cos(self) -> Self;
    /// `atan2(self, x)`.
    fn atan2(self, x: Self) -> Self;
}

impl Scalar for f64 {
    #[inline(always)]
    fn constant(x: f64) -> Self {
        x
    }
    #[inline(always)]
    fn seeded(value: f64, _tangent: f64) -> Self {
        value
    }
    #[inline(always)]
    fn real(self) -> f64 {
        self
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline(always)]
    fn sin(self) -> Self {
        f64::sin(self)
    }
    #[inline(always)]
    fn cos(self) -> Self {
        f64::cos(self)
    }
    #[inline(always)]
    fn atan2(self, x: Self) -> Self {
        f64::atan2(self, x)
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dual {
    pub value: f64,
    pub derivative: f64,
}

impl Dual {
    pub fn new(value: f64, derivative: f64) -> Self {
        Dual { value, derivative }
    }
}

impl Add for Dual {
    type Output = Dual;
    #[inline(always)]
    fn add(self, o: Dual) -> Dual {
        Dual::new(self.value + o.value, self.derivative + o.derivative)
    }
}

impl Sub for Dual {
    type Output = Dual;
    #[inline(always)]
    fn sub(self, o: Dual) -> Dual {
        Dual::new(self.value - o.value, self.derivative - o.derivative)
    }
}

impl Mul for Dual {
    type Output = Dual;
    #[inline(always)]
    fn mul(self, o: Dual) -> Dual {
        Dual::new(
            self.value * o.value,
            self.derivative * o.value + self.value * o.derivative,
        )
    }
}

impl Div for Dual {
    type Output = Dual;
    #[inline(always)]
    fn div(self, o: Dual) -> Dual {
        let value = self.value / o.value;
        Dual::new(value, (self.derivative - value * o.derivative) / o.value)
    }
}

impl Neg for Dual {
    type Output = Dual;
    #[inline(always)]
    fn neg(self) -> Dual {
        Dual::new(-self.value, -self.derivative)
    }
}

impl Scalar for Dual {
    #[inline(always)]
    fn constant(x: f64) -> Self {
        Dual::new(x, 0.0)
    }
    #[inline(always)]
    fn seeded(value: f64, tangent: f64) -> Self {
        Dual::new(value, tangent)
    }
    #[inline(always)]
    fn real(self) -> f64 {
        self.value
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        let root = self.value.sqrt();
        Dual::new(root, 0.5 * self.derivative / root)
    }
    #[inline(always)]
    fn sin(self) -> Self {
        Dual::new(self.value.sin(), self.derivative * self.value.cos())
    }
    #[inline(always)]
    fn cos(self) -> Self {
        Dual::new(self.value.cos(), -self.derivative * self.value.sin())
    }
    #[inline(always)]
    fn atan2(self, x: Self) -> Self {
        let r2 = x.value * x.value + self.value * self.value;
        Dual::new(
            self.value.atan2(x.value),
            (x.value * self.derivative - self.value * x.derivative) / r2,
        )
    }
}
