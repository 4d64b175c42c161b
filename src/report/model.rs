//! What a report is about, read from a manifest: the counted jobs, grouped by sample (rows) and by
//! the chosen grouping (columns), and the jobs that did not count.
//!
//! Every later stage (tables, sheets, plot, page) works from this one view, so they cannot
//! disagree on which jobs count or how they are grouped.

use crate::batch::manifest::{JobRecord, Manifest};
use serde_json::Value;
use std::cmp::Ordering;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// One component of the column grouping.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum GroupKey {
    Method,
    /// A resolved parameter, by name (`param:block`).
    Param(String),
    /// The output size, `W×H`.
    Size,
    Seed,
}

/// The column grouping. Jobs that agree on every key share a column; what else distinguishes
/// them (seeds, usually) becomes the spread of that column.
#[derive(Clone, Debug, PartialEq, Eq, Default)]
pub enum GroupBy {
    /// The method plus every parameter that varies among that method's jobs (and the output size
    /// where it varies on its own): one column per setting, so a seed sweep collapses into a
    /// spread while a block-size sweep (paper 003's B = 50 and B = 100) stays apart.
    #[default]
    Auto,
    /// Exactly these keys, e.g. `method,param:block`.
    Keys(Vec<GroupKey>),
}

impl std::str::FromStr for GroupBy {
    type Err = String;
    fn from_str(s: &str) -> Result<GroupBy, String> {
        if s.trim() == "auto" {
            return Ok(GroupBy::Auto);
        }
        let mut keys = Vec::new();
        for part in s.split(',').map(str::trim) {
            let key = match part {
                "method" => GroupKey::Method,
                "size" => GroupKey::Size,
                "seed" => GroupKey::Seed,
                p if p.starts_with("param:") && p.len() > "param:".len() => GroupKey::Param(p["param:".len()..].to_string()),
                other => {
                    return Err(format!(
                        "unknown grouping `{other}`: use `auto` or a comma-separated list of method, param:NAME, size, seed"
                    ));
                }
            };
            if keys.contains(&key) {
                return Err(format!("grouping `{part}` is given twice"));
            }
            keys.push(key);
        }
        Ok(GroupBy::Keys(keys))
    }
}

impl std::fmt::Display for GroupBy {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let GroupBy::Keys(keys) = self else { return write!(f, "auto") };
        let parts: Vec<String> = keys
            .iter()
            .map(|k| match k {
                GroupKey::Method => "method".into(),
                GroupKey::Param(p) => format!("param:{p}"),
                GroupKey::Size => "size".into(),
                GroupKey::Seed => "seed".into(),
            })
            .collect();
        write!(f, "{}", parts.join(","))
    }
}

/// A grouping value, ordered numerically when it is a number (block 100 after block 50).
#[derive(Clone, Debug)]
pub enum KeyValue {
    Missing,
    Num(f64, String),
    Text(String),
}

impl KeyValue {
    fn of_json(v: Option<&Value>) -> KeyValue {
        match v {
            None | Some(Value::Null) => KeyValue::Missing,
            Some(Value::Number(n)) => KeyValue::Num(n.as_f64().unwrap_or(f64::NAN), n.to_string()),
            Some(v) => KeyValue::Text(param_text(v)),
        }
    }
    pub fn text(&self) -> String {
        match self {
            KeyValue::Missing => "none".into(),
            KeyValue::Num(_, s) | KeyValue::Text(s) => s.clone(),
        }
    }
    fn rank(&self) -> u8 {
        match self {
            KeyValue::Missing => 0,
            KeyValue::Num(..) => 1,
            KeyValue::Text(_) => 2,
        }
    }
}

