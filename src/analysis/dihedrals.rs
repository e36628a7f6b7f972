//! Backbone dihedrals and their basins (`longstep analyze` with a topology).
//!
//! * **Which angles.** From a topology's atom names and residues: in residue `i` with atoms
//!   named `N`, `CA` and `C`, bonded to the `C` of residue `i − 1` and to the `N` of
//!   residue `i + 1`, φ is the dihedral C(i−1)–N–CA–C and ψ is N–CA–C–N(i+1) (IUPAC
//!   convention, IUPAC-IUB 1970: the angle of the far bond about the middle one, clockwise
//!   positive, in (−180°, 180°]). The alanine dipeptide (ACE–ALA–NME) has one such pair, in
//!   ALA; the caps and water have none.
//! * **The angle** of each frame from [`crate::forces::torsion::dihedral_angle`], with
//!   the three bond vectors taken by minimum image in a periodic box (a molecule wrapped
//!   across the box keeps its angles).
//! * **Histogram**: the fraction of frames per 10° × 10° bin of (φ, ψ), φ-major, φ and ψ from
//!   −180°.
//! * **Basins**, the usual coarse partition of the alanine-dipeptide Ramachandran plane
//!   into three boxes that tile it, placed along the barriers between the minima of
//!   Tobias & Brooks (J. Phys. Chem. 96:3864, 1992: C7eq near (−78°, 90°), C5 near
//!   (−135°, 146°), C7ax near (61°, −72°)) and the αR (−65°, −40°) and αL (+60°, +45°)
//!   helical regions:
//!   - **C7eq/β** (extended: C7eq, C5, β, PII): φ < 0 and (ψ ≥ 50° or ψ < −120°);
//!   - **αR**: φ < 0 and −120° ≤ ψ < 50°;
//!   - **αL**: φ ≥ 0 (αL and C7ax together: the whole left-handed half-plane).
//!
//! Populations are fractions of frames per basin; their error bars are the standard errors
//! of the block means of each basin's indicator ([`super::block_average`]), the blocks of the
//! rest of the analysis, but never below the error that the count of basin changes allows
//! ([`transition_error`]): a residue that changes basin less often than the blocks are long
//! has block means that are not independent, and their scatter understates the error.
//!
//! **A change of basin is counted between cores** ([`core`]: each box shrunk by
//! [`CORE_MARGIN`] at every edge), as in transition-based assignment (Buchete & Hummer,
//! J. Phys. Chem. B 112:6057, 2008): the residue changes basin when it reaches the core of a
//! basin other than the one whose core it was last in. Counting every crossing of a box edge
//! would count recrossings: on the solvated dipeptide most crossings of ψ = 50° are excursions
//! of a frame or two (0.2 ps) into the sparse region between αR and β, and counting them
//! gave 36 changes in a 550 ps run that changed basin 6 to 12 times, and an error bar
//! 2–3 times too small (`docs/data/verdicts/ala2-2026-11-29-cores.txt`).
//!
//! **Means coupled to the basins.** A mean over frames of anything that differs between
//! basins (a torsion's or a 1-4 term's energy) inherits the populations' error, which block
//! errors miss when basins change more slowly than blocks are long. [`BasinCounter::coupling_error`]
//! gives it: each frame is assigned to the basin whose core it was last in, and a series'
//! mean `Ē = Σ_k p_k Ē_k` moves by `Σ_k |Ē_k − Ē| σ_k` when the populations move by their
//! errors `σ_k` ([`transition_error`] of the core changes); exact for a residue with two
//! basins, an upper bound for more, summed over residues (residues of a protein change basin
//! together, so their errors are not taken as independent). A residue that never changed
//! basin core adds nothing: no second basin was seen to differ from.
//! Cost: one dihedral pair per backbone residue per frame, one byte per residue and frame.

use std::path::Path;

