//! A run folder's `manifest.json`: which run wrote which files, so that runs never mix.
//!
//! `longstep run` writes the manifest into its output folder when it starts (the command
//! line, the longstep version, a run id, the start time in UTC as RFC 3339, the files it
//! plans to write) and again when it ends, with each file it wrote fingerprinted by its
//! size and CRC-32. Before that, a folder that still holds an earlier run's outputs
//! ([`earlier_outputs`]: the files its manifest lists and the names a run or `analyze`
//! writes) is refused, or with `--force` cleared of exactly those files
//! ([`clear_earlier_run`]); no other file is touched. `analyze` checks that the energy table
//! and the trajectory it combines are both listed, unchanged, in their folder's manifest
//! ([`check_same_run`]). Cost: one pass over each written file at the end of the run (and
//! again in `analyze`), which reads it anyway.

use std::collections::BTreeSet;
use std::io::Read;
use std::path::{Component, Path};

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::io::summary::PairListSummary;

/// The manifest's file name in a run folder.
pub const MANIFEST: &str = "manifest.json";

/// What `longstep run` writes into its folder under fixed names (the trajectory's name may
/// differ: the scene's `[output] trajectory`, added by the caller).
pub const RUN_OUTPUTS: [&str; 7] = [
    MANIFEST,
    "energy.csv",
    "trajectory.xyz",
    "energy.png",
    "energy.svg",
    "energy-error.png",
    "energy-error.svg",
];

/// What `longstep analyze` writes into a run folder's `analysis/` (derived from that run,
/// so stale beside a new one).
pub const ANALYSIS_OUTPUTS: [&str; 7] = [
    "analysis/rdf.csv",
    "analysis/blocks.csv",
    "analysis/blocking.csv",
    "analysis/geometry.csv",
    "analysis/summary.json",
    "analysis/basins.csv",
    "analysis/ramachandran.csv",
];

/// One file a run wrote, by its name relative to the run folder; `bytes` and `crc32` are
/// set when the run finishes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ManifestFile {
    pub name: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bytes: Option<u64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crc32: Option<String>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunManifest {
    /// The longstep version that wrote the run.
    pub longstep: String,
    /// Unique per run: 16 hex digits.
    pub run_id: String,
    pub command: Vec<String>,
    /// UTC, RFC 3339.
    pub started: String,
    /// UTC, RFC 3339; absent while the run goes (or when it was killed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub finished: Option<String>,
    pub files: Vec<ManifestFile>,
    /// The degrees of freedom the run counted its kinetic temperature over
    /// (`system::velocities::DegreesOfFreedom`), for `analyze`; absent for a scene without
    /// a temperature, a scan's record, and runs written before this field (whose count
    /// `analyze` recovers from `command`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub degrees_of_freedom: Option<usize>,
    /// How often each non-bonded term's pair list was built and pruned (set when the run
    /// finishes; GROMACS's `nstlist`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub pair_lists: Vec<PairListSummary>,
}

impl RunManifest {
    /// The manifest of a run starting now, planning to write `files` (relative names).
    pub fn start(command: Vec<String>, files: &[String]) -> Self {
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap_or_default();
        RunManifest {
            longstep: env!("CARGO_PKG_VERSION").to_string(),
            run_id: run_id(now, &command),
            command,
            started: rfc3339(now.as_secs()),
            finished: None,
            files: files
                .iter()
                .map(|name| ManifestFile {
                    name: name.clone(),
                    bytes: None,
                    crc32: None,
                })
                .collect(),
            degrees_of_freedom: None,
            pair_lists: Vec::new(),
        }
    }

    /// This manifest recording the run's degrees of freedom (`None`: none counted).
    pub fn with_degrees_of_freedom(mut self, count: Option<usize>) -> Self {
        self.degrees_of_freedom = count;
        self
    }

    /// Read `dir/manifest.json`: `None` when there is none.
    pub fn read(dir: &Path) -> Result<Option<Self>> {
        let path = dir.join(MANIFEST);
        if !path.is_file() {
            return Ok(None);
        }
        let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
        serde_json::from_str(&text)
            .map(Some)
            .map_err(|e| Error::Structure {
                path,
                message: format!("is not a longstep run manifest: {e}"),
            })
    }

