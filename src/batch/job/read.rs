//! Reading one job file: TOML with positions, every top-level and `[output]` key checked, each
//! problem recorded with its line, column and key; the values handed to `sweep`.

use super::source::{Ctx, Raw, RawCompanion, RawGuide, RawInpaint, Ready, de_int, de_param, type_name};
use super::sweep;
use super::{
    COMPANION_KEYS, Companion, DEFAULT_GUIDE_PASSES, DEFAULT_GUIDE_WEIGHT, GUIDE_KEYS, GuideSpec, INPAINT_KEYS, Inpaint, InpaintMask, Job,
    JobError, JobFile, MAX_OUTPUT_SIDE, MaskChannel, OUTPUT_KEYS, TOP_KEYS, normalise_output_path,
};
use crate::digest::Digest;
use crate::image::io::Format;
use crate::synth::methods;
use crate::synth::params;
use crate::synth::params::Choice;
use crate::synth::placement::MapKind;
use std::path::Path;
use toml::Spanned;
use toml::de::{DeTable, DeValue};

pub(super) fn read_job_file(f: &JobFile) -> Result<Vec<Job>, Vec<JobError>> {
    let bytes = crate::files::read_limited(&f.path, crate::files::MAX_JOB_FILE_BYTES)
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
    let mut ctx = Ctx::new(f, &src);
    let (table, parse_errors) = DeTable::parse_recoverable(&src);
    for e in &parse_errors {
        ctx.err(e.span(), None, format!("malformed TOML: {}", e.message().trim()));
    }
    if !parse_errors.is_empty() {
        return Err(ctx.into_errors());
    }
    let jobs = build_jobs(&mut ctx, table.get_ref(), &bytes);
    if ctx.errors.is_empty() { Ok(jobs) } else { Err(ctx.into_errors()) }
}

/// The top-level keys, each checked for type; `[params]` and `[sweep]` are returned for later,
/// since they need the method.
fn read_top_level<'t>(ctx: &mut Ctx, table: &'t DeTable) -> (Raw<'t>, Option<&'t Spanned<DeValue<'t>>>, Option<&'t Spanned<DeValue<'t>>>) {
    let mut raw = Raw {
        sample: None,
        sample_mask: None,
        samples: None,
        sample_masks: None,
        augment: None,
        inpaint: None,
        guide: None,
        method: None,
        seed: None,
        output_path: None,
        width: None,
        height: None,
        bit_depth: None,
        tileable: false,
        source_map: None,
        companions: Vec::new(),
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
            "sample_mask" => match v.get_ref() {
                DeValue::String(s) if !s.is_empty() => raw.sample_mask = Some((s.to_string(), v.span())),
                DeValue::String(_) => ctx.err(Some(v.span()), Some("sample_mask"), "sample_mask path is empty"),
                DeValue::Array(_) => {
                    raw.sample_masks = read_string_list(ctx, v, "sample_mask", true).map(|l| (l, v.span()));
                }
                other => ctx.err(
                    Some(v.span()),
                    Some("sample_mask"),
                    format!(
                        "expected a string (the mask image's path: white = may be copied, black = never) or a list parallel to `samples`, found {}",
                        type_name(other)
                    ),
                ),
            },
            "samples" => match v.get_ref() {
                DeValue::Array(a) if a.is_empty() => ctx.err(Some(v.span()), Some("samples"), "samples is empty: name at least one sample"),
                DeValue::Array(_) => raw.samples = read_string_list(ctx, v, "samples", false).map(|l| (l, v.span())),
                other => ctx.err(
                    Some(v.span()),
                    Some("samples"),
                    format!("expected a list of sample paths (`samples = [\"a.png\", \"b.png\"]`), found {}", type_name(other)),
                ),
            },
            "augment" => read_augment(ctx, v, &mut raw),
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
            "companion" => read_companions(ctx, v, &mut raw),
            "guide" => match v.get_ref() {
                DeValue::Table(t) => raw.guide = Some(read_guide(ctx, t, v.span())),
                other => ctx.err(
                    Some(v.span()),
                    Some("guide"),
                    format!("expected a table ([guide] with target, and optionally source and weight), found {}", type_name(other)),
                ),
            },
            "inpaint" => match v.get_ref() {
                DeValue::Table(t) => raw.inpaint = Some(read_inpaint(ctx, t, v.span())),
                other => ctx.err(
                    Some(v.span()),
                    Some("inpaint"),
                    format!("expected a table ([inpaint] with image and mask or channel), found {}", type_name(other)),
                ),
            },
            other => ctx.err(Some(k.span()), Some(other), params::unknown_key_message(other, TOP_KEYS)),
        }
    }
    (raw, params_table, sweep_table)
}

