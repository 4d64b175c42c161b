//! Job files: reading, validating and expanding them into runnable jobs.
//!
//! A job file names a sample, a method, a seed, an output and parameters (the schema is a
//! contract; see README.md). A `[sweep]` table turns one file into many jobs. Validation happens
//! before anything runs and collects *every* problem in every file, each pointing at the file,
//! line, column and key, so that a user fixes a job directory in one pass.

use crate::digest::Digest;
use crate::error::Error;
use crate::image::io::Format;
use crate::synth::method::Method;
use crate::synth::methods;
use crate::synth::params::{self, ParamValue, Params};
use std::collections::BTreeMap;
use std::fmt;
use std::path::{Component, Path, PathBuf};
use toml::de::{DeTable, DeValue};
use toml::Spanned;

/// The top-level keys of a job file.
pub const TOP_KEYS: &[&str] = &["sample", "method", "seed", "output", "params", "sweep", "metrics"];
/// The keys of the `[output]` table.
pub const OUTPUT_KEYS: &[&str] = &["path", "width", "height", "bit_depth"];
/// Largest output side accepted.
pub const MAX_OUTPUT_SIDE: i64 = 65_536;
/// Largest number of jobs one file may expand to (a guard against a typo like `to = 1e9`).
pub const MAX_SWEEP_POINTS: usize = 100_000;

/// One problem in a job file.
#[derive(Clone, Debug, PartialEq)]
pub struct JobError {
    /// The job file as the user named it (or as found under a directory they named).
    pub file: PathBuf,
    /// 1-based line and column, when the problem has a place in the file.
    pub position: Option<(usize, usize)>,
    /// The dotted key concerned, e.g. `params.block`.
    pub key: Option<String>,
    pub message: String,
}

impl fmt::Display for JobError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file.display())?;
        if let Some((l, c)) = self.position {
            write!(f, ":{l}:{c}")?;
        }
        write!(f, ": ")?;
        if let Some(k) = &self.key {
            write!(f, "`{k}`: ")?;
        }
        write!(f, "{}", self.message)
    }
}

/// What a job writes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OutputSpec {
    /// Relative to the output directory, `/`-separated, normalised.
    pub path: String,
    pub width: u32,
    pub height: u32,
    pub format: Format,
    /// 8 or 16 for PNG, 32 for EXR.
    pub bit_depth: u8,
}

impl OutputSpec {
    pub fn encoding(&self) -> crate::image::io::Encoding {
        crate::image::io::Encoding { format: self.format, bit_depth: self.bit_depth }
    }
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({
            "path": self.path, "width": self.width, "height": self.height,
            "format": self.format.name(), "bit_depth": self.bit_depth,
        })
    }
}

/// One runnable job (a job file, or one point of its sweep).
#[derive(Clone)]
pub struct Job {
    /// The job file's path relative to the job root, plus `#k=v,…` for a sweep point.
    pub id: String,
    /// The job file as the user named it, for messages.
    pub file: PathBuf,
    /// The job file's path relative to the job root.
    pub file_rel: String,
    pub file_digest: Digest,
    /// The sample, resolved against the job file's directory.
    pub sample: PathBuf,
    pub method: &'static dyn Method,
    pub seed: u64,
    pub params: Params,
    pub output: OutputSpec,
    /// Metrics to compute after synthesis (`metrics = true` or a list); empty for none.
    pub metrics: Vec<String>,
    /// Line and column of each key, to point errors found later (e.g. by `Method::check`) at it.
    pub positions: BTreeMap<String, (usize, usize)>,
}

impl fmt::Debug for Job {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Job").field("id", &self.id).field("method", &self.method.name()).finish()
    }
}

impl Job {
    /// An error about this job's key `key` (e.g. `params.block`), placed at the key's line.
    pub fn error(&self, key: Option<&str>, message: impl Into<String>) -> JobError {
        JobError {
            file: self.file.clone(),
            position: key.and_then(|k| self.positions.get(k).copied()),
            key: key.map(str::to_string),
            message: message.into(),
        }
    }
}

/// A job that cannot run, with every reason.
#[derive(Clone, Debug)]
pub struct InvalidJob {
    pub id: String,
    pub file: PathBuf,
    pub errors: Vec<JobError>,
}

/// The result of reading job files: runnable jobs and invalid ones, both sorted by id.
#[derive(Debug, Default)]
pub struct JobSet {
    pub jobs: Vec<Job>,
    pub invalid: Vec<InvalidJob>,
}

/// A job file found under a root.
#[derive(Clone, Debug)]
pub struct JobFile {
    /// As the user will recognise it (the argument, or the argument joined with the found path).
    pub path: PathBuf,
    /// Relative to the job root, `/`-separated.
    pub rel: String,
}