    pub fn write(&self, dir: &Path) -> Result<()> {
        let path = dir.join(MANIFEST);
        let text = serde_json::to_string_pretty(self)
            .map_err(|e| Error::input(format!("cannot write the run manifest as JSON: {e}")))?;
        std::fs::write(&path, text + "\n").map_err(|e| Error::io(&path, e))
    }

    /// A run refused before it wrote any output: its manifest goes (the output folder is
    /// as it was), so the same command can be retried.
    pub fn withdraw(&self, dir: &Path) {
        if self.files.iter().all(|f| !dir.join(&f.name).exists()) {
            let _ = std::fs::remove_file(dir.join(MANIFEST));
        }
    }

    /// At the end of the run: fingerprint every planned file that was written (one not
    /// written, such as the trajectory of a run that failed before it, is dropped), stamp
    /// the end time and write the manifest again.
    pub fn finish(&mut self, dir: &Path) -> Result<()> {
        self.files.retain(|f| dir.join(&f.name).is_file());
        for file in &mut self.files {
            let (bytes, crc) = fingerprint(&dir.join(&file.name))?;
            file.bytes = Some(bytes);
            file.crc32 = Some(format!("{crc:08x}"));
        }
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap_or_default();
        self.finished = Some(rfc3339(now.as_secs()));
        self.write(dir)
    }
}

/// A run id from the start time and the command line: 16 hex digits from the `rand`
/// crate's generator seeded with both (unique as long as two runs do not start in the same
/// nanosecond with the same command).
fn run_id(now: std::time::Duration, command: &[String]) -> String {
    use rand::{Rng, SeedableRng};
    let mut seed = now.as_nanos() as u64 ^ u64::from(std::process::id()).rotate_left(32);
    for byte in command.iter().flat_map(|a| a.bytes()) {
        seed = seed.rotate_left(5) ^ u64::from(byte);
    }
    let mut rng = rand::rngs::Xoshiro256PlusPlus::seed_from_u64(seed);
    format!("{:016x}", rng.next_u64())
}

/// Seconds since 1970 as `YYYY-MM-DDThh:mm:ssZ` (the proleptic Gregorian calendar of
/// RFC 3339; the days to a date by the civil-from-days algorithm of H. Hinnant).
pub fn rfc3339(seconds: u64) -> String {
    let days = (seconds / 86_400) as i64;
    let of_day = seconds % 86_400;
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let day_of_era = z - era * 146_097;
    let year_of_era =
        (day_of_era - day_of_era / 1460 + day_of_era / 36_524 - day_of_era / 146_096) / 365;
    let day_of_year = day_of_era - (365 * year_of_era + year_of_era / 4 - year_of_era / 100);
    let mp = (5 * day_of_year + 2) / 153;
    let day = day_of_year - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = year_of_era + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}Z",
        of_day / 3600,
        of_day / 60 % 60,
        of_day % 60
    )
}

/// A file's size in bytes and CRC-32, read in blocks.
pub fn fingerprint(path: &Path) -> Result<(u64, u32)> {
    let mut file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut hasher = crc32fast::Hasher::new();
    let mut buffer = vec![0u8; 1 << 16];
    let mut bytes = 0u64;
    loop {
        let n = file.read(&mut buffer).map_err(|e| Error::io(path, e))?;
        if n == 0 {
            return Ok((bytes, hasher.finalize()));
        }
        bytes += n as u64;
        hasher.update(&buffer[..n]);
    }
}

/// A name a manifest may list: relative, inside the folder (no `..`, no root), so that a
/// hand-edited manifest cannot make `--force` remove anything outside it.
fn inside(name: &str) -> bool {
    let path = Path::new(name);
    !name.is_empty() && path.components().all(|c| matches!(c, Component::Normal(_)))
}

/// The outputs of an earlier run still in `dir`, by name: the files its manifest lists,
/// the names a run writes ([`RUN_OUTPUTS`] and the new run's `planned` files) and what
/// `analyze` wrote into `analysis/`, where they exist. An unreadable manifest counts as an
/// output itself.
pub fn earlier_outputs(dir: &Path, planned: &[String]) -> Vec<String> {
    let mut names: BTreeSet<String> = RUN_OUTPUTS
        .iter()
        .chain(&ANALYSIS_OUTPUTS)
        .map(|s| s.to_string())
        .chain(planned.iter().cloned())
        .collect();
    if let Ok(Some(manifest)) = RunManifest::read(dir) {
        names.extend(manifest.files.into_iter().map(|f| f.name));
    }
    names
        .into_iter()
        .filter(|name| inside(name) && dir.join(name).is_file())
        .collect()
}

