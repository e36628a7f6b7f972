//! Non-bonded pair forces of a molecular force field: Lennard-Jones 12-6 and Coulomb with a
//! cutoff, over a Verlet neighbour list ([`super::neighbour_list`]). Non-bonded: slow by
//! default. 3-D only.
//!
//! For a pair at distance `r < r_c` (every pair when there is no cutoff), not excluded:
//!
//! * Lennard-Jones `V = 4ε((σ/r)¹² − (σ/r)⁶) − V_shift`, written `c₁₂/r¹² − c₆/r⁶` with
//!   `c₁₂ = 4εσ¹²`, `c₆ = 4εσ⁶`; `V_shift` is the same at `r_c` when the energy is shifted
//!   (the force is not), else 0. ε and σ of a pair come from the scene (Lorentz–Berthelot
//!   or given per type pair, see `io::forcefield`).
//! * Coulomb with `k_e q_i q_j = Q`:
//!   - damped shifted force (DSF, Fennell & Gezelter, J. Chem. Phys. 124, 234104 (2006),
//!     eq. (18); LAMMPS `coul/dsf`): `V = Q [erfc(αr)/r − erfc(αr_c)/r_c + (r − r_c)
//!     (erfc(αr_c)/r_c² + 2α/√π · exp(−α²r_c²)/r_c)]`; energy and force vanish at `r_c`.
//!     With α = 0 it is `Q (1/r − 2/r_c + r/r_c²)`, the model of the peer kit's water box.
//!     The constant DSF self energy `−(erfc(αr_c)/(2r_c) + α/√π) Σ k_e q_i²` is left out (it
//!     moves no atom; the kit leaves it out too).
//!   - reaction field (OpenMM `NonbondedForce.CutoffPeriodic`/`CutoffNonPeriodic`):
//!     `V = Q (1/r + k_rf r² − c_rf)`, `k_rf = (ε_rf − 1)/((2ε_rf + 1) r_c³)`,
//!     `c_rf = 1/r_c + k_rf r_c²`.
//!   - plain `V = Q/r`, only without a cutoff (a molecule in vacuum).
//!
//! Excluded pairs (1-2, 1-3 and scaled 1-4 pairs, which live in their own terms) are not in
//! the list at all: no energy, no shift term, no force.
//!
//! **Speed.** Pairs come from a cluster-pair list ([`super::clusters`]: clusters of four
//! atoms, a buffered list rebuilt only when atoms have moved far enough to need it, pruned
//! between rebuilds) and go through a SIMD kernel over the 4 × 4 pairs of each cluster pair
//! (`nonbonded/kernel.rs`, AVX-512, AVX2 or portable lanes chosen at run time, the same
//! bits on each). Chunks of the list run in parallel (rayon) for large systems, each into
//! its own gradient buffer, summed in chunk order: bit-for-bit the same results for any
//! thread count. Nothing is allocated once the buffers have grown to their size. A gradient
//! evaluation computes the energy too when the previous one's energy was asked for, and
//! keeps it with a copy of the positions, so an energy monitor at the same positions costs
//! a comparison, not a second pass.
//!
//! **Precision.** Double by default; mixed ([`Precision::Mixed`], as GROMACS and OpenMM
//! run): f32 pair arithmetic, f64 accumulation of every cluster pair's forces and energies,
//! f64 integration.
//!
//! **Hessian-vector product.** For a radial `V(r)`, `∇²V = V″ r̂r̂ᵀ + (V′/r)(I − r̂r̂ᵀ)`, so
//! `(∇²V v)_j = a Δv + b (d·Δv) d` with `Δv = v_j − v_i`, `a = V′/r`, `b = (V″ − V′/r)/r²`.

use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use super::simd::{ERFC_X_MAX, EWALD_Z_MAX, EwaldForce, Isa};
use super::switch::Switch;
use super::{ForceTerm, TermClass};
use crate::units::Units;

mod engine;
pub(crate) mod kernel;
mod reference;

pub use super::Precision;
pub use reference::BruteForce;

/// `2/√π`.
const TWO_OVER_SQRT_PI: f64 = std::f64::consts::FRAC_2_SQRT_PI;

/// The Coulomb form of the term.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Electrostatics {
    None,
    Plain,
    DampedShiftedForce {
        alpha: f64,
    },
    ReactionField {
        dielectric: f64,
    },
    /// The real-space part of an Ewald sum, `erfc(αr)/r` cut at `r_c` (not shifted, as
    /// OpenMM and GROMACS compute it); the rest is in [`super::ewald`].
    Ewald {
        alpha: f64,
    },
}