/// Reads one file's keys, reports every problem, and expands the valid result into jobs.
fn build_jobs(ctx: &mut Ctx, table: &DeTable, file_bytes: &[u8]) -> Vec<Job> {
    let (mut raw, params_table, sweep_table) = read_top_level(ctx, table);
    let sample_given = raw.sample.is_some() || raw.samples.is_some() || raw.inpaint.is_some() || table.get("samples").is_some();
    for (key, what) in [("sample", sample_given), ("method", table.get("method").is_some())] {
        if !what && table.get(key).is_none() {
            ctx.err(None, Some(key), format!("missing required key `{key}`"));
        }
    }
    // An inpainting job's output has its image's size, a guided one its target's (as with
    // `texsyn synth --guide`): width and height may be left out.
    let inpaint_sized = raw.inpaint.is_some() || raw.guide.is_some();
    if table.get("output").is_none() {
        ctx.err(None, Some("output"), "missing required table [output] (with path, width and height)");
    } else if matches!(table.get("output").map(|v| v.get_ref()), Some(DeValue::Table(_))) {
        for (k, present) in [
            ("path", raw.output_path.is_some()),
            ("width", raw.width.is_some() || inpaint_sized),
            ("height", raw.height.is_some() || inpaint_sized),
        ] {
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

    // The samples must exist (they are decoded later, once per distinct file).
    let base = ctx.file.path.parent().unwrap_or(Path::new("")).to_path_buf();
    let exists = |ctx: &mut Ctx, s: &str, span: &std::ops::Range<usize>, key: &str, what: &str| {
        let p = base.join(s);
        if p.is_file() {
            Some(p)
        } else {
            let why = missing_file_reason(&p);
            ctx.err(Some(span.clone()), Some(key), format!("{what} `{}` {why} (paths are relative to the job file)", p.display()));
            None
        }
    };
    if let (Some(_), Some((_, span))) = (&raw.sample, &raw.samples) {
        ctx.err(Some(span.clone()), Some("samples"), "both `sample` and `samples` are given; keep one (`samples` may hold a single path)");
    }
    let mut sample_path = None;
    let mut more_paths: Vec<Option<std::path::PathBuf>> = Vec::new();
    if let Some((s, span)) = &raw.sample {
        sample_path = exists(ctx, s, span, "sample", "sample");
    } else if let Some((list, _)) = &raw.samples {
        let found: Vec<_> = list.iter().map(|(s, span)| exists(ctx, s, span, "samples", "sample")).collect();
        sample_path = found[0].clone();
        more_paths = found[1..].to_vec();
    }
    let sample_count = raw.samples.as_ref().map_or(1, |(l, _)| l.len());
    // The sample masks, likewise: one string for one sample, or a list parallel to `samples`.
    let mut sample_mask = None;
    let mut more_masks: Vec<Option<std::path::PathBuf>> = vec![None; sample_count.saturating_sub(1)];
    let mask_span = raw.sample_mask.as_ref().map(|(_, s)| s.clone()).or_else(|| raw.sample_masks.as_ref().map(|(_, s)| s.clone()));
    if let Some((s, span)) = &raw.sample_mask {
        if sample_count > 1 {
            ctx.err(
                Some(span.clone()),
                Some("sample_mask"),
                format!(
                    "with {sample_count} samples, give `sample_mask` as a list parallel to `samples` (\"\" for a sample without a mask)"
                ),
            );
        } else {
            sample_mask = exists(ctx, s, span, "sample_mask", "sample mask");
        }
    }
    if let Some((list, span)) = &raw.sample_masks {
        if list.len() != sample_count {
            ctx.err(
                Some(span.clone()),
                Some("sample_mask"),
                format!(
                    "lists {} masks for {sample_count} samples; give one per sample, in the order of `samples` (\"\" for none)",
                    list.len()
                ),
            );
        } else {
            let resolved: Vec<Option<std::path::PathBuf>> =
                list.iter().map(|(s, span)| if s.is_empty() { None } else { exists(ctx, s, span, "sample_mask", "sample mask") }).collect();
            sample_mask = resolved[0].clone();
            more_masks = resolved[1..].to_vec();
        }
    }
    let masked = raw.sample_mask.is_some() || raw.sample_masks.as_ref().is_some_and(|(l, _)| l.iter().any(|(s, _)| !s.is_empty()));
    if masked && let (Some(m), Some(span)) = (method.filter(|m| !m.honours_sample_mask()), &mask_span) {
        let can: Vec<&str> = methods::registry().iter().filter(|m| m.honours_sample_mask()).map(|m| m.name()).collect();
        ctx.err(
            Some(span.clone()),
            Some("sample_mask"),
            format!("{} does not honour a sample mask; methods that do: {}", m.name(), can.join(", ")),
        );
    }
    // Several samples and transformed copies are searched as one atlas whose gutters a sample
    // mask forbids: only a method that honours sample masks can learn from them.
    let augment = raw.augment.as_ref().map(|(a, _)| a.clone()).unwrap_or_default();
    if let Some(m) = method.filter(|m| !m.honours_sample_mask()) {
        let can: Vec<&str> = methods::registry().iter().filter(|m| m.honours_sample_mask()).map(|m| m.name()).collect();
        if let Some((_, span)) = raw.samples.as_ref().filter(|(l, _)| l.len() > 1) {
            ctx.err(
                Some(span.clone()),
                Some("samples"),
                format!("{} learns from one sample; methods that take several: {}", m.name(), can.join(", ")),
            );
        }
        if let Some((_, span)) = raw.augment.as_ref().filter(|(a, _)| !a.is_empty()) {
            ctx.err(
                Some(span.clone()),
                Some("augment"),
                format!("{} cannot search transformed copies of its sample; methods that can: {}", m.name(), can.join(", ")),
            );
        }
    }
    let mut more_samples: Vec<super::MoreSample> =
        more_paths.into_iter().zip(more_masks).filter_map(|(p, mask)| p.map(|path| super::MoreSample { path, mask })).collect();
    let inpaint = match raw.inpaint.take() {
        Some(r) => check_inpaint(ctx, r, &raw, method).map(|(mask, size, image)| {
            if let Some((w, h)) = size {
                raw.width.get_or_insert(w);
                raw.height.get_or_insert(h);
            }
            // The image is the first sample (its known pixels are the output's). Samples the
            // file lists are what the fill copies from; the image is one of them only when
            // listed (with the mask listed for it), or when none are given.
            let listed = raw.sample.is_some() || raw.samples.is_some();
            let given: Vec<super::MoreSample> = sample_path
                .take()
                .map(|path| super::MoreSample { path, mask: sample_mask.take() })
                .into_iter()
                .chain(std::mem::take(&mut more_samples))
                .collect();
            let same =
                |p: &Path| p == image || std::fs::canonicalize(p).ok().zip(std::fs::canonicalize(&image).ok()).is_some_and(|(a, b)| a == b);
            let own = given.iter().find(|s| same(&s.path)).map(|s| s.mask.clone());
            let copy_from_image = !listed || own.is_some();
            if listed {
                sample_mask = own.flatten();
                more_samples = given.into_iter().filter(|s| !same(&s.path)).collect();
            } else {
                sample_mask = given.into_iter().next().and_then(|s| s.mask);
            }
            sample_path = Some(image);
            Inpaint { mask, copy_from_image }
        }),
        None => None,
    };
    // With several samples each companion names one map per sample, in their order; when
    // inpainting from other samples, the image's map first, then one per other sample.
    let (maps_wanted, order) = match &inpaint {
        None => (sample_count, "one per sample, in the order of `samples`".to_string()),
        Some(_) => {
            (1 + more_samples.len(), "the [inpaint] image's map first, then one per other sample, in the order of `samples`".to_string())
        }
    };
    for c in &raw.companions {
        let key = format!("companion[{}].sample", c.index + 1);
        match &c.listed {
            Some((n, span)) if *n != maps_wanted => {
                let what = if inpaint.is_some() { "images to copy from" } else { "samples" };
                ctx.err(Some(span.clone()), Some(&key), format!("lists {n} maps for {maps_wanted} {what}; give {order}"))
            }
            None if maps_wanted > 1 && c.sample.is_some() => {
                let position = ctx.positions.get(&key).copied();
                let message = if inpaint.is_some() {
                    format!(
                        "with {maps_wanted} images to copy from, give this map of each: a list, {order} (`sample = [\"wall_normal.png\", \"rock_normal.png\"]`)"
                    )
                } else {
                    format!(
                        "with {sample_count} samples, give this map of each sample: a list parallel to `samples` (`sample = [\"a_normal.png\", \"b_normal.png\"]`)"
                    )
                };
                ctx.push(JobError { file: ctx.file.path.clone(), position, key: Some(key), message })
            }
            _ => {}
        }
    }
    let guide_span = raw.guide.as_ref().map(|g| g.target.as_ref().map_or(g.span.clone(), |t| t.1.clone()));
    let guide = match raw.guide.take() {
        Some(g) => check_guide(ctx, g, &raw, method, inpaint.is_some()),
        None => None,
    };
    if let Some(g) = &guide
        && (raw.width.is_none() || raw.height.is_none())
    {
        match image_size(&g.target) {
            Ok((w, h)) => {
                raw.width.get_or_insert(w);
                raw.height.get_or_insert(h);
            }
            Err(e) => ctx.err(guide_span, Some("guide.target"), format!("cannot read the size of `{}`: {e}", g.target.display())),
        }
    }
    let format_and_depth = check_output_format(ctx, &raw);
    let mut companions = Vec::new();
    for c in std::mem::take(&mut raw.companions) {
        let prefix = format!("companion[{}]", c.index + 1);
        let Some((path, span)) = &c.path else { continue };
        let Some((format, bit_depth, native_depth)) = check_format(ctx, &prefix, path, span, c.bit_depth.as_ref()) else { continue };
        if let Err(e) = normalise_output_path(path) {
            ctx.err(Some(span.clone()), Some(&format!("{prefix}.path")), e);
        }
        let Some(sample) = c.sample else { continue };
        // The path stays a template until the sweep point is known.
        companions.push(Companion { sample, more_samples: c.more, path: path.clone(), format, bit_depth, native_depth, kind: c.kind });
    }
    if let Some((template, span)) = &raw.source_map
        && let Err(e) = normalise_output_path(template)
    {
        ctx.err(Some(span.clone()), Some("output.source_map"), e);
    }
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
                ctx.push(JobError { file: ctx.file.path.clone(), position: pos, key: Some(key), message: e.message });
            }
        }
    }
    if !ctx.errors.is_empty() {
        return Vec::new();
    }
    let (Some(method), Some(sample), Some((path_template, path_span)), Some(width), Some(height), Some((format, bit_depth, native_depth))) =
        (method, sample_path, raw.output_path.clone(), raw.width, raw.height, format_and_depth)
    else {
        return Vec::new();
    };
    let ready = Ready {
        method,
        sample,
        sample_mask,
        more_samples,
        augment,
        inpaint,
        guide,
        path_template,
        path_span,
        width,
        height,
        format,
        bit_depth,
        native_depth,
        file_digest: Digest::of_bytes(file_bytes),
        companions,
    };
    sweep::expand(ctx, &raw, &ready)
}

