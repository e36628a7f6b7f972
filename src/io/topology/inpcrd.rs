//! AMBER coordinates: inpcrd / rst7 in ASCII (`.inpcrd`, `.rst7`, `.crd`).
//!
//! Line 1 a title; line 2 the atom count (and the time, in a restart); then the `3n`
//! coordinates in Å as `6F12.7` (six fields of 12 columns a line), then optionally `3n`
//! velocities in the same layout (Å per 1/20.455 ps, AMBER's time unit), then optionally
//! one line with the box: `a b c α β γ` (Å, degrees). Fields are cut by column, as AMBER
//! writes them; a coordinate of 12 characters touches its neighbour.
//!
//! Cost: one pass over the text.

use std::path::Path;

use super::fortran::{self, FieldKind, Format};
use crate::error::{Error, Result};

/// AMBER's velocity unit in Å/fs: its time unit is 1/20.455 ps.
pub const VELOCITY_TO_ANGSTROM_PER_FS: f64 = 20.455 / 1000.0;

/// What an inpcrd holds.
#[derive(Clone, Debug, PartialEq)]
pub struct Coordinates {
    pub title: String,
    /// `n × 3`, Å.
    pub positions: Vec<f64>,
    /// `n × 3`, Å/fs, when the file has them.
    pub velocities: Option<Vec<f64>>,
    /// Box edges (Å) and angles (degrees), when the file has a box line.
    pub box_lengths: Option<[f64; 3]>,
    pub box_angles: Option<[f64; 3]>,
}

impl Coordinates {
    pub fn n_atoms(&self) -> usize {
        self.positions.len() / 3
    }
}

fn error_at(path: &Path, line: usize, message: impl Into<String>) -> Error {
    Error::topology(path, message).line(line)
}

pub fn read_inpcrd(path: &Path) -> Result<Coordinates> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    if bytes.starts_with(b"CDF") || bytes.starts_with(b"\x89HDF") {
        return Err(error_at(
            path,
            1,
            "a binary (NetCDF) restart: longstep reads ASCII inpcrd/rst7 (convert it, e.g. \
             with cpptraj or ParmEd)",
        ));
    }
    let text = String::from_utf8(bytes)
        .map_err(|_| error_at(path, 1, "not a text file: longstep reads ASCII inpcrd/rst7"))?;
    parse_inpcrd(&text, path)
}

const LAYOUT: Format = Format {
    per_line: 6,
    kind: FieldKind::Real,
    width: 12,
};

/// `count` numbers from the lines starting at index `start` (0-based); the index after.
fn numbers(
    lines: &[&str],
    start: usize,
    count: usize,
    path: &Path,
    what: &str,
) -> Result<(Vec<f64>, usize)> {
    let mut out = Vec::with_capacity(count);
    let mut index = start;
    while out.len() < count {
        let Some(line) = lines.get(index) else {
            return Err(error_at(
                path,
                index,
                format!(
                    "{what}: {} of {count} numbers before the end (file truncated?)",
                    out.len()
                ),
            ));
        };
        let fields = fortran::fields(line, &LAYOUT).map_err(|e| error_at(path, index + 1, e))?;
        if fields.is_empty() {
            return Err(error_at(path, index + 1, format!("{what}: a blank line")));
        }
        for field in fields {
            out.push(
                fortran::real(field)
                    .map_err(|e| error_at(path, index + 1, format!("{what}: {e}")))?,
            );
        }
        index += 1;
    }
    if out.len() != count {
        return Err(error_at(
            path,
            index,
            format!("{what}: {} numbers where {count} end a line", out.len()),
        ));
    }
    Ok((out, index))
}