use super::block_average::{BlockAccumulator, Estimate, from_block_means};
use crate::error::{Error, Result};
use crate::forces::PeriodicBox;
use crate::forces::torsion::dihedral_angle;
use crate::io::scene::{is_topology_path, parse_scene, read_topology_file};
use crate::io::topology::Topology;

/// The basins, in the order of [`basin`]'s index.
pub const BASINS: [&str; 3] = ["C7eq/beta", "alphaR", "alphaL"];

/// Bins of the (φ, ψ) histogram per angle (10° each).
pub const HISTOGRAM_BINS: usize = 36;

/// The ψ edges of the αR box (degrees): αR is `[ALPHA_R_PSI.0, ALPHA_R_PSI.1)` at φ < 0.
pub const ALPHA_R_PSI: (f64, f64) = (-120.0, 50.0);

/// Degrees by which a basin's core lies inside its box at every edge ([`core`]). 30° puts the
/// edge between the αR and β cores across the sparse region 20° < ψ < 80° that the solvated
/// dipeptide crosses in a frame or two, and keeps the minima of every basin (module
/// documentation) inside their cores.
pub const CORE_MARGIN: f64 = 30.0;

/// The topology a scene was built from: the scene path itself when it is a topology file,
/// else its `[topology]` file (with its GROMACS defines); `None` for a scene without one.
pub fn scene_topology(path: &Path) -> Result<Option<Topology>> {
    if is_topology_path(path) {
        return read_topology_file(path, &[]).map(Some);
    }
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let file = parse_scene(&text, path)?;
    let Some(spec) = &file.topology else {
        return Ok(None);
    };
    let spec = spec.get_ref();
    let topology = path.parent().unwrap_or(Path::new(".")).join(&spec.file);
    let defines = spec.defines.clone().unwrap_or_default();
    read_topology_file(&topology, &defines).map(Some)
}

/// One backbone residue's φ and ψ atoms.
#[derive(Clone, Debug, PartialEq)]
pub struct BackboneResidue {
    /// Residue name and number (1-based), e.g. `ALA2`.
    pub label: String,
    pub phi: [usize; 4],
    pub psi: [usize; 4],
}

/// The backbone residues of `topology` (module documentation), in residue order.
pub fn backbone_residues(topology: &Topology) -> Vec<BackboneResidue> {
    let named = |residue: usize, name: &str| -> Option<usize> {
        let first = topology.residues.get(residue)?.first_atom;
        let end = topology
            .residues
            .get(residue + 1)
            .map_or(topology.atoms.len(), |r| r.first_atom);
        (first..end).find(|&k| topology.atoms[k].name == name)
    };
    let bonded = |a: usize, b: usize| {
        topology
            .bonds
            .iter()
            .any(|bond| bond.atoms == [a, b] || bond.atoms == [b, a])
    };
    let mut residues = Vec::new();
    for r in 1..topology.residues.len().saturating_sub(1) {
        let atoms = (
            named(r - 1, "C"),
            named(r, "N"),
            named(r, "CA"),
            named(r, "C"),
            named(r + 1, "N"),
        );
        if let (Some(c0), Some(n), Some(ca), Some(c), Some(n1)) = atoms
            && bonded(c0, n)
            && bonded(c, n1)
        {
            residues.push(BackboneResidue {
                label: format!("{}{}", topology.residues[r].name, r + 1),
                phi: [c0, n, ca, c],
                psi: [n, ca, c, n1],
            });
        }
    }
    residues
}

/// The dihedral angle of atoms `a` in positions `q` (`n × 3`), degrees in (−180°, 180°];
/// in a periodic box each bond vector is the minimum image.
pub fn dihedral_degrees(q: &[f64], a: [usize; 4], periodic_box: Option<&PeriodicBox>) -> f64 {
    let point = |k: usize| -> [f64; 3] { std::array::from_fn(|x| q[3 * a[k] + x]) };
    // Unwrap the chain from its first atom, bond by bond.
    let mut points = [point(0); 4];
    for k in 1..4 {
        let (raw_from, to, from) = (point(k - 1), point(k), points[k - 1]);
        points[k] = std::array::from_fn(|x| {
            let d = to[x] - raw_from[x];
            from[x] + periodic_box.map_or(d, |b| b.wrap(x, d))
        });
    }
    let angle = dihedral_angle(points[0], points[1], points[2], points[3]).to_degrees();
    if angle <= -180.0 {
        angle + 360.0
    } else {
        angle
    }
}

