//! The short-range part by molecule ([`ShortRange`], declared in [`super`] so that the
//! loops below read its fields without importing this file): its molecule list ([`super::search`]),
//! the pairs inside molecules, the fixed chunks it evaluates (a number that depends only on
//! the atom count; in parallel for large systems, each into its own buffer, summed in chunk
//! order: the same bits at any thread count), the gradient cache the remainder reads, and
//! the list's state for checkpoints. Nothing is allocated once the list has its size. Which
//! loop runs: the SIMD blocks of [`lanes`] or the row loop of [`kernels`] for energies and
//! gradients over whole molecules, else the pair loop of [`pairs`].

use std::sync::atomic::{AtomicU8, AtomicUsize, Ordering};
use std::sync::{Mutex, MutexGuard};

use rayon::prelude::*;

use super::model::{Model, molecule_table};
use super::search::PairSearch;
use super::{ShortRange, SplitSpec, Switch, SwitchBy, kernels, lanes, pairs};
use crate::forces::clusters::Cluster;
use crate::forces::nonbonded::{NonbondedSpec, exclusion_lists};
use crate::forces::simd::Isa;

/// Intramolecular non-excluded pairs held for the molecule switch, at most (a bound on
/// memory for scenes with very large molecules, which should switch by atom pair).
const MAX_INTRAMOLECULAR_PAIRS: usize = 20_000_000;

/// Whole molecules for one chunk: packed atoms, clusters (one molecule kind) and scratch.
struct Whole<'a> {
    packed: &'a [[f64; 4]],
    clusters: &'a [Cluster<f64>],
    scratch: &'a mut kernels::Scratch,
}

/// One chunk's index, gradient buffer and scratch.
type Chunk<'a> = ((usize, &'a mut Vec<f64>), &'a mut kernels::Scratch);

/// What one evaluation computes.
#[derive(Clone, Copy)]
enum Mode<'a> {
    Energy,
    Gradient,
    HessianVector(&'a [f64]),
}

pub(super) struct Workspace {
    search: PairSearch,
    /// By molecule: `[x, y, z, q√k_e]` per atom in molecule order, each atom at the image
    /// nearest its reference atom (molecules made whole).
    packed: Vec<[f64; 4]>,
    /// By molecule, one kind of molecule: each molecule as a cluster for [`lanes`].
    clusters: Vec<Cluster<f64>>,
    /// One scratch per chunk for the whole-molecule loop.
    scratch: Vec<kernels::Scratch>,
    /// One gradient (or Hessian-vector) buffer per chunk, `n × 3` each.
    buffers: Vec<Vec<f64>>,
    energies: Vec<f64>,
    /// Positions of the last gradient evaluation, its gradient and energy.
    cached_q: Vec<f64>,
    cached_gradient: Vec<f64>,
    cached_energy: Option<f64>,
}

/// The instruction sets by index, for [`ShortRange::set_isa`].
const INSTRUCTION_SETS: [Isa; 3] = [Isa::Portable, Isa::Avx2, Isa::Avx512];

/// Chunks of the short part's list: a function of the atom count only (determinism).
fn chunk_count(n_atoms: usize) -> usize {
    match n_atoms {
        0..2048 => 1,
        2048..8192 => 4,
        _ => 8,
    }
}

impl ShortRange {
    pub(super) fn new(
        spec: &NonbondedSpec,
        switch: Switch,
        split: &SplitSpec,
        q: &[f64],
    ) -> Result<Self, String> {
        let n = spec.types.len();
        let model = Model::new(spec, q)?;
        let (excluded_start, excluded_partners) = exclusion_lists(n, &spec.excluded)?;
        let molecules = molecule_table(n, split, &spec.types)?;
        let points = molecules.reference.len();
        let chunks = chunk_count(n);
        let mut short = ShortRange {
            model,
            switch,
            molecules,
            intramolecular: Vec::new(),
            excluded_start,
            excluded_partners,
            chunks,
            isa: AtomicU8::new(0),
            lanes: None,
            listed_atom_pairs: AtomicUsize::new(0),
            workspace: Mutex::new(Self::workspace(spec, switch, points, chunks)),
        };
        short.set_isa(Isa::best());
        short.lanes = lanes::Lanes::of(&short.model, &short.molecules);
        short.intramolecular = short.intramolecular_pairs()?;
        {
            let mut workspace = short.lock();
            short.refresh(&mut workspace, q);
        }
        Ok(short)
    }