/// Finds job files: each argument is a `.toml` file (its root is its directory) or a directory
/// searched recursively for `*.toml` (its root is itself). Sorted, without duplicates.
pub fn discover(args: &[PathBuf]) -> Result<Vec<JobFile>, Error> {
    let mut found: BTreeMap<String, JobFile> = BTreeMap::new();
    for arg in args {
        let meta = std::fs::metadata(arg).map_err(|e| Error::io(arg, "read", e))?;
        if meta.is_dir() {
            let mut files = Vec::new();
            walk(arg, &mut files).map_err(|e| Error::io(arg, "search", e))?;
            for f in files {
                let rel = slash_path(f.strip_prefix(arg).expect("walk stays under root"));
                add(&mut found, JobFile { path: f, rel })?;
            }
        } else {
            let rel = arg.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
            add(&mut found, JobFile { path: arg.clone(), rel })?;
        }
    }
    Ok(found.into_values().collect())
}

/// Adds a job file unless it is already there; two *different* files with the same id (same path
/// relative to their roots) would make ids, outputs and golden files ambiguous, so that is refused.
fn add(found: &mut BTreeMap<String, JobFile>, f: JobFile) -> Result<(), Error> {
    match found.get(&f.rel) {
        None => {
            found.insert(f.rel.clone(), f);
            Ok(())
        }
        Some(existing) => {
            let same = match (existing.path.canonicalize(), f.path.canonicalize()) {
                (Ok(a), Ok(b)) => a == b,
                _ => existing.path == f.path,
            };
            if same {
                Ok(())
            } else {
                Err(Error::Usage(format!(
                    "{} and {} both have the job id `{}` (ids are paths relative to the directory given); run them from a common parent directory",
                    existing.path.display(),
                    f.path.display(),
                    f.rel
                )))
            }
        }
    }
}

fn walk(dir: &Path, out: &mut Vec<PathBuf>) -> std::io::Result<()> {
    let mut entries: Vec<_> = std::fs::read_dir(dir)?.collect::<Result<_, _>>()?;
    entries.sort_by_key(|e| e.file_name());
    for e in entries {
        let name = e.file_name();
        if name.to_string_lossy().starts_with('.') {
            continue;
        }
        let path = e.path();
        let ft = e.file_type()?;
        if ft.is_dir() {
            walk(&path, out)?;
        } else if path.extension().is_some_and(|x| x == "toml") {
            out.push(path);
        }
    }
    Ok(())
}

fn slash_path(p: &Path) -> String {
    p.components().map(|c| c.as_os_str().to_string_lossy().into_owned()).collect::<Vec<_>>().join("/")
}

/// Reads, validates and expands job files into a plan. Problems never abort the plan: they make
/// the affected jobs invalid, with all their errors.
pub fn read_all(files: &[JobFile]) -> JobSet {
    let mut plan = JobSet::default();
    for f in files {
        match read_job_file(f) {
            Ok(jobs) => plan.jobs.extend(jobs),
            Err(errors) => plan.invalid.push(InvalidJob { id: f.rel.clone(), file: f.path.clone(), errors }),
        }
    }
    reject_shared_outputs(&mut plan);
    plan.jobs.sort_by(|a, b| a.id.cmp(&b.id));
    plan.invalid.sort_by(|a, b| a.id.cmp(&b.id));
    plan
}

/// Two jobs writing the same file would race; all of them are made invalid.
fn reject_shared_outputs(plan: &mut JobSet) {
    let mut by_output: BTreeMap<String, Vec<usize>> = BTreeMap::new();
    for (i, j) in plan.jobs.iter().enumerate() {
        by_output.entry(j.output.path.clone()).or_default().push(i);
    }
    let mut bad: BTreeMap<usize, String> = BTreeMap::new();
    for (path, idx) in &by_output {
        if idx.len() > 1 {
            for &i in idx {
                let others: Vec<&str> = idx.iter().filter(|&&k| k != i).map(|&k| plan.jobs[k].id.as_str()).collect();
                bad.insert(
                    i,
                    format!(
                        "output `{path}` is also written by {}; give each job its own output path (e.g. with {{seed}} in a sweep)",
                        others.join(", ")
                    ),
                );
            }
        }
    }
    for (i, msg) in bad.into_iter().rev() {
        let job = plan.jobs.remove(i);
        let err = job.error(Some("output.path"), msg);
        plan.invalid.push(InvalidJob { id: job.id, file: job.file, errors: vec![err] });
    }
}

/// Where a byte offset is, as 1-based (line, column).
fn line_col(src: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(src.len());
    let before = &src[..offset];
    let line = before.matches('\n').count() + 1;
    let col = before.rfind('\n').map_or(before.chars().count(), |nl| before[nl + 1..].chars().count()) + 1;
    (line, col)
}

struct Ctx<'a> {
    file: &'a JobFile,
    src: &'a str,
    errors: Vec<JobError>,
    positions: BTreeMap<String, (usize, usize)>,
}

