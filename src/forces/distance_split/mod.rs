//! The non-bonded term split by distance into a short-range part and a remainder, for
//! three or more r-RESPA levels (bonded innermost, short-range non-bonded in the middle, the
//! remainder outermost), as LAMMPS `run_style respa … inner/middle/outer` splits pair
//! forces. Non-bonded: both parts are placed by the scene.
//!
//! **The parts.** With `V_ij(r)` the pair energy of the non-bonded model
//! ([`super::nonbonded`]: Lennard-Jones and the Coulomb form, with its cutoff `r_c`, zero
//! beyond it) and a switch `S` that is 1 below `r_in` and 0 above `r_out`:
//!
//! * **by molecule**: `V_short = Σ_{I<J} S(R_IJ) Σ_{i∈I, j∈J} V_ij(r_ij) +
//!   Σ_I Σ_{i<j ∈ I, not excluded} S(r_ij) V_ij(r_ij)`, where `R_IJ` is the
//!   (minimum-image) distance between the reference atoms of molecules `I` and `J` (O–O for
//!   water) and molecules are the connected components of the bond graph. Every atom pair of
//!   two molecules gets the same weight, so a neutral molecule's short-range part is a whole
//!   dipole–dipole interaction, switched off together: the remainder is a small, smooth
//!   force. A pair inside one molecule has no second molecule: it is switched on its own
//!   distance, as by atom pair.
//! * **by atom pair**: `V_short = Σ_{i<j, not excluded} S(r_ij) V_ij(r_ij)`, LAMMPS's
//!   choice. Cheaper bookkeeping, but the O–H and H–H pairs of two waters at the same O–O
//!   distance are switched at different distances, so the remainder keeps large
//!   charge–charge pieces that cancel only when summed over the molecule.
//! * **the remainder**: `V_rest = V − V_short`, computed as the full term minus the short
//!   part: the two add up to the model to round-off, whatever `r_in`, `r_out`.
//!
//! **The switch** is the quintic smoothstep `S(R) = 1 − 10t³ + 15t⁴ − 6t⁵ = u³(10 − 15u + 6u²)`
//! (`u = 1 − t`, the form evaluated),
//! `t = (R − r_in)/(r_out − r_in)` on `[r_in, r_out]`: `S′ = −30t²(1 − t)²/w` and
//! `S″ = −60t(1 − t)(1 − 2t)/w²` (`w = r_out − r_in`) vanish at both ends, so both parts
//! have continuous forces and Hessians. (LAMMPS multiplies each pair's *force* by the cubic
//! `1 − t²(3 − 2t)`, which is C¹; switching the energy here keeps each part a potential
//! with an energy, for the level energies and the conserved-energy monitors.)
//!
//! **Conditions.** `0 < r_in < r_out ≤ r_c`: the short part must lie inside the cutoff
//! (beyond it there is nothing to switch), and `r_out < r_c < L/2` keeps `S(R_IJ)` smooth
//! where the minimum image of the reference atoms jumps (at `R = L/2`, where `S = 0`).
//!
//! **Chain rule.** By molecule, with `E_IJ = Σ V_ij` and `n̂ = (x_J − x_I)/R` between the
//! reference atoms: `∇(S E) = S ∇E + S′ E ∇R` (`∇R = ±n̂` on the reference atoms), and
//! `∇²(S E)·v = S ∇²E v + S′[(∇R·v)∇E + (∇E·v)∇R] + E S″ (∇R·v)∇R + E S′ ∇²R v`, with
//! `∇²R v = ±(I − n̂n̂ᵀ)(v_J − v_I)/R` on the reference atoms. By atom pair `W = S V` is
//! radial: `W′ = S′V + SV′`, `W″ = S″V + 2S′V′ + SV″`, and the radial Hessian of
//! [`super::nonbonded`] applies.
//!
//! **Cost.** By atom pair the short part is the cluster-pair kernel of [`super::nonbonded`]
//! with its list cut at `r_out` and the switch applied in the lanes ([`Nonbonded::switched`]),
//! in either precision: on the solvated Trp-cage (`r_out` = 6 Å, 9 Å cutoff) about half the
//! full term's cost. By molecule ([`ShortRange`]) one pass over its own list of molecule
//! pairs ([`search`]), one switch value per listed pair inside `r_out` for all its atom
//! pairs: SIMD blocks of 4 × 4 atom pairs ([`lanes`]) for one kind of small molecule, the
//! row loop of [`kernels`] for other whole molecules, the pair loop of [`pairs`] for the
//! rest (docs/thermostats.md has the costs). The remainder reads the short part's cached
//! gradient (r-RESPA evaluates both levels at the same positions), so it costs one full
//! non-bonded evaluation, not two.

