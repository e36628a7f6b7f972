//! The force splitter: which term is sampled how often.
//!
//! Terms go to levels, level 0 innermost (fastest, evaluated most often). By default
//! bonded terms (springs, angles, FPU springs) are fast, level 0, and non-bonded terms
//! (pair potentials, gravity, external fields) slow, the outermost level — the split
//! r-RESPA was made for (GSS98 section 1). A scene can move any term (`group = "fast" |
//! "slow"`, or `level = n` for recursive r-RESPA). Every term lands on exactly one level,
//! so no term can be silently dropped (the failure of openmm#2716), and every run prints
//! the level table first, as LAMMPS does.
//!
//! The split also classifies particles as fast, mixed or slow (MEMM18 section 4.1) and
//! finds the connected components of the fast-force graph (the diagonal blocks of the
//! mollified methods' averaging Jacobian), and it counts force evaluations per level:
//! every accuracy-against-cost chart rests on those counts.

mod blocks;

pub use blocks::Blocks;

use crate::error::{Error, Result};
use crate::forces::{ForceTerm, TermClass};

/// Where a scene puts a term.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Assignment {
    /// Bonded → fast (level 0), non-bonded → slow (outermost level).
    Default,
    Fast,
    Slow,
    Level(usize),
}

/// The kinds of the terms that keep pair lists, which a checkpoint must save
/// ([`ForceTerm::list_state`]) or else rebuild ([`ForceSplit::rebuild_lists_without_state`]).
pub const LIST_KINDS: [&str; 3] = ["nonbonded", "nonbonded-short", "nonbonded-remainder"];

pub struct LabelledTerm {
    pub name: String,
    pub term: Box<dyn ForceTerm>,
    pub level: usize,
}

/// Force evaluations so far. One gradient evaluation of a level evaluates every term on
/// it once; empty levels are never counted.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ForceCounts {
    /// Gradient evaluations per level, innermost first.
    pub gradient: Vec<u64>,
    /// Hessian-vector products per level.
    pub hessian_vector: Vec<u64>,
    /// Elementary interactions evaluated (one spring, one pair, one angle), gradient and
    /// Hessian-vector products together.
    pub interactions: u64,
}

impl ForceCounts {
    pub fn hessian_vector_total(&self) -> u64 {
        self.hessian_vector.iter().sum()
    }
}

/// MEMM18 section 4.1: fast particles feel only fast forces, slow only slow forces,
/// mixed both. A particle no force touches moves freely and counts as slow.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParticleClass {
    Fast,
    Mixed,
    Slow,
}

/// Terms from any levels evaluated together ([`ForceSplit::term_set`]).
#[derive(Clone, Debug, Default)]
pub struct TermSet {
    terms: Vec<usize>,
    /// The distinct levels of `terms`, each counted once per evaluation.
    levels: Vec<usize>,
}

impl TermSet {
    pub fn is_empty(&self) -> bool {
        self.terms.is_empty()
    }
}

pub struct ForceSplit {
    terms: Vec<LabelledTerm>,
    /// Term indices per level.
    levels: Vec<Vec<usize>>,
    counts: ForceCounts,
}

impl ForceSplit {
    /// Place every term on a level. There are at least two levels (fast and slow, either
    /// possibly empty); more when a term asks for `level ≥ 2`.
    pub fn new(terms: Vec<(String, Box<dyn ForceTerm>, Assignment)>) -> Result<Self> {
        let highest_explicit = terms
            .iter()
            .filter_map(|(_, _, assignment)| match assignment {
                Assignment::Level(level) => Some(*level),
                _ => None,
            })
            .max()
            .unwrap_or(0);
        let n_levels = (highest_explicit + 1).max(2);
        let mut levels = vec![Vec::new(); n_levels];
        let mut labelled = Vec::with_capacity(terms.len());
        for (index, (name, term, assignment)) in terms.into_iter().enumerate() {
            let level = match assignment {
                Assignment::Fast => 0,
                Assignment::Slow => n_levels - 1,
                Assignment::Level(level) => level,
                Assignment::Default => match term.class() {
                    TermClass::Bonded => 0,
                    TermClass::Nonbonded => n_levels - 1,
                },
            };
            levels[level].push(index);
            labelled.push(LabelledTerm { name, term, level });
        }
        for (level, members) in levels.iter().enumerate().skip(1) {
            if members.is_empty() && level + 1 < n_levels {
                return Err(Error::input(format!(
                    "force level {level} has no terms, but level {} does: levels must be \
                     filled from 0 up (recursive r-RESPA nests every level inside the next)",
                    n_levels - 1
                )));
            }
        }
        Ok(ForceSplit {
            terms: labelled,
            counts: ForceCounts {
                gradient: vec![0; n_levels],
                hessian_vector: vec![0; n_levels],
                interactions: 0,
            },
            levels,
        })
    }

