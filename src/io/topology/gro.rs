//! GROMACS `.gro` coordinates: a title line, the atom count, one fixed-column line per
//! atom (residue number and name, atom name, atom number in four 5-wide columns, then x,
//! y, z and optionally vx, vy, vz, each as wide as the distance between the decimal points
//! of the first line, 8 in GROMACS's default `%8.3f`), and the box line (`v1(x) v2(y)
//! v3(z)`, then the off-diagonal `v1(y) v1(z) v2(x) v2(z) v3(x) v3(y)` of a triclinic box).
//! nm → Å, nm/ps → Å/fs. A box of zero edges is no box (a molecule in vacuum).

use std::path::Path;

use super::Topology;
use super::inpcrd::Coordinates;
use crate::error::{Error, Result};

/// Å/fs per nm/ps.
const VELOCITY: f64 = 10.0 / 1000.0;

fn error(path: &Path, line: usize, message: impl Into<String>) -> Error {
    Error::topology(path, message).line(line)
}

/// A `.gro` file: its coordinates and atom names.
pub fn read_gro(path: &Path) -> Result<(Coordinates, Vec<String>)> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    parse_gro(&text, path)
}

/// [`read_gro`], checked against `topology`: the same count and, atom by atom, the same
/// names.
pub fn read_gro_for(path: &Path, topology: &Topology) -> Result<Coordinates> {
    let (coordinates, names) = read_gro(path)?;
    if names.len() != topology.atoms.len() {
        return Err(error(
            path,
            2,
            format!(
                "has {} atoms, the topology {} has {}",
                names.len(),
                topology.source.display(),
                topology.atoms.len()
            ),
        ));
    }
    for (k, (name, atom)) in names.iter().zip(&topology.atoms).enumerate() {
        if *name != atom.name {
            return Err(error(
                path,
                k + 3,
                format!(
                    "atom {} is named {name}, the topology's atom {} is {}",
                    k + 1,
                    k + 1,
                    atom.name
                ),
            ));
        }
    }
    Ok(coordinates)
}

pub fn parse_gro(text: &str, path: &Path) -> Result<(Coordinates, Vec<String>)> {
    let lines: Vec<&str> = text.lines().collect();
    let n: usize = lines
        .get(1)
        .and_then(|l| l.trim().parse().ok())
        .ok_or_else(|| error(path, 2, "expected the number of atoms"))?;
    if lines.len() < n + 3 {
        return Err(error(
            path,
            lines.len(),
            format!(
                "{n} atoms and a box line announced, the file ends after {} lines",
                lines.len()
            ),
        ));
    }
    let width = column_width(lines.get(2).copied().unwrap_or(""))
        .ok_or_else(|| error(path, 3, "no coordinates in fixed columns"))?;
    let mut positions = Vec::with_capacity(3 * n);
    let mut velocities = Vec::with_capacity(3 * n);
    let mut names = Vec::with_capacity(n);
    for (k, line) in lines[2..2 + n].iter().enumerate() {
        let at = k + 3;
        let name = line
            .get(10..15)
            .ok_or_else(|| error(path, at, "line too short for an atom"))?;
        names.push(name.trim().to_string());
        let field = |c: usize| -> Result<Option<f64>> {
            let start = 20 + c * width;
            match line.get(start..(start + width).min(line.len())) {
                None | Some("") => Ok(None),
                Some(s) if s.trim().is_empty() => Ok(None),
                Some(s) => number(s.trim(), path, at).map(Some),
            }
        };
        for c in 0..3 {
            let x = field(c)?.ok_or_else(|| error(path, at, "missing a coordinate"))?;
            positions.push(x * 10.0);
        }
        for c in 3..6 {
            if let Some(v) = field(c)? {
                velocities.push(v * VELOCITY);
            }
        }
    }
    if !velocities.is_empty() && velocities.len() != 3 * n {
        return Err(error(path, 3, "velocities on some atom lines but not all"));
    }
    let box_text = lines[2 + n];
    let (box_lengths, box_angles) = match box_line(box_text, path, n + 3) {
        Err(_) if reads_as_atom(box_text, width) => {
            return Err(error(
                path,
                2,
                format!(
                    "the count says {n} atoms, but line {} after them reads as an atom line, \
                     not the box line: is the count one short?",
                    n + 3
                ),
            )
            .key("atom count")
            .got(n.to_string()));
        }
        other => other?,
    };
    let coordinates = Coordinates {
        title: lines[0].trim().to_string(),
        positions,
        velocities: (!velocities.is_empty()).then_some(velocities),
        box_lengths,
        box_angles,
    };
    Ok((coordinates, names))
}

/// A coordinate or velocity: a finite number (Rust reads `nan` and `inf` as numbers).
fn number(text: &str, path: &Path, at: usize) -> Result<f64> {
    match text.parse::<f64>() {
        Ok(value) if value.is_finite() => Ok(value),
        Ok(_) => Err(error(path, at, "a coordinate that is not a finite number").got(text)),
        Err(_) => Err(error(path, at, "a coordinate that is not a number").got(text)),
    }
}

/// Whether `line` has an atom line's three coordinates in columns `width` wide.
fn reads_as_atom(line: &str, width: usize) -> bool {
    (0..3).all(|c| {
        let start = 20 + c * width;
        line.get(start..start + width)
            .is_some_and(|s| s.trim().parse::<f64>().is_ok())
    })
}

/// The width of a coordinate column: the distance between the first two decimal points
/// after column 20.
fn column_width(line: &str) -> Option<usize> {
    let tail = line.get(20..)?;
    let mut dots = tail
        .char_indices()
        .filter(|(_, c)| *c == '.')
        .map(|(k, _)| k);
    let first = dots.next()?;
    let second = dots.next()?;
    Some(second - first)
}

type BoxLine = (Option<[f64; 3]>, Option<[f64; 3]>);

fn box_line(line: &str, path: &Path, at: usize) -> Result<BoxLine> {
    let values: Vec<f64> = line
        .split_whitespace()
        .map(|v| v.parse())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| error(path, at, "box line: not numbers"))?;
    if values.len() != 3 && values.len() != 9 {
        return Err(error(path, at, "box line: expected 3 or 9 numbers"));
    }
    if values[3..].iter().any(|v| *v != 0.0) {
        return Err(error(
            path,
            at,
            "a triclinic box: longstep models orthorhombic boxes only",
        ));
    }
    if values[..3].iter().all(|v| *v == 0.0) {
        return Ok((None, None));
    }
    let lengths = [values[0] * 10.0, values[1] * 10.0, values[2] * 10.0];
    Ok((Some(lengths), Some([90.0; 3])))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_positions_velocities_and_box() {
        let text = "t\n 1\n    1SOL     OW    1   0.126   1.624   1.679  0.1227 -0.0580  0.0434\n   1.0 2.0 3.0\n";
        let (c, names) = parse_gro(text, Path::new("x.gro")).expect("parses");
        assert_eq!(names, vec!["OW"]);
        assert!((c.positions[1] - 16.24).abs() < 1e-12);
        let v = c.velocities.expect("velocities");
        assert!((v[0] - 0.1227 * VELOCITY).abs() < 1e-15);
        assert_eq!(c.box_lengths, Some([10.0, 20.0, 30.0]));
    }
}