impl Electrostatics {
    /// One line for reports, α in the scene's `units` (1/Å in a real scene).
    pub fn describe(&self, units: Units) -> String {
        match self {
            Electrostatics::None => "none".into(),
            Electrostatics::Plain => "plain 1/r (no cutoff)".into(),
            Electrostatics::DampedShiftedForce { alpha } => {
                format!(
                    "damped shifted force (DSF), alpha = {}",
                    units.inverse_length(*alpha)
                )
            }
            Electrostatics::ReactionField { dielectric } => {
                format!("reaction field, eps_rf = {dielectric}")
            }
            Electrostatics::Ewald { alpha } => {
                format!(
                    "Ewald real space erfc(alpha r)/r, alpha = {}",
                    units.inverse_length(*alpha)
                )
            }
        }
    }
}

/// Lennard-Jones coefficients of one type pair.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LjPair {
    pub c12: f64,
    pub c6: f64,
    /// The energy at the cutoff, subtracted when shifted (else 0).
    pub shift: f64,
}

impl LjPair {
    /// `(V, −V′/r)` at `1/r² = inv_r2`: `V = r⁻⁶(C₁₂ r⁻⁶ − C₆) − shift`,
    /// `−V′/r = r⁻² r⁻⁶ (12 C₁₂ r⁻⁶ − 6 C₆)`. The scalar pair of every f64 path (the
    /// distance split's loops, the brute-force reference); 7 multiplications.
    #[inline(always)]
    pub fn energy_force(&self, inv_r2: f64) -> (f64, f64) {
        let inv_r6 = inv_r2 * inv_r2 * inv_r2;
        let energy = inv_r6 * (self.c12 * inv_r6 - self.c6) - self.shift;
        let force = inv_r2 * inv_r6 * (12.0 * self.c12 * inv_r6 - 6.0 * self.c6);
        (energy, force)
    }

    /// `(V, V′, V″)` at `r` (shifted by [`LjPair::shift`]).
    pub fn derivatives(&self, r: f64) -> (f64, f64, f64) {
        let inv_r = 1.0 / r;
        let inv6 = inv_r.powi(6);
        let v = inv6 * (self.c12 * inv6 - self.c6) - self.shift;
        let d1 = inv_r * inv6 * (-12.0 * self.c12 * inv6 + 6.0 * self.c6);
        let d2 = inv_r * inv_r * inv6 * (156.0 * self.c12 * inv6 - 42.0 * self.c6);
        (v, d1, d2)
    }

    /// From ε, σ, for a cutoff (infinite for none) and whether the energy is shifted.
    pub fn new(epsilon: f64, sigma: f64, cutoff: f64, shift: bool) -> Self {
        let s6 = sigma.powi(6);
        let (c12, c6) = (4.0 * epsilon * s6 * s6, 4.0 * epsilon * s6);
        let shift = if shift && cutoff.is_finite() {
            let inv6 = cutoff.powi(-6);
            inv6 * (c12 * inv6 - c6)
        } else {
            0.0
        };
        LjPair { c12, c6, shift }
    }
}

/// The Coulomb kernel with its constants; `Q` is the charge product times `k_e`.
trait CoulombForm: Copy + Send + Sync {
    /// `(V, −V′/r)` at `r² = s` with `1/r = inv_r`.
    fn energy_force(&self, charge_product: f64, s: f64, inv_r: f64) -> (f64, f64);
    /// `(V, V′, V″)` at `r`.
    fn derivatives(&self, charge_product: f64, r: f64) -> (f64, f64, f64);
}

#[derive(Clone, Copy)]
struct Plain;

impl CoulombForm for Plain {
    #[inline(always)]
    fn energy_force(&self, qq: f64, _s: f64, inv_r: f64) -> (f64, f64) {
        let e = qq * inv_r;
        (e, e * inv_r * inv_r)
    }
    fn derivatives(&self, qq: f64, r: f64) -> (f64, f64, f64) {
        (qq / r, -qq / (r * r), 2.0 * qq / (r * r * r))
    }
}

/// DSF with α = 0 (shifted force): no erfc, no exp.
#[derive(Clone, Copy)]
struct ShiftedForce {
    two_over_rc: f64,
    inv_rc2: f64,
}

impl CoulombForm for ShiftedForce {
    #[inline(always)]
    fn energy_force(&self, qq: f64, s: f64, inv_r: f64) -> (f64, f64) {
        let r = s * inv_r;
        let e = qq * (inv_r - self.two_over_rc + r * self.inv_rc2);
        let f = qq * inv_r * (inv_r * inv_r - self.inv_rc2);
        (e, f)
    }
    fn derivatives(&self, qq: f64, r: f64) -> (f64, f64, f64) {
        (
            qq * (1.0 / r - self.two_over_rc + r * self.inv_rc2),
            qq * (-1.0 / (r * r) + self.inv_rc2),
            qq * 2.0 / (r * r * r),
        )
    }
}