    pub fn n_levels(&self) -> usize {
        self.levels.len()
    }

    pub fn terms(&self) -> &[LabelledTerm] {
        &self.terms
    }

    /// The first term of concrete type `T` (for benchmarks, profiles and tests that reach
    /// into the non-bonded engine), through [`ForceTerm::as_any`].
    pub fn find<T: 'static>(&self) -> Option<&T> {
        self.terms
            .iter()
            .find_map(|t| t.term.as_any().and_then(|a| a.downcast_ref::<T>()))
    }

    /// Every term computes in `precision` where it has that choice; how many terms took it.
    pub fn set_precision(&self, precision: crate::forces::Precision) -> usize {
        self.terms
            .iter()
            .filter(|t| t.term.set_precision(precision))
            .count()
    }

    pub fn level_is_empty(&self, level: usize) -> bool {
        self.levels[level].is_empty()
    }

    /// `"fast"` for level 0, `"slow"` for the outermost, `"level k"` between.
    pub fn level_name(&self, level: usize) -> String {
        if level == 0 {
            "fast".into()
        } else if level + 1 == self.n_levels() {
            "slow".into()
        } else {
            format!("level {level}")
        }
    }

    /// Energy of one level (a monitor: not counted as a force evaluation).
    pub fn energy(&self, level: usize, q: &[f64]) -> f64 {
        self.levels[level]
            .iter()
            .map(|&t| self.terms[t].term.energy(q))
            .sum()
    }

    /// Energy of every level together (not counted).
    pub fn total_energy(&self, q: &[f64]) -> f64 {
        self.terms.iter().map(|t| t.term.energy(q)).sum()
    }

    /// `gradient = ∇V_level(q)`.
    pub fn gradient(&mut self, level: usize, q: &[f64], gradient: &mut [f64]) {
        gradient.fill(0.0);
        self.add_gradient(level, q, gradient);
    }

    /// `gradient += ∇V_level(q)`.
    pub fn add_gradient(&mut self, level: usize, q: &[f64], gradient: &mut [f64]) {
        let members = &self.levels[level];
        if members.is_empty() {
            return;
        }
        for &t in members {
            let term = &self.terms[t].term;
            term.add_gradient(q, gradient);
            self.counts.interactions += term.interaction_count() as u64;
        }
        self.counts.gradient[level] += 1;
    }

    /// A fixed selection of terms (indices into [`ForceSplit::terms`]) from any levels, for
    /// [`ForceSplit::add_set_gradient`].
    pub fn term_set(&self, terms: &[usize]) -> TermSet {
        let mut levels: Vec<usize> = terms.iter().map(|&t| self.terms[t].level).collect();
        levels.sort_unstable();
        levels.dedup();
        TermSet {
            terms: terms.to_vec(),
            levels,
        }
    }

    /// `gradient += ∇V_set(q)`: one evaluation of every level the set draws from, and its
    /// terms' interactions. The asynchronous pseudo-energy scheme's fine grid (MEMM18 (20)–(22):
    /// the fast level and the slow terms touching mixed particles) is one set, evaluated
    /// without a per-level loop — on a small chain that loop cost as much as the terms.
    pub fn add_set_gradient(&mut self, set: &TermSet, q: &[f64], gradient: &mut [f64]) {
        for &t in &set.terms {
            let term = &self.terms[t].term;
            term.add_gradient(q, gradient);
            self.counts.interactions += term.interaction_count() as u64;
        }
        for &level in &set.levels {
            self.counts.gradient[level] += 1;
        }
    }

    /// Indices (into [`ForceSplit::terms`]) of the terms on `level`.
    pub fn level_terms(&self, level: usize) -> &[usize] {
        &self.levels[level]
    }

    /// `gradient = ∇V(q)` over all levels (one evaluation of each non-empty level).
    pub fn total_gradient(&mut self, q: &[f64], gradient: &mut [f64]) {
        gradient.fill(0.0);
        for level in 0..self.n_levels() {
            self.add_gradient(level, q, gradient);
        }
    }

    /// `out = ∇²V_level(q) · v`.
    pub fn hessian_vector(&mut self, level: usize, q: &[f64], v: &[f64], out: &mut [f64]) {
        out.fill(0.0);
        let members = &self.levels[level];
        if members.is_empty() {
            return;
        }
        for &t in members {
            let term = &self.terms[t].term;
            term.add_hessian_vector(q, v, out);
            self.counts.interactions += term.interaction_count() as u64;
        }
        self.counts.hessian_vector[level] += 1;
    }

    pub fn counts(&self) -> &ForceCounts {
        &self.counts
    }

    /// Forget every term's pair lists and cached results ([`ForceTerm::rebuild_lists`]).
    pub fn rebuild_lists(&self) {
        for term in &self.terms {
            term.term.rebuild_lists();
        }
    }

    /// Every term's [`ForceTerm::list_state`], in term order: what a checkpoint holds so
    /// that a continued run sums over the same pairs in the same order. Allocates (the
    /// states): for checkpoints only.
    pub fn list_states(&self) -> Vec<Option<serde_json::Value>> {
        self.terms.iter().map(|t| t.term.list_state()).collect()
    }

    /// Give each term its state from [`ForceSplit::list_states`] of the run that wrote a
    /// checkpoint ([`ForceTerm::restore_lists`]); a term without one (no lists, or a term
    /// rebuilt at the checkpoint, [`ForceSplit::rebuild_lists_without_state`]) builds its
    /// lists at its next evaluation, as a fresh term does. An error names the term.
    pub fn restore_lists(&self, states: &[Option<serde_json::Value>]) -> Result<()> {
        if states.len() != self.terms.len() {
            return Err(Error::input(format!(
                "pair-list states of {} force terms, this model has {}",
                states.len(),
                self.terms.len()
            )));
        }
        for (k, (term, state)) in self.terms.iter().zip(states).enumerate() {
            if let Some(state) = state {
                term.term
                    .restore_lists(state)
                    .map_err(|e| Error::input(format!("force term {k} ({:?}): {e}", term.name)))?;
            }
        }
        Ok(())
    }

    /// The fallback for a term that keeps pair lists but cannot save them
    /// ([`LIST_KINDS`] with no [`ForceTerm::list_state`]): rebuild its lists, as a
    /// continued run builds them afresh. `states` are [`ForceSplit::list_states`]. Whether
    /// any term was rebuilt: then cached forces must be recomputed too.
    pub fn rebuild_lists_without_state(&self, states: &[Option<serde_json::Value>]) -> bool {
        let mut rebuilt = false;
        for (term, state) in self.terms.iter().zip(states) {
            if state.is_none() && LIST_KINDS.contains(&term.term.kind()) {
                term.term.rebuild_lists();
                rebuilt = true;
            }
        }
        rebuilt
    }

    pub fn reset_counts(&mut self) {
        let n = self.n_levels();
        self.counts = ForceCounts {
            gradient: vec![0; n],
            hessian_vector: vec![0; n],
            interactions: 0,
        };
    }

    /// The level table every run prints first, e.g.
    /// `levels: 0 (fast) = spring "left", spring "right" | 1 (slow) = spring "middle"`.
    pub fn level_table(&self) -> String {
        let levels: Vec<String> = self
            .levels
            .iter()
            .enumerate()
            .map(|(level, members)| {
                let body = if members.is_empty() {
                    "(empty)".to_string()
                } else {
                    members
                        .iter()
                        .map(|&t| {
                            let term = &self.terms[t];
                            let count = term.term.interaction_count();
                            let plural = if count == 1 { "" } else { "s" };
                            format!(
                                "{} \"{}\" ({count} interaction{plural})",
                                term.term.kind(),
                                term.name
                            )
                        })
                        .collect::<Vec<_>>()
                        .join(", ")
                };
                format!("{level} ({}) = {body}", self.level_name(level))
            })
            .collect();
        format!("levels: {}", levels.join(" | "))
    }

    /// Fast, mixed or slow for each of `n_particles` (MEMM18 section 4.1); level 0 is
    /// fast, every other level slow.
    pub fn classify_particles(&self, n_particles: usize) -> Vec<ParticleClass> {
        let mut feels_fast = vec![false; n_particles];
        let mut feels_slow = vec![false; n_particles];
        for labelled in &self.terms {
            let touched = if labelled.level == 0 {
                &mut feels_fast
            } else {
                &mut feels_slow
            };
            for coupling in labelled.term.couplings() {
                for i in coupling {
                    touched[i] = true;
                }
            }
        }
        (0..n_particles)
            .map(|i| match (feels_fast[i], feels_slow[i]) {
                (true, true) => ParticleClass::Mixed,
                (true, false) => ParticleClass::Fast,
                (false, _) => ParticleClass::Slow,
            })
            .collect()
    }

    /// Connected components of the graph whose edges are the level-0 interactions, each
    /// a sorted particle list, in order of their smallest particle. A particle no fast
    /// force touches is a component of its own.
    pub fn fast_components(&self, n_particles: usize) -> Vec<Vec<usize>> {
        let mut components = crate::forces::components::Components::new(n_particles);
        for &t in &self.levels[0] {
            for coupling in self.terms[t].term.couplings() {
                for pair in coupling.windows(2) {
                    components.join(pair[0], pair[1]);
                }
            }
        }
        components.groups(0..n_particles)
    }
}