impl Ctx<'_> {
    fn err(&mut self, span: Option<std::ops::Range<usize>>, key: Option<&str>, message: impl Into<String>) {
        let e = JobError {
            file: self.file.path.clone(),
            position: span.map(|s| line_col(self.src, s.start)),
            key: key.map(str::to_string),
            message: message.into(),
        };
        if !self.errors.contains(&e) {
            self.errors.push(e);
        }
    }
    fn at(&mut self, key: &str, span: std::ops::Range<usize>) {
        self.positions.insert(key.to_string(), line_col(self.src, span.start));
    }
}

fn type_name(v: &DeValue) -> &'static str {
    match v {
        DeValue::String(_) => "a string",
        DeValue::Integer(_) => "an integer",
        DeValue::Float(_) => "a float",
        DeValue::Boolean(_) => "a boolean",
        DeValue::Datetime(_) => "a datetime",
        DeValue::Array(_) => "an array",
        DeValue::Table(_) => "a table",
    }
}

fn de_int(v: &DeValue) -> Option<Result<i64, String>> {
    match v {
        DeValue::Integer(i) => Some(
            i64::from_str_radix(i.as_str(), i.radix()).map_err(|_| format!("integer {} is out of range", i.as_str())),
        ),
        _ => None,
    }
}

fn de_param(v: &DeValue) -> Result<ParamValue, String> {
    match v {
        DeValue::String(s) => Ok(ParamValue::Str(s.to_string())),
        DeValue::Integer(_) => de_int(v).expect("integer").map(ParamValue::Int),
        DeValue::Float(f) => {
            let s = f.as_str().replace('_', "");
            s.parse::<f64>().map(ParamValue::Float).map_err(|_| format!("invalid float {s}"))
        }
        DeValue::Boolean(b) => Ok(ParamValue::Bool(*b)),
        other => Err(format!("expected a number, string or boolean, found {}", type_name(other))),
    }
}

fn read_job_file(f: &JobFile) -> Result<Vec<Job>, Vec<JobError>> {
    let bytes = std::fs::read(&f.path).map_err(|e| {
        vec![JobError { file: f.path.clone(), position: None, key: None, message: format!("cannot read job file: {e}") }]
    })?;
    let src = String::from_utf8(bytes.clone()).map_err(|e| {
        vec![JobError {
            file: f.path.clone(),
            position: None,
            key: None,
            message: format!("job file is not valid UTF-8 (byte {})", e.utf8_error().valid_up_to()),
        }]
    })?;
    let mut ctx = Ctx { file: f, src: &src, errors: Vec::new(), positions: BTreeMap::new() };
    let (table, parse_errors) = DeTable::parse_recoverable(&src);
    for e in &parse_errors {
        ctx.err(e.span(), None, format!("malformed TOML: {}", e.message().trim()));
    }
    if !parse_errors.is_empty() {
        return Err(ctx.errors);
    }
    let jobs = build_jobs(&mut ctx, table.get_ref(), &bytes);
    if ctx.errors.is_empty() {
        Ok(jobs)
    } else {
        // Errors without a place (missing keys) come last.
        ctx.errors.sort_by_key(|e| e.position.unwrap_or((usize::MAX, 0)));
        Err(ctx.errors)
    }
}

struct Raw<'a> {
    sample: Option<(String, std::ops::Range<usize>)>,
    method: Option<&'static dyn Method>,
    seed: Option<u64>,
    output_path: Option<(String, std::ops::Range<usize>)>,
    width: Option<u32>,
    height: Option<u32>,
    bit_depth: Option<(i64, std::ops::Range<usize>)>,
    params: Vec<(String, ParamValue)>,
    metrics: Vec<String>,
    sweep: Vec<(String, Vec<(ParamValue, std::ops::Range<usize>)>)>,
    _src: std::marker::PhantomData<&'a ()>,
}

