//! Sites: particles and anchors by index or name, lists, ranges and chains of them.

use std::collections::BTreeMap;

use super::particles::Start;
use super::{Builder, Reference, SceneFile};
use crate::error::Result;
use crate::forces::Site;
use crate::settings::Value;

/// A particle or anchor name resolved to a site.
pub(super) struct Names {
    pub sites: BTreeMap<String, Site>,
    pub n_particles: usize,
}

impl Builder<'_> {
    pub(super) fn site(
        &self,
        reference: &Reference,
        names: &Names,
        what: &str,
        offset: usize,
    ) -> Result<Site> {
        match reference {
            Reference::Index(i) if *i < names.n_particles => Ok(Site::Particle(*i)),
            Reference::Index(i) => Err(self.error_at(
                offset,
                format!(
                    "{what} names particle {i}, but the scene has {} particles (0 to {})",
                    names.n_particles,
                    names.n_particles.saturating_sub(1)
                ),
            )),
            Reference::Name(name) => names.sites.get(name).copied().ok_or_else(|| {
                self.error_at(
                    offset,
                    format!("{what} names \"{name}\", which is no particle or anchor"),
                )
            }),
        }
    }

    pub(super) fn particle(
        &self,
        reference: &Reference,
        names: &Names,
        what: &str,
        offset: usize,
    ) -> Result<usize> {
        match self.site(reference, names, what, offset)? {
            Site::Particle(i) => Ok(i),
            Site::Fixed(_) => Err(self.error_at(
                offset,
                format!("{what}: {reference} is an anchor, but a particle is needed here"),
            )),
        }
    }

    /// The sites of a chain-like term: `start`, then `particles` (or `range`, or every
    /// particle), then `end`; consecutive sites are linked.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn chain_sites(
        &self,
        particles: &Option<Vec<Reference>>,
        range: &Option<[Value; 2]>,
        start: &Option<Reference>,
        end: &Option<Reference>,
        names: &Names,
        parameters: &BTreeMap<String, f64>,
        what: &str,
        offset: usize,
    ) -> Result<Vec<Site>> {
        let members = match (particles, range) {
            (Some(_), Some(_)) => {
                return Err(self.error_at(
                    offset,
                    format!("{what} gives both particles and range; give one"),
                ));
            }
            (_, Some([first, last])) => {
                let index = |v: &Value, key: &str| -> Result<usize> {
                    let x =
                        self.evaluate(v, parameters, &format!("{what}: range {key}"), offset)?;
                    if x < 0.0 || x.fract() != 0.0 || x as usize >= names.n_particles {
                        return Err(self.error_at(
                            offset,
                            format!(
                                "{what}: range {key} = {x} is not a particle index (0 to {})",
                                names.n_particles.saturating_sub(1)
                            ),
                        ));
                    }
                    Ok(x as usize)
                };
                let (first, last) = (index(first, "first")?, index(last, "last")?);
                if last < first {
                    return Err(
                        self.error_at(offset, format!("{what}: range [{first}, {last}] is empty"))
                    );
                }
                (first..=last).collect()
            }
            (list, None) => self.particle_list(list, names, what, offset)?,
        };
        let mut sites = Vec::with_capacity(members.len() + 2);
        if let Some(reference) = start {
            sites.push(self.site(reference, names, what, offset)?);
        }
        sites.extend(members.into_iter().map(Site::Particle));
        if let Some(reference) = end {
            sites.push(self.site(reference, names, what, offset)?);
        }
        Ok(sites)
    }

    pub(super) fn particle_list(
        &self,
        list: &Option<Vec<Reference>>,
        names: &Names,
        what: &str,
        offset: usize,
    ) -> Result<Vec<usize>> {
        match list {
            None => Ok((0..names.n_particles).collect()),
            Some(list) => list
                .iter()
                .map(|r| self.particle(r, names, what, offset))
                .collect(),
        }
    }
}

impl Builder<'_> {
    /// The namespace of particle and anchor names (they share it). Atoms read from a
    /// structure file are named by type and may repeat, so only anchors name them.
    pub(super) fn names(
        &self,
        file: &SceneFile,
        start: &Start,
        dim: usize,
        parameters: &BTreeMap<String, f64>,
    ) -> Result<Names> {
        let mut sites = BTreeMap::new();
        // Atoms of a structure or topology repeat names (H1, …): they are no sites.
        if start.structure.is_none() && file.topology.is_none() {
            for (i, name) in start.names.iter().enumerate() {
                if sites.insert(name.clone(), Site::Particle(i)).is_some() {
                    return Err(self.error(format!("two particles are named \"{name}\"")));
                }
            }
        }
        for (name, coordinates) in &file.anchors {
            let position = self.vector(
                coordinates,
                dim,
                parameters,
                &format!("anchor \"{name}\""),
                0,
            )?;
            let mut fixed = [0.0; 3];
            fixed[..dim].copy_from_slice(&position);
            if sites.insert(name.clone(), Site::Fixed(fixed)).is_some() {
                return Err(self.error(format!(
                    "anchor \"{name}\" has the name of a particle; names must be unique"
                )));
            }
        }
        Ok(Names {
            sites,
            n_particles: start.masses.len(),
        })
    }
}
