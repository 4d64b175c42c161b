//! One synthesis from a sample already in memory, made exactly as a job would make it: the output
//! in the sample's own precision and channels, and a record with the manifest's keys and digests.
//!
//! Job files go through the plan and the runner; callers without one (the Python package, a
//! one-off command) come here, so that the same method, parameters, seed and sample give the same
//! pixels and the same pixel digest whichever door they came through.

use crate::batch::execute::{LoadedSample, main_output};
use crate::batch::job::OutputSpec;
use crate::batch::manifest;
use crate::digest::Digest;
use crate::error::Error;
use crate::image::io::{Format, NativeImage, Samples};
use crate::synth::advice;
use crate::synth::method::{Synthesis, Uses};
use crate::synth::params::ParamValue;
use crate::synthesizer::Synthesizer;
use std::path::PathBuf;
use std::time::Instant;

/// What to make: a method by name with job-file parameter values, a seed, a size (the sample's
/// when `None`), whether it wraps, whether to return the placement, and whether to describe the
/// result (the record and warnings, which analyse the sample: not worth it for the pixels alone).
#[derive(Clone, Debug)]
pub struct SingleRequest {
    pub method: String,
    pub params: Vec<(String, ParamValue)>,
    pub seed: u64,
    pub size: Option<(u32, u32)>,
    pub tileable: bool,
    pub placement: bool,
    pub describe: bool,
}

/// A finished synthesis.
pub struct Single {
    /// The output in the sample's precision and channels (what a job's PNG at the sample's depth,
    /// or its EXR for a float sample, stores).
    pub image: NativeImage,
    /// The method's result: its 8-bit image, seams, diagnostics and (when asked for, or needed to
    /// render a sample that is not 8-bit RGB) the placement.
    pub synthesis: Synthesis,
    /// With [`SingleRequest::describe`] (else `null`), the manifest keys of a job record: method, algorithm version, resolved params and their
    /// digest, seed, sample, output spec, content key, outputs with their pixel digest, warnings,
    /// diagnostics and timing.
    pub record: serde_json::Value,
    /// With [`SingleRequest::describe`], plain sentences when the method and parameters do not
    /// fit the sample (`texsyn advise`).
    pub warnings: Vec<String>,
    /// Seconds in the method's synthesis call alone.
    pub synthesis_seconds: f64,
}

/// The output spec a job would have for this sample and size: PNG at the sample's depth, EXR for
/// a float sample. Its path is empty: no file is written.
fn output_spec(sample: &LoadedSample, width: u32, height: u32, tileable: bool) -> OutputSpec {
    let float = matches!(sample.native.as_ref().map(|n| &n.samples), Some(Samples::F32(_)));
    let (format, bit_depth) = if float { (Format::Exr, 32) } else { (Format::Png, sample.native_png_depth()) };
    OutputSpec { path: String::new(), width, height, format, bit_depth, native_depth: false, tileable, source_map: None }
}