/// The basin index ([`BASINS`]) of a (φ, ψ) pair in degrees.
pub fn basin(phi: f64, psi: f64) -> usize {
    if phi >= 0.0 {
        2
    } else if (ALPHA_R_PSI.0..ALPHA_R_PSI.1).contains(&psi) {
        1
    } else {
        0
    }
}

/// The basin whose core holds (φ, ψ) in degrees: its box ([`basin`]) less a band of
/// [`CORE_MARGIN`] along each edge, angles taken around the circle; `None` in a band.
pub fn core(phi: f64, psi: f64) -> Option<usize> {
    let here = basin(phi, psi);
    let far = |angle: f64, edge: f64| {
        let d = (angle - edge).rem_euclid(360.0);
        d.min(360.0 - d) >= CORE_MARGIN
    };
    let phi_inside = far(phi, 0.0) && far(phi, 180.0);
    let psi_inside = here == 2 || (far(psi, ALPHA_R_PSI.0) && far(psi, ALPHA_R_PSI.1));
    (phi_inside && psi_inside).then_some(here)
}

/// The histogram bin of an angle in degrees (−180° is bin 0; 180° falls in the last).
fn bin(angle: f64) -> usize {
    let k = ((angle + 180.0) / (360.0 / HISTOGRAM_BINS as f64)).floor();
    (k.max(0.0) as usize).min(HISTOGRAM_BINS - 1)
}

/// The standard error of a basin's population `p` measured over a run in which the residue
/// changed basin `n` times, for a two-state (telegraph) process: with rates `k_A`, `k_B` out
/// of the two states and correlation time `τ = 1/(k_A + k_B)`, the fraction of a long time
/// `T` spent in A has variance `2 p(1 − p) τ / T`, and the expected count of changes is
/// `n = 2 T p(1 − p)/τ`; eliminating `τ/T`, `σ = 2 p(1 − p)/√n`. Few changes say little
/// about `p` itself, so `p` is first shrunk towards 1/2 by one pseudo-dwell,
/// `p̃ = (n p + 1/2)/(n + 1)`, and `σ = 2 p̃(1 − p̃)/√(n + 1)`: a residue that never changed
/// basin has one dwell, and an error of 1/2 (its population could be anything); many
/// changes give the telegraph error.
pub fn transition_error(p: f64, transitions: usize) -> f64 {
    let n = transitions as f64;
    let shrunk = (n * p + 0.5) / (n + 1.0);
    2.0 * shrunk * (1.0 - shrunk) / (n + 1.0).sqrt()
}

/// One residue's basin populations and (φ, ψ) histogram.
#[derive(Clone, Debug, PartialEq)]
pub struct ResidueBasins {
    pub label: String,
    /// Changes of basin core ([`core`]).
    pub transitions: usize,
    /// Fractions of frames in each of [`BASINS`], with block-average errors.
    pub populations: [Estimate; 3],
    /// Each basin's population in each block (the means behind `populations`' errors).
    pub block_means: [Vec<f64>; 3],
    /// Fraction of frames per bin, `HISTOGRAM_BINS²`, φ-major.
    pub histogram: Vec<f64>,
    pub frames: usize,
}

