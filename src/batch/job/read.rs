//! Reading one job file: TOML with positions, every top-level and `[output]` key checked, each
//! problem recorded with its line, column and key; the values handed to `sweep`.

use super::source::{Ctx, Raw, Ready, de_int, de_param, type_name};
use super::sweep;
use super::{Job, JobError, JobFile, MAX_OUTPUT_SIDE, OUTPUT_KEYS, TOP_KEYS, normalise_output_path};
use crate::digest::Digest;
use crate::image::io::Format;
use crate::synth::methods;
use crate::synth::params;
use std::collections::BTreeMap;
use std::path::Path;
use toml::Spanned;
use toml::de::{DeTable, DeValue};

pub(super) fn read_job_file(f: &JobFile) -> Result<Vec<Job>, Vec<JobError>> {
    let bytes = std::fs::read(&f.path)
        .map_err(|e| vec![JobError { file: f.path.clone(), position: None, key: None, message: format!("cannot read job file: {e}") }])?;
    parse_job_file(f, bytes)
}

/// Validates and expands a job file's bytes (the file is named for messages and to resolve the
/// sample; nothing else is read). What `cargo fuzz run job_file` feeds.
pub fn parse_job_file(f: &JobFile, bytes: Vec<u8>) -> Result<Vec<Job>, Vec<JobError>> {
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

/// The top-level keys, each checked for type; `[params]` and `[sweep]` are returned for later,
/// since they need the method.
fn read_top_level<'t>(ctx: &mut Ctx, table: &'t DeTable) -> (Raw<'t>, Option<&'t Spanned<DeValue<'t>>>, Option<&'t Spanned<DeValue<'t>>>) {
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
                other => {
                    ctx.err(Some(v.span()), Some("sample"), format!("expected a string (the sample's path), found {}", type_name(other)))
                }
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
    (raw, params_table, sweep_table)
}

/// Reads one file's keys, reports every problem, and expands the valid result into jobs.
fn build_jobs(ctx: &mut Ctx, table: &DeTable, file_bytes: &[u8]) -> Vec<Job> {
    let (mut raw, params_table, sweep_table) = read_top_level(ctx, table);
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
        sweep::read_sweep(ctx, s.get_ref().as_table().expect("checked"), method, &mut raw);
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
            let why = missing_file_reason(&p);
            ctx.err(Some(span.clone()), Some("sample"), format!("sample `{}` {why} (paths are relative to the job file)", p.display()));
        } else {
            sample_path = Some(p);
        }
    }
    let format_and_depth = check_output_format(ctx, &raw);
    if let Some((template, span)) = &raw.output_path
        && let Err(e) = normalise_output_path(template)
    {
        ctx.err(Some(span.clone()), Some("output.path"), e);
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
    let ready =
        Ready { method, sample, path_template, path_span, width, height, format, bit_depth, file_digest: Digest::of_bytes(file_bytes) };
    sweep::expand(ctx, &raw, &ready)
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
        other => {
            ctx.err(Some(v.span()), Some("metrics"), format!("expected true, false or a list of metric names, found {}", type_name(other)))
        }
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

/// Why `p` is not a readable file, in words.
pub(super) fn missing_file_reason(p: &Path) -> &'static str {
    /// Linux's ELOOP: too many levels of symbolic links.
    const ELOOP: i32 = 40;
    match std::fs::metadata(p) {
        Ok(_) => "is not a file",
        Err(e) if e.raw_os_error() == Some(ELOOP) => "is a symbolic link loop",
        Err(_) if std::fs::symlink_metadata(p).is_ok() => "is a symbolic link to nothing",
        Err(_) => "does not exist",
    }
}