/// Synthesises from `sample` as a job with these values would, validating them with the job
/// file's messages ([`Error::Params`] names each parameter).
pub fn synthesize(sample: &LoadedSample, req: &SingleRequest) -> Result<Single, Error> {
    let mut builder = Synthesizer::by_name(&req.method, req.params.clone())?.seed(req.seed);
    if let Some((w, h)) = req.size {
        builder = builder.size(w, h);
    }
    if req.tileable {
        builder = builder.tileable();
    }
    if req.placement || sample.native.is_some() {
        builder = builder.placement();
    }
    let session = builder.build(&sample.image)?;
    let method = session.method();
    let params_json = session.params().to_json();
    let started = Instant::now();
    let synthesis = session.run()?;
    let synthesis_seconds = started.elapsed().as_secs_f64();
    let (width, height) = synthesis.image.dimensions();
    let image = main_output(&synthesis, sample);
    if !req.describe {
        return Ok(Single { image, synthesis, record: serde_json::Value::Null, warnings: Vec::new(), synthesis_seconds });
    }
    let spec = output_spec(sample, width, height, req.tileable);
    let spec_json = spec.to_json();
    let analysis = advice::analyse(&sample.image);
    let wrap = analysis.lattice.as_ref().filter(|_| req.tileable).and_then(|l| crate::synth::wrap::warning(l, (width, height)));
    let warnings: Vec<String> = advice::warning(&analysis, method.name(), session.params()).into_iter().chain(wrap).collect();
    let content_key = manifest::content_key(
        method.name(),
        method.algorithm_version_of(session.params(), Uses::of_spec(&spec_json)),
        &params_json,
        req.seed,
        &sample.pixel_digest,
        &spec_json,
    );
    let record = serde_json::json!({
        "method": method.name(),
        "algorithm_version": method.algorithm_version_of(session.params(), Uses::of_spec(&spec_json)),
        "params_digest": Digest::of_json(&params_json),
        "params": params_json,
        "seed": req.seed,
        "sample": {
            "file_digest": sample.file_digest,
            "pixel_digest": sample.pixel_digest,
            "width": sample.image.width(),
            "height": sample.image.height(),
        },
        "output_spec": spec_json,
        "content_key": content_key,
        "outputs": [{
            "format": spec.format.name(),
            "bit_depth": spec.bit_depth,
            "width": width,
            "height": height,
            "pixel_digest": image.pixel_digest(),
        }],
        "seams": synthesis.seams,
        "diagnostics": synthesis.diagnostics,
        "warnings": warnings,
        "timing": {"synthesis_seconds": synthesis_seconds},
    });
    Ok(Single { image, synthesis, record, warnings, synthesis_seconds })
}

/// `texsyn synth`: one sample, no job file. The flags become the job file a user would write
/// ([`OneOff::job_text`]), which is validated and run by the same code as any job file: the same
/// messages, the same pixels, and a manifest that `verify` re-runs.
#[derive(Clone, Debug)]
pub struct OneOff {
    /// The sample; when inpainting, the image to repair (it is its own sample).
    pub sample: PathBuf,
    /// Further samples to learn from with `sample` (`samples = [...]`).
    pub more_samples: Vec<PathBuf>,
    /// Transformed copies of the samples to search too (`augment`, e.g. `rot90`).
    pub augment: Vec<String>,
    /// `sample_mask`: one per sample (`None` for a sample without), or empty for none.
    pub sample_masks: Vec<Option<PathBuf>>,
    /// With `guide`: the sample's guide (`guide.source`), the guide's weight and passes.
    pub guide_source: Option<PathBuf>,
    pub guide_weight: Option<f64>,
    pub guide_passes: Option<u32>,
    /// Also write the placement as `{stem}.map.exr` beside the output.
    pub source_map: bool,
    /// Inpaint `sample` instead of making a new image from it: which pixels to fill.
    pub inpaint: Option<OneOffMask>,
    /// With `inpaint`: the samples the fill copies from (`samples = [...]`; list `sample` among
    /// them to copy from it too); empty: the image itself. `sample_masks` and `augment` go with them.
    pub inpaint_from: Vec<PathBuf>,
    /// Texture transfer: the target guide (the output's size).
    pub guide: Option<PathBuf>,
    /// The image to write (.png or .exr); its manifest goes beside it as `{stem}.manifest.json`.
    pub output: PathBuf,
    pub method: String,
    /// (width, height); the sample's size when `None`.
    pub size: Option<(u32, u32)>,
    pub seed: u64,
    pub tileable: bool,
    /// `[params]` entries as `key = value` with the value in TOML (`40`, `0.1`, `"dp"`, `true`).
    pub params: Vec<(String, String)>,
    pub max_memory: Option<u64>,
}

/// A one-off inpainting job's mask: an image (white = fill) or a channel of the image.
#[derive(Clone, Debug)]
pub enum OneOffMask {
    File(PathBuf),
    Channel(String),
}

