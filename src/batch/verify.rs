//! `texsyn verify`: re-run every recorded job from the manifest alone and compare pixels.
//!
//! Checks, per job: the sample still has the recorded pixels, the method and algorithm version
//! exist, the recorded parameters still resolve to themselves, a fresh synthesis (written to a
//! temporary directory) has the recorded pixel digest, and the output file in the output
//! directory still has the recorded bytes and pixels. The manifest's deterministic digest is
//! recomputed too, so an edited manifest is caught even when its jobs still reproduce.

use crate::batch::execute::LoadedSample;
use crate::batch::execute::{JobInputs, SOURCE_MAP_FORMAT, load_sample, synthesize_and_encode};
use crate::batch::job::Companion;
use crate::batch::job::OutputSpec;
use crate::batch::manifest::{JobRecord, Manifest, Status};
use crate::batch::memory::{self, Budget};
use crate::digest::Digest;
use crate::error::Error;
use crate::image::io::{self as imageio, DecodeLimits};
use crate::synth::constraints::SampleMask;
use crate::synth::method::Uses;
use crate::synth::methods;
use crate::synth::params::Choice;
use crate::synth::params::{self, ParamValue};
use std::path::{Path, PathBuf};

/// The outcome for one job.
#[derive(Clone, Debug, PartialEq)]
pub enum Outcome {
    Verified,
    Skipped(String),
    Mismatch(Vec<String>),
    /// Not re-run: its estimated peak memory exceeds the limit (the message says both).
    TooLarge(String),
}

#[derive(Debug, Default)]
pub struct Report {
    /// Problems with the manifest as a whole.
    pub manifest_problems: Vec<String>,
    pub jobs: Vec<(String, Outcome)>,
}

impl Report {
    pub fn ok(&self) -> bool {
        self.manifest_problems.is_empty() && self.jobs.iter().all(|(_, o)| matches!(o, Outcome::Verified | Outcome::Skipped(_)))
    }
}

/// Verifies a manifest, re-running jobs on `threads` threads (all cores if `None`), within the
/// memory available now ([`verify_within`]).
pub fn verify(manifest_path: &Path, threads: Option<usize>) -> Result<Report, Error> {
    verify_within(manifest_path, threads, crate::batch::memory::available())
}

/// [`verify`] under a memory limit in bytes (`None`: none), kept as `texsyn run` keeps
/// `--max-memory`: a job whose estimated peak exceeds it is not re-run ([`Outcome::TooLarge`]),
/// and jobs whose estimates together exceed it never run at once. The sizes come from the
/// manifest, which [`Manifest::load`] has already bounded like a job file's.
pub fn verify_within(manifest_path: &Path, threads: Option<usize>, max_memory: Option<u64>) -> Result<Report, Error> {
    let manifest = Manifest::load(manifest_path)?;
    let dir = manifest_path.parent().map(Path::to_path_buf).unwrap_or_else(|| PathBuf::from("."));
    let dir = if dir.as_os_str().is_empty() { PathBuf::from(".") } else { dir };
    let mut report = Report::default();
    if manifest.recompute_digest() != manifest.deterministic_digest {
        report.manifest_problems.push(format!(
            "the manifest's deterministic digest ({}) does not match its content ({}): it was edited after texsyn wrote it",
            manifest.deterministic_digest.short(),
            manifest.recompute_digest().short()
        ));
    }
    let scratch = std::env::temp_dir().join(format!(
        "texsyn-verify-{}-{}",
        std::process::id(),
        Digest::of_bytes(manifest_path.display().to_string().as_bytes()).short()
    ));
    std::fs::create_dir_all(&scratch).map_err(|e| Error::io(&scratch, "create", e))?;
    let pool = crate::batch::run::pool(threads)?;
    let budget = Budget::new(max_memory);
    let outcomes: Vec<std::sync::Mutex<Option<Outcome>>> = manifest.jobs.iter().map(|_| std::sync::Mutex::new(None)).collect();
    pool.install(|| {
        // As in `run`: one dispatcher waits for the budget, in record order, never a job.
        rayon::scope(|scope| {
            for (rec, slot) in manifest.jobs.iter().zip(&outcomes) {
                let estimate = estimate(rec);
                if let Some(limit) = max_memory.filter(|&l| estimate > l) {
                    *slot.lock().expect("outcome") = Some(Outcome::TooLarge(memory::too_large(estimate, limit)));
                    continue;
                }
                let held = budget.acquire(estimate);
                let (dir, scratch) = (&dir, &scratch);
                scope.spawn(move |_| {
                    let outcome = verify_job(rec, dir, scratch);
                    *slot.lock().expect("outcome") = Some(outcome);
                    drop(held);
                });
            }
        })
    });
    report.jobs = manifest
        .jobs
        .iter()
        .zip(outcomes)
        .map(|(rec, slot)| (rec.id.clone(), slot.into_inner().expect("outcome").expect("every job has an outcome")))
        .collect();
    let _ = std::fs::remove_dir_all(&scratch);
    Ok(report)
}

