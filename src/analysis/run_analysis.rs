//! The configurational analysis of a finished run (`longstep analyze`): from its
//! `energy.csv` and trajectory, with the scene it was made from.
//!
//! * **Blocks.** The analysed span runs from the first energy row at or after `skip` to the
//!   last at or before `until` (default: the end). It is cut into `blocks` equal time
//!   blocks; every quantity's error bar is the standard error of its block means
//!   ([`super::block_average`]), and every block must hold at least one trajectory frame.
//! * **Potential energy per molecule**: the `potential` column over the molecule count
//!   (connected components of the bonded terms, [`super::geometry`]); the
//!   Flyvbjerg–Petersen levels of the row series check that the blocks are long enough.
//! * **Kinetic temperature** `2⟨K⟩/(n_dof k_B)` from the `kinetic` column (or another one
//!   named in the options), `n_dof` as the run counted it ([`RunFiles::dof`]: `3N − N_c − 3`
//!   with `N_c` constraints and the centre-of-mass momentum removed), else `3N` (a peer's
//!   run directory without a manifest; `--dof` says otherwise).
//! * **Configurational temperature** and **g(r)** and mean **bond lengths and angles** per
//!   type from the trajectory frames ([`super::configurational`], [`super::rdf`]).
//! * **Backbone (φ, ψ) basins** per residue, when the analyzer is given a topology's backbone
//!   ([`Analyzer::set_backbone`], [`super::dihedrals`]).
//! * **Each force-field term's energy** per frame, recomputed from the frame with the scene's
//!   force field ([`super::term_energies`]): its mean with a block error, and its variance
//!   over frames (the scale of the per-term bounds, `studies::criterion::reference`).
//! * **A trajectory file alone** ([`Analyzer::analyze_trajectory`]: another engine's, or
//!   longstep's without its `energy.csv`, read as [`super::trajectory_input`] says): the
//!   blocks cut the frames' times, and the potential energy per molecule is the sum of the
//!   recomputed terms; there is no kinetic energy (its temperature is NaN, said absent).

use std::path::PathBuf;

use super::block_average::{
    BlockAccumulator, BlockingLevel, Blocks, Estimate, blocks_long_enough, flyvbjerg_petersen,
    from_block_means, ratio_of_means,
};
use super::configurational::ConfigurationalProbe;
use super::dihedrals::{BackboneResidue, BasinCounter, ResidueBasins};
use super::geometry::{Topology, mean_angle, mean_bond_length};
use super::rdf::{PairSelection, Peak, RdfGrid, first_peak};
use super::term_energies;
use super::trajectory_input::{TrajectoryInput, check_order};
use crate::error::{Error, Result};
use crate::forces::PeriodicBox;
use crate::io::energy_table::EnergyTable;
use crate::io::scene::Scene;
use crate::io::trajectory::{FrameInfo, TrajectoryReader};

/// What to compute, and how.
#[derive(Clone, Debug)]
pub struct AnalysisOptions {
    /// Element pairs for g(r).
    pub pairs: Vec<(String, String)>,
    /// Count pairs within one molecule in g(r) (default: left out).
    pub intramolecular: bool,
    /// Start of the analysed span, in the scene's time unit.
    pub skip: f64,
    pub until: Option<f64>,
    pub blocks: usize,
    pub bin_width: f64,
    /// Default: half the shortest box edge.
    pub r_max: Option<f64>,
    pub peak_window: f64,
    pub peak_fit: f64,
    /// Hutchinson probes per frame; `configurational = false` skips the whole estimate.
    pub probes: usize,
    pub seed: u64,
    pub configurational: bool,
    pub dof: Option<f64>,
    /// The energy-table column of the kinetic energy (`kinetic`; a method may write
    /// another, e.g. one taken at a point of its step where it is canonical).
    pub kinetic_column: String,
    /// Use every `stride`-th frame.
    pub stride: usize,
}

/// Most blocks (a bound on a user-given size: each holds a g(r) per pair).
pub const MAX_BLOCKS: usize = 10_000;

/// A run's files.
#[derive(Clone, Debug)]
pub struct RunFiles {
    pub energy: PathBuf,
    pub trajectory: PathBuf,
    /// The degrees of freedom the run counted its kinetic temperature over (its constraints
    /// and removed centre-of-mass momentum, as `longstep analyze` recovers them from its
    /// manifest); `AnalysisOptions::dof` overrides it, `None` of both: `3N`.
    pub dof: Option<f64>,
}

#[derive(Clone, Debug)]
pub struct RdfResult {
    pub name: String,
    pub r: Vec<f64>,
    pub g: Vec<f64>,
    /// Standard error per bin, from the blocks' g(r).
    pub g_error: Vec<f64>,
    /// The first peak of the mean g(r); its error bars from the blocks' peaks.
    pub peak: Option<Peak>,
    pub peak_position: Option<Estimate>,
    pub peak_height: Option<Estimate>,
}

