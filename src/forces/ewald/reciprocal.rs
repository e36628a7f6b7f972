//! The smooth-PME reciprocal term `"pme-reciprocal"` (EPBDLP95) with the Ewald corrections
//! that move with it: the excluded pairs `−Q_ij erf(αr)/r`, the self energy and the
//! neutralising background (formulas in [`super`]). Each is its own energy component
//! (`pme-reciprocal`, `ewald-exclusions`, `ewald-self`, `ewald-background`). The
//! exclusion correction stays with the mesh term, as in OpenMM's reciprocal force group:
//! on excluded pairs the two nearly cancel, so splitting them across levels would give
//! large opposite impulses.
//!
//! **Mesh.** Charges are spread with B-splines of order `n` (`Q(k) = Σ_i q_i Π_a
//! M_n(u_ia − k_a)`, EPBDLP95 eq. (4.6)); with `F` the 3-D FFT and the influence function
//! `θ(m) = k_e exp(−π²m²/α²)/(πV m² B(m))`, `B(m) = Π_a 1/|b_a(m_a)|²` (eq. (4.7), (4.8)),
//! `E = ½ Σ_{m≠0} θ(m) |F(Q)(m)|²`. Its derivative on the grid is the potential
//! `φ = F⁻¹(θ F(Q))` (unnormalised inverse), and `∂E/∂r_i = q_i Σ_k φ(k) ∇_i W_i(k)` with
//! `W_i(k) = Π_a M_n(u_ia − k_a)`, `∂u_a/∂x_a = K_a/L_a` (eq. (4.9)).
//!
//! **Hessian-vector product.** `E = ½ QᵀΘQ` with `Q` a function of the positions, so
//! `∇²E v = Jᵀ Θ (J v) + Σ_k φ(k) ∇²Q(k) v` with `J = ∂Q/∂r`. `J v` spreads the
//! displacement-weighted spline derivatives `Σ_i q_i v_i·∇W_i`; `Θ` is one more
//! convolution (FFT, `θ`, inverse); `Jᵀ` gathers with the first derivatives as the
//! gradient does; the second sum gathers `φ` with the splines' second derivatives
//! (`q_i Σ_k φ(k) ∂_a∂_b W_i(k) v_ib`). Two passes of the pipeline.
//!
//! **Cost.** Per gradient: `N n³` spreading and gathering (along z in `n` lanes, the
//! stencil's run of a grid row, compiled for the processor's instruction set with plain
//! arithmetic: the same bits on every set), two 3-D FFTs of `K_x K_y K_z`
//! points (`O(K³ log K)`), `O(K³)` for the influence function; per Hessian-vector product
//! twice that. The exclusions are `O(N_excl)`. For large systems every part of the mesh
//! runs over rayon with the same bits at any thread count: the per-atom splines and the
//! gathering per atom (each atom's result is its own); spreading by slabs of grid planes
//! that each take their part of every atom in atom order (the same additions in the same
//! order as the serial pass); the FFT as independent line transforms with the energy summed
//! per line block in a fixed order ([`super::fft`]). The workspace is sized at
//! construction (and again when the precision changes): an evaluation allocates nothing.
//!
//! **Precision.** In [`Precision::Mixed`] the mesh computes in `f32` as GROMACS's mixed
//! build does: B-spline weights, spreading, the real-to-complex FFT, the influence-function
//! multiply and the gathering; positions are reduced to grid coordinates in `f64`, each
//! atom's gathered sums are widened to `f64` before they meet its charge and the gradient,
//! and the energy's sums over the spectrum are in `f64`. One generic body
//! ([`MeshFloat`]) serves both precisions; the excluded pairs and the self and background
//! terms stay in `f64`.

use std::sync::Mutex;

use rayon::prelude::*;

use super::exclusions::Exclusions;
use super::fft::{Fft3, FftScratch, Output};
use super::float::MeshFloat;
use super::spline::{self, MAX_ORDER, Weights};
use super::{EwaldParameters, background_energy, self_energy};
use crate::forces::scratch::parallel;
use crate::forces::simd::Isa;
use crate::forces::{ForceTerm, Precision, TermClass};

/// Atoms per batch of spline weights ([`PmeReciprocal::place`]).
const PLACE_BATCH: usize = 16;

