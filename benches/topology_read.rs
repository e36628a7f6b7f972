//! Reading a 100 001-atom topology (issue 27: "well under a second in release"): the
//! shipped solvated Trp-cage (6920 atoms) with 31 027 more copies of one of its TIP3P
//! waters, written to a temporary folder as an AMBER prmtop (the water's atoms, residue,
//! bonds, angle and exclusions appended to each section, POINTERS updated) and as a GROMACS
//! top (the `[ molecules ]` count of HOH raised), then read by `read_prmtop` and
//! `read_gromacs_top` (FLEXIBLE, so both have the same terms). Nothing of 10 MB is
//! committed: the files are made at the start and removed at the end.
//!
//!     cargo bench --bench topology_read

use std::path::{Path, PathBuf};
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use longstep::io::topology::gromacs::read_gromacs_top;
use longstep::io::topology::prmtop::read_prmtop;

const SYSTEM: &str = "systems/protein-amber/trpcage";
const TARGET_ATOMS: usize = 100_001;

/// One `%FLAG` section: its format's items per line and width, and its items as printed.
struct Section {
    flag: String,
    format: String,
    per_line: usize,
    width: usize,
    items: Vec<String>,
}

impl Section {
    fn ints(&self) -> Vec<i64> {
        self.items
            .iter()
            .map(|s| s.trim().parse().expect("an integer section"))
            .collect()
    }

    fn push_int(&mut self, value: i64) {
        self.items.push(format!("{value:>w$}", w = self.width));
    }
}

/// `%FORMAT(10I8)` → (10, 8); `5E16.8` → (5, 16); `20a4` → (20, 4).
fn format_shape(format: &str) -> (usize, usize) {
    let inner = format.trim_start_matches("%FORMAT(").trim_end_matches(')');
    let letter = inner
        .find(|c: char| c.is_ascii_alphabetic())
        .expect("a format letter");
    let width: String = inner[letter + 1..]
        .chars()
        .take_while(char::is_ascii_digit)
        .collect();
    (
        inner[..letter].parse().expect("a count"),
        width.parse().expect("a width"),
    )
}

fn parse(text: &str) -> (String, Vec<Section>) {
    let mut lines = text.lines();
    let version = lines.next().expect("a version line").to_string();
    let mut sections: Vec<Section> = Vec::new();
    while let Some(line) = lines.next() {
        if let Some(flag) = line.strip_prefix("%FLAG ") {
            let format = lines.next().expect("a format line").trim().to_string();
            let (per_line, width) = format_shape(&format);
            sections.push(Section {
                flag: flag.trim().to_string(),
                format,
                per_line,
                width,
                items: Vec::new(),
            });
            continue;
        }
        let section = sections.last_mut().expect("data after a flag");
        let mut rest = line;
        while !rest.is_empty() {
            let cut = rest.len().min(section.width);
            section.items.push(rest[..cut].to_string());
            rest = &rest[cut..];
        }
    }
    (version, sections)
}

fn write(version: &str, sections: &[Section]) -> String {
    let mut out = format!("{version}\n");
    for s in sections {
        out.push_str(&format!("%FLAG {}\n{}\n", s.flag, s.format));
        if s.items.is_empty() {
            out.push('\n');
        }
        for row in s.items.chunks(s.per_line) {
            out.push_str(&row.concat());
            out.push('\n');
        }
    }
    out
}

fn section<'a>(sections: &'a mut [Section], flag: &str) -> &'a mut Section {
    sections
        .iter_mut()
        .find(|s| s.flag == flag)
        .expect("a section the prmtop has")
}

