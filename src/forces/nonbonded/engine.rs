//! Evaluation of the non-bonded term over its cluster-pair list: list refresh, per-slot
//! parameters after a build, the kernel over the chunks (in parallel for large systems),
//! the reduction of the chunks' gradient buffers in chunk order, and the Hessian-vector
//! product.

use std::sync::atomic::Ordering;

use rayon::prelude::*;

use super::kernel::{self, Gradient4, Job, LjData, Out};
use super::{Electrostatics, Kernel, Nonbonded, Precision};
use crate::forces::clusters::{
    CLUSTER, Chunk, Cluster, ClusterList, PAD, PARALLEL_MIN_ATOMS, PARALLEL_PASSES_MIN_ATOMS,
    Refresh, reserve_total,
};
use crate::forces::simd::{Isa, Real};

/// The list, the kernel's inputs in both precisions, the chunks' buffers and the cached
/// energy; behind a mutex because `ForceTerm` methods take `&self`.
pub struct Workspace {
    pub list: ClusterList,
    pub isa: Isa,
    pub precision: Precision,
    /// [`Job::every_group`] (tests).
    pub every_group: bool,
    clusters32: Vec<Cluster<f32>>,
    /// Per-slot Lennard-Jones factors (factored parameters) or types (table).
    factors64: Vec<[f64; 8]>,
    factors32: Vec<[f32; 8]>,
    types: Vec<[u32; 4]>,
    table64: Vec<[f64; 3]>,
    table32: Vec<[f32; 3]>,
    /// Per j-cluster and i-type, the force lanes of the table ([`LjData::Table`]).
    by_type64: Vec<[[f64; 4]; 2]>,
    by_type32: Vec<[[f32; 4]; 2]>,
    /// Per cluster, bit `k` where slot `k` holds an atom with Lennard-Jones partners.
    lj_rows: Vec<u8>,
    /// Per type, whether it has a Lennard-Jones partner (a non-zero table entry).
    type_has_lj: Vec<bool>,
    /// One gradient buffer per chunk, by cluster.
    buffers: Vec<Vec<Gradient4>>,
    /// (Lennard-Jones, Coulomb) energy of each chunk.
    energies: Vec<(f64, f64)>,
    reduced: Vec<Gradient4>,
    /// Positions of the last evaluation and its energies, if computed.
    cached_q: Vec<f64>,
    pub cached: Option<(f64, f64)>,
    /// The chunks' buffers hold the gradient at `cached_q` for the current list (a switched
    /// term reuses them: r-RESPA asks for the short part and then the remainder there).
    pub reusable: bool,
    /// Whether gradients compute the energy too (the last one's energy was asked for).
    energy_wanted: bool,
    energy_used: bool,
}

impl Workspace {
    pub fn new(list: ClusterList) -> Self {
        let chunks = list.chunks.len();
        Workspace {
            list,
            isa: Isa::best(),
            precision: Precision::Double,
            every_group: false,
            clusters32: Vec::new(),
            factors64: Vec::new(),
            factors32: Vec::new(),
            types: Vec::new(),
            table64: Vec::new(),
            table32: Vec::new(),
            by_type64: Vec::new(),
            by_type32: Vec::new(),
            lj_rows: Vec::new(),
            type_has_lj: Vec::new(),
            buffers: vec![Vec::new(); chunks],
            energies: vec![(0.0, 0.0); chunks],
            reduced: Vec::new(),
            cached_q: Vec::new(),
            cached: None,
            reusable: false,
            energy_wanted: false,
            energy_used: false,
        }
    }
}

/// `len ≥ n`, with capacity for `most` (later builds of a run allocate nothing).
fn ensure<T: Clone + Default>(v: &mut Vec<T>, n: usize, most: usize) {
    reserve_total(v, most);
    if v.len() < n {
        v.resize(n, T::default());
    }
}

/// The cyclic window `(start, len)` of `n` clusters as two ranges.
fn window_ranges(window: (usize, usize), n: usize) -> [std::ops::Range<usize>; 2] {
    let (start, len) = (window.0.min(n), window.1.min(n));
    let end = start + len;
    if end <= n {
        [start..end, 0..0]
    } else {
        [start..n, 0..end - n]
    }
}