fn build_jobs(ctx: &mut Ctx, table: &DeTable, file_bytes: &[u8]) -> Vec<Job> {
    let mut raw = Raw {
        sample: None,
        method: None,
        seed: None,
        output_path: None,
        width: None,
        height: None,
        bit_depth: None,
        params: Vec::new(),
        metrics: Vec::new(),
        sweep: Vec::new(),
        _src: std::marker::PhantomData,
    };
    let mut params_table: Option<&Spanned<DeValue>> = None;
    let mut sweep_table: Option<&Spanned<DeValue>> = None;
    for (k, v) in table.iter() {
        let key: &str = k.get_ref();
        ctx.at(key, k.span());
        match key {
            "sample" => match v.get_ref() {
                DeValue::String(s) if !s.is_empty() => raw.sample = Some((s.to_string(), v.span())),
                DeValue::String(_) => ctx.err(Some(v.span()), Some("sample"), "sample path is empty"),
                other => ctx.err(Some(v.span()), Some("sample"), format!("expected a string (the sample's path), found {}", type_name(other))),
            },
            "method" => match v.get_ref() {
                DeValue::String(s) => match methods::find(s) {
                    Some(m) => raw.method = Some(m),
                    None => {
                        let names = methods::names();
                        let hint = params::nearest(s, &names).map(|n| format!(" (did you mean `{n}`?)")).unwrap_or_default();
                        ctx.err(Some(v.span()), Some("method"), format!("unknown method `{s}`{hint}; available: {}", names.join(", ")));
                    }
                },
                other => ctx.err(Some(v.span()), Some("method"), format!("expected a string (a method name), found {}", type_name(other))),
            },
            "seed" => match de_int(v.get_ref()) {
                Some(Ok(s)) if s >= 0 => raw.seed = Some(s as u64),
                Some(Ok(s)) => ctx.err(Some(v.span()), Some("seed"), format!("seed must be a non-negative integer, got {s}")),
                Some(Err(e)) => ctx.err(Some(v.span()), Some("seed"), e),
                None => ctx.err(Some(v.span()), Some("seed"), format!("expected an integer, found {}", type_name(v.get_ref()))),
            },
            "output" => match v.get_ref() {
                DeValue::Table(t) => read_output(ctx, t, &mut raw),
                other => ctx.err(Some(v.span()), Some("output"), format!("expected a table ([output]), found {}", type_name(other))),
            },
            "params" => match v.get_ref() {
                DeValue::Table(_) => params_table = Some(v),
                other => ctx.err(Some(v.span()), Some("params"), format!("expected a table ([params]), found {}", type_name(other))),
            },
            "sweep" => match v.get_ref() {
                DeValue::Table(_) => sweep_table = Some(v),
                other => ctx.err(Some(v.span()), Some("sweep"), format!("expected a table ([sweep]), found {}", type_name(other))),
            },
            "metrics" => read_metrics(ctx, v, &mut raw),
            other => ctx.err(Some(k.span()), Some(other), params::unknown_key_message(other, TOP_KEYS)),
        }
    }
    for (key, what) in [("sample", raw.sample.is_some()), ("method", table.get("method").is_some())] {
        if !what && table.get(key).is_none() {
            ctx.err(None, Some(key), format!("missing required key `{key}`"));
        }
    }
    if table.get("output").is_none() {
        ctx.err(None, Some("output"), "missing required table [output] (with path, width and height)");
    } else if matches!(table.get("output").map(|v| v.get_ref()), Some(DeValue::Table(_))) {
        for (k, present) in [("path", raw.output_path.is_some()), ("width", raw.width.is_some()), ("height", raw.height.is_some())] {
            let output = table.get("output").and_then(|v| v.get_ref().as_table());
            if !present && output.is_some_and(|t| t.get(k).is_none()) {
                ctx.err(None, Some(&format!("output.{k}")), format!("missing required key `output.{k}`"));
            }
        }
    }

    // Parameters need the method to be known.
    let method = raw.method;
    if let Some(p) = params_table {
        let t = p.get_ref().as_table().expect("checked");
        for (k, v) in t.iter() {
            let key = format!("params.{}", k.get_ref());
            ctx.at(&key, k.span());
            match de_param(v.get_ref()) {
                Ok(pv) => raw.params.push((k.get_ref().to_string(), pv)),
                Err(e) => ctx.err(Some(v.span()), Some(&key), e),
            }
        }
    }
    if let Some(s) = sweep_table {
        read_sweep(ctx, s.get_ref().as_table().expect("checked"), method, &mut raw);
    }
    let sweep_has_seed = sweep_table.and_then(|t| t.get_ref().as_table()).is_some_and(|t| t.get("seed").is_some());
    if raw.seed.is_none() && !sweep_has_seed && table.get("seed").is_none() {
        ctx.err(None, Some("seed"), "missing required key `seed` (or a `seed` list in [sweep])");
    }
    if raw.seed.is_some() && raw.sweep.iter().any(|(k, _)| k == "seed") {
        let span = table.get("seed").map(|v| v.span());
        ctx.err(span, Some("seed"), "seed is given both at the top level and in [sweep]; keep one");
    }

    // The sample must exist (it is decoded later, once per distinct file).
    let mut sample_path = None;
    if let Some((s, span)) = &raw.sample {
        let base = ctx.file.path.parent().unwrap_or(Path::new(""));
        let p = base.join(s);
        if !p.is_file() {
            let why = if p.exists() { "is not a file" } else { "does not exist" };
            ctx.err(Some(span.clone()), Some("sample"), format!("sample `{}` {why} (paths are relative to the job file)", p.display()));
        } else {
            sample_path = Some(p);
        }
    }
    let format_and_depth = check_output_format(ctx, &raw);
    if let Some((template, span)) = &raw.output_path {
        if let Err(e) = normalise_output_path(template) {
            ctx.err(Some(span.clone()), Some("output.path"), e);
        }
    }
    if let Some(m) = method {
        // Report parameter problems even when other keys are broken too.
        if let Err(errs) = params::resolve(m.params(), &raw.params) {
            for e in errs {
                let key = format!("params.{}", e.key);
                let pos = ctx.positions.get(&key).copied();
                let err = JobError { file: ctx.file.path.clone(), position: pos, key: Some(key), message: e.message };
                if !ctx.errors.contains(&err) {
                    ctx.errors.push(err);
                }
            }
        }
    }
    if !ctx.errors.is_empty() {
        return Vec::new();
    }
    let (Some(method), Some(sample), Some((path_template, path_span)), Some(width), Some(height), Some((format, bit_depth))) =
        (method, sample_path, raw.output_path.clone(), raw.width, raw.height, format_and_depth)
    else {
        return Vec::new();
    };
    let file_digest = Digest::of_bytes(file_bytes);

    // Expand the sweep: the cartesian product of its lists, keys in sorted order.
    let mut points: Vec<Vec<(String, ParamValue)>> = vec![Vec::new()];
    let mut sweep = raw.sweep.clone();
    sweep.sort_by(|a, b| a.0.cmp(&b.0));
    for (k, values) in &sweep {
        let mut next = Vec::with_capacity(points.len() * values.len());
        for p in &points {
            for (v, _) in values {
                let mut q = p.clone();
                q.push((k.clone(), v.clone()));
                next.push(q);
            }
        }
        points = next;
        if points.len() > MAX_SWEEP_POINTS {
            ctx.err(None, Some("sweep"), format!("the sweep expands to more than {MAX_SWEEP_POINTS} jobs"));
            return Vec::new();
        }
    }
    let mut jobs = Vec::new();
    for point in points {
        let mut given = raw.params.clone();
        let mut seed = raw.seed.unwrap_or(0);
        for (k, v) in &point {
            if k == "seed" {
                if let ParamValue::Int(s) = v {
                    seed = *s as u64;
                }
            } else {
                given.push((k.clone(), v.clone()));
            }
        }
        let params = match params::resolve(method.params(), &given) {
            Ok(p) => p,
            Err(errs) => {
                for e in errs {
                    let in_sweep = point.iter().any(|(k, _)| *k == e.key);
                    let key = if in_sweep { format!("sweep.{}", e.key) } else { format!("params.{}", e.key) };
                    let pos = ctx.positions.get(&key).copied();
                    let err = JobError { file: ctx.file.path.clone(), position: pos, key: Some(key), message: e.message };
                    if !ctx.errors.contains(&err) {
                        ctx.errors.push(err);
                    }
                }
                continue;
            }
        };
        let path = match expand_template(&path_template, method.name(), seed, &params) {
            Ok(p) => p,
            Err(e) => {
                ctx.err(Some(path_span.clone()), Some("output.path"), e);
                continue;
            }
        };
        let path = match normalise_output_path(&path) {
            Ok(p) => p,
            Err(e) => {
                ctx.err(Some(path_span.clone()), Some("output.path"), e);
                continue;
            }
        };
        let id = if point.is_empty() {
            ctx.file.rel.clone()
        } else {
            let parts: Vec<String> = point.iter().map(|(k, v)| format!("{k}={}", v.display())).collect();
            format!("{}#{}", ctx.file.rel, parts.join(","))
        };
        let mut positions = ctx.positions.clone();
        for (k, _) in &point {
            if let Some(p) = ctx.positions.get(&format!("sweep.{k}")).copied() {
                positions.insert(format!("params.{k}"), p);
            }
        }
        jobs.push(Job {
            id,
            file: ctx.file.path.clone(),
            file_rel: ctx.file.rel.clone(),
            file_digest: file_digest.clone(),
            sample: sample.clone(),
            method,
            seed,
            params,
            output: OutputSpec { path, width, height, format, bit_depth },
            metrics: raw.metrics.clone(),
            positions,
        });
    }
    jobs
}

