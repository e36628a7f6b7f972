//! Energy monitoring during a run: the error statistics of the summary and the blow-up
//! test that stops an unstable run.

/// Tracks `E(t) − E₀` and decides when a run has blown up.
#[derive(Clone, Debug)]
pub struct EnergyMonitor {
    pub initial: f64,
    pub last: f64,
    pub max_abs_error: f64,
    /// The denominator of relative errors: `|E₀|`, or the initial energy scale
    /// `K₀ + Σ|V_level|` when `E₀` is (nearly) zero.
    pub reference: f64,
    /// `|E − E₀|` beyond `blowup × reference` counts as a blow-up.
    pub blowup: f64,
    /// What `E₀` was made of, for a checkpoint (a continued run monitors against it).
    pub initial_kinetic: f64,
    pub initial_potentials: Vec<f64>,
}

impl EnergyMonitor {
    /// `kinetic` and `potentials` at the start; `blowup` is the factor of the blow-up test.
    pub fn new(kinetic: f64, potentials: &[f64], blowup: f64) -> Self {
        let initial = kinetic + potentials.iter().sum::<f64>();
        let scale = kinetic.abs() + potentials.iter().map(|v| v.abs()).sum::<f64>();
        let reference = if initial.abs() > 1e-12 * scale {
            initial.abs()
        } else if scale > 0.0 {
            scale
        } else {
            1.0
        };
        EnergyMonitor {
            initial,
            last: initial,
            max_abs_error: 0.0,
            reference,
            blowup,
            initial_kinetic: kinetic,
            initial_potentials: potentials.to_vec(),
        }
    }

    /// Record a total energy; `Err` with the reason when it is not finite or beyond the
    /// blow-up bound.
    pub fn record(&mut self, total: f64) -> Result<(), String> {
        self.last = total;
        if !total.is_finite() {
            return Err(format!("energy is not finite ({total})"));
        }
        let error = (total - self.initial).abs();
        self.max_abs_error = self.max_abs_error.max(error);
        if error > self.blowup * self.reference {
            return Err(format!(
                "|E - E0| = {error:.3e} exceeds {} x the initial energy scale {:.3e}",
                self.blowup, self.reference
            ));
        }
        Ok(())
    }

    pub fn max_relative_error(&self) -> f64 {
        self.max_abs_error / self.reference
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_error_uses_initial_energy() {
        let mut monitor = EnergyMonitor::new(1.0, &[1.0], 10.0);
        assert!(monitor.record(2.1).is_ok());
        assert!((monitor.max_relative_error() - 0.05).abs() < 1e-12);
    }

    #[test]
    fn zero_initial_energy_falls_back_to_the_scale() {
        let monitor = EnergyMonitor::new(1.0, &[-1.0], 10.0);
        assert_eq!(monitor.reference, 2.0);
    }

    #[test]
    fn blowup_and_non_finite_are_reported() {
        let mut monitor = EnergyMonitor::new(1.0, &[0.0], 10.0);
        assert!(monitor.record(5.0).is_ok());
        assert!(monitor.record(12.5).unwrap_err().contains("exceeds"));
        assert!(monitor.record(f64::NAN).unwrap_err().contains("not finite"));
    }
}