impl Nonbonded {
    /// Make the list valid at `q` and the kernel's inputs current.
    pub(super) fn refresh(&self, workspace: &mut Workspace, q: &[f64]) {
        workspace.reusable = false;
        let refresh = workspace.list.update(q);
        if refresh == Refresh::Built {
            self.slot_parameters(workspace);
        }
        if refresh != Refresh::Kept {
            self.listed_pairs
                .store(workspace.list.inner_pairs(), Ordering::Relaxed);
        }
        if workspace.precision == Precision::Mixed {
            let Workspace {
                list, clusters32, ..
            } = workspace;
            clusters32.clear();
            clusters32.extend(list.positions.iter().map(Cluster::to_f32));
        }
    }

    /// The lists as [`ClusterList::restore`] makes them from another run's
    /// [`ClusterList::built_at`], with the per-slot parameters of that build, and no cached
    /// result: the next evaluation computes afresh over the same pairs in the same order.
    pub(super) fn restore_cluster_lists(
        &self,
        at_build: &[f64],
        at_prune: &[f64],
    ) -> Result<(), String> {
        let mut guard = self.lock();
        let workspace = &mut *guard;
        workspace.list.restore(at_build, at_prune)?;
        self.slot_parameters(workspace);
        self.listed_pairs
            .store(workspace.list.inner_pairs(), Ordering::Relaxed);
        workspace.cached_q.clear();
        workspace.cached = None;
        workspace.reusable = false;
        Ok(())
    }

    /// Lennard-Jones data by slot (after a build), the tables, and buffers of the size.
    fn slot_parameters(&self, workspace: &mut Workspace) {
        let clusters = workspace.list.clusters();
        let most = workspace.list.max_clusters();
        reserve_total(&mut workspace.factors64, most);
        reserve_total(&mut workspace.factors32, most);
        reserve_total(&mut workspace.types, most);
        reserve_total(&mut workspace.clusters32, most);
        if workspace.table64.is_empty() {
            // Padding has type 0 but a zero mask, so its table entries never count.
            workspace.table64 = self.lj.iter().map(|p| [p.c12, p.c6, p.shift]).collect();
            workspace.table32 = self
                .lj
                .iter()
                .map(|p| [p.c12, p.c6, p.shift].map(|v| v as f32))
                .collect();
            workspace.type_has_lj = (0..self.n_types)
                .map(|t| {
                    let row = &workspace.table64[t * self.n_types..(t + 1) * self.n_types];
                    row.iter().flatten().any(|&v| v != 0.0)
                })
                .collect();
        }
        let slots = &workspace.list.grid.slots;
        workspace.factors64.clear();
        workspace.types.clear();
        for c in 0..clusters {
            let atoms = &slots[c * CLUSTER..(c + 1) * CLUSTER];
            let type_of = |k: usize| match atoms[k] {
                PAD => None,
                atom => Some(self.types[atom as usize] as usize),
            };
            workspace
                .types
                .push(std::array::from_fn(|k| type_of(k).unwrap_or(0) as u32));
            if let Some(factored) = &self.factored {
                workspace.factors64.push(std::array::from_fn(|k| {
                    type_of(k % 4).map_or(0.0, |t| factored.per_type[t][k / 4])
                }));
            }
        }
        let factors32 = workspace.factors64.iter().map(|f| f.map(|v| v as f32));
        workspace.factors32.clear();
        workspace.factors32.extend(factors32);
        if self.factored.is_none() {
            self.table_by_type(workspace, clusters, most);
        }
        for buffer in &mut workspace.buffers {
            ensure(buffer, clusters, most);
        }
        ensure(&mut workspace.reduced, clusters, most);
    }

    /// [`LjData::Table`]'s lanes by j-cluster and i-type, `(12 c₁₂, 6 c₆)` in each precision
    /// with the kernel's roundings (the coefficient rounded to the precision, then the
    /// product in it), and the slots with Lennard-Jones partners.
    fn table_by_type(&self, workspace: &mut Workspace, clusters: usize, most: usize) {
        let n_types = self.n_types;
        let Workspace {
            list,
            types,
            table64,
            by_type64,
            by_type32,
            lj_rows,
            type_has_lj,
            ..
        } = workspace;
        reserve_total(by_type64, most * n_types);
        by_type64.clear();
        reserve_total(by_type32, most * n_types);
        by_type32.clear();
        reserve_total(lj_rows, most);
        lj_rows.clear();
        let slots = &list.grid.slots;
        for (c, cluster_types) in types.iter().enumerate().take(clusters) {
            for t in 0..n_types {
                let entry = |k: usize| table64[t * n_types + cluster_types[k] as usize];
                by_type64.push([
                    std::array::from_fn(|k| 12.0 * entry(k)[0]),
                    std::array::from_fn(|k| 6.0 * entry(k)[1]),
                ]);
                by_type32.push([
                    std::array::from_fn(|k| 12.0f32 * entry(k)[0] as f32),
                    std::array::from_fn(|k| 6.0f32 * entry(k)[1] as f32),
                ]);
            }
            let atoms = &slots[c * CLUSTER..(c + 1) * CLUSTER];
            let bits = (0..CLUSTER).filter(|&k| {
                atoms[k] != PAD && type_has_lj[self.types[atoms[k] as usize] as usize]
            });
            lj_rows.push(bits.fold(0u8, |b, k| b | 1 << k));
        }
    }