/// The prmtop text with `copies` more copies of its first water appended.
fn replicate_water(text: &str, copies: usize) -> String {
    let (version, mut sections) = parse(text);
    let pointers = section(&mut sections, "POINTERS").ints();
    let n_atoms = pointers[0] as usize;
    let labels = &section(&mut sections, "RESIDUE_LABEL").items;
    let residue = labels
        .iter()
        .position(|l| l.trim() == "HOH")
        .expect("water");
    let first = section(&mut sections, "RESIDUE_POINTER").ints()[residue] as usize - 1;
    let water = first..first + 3;
    // Per-atom sections: the water's three items again for each copy.
    for s in sections.iter_mut().filter(|s| s.items.len() == n_atoms) {
        let block = s.items[water.clone()].to_vec();
        for _ in 0..copies {
            s.items.extend(block.iter().cloned());
        }
    }
    let shift = |k: usize| (n_atoms + 3 * k) as i64 - first as i64;
    for k in 0..copies {
        section(&mut sections, "RESIDUE_LABEL")
            .items
            .push("HOH ".into());
        section(&mut sections, "RESIDUE_POINTER").push_int((n_atoms + 3 * k + 1) as i64);
    }
    // Bonds and angles with hydrogen: lists of coordinate indices (3 × atom) and a type.
    let mut added = [0usize; 3];
    for (flag, width, slot) in [("BONDS_INC_HYDROGEN", 3, 0), ("ANGLES_INC_HYDROGEN", 4, 1)] {
        let s = section(&mut sections, flag);
        let rows: Vec<Vec<i64>> = s
            .ints()
            .chunks(width)
            .filter(|r| {
                r[..width - 1]
                    .iter()
                    .all(|&c| water.contains(&(c as usize / 3)))
            })
            .map(<[i64]>::to_vec)
            .collect();
        added[slot] = rows.len();
        for k in 0..copies {
            for row in &rows {
                for (j, &value) in row.iter().enumerate() {
                    let last = j == width - 1;
                    s.push_int(if last { value } else { value + 3 * shift(k) });
                }
            }
        }
    }
    // Exclusions: 1-based atom numbers, 0 for "none".
    let counts = section(&mut sections, "NUMBER_EXCLUDED_ATOMS").ints();
    let start: i64 = counts[..first].iter().sum();
    let count: i64 = counts[water.clone()].iter().sum();
    let s = section(&mut sections, "EXCLUDED_ATOMS_LIST");
    let block = s.ints()[start as usize..(start + count) as usize].to_vec();
    added[2] = block.len();
    for k in 0..copies {
        for &value in &block {
            s.push_int(if value == 0 { 0 } else { value + shift(k) });
        }
    }
    let p = section(&mut sections, "POINTERS");
    let mut updated = p.ints();
    updated[0] += 3 * copies as i64; // NATOM
    updated[2] += (added[0] * copies) as i64; // NBONH
    updated[4] += (added[1] * copies) as i64; // NTHETH
    updated[10] += (added[2] * copies) as i64; // NEXT
    updated[11] += copies as i64; // NRES
    p.items.clear();
    for value in updated {
        p.push_int(value);
    }
    write(&version, &sections)
}

/// The top text with `copies` more waters in `[ molecules ]`.
fn more_waters(text: &str, copies: usize) -> String {
    let mut out = String::new();
    let mut in_molecules = false;
    for line in text.lines() {
        let fields: Vec<&str> = line.split_whitespace().collect();
        if line.trim_start().starts_with('[') {
            in_molecules = line.contains("molecules");
        }
        if let (true, ["HOH", count]) = (in_molecules, fields.as_slice()) {
            let count: usize = count.parse().expect("a count");
            out.push_str(&format!("HOH {}\n", count + copies));
        } else {
            out.push_str(line);
            out.push('\n');
        }
    }
    out
}

fn files() -> (PathBuf, PathBuf, PathBuf) {
    let dir = std::env::temp_dir().join(format!("longstep-topology-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a temporary folder");
    let prmtop_text = std::fs::read_to_string(format!("{SYSTEM}.prmtop")).expect("reads");
    let copies = (TARGET_ATOMS - 6920) / 3;
    let prmtop = dir.join("big.prmtop");
    std::fs::write(&prmtop, replicate_water(&prmtop_text, copies)).expect("writes");
    let top_text = std::fs::read_to_string(format!("{SYSTEM}.top")).expect("reads");
    let top = dir.join("big.top");
    std::fs::write(&top, more_waters(&top_text, copies)).expect("writes");
    (dir, prmtop, top)
}

fn read_big_topologies(c: &mut Criterion) {
    let (dir, prmtop, top) = files();
    let flexible = vec!["FLEXIBLE".to_string()];
    let a = read_prmtop(&prmtop).expect("the big prmtop reads");
    let b = read_gromacs_top(&top, &flexible).expect("the big top reads");
    assert_eq!(a.atoms.len(), TARGET_ATOMS);
    assert_eq!(b.atoms.len(), TARGET_ATOMS);
    assert_eq!(a.bonds.len(), b.bonds.len());
    assert_eq!(a.exclusions.len(), b.exclusions.len());
    let mut group = c.benchmark_group("topology read 100001 atoms");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(20));
    group.bench_function("prmtop", |bench| {
        bench.iter(|| read_prmtop(Path::new(&prmtop)).expect("reads"))
    });
    group.bench_function("top (FLEXIBLE)", |bench| {
        bench.iter(|| read_gromacs_top(Path::new(&top), &flexible).expect("reads"))
    });
    group.finish();
    std::fs::remove_dir_all(dir).expect("removes its folder");
}

criterion_group!(benches, read_big_topologies);
criterion_main!(benches);
