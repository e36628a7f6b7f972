//! The one pair loop of the short part (formulas in the parent module's doc) over a list of
//! molecule pairs or of atom pairs, and what it yields: the energy, the energy and its
//! gradient, a Hessian-vector product, or the energy as (Lennard-Jones, Coulomb) for
//! reports ([`Yield`]). By molecule a listed pair inside `r_out` gets one switch value
//! `S(R)` for all its atom pairs inside the cutoff; by atom pair (the pairs inside a
//! molecule) each pair is switched on its own distance. Gradients and products go into one
//! chunk's buffer. (Whole molecules in energy or gradient take the faster row loop of
//! [`super::kernels`] or the blocks of [`super::lanes`] instead.)
//!
//! Cost: one pass over the list; per atom pair one model evaluation (`V`, `V′/r`) for the
//! energy and gradient, or `V, V′, V″` and two dot products for the product.

use super::{Model, ShortRange, Switch};

#[inline(always)]
pub(super) fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `buffer[j] += h`, `buffer[i] −= h`.
#[inline(always)]
pub(super) fn add_pair(buffer: &mut [f64], i: usize, j: usize, h: [f64; 3]) {
    for k in 0..3 {
        buffer[3 * j + k] += h[k];
        buffer[3 * i + k] -= h[k];
    }
}

#[inline(always)]
fn difference(v: &[f64], i: usize, j: usize) -> [f64; 3] {
    std::array::from_fn(|k| v[3 * j + k] - v[3 * i + k])
}

/// A listed molecule pair inside `r_out`: its reference atoms `ra`, `rb`, their minimum
/// image `d = x_rb − x_ra` and `R = |d|`.
#[derive(Clone, Copy)]
pub(super) struct MoleculePair {
    pub ra: usize,
    pub rb: usize,
    pub d: [f64; 3],
    pub big_r: f64,
}

/// An atom pair `i, j` with minimum image `d = x_j − x_i` and `r² = r2`.
#[derive(Clone, Copy)]
pub(super) struct AtomPair {
    pub i: usize,
    pub j: usize,
    pub d: [f64; 3],
    pub r2: f64,
}

/// What the pair loop yields, step by step: per listed molecule pair a switch state
/// ([`Yield::molecule`]), its atom pairs inside the cutoff ([`Yield::in_molecule`]) and the
/// switch's own terms on the reference atoms ([`Yield::end_molecule`]); per atom pair
/// inside `r_out` the switched pair on its own distance ([`Yield::atom_pair`]).
pub(super) trait Yield {
    type Molecule;
    fn molecule(&mut self, switch: Switch, pair: &MoleculePair) -> Self::Molecule;
    fn in_molecule(&mut self, m: &mut Self::Molecule, model: &Model, p: AtomPair, out: &mut [f64]);
    fn end_molecule(&mut self, m: Self::Molecule, pair: &MoleculePair, out: &mut [f64]);
    fn atom_pair(&mut self, model: &Model, switch: Switch, p: AtomPair, out: &mut [f64]);
}

/// The loop over molecule pairs `pairs` (molecule indices), each weighted by `S(R_IJ)`.
#[inline(always)]
pub(super) fn molecule_pairs<Y: Yield>(
    short: &ShortRange,
    q: &[f64],
    pairs: &[[u32; 2]],
    y: &mut Y,
    out: &mut [f64],
) {
    let (model, molecules) = (&short.model, &short.molecules);
    let r_out2 = short.switch.r_out() * short.switch.r_out();
    for &[a, b] in pairs {
        let (a, b) = (a as usize, b as usize);
        let (ra, rb) = (
            molecules.reference[a] as usize,
            molecules.reference[b] as usize,
        );
        let d = model.displacement(q, ra, rb);
        let big_r2 = dot(&d, &d);
        if big_r2 >= r_out2 {
            continue;
        }
        let pair = MoleculePair {
            ra,
            rb,
            d,
            big_r: big_r2.sqrt(),
        };
        let mut m = y.molecule(short.switch, &pair);
        for &i in molecules.atoms(a) {
            for &j in molecules.atoms(b) {
                let (i, j) = (i as usize, j as usize);
                let d = model.displacement(q, i, j);
                let r2 = dot(&d, &d);
                if r2 >= model.cutoff_squared {
                    continue;
                }
                y.in_molecule(&mut m, model, AtomPair { i, j, d, r2 }, out);
            }
        }
        y.end_molecule(m, &pair, out);
    }
}