    /// Energies (LJ, Coulomb) and, with `gradient`, `gradient += sign ∇V`.
    pub(super) fn evaluate(
        &self,
        q: &[f64],
        mut gradient: Option<&mut [f64]>,
        sign: f64,
    ) -> (f64, f64) {
        let mut guard = self.lock();
        let workspace = &mut *guard;
        let same = workspace.cached_q == q;
        if let Some(gradient) = gradient.as_deref_mut()
            && same
            && workspace.reusable
            && self.switch.is_some()
        {
            // The switched part's last gradient, here again: only the reduction.
            self.reduce(workspace, gradient, sign);
            return workspace.cached.unwrap_or_default();
        }
        if gradient.is_none() && same {
            if let Some(cached) = workspace.cached {
                workspace.energy_used = true;
                return cached;
            }
            // The last gradient was here without its energy: compute it with the next ones.
            workspace.energy_wanted = true;
        }
        if gradient.is_some() && workspace.cached.is_some() && !workspace.energy_used {
            workspace.energy_wanted = false;
        }
        self.refresh(workspace, q);
        let with_energy = gradient.is_none() || workspace.energy_wanted;
        let energies = match workspace.precision {
            Precision::Double => self.run_chunks::<f64>(workspace, with_energy),
            Precision::Mixed => self.run_chunks::<f32>(workspace, with_energy),
        };
        if let Some(gradient) = gradient {
            self.reduce(workspace, gradient, sign);
        }
        if workspace.cached_q.len() != q.len() {
            workspace.cached_q = vec![f64::NAN; q.len()];
        }
        workspace.cached_q.copy_from_slice(q);
        workspace.cached = with_energy.then_some(energies);
        workspace.reusable = true;
        workspace.energy_used = false;
        energies
    }