/// DSF with α > 0.
#[derive(Clone, Copy)]
struct DampedShiftedForce {
    alpha: f64,
    rc: f64,
    /// `erfc(α r_c)/r_c`.
    e_shift: f64,
    /// `erfc(α r_c)/r_c² + 2α/√π exp(−α² r_c²)/r_c`.
    f_shift: f64,
    /// `α r_c` within the SIMD erfc's range ([`ERFC_X_MAX`]): the kernel's lanes compute
    /// erfc, else they go through libm lane by lane.
    simd: bool,
}

impl DampedShiftedForce {
    fn new(alpha: f64, rc: f64) -> Self {
        let erfc_rc = libm::erfc(alpha * rc);
        DampedShiftedForce {
            alpha,
            rc,
            e_shift: erfc_rc / rc,
            f_shift: erfc_rc / (rc * rc)
                + TWO_OVER_SQRT_PI * alpha * (-alpha * alpha * rc * rc).exp() / rc,
            simd: alpha * rc <= ERFC_X_MAX,
        }
    }
}

impl CoulombForm for DampedShiftedForce {
    #[inline(always)]
    fn energy_force(&self, qq: f64, s: f64, inv_r: f64) -> (f64, f64) {
        let r = s * inv_r;
        let ar = self.alpha * r;
        let erfc = libm::erfc(ar);
        let gauss = TWO_OVER_SQRT_PI * self.alpha * (-ar * ar).exp();
        let e = qq * (erfc * inv_r - self.e_shift + (r - self.rc) * self.f_shift);
        // −V′ = Q (erfc/r² + (2α/√π) e^{−α²r²}/r − f_shift)
        let f = qq * inv_r * (erfc * inv_r * inv_r + gauss * inv_r - self.f_shift);
        (e, f)
    }
    fn derivatives(&self, qq: f64, r: f64) -> (f64, f64, f64) {
        let ar = self.alpha * r;
        let erfc = libm::erfc(ar);
        let gauss = TWO_OVER_SQRT_PI * self.alpha * (-ar * ar).exp();
        let v = qq * (erfc / r - self.e_shift + (r - self.rc) * self.f_shift);
        let d1 = qq * (-erfc / (r * r) - gauss / r + self.f_shift);
        let d2 = qq
            * (2.0 * erfc / (r * r * r) + gauss * (2.0 / (r * r) + 2.0 * self.alpha * self.alpha));
        (v, d1, d2)
    }
}

#[derive(Clone, Copy)]
struct ReactionField {
    k: f64,
    c: f64,
}

impl CoulombForm for ReactionField {
    #[inline(always)]
    fn energy_force(&self, qq: f64, s: f64, inv_r: f64) -> (f64, f64) {
        let e = qq * (inv_r + self.k * s - self.c);
        let f = qq * (inv_r * inv_r * inv_r - 2.0 * self.k);
        (e, f)
    }
    fn derivatives(&self, qq: f64, r: f64) -> (f64, f64, f64) {
        (
            qq * (1.0 / r + self.k * r * r - self.c),
            qq * (-1.0 / (r * r) + 2.0 * self.k * r),
            qq * (2.0 / (r * r * r) + 2.0 * self.k),
        )
    }
}

/// Ewald real space `V = Q erfc(αr)/r` (unshifted, cut at `r_c` by the caller).
#[derive(Clone, Copy)]
struct EwaldReal {
    alpha: f64,
    /// As [`DampedShiftedForce`]'s.
    simd: bool,
    /// `(α r_c)² ≤` [`EWALD_Z_MAX`]: in single precision the kernel's force is the rational
    /// [`EwaldForce`] (no erfc), in double it stays erfc's.
    rational: bool,
    force: EwaldForce,
}

impl CoulombForm for EwaldReal {
    #[inline(always)]
    fn energy_force(&self, qq: f64, s: f64, inv_r: f64) -> (f64, f64) {
        let r = s * inv_r;
        let ar = self.alpha * r;
        let erfc = libm::erfc(ar);
        let gauss = TWO_OVER_SQRT_PI * self.alpha * (-ar * ar).exp();
        let e = qq * erfc * inv_r;
        // −V′/r = Q (erfc/r² + (2α/√π) e^{−α²r²}/r)/r
        let f = qq * inv_r * inv_r * (erfc * inv_r + gauss);
        (e, f)
    }
    fn derivatives(&self, qq: f64, r: f64) -> (f64, f64, f64) {
        let ar = self.alpha * r;
        let erfc = libm::erfc(ar);
        let gauss = TWO_OVER_SQRT_PI * self.alpha * (-ar * ar).exp();
        let v = qq * erfc / r;
        let d1 = -qq * (erfc / (r * r) + gauss / r);
        let d2 = qq
            * (2.0 * erfc / (r * r * r) + gauss * (2.0 / (r * r) + 2.0 * self.alpha * self.alpha));
        (v, d1, d2)
    }
}