/// Atoms per task of the force gathering ([`PmeReciprocal::gather_forces`]).
const GATHER_BATCH: usize = 64;

/// Parallel spreading tasks per thread (slabs of x-planes).
const SLABS_PER_THREAD: usize = 2;

/// One atom's splines on the three axes: grid indices and weights.
#[derive(Clone, Copy, Debug, Default)]
struct Stencil<T> {
    index: [[u32; MAX_ORDER]; 3],
    weights: [Weights<T>; 3],
}

/// The mesh in one float type: the FFT plans, `θ(m)` over the half spectrum (zero at
/// `m = 0`) and the buffers an evaluation works in.
struct Mesh<T> {
    fft: Fft3<T>,
    influence: Vec<T>,
    stencils: Vec<Stencil<T>>,
    grid: Vec<T>,
    /// `φ`, the derivative of the energy on the grid.
    potential: Vec<T>,
    scratch: FftScratch<T>,
}

impl<T: MeshFloat> Mesh<T> {
    fn new(params: &EwaldParameters, lengths: [f64; 3], ke: f64, atoms: usize) -> Self {
        let fft = Fft3::new(params.grid);
        Mesh {
            influence: influence(params, lengths, ke, &fft),
            stencils: vec![Stencil::default(); atoms],
            grid: vec![T::zero(); fft.real_len()],
            potential: vec![T::zero(); fft.real_len()],
            scratch: fft.scratch(),
            fft,
        }
    }
}

/// The mesh of the term's current precision.
enum Workspace {
    Double(Mesh<f64>),
    Mixed(Mesh<f32>),
}

/// Run `$body` with `$mesh` bound to the workspace's mesh, of either float type.
macro_rules! with_mesh {
    ($workspace:expr, $mesh:ident => $body:expr) => {
        match $workspace {
            Workspace::Double($mesh) => $body,
            Workspace::Mixed($mesh) => $body,
        }
    };
}

pub struct PmeReciprocal {
    params: EwaldParameters,
    lengths: [f64; 3],
    coulomb_constant: f64,
    charges: Vec<f64>,
    excluded: Vec<(u32, u32)>,
    /// The excluded pairs' correction `−Q_ij erf(αr)/r`.
    exclusions: Exclusions,
    self_energy: f64,
    background: f64,
    workspace: Mutex<Workspace>,
    /// The instruction set the splines, spreading and gathering are compiled for.
    isa: Isa,
}

impl PmeReciprocal {
    /// The term for `charges` in a box of `lengths`, `k_e = coulomb_constant`, leaving out
    /// of the Ewald sum (by the erf correction) the `excluded` pairs.
    pub fn new(
        params: EwaldParameters,
        lengths: [f64; 3],
        coulomb_constant: f64,
        charges: Vec<f64>,
        excluded: &[(usize, usize)],
    ) -> Result<Self, String> {
        let n = charges.len();
        if let Some(&(i, j)) = excluded.iter().find(|&&(i, j)| i >= n || j >= n) {
            return Err(format!("excluded pair ({i}, {j}) names a missing particle"));
        }
        if !super::ORDERS.contains(&params.order) {
            return Err(format!("pme_order must be 4, 5 or 6, got {}", params.order));
        }
        let mut pairs: Vec<(u32, u32)> = excluded
            .iter()
            .filter(|(i, j)| i != j)
            .map(|&(i, j)| (i.min(j) as u32, i.max(j) as u32))
            .collect();
        pairs.sort_unstable();
        pairs.dedup();
        let volume: f64 = lengths.iter().product();
        let exclusions = Exclusions::new(params.alpha, lengths, coulomb_constant, &charges, &pairs);
        let workspace = Workspace::Double(Mesh::new(&params, lengths, coulomb_constant, n));
        Ok(PmeReciprocal {
            self_energy: self_energy(params.alpha, coulomb_constant, &charges),
            background: background_energy(params.alpha, coulomb_constant, &charges, volume),
            params,
            lengths,
            coulomb_constant,
            charges,
            exclusions,
            excluded: pairs,
            workspace: Mutex::new(workspace),
            isa: Isa::best(),
        })
    }

    pub fn parameters(&self) -> EwaldParameters {
        self.params
    }

