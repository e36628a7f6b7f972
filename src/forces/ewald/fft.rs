//! The PME convolution `φ = F⁻¹(θ F(Q))` of a real grid `[nx][ny][nz]` (z contiguous) with
//! an influence function `θ` on the half spectrum: real FFTs along z (realfft), complex FFTs
//! along y and x (rustfft), all as independent 1-D line transforms.
//!
//! **Passes.** (1) per x-plane: the real FFT of each z-row, then the y-lines of the plane,
//! into `planes` laid out `[x][z][y]` (y contiguous); (2) per y: the x-lines of every
//! `(y, z)` gathered into the spectrum `[y][z][x]` (x contiguous), transformed, multiplied by
//! `θ` (or summed into the energy) and, for the potential, transformed back in place;
//! (3) per x-plane: back into `planes`, the inverse y-lines, and the inverse real FFT of
//! each row into the output grid. Each pass is a set of tasks (one per plane or per y) that
//! share nothing: each owns its output block and its scratch, so the passes run over rayon
//! with each line transformed by the same code whatever the thread count, and the bits do
//! not depend on it. The energy is summed per y and the partial sums added in y order.
//!
//! **Cost.** `K_x K_y K_z` points: the FFTs are `O(K³ log K)`; the gathers into the two
//! layouts two more passes over the half spectrum. Only the `K_z/2 + 1` half planes go
//! through the y and x lines; the z-rows are real, and realfft transforms a row of even
//! `K_z` as a complex FFT of `K_z/2` points, but one of odd `K_z` as a full complex FFT of
//! `K_z` points. So even sizes cost less, and the grid rule picks them
//! ([`super::grid_size`], GROMACS's sizes): on Trp-cage (mixed precision, callgrind, AVX2
//! path) one potential convolution is 5.45 M instructions at 35³, 4.03 M at 36³, 3.44 M at
//! 30³ and 2.18 M at 32³ (rustfft is fastest at powers of two); on the AVX-512 path the
//! FFT's share of a Trp-cage step fell from 8.0 % at 35³ to 4.9 % at 36³
//! (docs/data/sittings/pme-2026-11-29-f.txt). Plans, layouts and per-task scratch are made
//! once; a convolution allocates nothing.
//!
//! **Precision.** Generic over the mesh's float `T` ([`MeshFloat`]): `f64`, or `f32` for
//! mixed precision, with the energy's line sums in `f64` either way. The FFT crates choose
//! their SIMD code (AVX, SSE or scalar) by the processor at run time, so the bits of either
//! precision are the same at any thread count but may differ between machines.

use std::sync::Arc;

use rayon::prelude::*;
use realfft::num_complex::Complex;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use rustfft::{Fft, FftPlanner};

use super::float::MeshFloat;

pub struct Fft3<T> {
    pub dims: [usize; 3],
    /// `nz/2 + 1`.
    pub half: usize,
    r2c: Arc<dyn RealToComplex<T>>,
    c2r: Arc<dyn ComplexToReal<T>>,
    /// Forward and inverse along x and y.
    x: [Arc<dyn Fft<T>>; 2],
    y: [Arc<dyn Fft<T>>; 2],
}

/// One task's buffers: the FFT scratch and one z-row of the half spectrum.
struct Lines<T> {
    scratch: Vec<Complex<T>>,
    row: Vec<Complex<T>>,
}

/// Buffers a convolution works in.
pub struct FftScratch<T> {
    /// `[x][z][y]`: the plane pass's layout.
    planes: Vec<Complex<T>>,
    /// `[y][z][x]`: the spectrum, in the layout of [`Fft3::spectrum_index`].
    spectrum: Vec<Complex<T>>,
    /// One per plane or per y (`max(nx, ny)`).
    tasks: Vec<Lines<T>>,
    /// Per y: `Σ_{z, x} weight θ |F|²` of its lines.
    partial: Vec<f64>,
}

/// What a convolution returns.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Output {
    /// `Σ_m θ(m) |F(Q)(m)|²` over the full spectrum; the grid is consumed.
    Energy,
    /// `φ = F⁻¹(θ F(Q))` (unnormalised inverse) into the output grid.
    Potential,
}

impl<T: MeshFloat> Fft3<T> {
    pub fn new(dims: [usize; 3]) -> Self {
        let mut real = RealFftPlanner::<T>::new();
        let mut complex = FftPlanner::<T>::new();
        let [nx, ny, nz] = dims;
        Fft3 {
            dims,
            half: nz / 2 + 1,
            r2c: real.plan_fft_forward(nz),
            c2r: real.plan_fft_inverse(nz),
            x: [complex.plan_fft_forward(nx), complex.plan_fft_inverse(nx)],
            y: [complex.plan_fft_forward(ny), complex.plan_fft_inverse(ny)],
        }
    }

    pub fn real_len(&self) -> usize {
        self.dims.iter().product()
    }

    pub fn spectrum_len(&self) -> usize {
        self.dims[0] * self.dims[1] * self.half
    }