/// `metrics = true` (all), `false` (none) or a list of metric names.
fn read_metrics(ctx: &mut Ctx, v: &Spanned<DeValue>, raw: &mut Raw) {
    let names = crate::metrics::METRIC_NAMES;
    match v.get_ref() {
        DeValue::Boolean(true) => raw.metrics = names.iter().map(|s| s.to_string()).collect(),
        DeValue::Boolean(false) => raw.metrics.clear(),
        DeValue::Array(items) => {
            for item in items {
                match item.get_ref() {
                    DeValue::String(s) if names.contains(&s.as_ref()) => {
                        if !raw.metrics.iter().any(|m| m == s.as_ref()) {
                            raw.metrics.push(s.to_string());
                        }
                    }
                    DeValue::String(s) => {
                        let hint = params::nearest(s, names).map(|n| format!(" (did you mean `{n}`?)")).unwrap_or_default();
                        ctx.err(Some(item.span()), Some("metrics"), format!("unknown metric `{s}`{hint}; available: {}", names.join(", ")));
                    }
                    other => ctx.err(Some(item.span()), Some("metrics"), format!("expected a metric name, found {}", type_name(other))),
                }
            }
        }
        other => ctx.err(
            Some(v.span()),
            Some("metrics"),
            format!("expected true, false or a list of metric names, found {}", type_name(other)),
        ),
    }
}

