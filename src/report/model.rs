//! What a report is about, read from a manifest: the counted jobs, grouped by sample (rows) and by
//! the chosen grouping (columns), and the jobs that did not count.
//!
//! Every later stage (tables, sheets, plot, page) works from this one view, so they cannot
//! disagree on which jobs count or how they are grouped.

use crate::manifest::{JobRecord, Manifest};
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

/// The column grouping, e.g. `method,param:block`. Jobs that agree on every key share a column;
/// the rest of what distinguishes them (seeds, usually) becomes the spread of that column.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GroupBy(pub Vec<GroupKey>);

impl Default for GroupBy {
    fn default() -> Self {
        GroupBy(vec![GroupKey::Method])
    }
}

impl std::str::FromStr for GroupBy {
    type Err = String;
    fn from_str(s: &str) -> Result<GroupBy, String> {
        let mut keys = Vec::new();
        for part in s.split(',').map(str::trim) {
            let key = match part {
                "method" => GroupKey::Method,
                "size" => GroupKey::Size,
                "seed" => GroupKey::Seed,
                p if p.starts_with("param:") && p.len() > "param:".len() => GroupKey::Param(p["param:".len()..].to_string()),
                other => {
                    return Err(format!(
                        "unknown grouping `{other}`: use a comma-separated list of method, param:NAME, size, seed"
                    ));
                }
            };
            if keys.contains(&key) {
                return Err(format!("grouping `{part}` is given twice"));
            }
            keys.push(key);
        }
        Ok(GroupBy(keys))
    }
}