#[derive(Clone, Copy)]
enum Kernel {
    Plain(Plain),
    ShiftedForce(ShiftedForce),
    Damped(DampedShiftedForce),
    ReactionField(ReactionField),
    Ewald(EwaldReal),
}

/// The Coulomb form of a term, pair by pair: `V`, `V′`, `V″` of one pair with its cutoff
/// constants, the same formulas as the pair loop's.
///
/// Pub for `forces::distance_split`, which multiplies these pair energies by a switch and
/// must use exactly the model of this term (its parts add up to it). Whoever rewrites the
/// pair engine: keep this (and its formulas equal to the engine's) or tell that file.
#[derive(Clone, Copy)]
pub struct CoulombPair(Kernel);

/// Work generic over a Coulomb form's SIMD lanes ([`CoulombPair::lanes`]).
pub(crate) trait CoulombLanes {
    type Out;
    fn with<C: kernel::Coulomb>(self, coulomb: C) -> Self::Out;
}

impl CoulombPair {
    /// The form for `electrostatics` with `cutoff` (`f64::INFINITY` for none).
    pub fn new(electrostatics: Electrostatics, cutoff: f64) -> Result<Self, String> {
        // The distance split multiplies these pairs by a switch: plain Coulomb inside it.
        coulomb_kernel(electrostatics, cutoff, true).map(CoulombPair)
    }

    /// `(V, −V′/r)` of a pair with `k_e q_i q_j = charge_product` at `r² = s`, `1/r = inv_r`.
    #[inline(always)]
    pub fn energy_force(&self, charge_product: f64, s: f64, inv_r: f64) -> (f64, f64) {
        match self.0 {
            Kernel::Plain(c) => c.energy_force(charge_product, s, inv_r),
            Kernel::ShiftedForce(c) => c.energy_force(charge_product, s, inv_r),
            Kernel::Damped(c) => c.energy_force(charge_product, s, inv_r),
            Kernel::ReactionField(c) => c.energy_force(charge_product, s, inv_r),
            Kernel::Ewald(c) => c.energy_force(charge_product, s, inv_r),
        }
    }

    /// `(V, −V′/r)` of a block of pairs, `energy[t]`, `force[t]` from `charge_product[t]`,
    /// `s[t] = r²` and `inv_r[t]`: one dispatch on the form for the whole block, so the loop
    /// vectorises.
    #[inline(always)]
    pub fn energy_force_block(
        &self,
        charge_product: &[f64],
        s: &[f64],
        inv_r: &[f64],
        energy: &mut [f64],
        force: &mut [f64],
    ) {
        #[inline(always)]
        fn block<C: CoulombForm>(
            c: C,
            qq: &[f64],
            s: &[f64],
            inv_r: &[f64],
            energy: &mut [f64],
            force: &mut [f64],
        ) {
            let n = qq.len();
            let (s, inv_r) = (&s[..n], &inv_r[..n]);
            let (energy, force) = (&mut energy[..n], &mut force[..n]);
            for t in 0..n {
                (energy[t], force[t]) = c.energy_force(qq[t], s[t], inv_r[t]);
            }
        }
        match self.0 {
            Kernel::Plain(c) => block(c, charge_product, s, inv_r, energy, force),
            Kernel::ShiftedForce(c) => block(c, charge_product, s, inv_r, energy, force),
            Kernel::Damped(c) => block(c, charge_product, s, inv_r, energy, force),
            Kernel::ReactionField(c) => block(c, charge_product, s, inv_r, energy, force),
            Kernel::Ewald(c) => block(c, charge_product, s, inv_r, energy, force),
        }
    }

    /// `with` called with this form's SIMD lanes (the cluster-pair kernel's).
    pub(crate) fn lanes<W: CoulombLanes>(&self, with: W) -> W::Out {
        match self.0 {
            Kernel::Plain(c) => with.with(c),
            Kernel::ShiftedForce(c) => with.with(c),
            Kernel::Damped(c) => with.with(c),
            Kernel::ReactionField(c) => with.with(c),
            Kernel::Ewald(c) => with.with(c),
        }
    }