#[derive(Clone, Debug)]
pub struct GeometryResult {
    /// `"bond"` (length unit) or `"angle"` (degrees).
    pub kind: &'static str,
    pub name: String,
    pub count: usize,
    pub mean: Estimate,
}

#[derive(Clone, Debug)]
pub struct ConfigurationalResult {
    pub temperature: Estimate,
    pub gradient_squared: f64,
    pub laplacian: f64,
    /// Mean over frames of the Hutchinson standard error of one frame's Laplacian,
    /// relative to the Laplacian.
    pub hutchinson_relative_error: f64,
    pub exact_terms: Vec<String>,
    pub estimated_terms: Vec<String>,
    pub probes: usize,
    pub colours: usize,
    /// Hessian-vector products per frame: exact, Hutchinson.
    pub products_per_frame: (usize, usize),
    /// Per block: `⟨|∇U|²⟩/⟨∇²U⟩/k_B`.
    pub block_values: Vec<f64>,
}

#[derive(Clone, Debug)]
pub struct RunAnalysis {
    pub blocks: Blocks,
    pub rows: usize,
    pub frames: usize,
    pub rows_per_block: Vec<usize>,
    pub frames_per_block: Vec<usize>,
    pub molecules: usize,
    pub potential_per_molecule: Estimate,
    pub potential_block_means: Vec<f64>,
    pub blocking: Vec<BlockingLevel>,
    pub blocks_long_enough: bool,
    /// Time between energy rows (for the blocking table).
    pub row_interval: f64,
    pub kinetic_temperature: Estimate,
    pub kinetic_block_means: Vec<f64>,
    pub dof: f64,
    pub configurational: Option<ConfigurationalResult>,
    pub rdf: Vec<RdfResult>,
    pub geometry: Vec<GeometryResult>,
    /// Backbone basin populations per residue (empty without a backbone).
    pub basins: Vec<ResidueBasins>,
    /// Each force-field term's energy over the frames ([`super::term_energies`]).
    pub terms: Vec<TermResult>,
    /// Where the energies came from: a run's `energy.csv`, or the frames of a trajectory
    /// file (then times are in frames when `times` is false).
    pub source: EnergySource,
    /// Several runs pooled into this one (`pooling::pool_runs`); `None` for a run.
    pub pooled: Option<Box<super::pooled::Pooling>>,
}

impl RunAnalysis {
    /// Each basin's population pooled over the backbone residues
    /// ([`super::dihedrals::pooled_populations`]), or over runs too for a pooled analysis;
    /// `None` without a backbone.
    pub fn basin_populations(&self) -> Option<[Estimate; 3]> {
        match &self.pooled {
            Some(p) => p.basins,
            None => super::dihedrals::pooled_populations(&self.basins),
        }
    }
}

/// One force-field term's energy over a run's frames.
#[derive(Clone, Debug, PartialEq)]
pub struct TermResult {
    /// The series' name ([`super::term_energies::series_names`]).
    pub name: String,
    /// Mean over frames; its error the block error or, when larger, `basin_error`.
    pub mean: Estimate,
    /// The error the mean takes from the backbone basins' populations
    /// ([`super::dihedrals::BasinCounter::coupling_error`]; zero without a backbone).
    pub basin_error: f64,
    /// Variance of the per-frame energy over all frames (`⟨E²⟩ − ⟨E⟩²`).
    pub variance: f64,
}

/// Where a [`RunAnalysis`] took its energies from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EnergySource {
    /// A run directory's `energy.csv` (and kinetic energies).
    Table,
    /// A trajectory file's frames, recomputed; `times`: false when the file carries none and
    /// no `--frame-time` was given (times are frame numbers).
    Frames { times: bool },
}

/// The scene-side setup shared by every run analysed against one scene.
pub struct Analyzer<'a> {
    scene: &'a Scene,
    options: AnalysisOptions,
    topology: Topology,
    selections: Vec<PairSelection>,
    grid: Option<RdfGrid>,
    box_lengths: Option<[f64; 3]>,
    backbone: Vec<BackboneResidue>,
}

fn bad_option(message: String) -> Error {
    Error::input(message)
}

/// `"O-H"` → `("O", "H")`.
pub fn parse_pair(text: &str) -> Result<(String, String)> {
    match text.trim().split_once('-') {
        Some((a, b)) if !a.is_empty() && !b.is_empty() && !b.contains('-') => {
            Ok((a.to_string(), b.to_string()))
        }
        _ => Err(bad_option(format!(
            "--pairs: \"{text}\" is not an element pair like O-H"
        ))),
    }
}