/// A list of strings (paths), each checked; `allow_empty`: `""` entries are kept (a sample
/// without a mask). `None` when an entry is not a string.
fn read_string_list(ctx: &mut Ctx, v: &Spanned<DeValue>, key: &str, allow_empty: bool) -> Option<Vec<(String, std::ops::Range<usize>)>> {
    let DeValue::Array(items) = v.get_ref() else { return None };
    let mut out = Vec::new();
    let mut ok = true;
    for (i, item) in items.iter().enumerate() {
        match item.get_ref() {
            DeValue::String(s) if !s.is_empty() || allow_empty => out.push((s.to_string(), item.span())),
            DeValue::String(_) => {
                ctx.err(Some(item.span()), Some(key), format!("entry {} is an empty path", i + 1));
                ok = false;
            }
            other => {
                ctx.err(Some(item.span()), Some(key), format!("entry {} should be a path (a string), found {}", i + 1, type_name(other)));
                ok = false;
            }
        }
    }
    ok.then_some(out)
}

/// `augment = ["rot90", …]`: known words, each once.
fn read_augment(ctx: &mut Ctx, v: &Spanned<DeValue>, raw: &mut Raw) {
    use crate::synth::atlas::Augment;
    let DeValue::Array(items) = v.get_ref() else {
        ctx.err(
            Some(v.span()),
            Some("augment"),
            format!("expected a list of transforms (any of {}), found {}", Augment::NAMES.join(", "), type_name(v.get_ref())),
        );
        return;
    };
    let mut out: Vec<Augment> = Vec::new();
    let mut ok = true;
    for item in items.iter() {
        let DeValue::String(word) = item.get_ref() else {
            ctx.err(Some(item.span()), Some("augment"), format!("expected a transform name, found {}", type_name(item.get_ref())));
            ok = false;
            continue;
        };
        match Augment::parse(word) {
            Some(a) if out.contains(&a) => {
                ctx.err(Some(item.span()), Some("augment"), format!("`{word}` is listed twice"));
                ok = false;
            }
            Some(a) => out.push(a),
            None => {
                let hint = params::nearest(word, Augment::NAMES).map(|n| format!(" (did you mean `{n}`?)")).unwrap_or_default();
                ctx.err(
                    Some(item.span()),
                    Some("augment"),
                    format!("unknown transform `{word}`{hint}; valid: {}", Augment::NAMES.join(", ")),
                );
                ok = false;
            }
        }
    }
    if ok {
        raw.augment = Some((out, v.span()));
    }
}

