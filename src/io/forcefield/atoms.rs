//! The atoms section of the force field: element, mass and charge per atom, and the
//! Lennard-Jones parameters per atom type.

use super::{AtomSpec, FfAtom, ForcefieldInput, ForcefieldSpec, LJ_TABLE};

/// Every atom's resolved parameters, and the atom types in order of appearance.
pub(super) struct AtomTable {
    /// Element symbol per atom (after `[forcefield.atoms] element` overrides).
    pub elements: Vec<String>,
    /// Per-atom masses in the scene's unit.
    pub masses: Vec<f64>,
    pub charges: Vec<f64>,
    /// Distinct type names in order of appearance.
    pub kinds: Vec<String>,
    /// The type index of each atom.
    pub kind_of: Vec<u32>,
    /// The first atom of each type.
    pub first_of_kind: Vec<usize>,
    /// (ε, σ) per type.
    pub lj_params: Vec<(f64, f64)>,
}

/// The `[forcefield.atoms]` entries for an atom: by its type name, by its element.
fn atom_spec<'a>(
    spec: &'a ForcefieldSpec,
    atom: &FfAtom,
) -> (Option<&'a AtomSpec>, Option<&'a AtomSpec>) {
    (
        spec.atoms.get(&atom.type_name),
        spec.atoms.get(&atom.element),
    )
}

/// Resolve every atom's element, mass, charge and its type's Lennard-Jones parameters;
/// one report line per type.
pub(super) fn resolve(
    input: &ForcefieldInput,
    report: &mut Vec<String>,
) -> Result<AtomTable, String> {
    check_keys(input)?;
    let (elements, masses, type_charges) = per_atom(input)?;
    let charges = charges(input.spec, type_charges, input.atoms.len())?;
    let (kinds, kind_of, first_of_kind) = kinds(input.atoms);
    let mut table = AtomTable {
        elements,
        masses,
        charges,
        kinds,
        kind_of,
        first_of_kind,
        lj_params: Vec::new(),
    };
    table.lj_params = lennard_jones_per_type(input, &table, report)?;
    Ok(table)
}

/// Every `[forcefield.atoms]` key names a type or an element of the structure.
fn check_keys(input: &ForcefieldInput) -> Result<(), String> {
    for key in input.spec.atoms.keys() {
        if !input
            .atoms
            .iter()
            .any(|a| &a.type_name == key || &a.element == key)
        {
            return Err(format!(
                "[forcefield.atoms] has \"{key}\", but no atom of the structure has that type \
                 or element"
            ));
        }
    }
    Ok(())
}

/// Element, mass and per-type charge of each atom.
#[allow(clippy::type_complexity)]
fn per_atom(input: &ForcefieldInput) -> Result<(Vec<String>, Vec<f64>, Vec<f64>), String> {
    let n = input.atoms.len();
    let mut elements = Vec::with_capacity(n);
    let mut masses = Vec::with_capacity(n);
    let mut type_charges = Vec::with_capacity(n);
    for (i, atom) in input.atoms.iter().enumerate() {
        let (by_type, by_element) = atom_spec(input.spec, atom);
        let element = by_type
            .and_then(|s| s.element.clone())
            .unwrap_or_else(|| atom.element.clone());
        let mass = by_type
            .and_then(|s| s.mass)
            .or_else(|| by_element.and_then(|s| s.mass));
        let mass = match mass {
            Some(m) if m > 0.0 && m.is_finite() => m,
            Some(m) => {
                return Err(format!(
                    "atom {i} ({}): mass {m} must be positive",
                    atom.type_name
                ));
            }
            None if atom.element_mass > 0.0 => atom.element_mass,
            None => {
                return Err(format!(
                    "atom {i} has type \"{}\", which is no element: give its element or mass in \
                     [forcefield.atoms] \"{}\"",
                    atom.type_name, atom.type_name
                ));
            }
        };
        let charge = by_type
            .and_then(|s| s.charge)
            .or_else(|| by_element.and_then(|s| s.charge))
            .unwrap_or(0.0);
        elements.push(element);
        masses.push(mass);
        type_charges.push(charge);
    }
    Ok((elements, masses, type_charges))
}

