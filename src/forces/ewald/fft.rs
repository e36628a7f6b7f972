//! The 3-D real-to-complex FFT of a PME grid `[nx][ny][nz]` (z contiguous) and its
//! unnormalised inverse: real FFTs along z (realfft), then complex FFTs along y and x
//! (rustfft) through a line buffer. The half spectrum is `[nx][ny][nz/2 + 1]`. Plans and
//! scratch are made once; a transform allocates nothing.

use std::sync::Arc;

use realfft::num_complex::Complex;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use rustfft::{Fft, FftPlanner};

pub type C64 = Complex<f64>;

pub struct Fft3 {
    pub dims: [usize; 3],
    /// `nz/2 + 1`.
    pub half: usize,
    r2c: Arc<dyn RealToComplex<f64>>,
    c2r: Arc<dyn ComplexToReal<f64>>,
    /// Forward and inverse along x and y.
    x: [Arc<dyn Fft<f64>>; 2],
    y: [Arc<dyn Fft<f64>>; 2],
}

/// Buffers a transform works in.
pub struct FftScratch {
    scratch: Vec<C64>,
    line: Vec<C64>,
}

impl Fft3 {
    pub fn new(dims: [usize; 3]) -> Self {
        let mut real = RealFftPlanner::<f64>::new();
        let mut complex = FftPlanner::<f64>::new();
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

    pub fn scratch(&self) -> FftScratch {
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
        FftScratch {
            scratch: vec![C64::default(); len],
            line: vec![C64::default(); self.dims[0].max(self.dims[1])],
        }
    }

    /// `spectrum = F(grid)`, `F(m) = Σ_k grid(k) exp(−2πi m·k/K)`; `grid` is overwritten.
    pub fn forward(&self, grid: &mut [f64], spectrum: &mut [C64], work: &mut FftScratch) {
        let [_, _, nz] = self.dims;
        for (row, out) in grid
            .chunks_exact_mut(nz)
            .zip(spectrum.chunks_exact_mut(self.half))
        {
            // Lengths are right by construction: no error can come back.
            let _ = self.r2c.process_with_scratch(row, out, &mut work.scratch);
        }
        self.lines(spectrum, work, 0);
    }

    /// `grid = Σ_m spectrum(m) exp(+2πi m·k/K)` over the full (Hermitian) spectrum,
    /// unnormalised; `spectrum` is overwritten.
    pub fn inverse(&self, spectrum: &mut [C64], grid: &mut [f64], work: &mut FftScratch) {
        let [_, _, nz] = self.dims;
        self.lines(spectrum, work, 1);
        for (row, out) in spectrum
            .chunks_exact_mut(self.half)
            .zip(grid.chunks_exact_mut(nz))
        {
            // The zero and Nyquist bins of a real signal are real; the complex passes
            // leave round-off in their imaginary parts, which c2r must not see.
            row[0].im = 0.0;
            if nz.is_multiple_of(2) {
                row[self.half - 1].im = 0.0;
            }
            let _ = self.c2r.process_with_scratch(row, out, &mut work.scratch);
        }
    }

    /// Complex FFTs along y, then x (`direction` 0 forward, 1 inverse).
    fn lines(&self, spectrum: &mut [C64], work: &mut FftScratch, direction: usize) {
        let [nx, ny, _] = self.dims;
        let h = self.half;
        let (fy, fx) = (&self.y[direction], &self.x[direction]);
        for x in 0..nx {
            for z in 0..h {
                let line = &mut work.line[..ny];
                for (y, slot) in line.iter_mut().enumerate() {
                    *slot = spectrum[(x * ny + y) * h + z];
                }
                fy.process_with_scratch(line, &mut work.scratch);
                for (y, value) in line.iter().enumerate() {
                    spectrum[(x * ny + y) * h + z] = *value;
                }
            }
        }
        for y in 0..ny {
            for z in 0..h {
                let line = &mut work.line[..nx];
                for (x, slot) in line.iter_mut().enumerate() {
                    *slot = spectrum[(x * ny + y) * h + z];
                }
                fx.process_with_scratch(line, &mut work.scratch);
                for (x, value) in line.iter().enumerate() {
                    spectrum[(x * ny + y) * h + z] = *value;
                }
            }
        }
    }
}
