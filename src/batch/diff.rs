//! What changed between two runs: the question a nightly run's reader has in the morning.
//!
//! Jobs are matched by id. For each job the diff says whether it was added or removed, started or
//! stopped failing, whether its pixels changed and — from the two records alone — why: every
//! input of its content key compared key by key (method, algorithm version, each parameter,
//! seed, sample pixels, output spec), or the tool when no input moved. Time and metric moves
//! beyond a threshold are listed apart: they are news, not regressions of the pixels.

use crate::batch::manifest::{JobRecord, Manifest};
use serde::Serialize;
use serde_json::Value;
use std::collections::{BTreeMap, BTreeSet};

/// When a number moved enough to be reported.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Thresholds {
    /// Relative change of a job's synthesis time (0.2 = ±20 %)…
    pub time_relative: f64,
    /// …and at least this many seconds (timings of fast jobs are noise).
    pub time_seconds: f64,
    /// Relative change of a metric (0.05 = 5 %), or an absolute 1e-6 near zero.
    pub metric_relative: f64,
}

impl Default for Thresholds {
    fn default() -> Thresholds {
        Thresholds { time_relative: 0.2, time_seconds: 0.05, metric_relative: 0.05 }
    }
}

/// One input of a job that differs between the runs.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct KeyChange {
    /// Dotted key: `params.block`, `algorithm_version`, `sample.pixels`, `output_spec.width`, `tool.commit`…
    pub key: String,
    pub old: Value,
    pub new: Value,
}

/// A job whose pixels differ.
#[derive(Clone, Debug, Serialize)]
pub struct PixelChange {
    pub id: String,
    /// Output paths whose pixel digests differ (or that exist in one run only).
    pub outputs: Vec<String>,
    /// Why: the inputs that differ; empty when none does and the tool did not change either
    /// (then the run was not reproducible, which is a bug).
    pub because: Vec<KeyChange>,
}

/// A number that moved beyond its threshold.
#[derive(Clone, Debug, Serialize)]
pub struct Moved {
    pub id: String,
    /// `synthesis_seconds` or the metric's name.
    pub what: String,
    pub old: f64,
    pub new: f64,
}

#[derive(Clone, Debug, Default, Serialize)]
pub struct Diff {
    pub added: Vec<String>,
    pub removed: Vec<String>,
    /// Succeeded before, failed or invalid now: (id, error).
    pub failed_now: Vec<(String, String)>,
    /// Failed or invalid before, succeeded now.
    pub fixed_now: Vec<String>,
    pub pixels_changed: Vec<PixelChange>,
    pub slower: Vec<Moved>,
    pub faster: Vec<Moved>,
    pub metrics_moved: Vec<Moved>,
    /// Jobs in both runs with the same pixels.
    pub unchanged: usize,
    /// The tool that wrote each manifest, when they differ.
    pub tool: Vec<KeyChange>,
}

impl Diff {
    /// Whether any job's pixels changed or a job started failing (exit 4).
    pub fn pixels_differ(&self) -> bool {
        !self.pixels_changed.is_empty() || !self.failed_now.is_empty()
    }
}

/// `params.block 24 → 40; sample.pixels 63af432be344 → fa2c33c018bd`: why a job's pixels
/// changed, as `texsyn diff` and the report say it (digests shortened to 12 characters).
pub fn describe_changes(changes: &[KeyChange]) -> String {
    if changes.is_empty() {
        return "no input changed and neither did the tool: not reproducible (a bug)".into();
    }
    changes
        .iter()
        .map(|c| {
            let change = format!("{} {} → {}", c.key, short_value(&c.old), short_value(&c.new));
            // A mask is an image whose digest says little to a reader; say what it is.
            let mask = c.key == "sample_mask.pixels" || c.key == "inpaint.mask.pixels" || c.key.contains("].mask");
            if mask { format!("mask changed ({change})") } else { change }
        })
        .collect::<Vec<_>>()
        .join("; ")
}

/// A changed value as people read it: a digest by its first 12 characters, `(none)` for absent.
pub fn short_value(v: &Value) -> String {
    match v {
        Value::String(s) if s.len() == 64 && s.chars().all(|c| c.is_ascii_hexdigit()) => s[..12].to_string(),
        Value::Null => "(none)".into(),
        other => other.to_string(),
    }
}