    /// The kernel over every chunk; the chunks' energies summed in chunk order.
    fn run_chunks<R: Real>(&self, workspace: &mut Workspace, energy: bool) -> (f64, f64)
    where
        Workspace: Inputs<R>,
    {
        let isa = workspace.isa;
        let inverse_cutoff6 = self.factored.as_ref().map_or(0.0, |f| f.inverse_cutoff6);
        let (inputs, chunks, buffers, energies) = Inputs::<R>::split(workspace, inverse_cutoff6);
        let n = inputs.clusters.len();
        let work = |((chunk, buffer), result): ((&Chunk, &mut Vec<Gradient4>), &mut (f64, f64))| {
            for range in window_ranges(chunk.window, n) {
                buffer[range].fill(Gradient4::default());
            }
            let job = Job {
                list: &chunk.inner,
                ..inputs
            };
            let mut out = Out {
                gradient: buffer,
                lj: [0.0; 4],
                coulomb: [0.0; 4],
            };
            if energy {
                self.dispatch::<R, true>(isa, &job, &mut out);
            } else {
                self.dispatch::<R, false>(isa, &job, &mut out);
            }
            let total = |e: [f64; 4]| (e[0] + e[2]) + (e[1] + e[3]);
            *result = (total(out.lj), total(out.coulomb));
        };
        if self.n >= PARALLEL_MIN_ATOMS && chunks.len() > 1 {
            chunks
                .par_iter()
                .zip(buffers.par_iter_mut())
                .zip(energies.par_iter_mut())
                .for_each(work);
        } else {
            chunks
                .iter()
                .zip(buffers.iter_mut())
                .zip(energies.iter_mut())
                .for_each(work);
        }
        energies
            .iter()
            .fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1))
    }

    /// The kernel with this term's Coulomb form.
    fn dispatch<R: Real, const ENERGY: bool>(&self, isa: Isa, job: &Job<R>, out: &mut Out) {
        if self.electrostatics == Electrostatics::None {
            return self.with_switch::<R, _, ENERGY>(isa, job, kernel::NoCoulomb, out);
        }
        match self.kernel {
            Kernel::Plain(c) => self.with_switch::<R, _, ENERGY>(isa, job, c, out),
            Kernel::ShiftedForce(c) => self.with_switch::<R, _, ENERGY>(isa, job, c, out),
            Kernel::Damped(c) => self.with_switch::<R, _, ENERGY>(isa, job, c, out),
            Kernel::ReactionField(c) => self.with_switch::<R, _, ENERGY>(isa, job, c, out),
            Kernel::Ewald(c) => {
                use kernel::{Ewald, ewald_route as route};
                match c.route::<R>() {
                    route::SCALAR => self.with_switch::<R, _, ENERGY>(
                        isa,
                        job,
                        Ewald::<{ route::SCALAR }>(c),
                        out,
                    ),
                    route::RATIONAL => self.with_switch::<R, _, ENERGY>(
                        isa,
                        job,
                        Ewald::<{ route::RATIONAL }>(c),
                        out,
                    ),
                    _ => {
                        self.with_switch::<R, _, ENERGY>(isa, job, Ewald::<{ route::ERFC }>(c), out)
                    }
                }
            }
        }
    }

    /// The kernel with Coulomb form `c`, multiplied by the switch of a short-range part.
    fn with_switch<R: Real, C: kernel::Coulomb, const ENERGY: bool>(
        &self,
        isa: Isa,
        job: &Job<R>,
        c: C,
        out: &mut Out,
    ) {
        match self.switch {
            None => kernel::evaluate::<R, C, ENERGY>(isa, job, c, out),
            Some(switch) => {
                let switched = kernel::Switched {
                    inner: c,
                    r_in: switch.r_in(),
                    inverse_width: switch.inverse_width(),
                };
                kernel::evaluate::<R, _, ENERGY>(isa, job, switched, out)
            }
        }
    }

    /// `gradient += Σ_c buffer_c`, chunk by chunk in order over each chunk's window
    /// (deterministic), in parallel over blocks of clusters for large systems; then from
    /// cluster slots to atoms.
    fn reduce(&self, workspace: &mut Workspace, gradient: &mut [f64], sign: f64) {
        let Workspace {
            list,
            buffers,
            reduced,
            ..
        } = workspace;
        let n = list.clusters();
        let chunks = &list.chunks;
        const BLOCK: usize = 256;
        let add = |(block, out): (usize, &mut [Gradient4])| {
            let first = block * BLOCK;
            out.fill(Gradient4::default());
            for (chunk, buffer) in chunks.iter().zip(buffers.iter()) {
                for range in window_ranges(chunk.window, n) {
                    let from = range.start.max(first);
                    let to = range.end.min(first + out.len());
                    for k in from..to.max(from) {
                        let (o, b) = (&mut out[k - first], &buffer[k]);
                        for l in 0..4 {
                            o.x[l] += b.x[l];
                            o.y[l] += b.y[l];
                            o.z[l] += b.z[l];
                        }
                    }
                }
            }
        };
        let reduced = &mut reduced[..n];
        if self.n >= PARALLEL_PASSES_MIN_ATOMS {
            reduced.par_chunks_mut(BLOCK).enumerate().for_each(add);
        } else {
            reduced.chunks_mut(BLOCK).enumerate().for_each(add);
        }
        // Each atom has one slot: one addition per atom, in any order the same bits.
        let slot_of = &list.grid.slot_of;
        let gradient = &mut gradient[..3 * slot_of.len()];
        let scatter = |(block, out): (usize, &mut [f64])| {
            for (k, g) in out.chunks_exact_mut(3).enumerate() {
                let slot = slot_of[block * BLOCK + k] as usize;
                let c = &reduced[slot / CLUSTER];
                let l = slot % CLUSTER;
                g[0] += sign * c.x[l];
                g[1] += sign * c.y[l];
                g[2] += sign * c.z[l];
            }
        };
        if self.n >= PARALLEL_PASSES_MIN_ATOMS {
            gradient
                .par_chunks_mut(3 * BLOCK)
                .enumerate()
                .for_each(scatter);
        } else {
            gradient.chunks_mut(3 * BLOCK).enumerate().for_each(scatter);
        }
    }

    /// `out += ∇²V v` over the pruned list (pairs within the cutoff): for a radial `V`,
    /// `(∇²V v)_j = a Δv + b (d·Δv) d` with `a = V′/r`, `b = (V″ − V′/r)/r²`.
    pub(super) fn hessian_vector(&self, q: &[f64], v: &[f64], out: &mut [f64], sign: f64) {
        let mut guard = self.lock();
        self.refresh(&mut guard, q);
        let list = &guard.list;
        let cutoff2 = self.cutoff * self.cutoff;
        list.for_each_pair(false, |i, j, d| {
            let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            if r2 >= cutoff2 {
                return;
            }
            let r = r2.sqrt();
            let (d1, d2) = self.pair_derivatives(i, j, r);
            let a = sign * d1 / r;
            let b = (sign * d2 - a) / r2;
            let dv: [f64; 3] = std::array::from_fn(|k| v[3 * j + k] - v[3 * i + k]);
            let along = b * (d[0] * dv[0] + d[1] * dv[1] + d[2] * dv[2]);
            for k in 0..3 {
                let h = a * dv[k] + along * d[k];
                out[3 * j + k] += h;
                out[3 * i + k] -= h;
            }
        });
    }

    /// Every atom pair of the outer list, `[min, max]`, sorted, once each.
    pub(super) fn coupled_pairs(&self) -> Vec<[usize; 2]> {
        let guard = self.lock();
        let mut pairs = Vec::new();
        guard
            .list
            .for_each_pair(true, |i, j, _| pairs.push([i.min(j), i.max(j)]));
        pairs.sort_unstable();
        pairs.dedup();
        pairs
    }
}