impl std::fmt::Display for GroupBy {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let parts: Vec<String> = self
            .0
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
    pub key: Vec<KeyValue>,
    /// `quilting`, `quilting block=50`.
    pub label: String,
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

/// The `metrics` object of every job in the raw manifest JSON, by job id. Read from the JSON
/// rather than the typed record so the report accepts any manifest that carries the field.
pub fn raw_metrics(raw: &Value) -> Result<BTreeMap<String, BTreeMap<String, Option<f64>>>, String> {
    let mut out = BTreeMap::new();
    let Some(jobs) = raw.get("jobs").and_then(Value::as_array) else { return Ok(out) };
    for job in jobs {
        let id = job.get("id").and_then(Value::as_str).unwrap_or_default().to_string();
        match job.get("metrics") {
            None | Some(Value::Null) => {}
            Some(Value::Object(map)) => {
                let mut m = BTreeMap::new();
                for (name, v) in map {
                    let value = match v {
                        Value::Null => None,
                        Value::Number(n) => Some(n.as_f64().ok_or_else(|| format!("job `{id}`: metric `{name}` is not a number"))?),
                        _ => return Err(format!("job `{id}`: metric `{name}` must be a number or null, found {v}")),
                    };
                    m.insert(name.clone(), value);
                }
                out.insert(id, m);
            }
            Some(other) => return Err(format!("job `{id}`: `metrics` must be an object, found {other}")),
        }
    }
    Ok(out)
}

fn resolve(base: &Path, recorded: &str) -> PathBuf {
    let p = Path::new(recorded);
    if p.is_absolute() { p.to_path_buf() } else { base.join(p) }
}

fn group_key(job: &JobRecord, by: &GroupBy) -> Vec<KeyValue> {
    by.0.iter()
        .map(|k| match k {
            GroupKey::Method => job.method.as_deref().map_or(KeyValue::Missing, |m| KeyValue::Text(m.into())),
            GroupKey::Param(p) => KeyValue::of_json(job.params.as_ref().and_then(|ps| ps.get(p))),
            GroupKey::Size => job
                .outputs
                .first()
                .map_or(KeyValue::Missing, |o| KeyValue::Num((o.width as u64 * o.height as u64) as f64, format!("{}×{}", o.width, o.height))),
            GroupKey::Seed => job.seed.map_or(KeyValue::Missing, |s| KeyValue::Num(s as f64, s.to_string())),
        })
        .collect()
}

fn group_label(by: &GroupBy, key: &[KeyValue]) -> String {
    by.0.iter()
        .zip(key)
        .map(|(k, v)| match k {
            GroupKey::Method | GroupKey::Size => v.text(),
            GroupKey::Param(p) => format!("{p}={}", v.text()),
            GroupKey::Seed => format!("seed={}", v.text()),
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// Builds the view. `base` is the manifest's directory, against which recorded paths resolve.
pub fn build(manifest: &Manifest, raw: &Value, base: &Path, group_by: &GroupBy) -> Result<Model, String> {
    let metrics = raw_metrics(raw)?;
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
    let mut sample_paths: BTreeMap<String, &crate::manifest::SampleRecord> = BTreeMap::new();
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

    let mut keys: BTreeSet<Vec<KeyValue>> = BTreeSet::new();
    for job in &counted {
        keys.insert(group_key(job, group_by));
    }
    let keys: Vec<Vec<KeyValue>> = keys.into_iter().collect();

    let mut entries = Vec::new();
    for job in &counted {
        let s = job.sample.as_ref().expect("counted jobs have a sample");
        let sample = samples.iter().position(|x| x.recorded_path == s.path).expect("every sample has a row");
        let key = group_key(job, group_by);
        let group = keys.iter().position(|k| *k == key).expect("every key has a column");
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
            metrics: metrics.get(&job.id).cloned().unwrap_or_default(),
            synthesis_seconds: job.timing.as_ref().map(|t| t.synthesis_seconds),
            output,
        });
    }

    let groups = keys
        .iter()
        .enumerate()
        .map(|(gi, key)| {
            let jobs: Vec<&JobRecord> = counted.iter().zip(&entries).filter(|(_, e)| e.group == gi).map(|(j, _)| *j).collect();
            Group { key: key.clone(), label: group_label(group_by, key), params_label: params_label(&jobs, group_by) }
        })
        .collect();

    let mut names: BTreeSet<&str> = BTreeSet::new();
    for e in &entries {
        names.extend(e.metrics.keys().map(String::as_str));
    }
    let mut metric_names: Vec<String> =
        crate::metrics::METRIC_NAMES.iter().filter(|n| names.contains(*n)).map(|n| n.to_string()).collect();
    metric_names.extend(names.iter().filter(|n| !crate::metrics::METRIC_NAMES.contains(n)).map(|n| n.to_string()));

    Ok(Model { group_by: group_by.clone(), samples, groups, entries, excluded, metric_names })
}

fn params_label(jobs: &[&JobRecord], by: &GroupBy) -> String {
    let mut values: BTreeMap<String, BTreeSet<KeyValue>> = BTreeMap::new();
    for job in jobs {
        if let Some(Value::Object(ps)) = &job.params {
            for (name, v) in ps {
                if by.0.contains(&GroupKey::Param(name.clone())) {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn group_by_parses_combinations_and_refuses_nonsense() {
        let g: GroupBy = "method,param:block".parse().unwrap();
        assert_eq!(g, GroupBy(vec![GroupKey::Method, GroupKey::Param("block".into())]));
        assert_eq!(g.to_string(), "method,param:block");
        assert!("param:".parse::<GroupBy>().is_err());
        assert!("colour".parse::<GroupBy>().is_err());
        assert!("method,method".parse::<GroupBy>().is_err());
    }

    #[test]
    fn numeric_values_sort_numerically() {
        let mut v = vec![
            KeyValue::Num(100.0, "100".into()),
            KeyValue::Text("dp".into()),
            KeyValue::Num(50.0, "50".into()),
            KeyValue::Missing,
        ];
        v.sort();
        let texts: Vec<String> = v.iter().map(KeyValue::text).collect();
        assert_eq!(texts, ["none", "50", "100", "dp"]);
    }

    #[test]
    fn raw_metrics_accepts_numbers_and_nulls_only() {
        let raw = serde_json::json!({"jobs": [
            {"id": "a", "metrics": {"kl_gray": 0.5, "acf_gray": null}},
            {"id": "b"}
        ]});
        let m = raw_metrics(&raw).unwrap();
        assert_eq!(m["a"]["kl_gray"], Some(0.5));
        assert_eq!(m["a"]["acf_gray"], None);
        assert!(!m.contains_key("b"));
        let bad = serde_json::json!({"jobs": [{"id": "a", "metrics": {"kl_gray": "high"}}]});
        assert!(raw_metrics(&bad).unwrap_err().contains("kl_gray"));
    }
}