    /// The buffers, sized once here: the pair search over `points` (molecule reference
    /// atoms or atoms), one scratch and gradient buffer per chunk, the position cache.
    fn workspace(spec: &NonbondedSpec, switch: Switch, points: usize, chunks: usize) -> Workspace {
        let n = spec.types.len();
        Workspace {
            search: PairSearch::new(
                points,
                switch.r_out() + spec.skin,
                spec.skin,
                spec.box_lengths,
            ),
            packed: vec![[0.0; 4]; n],
            clusters: vec![Cluster::default(); points],
            scratch: (0..chunks).map(|_| kernels::Scratch::default()).collect(),
            buffers: vec![vec![0.0; 3 * n]; chunks],
            energies: vec![0.0; chunks],
            cached_q: vec![f64::NAN; 3 * n],
            cached_gradient: vec![0.0; 3 * n],
            cached_energy: None,
        }
    }

    /// The instruction set of the pair loops.
    pub fn isa(&self) -> Isa {
        INSTRUCTION_SETS[self.isa.load(Ordering::Relaxed) as usize]
    }

    /// Compile-time choice of the pair loops' instruction set (default: the widest
    /// available); every set gives the same bits. Panics if the processor lacks it.
    pub fn set_isa(&self, isa: Isa) {
        assert!(isa.is_available(), "{} is not available", isa.name());
        let index = INSTRUCTION_SETS.iter().position(|&i| i == isa).unwrap_or(0);
        self.isa.store(index as u8, Ordering::Relaxed);
        self.lock().cached_energy = None;
    }