/// The kernel's inputs in precision `R` and the mutable parts, borrowed apart.
pub trait Inputs<R: Real> {
    #[allow(clippy::type_complexity)]
    fn split(
        &mut self,
        inverse_cutoff6: f64,
    ) -> (
        Job<'_, R>,
        &[Chunk],
        &mut [Vec<Gradient4>],
        &mut [(f64, f64)],
    );
}

/// A type-table term's Lennard-Jones tables: the pair table, the rows by j-cluster and
/// i-type (`table_by_type`), and which types have Lennard-Jones at all.
type LjTables<'a, R> = (&'a [[R; 3]], &'a [[[R; 4]; 2]], &'a [u8]);

/// The Lennard-Jones data: per-slot factors when the term has them, else types and table.
fn lj_data<'a, R>(
    factors: &'a [[R; 8]],
    types: &'a [[u32; 4]],
    (table, by_type, lj_rows): LjTables<'a, R>,
) -> LjData<'a, R> {
    if factors.is_empty() {
        LjData::Table {
            types,
            table,
            by_type,
            lj_rows,
            n_types: (table.len() as f64).sqrt().round() as usize,
        }
    } else {
        LjData::Geometric(factors)
    }
}

/// A job over `list`'s geometry with j-clusters `clusters` (its list set per chunk).
fn job<'a, R>(
    list: &'a ClusterList,
    clusters: &'a [Cluster<R>],
    lj: LjData<'a, R>,
    inverse_cutoff6: f64,
) -> Job<'a, R> {
    Job {
        list: &list.chunks[0].inner,
        clusters,
        clusters64: &list.positions,
        shifts: &list.geometry.shifts,
        cutoff2: list.cutoff() * list.cutoff(),
        inverse_cutoff6,
        lj,
        every_group: false,
    }
}

impl Inputs<f64> for Workspace {
    fn split(
        &mut self,
        inverse_cutoff6: f64,
    ) -> (
        Job<'_, f64>,
        &[Chunk],
        &mut [Vec<Gradient4>],
        &mut [(f64, f64)],
    ) {
        let lj = lj_data(
            &self.factors64,
            &self.types,
            (&self.table64, &self.by_type64, &self.lj_rows),
        );
        let job = Job {
            every_group: self.every_group,
            ..job(&self.list, &self.list.positions, lj, inverse_cutoff6)
        };
        (
            job,
            &self.list.chunks,
            &mut self.buffers,
            &mut self.energies,
        )
    }
}

impl Inputs<f32> for Workspace {
    fn split(
        &mut self,
        inverse_cutoff6: f64,
    ) -> (
        Job<'_, f32>,
        &[Chunk],
        &mut [Vec<Gradient4>],
        &mut [(f64, f64)],
    ) {
        let lj = lj_data(
            &self.factors32,
            &self.types,
            (&self.table32, &self.by_type32, &self.lj_rows),
        );
        let job = Job {
            every_group: self.every_group,
            ..job(&self.list, &self.clusters32, lj, inverse_cutoff6)
        };
        (
            job,
            &self.list.chunks,
            &mut self.buffers,
            &mut self.energies,
        )
    }
}