    /// `(V, V′, V″)` of a pair at distance `r`.
    pub fn derivatives(&self, charge_product: f64, r: f64) -> (f64, f64, f64) {
        match self.0 {
            Kernel::Plain(c) => c.derivatives(charge_product, r),
            Kernel::ShiftedForce(c) => c.derivatives(charge_product, r),
            Kernel::Damped(c) => c.derivatives(charge_product, r),
            Kernel::ReactionField(c) => c.derivatives(charge_product, r),
            Kernel::Ewald(c) => c.derivatives(charge_product, r),
        }
    }
}

/// Lennard-Jones coefficients that factor per type, `c₁₂(a, b) = A_a A_b` and `c₆(a, b) =
/// B_a B_b` (one Lennard-Jones type, or geometric mixing): the kernel then multiplies
/// per-atom factors instead of gathering from the table.
#[derive(Clone, Debug)]
struct Factored {
    /// `[A, B]` per type.
    per_type: Vec<[f64; 2]>,
    /// `r_c⁻⁶` when the energy is shifted, else 0.
    inverse_cutoff6: f64,
}

impl Factored {
    /// The factors if they give every table entry (shift included) to 1e-12 relative.
    fn find(lj: &[LjPair], n_types: usize, cutoff: f64) -> Option<Factored> {
        let per_type: Vec<[f64; 2]> = (0..n_types)
            .map(|t| {
                let p = lj[t * n_types + t];
                [p.c12.sqrt(), p.c6.sqrt()]
            })
            .collect();
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs();
        let shifted = lj.iter().any(|p| p.shift != 0.0);
        let inverse_cutoff6 = if shifted { cutoff.powi(-6) } else { 0.0 };
        if !inverse_cutoff6.is_finite() || per_type.iter().flatten().any(|v| !v.is_finite()) {
            return None;
        }
        let fits = (0..n_types * n_types).all(|k| {
            let (a, b) = (per_type[k / n_types], per_type[k % n_types]);
            let (c12, c6) = (a[0] * b[0], a[1] * b[1]);
            let shift = (c12 * inverse_cutoff6 - c6) * inverse_cutoff6;
            close(c12, lj[k].c12) && close(c6, lj[k].c6) && close(shift, lj[k].shift)
        });
        fits.then_some(Factored {
            per_type,
            inverse_cutoff6,
        })
    }
}

pub struct Nonbonded {
    n: usize,
    cutoff: f64,
    electrostatics: Electrostatics,
    kernel: Kernel,
    n_types: usize,
    types: Vec<u32>,
    /// `n_types × n_types` coefficients.
    lj: Vec<LjPair>,
    factored: Option<Factored>,
    /// `q_i √k_e`, so the product of two is `k_e q_i q_j`.
    scaled_charges: Vec<f64>,
    workspace: Mutex<engine::Workspace>,
    listed_pairs: AtomicUsize,
    /// The short-range part of a distance split: every pair multiplied by this switch,
    /// listed and cut at its `r_out` (the Coulomb form keeps the model's cutoff).
    switch: Option<Switch>,
}

/// What a non-bonded term is built from.
#[derive(Clone, Debug)]
pub struct NonbondedSpec {
    /// `f64::INFINITY` for no cutoff.
    pub cutoff: f64,
    /// The outer list buffer beyond the cutoff ([`crate::forces::clusters`]).
    pub skin: f64,
    /// The inner (pruned) list buffer, at most `skin`; `None`: `skin / 2`.
    pub inner_buffer: Option<f64>,
    pub electrostatics: Electrostatics,
    /// Coulomb constant `k_e` in the scene's units.
    pub coulomb_constant: f64,
    /// The periodic box, if any.
    pub box_lengths: Option<[f64; 3]>,
    /// Type index per particle.
    pub types: Vec<u32>,
    /// `n_types × n_types` Lennard-Jones coefficients (symmetric).
    pub lj: Vec<LjPair>,
    pub charges: Vec<f64>,
    /// Pairs left out of this term.
    pub excluded: Vec<(usize, usize)>,
}

impl NonbondedSpec {
    /// The number of atom types, after checking that the positions `q`, the types, the
    /// charges and the Lennard-Jones table agree in size (`what` names the term).
    pub(crate) fn type_count(&self, q: &[f64], what: &str) -> Result<usize, String> {
        let n = self.types.len();
        if q.len() != 3 * n || self.charges.len() != n {
            return Err(format!(
                "{what}: sizes of positions, types and charges differ"
            ));
        }
        let n_types = (self.lj.len() as f64).sqrt().round() as usize;
        if n_types * n_types != self.lj.len() || self.types.iter().any(|&t| t as usize >= n_types) {
            return Err(format!(
                "{what}: the Lennard-Jones table does not fit the types"
            ));
        }
        Ok(n_types)
    }
}