/// Per-block sums of every residue's basin indicators, and the histogram counts.
#[derive(Clone, Debug)]
pub struct BasinCounter {
    residues: Vec<BackboneResidue>,
    indicators: Vec<BlockAccumulator>,
    histograms: Vec<Vec<u64>>,
    /// Each residue's last basin core, and its changes of basin core so far.
    last: Vec<Option<usize>>,
    transitions: Vec<usize>,
    /// Per frame and residue, the basin of the core it was last in ([`NO_CORE_YET`] before
    /// it first reached one): frames × residues.
    assigned: Vec<u8>,
    frames: usize,
}

impl BasinCounter {
    pub fn new(residues: Vec<BackboneResidue>, blocks: usize) -> Self {
        let n = residues.len();
        BasinCounter {
            residues,
            indicators: (0..n).map(|_| BlockAccumulator::new(blocks, 3)).collect(),
            histograms: vec![vec![0; HISTOGRAM_BINS * HISTOGRAM_BINS]; n],
            last: vec![None; n],
            transitions: vec![0; n],
            assigned: Vec::new(),
            frames: 0,
        }
    }

    /// Count one frame into `block`.
    pub fn add(&mut self, q: &[f64], periodic_box: Option<&PeriodicBox>, block: usize) {
        self.frames += 1;
        for r in 0..self.residues.len() {
            let residue = &self.residues[r];
            let phi = dihedral_degrees(q, residue.phi, periodic_box);
            let psi = dihedral_degrees(q, residue.psi, periodic_box);
            self.count(r, phi, psi, block);
        }
    }

    /// Count one frame, given each residue's (φ, ψ) in degrees, into `block`.
    #[cfg(test)]
    fn add_angles(&mut self, angles: &[(f64, f64)], block: usize) {
        assert_eq!(angles.len(), self.residues.len());
        self.frames += 1;
        for (r, &(phi, psi)) in angles.iter().enumerate() {
            self.count(r, phi, psi, block);
        }
    }

    /// Residue `r`'s (φ, ψ) in the current frame: its core change, its assignment, its box's
    /// indicator and its histogram bin.
    fn count(&mut self, r: usize, phi: f64, psi: f64, block: usize) {
        if let Some(now) = core(phi, psi) {
            if self.last[r].is_some_and(|before| before != now) {
                self.transitions[r] += 1;
            }
            self.last[r] = Some(now);
        }
        self.assigned
            .push(self.last[r].map_or(NO_CORE_YET, |k| k as u8));
        let mut hit = [0.0; 3];
        hit[basin(phi, psi)] = 1.0;
        self.indicators[r].add_vector(block, &hit);
        self.histograms[r][bin(phi) * HISTOGRAM_BINS + bin(psi)] += 1;
    }

    pub fn finish(&self) -> Vec<ResidueBasins> {
        let total = self.frames.max(1) as f64;
        self.residues
            .iter()
            .zip(&self.indicators)
            .zip(&self.histograms)
            .zip(&self.transitions)
            .map(|(((residue, indicator), histogram), &transitions)| {
                let overall = indicator.overall_mean();
                let blocks = indicator.counts().len();
                let block_means: [Vec<f64>; 3] = std::array::from_fn(|k| {
                    (0..blocks).map(|b| indicator.block_mean(b)[k]).collect()
                });
                let populations = std::array::from_fn(|k| {
                    let blocked = from_block_means(&block_means[k]);
                    Estimate {
                        mean: overall[k],
                        error: blocked.error.max(transition_error(overall[k], transitions)),
                        ..blocked
                    }
                });
                ResidueBasins {
                    label: residue.label.clone(),
                    transitions,
                    populations,
                    block_means,
                    histogram: histogram.iter().map(|&c| c as f64 / total).collect(),
                    frames: self.frames,
                }
            })
            .collect()
    }
}

/// A frame before its residue first reached a basin core: it counts in the first core the
/// residue reaches (a residue that reaches none has one basin and no coupling).
const NO_CORE_YET: u8 = u8::MAX;