/// `[guide]`: `target` and `source` (paths), `weight` (a number in 0..=1), each checked for type.
fn read_guide(ctx: &mut Ctx, t: &DeTable, span: std::ops::Range<usize>) -> RawGuide {
    let mut g = RawGuide { span, ..RawGuide::default() };
    for (k, v) in t.iter() {
        let key = format!("guide.{}", k.get_ref());
        ctx.at(&key, k.span());
        match k.get_ref().as_ref() {
            which @ ("target" | "source") => match v.get_ref() {
                DeValue::String(s) if !s.is_empty() => {
                    let value = Some((s.to_string(), v.span()));
                    if which == "target" { g.target = value } else { g.source = value }
                }
                other => {
                    let what = if which == "target" { "the output's guide image" } else { "the sample's guide image" };
                    ctx.err(Some(v.span()), Some(&key), format!("expected a non-empty string ({what}), found {}", type_name(other)))
                }
            },
            "weight" => {
                let value = match v.get_ref() {
                    DeValue::Float(f) => f.as_str().replace('_', "").parse::<f64>().ok(),
                    DeValue::Integer(_) => de_int(v.get_ref()).and_then(|r| r.ok()).map(|i| i as f64),
                    _ => None,
                };
                match value {
                    Some(w) if (0.0..=1.0).contains(&w) => g.weight = Some(w),
                    Some(w) => ctx.err(
                        Some(v.span()),
                        Some(&key),
                        format!("{w} is out of range: the guide's share is 0 (ignore it) ..= 1 (only the guide)"),
                    ),
                    None => ctx.err(Some(v.span()), Some(&key), format!("expected a number in 0..=1, found {}", type_name(v.get_ref()))),
                }
            }
            "passes" => match de_int(v.get_ref()) {
                Some(Ok(n)) if (1..=8).contains(&n) => (g.passes, g.passes_span) = (Some(n as u32), Some(v.span())),
                Some(Ok(n)) => {
                    ctx.err(Some(v.span()), Some(&key), format!("{n} is out of range: allowed 1..=8 (Efros and Freeman use 3 to 5)"))
                }
                Some(Err(e)) => ctx.err(Some(v.span()), Some(&key), e),
                None => ctx.err(Some(v.span()), Some(&key), format!("expected an integer, found {}", type_name(v.get_ref()))),
            },
            other => ctx.err(Some(k.span()), Some(&key), params::unknown_key_message(other, GUIDE_KEYS)),
        }
    }
    g
}