    /// Where the bin `(kx, ky, kz)` (`kz < half`) lies in the spectrum (and in `θ`).
    pub fn spectrum_index(&self, kx: usize, ky: usize, kz: usize) -> usize {
        (ky * self.half + kz) * self.dims[0] + kx
    }

    pub fn scratch(&self) -> FftScratch<T> {
        let len = [
            self.r2c.get_scratch_len(),
            self.c2r.get_scratch_len(),
            self.x[0].get_inplace_scratch_len(),
            self.x[1].get_inplace_scratch_len(),
            self.y[0].get_inplace_scratch_len(),
            self.y[1].get_inplace_scratch_len(),
        ]
        .into_iter()
        .max()
        .unwrap_or(0);
        let [nx, ny, _] = self.dims;
        let tasks = (0..nx.max(ny))
            .map(|_| Lines {
                scratch: vec![Complex::default(); len],
                row: vec![Complex::default(); self.half],
            })
            .collect();
        FftScratch {
            planes: vec![Complex::default(); self.spectrum_len()],
            spectrum: vec![Complex::default(); self.spectrum_len()],
            tasks,
            partial: vec![0.0; ny],
        }
    }

    /// Convolve `grid` (overwritten) with `influence` (laid out by
    /// [`Self::spectrum_index`]): the energy sum, or the potential into `out` (which may
    /// be `None` to write it back into `grid`). Over rayon when `parallel`.
    pub fn convolve(
        &self,
        grid: &mut [T],
        influence: &[T],
        output: Output,
        out: Option<&mut [T]>,
        work: &mut FftScratch<T>,
        parallel: bool,
    ) -> f64 {
        self.forward_planes(grid, work, parallel);
        let energy = self.x_lines(influence, output, work, parallel);
        if output == Output::Potential {
            let target = out.unwrap_or(grid);
            self.inverse_planes(target, work, parallel);
        }
        energy
    }

    /// Pass (1): per x-plane, real FFTs of the rows, then the y-lines, into `planes`.
    #[inline(never)]
    fn forward_planes(&self, grid: &mut [T], work: &mut FftScratch<T>, parallel: bool) {
        let [_, ny, nz] = self.dims;
        let h = self.half;
        let plane = |input: &mut [T], planes: &mut [Complex<T>], lines: &mut Lines<T>| {
            for (y, row) in input.chunks_exact_mut(nz).enumerate() {
                // Lengths are right by construction: no error can come back.
                let _ = self
                    .r2c
                    .process_with_scratch(row, &mut lines.row, &mut lines.scratch);
                for (z, value) in lines.row.iter().enumerate() {
                    planes[z * ny + y] = *value;
                }
            }
            self.y[0].process_with_scratch(planes, &mut lines.scratch);
        };
        let FftScratch { planes, tasks, .. } = work;
        if parallel {
            grid.par_chunks_exact_mut(ny * nz)
                .zip(planes.par_chunks_exact_mut(h * ny))
                .zip(tasks.par_iter_mut())
                .for_each(|((g, p), t)| plane(g, p, t));
        } else {
            let blocks = grid
                .chunks_exact_mut(ny * nz)
                .zip(planes.chunks_exact_mut(h * ny));
            for ((g, p), t) in blocks.zip(tasks.iter_mut()) {
                plane(g, p, t);
            }
        }
    }

    /// Pass (2): per y, the x-lines gathered from `planes` into the spectrum, transformed,
    /// then weighted by `θ`: summed into the energy or multiplied and transformed back.
    #[inline(never)]
    fn x_lines(
        &self,
        influence: &[T],
        output: Output,
        work: &mut FftScratch<T>,
        parallel: bool,
    ) -> f64 {
        let [nx, ny, nz] = self.dims;
        let h = self.half;
        let planes = &work.planes;
        let spectrum = &mut work.spectrum;
        let tasks = &mut work.tasks;
        let partial = &mut work.partial;
        let one = |y: usize, lines: &mut [Complex<T>], task: &mut Lines<T>, sum: &mut f64| {
            for z in 0..h {
                for x in 0..nx {
                    lines[z * nx + x] = planes[(x * h + z) * ny + y];
                }
            }
            self.x[0].process_with_scratch(lines, &mut task.scratch);
            let theta = &influence[y * h * nx..(y + 1) * h * nx];
            *sum = 0.0;
            for z in 0..h {
                let range = z * nx..(z + 1) * nx;
                match output {
                    Output::Energy => {
                        // Bins other than 0 and the Nyquist bin stand for two (m and −m).
                        let weight = if z == 0 || (nz.is_multiple_of(2) && z == h - 1) {
                            1.0
                        } else {
                            2.0
                        };
                        // Each term in T, the sum in f64.
                        let mut line = 0.0;
                        for (value, t) in lines[range.clone()].iter().zip(&theta[range]) {
                            line += (*t * value.norm_sqr()).wide();
                        }
                        *sum += weight * line;
                    }
                    Output::Potential => {
                        for (value, t) in lines[range.clone()].iter_mut().zip(&theta[range]) {
                            *value = value.scale(*t);
                        }
                    }
                }
            }
            if output == Output::Potential {
                self.x[1].process_with_scratch(lines, &mut task.scratch);
            }
        };
        if parallel {
            spectrum
                .par_chunks_exact_mut(h * nx)
                .zip(tasks.par_iter_mut())
                .zip(partial.par_iter_mut())
                .enumerate()
                .for_each(|(y, ((l, t), s))| one(y, l, t, s));
        } else {
            let blocks = spectrum.chunks_exact_mut(h * nx).zip(tasks.iter_mut());
            for (y, ((l, t), s)) in blocks.zip(partial.iter_mut()).enumerate() {
                one(y, l, t, s);
            }
        }
        partial.iter().sum()
    }