mod kernels;
mod lanes;
mod model;
mod pairs;
mod search;
mod short_range;

use std::sync::atomic::{AtomicU8, AtomicUsize};
use std::sync::{Arc, Mutex};

use super::nonbonded::{Electrostatics, Nonbonded, NonbondedSpec};
use super::simd::Isa;
pub use super::switch::Switch;
use super::{ForceTerm, Precision, TermClass};
use model::{Model, Molecules};
use short_range::Workspace;

/// The short-range part by molecule.
pub struct ShortRange {
    pub(crate) model: Model,
    pub(crate) switch: Switch,
    pub(crate) molecules: Molecules,
    /// Non-excluded pairs inside one molecule (by molecule), switched on their distance.
    intramolecular: Vec<[u32; 2]>,
    excluded_start: Vec<u32>,
    excluded_partners: Vec<u32>,
    chunks: usize,
    /// The instruction set the pair loops are compiled for (default the widest there is),
    /// as its index in `short_range::INSTRUCTION_SETS`.
    isa: AtomicU8,
    /// By molecule in a box of one kind of small molecule: the SIMD block loop's constants.
    lanes: Option<lanes::Lanes>,
    listed_atom_pairs: AtomicUsize,
    workspace: Mutex<Workspace>,
}

/// What the switch variable is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SwitchBy {
    /// The distance between the reference atoms of the two molecules.
    Molecule,
    /// The distance of the atom pair itself.
    AtomPair,
}

/// The Coulomb form of the short-range part.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ShortCoulomb {
    /// The term's own form (shifted force, reaction field, PME's `erfc(αr)/r`).
    Model,
    /// Bare `1/r`, as LAMMPS's rRESPA inner and middle levels take it with `coul/long`: with
    /// PME the near-field Coulomb force is on the short level in full, and the remainder
    /// (real space − switched bare Coulomb) with the reciprocal sum is smooth when whole
    /// neutral molecules are switched together. With `erfc(αr)/r` in the short part the
    /// reciprocal sum's `erf(αr)/r` near field stays on the slow level.
    Bare,
}

/// How to split a non-bonded term.
#[derive(Clone, Debug)]
pub struct SplitSpec {
    pub r_in: f64,
    pub r_out: f64,
    pub by: SwitchBy,
    pub short_coulomb: ShortCoulomb,
    /// Molecule index per atom (by molecule; see [`molecules_from_bonds`]).
    pub molecule_of: Vec<u32>,
    /// The reference atom of each molecule (by molecule; see [`reference_atoms`]).
    pub reference_atoms: Vec<usize>,
}

/// Molecules as the connected components of the bond graph: an index per atom, numbered
/// in order of each molecule's first atom.
pub fn molecules_from_bonds(n: usize, bonds: &[[usize; 2]]) -> Vec<u32> {
    let mut components = super::components::Components::new(n);
    for &[a, b] in bonds {
        if a < n && b < n {
            components.join(a, b);
        }
    }
    components.labels()
}

/// The reference atom of each molecule: the first atom (in file order) for which
/// `eligible` holds, or with `eligible = None` the first of the heaviest atoms. Errors name
/// a molecule with no eligible atom.
pub fn reference_atoms(
    molecule_of: &[u32],
    masses: &[f64],
    eligible: Option<&dyn Fn(usize) -> bool>,
) -> Result<Vec<usize>, String> {
    let n_molecules = molecule_of
        .iter()
        .map(|&m| m as usize + 1)
        .max()
        .unwrap_or(0);
    let mut chosen: Vec<Option<usize>> = vec![None; n_molecules];
    for (i, &m) in molecule_of.iter().enumerate() {
        let slot = &mut chosen[m as usize];
        let better = match eligible {
            Some(eligible) => slot.is_none() && eligible(i),
            None => slot.is_none_or(|k| masses[i] > masses[k]),
        };
        if better {
            *slot = Some(i);
        }
    }
    chosen
        .into_iter()
        .enumerate()
        .map(|(m, atom)| {
            atom.ok_or_else(|| {
                let first = molecule_of
                    .iter()
                    .position(|&x| x as usize == m)
                    .unwrap_or(0);
                format!("molecule {m} (the one holding atom {first}) has no such atom")
            })
        })
        .collect()
}