/// The estimated peak memory of re-running a record (0 for one that will not run): the same
/// model as `run`'s, for a job rendered whole (verify never renders in strips) with its encoded
/// file held beside it.
fn estimate(rec: &JobRecord) -> u64 {
    let (Some(method), Some(params_json), Some(sample), Some(spec)) =
        (rec.method.as_deref().and_then(methods::find), &rec.params, &rec.sample, &rec.output_spec)
    else {
        return 0;
    };
    if !rec.status.is_success() {
        return 0;
    }
    let Ok(given) = serde_json::from_value::<std::collections::BTreeMap<String, ParamValue>>(params_json.clone()) else { return 0 };
    let mut given: Vec<(String, ParamValue)> = given.into_iter().collect();
    method.fill_older_record(&mut given);
    let (Ok(params), Ok(output)) = (params::resolve(method.params(), &given), output_spec(spec)) else {
        return 0;
    };
    let materials = memory::Materials { companions: rec.companions.len(), source_map: output.source_map.is_some() };
    let encoded = 8 * u64::from(output.width) * u64::from(output.height);
    memory::job_estimate_with(method, &params, (sample.width, sample.height), &output, false, Some(materials)) + encoded
}

fn verify_job(rec: &JobRecord, dir: &Path, _scratch: &Path) -> Outcome {
    if !rec.status.is_success() {
        return Outcome::Skipped(format!("recorded as {}", rec.status.name()));
    }
    let mut problems = Vec::new();
    let (Some(method_name), Some(version), Some(params_json), Some(seed), Some(sample), Some(spec)) =
        (&rec.method, rec.algorithm_version, &rec.params, rec.seed, &rec.sample, &rec.output_spec)
    else {
        return Outcome::Mismatch(vec!["the record lacks the fields needed to re-run it".into()]);
    };
    let Some(method) = methods::find(method_name) else {
        return Outcome::Mismatch(vec![format!("method `{method_name}` is not known to this texsyn")]);
    };
    // Parameters: they must resolve to exactly what was recorded.
    let mut given: Vec<(String, ParamValue)> =
        match serde_json::from_value::<std::collections::BTreeMap<String, ParamValue>>(params_json.clone()) {
            Ok(m) => m.into_iter().collect(),
            Err(e) => return Outcome::Mismatch(vec![format!("recorded params are malformed: {e}")]),
        };
    method.fill_older_record(&mut given);
    let params = match params::resolve(method.params(), &given) {
        Ok(p) => p,
        Err(errs) => {
            return Outcome::Mismatch(errs.into_iter().map(|e| format!("recorded param `{}`: {}", e.key, e.message)).collect());
        }
    };
    if method.algorithm_version_of(&params, Uses::of_spec(spec)) != version {
        return Outcome::Mismatch(vec![format!(
            "recorded with {method_name} algorithm version {version}; this texsyn makes these parameters' pixels with version {}",
            method.algorithm_version_of(&params, Uses::of_spec(spec))
        )]);
    }
    if rec.params_digest.as_ref() != Some(&Digest::of_json(params_json)) {
        problems.push("params_digest does not match the recorded params".into());
    }
    let output = match output_spec(spec) {
        Ok(o) => o,
        Err(e) => return Outcome::Mismatch(vec![e]),
    };
    let sample_path = dir.join(&sample.path);
    let loaded = match load_sample(&sample_path) {
        Ok(s) => s,
        Err(e) => return Outcome::Mismatch(vec![format!("sample {e}")]),
    };
    if loaded.pixel_digest != sample.pixel_digest {
        return Outcome::Mismatch(vec![format!("sample `{}` no longer has the recorded pixels", sample.path)]);
    }
    let loaded = std::sync::Arc::new(loaded);
    // The sample mask: still the recorded pixels, of the sample's size.
    let sample_mask = match (spec.get("sample_mask"), &rec.sample_mask) {
        (None, None) => None,
        (Some(wanted), Some(m)) => {
            let mask = match load_sample(&dir.join(&m.path)) {
                Ok(s) => s,
                Err(e) => return Outcome::Mismatch(vec![format!("sample mask {e}")]),
            };
            if mask.pixel_digest != m.pixel_digest || wanted.get("pixels") != Some(&serde_json::json!(m.pixel_digest)) {
                return Outcome::Mismatch(vec![format!("sample mask `{}` no longer has the recorded pixels", m.path)]);
            }
            if mask.image.dimensions() != loaded.image.dimensions() {
                return Outcome::Mismatch(vec![format!("sample mask `{}` is not the sample's size", m.path)]);
            }
            Some(SampleMask::from_image(&mask.image))
        }
        _ => return Outcome::Mismatch(vec!["the record's sample mask does not match its output spec".into()]),
    };
    if sample_mask.is_some() && !method.honours_sample_mask() {
        return Outcome::Mismatch(vec![format!("recorded `sample_mask`: {method_name} does not honour a sample mask")]);
    }
    // Inpainting: the mask image still has the recorded pixels (or the channel is a real one),
    // and the region it makes passes the checks a job file's would.
    let fill = match (spec.get("inpaint"), &rec.inpaint_mask) {
        (None, None) => None,
        (Some(wanted), mask_record) => {
            if !method.honours_inpaint() {
                return Outcome::Mismatch(vec![format!("recorded `inpaint`: {method_name} cannot inpaint")]);
            }
            let mask_loaded = match mask_record {
                Some(m) => match load_sample(&dir.join(&m.path)) {
                    Ok(l)
                        if l.pixel_digest == m.pixel_digest
                            && wanted.pointer("/mask/pixels") == Some(&serde_json::json!(m.pixel_digest)) =>
                    {
                        Some((l, dir.join(&m.path)))
                    }
                    Ok(_) => return Outcome::Mismatch(vec![format!("inpaint mask `{}` no longer has the recorded pixels", m.path)]),
                    Err(e) => return Outcome::Mismatch(vec![format!("inpaint mask {e}")]),
                },
                None => None,
            };
            let channel = wanted.get("channel").and_then(|c| c.as_str()).and_then(crate::batch::job::MaskChannel::parse);
            let source = match (&mask_loaded, channel) {
                (Some((l, path)), None) => crate::batch::inpaint::MaskSource::File { path, loaded: l },
                (None, Some(c)) => crate::batch::inpaint::MaskSource::Channel(c),
                _ => return Outcome::Mismatch(vec!["the record's inpaint mask does not match its output spec".into()]),
            };
            // With other samples or copies, the atlas's own check covers the block.
            let block = if spec.get("samples").is_some() { None } else { params.int("block").ok() };
            match crate::batch::inpaint::fill_region(&loaded, &sample_path, &source, block, sample_mask.as_ref()) {
                Ok(region) => Some(region),
                Err(e) => return Outcome::Mismatch(vec![format!("recorded `{}`: {e}", source.key())]),
            }
        }
        (None, Some(_)) => return Outcome::Mismatch(vec!["the record's inpaint mask does not match its output spec".into()]),
    };
    // Several samples or `augment`: the atlas the job searched, from the recorded files.
    let image_copyable = fill.as_ref().map(|r| {
        let copy = spec.pointer("/inpaint/copy_from_image").and_then(|c| c.as_bool()).unwrap_or(true);
        crate::batch::samples::image_copyable(r, copy)
    });
    let atlas = match atlas_of_record(rec, spec, dir, &loaded, image_copyable.as_ref()) {
        Ok(a) => a,
        Err(e) => return Outcome::Mismatch(vec![e]),
    };
    let searched: &LoadedSample = atlas.as_ref().map_or(&*loaded, |a| &*a.search);
    // The method's own checks, as for a job file: a manifest may have been edited into
    // parameters no job file would pass (a block larger than the sample).
    let size = searched.image.dimensions();
    if let Some(Err((key, e))) = atlas.as_ref().map(|a| a.check_block(params.int("block").ok())) {
        return Outcome::Mismatch(vec![format!("recorded `{key}`: {e}")]);
    }
    let issues = method.check(&params, size, (output.width, output.height));
    if !issues.is_empty() {
        return Outcome::Mismatch(issues.into_iter().map(|e| format!("recorded param `{}`: {}", e.key, e.message)).collect());
    }
    if output.tileable
        && let Err(why) = method.tileable(&params, size, (output.width, output.height))
    {
        return Outcome::Mismatch(vec![format!("recorded `output_spec.tileable`: {why}")]);
    }
    let key = crate::batch::manifest::content_key(method_name, version, params_json, seed, &sample.pixel_digest, spec);
    if rec.content_key.as_ref() != Some(&key) {
        problems.push("content_key does not match the recorded inputs".into());
    }
    // Companions: their samples must still have the recorded pixels.
    let wanted: Vec<serde_json::Value> = spec.get("companions").and_then(|c| c.as_array()).cloned().unwrap_or_default();
    if wanted.len() != rec.companions.len() {
        return Outcome::Mismatch(vec!["the record's companions do not match its output spec".into()]);
    }
    let mut companions = Vec::new();
    for (k, (w, c)) in wanted.iter().zip(&rec.companions).enumerate() {
        let loaded = match load_sample(&dir.join(&c.path)) {
            Ok(s) => s,
            Err(e) => return Outcome::Mismatch(vec![format!("companion sample {e}")]),
        };
        if loaded.pixel_digest != c.pixel_digest {
            return Outcome::Mismatch(vec![format!("companion sample `{}` no longer has the recorded pixels", c.path)]);
        }
        let spec = match companion_spec(w, &dir.join(&c.path)) {
            Ok(s) => s,
            Err(e) => return Outcome::Mismatch(vec![e]),
        };
        // With several samples, the other samples' maps: still the recorded pixels.
        let wanted_more: Vec<serde_json::Value> = w.get("more_sample_pixels").and_then(|m| m.as_array()).cloned().unwrap_or_default();
        let more_records = rec.more_companions.get(k).cloned().unwrap_or_default();
        if wanted_more.len() != more_records.len() {
            return Outcome::Mismatch(vec!["the record's companion maps do not match its output spec".into()]);
        }
        let mut more = Vec::new();
        for (digest, r) in wanted_more.iter().zip(&more_records) {
            match load_sample(&dir.join(&r.path)) {
                Ok(l) if l.pixel_digest == r.pixel_digest && digest == &serde_json::json!(r.pixel_digest) => more.push(l),
                Ok(_) => return Outcome::Mismatch(vec![format!("companion sample `{}` no longer has the recorded pixels", r.path)]),
                Err(e) => return Outcome::Mismatch(vec![format!("companion sample {e}")]),
            }
        }
        // Packed like the samples when the job searched an atlas of samples or transformed copies.
        let loaded = match &atlas {
            Some(a) => {
                let maps: Vec<&LoadedSample> = std::iter::once(&loaded).chain(&more).collect();
                let sizes = a.atlas.sample_sizes();
                if maps.len() != sizes.len() || maps.iter().zip(&sizes).any(|(m, &s)| m.image.dimensions() != s) {
                    return Outcome::Mismatch(vec!["the record's companion maps are not one per sample, of its size".into()]);
                }
                crate::batch::samples::pack_map(&a.atlas, &maps, spec.kind)
            }
            None if !more.is_empty() => return Outcome::Mismatch(vec!["the record's companion maps are not one per sample".into()]),
            None => loaded,
        };
        companions.push((spec, loaded));
    }
    // Guided: both guides still have the recorded pixels and the recorded weight.
    let guide = match (spec.get("guide"), &rec.guide_target) {
        (None, None) => None,
        (Some(wanted), Some(t)) => {
            if !method.honours_guide() {
                return Outcome::Mismatch(vec![format!("recorded `guide`: {method_name} cannot follow a guide")]);
            }
            let load = |r: &crate::batch::manifest::SampleRecord, what: &str| match load_sample(&dir.join(&r.path)) {
                Ok(l) if l.pixel_digest == r.pixel_digest => Ok(l),
                Ok(_) => Err(format!("{what} `{}` no longer has the recorded pixels", r.path)),
                Err(e) => Err(format!("{what} {e}")),
            };
            let target = match load(t, "target guide") {
                Ok(l) => l,
                Err(e) => return Outcome::Mismatch(vec![e]),
            };
            let source = match &rec.guide_source {
                Some(r) => match load(r, "source guide") {
                    Ok(l) => Some(l),
                    Err(e) => return Outcome::Mismatch(vec![e]),
                },
                None => None,
            };
            let Some(weight) = wanted.get("weight").and_then(|w| w.as_f64()).filter(|w| (0.0..=1.0).contains(w)) else {
                return Outcome::Mismatch(vec!["recorded `output_spec.guide.weight` is missing or out of 0..=1".into()]);
            };
            let Some(passes) = wanted.get("passes").and_then(|p| p.as_u64()).filter(|p| (1..=8).contains(p)) else {
                return Outcome::Mismatch(vec!["recorded `output_spec.guide.passes` is missing or out of 1..=8".into()]);
            };
            let (target_path, source_path) = (dir.join(&t.path), rec.guide_source.as_ref().map(|r| dir.join(&r.path)));
            let images = crate::batch::guide::GuideImages {
                target: (&target_path, &target),
                source: source_path.as_deref().zip(source.as_ref()),
                weight,
                passes: passes as u32,
            };
            if &images.spec() != wanted {
                return Outcome::Mismatch(vec!["the record's guides do not match its output spec".into()]);
            }
            let packed = atlas
                .as_ref()
                .zip(source.as_ref())
                .map(|(a, s)| crate::batch::samples::pack_map(&a.atlas, &[s], crate::synth::placement::MapKind::Color));
            let images =
                crate::batch::guide::GuideImages { source: source_path.as_deref().zip(packed.as_ref().or(source.as_ref())), ..images };
            match images.guide(searched, &sample_path, (output.width, output.height)) {
                Ok(g) => Some(g),
                Err((key, e)) => return Outcome::Mismatch(vec![format!("recorded `{key}`: {e}")]),
            }
        }
        _ => return Outcome::Mismatch(vec!["the record's guides do not match its output spec".into()]),
    };
    if fill.is_some() && (output.width, output.height) != loaded.image.dimensions() {
        return Outcome::Mismatch(vec!["recorded `inpaint`: the output is not the image's size".into()]);
    }
    let inputs = JobInputs {
        method,
        sample: searched,
        params: &params,
        seed,
        output: &output,
        companions: companions.iter().map(|(c, l)| (c, l)).collect(),
        sample_mask: atlas.as_ref().map(|a| &a.mask).or(sample_mask.as_ref()),
        fill: fill.as_ref(),
        guide: guide.as_ref(),
        atlas: atlas.as_ref().map(|a| crate::batch::execute::AtlasInputs { atlas: &a.atlas, first: &a.first }),
    };
    match synthesize_and_encode(&inputs) {
        Err(e) => problems.push(format!("re-run failed: {e}")),
        Ok((_, files, _)) => {
            for (fresh, _) in &files {
                match rec.outputs.iter().find(|o| o.path == fresh.path) {
                    None => problems.push(format!("the re-run also writes `{}`, which the record lacks", fresh.path)),
                    Some(o) if o.pixel_digest != fresh.pixel_digest => problems.push(format!(
                        "re-run pixels differ from the record for `{}` (recorded {}, re-run {})",
                        o.path,
                        o.pixel_digest.short(),
                        fresh.pixel_digest.short()
                    )),
                    Some(_) => {}
                }
            }
            for o in &rec.outputs {
                if !files.iter().any(|(f, _)| f.path == o.path) {
                    problems.push(format!("the record lists `{}`, which a re-run does not produce", o.path));
                }
            }
        }
    }
    for o in &rec.outputs {
        match crate::files::read_limited(&dir.join(&o.path), crate::files::MAX_IMAGE_FILE_BYTES) {
            Err(e) => problems.push(format!("output `{}` cannot be read: {e}", o.path)),
            Ok(bytes) => {
                if Digest::of_bytes(&bytes) != o.file_digest {
                    problems.push(format!("output file `{}` differs from the recorded bytes", o.path));
                }
                if o.format == "json" || o.format == SOURCE_MAP_FORMAT {
                    if Digest::of_bytes(&bytes) != o.pixel_digest {
                        problems.push(format!("output file `{}` does not have the recorded content", o.path));
                    }
                    continue;
                }
                match imageio::decode_output(&bytes, DecodeLimits::default()) {
                    Ok(img) if img.pixel_digest() != o.pixel_digest => {
                        problems.push(format!("output file `{}` does not decode to the recorded pixels", o.path))
                    }
                    Err(e) => problems.push(format!("output file `{}` does not decode: {e}", o.path)),
                    Ok(_) => {}
                }
            }
        }
    }
    if problems.is_empty() { Outcome::Verified } else { Outcome::Mismatch(problems) }
}