impl Ord for KeyValue {
    fn cmp(&self, other: &Self) -> Ordering {
        match (self, other) {
            (KeyValue::Num(a, sa), KeyValue::Num(b, sb)) => a.total_cmp(b).then_with(|| sa.cmp(sb)),
            (KeyValue::Text(a), KeyValue::Text(b)) => a.cmp(b),
            _ => self.rank().cmp(&other.rank()),
        }
    }
}
impl PartialOrd for KeyValue {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl PartialEq for KeyValue {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}
impl Eq for KeyValue {}

/// A parameter value as people write it in a job file (`50`, `0.1`, `dp`).
pub fn param_text(v: &Value) -> String {
    match v {
        Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

/// A table column.
#[derive(Clone, Debug)]
pub struct Group {
    /// `quilting`, `quilting block=50`.
    pub label: String,
    /// The jobs' method.
    pub method: Option<String>,
    /// The grouping keys other than the method, with this group's value of each
    /// (`("param:block", "50")`), so groups of different methods can be paired.
    pub key: Vec<(String, String)>,
    /// The parameters not in the key, each with its value(s) in this group (`overlap=8`, or
    /// `overlap=8|10` where they differ), for captions.
    pub params_label: String,
}

/// A table row.
#[derive(Clone, Debug)]
pub struct SampleInfo {
    /// The sample file's stem (its path where stems collide).
    pub key: String,
    /// As recorded in the manifest.
    pub recorded_path: String,
    pub path: PathBuf,
    pub width: u32,
    pub height: u32,
    pub pixel_digest: String,
}

/// The first output of a job, where the report finds its pixels.
#[derive(Clone, Debug)]
pub struct OutputInfo {
    pub recorded_path: String,
    pub path: PathBuf,
    pub width: u32,
    pub height: u32,
    pub pixel_digest: String,
}

/// A counted (ok or up-to-date) job.
#[derive(Clone, Debug)]
pub struct Entry {
    pub job_id: String,
    pub sample: usize,
    pub group: usize,
    pub seed: Option<u64>,
    /// Metric name → value; `None` where the metric is undefined for this pair of images.
    pub metrics: BTreeMap<String, Option<f64>>,
    pub synthesis_seconds: Option<f64>,
    pub output: Option<OutputInfo>,
    /// Why the method may not look right on this sample (`texsyn advise`).
    pub warnings: Vec<String>,
    /// The job's companion maps (their recorded path, and the output), in the job file's order.
    pub companions: Vec<(String, OutputInfo)>,
    /// What the job followed besides its sample (what it is, and the image): a sample mask, an
    /// inpaint mask, guides. Shown beside the output, so that input, mask or guide and output
    /// are read together.
    pub inputs: Vec<(String, OutputInfo)>,
}

/// The images a job followed besides its sample, as the record names them.
fn job_inputs(job: &JobRecord, base: &Path) -> Vec<(String, OutputInfo)> {
    // With several samples: the ones after the first (which is shown as the sample), and each
    // sample's mask.
    let more_samples = job.samples.iter().enumerate().skip(1).map(|(i, r)| (format!("sample {}", i + 1), Some(r)));
    let masks = job.sample_masks.iter().enumerate().map(|(i, r)| (format!("mask of sample {}", i + 1), r.as_ref()));
    more_samples
        .chain(masks)
        .chain(
            [
                ("sample mask", &job.sample_mask),
                ("inpaint mask", &job.inpaint_mask),
                ("target guide", &job.guide_target),
                ("source guide", &job.guide_source),
            ]
            .into_iter()
            .map(|(what, r)| (what.to_string(), r.as_ref())),
        )
        .filter_map(|(what, r)| r.map(|r| (what, r)))
        .map(|(what, r)| {
            let info = OutputInfo {
                recorded_path: r.path.clone(),
                path: resolve(base, &r.path),
                width: r.width,
                height: r.height,
                pixel_digest: r.pixel_digest.sha256.clone(),
            };
            (what, info)
        })
        .collect()
}

/// The outputs of a job that are its `[[companion]]` maps.
fn companion_outputs(job: &JobRecord, base: &Path) -> Vec<(String, OutputInfo)> {
    let wanted = job.output_spec.as_ref().and_then(|s| s.get("companions")).and_then(|c| c.as_array()).cloned().unwrap_or_default();
    wanted
        .iter()
        .filter_map(|c| c.get("path").and_then(|p| p.as_str()))
        .filter_map(|p| job.outputs.iter().find(|o| o.path == p))
        .map(|o| {
            let info = OutputInfo {
                recorded_path: o.path.clone(),
                path: resolve(base, &o.path),
                width: o.width,
                height: o.height,
                pixel_digest: o.pixel_digest.sha256.clone(),
            };
            (o.path.clone(), info)
        })
        .collect()
}

/// A job that did not count, with why.
#[derive(Clone, Debug)]
pub struct Excluded {
    pub job_id: String,
    pub status: String,
    pub reason: String,
}

#[derive(Clone, Debug)]
pub struct Model {
    pub group_by: GroupBy,
    /// What the columns are, in words (`auto` spelled out: `method + block, overlap`).
    pub grouping: String,
    pub samples: Vec<SampleInfo>,
    pub groups: Vec<Group>,
    /// In manifest (job id) order, which fixes every summation order.
    pub entries: Vec<Entry>,
    pub excluded: Vec<Excluded>,
    /// Every metric some counted job recorded: the contract's names first, in their order.
    pub metric_names: Vec<String>,
}

impl Model {
    pub fn entries_of(&self, sample: usize, group: usize) -> impl Iterator<Item = &Entry> {
        self.entries.iter().filter(move |e| e.sample == sample && e.group == group)
    }
}

fn resolve(base: &Path, recorded: &str) -> PathBuf {
    let p = Path::new(recorded);
    if p.is_absolute() { p.to_path_buf() } else { base.join(p) }
}

fn key_value(job: &JobRecord, k: &GroupKey) -> KeyValue {
    match k {
        GroupKey::Method => job.method.as_deref().map_or(KeyValue::Missing, |m| KeyValue::Text(m.into())),
        GroupKey::Param(p) => KeyValue::of_json(job.params.as_ref().and_then(|ps| ps.get(p))),
        GroupKey::Size => job
            .outputs
            .first()
            .map_or(KeyValue::Missing, |o| KeyValue::Num((o.width as u64 * o.height as u64) as f64, format!("{}×{}", o.width, o.height))),
        GroupKey::Seed => job.seed.map_or(KeyValue::Missing, |s| KeyValue::Num(s as f64, s.to_string())),
    }
}

/// How a method is shown to readers of a report: the job-file name, except that results of a
/// baseline we had to reconstruct from an outline are marked as such (docs/methods.md §2.11).
pub fn method_label(name: &str) -> String {
    match name {
        "tes" => "TES (reconstructed)".into(),
        other => other.into(),
    }
}

fn key_text(k: &GroupKey, v: &KeyValue) -> String {
    match k {
        GroupKey::Method => method_label(&v.text()),
        GroupKey::Size => v.text(),
        GroupKey::Param(p) => format!("{p}={}", v.text()),
        GroupKey::Seed => format!("seed={}", v.text()),
    }
}

/// The keys each method's jobs are grouped by: the explicit list, or for `auto` the method, the
/// parameters that take more than one value among its jobs, and the size if it still varies.
fn keys_per_method(jobs: &[&JobRecord], by: &GroupBy) -> BTreeMap<Option<String>, Vec<GroupKey>> {
    let mut per_method: BTreeMap<Option<String>, Vec<&JobRecord>> = BTreeMap::new();
    for j in jobs {
        per_method.entry(j.method.clone()).or_default().push(j);
    }
    per_method
        .into_iter()
        .map(|(method, js)| {
            let keys = match by {
                GroupBy::Keys(k) => k.clone(),
                GroupBy::Auto => {
                    let mut names: BTreeSet<String> = BTreeSet::new();
                    for j in &js {
                        if let Some(Value::Object(ps)) = &j.params {
                            names.extend(ps.keys().cloned());
                        }
                    }
                    let mut keys = vec![GroupKey::Method];
                    for n in names {
                        let k = GroupKey::Param(n);
                        let values: BTreeSet<KeyValue> = js.iter().map(|j| key_value(j, &k)).collect();
                        if values.len() > 1 {
                            keys.push(k);
                        }
                    }
                    let mut sizes: BTreeMap<Vec<KeyValue>, BTreeSet<KeyValue>> = BTreeMap::new();
                    for j in &js {
                        let setting = keys.iter().map(|k| key_value(j, k)).collect();
                        sizes.entry(setting).or_default().insert(key_value(j, &GroupKey::Size));
                    }
                    if sizes.values().any(|s| s.len() > 1) {
                        keys.push(GroupKey::Size);
                    }
                    keys
                }
            };
            (method, keys)
        })
        .collect()
}

/// Builds the view. `base` is the manifest's directory, against which recorded paths resolve.
pub fn build(manifest: &Manifest, base: &Path, group_by: &GroupBy) -> Model {
    let mut excluded = Vec::new();
    let mut counted = Vec::new();
    for job in &manifest.jobs {
        let reason = if !job.status.is_success() {
            Some(job.error.clone().unwrap_or_else(|| "no error recorded".into()))
        } else if job.sample.is_none() {
            Some("the record has no sample".into())
        } else {
            None
        };
        match reason {
            Some(reason) => excluded.push(Excluded { job_id: job.id.clone(), status: job.status.name().into(), reason }),
            None => counted.push(job),
        }
    }

    // Rows: one per sample file, named by stem unless two different files share one.
    let mut sample_paths: BTreeMap<String, &crate::batch::manifest::SampleRecord> = BTreeMap::new();
    for job in &counted {
        let s = job.sample.as_ref().expect("counted jobs have a sample");
        sample_paths.entry(s.path.clone()).or_insert(s);
    }
    let stem = |p: &str| Path::new(p).file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| p.to_string());
    let mut stem_count: BTreeMap<String, usize> = BTreeMap::new();
    for p in sample_paths.keys() {
        *stem_count.entry(stem(p)).or_default() += 1;
    }
    let mut samples: Vec<SampleInfo> = sample_paths
        .iter()
        .map(|(p, rec)| {
            let st = stem(p);
            let key = if stem_count[&st] > 1 {
                Path::new(p).with_extension("").to_string_lossy().trim_start_matches("../").to_string()
            } else {
                st
            };
            SampleInfo {
                key,
                recorded_path: p.clone(),
                path: resolve(base, p),
                width: rec.width,
                height: rec.height,
                pixel_digest: rec.pixel_digest.sha256.clone(),
            }
        })
        .collect();
    samples.sort_by(|a, b| a.key.cmp(&b.key).then_with(|| a.recorded_path.cmp(&b.recorded_path)));

    let method_keys = keys_per_method(&counted, group_by);
    // A key is (grouping key, value) pairs, so auto keys of different methods compare sensibly.
    let key_of = |job: &JobRecord| -> Vec<(String, KeyValue)> {
        method_keys[&job.method].iter().map(|k| (format!("{k:?}"), key_value(job, k))).collect()
    };
    let label_of = |job: &JobRecord| -> String {
        method_keys[&job.method].iter().map(|k| key_text(k, &key_value(job, k))).collect::<Vec<_>>().join(" ")
    };
    let mut keys: BTreeMap<Vec<(String, KeyValue)>, String> = BTreeMap::new();
    for job in &counted {
        keys.entry(key_of(job)).or_insert_with(|| label_of(job));
    }
    let keys: Vec<(Vec<(String, KeyValue)>, String)> = keys.into_iter().collect();

    let mut entries = Vec::new();
    for job in &counted {
        let s = job.sample.as_ref().expect("counted jobs have a sample");
        let sample = samples.iter().position(|x| x.recorded_path == s.path).expect("every sample has a row");
        let key = key_of(job);
        let group = keys.iter().position(|(k, _)| *k == key).expect("every key has a column");
        let output = job.outputs.first().map(|o| OutputInfo {
            recorded_path: o.path.clone(),
            path: resolve(base, &o.path),
            width: o.width,
            height: o.height,
            pixel_digest: o.pixel_digest.sha256.clone(),
        });
        entries.push(Entry {
            job_id: job.id.clone(),
            sample,
            group,
            seed: job.seed,
            metrics: metrics_and_summary(job),
            synthesis_seconds: job.timing.as_ref().map(|t| t.synthesis_seconds),
            output,
            warnings: job.warnings.clone(),
            companions: companion_outputs(job, base),
            inputs: job_inputs(job, base),
        });
    }

    let groups = keys
        .iter()
        .enumerate()
        .map(|(gi, (_, label))| {
            let jobs: Vec<&JobRecord> = counted.iter().zip(&entries).filter(|(_, e)| e.group == gi).map(|(j, _)| *j).collect();
            let in_key = jobs.first().map(|j| method_keys[&j.method].clone()).unwrap_or_default();
            let key = jobs
                .first()
                .map(|j| {
                    in_key
                        .iter()
                        .filter(|k| **k != GroupKey::Method)
                        .map(|k| (GroupBy::Keys(vec![k.clone()]).to_string(), key_value(j, k).text()))
                        .collect()
                })
                .unwrap_or_default();
            let method = jobs.first().and_then(|j| j.method.clone());
            Group { label: label.clone(), method, key, params_label: params_label(&jobs, &in_key) }
        })
        .collect();

    let mut names: BTreeSet<&str> = BTreeSet::new();
    for e in &entries {
        names.extend(e.metrics.keys().map(String::as_str));
    }
    let mut metric_names: Vec<String> = crate::metrics::METRIC_NAMES.iter().filter(|n| names.contains(*n)).map(|n| n.to_string()).collect();
    metric_names.extend(names.iter().filter(|n| !crate::metrics::METRIC_NAMES.contains(n)).map(|n| n.to_string()));

    let grouping = match group_by {
        GroupBy::Keys(_) => group_by.to_string(),
        GroupBy::Auto => {
            let parts: Vec<String> = method_keys
                .iter()
                .map(|(m, keys)| {
                    let extra: Vec<String> = keys[1..]
                        .iter()
                        .map(|k| match k {
                            GroupKey::Param(p) => p.clone(),
                            other => GroupBy::Keys(vec![other.clone()]).to_string(),
                        })
                        .collect();
                    let m = m.as_deref().unwrap_or("no method");
                    if extra.is_empty() { m.to_string() } else { format!("{m} by {}", extra.join(", ")) }
                })
                .collect();
            format!("auto ({})", parts.join("; "))
        }
    };
    Model { group_by: group_by.clone(), grouping, samples, groups, entries, excluded, metric_names }
}

fn params_label(jobs: &[&JobRecord], in_key: &[GroupKey]) -> String {
    let mut values: BTreeMap<String, BTreeSet<KeyValue>> = BTreeMap::new();
    for job in jobs {
        if let Some(Value::Object(ps)) = &job.params {
            for (name, v) in ps {
                if in_key.contains(&GroupKey::Param(name.clone())) {
                    continue;
                }
                values.entry(name.clone()).or_default().insert(KeyValue::of_json(Some(v)));
            }
        }
    }
    values
        .iter()
        .map(|(name, vs)| format!("{name}={}", vs.iter().map(KeyValue::text).collect::<Vec<_>>().join("|")))
        .collect::<Vec<_>>()
        .join(" ")
}

/// A job's metrics, plus the numbers its method put in `diagnostics.summary` as `diag.<name>`
/// (`null` there means "not applicable to this run", e.g. iterations of a failed search): that is
/// how a method gets per-run figures such as paper 002's search success into the tables without
/// changes here. The named phases of its synthesis time become `time.<phase>_seconds` (paper
/// 001's tile-build and fill times, paper 000's iteration time).
fn metrics_and_summary(job: &JobRecord) -> BTreeMap<String, Option<f64>> {
    let mut m = job.metrics.clone().unwrap_or_default();
    if let Some(timing) = &job.timing {
        for (phase, seconds) in &timing.phases {
            m.insert(format!("time.{phase}_seconds"), Some(*seconds));
        }
    }
    if let Some(summary) = job.diagnostics.get("summary").and_then(|v| v.as_object()) {
        for (k, v) in summary {
            if v.is_number() || v.is_null() {
                m.insert(format!("diag.{k}"), v.as_f64());
            }
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn group_by_parses_combinations_and_refuses_nonsense() {
        let g: GroupBy = "method,param:block".parse().unwrap();
        assert_eq!(g, GroupBy::Keys(vec![GroupKey::Method, GroupKey::Param("block".into())]));
        assert_eq!(g.to_string(), "method,param:block");
        assert_eq!("auto".parse::<GroupBy>().unwrap(), GroupBy::Auto);
        assert!("param:".parse::<GroupBy>().is_err());
        assert!("colour".parse::<GroupBy>().is_err());
        assert!("method,method".parse::<GroupBy>().is_err());
    }

    #[test]
    fn numeric_values_sort_numerically() {
        let mut v = [KeyValue::Num(100.0, "100".into()), KeyValue::Text("dp".into()), KeyValue::Num(50.0, "50".into()), KeyValue::Missing];
        v.sort();
        let texts: Vec<String> = v.iter().map(KeyValue::text).collect();
        assert_eq!(texts, ["none", "50", "100", "dp"]);
    }

    fn manifest(jobs: Vec<Value>) -> Manifest {
        let d = serde_json::json!({"sha256": "00"});
        let jobs: Vec<Value> = jobs
            .into_iter()
            .map(|mut j| {
                let o = j.as_object_mut().unwrap();
                o.insert("job_file".into(), serde_json::json!({"path": "j.toml", "digest": d}));
                o.entry("status").or_insert("ok".into());
                o.insert(
                    "sample".into(),
                    serde_json::json!({"path": "s/bricks.png", "file_digest": d, "pixel_digest": d, "width": 64, "height": 64}),
                );
                j
            })
            .collect();
        serde_json::from_value(serde_json::json!({
            "format": crate::batch::manifest::FORMAT,
            "tool": {"name": "texsyn", "version": "0", "commit": "x"},
            "deterministic_digest": d,
            "jobs": jobs,
            "run": crate::batch::manifest::RunFacts::default(),
        }))
        .unwrap()
    }

    fn job(id: &str, method: &str, block: u32, seed: u64) -> Value {
        serde_json::json!({"id": id, "method": method, "seed": seed, "params": {"block": block, "cut": "dp"},
            "metrics": {"kl_gray": seed as f64, "acf_gray": null}})
    }

    #[test]
    fn reconstructed_baselines_are_labelled() {
        let m = manifest(vec![job("a", "tes", 50, 1), job("b", "coevolution", 50, 1)]);
        let model = build(&m, Path::new("."), &"method".parse().unwrap());
        let labels: Vec<&str> = model.groups.iter().map(|g| g.label.as_str()).collect();
        assert_eq!(labels, ["coevolution", "TES (reconstructed)"]);
    }

    #[test]
    fn auto_grouping_separates_settings_and_pools_seeds() {
        let m = manifest(vec![
            job("a", "quilting", 50, 1),
            job("b", "quilting", 50, 2),
            job("c", "quilting", 100, 1),
            job("d", "other", 7, 1),
            serde_json::json!({"id": "e", "status": "failed", "error": "boom"}),
        ]);
        let model = build(&m, Path::new("."), &GroupBy::Auto);
        let labels: Vec<&str> = model.groups.iter().map(|g| g.label.as_str()).collect();
        assert_eq!(labels, ["other", "quilting block=50", "quilting block=100"]);
        assert_eq!(model.entries_of(0, 1).count(), 2, "two seeds share a column");
        assert_eq!(model.groups[1].params_label, "cut=dp");
        assert_eq!(model.excluded.len(), 1);
        assert_eq!(model.excluded[0].reason, "boom");
        assert_eq!(model.metric_names, ["kl_gray", "acf_gray"]);
        assert_eq!(model.entries[0].metrics["acf_gray"], None);
        let by_method = build(&m, Path::new("."), &"method".parse().unwrap());
        let labels: Vec<&str> = by_method.groups.iter().map(|g| g.label.as_str()).collect();
        assert_eq!(labels, ["other", "quilting"]);
        assert_eq!(by_method.groups[1].params_label, "block=50|100 cut=dp");
    }

    #[test]
    fn a_methods_diagnostics_summary_becomes_columns() {
        let mut a = job("a", "patch-sampling", 30, 1);
        a["diagnostics"] = serde_json::json!({"summary": {"success": 1.0, "iterations_when_successful": 12.0}, "blocks": {"cols": 2}});
        let mut b = job("b", "patch-sampling", 30, 2);
        b["diagnostics"] = serde_json::json!({"summary": {"success": 0.0, "iterations_when_successful": null}});
        let model = build(&manifest(vec![a, b]), Path::new("."), &GroupBy::Auto);
        assert!(model.metric_names.contains(&"diag.success".to_string()), "{:?}", model.metric_names);
        assert_eq!(model.entries[0].metrics["diag.success"], Some(1.0));
        assert_eq!(model.entries[1].metrics["diag.iterations_when_successful"], None);
        assert!(!model.metric_names.iter().any(|n| n.contains("blocks")), "only the summary object counts");
    }

    #[test]
    fn speedups_pair_each_group_with_the_baselines_matching_group() {
        let timed = |id: &str, method: &str, rows: u32, seed: u64, seconds: f64| {
            let mut j = job(id, method, 30, seed);
            j["params"] = serde_json::json!({"rows": rows, "c_tol": if method == "coevolution" { 0.05 } else { 0.0 }});
            j["timing"] = serde_json::json!({"synthesis_seconds": seconds, "metrics_seconds": 0.0, "phases": {}, "total_seconds": seconds, "finished_at": 1});
            j
        };
        let m = manifest(vec![
            timed("c8a", "coevolution", 8, 1, 0.5),
            timed("c8b", "coevolution", 8, 2, 1.5),
            timed("c32", "coevolution", 32, 1, 2.0),
            timed("t8", "tes", 8, 1, 4.0),
            timed("t32", "tes", 32, 1, 20.0),
            timed("t12", "tes", 12, 1, 7.0),
        ]);
        let model = build(&m, Path::new("."), &GroupBy::Auto);
        let tables = crate::report::tables::build(&model);
        let s = crate::report::tables::speedups(&model, &tables, "tes");
        assert_eq!(s.len(), 1, "only the synthesis time is recorded");
        let label = |g: usize| model.groups[g].label.clone();
        let pairs: Vec<(String, String)> = s[0].pairs.iter().map(|&(g, b)| (label(g), label(b))).collect();
        assert_eq!(
            pairs,
            [
                ("coevolution rows=8".to_string(), "TES (reconstructed) rows=8".to_string()),
                ("coevolution rows=32".into(), "TES (reconstructed) rows=32".into())
            ]
        );
        assert!(s[0].title.starts_with("Speed-up over TES (reconstructed) — "), "{}", s[0].title);
        // Ratio of the cells' means: 4.0 / mean(0.5, 1.5) and 20 / 2.
        assert_eq!(s[0].cells[0], [Some(4.0), Some(10.0)]);
        assert_eq!(s[0].mean[1], (Some(10.0), 1));
        let md = crate::report::tables::speedup_markdown(&model, &s);
        assert!(md.contains("| 4.000× | 10.00× |"), "{md}");
        assert!(crate::report::tables::speedups(&model, &tables, "nonexistent").is_empty());
    }

    #[test]
    fn named_phases_become_time_columns() {
        let mut a = job("a", "rw-tiles", 30, 1);
        a["timing"] = serde_json::json!({"synthesis_seconds": 0.5, "metrics_seconds": 0.0, "phases": {"fill": 0.25, "tile_build": 0.125}, "total_seconds": 1.0, "finished_at": 1});
        let b = job("b", "rw-tiles", 30, 2);
        let model = build(&manifest(vec![a, b]), Path::new("."), &GroupBy::Auto);
        assert_eq!(model.entries[0].metrics["time.tile_build_seconds"], Some(0.125));
        assert_eq!(model.entries[0].metrics["time.fill_seconds"], Some(0.25));
        assert!(!model.entries[1].metrics.contains_key("time.fill_seconds"));
        assert!(model.metric_names.contains(&"time.fill_seconds".to_string()));
    }
}