/// The short-range part, shared by the two terms (the remainder subtracts it): by atom
/// pair the model's term in the cluster-pair kernel with every pair multiplied by the
/// switch ([`Nonbonded::switched`]), by molecule the molecule loops of [`ShortRange`].
pub enum ShortPart {
    AtomPairs(Box<Nonbonded>),
    Molecules(Box<ShortRange>),
}

/// The short-range part on its level.
pub struct NonbondedShort {
    short: Arc<ShortPart>,
}

/// The full non-bonded term minus the short-range part, on a higher level.
pub struct NonbondedRemainder {
    full: Nonbonded,
    short: Arc<ShortPart>,
}

/// Split the non-bonded term of `spec` by `split` at positions `q`: the short-range part
/// and the remainder. Errors are messages for the scene to locate.
pub fn split_nonbonded(
    spec: NonbondedSpec,
    split: &SplitSpec,
    q: &[f64],
) -> Result<(NonbondedShort, NonbondedRemainder), String> {
    let switch = Switch::new(split.r_in, split.r_out)?;
    if split.r_out > spec.cutoff {
        return Err(format!(
            "r_out = {} is beyond the non-bonded cutoff {}: the short-range part must lie \
             inside the cutoff",
            split.r_out, spec.cutoff
        ));
    }
    let mut short_spec = spec.clone();
    if split.short_coulomb == ShortCoulomb::Bare && spec.electrostatics != Electrostatics::None {
        short_spec.electrostatics = Electrostatics::Plain;
    }
    let short = match split.by {
        SwitchBy::AtomPair => {
            ShortPart::AtomPairs(Box::new(Nonbonded::switched(short_spec, switch, q)?))
        }
        SwitchBy::Molecule => {
            ShortPart::Molecules(Box::new(ShortRange::new(&short_spec, switch, split, q)?))
        }
    };
    let full = Nonbonded::new(spec, q)?;
    let short = Arc::new(short);
    Ok((
        NonbondedShort {
            short: short.clone(),
        },
        NonbondedRemainder { full, short },
    ))
}

/// The same call on either kind of short part `$part: Arc<ShortPart>` (both have the
/// method).
macro_rules! either {
    ($part:expr, $p:ident => $call:expr) => {
        match &*$part {
            ShortPart::AtomPairs($p) => $call,
            ShortPart::Molecules($p) => $call,
        }
    };
}

impl ShortPart {
    /// `"switched off between r_in = 6 and r_out = 7 by molecule (reference atoms' distance)"`.
    pub fn describe(&self) -> String {
        let (by, switch) = match self {
            ShortPart::AtomPairs(pairs) => ("by atom pair", pairs.switch()),
            ShortPart::Molecules(short) => (
                "by molecule (distance of the reference atoms)",
                Some(short.switch),
            ),
        };
        let (r_in, r_out) = switch.map_or((0.0, 0.0), |s| (s.r_in(), s.r_out()));
        format!("switched off between r_in = {r_in} and r_out = {r_out} {by}")
    }

    /// Which loop evaluates the short part: `"cluster pairs"` by atom pair, else
    /// [`ShortRange::pair_loop`].
    pub fn pair_loop(&self) -> &'static str {
        match self {
            ShortPart::AtomPairs(_) => "cluster pairs",
            ShortPart::Molecules(short) => short.pair_loop(),
        }
    }

    /// The instruction set of the pair loops (every set gives the same bits).
    pub fn set_isa(&self, isa: Isa) {
        match self {
            ShortPart::AtomPairs(p) => p.set_isa(isa),
            ShortPart::Molecules(p) => p.set_isa(isa),
        }
    }
}

impl NonbondedShort {
    /// The shared short-range part (its switch, description and list statistics).
    pub fn short_range(&self) -> &ShortPart {
        &self.short
    }
}

