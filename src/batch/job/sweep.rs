//! `[sweep]`: reading its lists and ranges, and expanding their cartesian product into jobs with
//! ids, resolved parameters and templated output paths.

use super::source::{Ctx, Raw, Ready, de_int, de_param, type_name};
use super::{Job, JobError, MAX_SWEEP_POINTS, OutputSpec, expand_template, normalise_output_path};
use crate::synth::method::Method;
use crate::synth::params::{self, ParamValue};
use toml::de::{DeTable, DeValue};

pub(super) fn read_sweep(ctx: &mut Ctx, t: &DeTable, method: Option<&'static dyn Method>, raw: &mut Raw) {
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
                    other => {
                        ctx.err(Some(span.clone()), Some(&key), format!("seeds must be non-negative integers, got {}", other.display()))
                    }
                }
            }
        }
        // By the displayed value (what ids and paths are made of); linear, so a 100 000-value
        // range is checked in milliseconds.
        let mut seen = std::collections::HashSet::new();
        for (val, span) in &values {
            if !seen.insert(val.display()) {
                ctx.err(Some(span.clone()), Some(&key), format!("value {} appears twice in the sweep", val.display()));
            }
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

/// Every point of the sweep as a job (one job for a file without `[sweep]`).
pub(super) fn expand(ctx: &mut Ctx, raw: &Raw, ready: &Ready) -> Vec<Job> {
    let &Ready {
        method,
        ref sample,
        ref sample_mask,
        ref more_samples,
        ref augment,
        ref inpaint,
        ref guide,
        ref path_template,
        ref path_span,
        width,
        height,
        format,
        bit_depth,
        native_depth,
        ref file_digest,
        ref companions,
    } = ready;

    // Counted before it is expanded: a typo like `to = 1e9` times another list is refused at once.
    let total = raw.sweep.iter().try_fold(1usize, |acc, (_, values)| acc.checked_mul(values.len()).filter(|n| *n <= MAX_SWEEP_POINTS));
    if total.is_none() {
        let sizes: Vec<String> = raw.sweep.iter().map(|(k, v)| format!("{k}: {}", v.len())).collect();
        ctx.err(None, Some("sweep"), format!("the sweep expands to more than {MAX_SWEEP_POINTS} jobs ({})", sizes.join(" x ")));
        return Vec::new();
    }

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
    let uses = crate::synth::method::Uses {
        inpaint: inpaint.is_some(),
        copies: !augment.is_empty(),
        luminance_guide: guide.as_ref().is_some_and(|g| g.source.is_none()),
    };
    let mut jobs = Vec::new();
    for point in points {
        let mut given = raw.params.clone();
        for (key, value) in method.defaults_for(uses) {
            if !given.iter().any(|(k, _)| *k == key) && !point.iter().any(|(k, _)| *k == key) {
                given.push((key, value));
            }
        }
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
                    ctx.push(err);
                }
                continue;
            }
        };
        let path = match expand_template(path_template, method.name(), seed, &params) {
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
        // Companion and source-map paths take the same placeholders as the output path.
        let mut named = Vec::new();
        let mut broken = false;
        for (k, c) in companions.iter().enumerate() {
            let key = format!("companion[{}].path", k + 1);
            match expand_template(&c.path, method.name(), seed, &params).and_then(|p| normalise_output_path(&p)) {
                Ok(p) => named.push(super::Companion { path: p, ..c.clone() }),
                Err(e) => {
                    let pos = ctx.positions.get(&key).copied();
                    let err = JobError { file: ctx.file.path.clone(), position: pos, key: Some(key), message: e };
                    ctx.push(err);
                    broken = true;
                }
            }
        }
        let source_map = match &raw.source_map {
            None => None,
            Some((t, span)) => match expand_template(t, method.name(), seed, &params).and_then(|p| normalise_output_path(&p)) {
                Ok(p) => Some(p),
                Err(e) => {
                    ctx.err(Some(span.clone()), Some("output.source_map"), e);
                    broken = true;
                    None
                }
            },
        };
        // One file per name: the output, each companion and the source map must all differ.
        let mut seen: Vec<(&str, String)> = vec![(path.as_str(), "output.path".to_string())];
        for (k, c) in named.iter().enumerate() {
            seen.push((c.path.as_str(), format!("companion[{}].path", k + 1)));
        }
        if let Some(m) = &source_map {
            seen.push((m.as_str(), "output.source_map".to_string()));
        }
        for i in 1..seen.len() {
            if let Some(first) = seen[..i].iter().find(|s| s.0 == seen[i].0) {
                let key = seen[i].1.clone();
                let pos = ctx.positions.get(&key).or_else(|| ctx.positions.get(key.trim_end_matches(".path"))).copied();
                let message = format!("`{}` is also written by `{}` of this job; give each its own file", seen[i].0, first.1);
                let err = JobError { file: ctx.file.path.clone(), position: pos, key: Some(key), message };
                ctx.push(err);
                broken = true;
            }
        }
        if broken {
            continue;
        }
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
            sample_mask: sample_mask.clone(),
            more_samples: more_samples.clone(),
            augment: augment.clone(),
            inpaint: inpaint.clone(),
            guide: guide.clone(),
            method,
            seed,
            params,
            output: OutputSpec { path, width, height, format, bit_depth, native_depth, tileable: raw.tileable, source_map },
            metrics: raw.metrics.clone(),
            companions: named,
            positions,
        });
    }
    jobs
}
