//! Fortran fixed-width records, as AMBER's `%FORMAT(10I8)`, `(5E16.8)`, `(20a4)` give them:
//! a line holds up to `per_line` fields of `width` characters each; numbers may touch
//! (`-1234567-1234567`), so fields are cut by column, never split at spaces.

/// What one field holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FieldKind {
    /// `a`: characters, trailing blanks dropped.
    Text,
    /// `I`: a whole number.
    Integer,
    /// `E`, `F`, `D`, `G`: a real number.
    Real,
}

/// A parsed `%FORMAT(...)` descriptor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Format {
    pub per_line: usize,
    pub kind: FieldKind,
    pub width: usize,
}

/// Parse `(10I8)`, `(5E16.8)`, `(20a4)`, `(1a80)`, `(I8)` (a missing count is 1).
pub fn parse_format(spec: &str) -> Result<Format, String> {
    let inner = spec
        .trim()
        .strip_prefix('(')
        .and_then(|s| s.strip_suffix(')'))
        .ok_or_else(|| format!("format \"{spec}\" is not of the form (10I8)"))?
        .trim();
    let letter_at = inner
        .find(|c: char| c.is_ascii_alphabetic())
        .ok_or_else(|| format!("format \"{spec}\" names no field type (a, I, E, F)"))?;
    let count = &inner[..letter_at];
    let per_line = if count.is_empty() {
        1
    } else {
        count
            .parse::<usize>()
            .map_err(|_| format!("format \"{spec}\": bad repeat count \"{count}\""))?
    };
    let kind = match inner.as_bytes()[letter_at].to_ascii_uppercase() {
        b'A' => FieldKind::Text,
        b'I' => FieldKind::Integer,
        b'E' | b'F' | b'D' | b'G' => FieldKind::Real,
        other => {
            return Err(format!(
                "format \"{spec}\": field type '{}' is not a, I, E, F, D or G",
                other as char
            ));
        }
    };
    let rest = &inner[letter_at + 1..];
    let width_text = rest.split('.').next().unwrap_or("");
    let width = width_text
        .parse::<usize>()
        .map_err(|_| format!("format \"{spec}\": bad field width \"{width_text}\""))?;
    if per_line == 0 || width == 0 {
        return Err(format!("format \"{spec}\": count and width must be ≥ 1"));
    }
    Ok(Format {
        per_line,
        kind,
        width,
    })
}

/// The fields of one line (without its line end), cut every `width` columns; a shorter
/// last field is kept. Text fields lose trailing blanks, numbers all blanks.
pub fn fields<'a>(line: &'a str, format: &Format) -> Result<Vec<&'a str>, String> {
    if !line.is_ascii() {
        return Err("the line holds characters other than ASCII".into());
    }
    let line = line.trim_end_matches(['\r', '\n']);
    let line = if format.kind == FieldKind::Text {
        line
    } else {
        line.trim_end()
    };
    let count = line.len().div_ceil(format.width);
    if count > format.per_line {
        return Err(format!(
            "the line has {} characters, more than {} fields of {}",
            line.len(),
            format.per_line,
            format.width
        ));
    }
    Ok((0..count)
        .map(|k| {
            let field = &line[k * format.width..((k + 1) * format.width).min(line.len())];
            match format.kind {
                FieldKind::Text => field.trim_end(),
                _ => field.trim(),
            }
        })
        .collect())
}

/// A whole number field.
pub fn integer(field: &str) -> Result<i64, String> {
    field
        .parse::<i64>()
        .map_err(|_| format!("\"{field}\" is not a whole number"))
}

/// A real number field; Fortran's `D` exponent is read as `E`.
pub fn real(field: &str) -> Result<f64, String> {
    let parsed = if field.contains(['D', 'd']) {
        field.replace(['D', 'd'], "E").parse::<f64>()
    } else {
        field.parse::<f64>()
    };
    match parsed {
        Ok(x) if x.is_finite() => Ok(x),
        _ => Err(format!("\"{field}\" is not a finite number")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_of_amber_files_parse() {
        let f = parse_format("(10I8)").unwrap();
        assert_eq!((f.per_line, f.kind, f.width), (10, FieldKind::Integer, 8));
        let f = parse_format("(5E16.8)").unwrap();
        assert_eq!((f.per_line, f.kind, f.width), (5, FieldKind::Real, 16));
        let f = parse_format("(20a4)").unwrap();
        assert_eq!((f.per_line, f.kind, f.width), (20, FieldKind::Text, 4));
        let f = parse_format(" (I8) ").unwrap();
        assert_eq!((f.per_line, f.kind, f.width), (1, FieldKind::Integer, 8));
        assert!(parse_format("10I8").is_err());
        assert!(parse_format("(10X8)").is_err());
        assert!(parse_format("(10I)").is_err());
        assert!(parse_format("(0I8)").is_err());
    }

    #[test]
    fn touching_numbers_are_cut_by_column() {
        let f = parse_format("(10I8)").unwrap();
        let v = fields("-1234567-1234567       3", &f).unwrap();
        assert_eq!(v, ["-1234567", "-1234567", "3"]);
        let ints: Vec<i64> = v.iter().map(|s| integer(s).unwrap()).collect();
        assert_eq!(ints, [-1234567, -1234567, 3]);
    }

    #[test]
    fn text_fields_keep_inner_blanks_and_lose_trailing_ones() {
        let f = parse_format("(20a4)").unwrap();
        assert_eq!(fields("H1  C   O", &f).unwrap(), ["H1", "C", "O"]);
        assert_eq!(fields("", &f).unwrap(), Vec::<&str>::new());
    }

    #[test]
    fn reals_read_e_and_d_exponents_and_refuse_garbage() {
        let f = parse_format("(5E16.8)").unwrap();
        let v = fields("  1.20000000E+00 -3.50000000D-01", &f).unwrap();
        assert_eq!(real(v[0]).unwrap(), 1.2);
        assert_eq!(real(v[1]).unwrap(), -0.35);
        assert!(real("1.2.3").is_err());
        assert!(real("NaN").is_err());
        assert!(integer("12x").is_err());
    }

    #[test]
    fn a_line_longer_than_its_format_is_an_error() {
        let f = parse_format("(2I8)").unwrap();
        assert!(fields("       1       2       3", &f).is_err());
        assert!(fields("       1       2 ", &f).is_ok());
    }
}