    /// Which loop evaluates the molecule pairs: `"molecule blocks"` (SIMD, one kind of
    /// molecule of at most four atoms) or `"molecule rows"` (any molecules).
    pub fn pair_loop(&self) -> &'static str {
        match &self.lanes {
            Some(_) => "molecule blocks",
            None => "molecule rows",
        }
    }

    fn lock(&self) -> MutexGuard<'_, Workspace> {
        // A panic elsewhere while the lock was held leaves a list that is rebuilt anyway.
        self.workspace.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn is_excluded(&self, i: usize, j: usize) -> bool {
        self.excluded_partners[self.excluded_start[i] as usize..self.excluded_start[i + 1] as usize]
            .contains(&(j as u32))
    }

    fn intramolecular_pairs(&self) -> Result<Vec<[u32; 2]>, String> {
        let count: usize = (0..self.molecules.reference.len())
            .map(|m| {
                let k = self.molecules.atoms(m).len();
                k * k.saturating_sub(1) / 2
            })
            .sum();
        if count > MAX_INTRAMOLECULAR_PAIRS {
            return Err(format!(
                "by = \"molecule\" holds every pair inside a molecule ({count} here, at most \
                 {MAX_INTRAMOLECULAR_PAIRS}): switch large molecules by = \"atom\""
            ));
        }
        let mut pairs = Vec::new();
        for m in 0..self.molecules.reference.len() {
            let atoms = self.molecules.atoms(m);
            for (a, &i) in atoms.iter().enumerate() {
                for &j in &atoms[a + 1..] {
                    if !self.is_excluded(i as usize, j as usize) {
                        pairs.push([i, j]);
                    }
                }
            }
        }
        Ok(pairs)
    }

    /// Rebuild the molecule pair list if a reference atom (search point) has moved half the
    /// skin.
    fn refresh(&self, workspace: &mut Workspace, q: &[f64]) {
        let reference = &self.molecules.reference;
        let point = |k: usize| std::array::from_fn(|c| q[3 * reference[k] as usize + c]);
        self.refresh_at(workspace, point);
    }

    /// [`ShortRange::refresh`] with search point `k` at `point(k)`.
    fn refresh_at(&self, workspace: &mut Workspace, point: impl Fn(usize) -> [f64; 3]) {
        let search = &mut workspace.search;
        if !search.needs_rebuild(&point) {
            return;
        }
        search.build(point);
        let listed = search
            .pairs
            .iter()
            .map(|&[a, b]| {
                self.molecules.atoms(a as usize).len() * self.molecules.atoms(b as usize).len()
            })
            .sum::<usize>()
            + self.intramolecular.len();
        self.listed_atom_pairs.store(listed, Ordering::Relaxed);
        let (partners, atoms) = self.largest_row(&workspace.search.pairs);
        for scratch in &mut workspace.scratch {
            scratch.reserve(partners, atoms);
        }
    }

    /// The most partner molecules and partner atoms of one row molecule in `pairs`.
    fn largest_row(&self, pairs: &[[u32; 2]]) -> (usize, usize) {
        kernels::list_rows(pairs).fold((0, 0), |(partners, atoms), (_, group)| {
            let row_atoms = group
                .iter()
                .map(|&[_, b]| self.molecules.atoms(b as usize).len())
                .sum::<usize>();
            (partners.max(group.len()), atoms.max(row_atoms))
        })
    }

    /// One evaluation into the chunk buffers; returns the energy (0 for a Hessian-vector
    /// product). The buffers hold the gradient or product afterwards (not for `Energy`).
    fn run(&self, workspace: &mut Workspace, q: &[f64], mode: Mode) -> f64 {
        self.refresh(workspace, q);
        let whole = self.pack_molecules(q, &mut workspace.packed);
        if let (true, Some(lanes)) = (whole, &self.lanes) {
            lanes.pack(&workspace.packed, &mut workspace.clusters);
        }
        let Workspace {
            search,
            packed,
            clusters,
            scratch,
            buffers,
            energies,
            ..
        } = workspace;
        let pairs: &[[u32; 2]] = &search.pairs;
        let packed = whole.then_some(&packed[..]);
        let chunks = self.chunks;
        let work = |((c, buffer), scratch): Chunk| {
            let part = &pairs[c * pairs.len() / chunks..(c + 1) * pairs.len() / chunks];
            if !matches!(mode, Mode::Energy) {
                buffer.fill(0.0);
            }
            let whole = packed.map(|packed| Whole {
                packed,
                clusters,
                scratch,
            });
            self.evaluate(q, mode, part, SwitchBy::Molecule, whole, buffer)
        };
        if chunks > 1 {
            buffers
                .par_iter_mut()
                .enumerate()
                .zip(scratch.par_iter_mut())
                .zip(energies.par_iter_mut())
                .for_each(|(chunk, energy)| *energy = work(chunk));
        } else {
            energies[0] = work(((0, &mut buffers[0]), &mut scratch[0]));
        }
        // Pairs inside molecules after the chunks, into the first buffer (same order always).
        energies[0] += self.evaluate(
            q,
            mode,
            &self.intramolecular,
            SwitchBy::AtomPair,
            None,
            &mut buffers[0],
        );
        energies.iter().sum()
    }

    /// Fill `packed` (molecules made whole, charges) and say whether the whole-molecule
    /// pair loop gives the model's minimum-image pairs: it uses `d = D_IJ + u_j − u_i`
    /// (`D_IJ` the reference atoms' minimum image, `u` each atom's offset from its reference,
    /// at most `e`), which is the minimum image whenever `|d| < r_c < L/2`, and can only
    /// miss a pair inside the cutoff when `r_out + 2e > L − r_c` (a lattice vector is at
    /// least `L` long). Then the loop takes the minimum image pair by pair instead.
    fn pack_molecules(&self, q: &[f64], packed: &mut [[f64; 4]]) -> bool {
        let molecules = &self.molecules;
        let mut largest_offset2: f64 = 0.0;
        for m in 0..molecules.reference.len() {
            let r = molecules.reference[m] as usize;
            let x_ref = [q[3 * r], q[3 * r + 1], q[3 * r + 2]];
            let slots = molecules.start[m] as usize..molecules.start[m + 1] as usize;
            for (slot, &i) in packed[slots.clone()]
                .iter_mut()
                .zip(&molecules.atoms[slots])
            {
                let i = i as usize;
                let u = self
                    .model
                    .image(std::array::from_fn(|a| q[3 * i + a] - x_ref[a]));
                largest_offset2 = largest_offset2.max(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
                *slot = [
                    x_ref[0] + u[0],
                    x_ref[1] + u[1],
                    x_ref[2] + u[2],
                    self.model.scaled_charge(i),
                ];
            }
        }
        let reach = self.switch.r_out() + 2.0 * largest_offset2.sqrt();
        reach < self.model.shortest_period() - self.model.cutoff_squared.sqrt()
    }

    /// The pairs `part` of the list, switched `by` molecule or atom pair; `whole`: whole
    /// molecules (packed) and the chunk's scratch for the fast molecule loops. Each loop is
    /// compiled for the widest instruction set there is, on its own (the same operations in
    /// the same order, so the same bits; `round` becomes inline).
    fn evaluate(
        &self,
        q: &[f64],
        mode: Mode,
        part: &[[u32; 2]],
        by: SwitchBy,
        whole: Option<Whole>,
        buffer: &mut [f64],
    ) -> f64 {
        let gradient = matches!(mode, Mode::Gradient);
        match (mode, whole) {
            (Mode::HessianVector(v), _) => {
                self.run_loop(q, part, by, pairs::HessianVector { v }, buffer);
                0.0
            }
            (_, Some(whole)) => self.isa().run(
                #[inline(always)]
                || self.whole_molecules(gradient, part, whole, buffer),
            ),
            (_, None) if gradient => {
                let y = pairs::Energy::<true> { energy: 0.0 };
                self.run_loop(q, part, by, y, buffer).energy
            }
            (_, None) => {
                let y = pairs::Energy::<false> { energy: 0.0 };
                self.run_loop(q, part, by, y, buffer).energy
            }
        }
    }

    /// The pair loop of [`pairs`] over `part`, a list of molecule pairs or of atom pairs,
    /// compiled for the instruction set; returns what it yielded.
    fn run_loop<Y: pairs::Yield>(
        &self,
        q: &[f64],
        part: &[[u32; 2]],
        by: SwitchBy,
        mut y: Y,
        out: &mut [f64],
    ) -> Y {
        self.isa().run(
            #[inline(always)]
            || {
                match by {
                    SwitchBy::Molecule => pairs::molecule_pairs(self, q, part, &mut y, out),
                    SwitchBy::AtomPair => pairs::atom_pairs(self, q, part, &mut y, out),
                }
                y
            },
        )
    }

    /// Energy or gradient over whole molecules: the SIMD blocks for one molecule kind, else
    /// the row loop.
    #[inline(always)]
    fn whole_molecules(&self, gradient: bool, part: &[[u32; 2]], w: Whole, out: &mut [f64]) -> f64 {
        let Some(lanes) = &self.lanes else {
            return match gradient {
                true => kernels::whole_molecule_rows::<true>(self, w.packed, part, w.scratch, out),
                false => {
                    kernels::whole_molecule_rows::<false>(self, w.packed, part, w.scratch, out)
                }
            };
        };
        let block = lanes::Block {
            lanes,
            model: &self.model,
            switch: self.switch,
            molecules: &self.molecules,
            clusters: w.clusters,
            packed: w.packed,
            pairs: part,
        };
        match gradient {
            true => lanes::evaluate::<true>(self.isa(), &block, w.scratch, out),
            false => lanes::evaluate::<false>(self.isa(), &block, w.scratch, out),
        }
    }

    pub(super) fn energy(&self, q: &[f64]) -> f64 {
        let mut workspace = self.lock();
        if let Some(energy) = workspace.cached_energy
            && workspace.cached_q == q
        {
            return energy;
        }
        self.run(&mut workspace, q, Mode::Energy)
    }

    /// `gradient += sign ∇V_short(q)`, from the cache when `q` is the last gradient's.
    pub(super) fn add_scaled_gradient(&self, q: &[f64], gradient: &mut [f64], sign: f64) {
        let mut guard = self.lock();
        let workspace = &mut *guard;
        if !(workspace.cached_energy.is_some() && workspace.cached_q == q) {
            let energy = self.run(workspace, q, Mode::Gradient);
            workspace.cached_gradient.fill(0.0);
            reduce(&workspace.buffers, &mut workspace.cached_gradient, 1.0);
            workspace.cached_q.copy_from_slice(q);
            workspace.cached_energy = Some(energy);
        }
        for (g, c) in gradient.iter_mut().zip(&workspace.cached_gradient) {
            *g += sign * c;
        }
    }

    /// `out += sign ∇²V_short(q) v`.
    pub(super) fn add_scaled_hessian_vector(
        &self,
        q: &[f64],
        v: &[f64],
        out: &mut [f64],
        sign: f64,
    ) {
        let mut workspace = self.lock();
        self.run(&mut workspace, q, Mode::HessianVector(v));
        reduce(&workspace.buffers, out, sign);
    }

    /// The energy as (Lennard-Jones, Coulomb), for reports.
    pub(super) fn energy_parts(&self, q: &[f64]) -> (f64, f64) {
        let mut workspace = self.lock();
        self.refresh(&mut workspace, q);
        let parts =
            |list: &[[u32; 2]], by| self.run_loop(q, list, by, pairs::Parts::default(), &mut []);
        let [lj, coulomb] = parts(&workspace.search.pairs, SwitchBy::Molecule).parts;
        let [lj_inside, coulomb_inside] = parts(&self.intramolecular, SwitchBy::AtomPair).parts;
        (lj + lj_inside, coulomb + coulomb_inside)
    }

    pub(super) fn couplings(&self) -> Vec<Vec<usize>> {
        let workspace = self.lock();
        let mut couplings: Vec<Vec<usize>> = workspace
            .search
            .pairs
            .iter()
            .map(|&[a, b]| {
                let atoms = |m: u32| self.molecules.atoms(m as usize).iter().map(|&i| i as usize);
                atoms(a).chain(atoms(b)).collect()
            })
            .collect();
        couplings.extend(
            self.intramolecular
                .iter()
                .map(|&[a, b]| vec![a as usize, b as usize]),
        );
        couplings
    }

    /// Atom pairs of the list (molecule pairs counted by their atom pairs).
    pub(super) fn interaction_count(&self) -> usize {
        self.listed_atom_pairs.load(Ordering::Relaxed)
    }

    /// Forget the pair list and the cached gradient ([`ForceTerm::rebuild_lists`]).
    pub(super) fn rebuild_lists(&self) {
        let mut workspace = self.lock();
        workspace.search.invalidate();
        workspace.cached_q.fill(f64::NAN);
        workspace.cached_energy = None;
    }

    /// The reference atoms' positions at the molecule list's last build (`None` before
    /// it): `{"molecule_list_built_at": [x, y, z, …]}`, three numbers per molecule.
    pub(super) fn list_state(&self) -> Option<serde_json::Value> {
        let workspace = self.lock();
        let built_at = workspace.search.built_at()?;
        let flat: Vec<f64> = built_at.iter().flatten().copied().collect();
        Some(serde_json::json!({ LIST_KEY: flat }))
    }

    /// Build the molecule list at the positions of [`ShortRange::list_state`] (the build is
    /// a function of them alone), and forget the cached gradient.
    pub(super) fn restore_lists(&self, state: &serde_json::Value) -> crate::error::Result<()> {
        let points = self.molecules.reference.len();
        let built_at = state_points(state, points).map_err(|e| {
            crate::error::Error::input(format!("the pair list of the nonbonded split: {e}"))
        })?;
        self.rebuild_lists();
        self.refresh_at(&mut self.lock(), |k| built_at[k]);
        Ok(())
    }
}