    /// Pass (3): per x-plane, the spectrum back into `planes`, the inverse y-lines and the
    /// inverse real FFT of each row into `grid`.
    #[inline(never)]
    fn inverse_planes(&self, grid: &mut [T], work: &mut FftScratch<T>, parallel: bool) {
        let [nx, ny, nz] = self.dims;
        let h = self.half;
        let spectrum = &work.spectrum;
        let planes = &mut work.planes;
        let tasks = &mut work.tasks;
        let plane = |x: usize, output: &mut [T], lines: &mut [Complex<T>], task: &mut Lines<T>| {
            for y in 0..ny {
                for z in 0..h {
                    lines[z * ny + y] = spectrum[(y * h + z) * nx + x];
                }
            }
            self.y[1].process_with_scratch(lines, &mut task.scratch);
            for (y, out) in output.chunks_exact_mut(nz).enumerate() {
                for (z, slot) in task.row.iter_mut().enumerate() {
                    *slot = lines[z * ny + y];
                }
                // The zero and Nyquist bins of a real signal are real; the complex passes
                // leave round-off in their imaginary parts, which c2r must not see.
                task.row[0].im = T::zero();
                if nz.is_multiple_of(2) {
                    task.row[h - 1].im = T::zero();
                }
                let _ = self
                    .c2r
                    .process_with_scratch(&mut task.row, out, &mut task.scratch);
            }
        };
        if parallel {
            grid.par_chunks_exact_mut(ny * nz)
                .zip(planes.par_chunks_exact_mut(h * ny))
                .zip(tasks.par_iter_mut())
                .enumerate()
                .for_each(|(x, ((g, p), t))| plane(x, g, p, t));
        } else {
            let blocks = grid
                .chunks_exact_mut(ny * nz)
                .zip(planes.chunks_exact_mut(h * ny));
            for (x, ((g, p), t)) in blocks.zip(tasks.iter_mut()).enumerate() {
                plane(x, g, p, t);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic grid of values in [−1, 1).
    fn grid(len: usize) -> Vec<f64> {
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        (0..len)
            .map(|_| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (state >> 11) as f64 / (1u64 << 52) as f64 - 1.0
            })
            .collect()
    }

    #[test]
    fn convolution_with_unit_influence_is_parseval_and_the_identity() {
        // Odd and even sizes on every axis, x ≠ y so that a swapped layout would fail.
        for dims in [[6, 10, 7], [5, 4, 8], [8, 8, 8]] {
            let fft = Fft3::<f64>::new(dims);
            let n = fft.real_len();
            let original = grid(n);
            let ones = vec![1.0; fft.spectrum_len()];
            let mut work = fft.scratch();
            // Parseval: Σ_m |F(m)|² = N Σ_k g(k)².
            let mut g = original.clone();
            let sum = fft.convolve(&mut g, &ones, Output::Energy, None, &mut work, false);
            let norm: f64 = original.iter().map(|x| x * x).sum();
            // Round-off of O(log N) passes of ε on sums of N terms of order one.
            assert!((sum - n as f64 * norm).abs() < 1e-10 * sum, "{dims:?}");
            // θ = 1: the unnormalised inverse of the forward transform is N g.
            let mut g = original.clone();
            let mut out = vec![0.0; n];
            fft.convolve(
                &mut g,
                &ones,
                Output::Potential,
                Some(&mut out),
                &mut work,
                false,
            );
            for (a, b) in out.iter().zip(&original) {
                assert!((a / n as f64 - b).abs() < 1e-13, "{dims:?}");
            }
            // Over rayon, two threads: the same bits.
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(2)
                .build()
                .unwrap();
            let mut g = original.clone();
            let mut parallel_out = vec![0.0; n];
            pool.install(|| {
                fft.convolve(
                    &mut g,
                    &ones,
                    Output::Potential,
                    Some(&mut parallel_out),
                    &mut work,
                    true,
                )
            });
            assert!(
                out.iter()
                    .zip(&parallel_out)
                    .all(|(a, b)| a.to_bits() == b.to_bits())
            );
        }
    }
}