/// A companion as its output spec records it.
fn companion_spec(v: &serde_json::Value, sample: &Path) -> Result<Companion, String> {
    let text = |k: &str| v.get(k).and_then(|x| x.as_str()).ok_or_else(|| format!("output_spec.companions[].{k} is missing"));
    let format = match text("format")? {
        "png" => crate::image::io::Format::Png,
        "exr" => crate::image::io::Format::Exr,
        other => return Err(format!("companion format {other:?} is not png or exr")),
    };
    let kind = text("kind")?;
    let kind =
        crate::synth::placement::MapKind::from_name(kind).ok_or_else(|| format!("companion kind {kind:?} is not color or normal"))?;
    let bit_depth = v.get("bit_depth").and_then(|x| x.as_u64()).ok_or("output_spec.companions[].bit_depth is missing")? as u8;
    Ok(Companion {
        sample: sample.to_path_buf(),
        more_samples: Vec::new(),
        path: text("path")?.to_string(),
        format,
        bit_depth,
        native_depth: false,
        kind,
    })
}

fn output_spec(v: &serde_json::Value) -> Result<OutputSpec, String> {
    let get_u = |k: &str| v.get(k).and_then(|x| x.as_u64()).ok_or_else(|| format!("output_spec.{k} is missing"));
    let path = v.get("path").and_then(|x| x.as_str()).ok_or("output_spec.path is missing")?.to_string();
    let format = match v.get("format").and_then(|x| x.as_str()) {
        Some("png") => imageio::Format::Png,
        Some("exr") => imageio::Format::Exr,
        other => return Err(format!("output_spec.format {other:?} is not png or exr")),
    };
    Ok(OutputSpec {
        path,
        width: get_u("width")? as u32,
        height: get_u("height")? as u32,
        format,
        bit_depth: get_u("bit_depth")? as u8,
        native_depth: false,
        tileable: v.get("tileable").and_then(|x| x.as_bool()).unwrap_or(false),
        source_map: v.get("source_map").and_then(|x| x.as_str()).map(str::to_string),
    })
}

