//! Plain Coulomb pair `V = Q/r` (`Q = k_e q_a q_b`, already scaled), no cutoff: the scaled
//! 1-4 pairs of a molecular force field, which OpenMM's `NonbondedForce` exceptions also
//! compute without cutoff or reaction field. Non-bonded: slow by default.
//!
//! In `s = r²`: `χ = Q s^{−1/2}`, `χ′ = −Q s^{−3/2}/2`, `χ″ = 3Q s^{−5/2}/4`.

use super::pair::PairPotential;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coulomb {
    pub charge_product: f64,
}

impl PairPotential for Coulomb {
    #[inline(always)]
    fn value(&self, s: f64) -> f64 {
        self.charge_product / s.sqrt()
    }

    #[inline(always)]
    fn d1(&self, s: f64) -> f64 {
        -0.5 * self.charge_product / (s * s.sqrt())
    }

    #[inline(always)]
    fn d1_d2(&self, s: f64) -> (f64, f64) {
        let r3 = s * s.sqrt();
        (
            -0.5 * self.charge_product / r3,
            0.75 * self.charge_product / (s * r3),
        )
    }
}