    /// The charges `q_i`.
    pub fn charges(&self) -> &[f64] {
        &self.charges
    }

    /// The net charge `Σ q_i`.
    pub fn net_charge(&self) -> f64 {
        self.charges.iter().sum()
    }

    /// The precision the mesh computes in.
    pub fn precision(&self) -> Precision {
        match *self.lock() {
            Workspace::Double(_) => Precision::Double,
            Workspace::Mixed(_) => Precision::Mixed,
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Workspace> {
        // A panic elsewhere while the lock was held leaves buffers that are overwritten.
        self.workspace.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// `K_a / L_a`.
    fn scale(&self) -> [f64; 3] {
        std::array::from_fn(|a| self.params.grid[a] as f64 / self.lengths[a])
    }

    /// Whether this evaluation runs over rayon.
    fn parallel(&self) -> bool {
        parallel(self.charges.len())
    }

    /// Every atom's stencil at `q` (with the splines' second derivatives for `second`).
    #[inline(never)]
    fn place<T: MeshFloat>(&self, q: &[f64], stencils: &mut [Stencil<T>], second: bool) {
        match self.params.order {
            4 => self.place_order::<T, 4>(q, stencils, second),
            5 => self.place_order::<T, 5>(q, stencils, second),
            _ => self.place_order::<T, 6>(q, stencils, second),
        }
    }

    /// [`Self::place`] for B-splines of order `N` (the spline recursion unrolled), in
    /// batches of [`PLACE_BATCH`] atoms compiled for the processor's instruction set
    /// ([`Isa::run`]): each batch's weights are computed side by side, one lane per atom,
    /// in plain arithmetic (no fused operations), so the same bits on every set.
    fn place_order<T: MeshFloat, const N: usize>(
        &self,
        q: &[f64],
        stencils: &mut [Stencil<T>],
        second: bool,
    ) {
        let isa = self.isa;
        let batch = |(b, stencils): (usize, &mut [Stencil<T>])| {
            isa.run(
                #[inline(always)]
                || self.place_batch::<T, N>(q, b * PLACE_BATCH, stencils, second),
            )
        };
        if self.parallel() {
            stencils
                .par_chunks_mut(PLACE_BATCH)
                .enumerate()
                .for_each(batch);
        } else {
            stencils.chunks_mut(PLACE_BATCH).enumerate().for_each(batch);
        }
    }

    /// The stencils of atoms `first …` (at most [`PLACE_BATCH`]): per axis the grid
    /// offsets and indices atom by atom, then the weights of all of them.
    #[inline(always)]
    fn place_batch<T: MeshFloat, const N: usize>(
        &self,
        q: &[f64],
        first: usize,
        stencils: &mut [Stencil<T>],
        second: bool,
    ) {
        let weights = &mut spline::WeightsBatch::<T, PLACE_BATCH>::new();
        for a in 0..3 {
            let size = self.params.grid[a];
            let (length, top) = (self.lengths[a], (size - 1) as f64);
            // Lane by lane: u = K (s − ⌊s⌋) ≥ 0 and its grid point ⌊u⌋, at most K − 1 (u
            // may round up to K for s just below 1); `floor` is exact, so these are the
            // values of any other exact floor.
            let mut bases = [0.0; PLACE_BATCH];
            let mut offsets = [T::zero(); PLACE_BATCH];
            for b in 0..stencils.len() {
                let s = q[3 * (first + b) + a] / length;
                let u = (s - s.floor()) * size as f64;
                bases[b] = u.floor().min(top);
                offsets[b] = T::of(u - bases[b]);
            }
            for (stencil, &base) in stencils.iter_mut().zip(&bases) {
                // (base − k) mod K with base < K and k < N ≤ K: one wrap at most.
                let base = base as usize;
                for k in 0..N {
                    let index = base + size - k;
                    stencil.index[a][k] = (if index >= size { index - size } else { index }) as u32;
                }
            }
            spline::weights_batch::<T, N, PLACE_BATCH>(&offsets, second, weights);
            for (b, stencil) in stencils.iter_mut().enumerate() {
                let to = &mut stencil.weights[a];
                for k in 0..N {
                    to.value[k] = weights.value[k][b];
                    to.first[k] = weights.first[k][b];
                    if second {
                        to.second[k] = weights.second[k][b];
                    }
                }
            }
        }
    }

    /// `grid = Σ_i c_i(k) ...`: the charges (`v = None`) or, with `v`, the
    /// displacement-weighted derivatives `Σ_i q_i v_i·∇W_i` spread on the grid. For large
    /// systems in parallel over slabs of x-planes ([`SLABS_PER_THREAD`] per thread), each
    /// slab taking its part of every atom's stencil in atom order: each grid point gains the
    /// same terms in the same order as in the serial pass (an atom touches a point once, as
    /// `K ≥ 2n`), so the same bits at any thread count and any slab size.
    #[inline(never)]
    fn spread<T: MeshFloat>(&self, stencils: &[Stencil<T>], v: Option<&[f64]>, grid: &mut [T]) {
        let [nx, ny, nz] = self.params.grid;
        let slabs = SLABS_PER_THREAD * rayon::current_num_threads();
        let slab = nx.div_ceil(slabs);
        if self.parallel() && slab < nx {
            grid.par_chunks_mut(slab * ny * nz)
                .enumerate()
                .for_each(|(index, planes)| {
                    let first = index * slab;
                    self.spread_planes(stencils, v, planes, first..(first + slab).min(nx));
                });
        } else {
            self.spread_planes(stencils, v, grid, 0..nx);
        }
    }

    /// [`Self::spread`] into the x-planes `planes` only, held by `grid` (from plane
    /// `planes.start`).
    fn spread_planes<T: MeshFloat>(
        &self,
        stencils: &[Stencil<T>],
        v: Option<&[f64]>,
        grid: &mut [T],
        planes: std::ops::Range<usize>,
    ) {
        grid.fill(T::zero());
        let Some(v) = v else {
            match self.params.order {
                4 => self.spread_charges::<T, 4>(stencils, grid, &planes),
                5 => self.spread_charges::<T, 5>(stencils, grid, &planes),
                _ => self.spread_charges::<T, 6>(stencils, grid, &planes),
            }
            return;
        };
        let [_, ny, nz] = self.params.grid;
        let order = self.params.order;
        let scale = self.scale();
        for (i, st) in stencils.iter().enumerate() {
            if self.charges[i] == 0.0 {
                continue;
            }
            let q = T::of(self.charges[i]);
            let [wx, wy, wz] = &st.weights;
            let d: [T; 3] = std::array::from_fn(|a| T::of(scale[a] * v[3 * i + a]));
            let iz = &st.index[2][..order];
            for kx in 0..order {
                let x = st.index[0][kx] as usize;
                if !planes.contains(&x) {
                    continue;
                }
                let gx = (x - planes.start) * ny;
                for ky in 0..order {
                    let row = &mut grid[(gx + st.index[1][ky] as usize) * nz..][..nz];
                    let (vx, vy) = (wx.value[kx], wy.value[ky]);
                    // q (d_x M′_x M_y + d_y M_x M′_y) M_z + q d_z M_x M_y M′_z.
                    let (fx, fy) = (wx.first[kx], wy.first[ky]);
                    let a = q * (d[0] * fx * vy + d[1] * vx * fy);
                    let b = q * d[2] * vx * vy;
                    for k in 0..order {
                        row[iz[k] as usize] += a * wz.value[k] + b * wz.first[k];
                    }
                }
            }
        }
    }

    /// The charges of every atom, in atom order, onto the planes `planes` of `grid`
    /// ([`spread_charge`]), compiled for the processor's instruction set ([`Isa::run`]; plain
    /// arithmetic, so the same bits on every set).
    fn spread_charges<T: MeshFloat, const N: usize>(
        &self,
        stencils: &[Stencil<T>],
        grid: &mut [T],
        planes: &std::ops::Range<usize>,
    ) {
        let [_, ny, nz] = self.params.grid;
        self.isa.run(
            #[inline(always)]
            || {
                for (st, &q) in stencils.iter().zip(&self.charges) {
                    if q != 0.0 {
                        spread_charge::<T, N>(T::of(q), st, grid, planes, ny, nz);
                    }
                }
            },
        )
    }

    /// The mesh energy of the grid in `ws.grid` and, for [`Output::Potential`], `θ * grid`
    /// into the potential (`out_is_potential`) or back into the grid (the grid is consumed).
    fn convolve<T: MeshFloat>(
        &self,
        ws: &mut Mesh<T>,
        output: Output,
        out_is_potential: bool,
    ) -> f64 {
        let Mesh {
            fft,
            influence,
            grid,
            potential,
            scratch,
            ..
        } = ws;
        let out = if out_is_potential {
            Some(&mut potential[..])
        } else {
            None
        };
        // The full-spectrum sum is Σ_m θ|F|², the energy half of it.
        let sum = fft.convolve(grid, influence, output, out, scratch, self.parallel());
        0.5 * sum
    }

    /// The mesh energy at `q`.
    fn mesh_energy(&self, q: &[f64]) -> f64 {
        with_mesh!(&mut *self.lock(), ws => {
            self.place(q, &mut ws.stencils, false);
            self.spread(&ws.stencils, None, &mut ws.grid);
            self.convolve(ws, Output::Energy, false)
        })
    }

    /// `φ` at `q` into `ws.potential` (stencils placed, with second derivatives for
    /// `second`).
    fn potential<T: MeshFloat>(&self, q: &[f64], ws: &mut Mesh<T>, second: bool) {
        self.place(q, &mut ws.stencils, second);
        self.spread(&ws.stencils, None, &mut ws.grid);
        self.convolve(ws, Output::Potential, true);
    }

    /// Per atom `i`: `out_i += q_i Σ_k g(k) ∇_i W_i(k)` and, with `v`, `+ q_i Σ_k h(k)
    /// ∇_i∇_iᵀ W_i(k) v_i` (`h` is the second grid). The sums over the stencil in `T`,
    /// widened to `f64` before the charge and the scale multiply them.
    #[inline(never)]
    fn gather<T: MeshFloat>(
        &self,
        stencils: &[Stencil<T>],
        g: &[T],
        hv: Option<(&[T], &[f64])>,
        out: &mut [f64],
    ) {
        let Some((h, v)) = hv else {
            match self.params.order {
                4 => self.gather_forces::<T, 4>(stencils, g, out),
                5 => self.gather_forces::<T, 5>(stencils, g, out),
                _ => self.gather_forces::<T, 6>(stencils, g, out),
            }
            return;
        };
        let scale = self.scale();
        let one = |i: usize, out: &mut [f64]| {
            let q = self.charges[i];
            if q == 0.0 {
                return;
            }
            let (first, second) = self.gather_one(&stencils[i], g, h);
            for a in 0..3 {
                let mut value = scale[a] * first[a].wide();
                for b in 0..3 {
                    value += scale[a] * scale[b] * second[a][b].wide() * v[3 * i + b];
                }
                out[a] += q * value;
            }
        };
        if self.parallel() {
            out.par_chunks_mut(3)
                .enumerate()
                .for_each(|(i, out)| one(i, out));
        } else {
            for (i, out) in out.chunks_mut(3).enumerate() {
                one(i, out);
            }
        }
    }

    /// The gradient part of [`Self::gather`]: per atom `out_i += q_i K_a/L_a Σ_k g(k) ∂_a
    /// W_i(k)` ([`gather_first`], widened to `f64` once per atom), in batches of
    /// [`GATHER_BATCH`] atoms compiled for the processor's instruction set (plain
    /// arithmetic: the same bits on every set); each atom's result is its own, so the same
    /// bits at any thread count.
    fn gather_forces<T: MeshFloat, const N: usize>(
        &self,
        stencils: &[Stencil<T>],
        g: &[T],
        out: &mut [f64],
    ) {
        let scale = self.scale();
        let [_, ny, nz] = self.params.grid;
        let isa = self.isa;
        let batch = |(b, out): (usize, &mut [f64])| {
            isa.run(
                #[inline(always)]
                || {
                    let first = b * GATHER_BATCH;
                    for (k, out) in out.chunks_exact_mut(3).enumerate() {
                        let q = self.charges[first + k];
                        if q == 0.0 {
                            continue;
                        }
                        let sums = gather_first::<T, N>(&stencils[first + k], g, ny, nz);
                        for a in 0..3 {
                            out[a] += q * (scale[a] * sums[a].wide());
                        }
                    }
                },
            )
        };
        if self.parallel() {
            out.par_chunks_mut(3 * GATHER_BATCH)
                .enumerate()
                .for_each(batch);
        } else {
            out.chunks_mut(3 * GATHER_BATCH).enumerate().for_each(batch);
        }
    }

    /// `Σ_k g(k) ∂_a W(k)` (in `u`) and `Σ_k h(k) ∂_a∂_b W(k)`.
    fn gather_one<T: MeshFloat>(&self, st: &Stencil<T>, g: &[T], h: &[T]) -> ([T; 3], [[T; 3]; 3]) {
        let [_, ny, nz] = self.params.grid;
        let order = self.params.order;
        let [wx, wy, wz] = &st.weights;
        let mut first = [T::zero(); 3];
        let mut second = [[T::zero(); 3]; 3];
        for kx in 0..order {
            let gx = st.index[0][kx] as usize * ny;
            for ky in 0..order {
                let row = (gx + st.index[1][ky] as usize) * nz;
                for kz in 0..order {
                    let at = row + st.index[2][kz] as usize;
                    let (x, y, z) = (wx.value[kx], wy.value[ky], wz.value[kz]);
                    let (dx, dy, dz) = (wx.first[kx], wy.first[ky], wz.first[kz]);
                    let p = g[at];
                    first[0] += p * dx * y * z;
                    first[1] += p * x * dy * z;
                    first[2] += p * x * y * dz;
                    {
                        let p = h[at];
                        let (sx, sy, sz) = (wx.second[kx], wy.second[ky], wz.second[kz]);
                        second[0][0] += p * sx * y * z;
                        second[1][1] += p * x * sy * z;
                        second[2][2] += p * x * y * sz;
                        second[0][1] += p * dx * dy * z;
                        second[0][2] += p * dx * y * dz;
                        second[1][2] += p * x * dy * dz;
                    }
                }
            }
        }
        second[1][0] = second[0][1];
        second[2][0] = second[0][2];
        second[2][1] = second[1][2];
        (first, second)
    }
}

/// `θ(m) = k_e exp(−π²m²/α²)/(πV m² B(m))` over the half spectrum (in the FFT's layout), with
/// `m_a = k_a` for `k_a < (K_a + 1)/2`, else `k_a − K_a`, and `m² = Σ (m_a/L_a)²`; zero at
/// `m = 0` (the background term stands for it). Computed in `f64`, stored in `T`.
fn influence<T: MeshFloat>(
    params: &EwaldParameters,
    lengths: [f64; 3],
    ke: f64,
    fft: &Fft3<T>,
) -> Vec<T> {
    let [nx, ny, nz] = params.grid;
    let half = fft.half;
    let moduli: [Vec<f64>; 3] =
        std::array::from_fn(|a| spline::moduli(params.order, params.grid[a]));
    let volume: f64 = lengths.iter().product();
    let pi = std::f64::consts::PI;
    let factor = pi * pi / (params.alpha * params.alpha);
    let signed = |k: usize, size: usize| -> f64 {
        if k < size.div_ceil(2) {
            k as f64
        } else {
            k as f64 - size as f64
        }
    };
    let mut out = vec![T::zero(); nx * ny * half];
    for kx in 0..nx {
        let mx = signed(kx, nx) / lengths[0];
        for ky in 0..ny {
            let my = signed(ky, ny) / lengths[1];
            for kz in 0..half {
                if kx == 0 && ky == 0 && kz == 0 {
                    continue;
                }
                let mz = signed(kz, nz) / lengths[2];
                let m2 = mx * mx + my * my + mz * mz;
                let denominator = pi * volume * m2 * moduli[0][kx] * moduli[1][ky] * moduli[2][kz];
                out[fft.spectrum_index(kx, ky, kz)] =
                    T::of(ke * (-factor * m2).exp() / denominator);
            }
        }
    }
    out
}

impl ForceTerm for PmeReciprocal {
    fn kind(&self) -> &'static str {
        "pme-reciprocal"
    }

    /// The Ewald sum is translation invariant; the B-spline interpolation is not quite
    /// (a net force of ~1e-3 of the forces), which the momentum test must not read as an
    /// external field.
    fn invariant_by_construction(&self) -> bool {
        true
    }

    fn class(&self) -> TermClass {
        TermClass::Nonbonded
    }

    fn energy(&self, q: &[f64]) -> f64 {
        self.mesh_energy(q) + self.exclusions.energy(q) + self.self_energy + self.background
    }

    fn add_gradient(&self, q: &[f64], gradient: &mut [f64]) {
        with_mesh!(&mut *self.lock(), ws => {
            self.potential(q, ws, false);
            self.gather(&ws.stencils, &ws.potential, None, gradient);
        });
        self.exclusions.add_gradient(q, gradient);
    }

    fn add_hessian_vector(&self, q: &[f64], v: &[f64], out: &mut [f64]) {
        with_mesh!(&mut *self.lock(), ws => {
            self.potential(q, ws, true);
            self.spread(&ws.stencils, Some(v), &mut ws.grid);
            // ψ = Θ (J v) into the grid itself.
            self.convolve(ws, Output::Potential, false);
            let Mesh {
                stencils,
                grid,
                potential,
                ..
            } = ws;
            self.gather(stencils, grid, Some((potential, v)), out);
        });
        self.exclusions.add_hessian_vector(q, v, out);
    }

    /// Every charged particle with every other: one interaction of all of them.
    fn couplings(&self) -> Vec<Vec<usize>> {
        let charged: Vec<usize> = (0..self.charges.len())
            .filter(|&i| self.charges[i] != 0.0)
            .collect();
        let mut out = vec![charged];
        out.extend(
            self.excluded
                .iter()
                .map(|&(i, j)| vec![i as usize, j as usize]),
        );
        out
    }

    fn interaction_count(&self) -> usize {
        self.charges.len() + self.excluded.len()
    }

    fn energy_components(&self, q: &[f64]) -> Vec<(&'static str, f64)> {
        vec![
            ("pme-reciprocal", self.mesh_energy(q)),
            ("ewald-exclusions", self.exclusions.energy(q)),
            ("ewald-self", self.self_energy),
            ("ewald-background", self.background),
        ]
    }

    /// Mixed: the mesh in `f32` (the module's doc); the mesh is rebuilt in the new float
    /// type when the precision changes.
    fn set_precision(&self, precision: Precision) -> bool {
        if self.precision() != precision {
            let n = self.charges.len();
            let (p, l, ke) = (&self.params, self.lengths, self.coulomb_constant);
            *self.lock() = match precision {
                Precision::Double => Workspace::Double(Mesh::new(p, l, ke, n)),
                Precision::Mixed => Workspace::Mixed(Mesh::new(p, l, ke, n)),
            };
        }
        true
    }

    fn as_any(&self) -> Option<&dyn std::any::Any> {
        Some(self)
    }
}

/// The first grid index of an atom's `N` z-points in ascending order (`index[2]` holds
/// them descending) when they form one run `start … start + N − 1` inside the row, `None`
/// when the stencil wraps the grid's edge (`N − 1` positions in `K_z`).
#[inline(always)]
fn z_run<T, const N: usize>(st: &Stencil<T>, nz: usize) -> Option<usize> {
    let start = st.index[2][N - 1] as usize;
    (start + N <= nz).then_some(start)
}

/// The charge of one atom onto the planes `planes` of `grid` (from plane `planes.start`),
/// for B-splines of order `N`: `Q(k) += q M_x M_y M_z`, each point gaining the product
/// `((q M_x) M_y) M_z` in this order. Along z the `N` points are one run of the row, added
/// as `N` lanes (an atom touches a point once, so the order of its points is free: the
/// bits are those of a point-by-point pass); a wrapped stencil goes point by point.
#[inline(always)]
fn spread_charge<T: MeshFloat, const N: usize>(
    q: T,
    st: &Stencil<T>,
    grid: &mut [T],
    planes: &std::ops::Range<usize>,
    ny: usize,
    nz: usize,
) {
    let [wx, wy, wz] = &st.weights;
    let run = z_run::<T, N>(st, nz);
    let ascending: [T; N] = std::array::from_fn(|j| wz.value[N - 1 - j]);
    for kx in 0..N {
        let x = st.index[0][kx] as usize;
        if !planes.contains(&x) {
            continue;
        }
        let gx = (x - planes.start) * ny;
        let qx = q * wx.value[kx];
        for ky in 0..N {
            let row = &mut grid[(gx + st.index[1][ky] as usize) * nz..][..nz];
            let qxy = qx * wy.value[ky];
            match run {
                Some(start) => {
                    for (point, &w) in row[start..][..N].iter_mut().zip(&ascending) {
                        *point += qxy * w;
                    }
                }
                None => {
                    for kz in 0..N {
                        row[st.index[2][kz] as usize] += qxy * wz.value[kz];
                    }
                }
            }
        }
    }
}

/// `Σ_k g(k) ∂_a W(k)` (in `u`) for B-splines of order `N`, as GROMACS's SIMD gather: `N`
/// lanes along z (the row's run, or its points gathered when the stencil wraps)
/// accumulate over the `N²` x-y pairs `g · (M′_x M_y, M_x M′_y, M_x M_y)`; the lanes are
/// then weighted by `M_z` (or `M′_z`) and summed in z order. A fixed order of operations
/// per atom, so the same bits at any thread count and on every instruction set. Cost:
/// `N²` rows of `3N` multiply-adds and `3N` at the end.
#[inline(always)]
fn gather_first<T: MeshFloat, const N: usize>(
    st: &Stencil<T>,
    g: &[T],
    ny: usize,
    nz: usize,
) -> [T; 3] {
    let [wx, wy, wz] = &st.weights;
    let run = z_run::<T, N>(st, nz);
    let mut lanes = [[T::zero(); N]; 3];
    for kx in 0..N {
        let gx = st.index[0][kx] as usize * ny;
        let (x, dx) = (wx.value[kx], wx.first[kx]);
        for ky in 0..N {
            let row = &g[(gx + st.index[1][ky] as usize) * nz..][..nz];
            let p: [T; N] = match run {
                Some(start) => {
                    let run = &row[start..][..N];
                    std::array::from_fn(|j| run[j])
                }
                None => std::array::from_fn(|j| row[st.index[2][N - 1 - j] as usize]),
            };
            let (y, dy) = (wy.value[ky], wy.first[ky]);
            let c = [dx * y, x * dy, x * y];
            for a in 0..3 {
                for j in 0..N {
                    lanes[a][j] += p[j] * c[a];
                }
            }
        }
    }
    let up: [(T, T); N] = std::array::from_fn(|j| (wz.value[N - 1 - j], wz.first[N - 1 - j]));
    let mut first = [T::zero(); 3];
    for (j, &(z, dz)) in up.iter().enumerate() {
        first[0] += lanes[0][j] * z;
        first[1] += lanes[1][j] * z;
        first[2] += lanes[2][j] * dz;
    }
    first
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The splines, spreading and gathering compiled for each instruction set give the
    /// portable path's bits, in both precisions and every order, with atoms anywhere in the
    /// box (so stencils that wrap the grid's edge along each axis are among them).
    #[test]
    fn every_instruction_set_gives_the_portable_bits() {
        let lengths = [19.0, 21.0, 23.0];
        let n = 300;
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let q: Vec<f64> = (0..3 * n).map(|k| lengths[k % 3] * next()).collect();
        let mut charges: Vec<f64> = (0..n).map(|_| next() - 0.5).collect();
        charges[7] = 0.0;
        for order in 4..=MAX_ORDER {
            let params = EwaldParameters {
                alpha: 0.35,
                grid: [20, 22, 24],
                order,
            };
            for precision in [Precision::Double, Precision::Mixed] {
                let mut reference: Option<Vec<u64>> = None;
                for isa in Isa::available() {
                    let mut term =
                        PmeReciprocal::new(params, lengths, 332.0, charges.clone(), &[]).unwrap();
                    term.isa = isa;
                    assert!(term.set_precision(precision));
                    let mut g = vec![0.0; 3 * n];
                    term.add_gradient(&q, &mut g);
                    assert!(g.iter().all(|x| x.is_finite()) && g.iter().any(|&x| x != 0.0));
                    let bits: Vec<u64> = g.iter().map(|x| x.to_bits()).collect();
                    match &reference {
                        None => reference = Some(bits),
                        Some(first) => assert!(
                            *first == bits,
                            "order {order} {precision:?}: {isa:?} differs from the portable path"
                        ),
                    }
                }
            }
        }
    }
}