/// What `texsyn synth` wrote.
pub struct OneOffDone {
    pub record: crate::batch::manifest::JobRecord,
    pub manifest: PathBuf,
}

impl OneOff {
    fn stem(&self) -> Result<String, Error> {
        let name = self.output.file_name().and_then(|n| n.to_str()).unwrap_or("");
        let ok = crate::image::io::Format::from_path(&self.output).is_some() && !name.starts_with('.');
        if !ok {
            return Err(Error::Usage(format!("{}: the output must be a .png or .exr file name", self.output.display())));
        }
        Ok(crate::batch::job::output_stem(name).to_string())
    }

    /// A `[params]` value as written on the command line: TOML if it parses as a TOML value
    /// (`40`, `0.5`, `true`, `"dp"`), else a string (`--set cut=dp`).
    pub fn param_value(text: &str) -> String {
        let as_toml = format!("v = {text}");
        if toml::from_str::<toml::Table>(&as_toml).is_ok() { text.to_string() } else { toml::Value::String(text.to_string()).to_string() }
    }

    /// A parameter value as a job file's `[params]` writes it.
    pub fn param_text(value: &ParamValue) -> String {
        match value {
            ParamValue::Int(i) => i.to_string(),
            ParamValue::Float(f) => toml::Value::Float(*f).to_string(),
            ParamValue::Bool(b) => b.to_string(),
            ParamValue::Str(s) => toml::Value::String(s.clone()).to_string(),
        }
    }

    /// The job file these flags stand for; `sample` as given (absolute where it was), the output
    /// by its file name, the size given or the sample's.
    pub fn job_text(&self, size: (u32, u32)) -> String {
        let q = |s: &str| toml::Value::String(s.to_string()).to_string();
        let name = self.output.file_name().and_then(|n| n.to_str()).unwrap_or_default();
        let mut t = String::from("# The job file of a `texsyn synth` one-off: put it in a job directory to make it part of a run.\n");
        match &self.inpaint {
            None => {
                let sample = if self.more_samples.is_empty() {
                    format!("sample = {}", q(&self.sample.to_string_lossy()))
                } else {
                    let all: Vec<String> =
                        std::iter::once(&self.sample).chain(&self.more_samples).map(|p| q(&p.to_string_lossy())).collect();
                    format!("samples = [{}]", all.join(", "))
                };
                let augment = self.augment_line() + &self.mask_line();
                t += &format!(
                    "{sample}\n{augment}method = {}\nseed = {}\n\n[output]\npath = {}\nwidth = {}\nheight = {}\n",
                    q(&self.method),
                    self.seed,
                    q(name),
                    size.0,
                    size.1
                );
            }
            Some(mask) => {
                // The output has the image's size: the job file leaves it out.
                let mask = match mask {
                    OneOffMask::File(p) => format!("mask = {}", q(&p.to_string_lossy())),
                    OneOffMask::Channel(c) => format!("channel = {}", q(c)),
                };
                let samples = match self.inpaint_from.as_slice() {
                    [] => String::new(),
                    [one] => format!("sample = {}\n", q(&one.to_string_lossy())),
                    all => format!("samples = [{}]\n", all.iter().map(|p| q(&p.to_string_lossy())).collect::<Vec<_>>().join(", ")),
                };
                t += &format!(
                    "{samples}{}{}method = {}\nseed = {}\n\n[inpaint]\nimage = {}\n{mask}\n\n[output]\npath = {}\n",
                    self.augment_line(),
                    self.mask_line(),
                    q(&self.method),
                    self.seed,
                    q(&self.sample.to_string_lossy()),
                    q(name)
                );
            }
        }
        if self.tileable {
            t += "tileable = true\n";
        }
        if self.source_map {
            t += &format!("source_map = {}\n", q(&format!("{}.map.exr", crate::batch::job::output_stem(name))));
        }
        if let Some(target) = &self.guide {
            t += &format!("\n[guide]\ntarget = {}\n", q(&target.to_string_lossy()));
            if let Some(source) = &self.guide_source {
                t += &format!("source = {}\n", q(&source.to_string_lossy()));
            }
            if let Some(w) = self.guide_weight {
                t += &format!("weight = {}\n", toml::Value::Float(w));
            }
            if let Some(p) = self.guide_passes {
                t += &format!("passes = {p}\n");
            }
        }
        if !self.params.is_empty() {
            t += "\n[params]\n";
            for (k, v) in &self.params {
                let bare = !k.is_empty() && k.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
                t += &format!("{} = {v}\n", if bare { k.clone() } else { q(k) });
            }
        }
        t
    }