/// Used by `golden`: the pixel digests of each successful job's outputs.
pub fn pixel_digests(manifest: &Manifest) -> Vec<(&JobRecord, Vec<(&str, &Digest)>)> {
    manifest
        .jobs
        .iter()
        .filter(|j| matches!(j.status, Status::Ok | Status::UpToDate))
        .map(|j| (j, j.outputs.iter().map(|o| (o.path.as_str(), &o.pixel_digest)).collect()))
        .collect()
}

/// The atlas a recorded job with several samples or `augment` searched (`output_spec.samples`),
/// rebuilt from its recorded sample and mask files, each checked against its recorded pixels.
fn atlas_of_record(
    rec: &JobRecord,
    spec: &serde_json::Value,
    dir: &Path,
    first: &std::sync::Arc<LoadedSample>,
    image_copyable: Option<&SampleMask>,
) -> Result<Option<crate::batch::samples::AtlasSamples>, String> {
    use crate::synth::params::Choice;
    let Some(wanted) = spec.get("samples") else {
        return if rec.samples.is_empty() && spec.get("augment").is_none() {
            Ok(None)
        } else {
            Err("the record's samples do not match its output spec".into())
        };
    };
    let wanted = wanted.as_array().ok_or("recorded `output_spec.samples` is not a list")?;
    if wanted.len() != rec.samples.len()
        || rec.samples.is_empty()
        || (!rec.sample_masks.is_empty() && rec.sample_masks.len() != wanted.len())
    {
        return Err("the record's samples do not match its output spec".into());
    }
    let augment: Vec<crate::synth::atlas::Augment> = match spec.get("augment") {
        None => Vec::new(),
        Some(list) => list
            .as_array()
            .and_then(|l| l.iter().map(|a| a.as_str().and_then(crate::synth::atlas::Augment::parse)).collect::<Option<Vec<_>>>())
            .ok_or("recorded `output_spec.augment` is not a list of transforms")?,
    };
    let load = |r: &crate::batch::manifest::SampleRecord, what: &str| -> Result<std::sync::Arc<LoadedSample>, String> {
        match load_sample(&dir.join(&r.path)) {
            Ok(l) if l.pixel_digest == r.pixel_digest => Ok(std::sync::Arc::new(l)),
            Ok(_) => Err(format!("{what} `{}` no longer has the recorded pixels", r.path)),
            Err(e) => Err(format!("{what} {e}")),
        }
    };
    let mut samples = Vec::new();
    let mut masks = Vec::new();
    for (i, (w, r)) in wanted.iter().zip(&rec.samples).enumerate() {
        if w.get("pixels") != Some(&serde_json::json!(r.pixel_digest)) {
            return Err(format!("sample `{}` does not match its output spec", r.path));
        }
        let s = if i == 0 { first.clone() } else { load(r, "sample")? };
        if i == 0 && s.pixel_digest != r.pixel_digest {
            return Err(format!("sample `{}` does not match the record's first sample", r.path));
        }
        samples.push((dir.join(&r.path), s));
        let mask = match rec.sample_masks.get(i).cloned().flatten() {
            Some(m) if w.get("mask") == Some(&serde_json::json!(m.pixel_digest)) => Some((dir.join(&m.path), load(&m, "sample mask")?)),
            None if w.get("mask").is_none() => None,
            _ => return Err("the record's sample masks do not match its output spec".into()),
        };
        masks.push(mask);
    }
    let samples_ref: Vec<(&Path, std::sync::Arc<LoadedSample>)> = samples.iter().map(|(p, s)| (p.as_path(), s.clone())).collect();
    let masks_ref: Vec<Option<(&Path, &LoadedSample)>> = masks.iter().map(|m| m.as_ref().map(|(p, l)| (p.as_path(), &**l))).collect();
    crate::batch::samples::assemble(&samples_ref, &masks_ref, &augment, image_copyable)
        .map(Some)
        .map_err(|(key, e)| format!("recorded `{key}`: {e}"))
}