impl<'a> Analyzer<'a> {
    pub fn new(scene: &'a Scene, options: AnalysisOptions) -> Result<Self> {
        check_options(&options)?;
        let system = &scene.system;
        if system.dim != 3 {
            return Err(bad_option(format!(
                "{}: analyze needs a 3-D scene (this one has dim = {})",
                scene.path.display(),
                system.dim
            )));
        }
        let topology = Topology::from_terms(system.forces.terms(), &scene.elements);
        let box_lengths = system.periodic_box.map(|b| b.lengths);
        let (grid, selections) = if options.pairs.is_empty() {
            (None, Vec::new())
        } else {
            rdf_setup(scene, &options, &topology, box_lengths)?
        };
        Ok(Analyzer {
            scene,
            options,
            topology,
            selections,
            grid,
            box_lengths,
            backbone: Vec::new(),
        })
    }

    /// Count the backbone (φ, ψ) basins of these residues in every frame
    /// ([`super::dihedrals::backbone_residues`] of the scene's topology).
    pub fn set_backbone(&mut self, residues: Vec<BackboneResidue>) {
        self.backbone = residues;
    }

    pub fn topology(&self) -> &Topology {
        &self.topology
    }

    pub fn options(&self) -> &AnalysisOptions {
        &self.options
    }

    /// Analyse one run.
    pub fn analyze(&self, files: &RunFiles) -> Result<RunAnalysis> {
        self.analyze_with(files, &mut |_| {})
    }

    /// [`Analyzer::analyze`], calling `progress` after each frame with the fraction of
    /// the analysed span its time has reached (0 to 1; for a progress bar).
    pub fn analyze_with(
        &self,
        files: &RunFiles,
        progress: &mut dyn FnMut(f64),
    ) -> Result<RunAnalysis> {
        let kinetic = self.options.kinetic_column.as_str();
        let table = EnergyTable::read(&files.energy, &["t", kinetic, "potential"])?;
        let blocks = self.blocks_of(&table)?;
        let mut reader = TrajectoryReader::open(&files.trajectory)?;
        let mut frames = FramePass::new(self, blocks);
        frames.run(self, &mut reader, None, progress)?;
        let energies = self.energy_part(&table, blocks, files.dof)?;
        frames.finish(self, energies, EnergySource::Table)
    }

    /// Analyse a trajectory file alone (module documentation): the blocks cut the span of
    /// its frames' times from `skip`, and the energies are recomputed from the frames.
    pub fn analyze_trajectory(&self, input: &TrajectoryInput) -> Result<RunAnalysis> {
        self.analyze_trajectory_with(input, &mut |_| {})
    }

    /// [`Analyzer::analyze_trajectory`] with `progress` as in [`Analyzer::analyze_with`].
    pub fn analyze_trajectory_with(
        &self,
        input: &TrajectoryInput,
        progress: &mut dyn FnMut(f64),
    ) -> Result<RunAnalysis> {
        let blocks = self.frame_blocks(input)?;
        let mut reader = TrajectoryReader::open(&input.path)?;
        let mut frames = FramePass::new(self, blocks);
        frames.run(self, &mut reader, Some(input), progress)?;
        let energies = frames.energy_part(self, &input.path)?;
        let source = EnergySource::Frames {
            times: input.has_times(),
        };
        frames.finish(self, energies, source)
    }

    /// An error where `input`'s frames carry no time but `--skip` or `--until` needs one:
    /// checked for every input before any is read, so that a long analysis does not stop
    /// at its last file.
    pub fn check_clock(&self, input: &TrajectoryInput) -> Result<()> {
        if !input.has_times() && (self.options.skip > 0.0 || self.options.until.is_some()) {
            return Err(Error::Structure {
                path: input.path.clone(),
                message: "its frames carry no time (a .dcd's header time is unreliable, a .nc's \
                          is not read): give --frame-time to use --skip or --until"
                    .into(),
            });
        }
        Ok(())
    }