/// The loop over atom pairs `pairs`, each switched on its own distance (`r_out ≤ r_c`:
/// every pair inside `r_out` is inside the cutoff).
#[inline(always)]
pub(super) fn atom_pairs<Y: Yield>(
    short: &ShortRange,
    q: &[f64],
    pairs: &[[u32; 2]],
    y: &mut Y,
    out: &mut [f64],
) {
    let model = &short.model;
    let r_out2 = short.switch.r_out() * short.switch.r_out();
    for &[i, j] in pairs {
        let (i, j) = (i as usize, j as usize);
        let d = model.displacement(q, i, j);
        let r2 = dot(&d, &d);
        if r2 >= r_out2 {
            continue;
        }
        y.atom_pair(model, short.switch, AtomPair { i, j, d, r2 }, out);
    }
}

/// `Σ S V` in `energy`, and its gradient into the buffer when `GRADIENT`.
pub(super) struct Energy<const GRADIENT: bool> {
    pub energy: f64,
}

impl<const GRADIENT: bool> Yield for Energy<GRADIENT> {
    /// `S`, `S′` and `E_IJ` summed so far.
    type Molecule = (f64, f64, f64);

    #[inline(always)]
    fn molecule(&mut self, switch: Switch, pair: &MoleculePair) -> Self::Molecule {
        let (s, s1) = switch.value_slope(pair.big_r);
        (s, s1, 0.0)
    }

    #[inline(always)]
    fn in_molecule(&mut self, m: &mut Self::Molecule, model: &Model, p: AtomPair, out: &mut [f64]) {
        let (v, f) = model.energy_force(p.i, p.j, p.r2);
        m.2 += v;
        if GRADIENT {
            // ∂V/∂x_j = V′ d/r = −f d, weighted by S.
            let k = -m.0 * f;
            add_pair(out, p.i, p.j, p.d.map(|x| k * x));
        }
    }

    #[inline(always)]
    fn end_molecule(
        &mut self,
        (s, s1, pair_energy): Self::Molecule,
        pair: &MoleculePair,
        out: &mut [f64],
    ) {
        self.energy += s * pair_energy;
        if GRADIENT && s1 != 0.0 {
            let k = pair_energy * s1 / pair.big_r;
            add_pair(out, pair.ra, pair.rb, pair.d.map(|x| k * x));
        }
    }

    #[inline(always)]
    fn atom_pair(&mut self, model: &Model, switch: Switch, p: AtomPair, out: &mut [f64]) {
        let (v, f) = model.energy_force(p.i, p.j, p.r2);
        let r = p.r2.sqrt();
        let (s, s1) = switch.value_slope(r);
        self.energy += s * v;
        if GRADIENT {
            // W′/r = S′V/r + S V′/r = S′V/r − S f.
            let k = s1 * v / r - s * f;
            add_pair(out, p.i, p.j, p.d.map(|x| k * x));
        }
    }
}

/// `∇²V_short v` into the buffer.
pub(super) struct HessianVector<'a> {
    pub v: &'a [f64],
}

/// A molecule pair's switch for the product: `(S, S′, S″)`, `n̂`, `v_J − v_I` on the
/// reference atoms, `∇R·v`, and `E_IJ`, `∇E·v` summed so far.
pub(super) struct Curved {
    s: (f64, f64, f64),
    n: [f64; 3],
    dv_ref: [f64; 3],
    rv: f64,
    energy: f64,
    ev: f64,
}