/// `[guide]` checked against the rest of the file: a target that exists, a source that exists
/// when given, a method that follows guides (while it inpaints, too), one pass for a hole.
fn check_guide(
    ctx: &mut Ctx,
    g: RawGuide,
    raw: &Raw,
    method: Option<&'static dyn crate::synth::method::Method>,
    inpainting: bool,
) -> Option<GuideSpec> {
    let base = ctx.file.path.parent().unwrap_or(Path::new("")).to_path_buf();
    let mut ok = true;
    if let Some(m) = method.filter(|m| !m.honours_guide()) {
        let can: Vec<&str> = methods::registry().iter().filter(|m| m.honours_guide()).map(|m| m.name()).collect();
        ctx.err(Some(g.span.clone()), Some("guide"), format!("{} cannot follow a guide; methods that can: {}", m.name(), can.join(", ")));
        ok = false;
    }
    // A hole is filled once, each block matched to the known pixels: the iteration that
    // re-synthesises a whole output with smaller blocks does not apply.
    if inpainting && let Some(passes) = g.passes.filter(|&p| p > 1) {
        let span = g.passes_span.clone().unwrap_or(g.span.clone());
        ctx.err(
            Some(span),
            Some("guide.passes"),
            format!("an [inpaint] job fills its hole in one guided pass: leave `guide.passes` out or set it to 1 (found {passes})"),
        );
        ok = false;
    }
    if let (Some((_, span)), Some((list, _))) = (&g.source, &raw.samples)
        && list.len() > 1
    {
        ctx.err(
            Some(span.clone()),
            Some("guide.source"),
            "with several `samples`, each sample's luminance is its guide: leave `guide.source` out (one source guide per sample is not supported yet)",
        );
        ok = false;
    }
    let mut file = |key: &str, value: &Option<(String, std::ops::Range<usize>)>, what: &str| -> Option<std::path::PathBuf> {
        let (s, span) = value.as_ref()?;
        let p = base.join(s);
        if p.is_file() {
            Some(p)
        } else {
            let why = missing_file_reason(&p);
            ctx.err(Some(span.clone()), Some(key), format!("{what} `{}` {why} (paths are relative to the job file)", p.display()));
            ok = false;
            None
        }
    };
    let target = file("guide.target", &g.target, "target guide");
    let source = file("guide.source", &g.source, "source guide");
    if g.target.is_none() {
        ctx.err(Some(g.span.clone()), Some("guide.target"), "missing required key `guide.target` (the output's guide image)");
        return None;
    }
    if !ok {
        return None;
    }
    Some(GuideSpec {
        target: target?,
        source,
        weight: g.weight.unwrap_or(DEFAULT_GUIDE_WEIGHT),
        passes: g.passes.unwrap_or(if inpainting { 1 } else { DEFAULT_GUIDE_PASSES }),
    })
}