    /// The blocks over the times of `input`'s frames from `skip` to `until` (a first pass
    /// over the file that reads only the times).
    fn frame_blocks(&self, input: &TrajectoryInput) -> Result<Blocks> {
        let path = &input.path;
        self.check_clock(input)?;
        let mut reader = TrajectoryReader::open(path)?;
        let mut q = Vec::new();
        let until = self.options.until.unwrap_or(f64::INFINITY);
        let mut inside = Vec::new();
        while let Some(info) = reader.read_next(&mut q)? {
            if info.index == 0 {
                check_first_frame(self, &reader, &q, &info, !input.own)?;
            }
            let t = input.time(info.index, info.time)?;
            if t >= self.options.skip && t <= until {
                inside.push(t);
            }
        }
        let (Some(&start), Some(&end)) = (inside.first(), inside.last()) else {
            return Err(Error::Structure {
                path: path.clone(),
                message: format!(
                    "no frame between the --skip time {} and {}",
                    self.options.skip,
                    self.options
                        .until
                        .map_or("the end".into(), |u| u.to_string()),
                ),
            });
        };
        if inside.len() < self.options.blocks || end <= start {
            return Err(Error::Structure {
                path: path.clone(),
                message: format!(
                    "{} frames from t = {start} to {end} are too few for {} blocks (each block \
                     needs a frame): give fewer --blocks",
                    inside.len(),
                    self.options.blocks
                ),
            });
        }
        Ok(Blocks {
            start,
            end,
            count: self.options.blocks,
        })
    }

    fn blocks_of(&self, table: &EnergyTable) -> Result<Blocks> {
        let path = &table.path;
        let times = table.column(0);
        let until = self.options.until.unwrap_or(f64::INFINITY);
        let inside: Vec<f64> = times
            .iter()
            .copied()
            .filter(|&t| t >= self.options.skip && t <= until)
            .collect();
        let (Some(&start), Some(&end)) = (inside.first(), inside.last()) else {
            return Err(Error::Structure {
                path: path.clone(),
                message: format!(
                    "no energy row between the --skip time {} and {} (the rows run from {} to {})",
                    self.options.skip,
                    self.options
                        .until
                        .map_or("the end".into(), |u| u.to_string()),
                    times.first().copied().unwrap_or(f64::NAN),
                    times.last().copied().unwrap_or(f64::NAN),
                ),
            });
        };
        if inside.len() < 2 * self.options.blocks || end <= start {
            return Err(Error::Structure {
                path: path.clone(),
                message: format!(
                    "{} energy rows from t = {start} to {end} are too few for {} blocks",
                    inside.len(),
                    self.options.blocks
                ),
            });
        }
        Ok(Blocks {
            start,
            end,
            count: self.options.blocks,
        })
    }
}

fn check_options(options: &AnalysisOptions) -> Result<()> {
    if !(2..=MAX_BLOCKS).contains(&options.blocks) {
        return Err(bad_option(format!(
            "--blocks must be between 2 and {MAX_BLOCKS}, got {}",
            options.blocks
        )));
    }
    if options.stride == 0 {
        return Err(bad_option("--stride must be at least 1".into()));
    }
    if options.configurational
        && !(1..=super::configurational::MAX_PROBES).contains(&options.probes)
    {
        return Err(bad_option(format!(
            "--probes must be between 1 and {}, got {}",
            super::configurational::MAX_PROBES,
            options.probes
        )));
    }
    for (value, flag) in [
        (options.peak_window, "--peak-window"),
        (options.peak_fit, "--peak-fit"),
    ] {
        if !(value > 0.0 && value.is_finite()) {
            return Err(bad_option(format!("{flag} must be positive, got {value}")));
        }
    }
    if let Some(dof) = options.dof
        && !(dof > 0.0 && dof.is_finite())
    {
        return Err(bad_option(format!("--dof must be positive, got {dof}")));
    }
    if let Some(until) = options.until
        && until <= options.skip
    {
        return Err(bad_option(format!(
            "--until ({until}) must be after --skip ({})",
            options.skip
        )));
    }
    Ok(())
}

fn rdf_setup(
    scene: &Scene,
    options: &AnalysisOptions,
    topology: &Topology,
    box_lengths: Option<[f64; 3]>,
) -> Result<(Option<RdfGrid>, Vec<PairSelection>)> {
    let Some(lengths) = box_lengths else {
        return Err(bad_option(format!(
            "{}: g(r) needs a periodic box (the scene has none); give --pairs none",
            scene.path.display()
        )));
    };
    let half = lengths.iter().copied().fold(f64::INFINITY, f64::min) / 2.0;
    let r_max = options.r_max.unwrap_or(half);
    if r_max > half * (1.0 + 1e-12) {
        return Err(bad_option(format!(
            "--r-max {r_max} is beyond half the shortest box edge ({half}), where minimum-image \
             distances stop counting every pair"
        )));
    }
    let grid =
        RdfGrid::new(r_max, options.bin_width).map_err(|e| bad_option(format!("g(r): {e}")))?;
    let molecule_of = (!options.intramolecular).then_some(topology.molecule_of.as_slice());
    let selections = options
        .pairs
        .iter()
        .map(|(a, b)| {
            PairSelection::new(&scene.elements, a, b, molecule_of).map_err(|e| {
                bad_option(format!(
                    "--pairs {a}-{b}: the scene {} and its trajectories have {e}",
                    scene.path.display()
                ))
            })
        })
        .collect::<Result<_>>()?;
    Ok((Some(grid), selections))
}