fn read_output(ctx: &mut Ctx, t: &DeTable, raw: &mut Raw) {
    for (k, v) in t.iter() {
        let key = format!("output.{}", k.get_ref());
        ctx.at(&key, k.span());
        match k.get_ref().as_ref() {
            "path" => match v.get_ref() {
                DeValue::String(s) if !s.is_empty() => raw.output_path = Some((s.to_string(), v.span())),
                DeValue::String(_) => ctx.err(Some(v.span()), Some(&key), "output path is empty"),
                other => ctx.err(Some(v.span()), Some(&key), format!("expected a string, found {}", type_name(other))),
            },
            side @ ("width" | "height") => match de_int(v.get_ref()) {
                Some(Ok(n)) if (1..=MAX_OUTPUT_SIDE).contains(&n) => {
                    if side == "width" {
                        raw.width = Some(n as u32)
                    } else {
                        raw.height = Some(n as u32)
                    }
                }
                Some(Ok(n)) => ctx.err(Some(v.span()), Some(&key), format!("{n} is out of range: allowed 1..={MAX_OUTPUT_SIDE}")),
                Some(Err(e)) => ctx.err(Some(v.span()), Some(&key), e),
                None => ctx.err(Some(v.span()), Some(&key), format!("expected an integer, found {}", type_name(v.get_ref()))),
            },
            "bit_depth" => match de_int(v.get_ref()) {
                Some(Ok(n)) => raw.bit_depth = Some((n, v.span())),
                Some(Err(e)) => ctx.err(Some(v.span()), Some(&key), e),
                None => ctx.err(Some(v.span()), Some(&key), format!("expected an integer (8 or 16), found {}", type_name(v.get_ref()))),
            },
            other => ctx.err(Some(k.span()), Some(&key), params::unknown_key_message(other, OUTPUT_KEYS)),
        }
    }
}

fn check_output_format(ctx: &mut Ctx, raw: &Raw) -> Option<(Format, u8)> {
    let (path, span) = raw.output_path.as_ref()?;
    let format = match Format::from_path(Path::new(path)) {
        Some(f) => f,
        None => {
            ctx.err(Some(span.clone()), Some("output.path"), format!("output `{path}` must end in .png or .exr"));
            return None;
        }
    };
    match (format, &raw.bit_depth) {
        (Format::Png, None) => Some((format, 8)),
        (Format::Png, Some((8, _))) => Some((format, 8)),
        (Format::Png, Some((16, _))) => Some((format, 16)),
        (Format::Png, Some((d, s))) => {
            ctx.err(Some(s.clone()), Some("output.bit_depth"), format!("bit depth {d} is not supported for PNG: use 8 or 16"));
            None
        }
        (Format::Exr, None) => Some((format, 32)),
        (Format::Exr, Some((_, s))) => {
            ctx.err(Some(s.clone()), Some("output.bit_depth"), "bit_depth applies to PNG only (EXR outputs are 32-bit float); remove it");
            None
        }
    }
}

fn read_sweep(ctx: &mut Ctx, t: &DeTable, method: Option<&'static dyn Method>, raw: &mut Raw) {
    for (k, v) in t.iter() {
        let name = k.get_ref().to_string();
        let key = format!("sweep.{name}");
        ctx.at(&key, k.span());
        if name != "seed" {
            if let Some(m) = method {
                let mut valid: Vec<&str> = m.params().iter().map(|p| p.name).collect();
                valid.push("seed");
                if !valid.contains(&name.as_str()) {
                    ctx.err(Some(k.span()), Some(&key), params::unknown_key_message(&name, &valid));
                    continue;
                }
            }
            if raw.params.iter().any(|(p, _)| *p == name) {
                ctx.err(Some(k.span()), Some(&key), format!("`{name}` is both in [params] and in [sweep]; keep one"));
                continue;
            }
        }
        let values: Vec<(ParamValue, std::ops::Range<usize>)> = match v.get_ref() {
            DeValue::Array(items) => {
                let mut vals = Vec::new();
                for item in items {
                    match de_param(item.get_ref()) {
                        Ok(p) => vals.push((p, item.span())),
                        Err(e) => ctx.err(Some(item.span()), Some(&key), e),
                    }
                }
                vals
            }
            DeValue::Table(range) => match read_range(range) {
                Ok(vals) => vals.into_iter().map(|i| (ParamValue::Int(i), v.span())).collect(),
                Err(e) => {
                    ctx.err(Some(v.span()), Some(&key), e);
                    continue;
                }
            },
            other => {
                ctx.err(
                    Some(v.span()),
                    Some(&key),
                    format!("expected a list of values or a range table {{ from = …, to = … }}, found {}", type_name(other)),
                );
                continue;
            }
        };
        if values.is_empty() {
            ctx.err(Some(v.span()), Some(&key), "sweep list is empty");
            continue;
        }
        if name == "seed" {
            for (val, span) in &values {
                match val {
                    ParamValue::Int(s) if *s >= 0 => {}
                    other => ctx.err(Some(span.clone()), Some(&key), format!("seeds must be non-negative integers, got {}", other.display())),
                }
            }
        }
        let mut seen = Vec::new();
        for (val, span) in &values {
            if seen.contains(val) {
                ctx.err(Some(span.clone()), Some(&key), format!("value {} appears twice in the sweep", val.display()));
            }
            seen.push(val.clone());
        }
        raw.sweep.push((name, values));
    }
}