    /// The `augment = [...]` line, when there are transforms.
    fn augment_line(&self) -> String {
        let q = |s: &str| toml::Value::String(s.to_string()).to_string();
        if self.augment.is_empty() {
            return String::new();
        }
        format!("augment = [{}]\n", self.augment.iter().map(|a| q(a)).collect::<Vec<_>>().join(", "))
    }

    /// The `sample_mask = …` line, when there are masks: a string for one sample, else a list
    /// parallel to the samples (`""` for a sample without a mask).
    fn mask_line(&self) -> String {
        let q = |s: &str| toml::Value::String(s.to_string()).to_string();
        let path = |m: &Option<PathBuf>| q(&m.as_ref().map(|p| p.to_string_lossy().into_owned()).unwrap_or_default());
        let one_sample = if self.inpaint.is_some() && !self.inpaint_from.is_empty() {
            self.inpaint_from.len() == 1
        } else {
            self.more_samples.is_empty()
        };
        match self.sample_masks.as_slice() {
            [] => String::new(),
            [one] if one_sample => format!("sample_mask = {}\n", path(one)),
            all => format!("sample_mask = [{}]\n", all.iter().map(path).collect::<Vec<_>>().join(", ")),
        }
    }

    /// The size the output gets: the one given, else the sample's (read for it).
    pub fn size(&self) -> Result<(u32, u32), Error> {
        match self.size {
            Some(s) => Ok(s),
            None => Ok(crate::batch::execute::load_sample(&self.sample)?.image.dimensions()),
        }
    }

