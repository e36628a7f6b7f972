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
        d - length * (d / length).round()
    }
}