impl BasinCounter {
    /// The error that a mean over the counted frames of `series` (its value in frame `f`,
    /// in counting order) takes from the basins' populations (module documentation):
    /// `Σ_r Σ_k |Ē_rk − Ē| σ_rk`, frames assigned to the basin whose core residue `r` was last
    /// in, `σ_rk` the [`transition_error`] of that assignment's population. Zero without
    /// residues or frames.
    pub fn coupling_error(&self, series: impl Fn(usize) -> f64) -> f64 {
        let n = self.residues.len();
        if n == 0 || self.frames == 0 {
            return 0.0;
        }
        let values: Vec<f64> = (0..self.frames).map(&series).collect();
        let mean = values.iter().sum::<f64>() / self.frames as f64;
        (0..n)
            .map(|r| {
                let first = (0..self.frames)
                    .map(|f| self.assigned[f * n + r])
                    .find(|&k| k != NO_CORE_YET)
                    .unwrap_or(0);
                let (mut sums, mut counts) = ([0.0; 3], [0usize; 3]);
                for (f, &v) in values.iter().enumerate() {
                    let k = match self.assigned[f * n + r] {
                        NO_CORE_YET => usize::from(first),
                        k => usize::from(k),
                    };
                    sums[k] += v;
                    counts[k] += 1;
                }
                (0..3)
                    .filter(|&k| counts[k] > 0)
                    .map(|k| {
                        let p = counts[k] as f64 / self.frames as f64;
                        let basin_mean = sums[k] / counts[k] as f64;
                        (basin_mean - mean).abs() * transition_error(p, self.transitions[r])
                    })
                    .sum::<f64>()
            })
            .sum()
    }
}