/// Energy-table results: (PE per molecule block means and estimate, FP levels, kinetic
/// temperature, rows per block, row interval, dof).
struct EnergyPart {
    potential: BlockAccumulator,
    blocking: Vec<BlockingLevel>,
    kinetic: BlockAccumulator,
    rows: usize,
    row_interval: f64,
    dof: f64,
}

impl Analyzer<'_> {
    fn energy_part(
        &self,
        table: &EnergyTable,
        blocks: Blocks,
        run_dof: Option<f64>,
    ) -> Result<EnergyPart> {
        let (times, kinetic, potential) = (table.column(0), table.column(1), table.column(2));
        let n = self.scene.elements.len();
        let dof = self.options.dof.or(run_dof).unwrap_or(3.0 * n as f64);
        let k_b = self.scene.units.boltzmann();
        let molecules = self.topology.molecules as f64;
        let mut pe = BlockAccumulator::new(blocks.count, 1);
        let mut temperature = BlockAccumulator::new(blocks.count, 1);
        let mut series = Vec::new();
        let mut used_times = Vec::new();
        for (row, &t) in times.iter().enumerate() {
            let Some(block) = blocks.index(t) else {
                continue;
            };
            if !(potential[row].is_finite() && kinetic[row].is_finite()) {
                return Err(Error::Structure {
                    path: table.path.clone(),
                    message: format!(
                        "the energies at t = {t} are not finite (the run blew up): analyse up to \
                         before then with --until"
                    ),
                });
            }
            pe.add(block, potential[row] / molecules);
            temperature.add(block, 2.0 * kinetic[row] / (dof * k_b));
            series.push(potential[row] / molecules);
            used_times.push(t);
        }
        let row_interval = (used_times.last().unwrap_or(&0.0) - used_times.first().unwrap_or(&0.0))
            / (used_times.len().max(2) - 1) as f64;
        Ok(EnergyPart {
            potential: pe,
            blocking: flyvbjerg_petersen(&series),
            kinetic: temperature,
            rows: series.len(),
            row_interval,
            dof,
        })
    }
}

/// Per-block sums over the trajectory frames.
struct FramePass {
    blocks: Blocks,
    frames: usize,
    rdf: Vec<BlockAccumulator>,
    counts: Vec<u64>,
    g_frame: Vec<f64>,
    geometry: Vec<(&'static str, String, usize, BlockAccumulator)>,
    gradient_squared: BlockAccumulator,
    laplacian: BlockAccumulator,
    hutchinson: BlockAccumulator,
    probe: Option<ConfigurationalProbe>,
    basins: BasinCounter,
    terms: TermPass,
}

/// Each term's energy in every frame (frames × terms), with each frame's block and time.
#[derive(Default)]
struct TermPass {
    names: Vec<String>,
    values: Vec<f64>,
    blocks: Vec<usize>,
    times: Vec<f64>,
    buffer: Vec<f64>,
}

impl TermPass {
    fn add(&mut self, analyzer: &Analyzer, q: &[f64], block: usize, time: f64) {
        let terms = analyzer.scene.system.forces.terms();
        if self.names.is_empty() {
            self.names = term_energies::series_names(terms, q);
        }
        term_energies::evaluate(terms, q, &mut self.buffer);
        self.values.extend_from_slice(&self.buffer);
        self.blocks.push(block);
        self.times.push(time);
    }

    /// Per term: the mean with its error (the block error, or the error coupled to the
    /// `basins` counted over the same frames when larger), and the variance over frames.
    fn results(&self, blocks: usize, basins: &BasinCounter) -> Vec<TermResult> {
        let width = self.names.len();
        let frames = self.blocks.len();
        (0..width)
            .map(|k| {
                let mut accumulator = BlockAccumulator::new(blocks, 1);
                for (f, &block) in self.blocks.iter().enumerate() {
                    accumulator.add(block, self.values[f * width + k]);
                }
                let mut mean = accumulator.estimate();
                let basin_error = basins.coupling_error(|f| self.values[f * width + k]);
                mean.error = mean.error.max(basin_error);
                let variance = (0..frames)
                    .map(|f| (self.values[f * width + k] - mean.mean).powi(2))
                    .sum::<f64>()
                    / frames.max(1) as f64;
                TermResult {
                    name: self.names[k].clone(),
                    mean,
                    basin_error,
                    variance,
                }
            })
            .collect()
    }