impl Yield for HessianVector<'_> {
    type Molecule = Curved;

    #[inline(always)]
    fn molecule(&mut self, switch: Switch, pair: &MoleculePair) -> Curved {
        let n = pair.d.map(|x| x / pair.big_r);
        let dv_ref = difference(self.v, pair.ra, pair.rb);
        let (rv, energy, ev) = (dot(&n, &dv_ref), 0.0, 0.0);
        let s = switch.derivatives(pair.big_r);
        Curved {
            s,
            n,
            dv_ref,
            rv,
            energy,
            ev,
        }
    }

    #[inline(always)]
    fn in_molecule(&mut self, m: &mut Curved, model: &Model, p: AtomPair, out: &mut [f64]) {
        let r = p.r2.sqrt();
        let (e, d1, d2) = model.derivatives(p.i, p.j, r);
        m.energy += e;
        let dv = difference(self.v, p.i, p.j);
        let alpha = d1 / r;
        let along = (d2 - alpha) / p.r2 * dot(&p.d, &dv);
        m.ev += alpha * dot(&p.d, &dv);
        // S ∇²E v + S′(∇R·v)∇E, pair by pair (∇_j V = α d).
        let (s, s1, _) = m.s;
        let kick = s1 * m.rv * alpha;
        let h: [f64; 3] =
            std::array::from_fn(|k| s * (alpha * dv[k] + along * p.d[k]) + kick * p.d[k]);
        add_pair(out, p.i, p.j, h);
    }

    #[inline(always)]
    fn end_molecule(&mut self, m: Curved, pair: &MoleculePair, out: &mut [f64]) {
        let (_, s1, s2) = m.s;
        if s1 != 0.0 || s2 != 0.0 {
            // S′(∇E·v)∇R + E S″(∇R·v)∇R + E S′∇²R v on the reference atoms.
            let c = s1 * m.ev + m.energy * s2 * m.rv;
            let t = m.energy * s1 / pair.big_r;
            let h: [f64; 3] =
                std::array::from_fn(|k| c * m.n[k] + t * (m.dv_ref[k] - m.n[k] * m.rv));
            add_pair(out, pair.ra, pair.rb, h);
        }
    }

    /// The radial Hessian of `W = S V`.
    #[inline(always)]
    fn atom_pair(&mut self, model: &Model, switch: Switch, p: AtomPair, out: &mut [f64]) {
        let r = p.r2.sqrt();
        let (e, d1, d2) = model.derivatives(p.i, p.j, r);
        let (s, s1, s2) = switch.derivatives(r);
        let w1 = s1 * e + s * d1;
        let w2 = s2 * e + 2.0 * s1 * d1 + s * d2;
        let alpha = w1 / r;
        let dv = difference(self.v, p.i, p.j);
        let along = (w2 - alpha) / p.r2 * dot(&p.d, &dv);
        let h: [f64; 3] = std::array::from_fn(|k| alpha * dv[k] + along * p.d[k]);
        add_pair(out, p.i, p.j, h);
    }
}

/// The switched energy as (Lennard-Jones, Coulomb), for reports.
#[derive(Default)]
pub(super) struct Parts {
    pub parts: [f64; 2],
}

impl Parts {
    #[inline(always)]
    fn add(&mut self, model: &Model, p: AtomPair, s: f64) {
        let (lj, coulomb) = model.energy_parts(p.i, p.j, p.r2);
        self.parts[0] += s * lj;
        self.parts[1] += s * coulomb;
    }
}

impl Yield for Parts {
    /// `S(R)`.
    type Molecule = f64;

    fn molecule(&mut self, switch: Switch, pair: &MoleculePair) -> f64 {
        switch.value_slope(pair.big_r).0
    }

    fn in_molecule(&mut self, s: &mut f64, model: &Model, p: AtomPair, _: &mut [f64]) {
        self.add(model, p, *s);
    }

    fn end_molecule(&mut self, _: f64, _: &MoleculePair, _: &mut [f64]) {}

    fn atom_pair(&mut self, model: &Model, switch: Switch, p: AtomPair, _: &mut [f64]) {
        self.add(model, p, switch.value_slope(p.r2.sqrt()).0);
    }
}