/// Parse inpcrd text; `path` names the file in messages.
pub fn parse_inpcrd(text: &str, path: &Path) -> Result<Coordinates> {
    let lines: Vec<&str> = text.lines().collect();
    if lines.len() < 2 {
        return Err(error_at(
            path,
            lines.len().max(1),
            "no atom-count line: not an inpcrd",
        ));
    }
    let count_field = lines[1].split_whitespace().next().unwrap_or("");
    let n = count_field.parse::<usize>().map_err(|_| {
        error_at(
            path,
            2,
            format!("atom count \"{count_field}\" is not a whole number"),
        )
    })?;
    let (positions, mut next) = numbers(&lines, 2, 3 * n, path, "coordinates")?;
    let remaining: Vec<usize> = (next..lines.len())
        .filter(|&i| !lines[i].trim().is_empty())
        .collect();
    let mut velocities = None;
    // Velocities take ⌈3n/6⌉ lines; a box is one line.
    if remaining.len() > 1 {
        let (v, after) = numbers(&lines, next, 3 * n, path, "velocities")?;
        velocities = Some(v.iter().map(|x| x * VELOCITY_TO_ANGSTROM_PER_FS).collect());
        next = after;
    }
    let rest: Vec<usize> = (next..lines.len())
        .filter(|&i| !lines[i].trim().is_empty())
        .collect();
    let (box_lengths, box_angles) = match rest.as_slice() {
        [] => (None, None),
        [line] => box_line(lines[*line], *line + 1, path)?,
        [_, extra, ..] => {
            return Err(error_at(
                path,
                extra + 1,
                "more lines than coordinates, velocities and a box",
            ));
        }
    };
    Ok(Coordinates {
        title: lines[0].trim().to_string(),
        positions,
        velocities,
        box_lengths,
        box_angles,
    })
}

type BoxLine = (Option<[f64; 3]>, Option<[f64; 3]>);

/// `a b c [α β γ]`.
fn box_line(line: &str, number: usize, path: &Path) -> Result<BoxLine> {
    let fields = fortran::fields(line, &LAYOUT).map_err(|e| error_at(path, number, e))?;
    let values = fields
        .iter()
        .map(|f| fortran::real(f).map_err(|e| error_at(path, number, format!("box: {e}"))))
        .collect::<Result<Vec<f64>>>()?;
    if values.len() != 3 && values.len() != 6 {
        return Err(error_at(
            path,
            number,
            format!("box line has {} numbers, 3 or 6 expected", values.len()),
        ));
    }
    let lengths = [values[0], values[1], values[2]];
    if lengths.iter().any(|&l| l <= 0.0) {
        return Err(error_at(
            path,
            number,
            format!("box lengths {lengths:?} must be positive"),
        ));
    }
    let angles = (values.len() == 6).then(|| [values[3], values[4], values[5]]);
    Ok((Some(lengths), angles))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn coordinates_velocities_and_box_are_read_by_column() {
        let text = "title\n    2  1.0000000E+01\n   1.0000000   2.0000000   3.0000000-104.1234567   5.0000000   6.0000000\n   1.0000000   0.0000000   0.0000000   0.0000000   0.0000000  -2.0000000\n  30.0000000  31.0000000  32.0000000  90.0000000  90.0000000  90.0000000\n";
        let c = parse_inpcrd(text, Path::new("t.rst7")).unwrap();
        assert_eq!(c.positions, [1.0, 2.0, 3.0, -104.1234567, 5.0, 6.0]);
        let v = c.velocities.unwrap();
        assert_eq!(v[0], VELOCITY_TO_ANGSTROM_PER_FS);
        assert_eq!(v[5], -2.0 * VELOCITY_TO_ANGSTROM_PER_FS);
        assert_eq!(c.box_lengths, Some([30.0, 31.0, 32.0]));
        assert_eq!(c.box_angles, Some([90.0, 90.0, 90.0]));
    }

    #[test]
    fn a_truncated_file_names_its_line() {
        let text = "title\n    3\n   1.0000000   2.0000000   3.0000000   4.0000000   5.0000000   6.0000000\n";
        let e = parse_inpcrd(text, Path::new("t.inpcrd"))
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("t.inpcrd:3:"), "{e}");
        assert!(e.contains("6 of 9"), "{e}");
    }
}