    /// The potential energy of frame `f`: the sum of its terms.
    fn potential(&self, f: usize) -> f64 {
        let width = self.names.len();
        self.values[f * width..(f + 1) * width].iter().sum()
    }
}

impl FramePass {
    fn new(analyzer: &Analyzer, blocks: Blocks) -> Self {
        let bins = analyzer.grid.map_or(0, |g| g.bins);
        let topology = &analyzer.topology;
        let mut geometry = Vec::new();
        for (name, bonds) in &topology.bonds {
            geometry.push((
                "bond",
                name.clone(),
                bonds.len(),
                BlockAccumulator::new(blocks.count, 1),
            ));
        }
        for (name, angles) in &topology.angles {
            geometry.push((
                "angle",
                name.clone(),
                angles.len(),
                BlockAccumulator::new(blocks.count, 1),
            ));
        }
        let options = &analyzer.options;
        let system = &analyzer.scene.system;
        let probe = options.configurational.then(|| {
            ConfigurationalProbe::new(
                system.forces.terms(),
                system.n_particles(),
                3,
                options.probes,
                options.seed,
                true,
            )
        });
        FramePass {
            blocks,
            frames: 0,
            rdf: (0..analyzer.selections.len())
                .map(|_| BlockAccumulator::new(blocks.count, bins))
                .collect(),
            counts: vec![0; bins],
            g_frame: vec![0.0; bins],
            geometry,
            gradient_squared: BlockAccumulator::new(blocks.count, 1),
            laplacian: BlockAccumulator::new(blocks.count, 1),
            hutchinson: BlockAccumulator::new(blocks.count, 1),
            probe,
            basins: BasinCounter::new(analyzer.backbone.clone(), blocks.count),
            terms: TermPass::default(),
        }
    }

    /// Read every frame of `reader`: a run directory's trajectory (`input` None) or a
    /// trajectory file analysed alone; `progress` gets the share of the span done.
    fn run(
        &mut self,
        analyzer: &Analyzer,
        reader: &mut TrajectoryReader,
        input: Option<&TrajectoryInput>,
        progress: &mut dyn FnMut(f64),
    ) -> Result<()> {
        let mut q = Vec::new();
        let mut in_span = 0usize;
        let foreign = input.is_some_and(|i| !i.own);
        while let Some(info) = reader.read_next(&mut q)? {
            if info.index == 0 {
                check_first_frame(analyzer, reader, &q, &info, foreign)?;
            }
            let time = match input {
                Some(input) => input.time(info.index, info.time)?,
                None => info.time.ok_or_else(|| Error::Structure {
                    path: reader.path().to_path_buf(),
                    message: format!(
                        "frame {} has no time property (longstep and scripts/openmm_mts_langevin.py \
                         write it in extended XYZ)",
                        info.index
                    ),
                })?,
            };
            let Some(block) = self.blocks.index(time) else {
                continue;
            };
            in_span += 1;
            if !(in_span - 1).is_multiple_of(analyzer.options.stride) {
                continue;
            }
            let lengths = frame_box(analyzer, reader, &info, foreign)?;
            self.frame(analyzer, &q, lengths, &info, block);
            self.terms.add(analyzer, &q, block, time);
            let span = self.blocks.end - self.blocks.start;
            progress(((time - self.blocks.start) / span).clamp(0.0, 1.0));
        }
        if let Some(empty) = self
            .rdf
            .first()
            .map_or(self.gradient_squared.empty_block(), |a| a.empty_block())
        {
            return Err(Error::Structure {
                path: reader.path().to_path_buf(),
                message: format!(
                    "block {empty} of {} (t = {} to {}) has no trajectory frame: write frames more \
                     often, use fewer --blocks or a smaller --stride",
                    self.blocks.count,
                    self.blocks.start + empty as f64 * self.blocks.length(),
                    self.blocks.start + (empty + 1) as f64 * self.blocks.length()
                ),
            });
        }
        Ok(())
    }