/// Compares two manifests.
pub fn diff(old: &Manifest, new: &Manifest, t: &Thresholds) -> Diff {
    let olds: BTreeMap<&str, &JobRecord> = old.jobs.iter().map(|j| (j.id.as_str(), j)).collect();
    let news: BTreeMap<&str, &JobRecord> = new.jobs.iter().map(|j| (j.id.as_str(), j)).collect();
    let mut d = Diff { tool: differences("tool", &to_value(&old.tool), &to_value(&new.tool)), ..Diff::default() };
    d.added = news.keys().filter(|id| !olds.contains_key(*id)).map(|s| s.to_string()).collect();
    d.removed = olds.keys().filter(|id| !news.contains_key(*id)).map(|s| s.to_string()).collect();
    for (id, n) in &news {
        let Some(o) = olds.get(id) else { continue };
        match (o.status.is_success(), n.status.is_success()) {
            (true, false) => {
                d.failed_now.push((id.to_string(), n.error.clone().unwrap_or_else(|| n.status.name().to_string())));
                continue;
            }
            (false, true) => d.fixed_now.push(id.to_string()),
            (false, false) => continue,
            (true, true) => {}
        }
        let outputs = changed_outputs(o, n);
        if outputs.is_empty() {
            d.unchanged += 1;
        } else if o.status.is_success() {
            let mut because = input_changes(o, n);
            if because.is_empty() {
                because = d.tool.clone();
            }
            d.pixels_changed.push(PixelChange { id: id.to_string(), outputs, because });
        }
        if let (Some(to), Some(tn)) = (&o.timing, &n.timing) {
            let (a, b) = (to.synthesis_seconds, tn.synthesis_seconds);
            if (b - a).abs() >= t.time_seconds && (b - a).abs() >= t.time_relative * a.max(1e-9) {
                let m = Moved { id: id.to_string(), what: "synthesis_seconds".into(), old: a, new: b };
                if b > a { d.slower.push(m) } else { d.faster.push(m) }
            }
        }
        if let (Some(mo), Some(mn)) = (&o.metrics, &n.metrics) {
            for (name, vo) in mo {
                if let (Some(a), Some(Some(b))) = (vo, mn.get(name)) {
                    let delta = (b - a).abs();
                    if delta > 1e-6 && delta > t.metric_relative * a.abs() {
                        d.metrics_moved.push(Moved { id: id.to_string(), what: name.clone(), old: *a, new: *b });
                    }
                }
            }
        }
    }
    let ratio = |m: &Moved| m.new / m.old.max(1e-9);
    d.slower.sort_by(|a, b| ratio(b).total_cmp(&ratio(a)).then_with(|| a.id.cmp(&b.id)));
    d.faster.sort_by(|a, b| ratio(a).total_cmp(&ratio(b)).then_with(|| a.id.cmp(&b.id)));
    d
}

fn to_value<T: Serialize>(v: &T) -> Value {
    serde_json::to_value(v).expect("serialisable")
}

/// Outputs (by path) whose pixel digests differ, or that only one run has.
fn changed_outputs(o: &JobRecord, n: &JobRecord) -> Vec<String> {
    let a: BTreeMap<&str, &str> = o.outputs.iter().map(|x| (x.path.as_str(), x.pixel_digest.sha256.as_str())).collect();
    let b: BTreeMap<&str, &str> = n.outputs.iter().map(|x| (x.path.as_str(), x.pixel_digest.sha256.as_str())).collect();
    let paths: BTreeSet<&str> = a.keys().chain(b.keys()).copied().collect();
    paths.into_iter().filter(|p| a.get(p) != b.get(p)).map(str::to_string).collect()
}

/// The inputs of a job's content key that differ, key by key.
fn input_changes(o: &JobRecord, n: &JobRecord) -> Vec<KeyChange> {
    let mut out = Vec::new();
    let mut cmp = |key: &str, a: Value, b: Value| out.extend(differences(key, &a, &b));
    cmp("method", to_value(&o.method), to_value(&n.method));
    cmp("algorithm_version", to_value(&o.algorithm_version), to_value(&n.algorithm_version));
    cmp("params", o.params.clone().unwrap_or(Value::Null), n.params.clone().unwrap_or(Value::Null));
    cmp("seed", to_value(&o.seed), to_value(&n.seed));
    let sample = |r: &JobRecord| r.sample.as_ref().map(|s| s.pixel_digest.sha256.clone());
    cmp("sample.pixels", to_value(&sample(o)), to_value(&sample(n)));
    let mask = |r: &JobRecord| r.sample_mask.as_ref().map(|s| s.pixel_digest.sha256.clone());
    cmp("sample_mask.pixels", to_value(&mask(o)), to_value(&mask(n)));
    let inpaint_mask = |r: &JobRecord| r.inpaint_mask.as_ref().map(|s| s.pixel_digest.sha256.clone());
    cmp("inpaint.mask.pixels", to_value(&inpaint_mask(o)), to_value(&inpaint_mask(n)));
    // Several samples: each sample's pixels and mask, numbered from 1 as in `samples`.
    let listed =
        |r: &JobRecord| r.output_spec.as_ref().and_then(|s| s.get("samples")).and_then(|l| l.as_array()).cloned().unwrap_or_default();
    let (a, b) = (listed(o), listed(n));
    for i in 0..a.len().max(b.len()) {
        for part in ["pixels", "mask"] {
            let at = |l: &[Value]| l.get(i).and_then(|s| s.get(part)).cloned().unwrap_or(Value::Null);
            cmp(&format!("samples[{}].{part}", i + 1), at(&a), at(&b));
        }
    }
    // The mask's digest is also in the output spec (for the content key): said once, above.
    let spec = |r: &JobRecord| {
        let mut v = r.output_spec.clone().unwrap_or(Value::Null);
        if let Some(m) = v.as_object_mut() {
            m.remove("sample_mask");
            m.remove("samples");
            // An inpaint mask image likewise; a channel stays in the spec, where it is named.
            if let Some(i) = m.get_mut("inpaint").and_then(|i| i.as_object_mut()) {
                i.remove("mask");
            }
        }
        v
    };
    cmp("output_spec", spec(o), spec(n));
    out
}

