//! Unit systems of scenes.
//!
//! Most scenes are dimensionless (`units` absent or `"none"`): every number is taken as
//! written. Molecule scenes declare `units = "real"`, the units of the peer codes' kit
//! (LAMMPS `units real`): length Å, time fs, mass amu (g/mol), energy kcal/mol, charge e,
//! temperature K; forces in kcal/mol/Å, velocities in Å/fs.
//!
//! **One conversion, at the masses.** The equations of motion are `dq/dt = M⁻¹p`,
//! `dp/dt = −∇V`. With q in Å, t in fs and V in kcal/mol they hold as written if the mass
//! is expressed in kcal/mol·fs²/Å²: 1 kcal/mol per amu = 4184 J/mol / (10⁻³ kg/mol)
//! = 4.184·10⁶ m²/s² = 4.184·10⁶ · (10¹⁰ Å)² / (10¹⁵ fs)² = 4.184·10⁻⁴ Å²/fs², so
//! 1 amu = 1 / 4.184·10⁻⁴ = 2390.057… kcal/mol·fs²/Å² ([`MASS_AMU`]). Everything
//! else stays in the scene's units: positions Å, time fs, energies and forces kcal/mol and
//! kcal/mol/Å (energy.csv and `longstep forces` print them as they are), momenta
//! kcal/mol·fs/Å, and a velocity v in Å/fs gives the momentum `p = m v` with m converted.
//!
//! Time values may carry a unit in a real scene: `4fs`, `0.5 fs`, `10ps`, `1ns`
//! (see [`Units::time_units`]); a plain number is in the scene's time unit (fs).

/// 1 amu in kcal/mol·fs²/Å² (the internal mass unit of a real scene); see the module doc.
pub const MASS_AMU: f64 = 1.0 / 4.184e-4;

/// Coulomb constant `1/(4πε₀)` in kcal/mol·Å/e², as LAMMPS `units real` (`qqr2e`) and the
/// peer kit (`ke = 332.06371`); OpenMM's 138.935456 kJ/mol·nm/e² is 332.0637… in these units.
pub const COULOMB_KCAL_ANGSTROM: f64 = 332.06371;

/// Boltzmann's constant in kcal/mol/K (CODATA: 1.380649e-23 J/K × 6.02214076e23 / 4184).
pub const BOLTZMANN_KCAL_PER_K: f64 = 1.380649e-23 * 6.02214076e23 / 4184.0;

/// `x` with at most `digits` significant digits, without trailing zeros.
pub fn significant(x: f64, digits: usize) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let magnitude = x.abs().log10().floor() as i32;
    let decimals = (digits as i32 - 1 - magnitude).max(0) as usize;
    let text = format!("{x:.decimals$}");
    if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        text
    }
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Units {
    /// Dimensionless: numbers as written, no unit suffixes.
    #[default]
    None,
    /// Å, fs, amu, kcal/mol, e, K.
    Real,
}

/// Time-unit suffixes of a real scene and their value in fs.
const REAL_TIME_UNITS: &[(&str, f64)] = &[("fs", 1.0), ("ps", 1e3), ("ns", 1e6)];

/// Temperature-unit suffixes of a real scene (kelvin).
const REAL_TEMPERATURE_UNITS: &[(&str, f64)] = &[("K", 1.0)];

impl Units {
    /// Parse the scene key `units`.
    pub fn parse(text: &str) -> Result<Self, String> {
        match text {
            "none" => Ok(Units::None),
            "real" => Ok(Units::Real),
            other => Err(format!(
                "unknown units \"{other}\"; use \"real\" (Å, fs, amu, kcal/mol, e) or \"none\""
            )),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Units::None => "none",
            Units::Real => "real",
        }
    }

