//! The manifest: what was run, from what, producing what — enough to re-run and check every
//! result from the manifest alone.
//!
//! Layout (`<out>/manifest.json`): `format`, `tool`, `deterministic_digest`, `jobs` (sorted by id)
//! and `run`. Everything that depends on the moment (times, host, argv, durations) lives in `run`
//! and in each job's `timing`; the *deterministic part* is `tool` plus every job without its
//! `timing`, with status `up-to-date` counted as `ok`. Its digest is SHA-256 over RFC 8785
//! canonical JSON, so it can be recomputed by any tool.

use crate::digest::{Digest, Hasher, canonical_json};
use crate::error::Error;
use crate::image::seam_grid::SeamGrid;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::path::Path;

pub const FORMAT: &str = "texsyn-manifest/1";
pub const FILE_NAME: &str = "manifest.json";

/// The tool that wrote a manifest.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Tool {
    pub name: String,
    pub version: String,
    pub commit: String,
}

impl Tool {
    pub fn current() -> Tool {
        Tool { name: "texsyn".into(), version: env!("CARGO_PKG_VERSION").into(), commit: env!("TEXSYN_COMMIT").into() }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Status {
    /// Synthesised in this run.
    Ok,
    /// Recorded earlier with the same content key; its output file still hashes as recorded.
    UpToDate,
    /// Valid, but synthesis or writing failed (see `error`).
    Failed,
    /// Rejected by validation before running (see `error`).
    Invalid,
}

impl Status {
    pub fn is_success(&self) -> bool {
        matches!(self, Status::Ok | Status::UpToDate)
    }
    pub fn name(&self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::UpToDate => "up-to-date",
            Status::Failed => "failed",
            Status::Invalid => "invalid",
        }
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FileRef {
    /// Relative to the manifest's directory when possible, else absolute; `/`-separated.
    pub path: String,
    pub digest: Digest,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SampleRecord {
    /// Relative to the manifest's directory when possible, else absolute.
    pub path: String,
    pub file_digest: Digest,
    /// Digest of the stored pixels (`imageio::NativeImage::pixel_digest`): for an 8-bit RGB
    /// sample, the pixels the method saw.
    pub pixel_digest: Digest,
    pub width: u32,
    pub height: u32,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OutputRecord {
    /// Relative to the output directory.
    pub path: String,
    pub format: String,
    pub bit_depth: u8,
    pub width: u32,
    pub height: u32,
    pub file_digest: Digest,
    /// Digest of the stored samples (see `imageio::NativeImage::pixel_digest`).
    pub pixel_digest: Digest,
}

/// Durations of one job's last actual run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Timing {
    /// The method's synthesis call only (no decoding or encoding).
    pub synthesis_seconds: f64,
    /// Computing the requested metrics (0 when none were requested).
    #[serde(default)]
    pub metrics_seconds: f64,
    /// Named phases of the synthesis call, when the method reports them.
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub phases: std::collections::BTreeMap<String, f64>,
    /// Everything for this job, including encoding and writing.
    pub total_seconds: f64,
    /// When it ran, seconds since the Unix epoch.
    pub finished_at: u64,
    /// The job's estimated peak memory in bytes (`batch::memory`), which the scheduler reserved
    /// while it ran. A model's output, so kept out of the deterministic part like the times.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub estimated_peak_bytes: Option<u64>,
}

/// One job's record.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct JobRecord {
    pub id: String,
    pub job_file: FileRef,
    pub status: Status,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub method: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub algorithm_version: Option<u32>,
    /// Fully resolved parameters (defaults filled in).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub params: Option<Value>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub params_digest: Option<Digest>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sample: Option<SampleRecord>,
    /// The samples of the job's `[[companion]]` maps, in order (their pixels are in the content
    /// key through `output_spec.companions`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub companions: Vec<SampleRecord>,
    /// With several samples: each companion's maps of the samples after the first, in order
    /// (their pixels are in `output_spec.companions[].more_sample_pixels`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub more_companions: Vec<Vec<SampleRecord>>,
    /// The job's `sample_mask` image (its pixels are in the content key through
    /// `output_spec.sample_mask`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sample_mask: Option<SampleRecord>,
    /// An inpainting job's mask image, when it has one (its pixels are in the content key through
    /// `output_spec.inpaint.mask`; a channel of the image is named there instead).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inpaint_mask: Option<SampleRecord>,
    /// A guided job's target guide (its pixels are in the content key through `output_spec.guide`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub guide_target: Option<SampleRecord>,
    /// A guided job's source guide, when it has one (else the sample's luminance is its guide).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub guide_source: Option<SampleRecord>,
    /// Several samples or `augment`: every sample, the first one (also `sample`) first (their
    /// pixels are in the content key through `output_spec.samples`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub samples: Vec<SampleRecord>,
    /// With `samples`, each sample's mask image (`null` for one without), when any has one.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sample_masks: Vec<Option<SampleRecord>>,
    /// What the job asked for (`path`, `width`, `height`, `format`, `bit_depth`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub output_spec: Option<Value>,
    /// Content key: method, algorithm version, params, seed, sample pixels, output spec.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub content_key: Option<Digest>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub outputs: Vec<OutputRecord>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seams: Option<SeamGrid>,
    #[serde(default, skip_serializing_if = "Value::is_null")]
    pub diagnostics: Value,
    /// Requested metrics of the output against the sample (`null` where undefined).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub metrics: Option<std::collections::BTreeMap<String, Option<f64>>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub timing: Option<Timing>,
    /// Plain sentences when the job's method and parameters do not fit its sample (`texsyn
    /// advise`); the job still ran. Deterministic: a function of the sample's pixels and the
    /// parameters.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

/// Facts about the run that wrote the manifest (not reproducible by nature).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RunFacts {
    pub started_at: u64,
    pub finished_at: u64,
    pub wall_seconds: f64,
    pub host: String,
    pub argv: Vec<String>,
    pub threads: usize,
    pub ran: usize,
    pub up_to_date: usize,
    pub failed: usize,
    pub invalid: usize,
    /// True while the run is still going (the manifest is rewritten as jobs finish).
    pub in_progress: bool,
    /// Set in a shard's fragment (`--shard I/N`); absent in a whole run's manifest.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shard: Option<ShardFacts>,
    /// Jobs of the plan that did not run because the run was stopped (a signal); a re-run does them.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub not_run: Vec<String>,
    /// Set by `texsyn merge`: the fragments the manifest was merged from.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub merged_from: Vec<ShardFacts>,
    /// The memory limit the run kept to (`--max-memory`), in bytes; absent when it had none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_memory_bytes: Option<u64>,
    /// The process's peak resident set size (VmHWM) when the manifest was written, in bytes,
    /// where the platform reports it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub peak_rss_bytes: Option<u64>,
    /// The job roots (absolute directories; job ids are paths relative to them) whose jobs this
    /// manifest records. A run from another root into the same directory is refused unless asked
    /// for (`--allow-other-root`), since equal ids from two roots would replace each other's records.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub job_roots: Vec<String>,
    /// While a run is in progress: jobs being re-run whose record is still the previous run's
    /// (their files on disk are still the previous ones until they finish).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub rerunning: Vec<String>,
}

/// Which part of a split run a fragment holds, and what the scheduler called it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShardFacts {
    pub index: usize,
    pub count: usize,
    /// Jobs (valid and invalid) in the whole job set, over all shards.
    pub plan_jobs: usize,
    /// Digest of the whole job set's sorted ids: fragments of one run agree on it.
    pub plan_digest: Digest,
    /// Jobs assigned to this shard.
    pub assigned: usize,
    pub host: String,
    /// The scheduler's own names for this task (`SLURM_ARRAY_JOB_ID`, `SLURM_ARRAY_TASK_ID`,
    /// `SLURM_JOB_ID`, `JOB_COMPLETION_INDEX`, as present).
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub scheduler: std::collections::BTreeMap<String, String>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    pub format: String,
    pub tool: Tool,
    pub deterministic_digest: Digest,
    pub jobs: Vec<JobRecord>,
    pub run: RunFacts,
}

impl Manifest {
    /// Builds a manifest from records (sorted here) and computes its deterministic digest.
    pub fn new(jobs: Vec<JobRecord>, run: RunFacts) -> Manifest {
        Manifest::with_tool(Tool::current(), jobs, run)
    }

    /// A manifest of records written by `tool` (a merge keeps the fragments' tool).
    pub fn with_tool(tool: Tool, mut jobs: Vec<JobRecord>, run: RunFacts) -> Manifest {
        jobs.sort_by(|a, b| a.id.cmp(&b.id));
        let deterministic_digest = deterministic_digest(&tool, &jobs);
        Manifest { format: FORMAT.into(), tool, deterministic_digest, jobs, run }
    }

    /// Recomputes the deterministic digest from the content (to detect edits).
    pub fn recompute_digest(&self) -> Digest {
        deterministic_digest(&self.tool, &self.jobs)
    }

    pub fn load(path: &Path) -> Result<Manifest, Error> {
        let bytes = crate::files::read_limited(path, crate::files::MAX_MANIFEST_BYTES).map_err(|e| Error::io(path, "read manifest", e))?;
        Manifest::parse(path, &bytes)
    }

    /// A manifest from its bytes (`path` names it in errors), with every check [`Manifest::load`]
    /// makes. What `cargo fuzz run manifest` feeds.
    pub fn parse(path: &Path, bytes: &[u8]) -> Result<Manifest, Error> {
        let m: Manifest = serde_json::from_slice(bytes).map_err(|e| Error::manifest(path, format!("not a texsyn manifest: {e}")))?;
        if m.format != FORMAT {
            return Err(Error::manifest(path, format!("unsupported manifest format `{}` (expected {FORMAT})", m.format)));
        }
        m.check().map_err(|reason| Error::manifest(path, reason))?;
        Ok(m)
    }

    /// Problems that make a manifest unusable, found before anything acts on it: a job id recorded
    /// twice, two jobs claiming one output file, an output path that leaves the output directory.
    ///
    /// A manifest travels (shard fragments from other nodes, CI artifacts, a colleague's run), so
    /// it is untrusted input: every value that some command turns into a file name (job ids become
    /// golden files and report sections, output paths become files to read or write) or into an
    /// allocation (sizes) is checked here, once, for every command that loads one. Each problem
    /// names the job and the key.
    pub fn check(&self) -> Result<(), String> {
        for j in &self.jobs {
            check_record(j).map_err(|reason| format!("job `{}`: {reason}", j.id.escape_debug()))?;
        }
        let mut ids = std::collections::BTreeSet::new();
        let mut dup_ids = std::collections::BTreeSet::new();
        for j in &self.jobs {
            if !ids.insert(j.id.as_str()) {
                dup_ids.insert(j.id.as_str());
            }
        }
        if !dup_ids.is_empty() {
            let n = dup_ids.len();
            let some: Vec<&str> = dup_ids.into_iter().take(5).collect();
            return Err(format!(
                "{n} job id(s) are recorded more than once (e.g. `{}`); a manifest lists each job once",
                some.join("`, `")
            ));
        }
        let mut owner: std::collections::BTreeMap<&str, &str> = std::collections::BTreeMap::new();
        for j in &self.jobs {
            for o in &j.outputs {
                if !is_inside(&o.path) {
                    return Err(format!("job `{}` records the output `{}`, which is not a path inside the output directory", j.id, o.path));
                }
                if let Some(other) = owner.insert(o.path.as_str(), j.id.as_str())
                    && other != j.id
                {
                    return Err(format!("jobs `{other}` and `{}` both record the output `{}`", j.id, o.path));
                }
            }
        }
        Ok(())
    }

    pub fn to_bytes(&self) -> Vec<u8> {
        let mut s = serde_json::to_string_pretty(self).expect("manifest serialises");
        s.push('\n');
        s.into_bytes()
    }

    pub fn job(&self, id: &str) -> Option<&JobRecord> {
        self.jobs.binary_search_by(|j| j.id.as_str().cmp(id)).ok().map(|i| &self.jobs[i])
    }
}

fn deterministic_digest(tool: &Tool, jobs: &[JobRecord]) -> Digest {
    // The canonical JSON of `{"jobs": [...], "tool": {...}}` ("jobs" sorts before "tool"), fed to
    // the hasher record by record: the same bytes as serialising the whole object at once, without
    // holding it (a merged manifest of 100 000 jobs would need gigabytes).
    let mut h = Hasher::new();
    h.update(b"{\"jobs\":[");
    for (i, j) in jobs.iter().enumerate() {
        if i > 0 {
            h.update(b",");
        }
        let mut v = serde_json::to_value(j).expect("record serialises");
        let obj = v.as_object_mut().expect("record is an object");
        obj.remove("timing");
        if j.status == Status::UpToDate {
            obj.insert("status".into(), Value::String("ok".into()));
        }
        h.update(canonical_json(&v).as_bytes());
    }
    h.update(b"],\"tool\":");
    h.update(canonical_json(&serde_json::to_value(tool).expect("tool serialises")).as_bytes());
    h.update(b"}");
    h.finish()
}

/// The content key of a job: everything its pixels depend on, and its output spec.
pub fn content_key(method: &str, algorithm_version: u32, params: &Value, seed: u64, sample_pixels: &Digest, output_spec: &Value) -> Digest {
    Digest::of_json(&serde_json::json!({
        "method": method,
        "algorithm_version": algorithm_version,
        "params": params,
        "seed": seed,
        "sample_pixels": sample_pixels,
        "output": output_spec,
    }))
}

/// The largest side recorded for an output or a sample: what job files accept
/// ([`crate::batch::job::MAX_OUTPUT_SIDE`]).
const MAX_SIDE: u64 = crate::batch::job::MAX_OUTPUT_SIDE as u64;

/// Whether a job id can be used to name files: the part before `#` (the job file's path relative to
/// its root) is a relative `/`-separated path that stays inside the root, and no part of the id has
/// control characters. Golden files and report sections are named after it.
pub fn check_id(id: &str) -> Result<(), String> {
    if id.chars().any(char::is_control) {
        return Err("`id`: has control characters".into());
    }
    let file = id.split('#').next().unwrap_or(id);
    if !is_inside(file) {
        return Err(format!(
            "`id`: `{}` is not a relative path inside the job root (no leading `/`, no `..`, `.` or empty parts, no `\\`)",
            file
        ));
    }
    Ok(())
}

/// The checks of [`Manifest::check`] that concern one record alone.
fn check_record(j: &JobRecord) -> Result<(), String> {
    check_id(&j.id)?;
    for (k, o) in j.outputs.iter().enumerate() {
        if !matches!(o.bit_depth, 0 | 8 | 16 | 32) {
            return Err(format!("`outputs[{k}].bit_depth`: {} is not 0, 8, 16 or 32", o.bit_depth));
        }
        side(&format!("outputs[{k}]"), u64::from(o.width), u64::from(o.height), true)?;
    }
    if let Some(s) = &j.sample {
        side("sample", u64::from(s.width), u64::from(s.height), false)?;
    }
    for (k, c) in j.companions.iter().enumerate() {
        side(&format!("companions[{k}]"), u64::from(c.width), u64::from(c.height), false)?;
    }
    if let Some(spec) = &j.output_spec {
        check_output_spec(spec)?;
    }
    if let Some(seams) = &j.seams {
        for (axis, bands) in [("columns", &seams.columns), ("rows", &seams.rows)] {
            if let Some(b) = bands.iter().find(|b| u64::from(b.start) + u64::from(b.len) > MAX_SIDE + 1) {
                return Err(format!(
                    "`seams.{axis}`: a band at {}..{} lies beyond any output side",
                    b.start,
                    u64::from(b.start) + u64::from(b.len)
                ));
            }
        }
    }
    Ok(())
}

/// Width and height of something recorded: at most [`MAX_SIDE`] (and not 0 where `zero_ok` is
/// false and the record is an image; JSON extras record 0×0).
fn side(key: &str, w: u64, h: u64, zero_ok: bool) -> Result<(), String> {
    for (k, v) in [("width", w), ("height", h)] {
        if v > MAX_SIDE || (!zero_ok && v == 0) {
            return Err(format!("`{key}.{k}`: {v} is out of range {}..={MAX_SIDE}", u8::from(!zero_ok)));
        }
    }
    Ok(())
}

/// The recorded output spec: what `verify` rebuilds a job's output from. Sizes within what job
/// files accept, every path inside the output directory.
fn check_output_spec(spec: &Value) -> Result<(), String> {
    let Some(obj) = spec.as_object() else { return Err("`output_spec`: is not a table".into()) };
    for k in ["width", "height"] {
        match obj.get(k) {
            None => {}
            Some(v) => match v.as_u64() {
                Some(n) if (1..=MAX_SIDE).contains(&n) => {}
                _ => return Err(format!("`output_spec.{k}`: {v} is out of range 1..={MAX_SIDE}")),
            },
        }
    }
    if let Some(v) = obj.get("bit_depth")
        && !v.as_u64().is_some_and(|d| matches!(d, 8 | 16 | 32))
    {
        return Err(format!("`output_spec.bit_depth`: {v} is not 8, 16 or 32"));
    }
    let path = |key: &str, v: &Value| -> Result<(), String> {
        match v.as_str() {
            Some(p) if is_inside(p) => Ok(()),
            _ => Err(format!("`{key}`: {v} is not a path inside the output directory")),
        }
    };
    for k in ["path", "source_map"] {
        if let Some(v) = obj.get(k).filter(|v| !v.is_null()) {
            path(&format!("output_spec.{k}"), v)?;
        }
    }
    if let Some(c) = obj.get("companions") {
        let Some(list) = c.as_array() else { return Err("`output_spec.companions`: is not a list".into()) };
        for (k, c) in list.iter().enumerate() {
            let key = format!("output_spec.companions[{k}].path");
            path(&key, c.get("path").unwrap_or(&Value::Null))?;
            if let Some(v) = c.get("bit_depth")
                && !v.as_u64().is_some_and(|d| matches!(d, 8 | 16 | 32))
            {
                return Err(format!("`output_spec.companions[{k}].bit_depth`: {v} is not 8, 16 or 32"));
            }
        }
    }
    Ok(())
}

/// Whether a recorded output path is relative, `/`-separated and stays inside its directory.
pub fn is_inside(path: &str) -> bool {
    !path.is_empty() && !path.starts_with('/') && !path.contains('\\') && path.split('/').all(|c| !c.is_empty() && c != "." && c != "..")
}

/// `path` relative to `base` when it lies under it (or reachable with `..`), `/`-separated;
/// absolute otherwise. Both are made absolute first.
pub fn relative_path(path: &Path, base: &Path) -> String {
    let abs = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    let (p, b) = (normalise(&abs(path)), normalise(&abs(base)));
    let pc: Vec<_> = p.components().collect();
    let bc: Vec<_> = b.components().collect();
    let common = pc.iter().zip(&bc).take_while(|(a, b)| a == b).count();
    if common == 0 {
        return p.to_string_lossy().replace('\\', "/");
    }
    let mut parts: Vec<String> = vec!["..".into(); bc.len() - common];
    parts.extend(pc[common..].iter().map(|c| c.as_os_str().to_string_lossy().into_owned()));
    if parts.is_empty() { ".".into() } else { parts.join("/") }
}

/// Removes `.` and resolves `..` lexically.
fn normalise(p: &Path) -> std::path::PathBuf {
    let mut out = std::path::PathBuf::new();
    for c in p.components() {
        match c {
            std::path::Component::CurDir => {}
            std::path::Component::ParentDir => {
                out.pop();
            }
            other => out.push(other.as_os_str()),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(id: &str, status: Status) -> JobRecord {
        JobRecord {
            id: id.into(),
            job_file: FileRef { path: "jobs/a.toml".into(), digest: Digest::of_bytes(b"a") },
            status,
            error: None,
            method: Some("quilting".into()),
            algorithm_version: Some(1),
            params: Some(serde_json::json!({"block": 50})),
            params_digest: None,
            seed: Some(1),
            sample: None,
            output_spec: None,
            content_key: None,
            outputs: vec![],
            seams: None,
            warnings: Vec::new(),
            companions: Vec::new(),
            more_companions: Vec::new(),
            sample_mask: None,
            inpaint_mask: None,
            guide_target: None,
            guide_source: None,
            samples: Vec::new(),
            sample_masks: Vec::new(),
            diagnostics: Value::Null,
            metrics: None,
            timing: Some(Timing {
                synthesis_seconds: 1.0,
                metrics_seconds: 0.0,
                phases: Default::default(),
                total_seconds: 2.0,
                finished_at: 5,
                estimated_peak_bytes: None,
            }),
        }
    }

    fn with_output(mut r: JobRecord, path: &str) -> JobRecord {
        let d = Digest::of_bytes(path.as_bytes());
        r.outputs.push(OutputRecord {
            path: path.into(),
            format: "png".into(),
            bit_depth: 8,
            width: 1,
            height: 1,
            file_digest: d.clone(),
            pixel_digest: d,
        });
        r
    }

    #[test]
    fn manifests_with_duplicate_ids_shared_outputs_or_escaping_paths_are_refused_on_load() {
        let dir = std::env::temp_dir().join(format!("texsyn-manifest-check-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("manifest.json");
        let load = |jobs: Vec<JobRecord>| {
            // Written as texsyn would, but with the problem in it.
            let m = Manifest {
                format: FORMAT.into(),
                tool: Tool::current(),
                deterministic_digest: Digest::of_bytes(b""),
                jobs,
                run: RunFacts::default(),
            };
            std::fs::write(&path, m.to_bytes()).unwrap();
            Manifest::load(&path).map(|_| ()).map_err(|e| e.to_string())
        };
        assert!(load(vec![with_output(record("a", Status::Ok), "a.png"), with_output(record("b", Status::Ok), "b.png")]).is_ok());
        let many: Vec<JobRecord> = (0..200).flat_map(|_| [record("a", Status::Ok), record("b", Status::Ok)]).collect();
        let e = load(many).unwrap_err();
        assert!(e.contains("2 job id(s) are recorded more than once") && e.contains("manifest.json"), "{e}");
        let e = load(vec![with_output(record("a", Status::Ok), "x.png"), with_output(record("b", Status::Ok), "x.png")]).unwrap_err();
        assert!(e.contains("jobs `a` and `b` both record the output `x.png`"), "{e}");
        for bad in ["../x.png", "/etc/x.png", "a/../../x.png", "a//x.png", ""] {
            let e = load(vec![with_output(record("a", Status::Ok), bad)]).unwrap_err();
            assert!(e.contains("not a path inside the output directory"), "{bad}: {e}");
        }
    }

    #[test]
    fn the_streamed_digest_is_the_digest_of_the_whole_canonical_object() {
        let jobs = vec![record("a", Status::Ok), record("b", Status::UpToDate), with_output(record("c", Status::Failed), "c.png")];
        let projected: Vec<Value> = jobs
            .iter()
            .map(|j| {
                let mut v = serde_json::to_value(j).unwrap();
                v.as_object_mut().unwrap().remove("timing");
                if j.status == Status::UpToDate {
                    v["status"] = Value::String("ok".into());
                }
                v
            })
            .collect();
        let tool = Tool::current();
        assert_eq!(deterministic_digest(&tool, &jobs), Digest::of_json(&serde_json::json!({"tool": tool, "jobs": projected})));
        assert_eq!(deterministic_digest(&tool, &[]), Digest::of_json(&serde_json::json!({"tool": tool, "jobs": []})));
    }

    #[test]
    fn deterministic_digest_ignores_timing_run_facts_and_up_to_date() {
        let a = Manifest::new(vec![record("b", Status::Ok), record("a", Status::Ok)], RunFacts::default());
        let mut r = record("a", Status::UpToDate);
        r.timing = None;
        let b = Manifest::new(vec![r, record("b", Status::Ok)], RunFacts { host: "elsewhere".into(), ..RunFacts::default() });
        assert_eq!(a.deterministic_digest, b.deterministic_digest);
        assert_eq!(a.jobs[0].id, "a");
        let mut c = a.clone();
        c.jobs[0].seed = Some(2);
        assert_ne!(c.recompute_digest(), a.deterministic_digest);
    }

    #[test]
    fn manifest_round_trips_through_json() {
        let a = Manifest::new(vec![record("x", Status::Failed)], RunFacts::default());
        let back: Manifest = serde_json::from_slice(&a.to_bytes()).unwrap();
        assert_eq!(a, back);
        assert_eq!(back.recompute_digest(), a.deterministic_digest);
    }

    #[test]
    fn relative_paths() {
        assert_eq!(relative_path(Path::new("/a/b/c.png"), Path::new("/a/out")), "../b/c.png");
        assert_eq!(relative_path(Path::new("/a/out/x/y.png"), Path::new("/a/out")), "x/y.png");
    }
}