/// `{ from = a, to = b }` (inclusive) with an optional positive `step`.
fn read_range(t: &DeTable) -> Result<Vec<i64>, String> {
    let mut from = None;
    let mut to = None;
    let mut step = 1i64;
    for (k, v) in t.iter() {
        let n = match de_int(v.get_ref()) {
            Some(Ok(n)) => n,
            _ => return Err(format!("range `{}` must be an integer", k.get_ref())),
        };
        match k.get_ref().as_ref() {
            "from" => from = Some(n),
            "to" => to = Some(n),
            "step" => step = n,
            other => return Err(params::unknown_key_message(other, &["from", "to", "step"])),
        }
    }
    let (Some(from), Some(to)) = (from, to) else { return Err("a range needs both `from` and `to` (inclusive)".into()) };
    if step <= 0 {
        return Err(format!("range step must be positive, got {step}"));
    }
    if to < from {
        return Err(format!("range is empty: from {from} is after to {to}"));
    }
    let count = (to - from) / step + 1;
    if count as usize > MAX_SWEEP_POINTS {
        return Err(format!("range has {count} values, more than {MAX_SWEEP_POINTS}"));
    }
    Ok((0..count).map(|i| from + i * step).collect())
}

/// Replaces `{seed}`, `{method}` and `{<param>}` in an output path template.
pub fn expand_template(template: &str, method: &str, seed: u64, params: &Params) -> Result<String, String> {
    let mut out = String::new();
    let mut rest = template;
    while let Some(open) = rest.find('{') {
        out.push_str(&rest[..open]);
        let after = &rest[open + 1..];
        let close = after.find('}').ok_or_else(|| format!("unclosed `{{` in output path `{template}`"))?;
        let name = &after[..close];
        let value = match name {
            "seed" => seed.to_string(),
            "method" => method.to_string(),
            _ => match params.get(name) {
                Some(v) => v.display(),
                None => {
                    let mut valid: Vec<&str> = vec!["seed", "method"];
                    valid.extend(params.0.keys().map(String::as_str));
                    return Err(format!("unknown placeholder `{{{name}}}` in output path; available: {}", valid.join(", ")));
                }
            },
        };
        out.push_str(&value);
        rest = &after[close + 1..];
    }
    if rest.contains('}') {
        return Err(format!("unmatched `}}` in output path `{template}`"));
    }
    out.push_str(rest);
    Ok(out)
}