/// The per-atom `charges` list when given, else the per-type charges.
fn charges(spec: &ForcefieldSpec, type_charges: Vec<f64>, n: usize) -> Result<Vec<f64>, String> {
    let charges = match &spec.charges {
        Some(list) => {
            if list.len() != n {
                return Err(format!(
                    "[forcefield] charges lists {} charges for {n} atoms",
                    list.len()
                ));
            }
            list.clone()
        }
        None => type_charges,
    };
    if let Some(bad) = charges.iter().position(|c| !c.is_finite()) {
        return Err(format!("atom {bad} has a non-finite charge"));
    }
    Ok(charges)
}

/// Atom kinds for reports and LJ types: distinct type names in order of appearance, the
/// kind of each atom and the first atom of each kind.
fn kinds(atoms: &[FfAtom]) -> (Vec<String>, Vec<u32>, Vec<usize>) {
    let mut kinds: Vec<String> = Vec::new();
    let mut kind_of = vec![0u32; atoms.len()];
    for (i, atom) in atoms.iter().enumerate() {
        let index = match kinds.iter().position(|k| k == &atom.type_name) {
            Some(index) => index,
            None => {
                kinds.push(atom.type_name.clone());
                kinds.len() - 1
            }
        };
        kind_of[i] = index as u32;
    }
    let first_of_kind: Vec<usize> = (0..kinds.len())
        .map(|k| kind_of.iter().position(|&x| x as usize == k).unwrap_or(0))
        .collect();
    (kinds, kind_of, first_of_kind)
}

/// (ε, σ) of each atom type: given in the scene, or from the built-in table by element.
fn lennard_jones_per_type(
    input: &ForcefieldInput,
    table: &AtomTable,
    report: &mut Vec<String>,
) -> Result<Vec<(f64, f64)>, String> {
    let mut lj_params = Vec::with_capacity(table.kinds.len());
    for (k, name) in table.kinds.iter().enumerate() {
        let i = table.first_of_kind[k];
        let (by_type, by_element) = atom_spec(input.spec, &input.atoms[i]);
        let element = &table.elements[i];
        let given = |f: fn(&AtomSpec) -> Option<f64>| {
            by_type.and_then(f).or_else(|| by_element.and_then(f))
        };
        let builtin = LJ_TABLE.iter().find(|(e, _, _)| e == element);
        let (epsilon, sigma, from) = match (given(|s| s.epsilon), given(|s| s.sigma), builtin) {
            (Some(e), Some(s), _) => (e, s, "scene"),
            (None, None, Some(&(_, e, s))) => (e, s, "built-in table (AMBER parm99)"),
            (Some(_), None, _) | (None, Some(_), _) => {
                return Err(format!(
                    "[forcefield.atoms] \"{name}\" gives only one of epsilon and sigma; give both"
                ));
            }
            (None, None, None) => {
                return Err(format!(
                    "no Lennard-Jones parameters for atom type \"{name}\" (element \"{element}\", \
                     first at atom {i}): give epsilon and sigma in [forcefield.atoms] \"{name}\""
                ));
            }
        };
        if !(epsilon >= 0.0 && sigma > 0.0) {
            return Err(format!(
                "atom type \"{name}\": epsilon must be ≥ 0 and sigma > 0, got {epsilon} and {sigma}"
            ));
        }
        let count = table.kind_of.iter().filter(|&&x| x as usize == k).count();
        let line = format!("atom {name} ×{count}: element {element}, ");
        let lj = (epsilon, sigma, from);
        report.push(line + &type_report(input.spec, table, i, (by_type, by_element), lj));
        lj_params.push((epsilon, sigma));
    }
    Ok(lj_params)
}

/// The rest of an atom type's report line: mass, charge and LJ with their sources.
fn type_report(
    spec: &ForcefieldSpec,
    table: &AtomTable,
    i: usize,
    (by_type, by_element): (Option<&AtomSpec>, Option<&AtomSpec>),
    (epsilon, sigma, from): (f64, f64, &str),
) -> String {
    let given = |f: fn(&AtomSpec) -> Option<f64>| by_type.and_then(f).or(by_element.and_then(f));
    format!(
        "mass {} ({}), charge {} ({}), LJ ε = {epsilon}, σ = {sigma} ({from})",
        table.masses[i],
        if given(|s| s.mass).is_some() {
            "scene"
        } else {
            "element"
        },
        table.charges[i],
        if spec.charges.is_some() {
            "per-atom list"
        } else if given(|s| s.charge).is_some() {
            "scene"
        } else {
            "default 0"
        },
    )
}