impl Nonbonded {
    /// Build the term and its first list at positions `q`.
    pub fn new(spec: NonbondedSpec, q: &[f64]) -> Result<Self, String> {
        Self::build(spec, None, q)
    }

    /// The term's pairs multiplied by `switch` (`S V`, zero beyond `r_out`): the short-range
    /// part of a distance split by atom pair, in the cluster-pair kernel with a list cut at
    /// `r_out`. The model (the Coulomb form's cutoff, the Lennard-Jones shift) stays `spec`'s.
    pub fn switched(spec: NonbondedSpec, switch: Switch, q: &[f64]) -> Result<Self, String> {
        if switch.r_out() > spec.cutoff {
            return Err(format!(
                "r_out = {} is beyond the non-bonded cutoff {}",
                switch.r_out(),
                spec.cutoff
            ));
        }
        Self::build(spec, Some(switch), q)
    }

    fn build(spec: NonbondedSpec, switch: Option<Switch>, q: &[f64]) -> Result<Self, String> {
        let n = spec.types.len();
        let n_types = spec.type_count(q, "non-bonded term")?;
        let cutoff = spec.cutoff;
        if let Some(lengths) = spec.box_lengths {
            let shortest = lengths.iter().cloned().fold(f64::INFINITY, f64::min);
            if !cutoff.is_finite() || 2.0 * cutoff >= shortest {
                return Err(format!(
                    "the non-bonded cutoff {cutoff} must be shorter than half the shortest box \
                     length ({shortest}) for the minimum-image convention"
                ));
            }
        }
        let kernel = coulomb_kernel(spec.electrostatics, cutoff, switch.is_some())?;
        let root_ke = spec.coulomb_constant.sqrt();
        let scaled_charges: Vec<f64> = if spec.electrostatics == Electrostatics::None {
            vec![0.0; n]
        } else {
            spec.charges.iter().map(|q| q * root_ke).collect()
        };
        let (excluded_start, excluded) = exclusion_lists(n, &spec.excluded)?;
        let factored = Factored::find(&spec.lj, n_types, cutoff);
        let mut list = super::clusters::ClusterList::new(
            switch.map_or(cutoff, |s| s.r_out()),
            spec.skin,
            spec.box_lengths,
            excluded_start,
            excluded,
            scaled_charges.clone(),
        );
        if let Some(inner) = spec.inner_buffer {
            list.set_buffers(spec.skin, inner);
        }
        let term = Nonbonded {
            n,
            cutoff: switch.map_or(cutoff, |s| s.r_out()),
            electrostatics: spec.electrostatics,
            kernel,
            n_types,
            types: spec.types,
            lj: spec.lj,
            factored,
            scaled_charges,
            workspace: Mutex::new(engine::Workspace::new(list)),
            listed_pairs: AtomicUsize::new(0),
            switch,
        };
        term.refresh(&mut term.lock(), q);
        Ok(term)
    }

    /// The switch of a short-range part ([`Nonbonded::switched`]), `None` for a whole term.
    pub fn switch(&self) -> Option<Switch> {
        self.switch
    }

    /// `gradient += sign ∇V` (the remainder of a distance split subtracts its short part).
    pub fn add_scaled_gradient(&self, q: &[f64], gradient: &mut [f64], sign: f64) {
        self.evaluate(q, Some(gradient), sign);
    }

    /// `out += sign ∇²V v`.
    pub fn add_scaled_hessian_vector(&self, q: &[f64], v: &[f64], out: &mut [f64], sign: f64) {
        self.hessian_vector(q, v, out, sign);
    }

    /// The (Lennard-Jones, Coulomb) energies.
    pub fn energy_parts(&self, q: &[f64]) -> (f64, f64) {
        self.evaluate(q, None, 1.0)
    }

    pub fn electrostatics(&self) -> Electrostatics {
        self.electrostatics
    }

    /// Cutoff, outer list buffer (the scene's skin) and how many times the list was built.
    pub fn list_statistics(&self) -> (f64, f64, u64) {
        let workspace = self.lock();
        (
            workspace.list.cutoff(),
            workspace.list.buffers().0,
            workspace.list.builds(),
        )
    }

    /// How often the list was built and pruned, and its atom pairs (outer, inner).
    pub fn list_counts(&self) -> ListCounts {
        let workspace = self.lock();
        let list = &workspace.list;
        ListCounts {
            builds: list.builds(),
            prunes: list.prunes(),
            clusters: list.clusters(),
            outer_pairs: list.outer_pairs(),
            inner_pairs: list.inner_pairs(),
        }
    }

    /// (outer, inner) list buffers.
    pub fn list_buffers(&self) -> (f64, f64) {
        self.lock().list.buffers()
    }