    fn frame(
        &mut self,
        analyzer: &Analyzer,
        q: &[f64],
        lengths: Option<[f64; 3]>,
        info: &FrameInfo,
        block: usize,
    ) {
        self.frames += 1;
        if let (Some(grid), Some(l)) = (&analyzer.grid, lengths) {
            let volume = l[0] * l[1] * l[2];
            for (selection, accumulator) in analyzer.selections.iter().zip(&mut self.rdf) {
                self.counts.fill(0);
                selection.histogram(q, l, grid, &mut self.counts);
                selection.normalise(&self.counts, volume, grid, &mut self.g_frame);
                accumulator.add_vector(block, &self.g_frame);
            }
        }
        let periodic_box = lengths.map(|lengths| PeriodicBox { lengths });
        self.basins.add(q, periodic_box.as_ref(), block);
        let topology = &analyzer.topology;
        for (kind, name, _, accumulator) in &mut self.geometry {
            let value = if *kind == "bond" {
                mean_bond_length(q, lengths, &topology.bonds[name.as_str()])
            } else {
                mean_angle(q, lengths, &topology.angles[name.as_str()]).to_degrees()
            };
            accumulator.add(block, value);
        }
        if let Some(probe) = &mut self.probe {
            let sample = probe.sample(analyzer.scene.system.forces.terms(), q, info.index as u64);
            self.gradient_squared.add(block, sample.gradient_squared);
            self.laplacian.add(block, sample.laplacian);
            self.hutchinson.add(
                block,
                sample.laplacian_variance.sqrt() / sample.laplacian.abs(),
            );
        }
        // Every block accumulator counts frames; keep one that always exists.
        if analyzer.selections.is_empty() && self.probe.is_none() {
            self.gradient_squared.add(block, 0.0);
        }
    }
}

/// The trajectory must hold the scene's atoms in its order: the same names in longstep's
/// own files, the model's bonds in another engine's ([`check_order`]).
fn check_first_frame(
    analyzer: &Analyzer,
    reader: &TrajectoryReader,
    q: &[f64],
    info: &FrameInfo,
    foreign: bool,
) -> Result<()> {
    let scene = analyzer.scene;
    let bad = |message: String| Error::Structure {
        path: reader.path().to_path_buf(),
        message,
    };
    let atoms = q.len() / 3;
    if atoms != scene.elements.len() {
        return Err(bad(format!(
            "has {atoms} atoms, but the scene {} has {}: give the scene or topology the \
             trajectory was made from",
            scene.path.display(),
            scene.elements.len()
        )));
    }
    if foreign {
        let lengths = frame_box(analyzer, reader, info, true)?;
        let periodic_box = lengths.map(|lengths| PeriodicBox { lengths });
        let rest: Vec<_> = scene
            .system
            .forces
            .terms()
            .iter()
            .flat_map(|t| t.term.rest_geometry())
            .collect();
        return check_order(reader.path(), &scene.path, q, periodic_box.as_ref(), &rest);
    }
    let names = reader.names();
    if let Some(i) = (0..atoms).find(|&i| names[i] != scene.elements[i]) {
        return Err(bad(format!(
            "atom {i} is \"{}\", but the scene {} has \"{}\" there",
            names[i],
            scene.path.display(),
            scene.elements[i]
        )));
    }
    Ok(())
}

/// The box of a frame: its cell, which must be the scene's box (the runs are at constant
/// volume; trajectory cells are written with about 6 significant digits), else the scene's;
/// `strict` (another engine's file): a periodic model needs the frame's cell.
fn frame_box(
    analyzer: &Analyzer,
    reader: &TrajectoryReader,
    info: &FrameInfo,
    strict: bool,
) -> Result<Option<[f64; 3]>> {
    if strict && info.cell.is_none() && analyzer.box_lengths.is_some() {
        return Err(Error::Structure {
            path: reader.path().to_path_buf(),
            message: format!(
                "frame {} has no box, but the model {} is periodic",
                info.index,
                analyzer.scene.path.display()
            ),
        });
    }
    match (info.cell, analyzer.box_lengths) {
        (Some(cell), Some(scene_box)) => {
            if (0..3).any(|a| (cell[a] - scene_box[a]).abs() > 1e-4 * scene_box[a]) {
                return Err(Error::Structure {
                    path: reader.path().to_path_buf(),
                    message: format!(
                        "frame {}: the cell {cell:?} is not the scene's box {scene_box:?}",
                        info.index
                    ),
                });
            }
            Ok(Some(scene_box))
        }
        (_, scene_box) => Ok(scene_box),
    }
}

impl FramePass {
    /// The energy part of a trajectory file alone: the potential energy per molecule of
    /// every frame from its terms; no kinetic energy (NaN).
    fn energy_part(&self, analyzer: &Analyzer, path: &std::path::Path) -> Result<EnergyPart> {
        let blocks = self.blocks.count;
        let molecules = analyzer.topology.molecules as f64;
        let mut potential = BlockAccumulator::new(blocks, 1);
        let mut kinetic = BlockAccumulator::new(blocks, 1);
        let mut series = Vec::with_capacity(self.terms.blocks.len());
        for (f, &block) in self.terms.blocks.iter().enumerate() {
            let u = self.terms.potential(f) / molecules;
            if !u.is_finite() {
                return Err(Error::Structure {
                    path: path.to_path_buf(),
                    message: format!(
                        "the potential energy of the frame at t = {} is not finite",
                        self.terms.times[f]
                    ),
                });
            }
            potential.add(block, u);
            kinetic.add(block, f64::NAN);
            series.push(u);
        }
        let times = &self.terms.times;
        let row_interval = match (times.first(), times.last()) {
            (Some(a), Some(b)) if times.len() > 1 => (b - a) / (times.len() - 1) as f64,
            _ => 0.0,
        };
        Ok(EnergyPart {
            potential,
            blocking: flyvbjerg_petersen(&series),
            kinetic,
            rows: series.len(),
            row_interval,
            dof: f64::NAN,
        })
    }