/// The basin populations of every residue pooled (each residue's frames counted alike):
/// per basin the mean of the residues' populations, its error from the means over residues
/// of their block means (so the residues' correlation within a block is kept), never below
/// the residues' [`transition_error`]s combined as independent, `√(Σ σ_r²)/n`. `None`
/// without residues.
pub fn pooled_populations(residues: &[ResidueBasins]) -> Option<[Estimate; 3]> {
    let n = residues.len();
    let first = residues.first()?;
    Some(std::array::from_fn(|k| {
        let blocks = first.block_means[k].len();
        let means: Vec<f64> = (0..blocks)
            .map(|b| {
                residues
                    .iter()
                    .map(|r| r.block_means[k].get(b).copied().unwrap_or(f64::NAN))
                    .sum::<f64>()
                    / n as f64
            })
            .collect();
        let blocked = from_block_means(&means);
        let floor = residues
            .iter()
            .map(|r| transition_error(r.populations[k].mean, r.transitions).powi(2))
            .sum::<f64>()
            .sqrt()
            / n as f64;
        Estimate {
            mean: residues.iter().map(|r| r.populations[k].mean).sum::<f64>() / n as f64,
            error: blocked.error.max(floor),
            ..blocked
        }
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_boxes_tile_the_plane() {
        assert_eq!(basin(-78.0, 90.0), 0); // C7eq
        assert_eq!(basin(-135.0, 146.0), 0); // C5
        assert_eq!(basin(-80.0, -170.0), 0); // β across ψ = ±180°
        assert_eq!(basin(-65.0, -40.0), 1); // αR
        assert_eq!(basin(61.0, -72.0), 2); // C7ax
        assert_eq!(basin(60.0, 45.0), 2); // αL
        assert_eq!(
            (bin(-180.0), bin(-175.0), bin(0.0), bin(180.0)),
            (0, 0, 18, 35)
        );
    }

    #[test]
    fn a_core_leaves_out_a_band_along_each_edge() {
        assert_eq!(core(-65.0, -40.0), Some(1)); // αR minimum
        assert_eq!(core(-78.0, 90.0), Some(0)); // C7eq
        assert_eq!(core(-80.0, -170.0), Some(0)); // β across ψ = ±180°
        assert_eq!(core(60.0, 45.0), Some(2)); // αL
        assert_eq!(core(-78.0, 60.0), None); // 10° from the αR/β edge ψ = 50°
        assert_eq!(core(-78.0, 30.0), None);
        assert_eq!(core(-10.0, -40.0), None); // near φ = 0
        assert_eq!(core(-165.0, 150.0), None); // near φ = ±180°
        assert_eq!(core(-78.0, -140.0), None); // near ψ = −120°
    }

    /// A residue that visits β for `dwell` frames, then αR for `dwell` frames, `cycles`
    /// times, with a one-frame excursion across ψ = 50° (not reaching a core) in every
    /// αR dwell; the series is 1 in β and 0 in αR.
    fn telegraph(dwell: usize, cycles: usize) -> (BasinCounter, Vec<f64>) {
        let residue = BackboneResidue {
            label: "ALA2".into(),
            phi: [0, 1, 2, 3],
            psi: [1, 2, 3, 4],
        };
        let mut counter = BasinCounter::new(vec![residue], 2);
        let mut series = Vec::new();
        for c in 0..cycles {
            for (psi, value) in [(150.0, 1.0), (-40.0, 0.0)] {
                for f in 0..dwell {
                    let excursion = value == 0.0 && f == dwell / 2;
                    let psi = if excursion { 60.0 } else { psi };
                    counter.add_angles(&[(-70.0, psi)], usize::from(2 * c >= cycles));
                    series.push(value);
                }
            }
        }
        (counter, series)
    }

    #[test]
    fn excursions_across_an_edge_are_not_changes_of_basin() {
        let (counter, _) = telegraph(10, 4);
        let residue = &counter.finish()[0];
        // 8 dwells: 7 changes between cores; the 4 excursions to ψ = 60° (β by its box,
        // in no core) are not changes, though they count in β's population.
        assert_eq!(residue.transitions, 7);
        assert!((residue.populations[0].mean - 44.0 / 80.0).abs() < 1e-12);
    }

    #[test]
    fn a_mean_coupled_to_two_basins_takes_their_population_error() {
        let (counter, series) = telegraph(10, 4);
        // Two basins, the series' means 1 (β) and 0 (αR), the excursions counted in αR (the
        // core last visited): p = 1/2, and Σ_k |Ē_k − Ē| σ_k = σ(1/2, 7), exactly.
        let coupled = counter.coupling_error(|f| series[f]);
        let expected = transition_error(0.5, 7);
        assert!((coupled - expected).abs() < 1e-12, "{coupled} {expected}");
        // Without a second basin there is nothing to couple to.
        let (mut one, _) = telegraph(0, 1);
        for _ in 0..5 {
            one.add_angles(&[(-70.0, -40.0)], 0);
        }
        assert_eq!(one.coupling_error(|f| f as f64), 0.0);
    }

    #[test]
    fn an_angle_across_the_box_is_the_unwrapped_one() {
        // A trans chain (180°) and a gauche one (60°), then the same with the last atom
        // moved by a box edge: minimum images keep the angle.
        let trans = [0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.5, 0.0, 0.0, 1.5, -1.0, 0.0];
        let b = PeriodicBox { lengths: [10.0; 3] };
        assert!((dihedral_degrees(&trans, [0, 1, 2, 3], None).abs() - 180.0).abs() < 1e-9);
        let mut moved = trans;
        moved[9] += 10.0;
        moved[4] -= 10.0;
        let wrapped = dihedral_degrees(&moved, [0, 1, 2, 3], Some(&b));
        assert!((wrapped.abs() - 180.0).abs() < 1e-9, "{wrapped}");
        let s = 60f64.to_radians();
        let gauche = [
            0.0,
            1.0,
            0.0,
            0.0,
            0.0,
            0.0,
            1.5,
            0.0,
            0.0,
            1.5,
            s.cos(),
            s.sin(),
        ];
        let angle = dihedral_degrees(&gauche, [0, 1, 2, 3], Some(&b));
        assert!((angle.abs() - 60.0).abs() < 1e-9, "{angle}");
    }
}