/// The key of the molecule list's state in a checkpoint.
const LIST_KEY: &str = "molecule_list_built_at";

/// The `points` positions of a [`ShortRange::list_state`]; an error names what is wrong.
fn state_points(state: &serde_json::Value, points: usize) -> Result<Vec<[f64; 3]>, String> {
    let values = state
        .get(LIST_KEY)
        .and_then(|v| v.as_array())
        .ok_or_else(|| format!("no array \"{LIST_KEY}\""))?;
    if values.len() != 3 * points {
        return Err(format!(
            "\"{LIST_KEY}\" has {} numbers, this split has {points} molecules ({} expected)",
            values.len(),
            3 * points
        ));
    }
    let number = |k: usize| {
        values[k]
            .as_f64()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("\"{LIST_KEY}\"[{k}] is not a finite number"))
    };
    (0..points)
        .map(|m| Ok([number(3 * m)?, number(3 * m + 1)?, number(3 * m + 2)?]))
        .collect()
}

/// `out += sign Σ_c buffers[c]`, chunk by chunk in order.
fn reduce(buffers: &[Vec<f64>], out: &mut [f64], sign: f64) {
    if buffers.len() == 1 {
        for (o, b) in out.iter_mut().zip(&buffers[0]) {
            *o += sign * b;
        }
        return;
    }
    for (k, o) in out.iter_mut().enumerate() {
        let mut sum = 0.0;
        for buffer in buffers {
            sum += buffer[k];
        }
        *o += sign * sum;
    }
}