    fn finish(
        self,
        analyzer: &Analyzer,
        energies: EnergyPart,
        source: EnergySource,
    ) -> Result<RunAnalysis> {
        let options = &analyzer.options;
        let potential = energies.potential.estimate();
        let frames_per_block = match self.rdf.first() {
            Some(a) => a.counts().to_vec(),
            None => self.gradient_squared.counts().to_vec(),
        };
        let rdf = match analyzer.grid {
            Some(grid) => analyzer
                .selections
                .iter()
                .zip(&self.rdf)
                .map(|(s, a)| rdf_result(&s.name, &grid, a, options))
                .collect(),
            None => Vec::new(),
        };
        let geometry = self
            .geometry
            .iter()
            .map(|(kind, name, count, a)| GeometryResult {
                kind,
                name: name.clone(),
                count: *count,
                mean: a.estimate(),
            })
            .collect();
        let configurational = self.configurational(analyzer);
        Ok(RunAnalysis {
            blocks: self.blocks,
            rows: energies.rows,
            frames: self.frames,
            rows_per_block: energies.potential.counts().to_vec(),
            frames_per_block,
            molecules: analyzer.topology.molecules,
            blocks_long_enough: blocks_long_enough(
                &energies.blocking,
                potential.error,
                potential.blocks,
            ),
            potential_per_molecule: potential,
            potential_block_means: energies.potential.block_means(),
            blocking: energies.blocking,
            row_interval: energies.row_interval,
            kinetic_temperature: energies.kinetic.estimate(),
            kinetic_block_means: energies.kinetic.block_means(),
            dof: energies.dof,
            configurational,
            rdf,
            geometry,
            basins: self.basins.finish(),
            terms: self.terms.results(self.blocks.count, &self.basins),
            source,
            pooled: None,
        })
    }

    fn configurational(&self, analyzer: &Analyzer) -> Option<ConfigurationalResult> {
        let probe = self.probe.as_ref()?;
        let k_b = analyzer.scene.units.boltzmann();
        let (numerator, denominator) = (
            self.gradient_squared.block_means(),
            self.laplacian.block_means(),
        );
        let mut temperature = ratio_of_means(&numerator, &denominator);
        temperature.mean /= k_b;
        temperature.error /= k_b;
        let (exact_terms, estimated_terms) = probe.term_names(analyzer.scene.system.forces.terms());
        Some(ConfigurationalResult {
            temperature,
            gradient_squared: self.gradient_squared.overall_mean()[0],
            laplacian: self.laplacian.overall_mean()[0],
            hutchinson_relative_error: self.hutchinson.overall_mean()[0],
            exact_terms,
            estimated_terms,
            probes: analyzer.options.probes,
            colours: probe.colours(),
            products_per_frame: probe.products_per_frame(),
            block_values: numerator
                .iter()
                .zip(&denominator)
                .map(|(n, d)| n / d / k_b)
                .collect(),
        })
    }
}

fn rdf_result(
    name: &str,
    grid: &RdfGrid,
    accumulator: &BlockAccumulator,
    options: &AnalysisOptions,
) -> RdfResult {
    let g = accumulator.overall_mean();
    let blocks = accumulator.counts().len();
    let block_g: Vec<Vec<f64>> = (0..blocks).map(|b| accumulator.block_mean(b)).collect();
    let g_error = (0..grid.bins)
        .map(|k| from_block_means(&block_g.iter().map(|g| g[k]).collect::<Vec<_>>()).error)
        .collect();
    let peak = first_peak(grid, &g, options.peak_window, options.peak_fit);
    let block_peaks: Option<Vec<Peak>> = block_g
        .iter()
        .map(|g| first_peak(grid, g, options.peak_window, options.peak_fit))
        .collect();
    let spread = |f: fn(&Peak) -> f64| {
        let peaks = block_peaks.as_ref()?;
        let values: Vec<f64> = peaks.iter().map(f).collect();
        let main = peak.as_ref().map(f)?;
        Some(Estimate {
            mean: main,
            ..from_block_means(&values)
        })
    };
    RdfResult {
        name: name.to_string(),
        r: (0..grid.bins).map(|k| grid.centre(k)).collect(),
        peak_position: spread(|p| p.position),
        peak_height: spread(|p| p.height),
        g,
        g_error,
        peak,
    }
}