/// `[inpaint]`: `image` (a path), and `mask` (a path) or `channel` (a word), each checked for type.
fn read_inpaint(ctx: &mut Ctx, t: &DeTable, span: std::ops::Range<usize>) -> RawInpaint {
    let mut r = RawInpaint { span, channel_given: t.get("channel").is_some(), ..RawInpaint::default() };
    for (k, v) in t.iter() {
        let key = format!("inpaint.{}", k.get_ref());
        ctx.at(&key, k.span());
        match k.get_ref().as_ref() {
            which @ ("image" | "mask") => match v.get_ref() {
                DeValue::String(s) if !s.is_empty() => {
                    let value = Some((s.to_string(), v.span()));
                    if which == "image" { r.image = value } else { r.mask = value }
                }
                other => {
                    let what = if which == "image" { "the image to repair" } else { "the mask image: white = fill" };
                    ctx.err(Some(v.span()), Some(&key), format!("expected a non-empty string ({what}), found {}", type_name(other)))
                }
            },
            "channel" => match v.get_ref() {
                DeValue::String(s) => match MaskChannel::parse(s) {
                    Some(c) => r.channel = Some(c),
                    None => {
                        let hint = params::nearest(s, MaskChannel::NAMES).map(|n| format!(" (did you mean `{n}`?)")).unwrap_or_default();
                        ctx.err(
                            Some(v.span()),
                            Some(&key),
                            format!("unknown channel `{s}`{hint}; use one of {}", MaskChannel::NAMES.join(", ")),
                        );
                    }
                },
                other => ctx.err(Some(v.span()), Some(&key), format!("expected \"r\", \"g\", \"b\" or \"a\", found {}", type_name(other))),
            },
            other => ctx.err(Some(k.span()), Some(&key), params::unknown_key_message(other, INPAINT_KEYS)),
        }
    }
    r
}

/// `[inpaint]` checked against the rest of the file: an image that exists (it becomes the first
/// sample), exactly one of `mask` and `channel`, a method that inpaints, and the output's size
/// (the image's, read from its header when the file leaves it out). Returns the mask, that size
/// and the image's path.
fn check_inpaint(
    ctx: &mut Ctx,
    r: RawInpaint,
    raw: &Raw,
    method: Option<&'static dyn crate::synth::method::Method>,
) -> Option<(InpaintMask, Option<(u32, u32)>, std::path::PathBuf)> {
    let base = ctx.file.path.parent().unwrap_or(Path::new("")).to_path_buf();
    let mut ok = true;
    if let Some(m) = method.filter(|m| !m.honours_inpaint()) {
        let can: Vec<&str> = methods::registry().iter().filter(|m| m.honours_inpaint()).map(|m| m.name()).collect();
        ctx.err(Some(r.span.clone()), Some("inpaint"), format!("{} cannot inpaint; methods that can: {}", m.name(), can.join(", ")));
        ok = false;
    }
    let image = match &r.image {
        None => {
            ctx.err(Some(r.span.clone()), Some("inpaint.image"), "missing required key `inpaint.image` (the image to repair)");
            None
        }
        Some((s, span)) => {
            let p = base.join(s);
            if p.is_file() {
                Some(p)
            } else {
                let why = missing_file_reason(&p);
                ctx.err(
                    Some(span.clone()),
                    Some("inpaint.image"),
                    format!("image `{}` {why} (paths are relative to the job file)", p.display()),
                );
                None
            }
        }
    };
    let mask = match (&r.mask, r.channel) {
        (Some(_), Some(_)) => {
            ctx.err(
                Some(r.span.clone()),
                Some("inpaint.channel"),
                "give either `mask` (an image) or `channel` (one of the image's), not both",
            );
            None
        }
        (None, None) if r.channel_given => None,
        (None, None) => {
            ctx.err(
                Some(r.span.clone()),
                Some("inpaint.mask"),
                "missing `inpaint.mask` (an image, white = fill) or `inpaint.channel` (\"a\": fill the transparent pixels)",
            );
            None
        }
        (None, Some(c)) => Some(InpaintMask::Channel(c)),
        (Some((s, span)), None) => {
            let p = base.join(s);
            if p.is_file() {
                Some(InpaintMask::File(p))
            } else {
                let why = missing_file_reason(&p);
                ctx.err(
                    Some(span.clone()),
                    Some("inpaint.mask"),
                    format!("mask `{}` {why} (paths are relative to the job file)", p.display()),
                );
                None
            }
        }
    };
    let (image, mask) = (image?, mask?);
    if !ok {
        return None;
    }
    let mut size = None;
    if raw.width.is_none() || raw.height.is_none() {
        match image_size(&image) {
            Ok(dims) => size = Some(dims),
            Err(e) => {
                let span = r.image.as_ref().map(|(_, s)| s.clone());
                ctx.err(span, Some("inpaint.image"), format!("cannot read the size of `{}`: {e}", image.display()));
                return None;
            }
        }
    }
    Some((mask, size, image))
}