/// Before a run writes into `dir`: with no earlier outputs there ([`earlier_outputs`]),
/// nothing; else refuse (naming them and `--force`), or with `force` remove exactly them
/// (and `analysis/` when that leaves it empty) and return their names.
pub fn clear_earlier_run(dir: &Path, planned: &[String], force: bool) -> Result<Vec<String>> {
    let stale = earlier_outputs(dir, planned);
    if stale.is_empty() {
        return Ok(stale);
    }
    if !force {
        // A manifest without an end time is a run that was killed or crashed.
        let which = match RunManifest::read(dir) {
            Ok(Some(m)) if m.finished.is_none() => format!(
                "an interrupted run (started {}, never finished: killed or crashed)",
                m.started
            ),
            _ => "an earlier run".to_string(),
        };
        return Err(Error::Structure {
            path: dir.to_path_buf(),
            message: format!(
                "holds the outputs of {which} ({}); run with --force to remove them first{}, \
                 or give another --out",
                stale.join(", "),
                if stale.iter().any(|s| s == "checkpoint.json") {
                    " (its checkpoint.json continues it with --restart: copy it out first)"
                } else {
                    ""
                }
            ),
        });
    }
    for name in &stale {
        let path = dir.join(name);
        std::fs::remove_file(&path).map_err(|e| Error::io(&path, e))?;
    }
    // Only when empty: a folder the user added files to stays.
    let _ = std::fs::remove_dir(dir.join("analysis"));
    Ok(stale)
}

/// Before `analyze` combines `files` (the energy table and the trajectory, inside `dir`):
/// when `dir` has a manifest, each must be listed in it and, once the run has finished,
/// unchanged (size and CRC-32); else the files come from different runs (or were edited)
/// and the error names them. A folder without a manifest (a peer code's, an older
/// longstep's) is not checked.
pub fn check_same_run(dir: &Path, files: &[&Path]) -> Result<()> {
    let Some(manifest) = RunManifest::read(dir)? else {
        return Ok(());
    };
    let names: Vec<String> = files
        .iter()
        .map(|f| {
            f.strip_prefix(dir)
                .unwrap_or(f)
                .to_string_lossy()
                .into_owned()
        })
        .collect();
    for (name, path) in names.iter().zip(files) {
        let reason = match manifest.files.iter().find(|f| &f.name == name) {
            None => format!("{name} is not one of its files"),
            Some(listed) => match (listed.bytes, &listed.crc32) {
                (Some(bytes), Some(crc)) => {
                    let (now_bytes, now_crc) = fingerprint(path)?;
                    if now_bytes == bytes && format!("{now_crc:08x}") == *crc {
                        continue;
                    }
                    format!("{name} is not the file it wrote (size or CRC-32 differ)")
                }
                _ => continue,
            },
        };
        return Err(Error::Structure {
            path: dir.to_path_buf(),
            message: format!(
                "{} do not come from the same run: {MANIFEST} lists run {} (started {}), \
                 and {reason}; analyse the folder of one run",
                names.join(" and "),
                manifest.run_id,
                manifest.started
            ),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dates_follow_the_gregorian_calendar() {
        // Known instants: the epoch, 10^9 s (a Sunday in 2001), a leap day, a year end.
        assert_eq!(rfc3339(0), "1970-01-01T00:00:00Z");
        assert_eq!(rfc3339(1_000_000_000), "2001-09-09T01:46:40Z");
        assert_eq!(rfc3339(951_782_400), "2000-02-29T00:00:00Z");
        assert_eq!(rfc3339(1_798_761_599), "2026-12-31T23:59:59Z");
    }

    #[test]
    fn names_outside_the_folder_are_never_outputs() {
        assert!(inside("energy.csv") && inside("analysis/rdf.csv"));
        assert!(!inside("../energy.csv") && !inside("/etc/passwd") && !inside(""));
    }
}
