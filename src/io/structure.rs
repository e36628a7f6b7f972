//! Structure files (XYZ, PDB, extended XYZ, … — whatever chemfiles reads).

use std::path::Path;
use std::sync::Mutex;

use crate::error::{Error, Result};

#[derive(Clone, Debug)]
pub struct Atom {
    /// The atom's name as written in the file (usually its element symbol).
    pub name: String,
    /// Mass from the element table; 0 when chemfiles does not know the element.
    pub mass: f64,
    /// The element (chemfiles' atomic type: the name, or the element a PDB names).
    pub element: String,
    pub position: [f64; 3],
}

#[derive(Clone, Debug)]
pub struct Structure {
    pub atoms: Vec<Atom>,
    /// Orthorhombic cell lengths, when the file gives a cell.
    pub cell: Option<[f64; 3]>,
    /// Bonds the file lists (none for plain XYZ).
    pub bonds: Vec<[usize; 2]>,
    /// Velocities the file carries (extended XYZ `velo:R:3`, as `run
    /// --trajectory-velocities` writes them), one per atom, checked finite.
    pub velocities: Option<Vec<[f64; 3]>>,
}

/// Chemfiles warnings of the current read, attached to the error when the read fails.
static WARNINGS: Mutex<Vec<String>> = Mutex::new(Vec::new());

fn collect_warnings() {
    static INSTALL: std::sync::Once = std::sync::Once::new();
    INSTALL.call_once(|| {
        chemfiles::set_warning_callback(|message: &str| {
            if let Ok(mut warnings) = WARNINGS.lock() {
                warnings.push(message.to_string());
            }
        });
    });
    if let Ok(mut warnings) = WARNINGS.lock() {
        warnings.clear();
    }
}

fn structure_error(path: &Path, message: String) -> Error {
    // Chemfiles often also sends the error text as a warning: keep only new information.
    let warnings = WARNINGS
        .lock()
        .map(|w| {
            w.iter()
                .filter(|warning| !message.contains(warning.as_str()))
                .cloned()
                .collect::<Vec<_>>()
                .join("; ")
        })
        .unwrap_or_default();
    let message = if warnings.is_empty() {
        message
    } else {
        format!("{message} ({warnings})")
    };
    Error::Structure {
        path: path.to_path_buf(),
        message,
    }
}

/// Extensions of the text formats chemfiles reads.
const TEXT_FORMATS: [&str; 16] = [
    "xyz",
    "extxyz",
    "pdb",
    "ent",
    "gro",
    "mol2",
    "sdf",
    "sd",
    "cml",
    "cif",
    "mmcif",
    "arc",
    "cssr",
    "smi",
    "lammpstrj",
    "molden",
];

/// A text structure file must be UTF-8 before chemfiles sees it: chemfiles turns the bytes
/// of names and messages into Rust strings and panics (or, inside its warning callback,
/// aborts) on anything else. The error names the line and the byte.
fn check_text(path: &Path) -> Result<()> {
    use std::io::BufRead;
    let extension = path
        .extension()
        .map(|e| e.to_string_lossy().to_lowercase())
        .unwrap_or_default();
    if !TEXT_FORMATS.contains(&extension.as_str()) {
        return Ok(());
    }
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut reader = std::io::BufReader::new(file);
    let mut line = Vec::new();
    for number in 1.. {
        line.clear();
        if reader
            .read_until(b'\n', &mut line)
            .map_err(|e| Error::io(path, e))?
            == 0
        {
            return Ok(());
        }
        if let Err(e) = std::str::from_utf8(&line) {
            let at = e.valid_up_to();
            return Err(Error::scene(
                path,
                format!(
                    "byte 0x{:02X} (column {}) is not UTF-8 text; a structure file must be \
                     plain text (ASCII or UTF-8)",
                    line[at],
                    at + 1
                ),
            )
            .line(number));
        }
    }
    Ok(())
}

/// An XYZ file's first line counts the atom lines of the frame after the comment line;
/// chemfiles trusts it, so a count smaller than the atom lines drops atoms (read as a
/// broken next frame) and a larger one reads past them. Check the first frame: exactly
/// `count` atom lines, then the end of the file, blank lines or the next frame's count.
fn check_xyz_count(path: &Path) -> Result<()> {
    let extension = path
        .extension()
        .map(|e| e.to_string_lossy().to_lowercase())
        .unwrap_or_default();
    if extension != "xyz" && extension != "extxyz" {
        return Ok(());
    }
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let lines: Vec<&str> = text.lines().collect();
    let Some(Ok(count)) = lines.first().map(|l| l.trim().parse::<usize>()) else {
        return Ok(()); // chemfiles names a count line that is no number
    };
    let at = |line: usize, message: String| Error::scene(path, message).line(line);
    let atom_lines = lines.iter().skip(2).take(count);
    if let Some(blank) = atom_lines.clone().position(|l| l.trim().is_empty()) {
        return Err(at(
            blank + 3,
            format!(
                "line 1 counts {count} atoms, but the frame has {blank} atom lines before this \
                 blank line: make the count the number of atom lines"
            ),
        ));
    }
    let present = atom_lines.count();
    if present < count {
        return Err(at(
            1,
            format!(
                "this count line says {count} atoms, but the file has {present} atom lines \
                 after the comment line: make the count the number of atom lines"
            ),
        ));
    }
    match lines.get(count + 2).map(|l| l.trim()) {
        Some(next) if !next.is_empty() && next.parse::<usize>().is_err() => Err(at(
            count + 3,
            format!(
                "line 1 counts {count} atoms, but this line (after the {count}th atom line) is \
                 another atom line, not the next frame's count: make the count the number of \
                 atom lines"
            ),
        )),
        _ => Ok(()),
    }
}