/// `metrics = true` (all but `repetition`: [`crate::metrics::DEFAULT_METRICS`]), `false` (none)
/// or a list of metric names.
fn read_metrics(ctx: &mut Ctx, v: &Spanned<DeValue>, raw: &mut Raw) {
    let names = crate::metrics::METRIC_NAMES;
    match v.get_ref() {
        DeValue::Boolean(true) => raw.metrics = crate::metrics::DEFAULT_METRICS.iter().map(|s| s.to_string()).collect(),
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
            "tileable" => match v.get_ref() {
                DeValue::Boolean(b) => raw.tileable = *b,
                other => ctx.err(Some(v.span()), Some(&key), format!("expected true or false, found {}", type_name(other))),
            },
            "source_map" => match v.get_ref() {
                DeValue::String(s) if s.to_ascii_lowercase().ends_with(".exr") => raw.source_map = Some((s.to_string(), v.span())),
                DeValue::String(s) => ctx.err(
                    Some(v.span()),
                    Some(&key),
                    format!("source map `{s}` must end in .exr (the placement is stored as an EXR with integer channels)"),
                ),
                other => {
                    ctx.err(Some(v.span()), Some(&key), format!("expected a string (a path ending in .exr), found {}", type_name(other)))
                }
            },
            other => ctx.err(Some(k.span()), Some(&key), params::unknown_key_message(other, OUTPUT_KEYS)),
        }
    }
}