/// Leaf-by-leaf differences of two JSON values under `key`.
fn differences(key: &str, a: &Value, b: &Value) -> Vec<KeyChange> {
    match (a, b) {
        (Value::Object(x), Value::Object(y)) => {
            let keys: BTreeSet<&String> = x.keys().chain(y.keys()).collect();
            keys.into_iter()
                .flat_map(|k| differences(&format!("{key}.{k}"), x.get(k).unwrap_or(&Value::Null), y.get(k).unwrap_or(&Value::Null)))
                .collect()
        }
        _ if a == b => Vec::new(),
        _ => vec![KeyChange { key: key.to_string(), old: a.clone(), new: b.clone() }],
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::batch::manifest::{FileRef, OutputRecord, RunFacts, SampleRecord, Status, Timing};
    use crate::digest::Digest;

    fn record(id: &str, block: i64, pixels: &str, seconds: f64) -> JobRecord {
        let d = |s: &str| Digest::of_bytes(s.as_bytes());
        JobRecord {
            id: id.into(),
            job_file: FileRef { path: format!("{id}.toml"), digest: d(id) },
            status: Status::Ok,
            error: None,
            method: Some("quilting".into()),
            algorithm_version: Some(1),
            params: Some(serde_json::json!({"block": block, "cut": "dp"})),
            params_digest: None,
            seed: Some(1),
            sample: Some(SampleRecord { path: "s.png".into(), file_digest: d("sf"), pixel_digest: d("sp"), width: 64, height: 64 }),
            output_spec: Some(serde_json::json!({"path": format!("{id}.png"), "width": 64, "height": 64})),
            content_key: None,
            outputs: vec![OutputRecord {
                path: format!("{id}.png"),
                format: "png".into(),
                bit_depth: 8,
                width: 64,
                height: 64,
                file_digest: d(pixels),
                pixel_digest: d(pixels),
            }],
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
            metrics: Some([("kl_gray".to_string(), Some(0.1))].into()),
            timing: Some(Timing {
                synthesis_seconds: seconds,
                metrics_seconds: 0.0,
                phases: Default::default(),
                total_seconds: seconds,
                finished_at: 0,
                estimated_peak_bytes: None,
            }),
        }
    }

    #[test]
    fn each_kind_of_change_is_named_with_its_reason() {
        let old = Manifest::new(
            vec![
                record("same", 32, "a", 1.0),
                record("param", 32, "b", 1.0),
                record("gone", 32, "c", 1.0),
                record("breaks", 32, "d", 1.0),
                record("slow", 32, "e", 0.1),
            ],
            RunFacts::default(),
        );
        let mut breaks = record("breaks", 32, "d", 1.0);
        breaks.status = Status::Failed;
        breaks.error = Some("quilting failed: boom".into());
        let mut slow = record("slow", 32, "e", 0.35);
        slow.metrics = Some([("kl_gray".to_string(), Some(0.2))].into());
        let new = Manifest::new(
            vec![record("same", 32, "a", 1.05), record("param", 48, "b2", 1.0), record("new", 32, "f", 1.0), breaks, slow],
            RunFacts::default(),
        );
        let d = diff(&old, &new, &Thresholds::default());
        assert_eq!(d.added, ["new"]);
        assert_eq!(d.removed, ["gone"]);
        assert_eq!(d.failed_now, [("breaks".to_string(), "quilting failed: boom".to_string())]);
        assert_eq!(d.pixels_changed.len(), 1);
        let p = &d.pixels_changed[0];
        assert_eq!((p.id.as_str(), p.outputs.as_slice()), ("param", ["param.png".to_string()].as_slice()));
        assert_eq!(p.because, [KeyChange { key: "params.block".into(), old: 32.into(), new: 48.into() }]);
        assert_eq!(d.slower.len(), 1, "1.0 → 1.05 s is within 20 %; 0.1 → 0.35 s is not");
        assert_eq!((d.slower[0].id.as_str(), d.slower[0].new), ("slow", 0.35));
        assert_eq!(d.metrics_moved.len(), 1);
        assert_eq!(d.unchanged, 2);
        assert!(d.pixels_differ());
        assert!(d.tool.is_empty());
    }

    #[test]
    fn identical_runs_differ_in_nothing() {
        let m = Manifest::new(vec![record("a", 32, "a", 1.0)], RunFacts::default());
        let d = diff(&m, &m, &Thresholds::default());
        assert!(!d.pixels_differ() && d.added.is_empty() && d.removed.is_empty() && d.slower.is_empty());
        assert_eq!(d.unchanged, 1);
    }
}