/// chemfiles guesses bonds from van der Waals radii, which only elements have: name the
/// first atom without one, and the two ways on.
fn check_radii(path: &Path, frame: &chemfiles::Frame) -> Result<()> {
    let Some(i) = (0..frame.size()).find(|&i| frame.atom(i).vdw_radius() <= 0.0) else {
        return Ok(());
    };
    let xyz = path
        .extension()
        .is_some_and(|e| ["xyz", "extxyz"].contains(&e.to_string_lossy().to_lowercase().as_str()));
    // In an XYZ file, atom i is on line i + 3 (after the count and the comment).
    let line = if xyz {
        format!(", line {}", i + 3)
    } else {
        String::new()
    };
    Err(structure_error(
        path,
        format!(
            "atom {i} (\"{}\"{line}) is no known element, so bonds cannot be guessed (chemfiles \
             needs the elements' van der Waals radii): write its element symbol, or list the \
             bonds in the scene's [structure] section (`bonds = [[0, 1], …]` and \
             `guess_bonds = false`)",
            frame.atom(i).name()
        ),
    ))
}

/// Read the first frame of a structure file.
pub fn read_structure(path: &Path) -> Result<Structure> {
    read_structure_with(path, false)
}

/// Read the first frame; with `guess_bonds`, bonds are perceived by chemfiles (its VMD
/// criterion: `0.03 Å < d < 0.6 (R_a + R_b)` with van der Waals radii, minimum image in a
/// cell) when the file lists none.
/// Largest |coordinate| a structure may hold (Å): a molecule or box further out than a
/// metre's ten-thousandth is a typo, and bond guessing and cell lists fail silently there.
pub const MAX_COORDINATE: f64 = 1e6;

/// Every coordinate finite and within ±[`MAX_COORDINATE`].
fn check_coordinates(path: &Path, frame: &chemfiles::Frame) -> Result<()> {
    for (i, position) in frame.positions().iter().enumerate() {
        if position.iter().any(|x| !x.is_finite()) {
            return Err(structure_error(
                path,
                format!("atom {i} has a non-finite coordinate {position:?}"),
            ));
        }
        if position.iter().any(|x| x.abs() > MAX_COORDINATE) {
            return Err(structure_error(
                path,
                format!(
                    "atom {i} has a coordinate beyond ±{MAX_COORDINATE:e} Å: {position:?} \
                     (a typo in the file?)"
                ),
            ));
        }
    }
    Ok(())
}

/// The frame's velocities: chemfiles' own (formats that carry them), else the extended XYZ
/// `velo:R:3` columns (an atom property there), which every atom must have.
fn velocities(path: &Path, frame: &chemfiles::Frame) -> Result<Option<Vec<[f64; 3]>>> {
    if let Some(v) = frame.velocities() {
        return Ok(Some(v.to_vec()));
    }
    let velocity = |i: usize| match frame.atom(i).get("velo") {
        Some(chemfiles::Property::Vector3D(v)) => Some(v),
        _ => None,
    };
    if frame.size() == 0 || velocity(0).is_none() {
        return Ok(None);
    }
    (0..frame.size())
        .map(|i| {
            velocity(i).ok_or_else(|| {
                structure_error(
                    path,
                    format!("atom {i} has no velocity (velo), but atom 0 has one"),
                )
            })
        })
        .collect::<Result<Vec<_>>>()
        .map(Some)
}

pub fn read_structure_with(path: &Path, guess_bonds: bool) -> Result<Structure> {
    if !path.exists() {
        return Err(Error::Structure {
            path: path.to_path_buf(),
            message: "no such file".into(),
        });
    }
    check_text(path)?;
    check_xyz_count(path)?;
    collect_warnings();
    let mut trajectory = chemfiles::Trajectory::open(path, 'r')
        .map_err(|e| structure_error(path, format!("cannot open: {}", e.message)))?;
    let mut frame = chemfiles::Frame::new();
    trajectory.read(&mut frame).map_err(|e| {
        structure_error(path, format!("cannot read the first frame: {}", e.message))
    })?;
    check_coordinates(path, &frame)?;
    if guess_bonds
        && frame.topology().bonds_count() == 0
        && let Err(e) = frame.guess_bonds()
    {
        check_radii(path, &frame)?;
        return Err(structure_error(
            path,
            format!("cannot guess bonds: {}", e.message),
        ));
    }
    let positions = frame.positions();
    let mut atoms = Vec::with_capacity(frame.size());
    for (i, position) in positions.iter().enumerate() {
        let atom = frame.atom(i);
        atoms.push(Atom {
            name: atom.name(),
            mass: atom.mass(),
            element: atom.atomic_type(),
            position: *position,
        });
    }
    let cell = frame.cell();
    let cell = match cell.shape() {
        chemfiles::CellShape::Infinite => None,
        chemfiles::CellShape::Orthorhombic => Some(cell.lengths()),
        chemfiles::CellShape::Triclinic => {
            return Err(structure_error(
                path,
                "triclinic cells are not supported; longstep handles orthorhombic boxes".into(),
            ));
        }
    };
    let bonds = frame.topology().bonds();
    let velocities = velocities(path, &frame)?;
    if let Some(v) = &velocities
        && let Some(i) = v.iter().position(|v| v.iter().any(|x| !x.is_finite()))
    {
        return Err(structure_error(
            path,
            format!("atom {i} has a non-finite velocity {:?}", v[i]),
        ));
    }
    Ok(Structure {
        atoms,
        cell,
        bonds,
        velocities,
    })
}