/// Checks that an output path stays inside the output directory and normalises it to a relative,
/// `/`-separated path without `.` components.
pub fn normalise_output_path(path: &str) -> Result<String, String> {
    if path.contains('\0') {
        return Err("output path contains a NUL byte".into());
    }
    let p = Path::new(path);
    let mut parts = Vec::new();
    for c in p.components() {
        match c {
            Component::Normal(s) => {
                let s = s.to_string_lossy();
                if s.starts_with('.') && s.ends_with(".tmp") {
                    return Err(format!("output path `{path}` uses a reserved temporary-file name"));
                }
                parts.push(s.into_owned())
            }
            Component::CurDir => {}
            Component::ParentDir => {
                return Err(format!("output path `{path}` must stay inside the output directory (no `..`)"));
            }
            Component::RootDir | Component::Prefix(_) => {
                return Err(format!("output path `{path}` must be relative to the output directory, not absolute"));
            }
        }
    }
    if parts.is_empty() {
        return Err(format!("output path `{path}` names no file"));
    }
    if parts.len() == 1 && parts[0] == "manifest.json" {
        return Err("output path `manifest.json` is reserved for the manifest".into());
    }
    Ok(parts.join("/"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, body: &str) -> JobFile {
        let p = dir.join(name);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(&p, body).unwrap();
        JobFile { path: p, rel: name.to_string() }
    }

    fn tmpdir(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("texsyn-job-test-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        std::fs::write(d.join("s.png"), b"not decoded here").unwrap();
        d
    }

    #[test]
    fn a_complete_job_parses_with_defaults_filled() {
        let d = tmpdir("ok");
        let f = write(&d, "a.toml", "sample = \"s.png\"\nmethod = \"quilting\"\nseed = 7\n[output]\npath = \"x/a.png\"\nwidth = 100\nheight = 80\n[params]\nblock = 30\n");
        let plan = read_all(&[f]);
        assert!(plan.invalid.is_empty(), "{:?}", plan.invalid);
        let j = &plan.jobs[0];
        assert_eq!(j.id, "a.toml");
        assert_eq!(j.params.int_unchecked("overlap"), 5);
        assert_eq!(j.output.bit_depth, 8);
        assert_eq!(j.positions["params.block"], (9, 1));
    }

    #[test]
    fn sweeps_expand_with_stable_ids_and_templated_paths() {
        let d = tmpdir("sweep");
        let f = write(
            &d,
            "s.toml",
            "sample = \"s.png\"\nmethod = \"quilting\"\n[output]\npath = \"o/{block}_{seed}.png\"\nwidth = 60\nheight = 60\n[sweep]\nseed = { from = 1, to = 3 }\nblock = [20, 30]\n",
        );
        let plan = read_all(&[f]);
        assert!(plan.invalid.is_empty(), "{:?}", plan.invalid);
        let ids: Vec<&str> = plan.jobs.iter().map(|j| j.id.as_str()).collect();
        assert_eq!(ids.len(), 6);
        assert!(ids.contains(&"s.toml#block=20,seed=1"));
        let j = plan.jobs.iter().find(|j| j.id == "s.toml#block=30,seed=3").unwrap();
        assert_eq!(j.output.path, "o/30_3.png");
        assert_eq!(j.seed, 3);
    }

    #[test]
    fn every_problem_is_reported_with_line_and_key() {
        let d = tmpdir("bad");
        let f = write(
            &d,
            "bad.toml",
            "sample = \"missing.png\"\nmethod = \"quilting\"\nseed = -1\ncolour = 1\n[output]\npath = \"../x.png\"\nwidth = 0\nheight = 10\n[params]\nblok = 3\n",
        );
        let plan = read_all(&[f]);
        let errs = &plan.invalid[0].errors;
        let text: Vec<String> = errs.iter().map(|e| e.to_string()).collect();
        let all = text.join("\n");
        assert!(all.contains("bad.toml:3:8: `seed`"), "{all}");
        assert!(all.contains("bad.toml:4:1: `colour`: unknown key"), "{all}");
        assert!(all.contains("`output.width`: 0 is out of range"), "{all}");
        assert!(all.contains("missing.png` does not exist"), "{all}");
        assert!(all.contains("blok") && all.contains("did you mean `block`"), "{all}");
    }

    #[test]
    fn metrics_key_accepts_true_or_a_list_and_rejects_unknown_names() {
        let d = tmpdir("metrics");
        let head = "sample = \"s.png\"\nmethod = \"quilting\"\nseed = 1\n[output]\npath = \"o.png\"\nwidth = 60\nheight = 60\n";
        let all = write(&d, "all.toml", &format!("metrics = true\n{head}"));
        let some = write(&d, "some.toml", &format!("metrics = [\"kl_gray\", \"verbatim\"]\n{head}").replace("o.png", "p.png"));
        let bad = write(&d, "bad.toml", &format!("metrics = [\"kl_grey\"]\n{head}").replace("o.png", "q.png"));
        let plan = read_all(&[all, some, bad]);
        assert_eq!(plan.jobs[0].metrics.len(), crate::metrics::METRIC_NAMES.len());
        assert_eq!(plan.jobs[1].metrics, vec!["kl_gray", "verbatim"]);
        let msg = plan.invalid[0].errors[0].to_string();
        assert!(msg.contains("bad.toml:1:12: `metrics`: unknown metric `kl_grey` (did you mean `kl_gray`?)"), "{msg}");
    }

    #[test]
    fn malformed_toml_names_line_and_column() {
        let d = tmpdir("toml");
        let f = write(&d, "m.toml", "sample = \"s.png\"\nmethod = quilting\n");
        let plan = read_all(&[f]);
        let e = &plan.invalid[0].errors[0];
        assert_eq!(e.position.unwrap().0, 2);
        assert!(e.message.contains("malformed TOML"), "{}", e.message);
    }

    #[test]
    fn two_files_with_one_id_are_refused() {
        let d = tmpdir("ids");
        let a = write(&d, "x/same.toml", "");
        let b = write(&d, "y/same.toml", "");
        let err = discover(&[d.join("x"), d.join("y")]).unwrap_err();
        assert!(err.to_string().contains("both have the job id `same.toml`"), "{err}");
        // The same file named twice is fine.
        assert_eq!(discover(&[a.path.clone(), a.path.clone(), d.join("x")]).unwrap().len(), 1);
        let _ = b;
    }

    #[test]
    fn output_paths_must_stay_inside() {
        assert!(normalise_output_path("/etc/x.png").is_err());
        assert!(normalise_output_path("a/../../x.png").is_err());
        assert_eq!(normalise_output_path("./a//b.png").unwrap(), "a/b.png");
        assert!(normalise_output_path("manifest.json").is_err());
    }

    #[test]
    fn shared_outputs_invalidate_every_writer() {
        let d = tmpdir("shared");
        let body = "sample = \"s.png\"\nmethod = \"quilting\"\nseed = 1\n[output]\npath = \"same.png\"\nwidth = 60\nheight = 60\n";
        let a = write(&d, "a.toml", body);
        let b = write(&d, "b.toml", body);
        let plan = read_all(&[a, b]);
        assert!(plan.jobs.is_empty());
        assert_eq!(plan.invalid.len(), 2);
        assert!(plan.invalid[0].errors[0].message.contains("also written by b.toml"));
    }
}