impl ForceTerm for NonbondedShort {
    fn kind(&self) -> &'static str {
        "nonbonded-short"
    }

    fn class(&self) -> TermClass {
        TermClass::Nonbonded
    }

    fn energy(&self, q: &[f64]) -> f64 {
        either!(self.short, p => p.energy(q))
    }

    fn add_gradient(&self, q: &[f64], gradient: &mut [f64]) {
        either!(self.short, p => p.add_scaled_gradient(q, gradient, 1.0));
    }

    fn add_hessian_vector(&self, q: &[f64], v: &[f64], out: &mut [f64]) {
        either!(self.short, p => p.add_scaled_hessian_vector(q, v, out, 1.0));
    }

    fn couplings(&self) -> Vec<Vec<usize>> {
        either!(self.short, p => p.couplings())
    }

    fn interaction_count(&self) -> usize {
        either!(self.short, p => p.interaction_count())
    }

    fn energy_components(&self, q: &[f64]) -> Vec<(&'static str, f64)> {
        let (lj, coulomb) = either!(self.short, p => p.energy_parts(q));
        vec![("lennard-jones", lj), ("coulomb", coulomb)]
    }

    fn rebuild_lists(&self) {
        either!(self.short, p => p.rebuild_lists());
    }

    fn list_state(&self) -> Option<serde_json::Value> {
        either!(self.short, p => p.list_state())
    }

    fn restore_lists(&self, state: &serde_json::Value) -> crate::error::Result<()> {
        either!(self.short, p => p.restore_lists(state))
    }

    /// By atom pair (the cluster-pair kernel) in either precision; the molecule loops
    /// stay in double.
    fn set_precision(&self, precision: Precision) -> bool {
        match &*self.short {
            ShortPart::AtomPairs(pairs) => pairs.set_precision(precision),
            ShortPart::Molecules(_) => false,
        }
    }
}

impl ForceTerm for NonbondedRemainder {
    fn kind(&self) -> &'static str {
        "nonbonded-remainder"
    }

    fn class(&self) -> TermClass {
        TermClass::Nonbonded
    }

    fn energy(&self, q: &[f64]) -> f64 {
        self.full.energy(q) - either!(self.short, p => p.energy(q))
    }

    fn rebuild_lists(&self) {
        self.full.rebuild_lists();
        either!(self.short, p => p.rebuild_lists());
    }

    /// The full term's lists and the short part's (which [`NonbondedShort`] saves too):
    /// `{"full": …, "short": …}`, or `None` unless both have a state, so that a checkpoint
    /// rebuilds both or neither ([`ForceTerm::rebuild_lists`] does both).
    fn list_state(&self) -> Option<serde_json::Value> {
        let (full, short) = (
            self.full.list_state()?,
            either!(self.short, p => p.list_state())?,
        );
        Some(serde_json::json!({ "full": full, "short": short }))
    }

    fn restore_lists(&self, state: &serde_json::Value) -> crate::error::Result<()> {
        let part = |key: &str| {
            state.get(key).ok_or_else(|| {
                crate::error::Error::input(format!(
                    "the pair lists of the nonbonded remainder: no \"{key}\""
                ))
            })
        };
        self.full.restore_lists(part("full")?)?;
        either!(self.short, p => p.restore_lists(part("short")?))
    }

    fn add_gradient(&self, q: &[f64], gradient: &mut [f64]) {
        self.full.add_gradient(q, gradient);
        either!(self.short, p => p.add_scaled_gradient(q, gradient, -1.0));
    }

    fn add_hessian_vector(&self, q: &[f64], v: &[f64], out: &mut [f64]) {
        self.full.add_hessian_vector(q, v, out);
        either!(self.short, p => p.add_scaled_hessian_vector(q, v, out, -1.0));
    }

    fn couplings(&self) -> Vec<Vec<usize>> {
        self.full.couplings()
    }

    /// The full term's pairs: the short part's gradient usually comes from its cache (the
    /// middle level was just evaluated at the same positions).
    fn interaction_count(&self) -> usize {
        self.full.interaction_count()
    }

    /// The full term's precision (the short part is the other term's).
    fn set_precision(&self, precision: Precision) -> bool {
        self.full.set_precision(precision)
    }

    fn energy_components(&self, q: &[f64]) -> Vec<(&'static str, f64)> {
        let full = self.full.energy_components(q);
        let (lj, coulomb) = either!(self.short, p => p.energy_parts(q));
        let component = |name: &str| full.iter().find(|(n, _)| *n == name).map_or(0.0, |c| c.1);
        vec![
            ("lennard-jones", component("lennard-jones") - lj),
            ("coulomb", component("coulomb") - coulomb),
        ]
    }
}