/// `[[companion]]` tables: each needs `sample` and `path`; `kind` and `bit_depth` are optional.
fn read_companions(ctx: &mut Ctx, v: &Spanned<DeValue>, raw: &mut Raw) {
    let DeValue::Array(items) = v.get_ref() else {
        let found = type_name(v.get_ref());
        ctx.err(Some(v.span()), Some("companion"), format!("expected [[companion]] tables, found {found}"));
        return;
    };
    let base = ctx.file.path.parent().unwrap_or(Path::new("")).to_path_buf();
    for (index, item) in items.iter().enumerate() {
        let prefix = format!("companion[{}]", index + 1);
        let DeValue::Table(t) = item.get_ref() else {
            ctx.err(Some(item.span()), Some(&prefix), format!("expected a table, found {}", type_name(item.get_ref())));
            continue;
        };
        ctx.at(&prefix, item.span());
        let mut c = RawCompanion { index, sample: None, more: Vec::new(), listed: None, path: None, kind: MapKind::Color, bit_depth: None };
        for (k, v) in t.iter() {
            let key = format!("{prefix}.{}", k.get_ref());
            ctx.at(&key, k.span());
            match k.get_ref().as_ref() {
                "sample" => match v.get_ref() {
                    DeValue::String(s) if !s.is_empty() => {
                        let p = base.join(s.as_ref() as &str);
                        if p.is_file() {
                            c.sample = Some(p);
                        } else {
                            let why = missing_file_reason(&p);
                            ctx.err(
                                Some(v.span()),
                                Some(&key),
                                format!("companion sample `{}` {why} (paths are relative to the job file)", p.display()),
                            );
                        }
                    }
                    // With several samples: one map per sample, in their order.
                    DeValue::Array(_) => {
                        if let Some(list) = read_string_list(ctx, v, &key, false) {
                            let mut found = Vec::new();
                            for (s, span) in &list {
                                let p = base.join(s);
                                if p.is_file() {
                                    found.push(p);
                                } else {
                                    let why = missing_file_reason(&p);
                                    ctx.err(
                                        Some(span.clone()),
                                        Some(&key),
                                        format!("companion sample `{}` {why} (paths are relative to the job file)", p.display()),
                                    );
                                }
                            }
                            c.listed = Some((list.len(), v.span()));
                            if found.len() == list.len() && !found.is_empty() {
                                c.sample = Some(found.remove(0));
                                c.more = found;
                            }
                        }
                    }
                    other => ctx.err(
                        Some(v.span()),
                        Some(&key),
                        format!(
                            "expected a non-empty string (the map's path), or with several samples a list of one per sample, found {}",
                            type_name(other)
                        ),
                    ),
                },
                "path" => match v.get_ref() {
                    DeValue::String(s) if !s.is_empty() => c.path = Some((s.to_string(), v.span())),
                    other => ctx.err(
                        Some(v.span()),
                        Some(&key),
                        format!("expected a non-empty string (where to write it), found {}", type_name(other)),
                    ),
                },
                "kind" => match v.get_ref() {
                    DeValue::String(s) => match MapKind::from_name(s) {
                        Some(kind) => c.kind = kind,
                        None => ctx.err(
                            Some(v.span()),
                            Some(&key),
                            format!("unknown kind `{s}`; use \"color\" (blended as is) or \"normal\" (blended normals are renormalised)"),
                        ),
                    },
                    other => ctx.err(Some(v.span()), Some(&key), format!("expected \"color\" or \"normal\", found {}", type_name(other))),
                },
                "bit_depth" => match de_int(v.get_ref()) {
                    Some(Ok(n)) => c.bit_depth = Some((n, v.span())),
                    Some(Err(e)) => ctx.err(Some(v.span()), Some(&key), e),
                    None => ctx.err(Some(v.span()), Some(&key), format!("expected an integer (8 or 16), found {}", type_name(v.get_ref()))),
                },
                other => ctx.err(Some(k.span()), Some(&key), params::unknown_key_message(other, COMPANION_KEYS)),
            }
        }
        for (k, present) in [("sample", t.get("sample").is_some()), ("path", t.get("path").is_some())] {
            if !present {
                ctx.err(Some(item.span()), Some(&format!("{prefix}.{k}")), format!("missing required key `{prefix}.{k}`"));
            }
        }
        raw.companions.push(c);
    }
}

fn check_output_format(ctx: &mut Ctx, raw: &Raw) -> Option<(Format, u8, bool)> {
    let (path, span) = raw.output_path.as_ref()?;
    check_format(ctx, "output", path, span, raw.bit_depth.as_ref())
}

/// The format a path asks for and the bit depth: given, or (`true`) the sample's precision.
fn check_format(
    ctx: &mut Ctx,
    table: &str,
    path: &str,
    span: &std::ops::Range<usize>,
    bit_depth: Option<&(i64, std::ops::Range<usize>)>,
) -> Option<(Format, u8, bool)> {
    let format = match Format::from_path(Path::new(path)) {
        Some(f) => f,
        None => {
            ctx.err(Some(span.clone()), Some(&format!("{table}.path")), format!("output `{path}` must end in .png or .exr"));
            return None;
        }
    };
    let key = format!("{table}.bit_depth");
    match (format, bit_depth) {
        (Format::Png, None) => Some((format, 8, true)),
        (Format::Png, Some((8, _))) => Some((format, 8, false)),
        (Format::Png, Some((16, _))) => Some((format, 16, false)),
        (Format::Png, Some((d, s))) => {
            ctx.err(Some(s.clone()), Some(&key), format!("bit depth {d} is not supported for PNG: use 8 or 16"));
            None
        }
        (Format::Exr, None) => Some((format, 32, false)),
        (Format::Exr, Some((_, s))) => {
            ctx.err(Some(s.clone()), Some(&key), "bit_depth applies to PNG only (EXR outputs are 32-bit float); remove it");
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

/// The size an image file's header gives, without decoding it.
fn image_size(path: &std::path::Path) -> Result<(u32, u32), String> {
    ::image::ImageReader::open(path)
        .and_then(|r| r.with_guessed_format())
        .map_err(|e| e.to_string())
        .and_then(|r| r.into_dimensions().map_err(|e| e.to_string()))
}