    /// The suffixes a time value may carry, each with its value in the scene's time unit.
    pub fn time_units(self) -> &'static [(&'static str, f64)] {
        match self {
            Units::None => &[],
            Units::Real => REAL_TIME_UNITS,
        }
    }

    /// The suffixes a temperature may carry (`300K` in a real scene; none in a
    /// dimensionless one, where a temperature is the number `k_B T` with `k_B = 1`).
    pub fn temperature_units(self) -> &'static [(&'static str, f64)] {
        match self {
            Units::None => &[],
            Units::Real => REAL_TEMPERATURE_UNITS,
        }
    }

    /// Boltzmann's constant in the scene's energy per temperature unit: kcal/mol/K in a
    /// real scene, 1 in a dimensionless one (a temperature there is `k_B T` itself).
    pub fn boltzmann(self) -> f64 {
        match self {
            Units::None => 1.0,
            Units::Real => BOLTZMANN_KCAL_PER_K,
        }
    }

    /// The time unit's name (`fs`; empty in a dimensionless scene).
    pub fn time_name(self) -> &'static str {
        match self {
            Units::None => "",
            Units::Real => "fs",
        }
    }

    /// The length unit's name (`Å`; empty in a dimensionless scene).
    pub fn length_name(self) -> &'static str {
        match self {
            Units::None => "",
            Units::Real => "Å",
        }
    }

    /// An inverse length (`0.347 1/Å`, the Ewald splitting α) with ten significant digits
    /// and its unit; a bare number in a dimensionless scene.
    pub fn inverse_length(self, x: f64) -> String {
        match self {
            Units::None => significant(x, 10),
            Units::Real => format!("{} 1/{}", significant(x, 10), self.length_name()),
        }
    }

    /// A length with ten significant digits and its unit (`9 Å`; bare when dimensionless).
    pub fn length(self, x: f64) -> String {
        match self {
            Units::None => significant(x, 10),
            Units::Real => format!("{} {}", significant(x, 10), self.length_name()),
        }
    }

    /// The energy unit's name (`kcal/mol`; empty in a dimensionless scene).
    pub fn energy_name(self) -> &'static str {
        match self {
            Units::None => "",
            Units::Real => "kcal/mol",
        }
    }

    /// The temperature unit's name (`K`; empty in a dimensionless scene).
    pub fn temperature_name(self) -> &'static str {
        match self {
            Units::None => "",
            Units::Real => "K",
        }
    }

    /// Internal mass for a mass given in the scene's mass unit.
    pub fn mass(self, given: f64) -> f64 {
        match self {
            Units::None => given,
            Units::Real => given * MASS_AMU,
        }
    }

    /// The mass in the scene's mass unit for an internal mass (inverse of [`Units::mass`]).
    pub fn mass_in_scene_units(self, internal: f64) -> f64 {
        match self {
            Units::None => internal,
            Units::Real => internal / MASS_AMU,
        }
    }

    /// Unit names for tables and JSON: (length, time, mass, energy, force, charge).
    pub fn labels(self) -> [(&'static str, &'static str); 6] {
        match self {
            Units::None => [
                ("length", "scene"),
                ("time", "scene"),
                ("mass", "scene"),
                ("energy", "scene"),
                ("force", "scene"),
                ("charge", "scene"),
            ],
            Units::Real => [
                ("length", "angstrom"),
                ("time", "fs"),
                ("mass", "amu"),
                ("energy", "kcal/mol"),
                ("force", "kcal/mol/angstrom"),
                ("charge", "e"),
            ],
        }
    }
}

/// Every unit suffix any unit system knows (time, temperature), for an error that says
/// which scene accepts it.
pub fn is_known_unit(name: &str) -> bool {
    REAL_TIME_UNITS
        .iter()
        .chain(REAL_TEMPERATURE_UNITS)
        .any(|(n, _)| *n == name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mass_unit_is_the_inverse_of_the_energy_conversion() {
        // A 1 amu particle with 1 kcal/mol kinetic energy: v² = 2E/m = 2 × 4.184e-4 Å²/fs².
        let m = Units::Real.mass(1.0);
        let v2 = 2.0 * 1.0 / m;
        assert!((v2 - 2.0 * 4.184e-4).abs() < 1e-18);
        // kB T at 300 K ≈ 0.596 kcal/mol.
        assert!((BOLTZMANN_KCAL_PER_K * 300.0 - 0.596_16).abs() < 1e-5);
    }
}
