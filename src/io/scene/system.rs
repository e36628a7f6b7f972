//! The box, a non-diagonal mass matrix and an exact solution.

use std::collections::BTreeMap;

use toml::Spanned;

use super::sites::Names;
use super::{Builder, ExactSpec, MassMatrixSpec, MassPairs};
use crate::error::Result;
use crate::io::structure::Structure;
use crate::settings::Value;
use crate::system::exact::{ExactSolution, ExpressionSolution, TwoMediaWave};
use crate::system::{MassMatrix, PeriodicBox};

impl Builder<'_> {
    /// The periodic box: `box = [...]`, else a cell in the structure file (extended XYZ
    /// `Lattice=`, PDB `CRYST1`) when dim = 3.
    pub(super) fn periodic_box(
        &self,
        spanned: Option<&Spanned<Vec<Value>>>,
        dim: usize,
        parameters: &BTreeMap<String, f64>,
        structure: Option<&Structure>,
    ) -> Result<Option<PeriodicBox>> {
        let Some(spanned) = spanned else {
            return Ok(structure
                .and_then(|s| s.cell)
                .filter(|_| dim == 3)
                .map(|lengths| PeriodicBox { lengths }));
        };
        let offset = spanned.span().start;
        let lengths = self.vector(spanned.get_ref(), dim, parameters, "box", offset)?;
        if lengths.iter().any(|&l| l <= 0.0) {
            return Err(self.error_at(offset, "box lengths must be positive"));
        }
        let mut all = [f64::INFINITY; 3];
        all[..dim].copy_from_slice(&lengths);
        Ok(Some(PeriodicBox { lengths: all }))
    }

    /// The `[mass_matrix]` table: the full matrix, or `None` after lumping it into `masses`.
    pub(super) fn mass_matrix(
        &self,
        spanned: &Spanned<MassMatrixSpec>,
        dim: usize,
        masses: &mut [f64],
        names: &Names,
        parameters: &BTreeMap<String, f64>,
    ) -> Result<Option<MassMatrix>> {
        let offset = spanned.span().start;
        let spec = spanned.get_ref();
        let what = "[mass_matrix]";
        let value = self.evaluate(
            &spec.off_diagonal,
            parameters,
            "[mass_matrix] off_diagonal",
            offset,
        )?;
        let pairs: Vec<(usize, usize)> = match &spec.pairs {
            MassPairs::Keyword(word) if word == "chain" => {
                (1..masses.len()).map(|i| (i - 1, i)).collect()
            }
            MassPairs::Keyword(other) => {
                return Err(self.error_at(
                    offset,
                    format!("{what}: pairs must be \"chain\" or a list of pairs, got \"{other}\""),
                ));
            }
            MassPairs::List(list) => list
                .iter()
                .map(|[a, b]| {
                    Ok((
                        self.particle(a, names, what, offset)?,
                        self.particle(b, names, what, offset)?,
                    ))
                })
                .collect::<Result<_>>()?,
        };
        let entries: Vec<(usize, usize, f64)> = pairs.iter().map(|&(i, j)| (i, j, value)).collect();
        let matrix = MassMatrix::new(dim, masses, &entries)
            .map_err(|e| self.error_at(offset, format!("{what}: {e}")))?;
        if spec.lump.unwrap_or(false) {
            let lumped = matrix.row_sums();
            if let Some(i) = lumped.iter().position(|&m| m.is_nan() || m <= 0.0) {
                return Err(self.error_at(
                    offset,
                    format!(
                        "{what}: lumped mass of particle {i} is {} (not positive)",
                        lumped[i]
                    ),
                ));
            }
            masses.copy_from_slice(&lumped);
            return Ok(None);
        }
        Ok(Some(matrix))
    }

    pub(super) fn exact_solution(
        &self,
        spanned: &Spanned<ExactSpec>,
        dim: usize,
        parameters: &BTreeMap<String, f64>,
    ) -> Result<Box<dyn ExactSolution>> {
        let offset = spanned.span().start;
        let solution: Box<dyn ExactSolution> = match spanned.get_ref() {
            ExactSpec::Expression { position } => {
                if position.len() != dim {
                    return Err(self.error_at(
                        offset,
                        format!(
                            "[exact] position has {} components, but the scene has dim = {dim}",
                            position.len()
                        ),
                    ));
                }
                Box::new(ExpressionSolution {
                    dim,
                    position: position.clone(),
                    parameters: parameters.clone(),
                })
            }
            ExactSpec::TwoMediaWave {
                c1,
                c2,
                interface,
                pulse,
                support,
                node,
            } => {
                let positive = |v: &Value, key: &str| -> Result<f64> {
                    let x = self.evaluate(v, parameters, &format!("[exact] {key}"), offset)?;
                    if x <= 0.0 {
                        return Err(self
                            .error_at(offset, format!("[exact] {key} must be positive, got {x}")));
                    }
                    Ok(x)
                };
                let support = (
                    self.evaluate(&support[0], parameters, "[exact] support", offset)?,
                    self.evaluate(&support[1], parameters, "[exact] support", offset)?,
                );
                Box::new(TwoMediaWave {
                    c1: positive(c1, "c1")?,
                    c2: positive(c2, "c2")?,
                    interface: positive(interface, "interface")?,
                    pulse: pulse.clone(),
                    support,
                    node: node.clone(),
                    parameters: parameters.clone(),
                })
            }
        };
        // Evaluate once now, so a typo is a scene error and not a failure after the run.
        let mut probe = vec![0.0; dim];
        solution
            .positions(0.0, &mut probe)
            .map_err(|e| self.error_at(offset, e.to_string()))?;
        Ok(solution)
    }
}