    /// Outer and inner list buffers (lengths; the outer defaults to the skin, the inner to
    /// half of it). The next evaluation rebuilds.
    pub fn set_list_buffers(&self, outer: f64, inner: f64) {
        self.lock().list.set_buffers(outer, inner);
    }

    /// The instruction set of the kernel (default: the widest available). Panics if the
    /// processor does not have it.
    pub fn set_isa(&self, isa: Isa) {
        assert!(isa.is_available(), "{} is not available", isa.name());
        let mut workspace = self.lock();
        workspace.isa = isa;
        workspace.list.isa = isa;
        workspace.cached = None;
        workspace.reusable = false;
    }

    pub fn isa(&self) -> Isa {
        self.lock().isa
    }

    /// Whether the kernel computes every register group, Lennard-Jones lanes included,
    /// instead of only those with a pair within the cutoff (the default). The results are
    /// the same bits; `tests/nonbonded_engine.rs` checks it.
    pub fn set_every_group(&self, every: bool) {
        let mut workspace = self.lock();
        workspace.every_group = every;
        workspace.cached = None;
        workspace.reusable = false;
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, engine::Workspace> {
        // A panic elsewhere while the lock was held leaves a list that is rebuilt anyway.
        self.workspace.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// `(V′, V″)` of the pair `i, j` at distance `r < r_c`; of `W = S V` when switched
    /// (`W′ = S′V + SV′`, `W″ = S″V + 2S′V′ + SV″`).
    fn pair_derivatives(&self, i: usize, j: usize, r: f64) -> (f64, f64) {
        let (v, d1, d2) = self.pair_values(i, j, r);
        match self.switch {
            None => (d1, d2),
            Some(switch) => {
                let (s, s1, s2) = switch.derivatives(r);
                (s1 * v + s * d1, s2 * v + 2.0 * s1 * d1 + s * d2)
            }
        }
    }

    /// `(V, V′, V″)` of the pair `i, j` at distance `r < r_c`, unswitched.
    fn pair_values(&self, i: usize, j: usize, r: f64) -> (f64, f64, f64) {
        let p = self.lj[self.types[i] as usize * self.n_types + self.types[j] as usize];
        let (mut v, mut d1, mut d2) = p.derivatives(r);
        let qq = self.scaled_charges[i] * self.scaled_charges[j];
        if qq != 0.0 {
            let (e, a, b) = match self.kernel {
                Kernel::Plain(c) => c.derivatives(qq, r),
                Kernel::ShiftedForce(c) => c.derivatives(qq, r),
                Kernel::Damped(c) => c.derivatives(qq, r),
                Kernel::ReactionField(c) => c.derivatives(qq, r),
                Kernel::Ewald(c) => c.derivatives(qq, r),
            };
            v += e;
            d1 += a;
            d2 += b;
        }
        (v, d1, d2)
    }
}

/// Counters of the cluster-pair list.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ListCounts {
    pub builds: u64,
    pub prunes: u64,
    pub clusters: usize,
    /// Atom pairs of the outer (buffered) list.
    pub outer_pairs: usize,
    /// Atom pairs the kernel computes (the pruned list).
    pub inner_pairs: usize,
}

/// The Coulomb kernel of `electrostatics` at `cutoff`. Plain Coulomb has no cutoff form,
/// except in a `switched` term, whose switch takes it to zero inside the cutoff (the bare
/// short part of a distance split).
fn coulomb_kernel(
    electrostatics: Electrostatics,
    cutoff: f64,
    switched: bool,
) -> Result<Kernel, String> {
    Ok(match electrostatics {
        Electrostatics::None | Electrostatics::Plain => {
            if electrostatics == Electrostatics::Plain && cutoff.is_finite() && !switched {
                return Err(
                    "plain Coulomb has no cutoff form: use coulomb = \"dsf\" or \
                            \"reaction-field\" with a cutoff, or no cutoff"
                        .into(),
                );
            }
            Kernel::Plain(Plain)
        }
        Electrostatics::DampedShiftedForce { alpha } => {
            if !cutoff.is_finite() {
                return Err("damped shifted force Coulomb needs a cutoff".into());
            }
            if alpha == 0.0 {
                Kernel::ShiftedForce(ShiftedForce {
                    two_over_rc: 2.0 / cutoff,
                    inv_rc2: 1.0 / (cutoff * cutoff),
                })
            } else {
                Kernel::Damped(DampedShiftedForce::new(alpha, cutoff))
            }
        }
        Electrostatics::ReactionField { dielectric } => {
            if !cutoff.is_finite() {
                return Err("reaction-field Coulomb needs a cutoff".into());
            }
            let k = (dielectric - 1.0) / ((2.0 * dielectric + 1.0) * cutoff.powi(3));
            Kernel::ReactionField(ReactionField {
                k,
                c: 1.0 / cutoff + k * cutoff * cutoff,
            })
        }
        Electrostatics::Ewald { alpha } => {
            if !cutoff.is_finite() {
                return Err("Ewald (PME) real space needs a cutoff".into());
            }
            Kernel::Ewald(EwaldReal {
                alpha,
                simd: alpha * cutoff <= ERFC_X_MAX,
                // z = α²r² of a pair within the cutoff, its r² rounded to f32, stays in the fit.
                rational: (alpha * cutoff).powi(2) <= EWALD_Z_MAX - 0.5,
                force: EwaldForce::new(alpha),
            })
        }
    })
}

/// Excluded partners per particle, sorted (CSR: `start[i]..start[i + 1]`).
pub(super) fn exclusion_lists(
    n: usize,
    pairs: &[(usize, usize)],
) -> Result<(Vec<u32>, Vec<u32>), String> {
    let mut excluded = vec![Vec::new(); n];
    for &(i, j) in pairs {
        if i >= n || j >= n {
            return Err(format!("excluded pair ({i}, {j}) names a missing particle"));
        }
        if i != j {
            excluded[i].push(j as u32);
            excluded[j].push(i as u32);
        }
    }
    let mut start = vec![0u32; n + 1];
    for (i, list) in excluded.iter_mut().enumerate() {
        list.sort_unstable();
        list.dedup();
        start[i + 1] = start[i] + list.len() as u32;
    }
    Ok((start, excluded.concat()))
}

impl ForceTerm for Nonbonded {
    fn kind(&self) -> &'static str {
        "nonbonded"
    }

