/// An orthorhombic periodic box; pair terms use the minimum-image displacement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PeriodicBox {
    pub lengths: [f64; 3],
}

impl PeriodicBox {
    /// Minimum-image displacement along axis `axis` for a raw difference `d`.
    #[inline]
    pub fn wrap(&self, axis: usize, d: f64) -> f64 {
        let length = self.lengths[axis];
        // Bonded neighbours are nearly always within half a box: no division or rounding
        // (a library call on baseline x86-64) for them.
        if d.abs() < 0.5 * length {
            return d;
        }
        d - length * (d / length).round()
    }
}
