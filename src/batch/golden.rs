//! Golden digests: the expected pixels of bundled jobs, kept in `golden/` under version control.
//!
//! One JSON file per job file (`golden/<job file path without .toml>.json`), mapping each job id
//! to the pixel digest of each of its outputs. Pixel digests, not file digests, so that a change
//! of PNG compression never looks like a change of result. Changing a golden file is a
//! deliberate act: `bless` prints every digest it changes.

use crate::batch::manifest::{JobRecord, Manifest};
use crate::digest::Digest;
use crate::error::Error;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// job id → output path → pixel digest.
pub type GoldenFile = BTreeMap<String, BTreeMap<String, Digest>>;

/// The golden file of a job: `dir/<id's file part without .toml>.json`. The id comes from a
/// manifest, which may have been made elsewhere: [`Manifest::load`] refuses ids that are not
/// relative paths inside the job root, and this checks again, so that no id ever names a file
/// outside `dir`.
fn golden_path(dir: &Path, rec: &JobRecord) -> Result<PathBuf, Error> {
    crate::batch::manifest::check_id(&rec.id)
        .map_err(|reason| Error::manifest(dir, format!("job `{}`: {reason}", rec.id.escape_debug())))?;
    let file_part = rec.id.split('#').next().unwrap_or(&rec.id);
    let stem = file_part.strip_suffix(".toml").unwrap_or(file_part);
    Ok(dir.join(format!("{stem}.json")))
}

/// Creates the golden file's directory and checks that it resolves inside `dir` (a symlink in
/// the golden tree must not carry a write elsewhere).
fn contained(dir: &Path, path: &Path) -> Result<(), Error> {
    let parent = path.parent().unwrap_or(dir);
    std::fs::create_dir_all(parent).map_err(|e| Error::io(parent, "create", e))?;
    let root = dir.canonicalize().map_err(|e| Error::io(dir, "resolve", e))?;
    let real = parent.canonicalize().map_err(|e| Error::io(parent, "resolve", e))?;
    if !real.starts_with(&root) {
        return Err(Error::Containment {
            path: path.to_path_buf(),
            reason: format!(
                "would be written to {}, outside the golden directory {} (a symlink?); refusing",
                real.display(),
                root.display()
            ),
        });
    }
    Ok(())
}

fn read_golden(path: &Path) -> Result<GoldenFile, Error> {
    match crate::files::read_limited(path, crate::files::MAX_JSON_BYTES) {
        Ok(b) => serde_json::from_slice(&b).map_err(|e| Error::manifest(path, format!("not a golden file: {e}"))),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(GoldenFile::new()),
        Err(e) => Err(Error::io(path, "read", e)),
    }
}

#[derive(Debug, Default)]
pub struct CheckReport {
    pub matched: usize,
    pub mismatched: Vec<String>,
    /// The same mismatches as (job id, output path), for programs.
    pub mismatched_outputs: Vec<(String, String)>,
    pub missing: Vec<String>,
    pub not_checked: Vec<String>,
}

impl CheckReport {
    pub fn ok(&self) -> bool {
        self.mismatched.is_empty() && self.missing.is_empty() && self.not_checked.is_empty()
    }
}

/// Compares the manifest's pixel digests with `golden/`.
pub fn check(dir: &Path, manifest: &Manifest) -> Result<CheckReport, Error> {
    let mut report = CheckReport::default();
    let mut cache: BTreeMap<PathBuf, GoldenFile> = BTreeMap::new();
    for rec in &manifest.jobs {
        if !rec.status.is_success() {
            report.not_checked.push(format!("{}: {} in this run, nothing to compare", rec.id, rec.status.name()));
            continue;
        }
        let path = golden_path(dir, rec)?;
        if !cache.contains_key(&path) {
            cache.insert(path.clone(), read_golden(&path)?);
        }
        let golden = &cache[&path];
        for o in &rec.outputs {
            match golden.get(&rec.id).and_then(|m| m.get(&o.path)) {
                None => report.missing.push(format!("{} ({}): no golden digest in {}", rec.id, o.path, path.display())),
                Some(d) if *d == o.pixel_digest => report.matched += 1,
                Some(d) => {
                    report.mismatched_outputs.push((rec.id.clone(), o.path.clone()));
                    report.mismatched.push(format!(
                        "{} ({}): pixels {} but golden {} ({})",
                        rec.id,
                        o.path,
                        o.pixel_digest.short(),
                        d.short(),
                        path.display()
                    ))
                }
            }
        }
    }
    Ok(report)
}

/// Writes the manifest's pixel digests into `golden/`; returns one line per change.
pub fn bless(dir: &Path, manifest: &Manifest) -> Result<Vec<String>, Error> {
    let mut files: BTreeMap<PathBuf, GoldenFile> = BTreeMap::new();
    let mut changes = Vec::new();
    for rec in &manifest.jobs {
        if !rec.status.is_success() {
            changes.push(format!("skipped {}: {} in this run", rec.id, rec.status.name()));
            continue;
        }
        let path = golden_path(dir, rec)?;
        if !files.contains_key(&path) {
            files.insert(path.clone(), read_golden(&path)?);
        }
        let golden = files.get_mut(&path).expect("inserted");
        let entry = golden.entry(rec.id.clone()).or_default();
        for o in &rec.outputs {
            match entry.get(&o.path) {
                None => changes.push(format!("new      {} ({}): {}", rec.id, o.path, o.pixel_digest.short())),
                Some(d) if *d != o.pixel_digest => {
                    changes.push(format!("changed  {} ({}): {} -> {}", rec.id, o.path, d.short(), o.pixel_digest.short()))
                }
                Some(_) => {}
            }
            entry.insert(o.path.clone(), o.pixel_digest.clone());
        }
    }
    // Every destination is checked before the first is written: a bad one writes nothing.
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, "create", e))?;
    for path in files.keys() {
        contained(dir, path)?;
    }
    for (path, content) in files {
        let mut text = serde_json::to_string_pretty(&content).expect("golden serialises");
        text.push('\n');
        crate::batch::outdir::write_atomic(&path, text.as_bytes())?;
    }
    Ok(changes)
}