    /// Validates the equivalent job file like any other, runs it into the output's folder (under
    /// a lock of its own) and writes the output and its manifest atomically.
    pub fn run(&self) -> Result<OneOffDone, Error> {
        use crate::batch::outdir::OutDir;
        use crate::batch::plan::{self, PlanOptions};
        let stem = self.stem()?;
        let dir = match self.output.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        // The sample by its absolute path: the job file is read from a scratch folder.
        let sample = std::path::absolute(&self.sample).map_err(|e| Error::io(&self.sample, "resolve", e))?;
        let inpaint = match &self.inpaint {
            Some(OneOffMask::File(m)) => Some(OneOffMask::File(std::path::absolute(m).map_err(|e| Error::io(m, "resolve", e))?)),
            other => other.clone(),
        };
        let more_samples = self
            .more_samples
            .iter()
            .map(|p| std::path::absolute(p).map_err(|e| Error::io(p, "resolve", e)))
            .collect::<Result<Vec<_>, _>>()?;
        let absolute = |p: &PathBuf| std::path::absolute(p).map_err(|e| Error::io(p, "resolve", e));
        let sample_masks = self.sample_masks.iter().map(|m| m.as_ref().map(absolute).transpose()).collect::<Result<Vec<_>, _>>()?;
        let guide_source = self.guide_source.as_ref().map(absolute).transpose()?;
        let inpaint_from = self.inpaint_from.iter().map(absolute).collect::<Result<Vec<_>, _>>()?;
        let this = OneOff { sample, more_samples, sample_masks, guide_source, inpaint, inpaint_from, ..self.clone() };
        let text = this.job_text(this.size()?);
        static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let scratch = std::env::temp_dir().join(format!(
            "texsyn-synth-{}-{}",
            std::process::id(),
            NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
        ));
        std::fs::create_dir_all(&scratch).map_err(|e| Error::io(&scratch, "create", e))?;
        let job_path = scratch.join(format!("{stem}.toml"));
        let result = (|| {
            std::fs::write(&job_path, &text).map_err(|e| Error::io(&job_path, "write", e))?;
            let opts = PlanOptions { out: dir.clone(), force: true, shard: None, max_memory: self.max_memory, allow_other_root: true };
            let plan = plan::plan(std::slice::from_ref(&job_path), &opts)?;
            if let Some(inv) = plan.invalid.first() {
                // The job file is this command's own: its problems are named by key, not by line.
                let lines: Vec<String> = inv
                    .errors
                    .iter()
                    .map(|e| format!("{}{}", e.key.as_ref().map(|k| format!("`{k}`: ")).unwrap_or_default(), e.message))
                    .collect();
                return Err(Error::Usage(lines.join("\n")));
            }
            let entry = plan.entries.first().ok_or_else(|| Error::Usage("nothing to run".into()))?;
            let out = OutDir::open_part(&dir, Some(&format!("synth-{stem}")))?;
            let job = &entry.job;
            let inputs = entry.inputs();
            let started = Instant::now();
            let mut rec = entry.record.clone();
            crate::batch::run::finish_record(&mut rec, crate::batch::execute::execute(&inputs, &job.metrics, &out), started, entry.memory);
            rec.job_file.path = format!("{stem}.toml");
            let run = crate::batch::manifest::RunFacts {
                started_at: crate::batch::run::now_unix(),
                finished_at: crate::batch::run::now_unix(),
                wall_seconds: started.elapsed().as_secs_f64(),
                host: crate::batch::run::hostname(),
                argv: std::env::args().collect(),
                threads: rayon::current_num_threads(),
                ran: usize::from(rec.status == crate::batch::manifest::Status::Ok),
                failed: usize::from(rec.status == crate::batch::manifest::Status::Failed),
                max_memory_bytes: self.max_memory,
                peak_rss_bytes: crate::batch::memory::peak_rss(),
                ..Default::default()
            };
            let manifest = crate::batch::manifest::Manifest::new(vec![rec.clone()], run);
            let name = format!("{stem}.manifest.json");
            let path = out.write(&name, &manifest.to_bytes())?;
            if let Some(e) = &rec.error {
                return Err(Error::Usage(format!("{}: {e} (recorded in {})", self.output.display(), path.display())));
            }
            Ok(OneOffDone { record: rec, manifest: path })
        })();
        let _ = std::fs::remove_dir_all(&scratch);
        result
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::RgbImage;

    #[test]
    fn the_output_and_its_digest_are_the_methods_own_for_an_8_bit_sample() {
        let img = RgbImage::from_fn(64, 64, |x, y| [(x * 4) as u8, (y * 4) as u8, ((x ^ y) * 4) as u8]);
        let sample = LoadedSample::from_native(NativeImage::from_rgb8(&img));
        let req = SingleRequest {
            method: "quilting".into(),
            params: vec![crate::synth::params::int("block", 16)],
            seed: 3,
            size: Some((48, 40)),
            tileable: false,
            placement: false,
            describe: true,
        };
        let a = synthesize(&sample, &req).unwrap();
        let b = synthesize(&sample, &req).unwrap();
        assert_eq!(a.image, b.image);
        assert_eq!(a.image, NativeImage::from_rgb8(&a.synthesis.image));
        assert_eq!(a.record["outputs"][0]["pixel_digest"], serde_json::to_value(a.image.pixel_digest()).unwrap());
        assert_eq!(a.record["params"]["overlap"], 3, "resolved parameters are recorded");
        let bad = SingleRequest { params: vec![crate::synth::params::int("block", 2)], ..req };
        assert!(synthesize(&sample, &bad).err().unwrap().to_string().contains("`block`: 2 is out of range"));
    }
}