    fn class(&self) -> TermClass {
        TermClass::Nonbonded
    }

    fn energy(&self, q: &[f64]) -> f64 {
        let (lj, coulomb) = self.evaluate(q, None, 1.0);
        lj + coulomb
    }

    fn add_gradient(&self, q: &[f64], gradient: &mut [f64]) {
        self.evaluate(q, Some(gradient), 1.0);
    }

    fn add_hessian_vector(&self, q: &[f64], v: &[f64], out: &mut [f64]) {
        self.hessian_vector(q, v, out, 1.0);
    }

    fn couplings(&self) -> Vec<Vec<usize>> {
        self.coupled_pairs()
            .into_iter()
            .map(|p| p.to_vec())
            .collect()
    }

    fn interaction_count(&self) -> usize {
        self.listed_pairs.load(Ordering::Relaxed)
    }

    fn energy_components(&self, q: &[f64]) -> Vec<(&'static str, f64)> {
        let (lj, coulomb) = self.evaluate(q, None, 1.0);
        vec![("lennard-jones", lj), ("coulomb", coulomb)]
    }

    fn rebuild_lists(&self) {
        let mut workspace = self.lock();
        let (outer, inner) = workspace.list.buffers();
        workspace.list.set_buffers(outer, inner);
        workspace.cached = None;
        workspace.reusable = false;
    }

    /// The positions the cluster lists were built and pruned at
    /// ([`ClusterList::built_at`](super::clusters::ClusterList::built_at)):
    /// `{"built_at": [..], "pruned_at": [..]}`, `6N` numbers.
    fn list_state(&self) -> Option<serde_json::Value> {
        let workspace = self.lock();
        let (at_build, at_prune) = workspace.list.built_at()?;
        Some(serde_json::json!({ "built_at": at_build, "pruned_at": at_prune }))
    }

    fn restore_lists(&self, state: &serde_json::Value) -> crate::error::Result<()> {
        let array = |key: &str| -> Result<Vec<f64>, String> {
            let values = state
                .get(key)
                .and_then(|v| v.as_array())
                .ok_or_else(|| format!("no array \"{key}\""))?;
            values
                .iter()
                .enumerate()
                .map(|(k, v)| {
                    v.as_f64()
                        .ok_or_else(|| format!("{key}[{k}] is not a number"))
                })
                .collect()
        };
        let restored = array("built_at").and_then(|at_build| {
            let at_prune = array("pruned_at")?;
            self.restore_cluster_lists(&at_build, &at_prune)
        });
        restored.map_err(|e| {
            crate::error::Error::input(format!("the pair lists of the nonbonded term: {e}"))
        })
    }

    fn set_precision(&self, precision: Precision) -> bool {
        let mut workspace = self.lock();
        workspace.precision = precision;
        workspace.cached = None;
        workspace.reusable = false;
        true
    }

    fn as_any(&self) -> Option<&dyn std::any::Any> {
        Some(self)
    }
}
