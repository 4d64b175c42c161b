//! Executing one job: synthesise (catching panics), encode, score, write its files.
//!
//! `run` and `verify` both come through here, so a re-run from a manifest is the same code path
//! as the run that wrote it, and they cannot drift apart.

use crate::batch::job::{Companion, OutputSpec};
use crate::batch::manifest::{JobRecord, OutputRecord};
use crate::batch::outdir::OutDir;
use crate::digest::Digest;
use crate::error::Error;
use crate::image::RgbImage;
use crate::image::io::{self as imageio, DecodeLimits, ImageError, NativeImage, Samples};
use crate::metrics::MetricError;
use crate::synth::constraints::{Constraints, FillRegion, Guide, SampleMask};
use crate::synth::error::SynthError;
use crate::synth::method::{ExtraContent, ExtraOutput, Method, Request, STRIP_ROWS, Synthesis};
use crate::synth::params::Params;
use crate::synth::placement::MapKind;
use std::collections::BTreeMap;
use std::fmt;
use std::path::Path;
use std::time::Instant;

/// A decoded sample and its digests.
pub struct LoadedSample {
    /// The 8-bit RGB pixels the methods search (the guide).
    pub image: RgbImage,
    /// The sample in its stored precision and channels, when that is not 8-bit RGB (else
    /// `image` is the sample): what the output is rendered from.
    pub native: Option<NativeImage>,
    pub file_digest: Digest,
    /// Digest of the stored pixels ([`NativeImage::pixel_digest`]; for an 8-bit RGB sample the
    /// same as of `image`).
    pub pixel_digest: Digest,
    /// The sample's half of the metrics, computed by the first job that scores against it and
    /// shared by the others.
    pub metrics: crate::metrics::SampleReference,
}

impl LoadedSample {
    /// The sample in its own precision (a copy of the 8-bit guide when it is 8-bit RGB).
    pub fn native_or_guide(&self) -> std::borrow::Cow<'_, NativeImage> {
        match &self.native {
            Some(n) => std::borrow::Cow::Borrowed(n),
            None => std::borrow::Cow::Owned(NativeImage::from_rgb8(&self.image)),
        }
    }
    /// Its precision in words, for messages (`8-bit RGB`, `16-bit gray`, `float RGBA`…).
    pub fn describe(&self) -> String {
        match &self.native {
            None => "8-bit RGB".into(),
            Some(n) => {
                let depth = match n.samples {
                    Samples::U8(_) => "8-bit",
                    Samples::U16(_) => "16-bit",
                    Samples::F32(_) => "float",
                };
                let channels = ["gray", "gray + alpha", "RGB", "RGBA"].get(n.channels as usize - 1).copied().unwrap_or("?");
                format!("{depth} {channels}")
            }
        }
    }
    /// The PNG bit depth that keeps its precision: 16 for 16-bit and float samples, else 8.
    pub fn native_png_depth(&self) -> u8 {
        match self.native.as_ref().map(|n| &n.samples) {
            Some(Samples::U16(_)) | Some(Samples::F32(_)) => 16,
            _ => 8,
        }
    }
}

/// Reads and decodes a sample; the error names the file and the reason.
pub fn load_sample(path: &Path) -> Result<LoadedSample, Error> {
    let bytes = crate::files::read_limited(path, crate::files::MAX_IMAGE_FILE_BYTES)
        .map_err(|e| Error::Image { path: path.to_path_buf(), source: ImageError::Io(e) })?;
    let native =
        imageio::decode_native(&bytes, DecodeLimits::default()).map_err(|source| Error::Image { path: path.to_path_buf(), source })?;
    Ok(LoadedSample::with_file_digest(native, Digest::of_bytes(&bytes)))
}

impl LoadedSample {
    /// A sample from pixels in memory (an array handed over by a caller): with no file, its file
    /// digest is its pixel digest.
    pub fn from_native(native: NativeImage) -> LoadedSample {
        let digest = native.pixel_digest();
        LoadedSample::with_file_digest(native, digest)
    }

    fn with_file_digest(native: NativeImage, file_digest: Digest) -> LoadedSample {
        let image = imageio::native_to_rgb8(&native);
        let plain = native.channels == 3 && matches!(native.samples, Samples::U8(_));
        let pixel_digest = native.pixel_digest();
        LoadedSample {
            image,
            native: (!plain).then_some(native),
            file_digest,
            pixel_digest,
            metrics: crate::metrics::SampleReference::new(crate::metrics::MetricParams::default()),
        }
    }
}

/// A job's main output in the sample's own precision and channels, as `run` encodes it: the
/// method's 8-bit image for an 8-bit RGB sample, else the placement rendered from the sample
/// (which the synthesis must then carry).
pub fn main_output(synthesis: &Synthesis, sample: &LoadedSample) -> NativeImage {
    match (&sample.native, &synthesis.placement) {
        (Some(native), Some(placement)) => placement.render(native, MapKind::Color),
        _ => NativeImage::from_rgb8(&synthesis.image),
    }
}

/// Whether a job renders from its method's placement: its sample is not 8-bit RGB, it has
/// companions, or it writes a source map. The plan's memory estimate and execution both ask.
pub fn needs_placement(sample: &LoadedSample, companions: usize, output: &OutputSpec) -> bool {
    sample.native.is_some() || companions > 0 || output.source_map.is_some()
}

/// Everything a job's execution reads: the method and its inputs, resolved.
pub struct JobInputs<'a> {
    pub method: &'a dyn Method,
    pub sample: &'a LoadedSample,
    pub params: &'a Params,
    pub seed: u64,
    pub output: &'a OutputSpec,
    /// Each companion with its decoded sample (the sample's size, checked by the plan).
    pub companions: Vec<(&'a Companion, &'a LoadedSample)>,
    /// Which sample pixels may be copied (the sample's size, checked by the plan).
    pub sample_mask: Option<&'a SampleMask>,
    /// Inpainting: which pixels of the sample (the image) to fill (its size, checked by the plan).
    pub fill: Option<&'a FillRegion>,
    /// Guided synthesis: the guides (the output's and the sample's sizes, checked by the plan).
    pub guide: Option<&'a Guide>,
    /// Several samples or `augment`: `sample` is their atlas; the source map records which
    /// sample and transform each pixel came from, and the metrics compare with the first sample.
    pub atlas: Option<AtlasInputs<'a>>,
}

/// The atlas a job searches, and its first sample.
#[derive(Clone, Copy)]
pub struct AtlasInputs<'a> {
    pub atlas: &'a crate::synth::atlas::Atlas,
    pub first: &'a LoadedSample,
}

impl JobInputs<'_> {
    /// Whether the output is more than the method's own 8-bit image: rendered from a sample
    /// that is not 8-bit RGB, with companions, or with a source map. Then the placement is asked for.
    pub fn needs_placement(&self) -> bool {
        needs_placement(self.sample, self.companions.len(), self.output)
    }

    fn request(&self) -> Request<'_> {
        Request {
            sample: &self.sample.image,
            width: self.output.width,
            height: self.output.height,
            params: self.params,
            seed: self.seed,
            placement: self.needs_placement(),
            tileable: self.output.tileable,
            constraints: Constraints {
                sample_mask: self.sample_mask,
                fill: self.fill,
                guide: self.guide,
                atlas: self.atlas.map(|a| a.atlas),
            },
        }
    }
}

/// Why a job failed. Its text is recorded in the manifest's `error` field.
#[derive(Debug)]
pub enum JobFailure {
    /// The method returned an error.
    Synthesis { method: &'static str, source: SynthError },
    /// The method panicked: a bug in texsyn, reported with where it happened.
    Crashed { method: &'static str, what: String, at: Option<String> },
    /// The method returned an image of the wrong size: a bug in the method.
    WrongSize { method: &'static str, got: (u32, u32), want: (u32, u32) },
    /// An output could not be encoded.
    Encode(ImageError),
    /// An extra output had a name that would leave its folder: a bug in the method.
    ExtraName(String),
    /// The metrics could not be computed.
    Metrics(MetricError),
    /// A file could not be written.
    Write(Error),
}

impl fmt::Display for JobFailure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            JobFailure::Synthesis { method, source } => write!(f, "{method} failed: {source}"),
            JobFailure::Crashed { method, what, at } => {
                let at = at.as_ref().map(|l| format!(" at {l}")).unwrap_or_default();
                write!(f, "{method} crashed: {what}{at} (this is a bug in texsyn; please report it)")
            }
            JobFailure::WrongSize { method, got, want } => {
                write!(f, "{method} produced {}x{} instead of {}x{} (a bug in the method)", got.0, got.1, want.0, want.1)
            }
            JobFailure::Encode(e) => write!(f, "{e}"),
            JobFailure::ExtraName(name) => write!(f, "extra output name `{name}` is not a plain relative path (a bug in the method)"),
            JobFailure::Metrics(e) => write!(f, "metrics: {e}"),
            JobFailure::Write(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for JobFailure {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            JobFailure::Synthesis { source, .. } => Some(source),
            JobFailure::Encode(e) => Some(e),
            JobFailure::Metrics(e) => Some(e),
            JobFailure::Write(e) => Some(e),
            _ => None,
        }
    }
}

thread_local! {
    static PANIC_LOCATION: std::cell::RefCell<Option<String>> = const { std::cell::RefCell::new(None) };
}

/// Replaces the default panic output (a backtrace per panicking job would bury the run's report)
/// with a record of where the panic happened, which the job's error message then includes.
pub fn install_panic_hook() {
    std::panic::set_hook(Box::new(|info| {
        let location = info.location().map(|l| format!("{}:{}", l.file(), l.line()));
        PANIC_LOCATION.with(|p| *p.borrow_mut() = location);
    }));
}

/// Runs the method (catching panics) and encodes every output the job names in memory, as `run`
/// writes them (the same encoders, so the same pixels): the main output first, then companions
/// and the source map, then the method's extras. Also returns the synthesis seconds. `verify`
/// uses it.
pub fn synthesize_and_encode(inputs: &JobInputs) -> Result<(Synthesis, Vec<(OutputRecord, Vec<u8>)>, f64), JobFailure> {
    let (synthesis, seconds) = synthesize(inputs)?;
    let mut files = Vec::new();
    let mut bytes = Vec::new();
    let pixel_digest = encode_main(&synthesis, inputs, &mut bytes)?;
    files.push((output_record(inputs.output, &bytes, pixel_digest), bytes));
    files.extend(material_outputs(&synthesis, inputs)?);
    for extra in &synthesis.extras {
        files.push(encode_extra(&inputs.output.path, extra)?);
    }
    Ok((synthesis, files, seconds))
}

fn output_record(output: &OutputSpec, bytes: &[u8], pixel_digest: Digest) -> OutputRecord {
    OutputRecord {
        path: output.path.clone(),
        format: output.format.name().to_string(),
        bit_depth: output.bit_depth,
        width: output.width,
        height: output.height,
        file_digest: Digest::of_bytes(bytes),
        pixel_digest,
    }
}

/// Runs the method, catching panics and checking the size of what it returns; also returns the
/// synthesis seconds.
pub fn synthesize(inputs: &JobInputs) -> Result<(Synthesis, f64), JobFailure> {
    let method = inputs.method;
    let request = inputs.request();
    let started = Instant::now();
    let synthesis = caught(method, || method.synthesize(&request))?;
    let seconds = started.elapsed().as_secs_f64();
    let want = (inputs.output.width, inputs.output.height);
    if synthesis.image.dimensions() != want {
        return Err(JobFailure::WrongSize { method: method.name(), got: synthesis.image.dimensions(), want });
    }
    if request.placement {
        match &synthesis.placement {
            Some(p) if p.dimensions() == want => {}
            Some(p) => return Err(JobFailure::WrongSize { method: method.name(), got: p.dimensions(), want }),
            None => {
                return Err(JobFailure::Synthesis {
                    method: method.name(),
                    source: SynthError::Failed("the method did not return the placement it was asked for (a bug in the method)".into()),
                });
            }
        }
    }
    Ok((synthesis, seconds))
}

/// Encodes the main output into `w`: the method's own 8-bit image, or, for a sample that is not
/// 8-bit RGB, the placement rendered from the sample in its own precision and channels.
fn encode_main(synthesis: &Synthesis, inputs: &JobInputs, w: &mut dyn std::io::Write) -> Result<Digest, JobFailure> {
    match (&inputs.sample.native, &synthesis.placement) {
        (Some(native), Some(placement)) => {
            let rendered = placement.render(native, MapKind::Color);
            imageio::encode_native_to(&rendered, inputs.output.encoding(), w).map_err(JobFailure::Encode)
        }
        _ => imageio::encode_to(&synthesis.image, inputs.output.encoding(), w).map_err(JobFailure::Encode),
    }
}

/// The companions rendered with the placement, and the source map, encoded with their records.
fn material_outputs(synthesis: &Synthesis, inputs: &JobInputs) -> Result<Vec<(OutputRecord, Vec<u8>)>, JobFailure> {
    let mut files = Vec::new();
    let Some(placement) = &synthesis.placement else { return Ok(files) };
    for (c, loaded) in &inputs.companions {
        let rendered = placement.render(&loaded.native_or_guide(), c.kind);
        let encoded = imageio::encode_native(&rendered, c.encoding()).map_err(JobFailure::Encode)?;
        let record = OutputRecord {
            path: c.path.clone(),
            format: c.format.name().to_string(),
            bit_depth: c.bit_depth,
            width: placement.width(),
            height: placement.height(),
            file_digest: Digest::of_bytes(&encoded.bytes),
            pixel_digest: encoded.pixels.pixel_digest(),
        };
        files.push((record, encoded.bytes));
    }
    if let Some(path) = &inputs.output.source_map {
        let bytes = crate::batch::source_map::encode(placement, inputs.atlas.map(|a| a.atlas))
            .map_err(|e| JobFailure::Encode(ImageError::Encode(e)))?;
        let digest = Digest::of_bytes(&bytes);
        let record = OutputRecord {
            path: path.clone(),
            format: SOURCE_MAP_FORMAT.to_string(),
            bit_depth: 32,
            width: placement.width(),
            height: placement.height(),
            file_digest: digest.clone(),
            pixel_digest: digest,
        };
        files.push((record, bytes));
    }
    Ok(files)
}

/// The `format` of a source map's output record. Like a JSON extra, its "pixel digest" is the
/// digest of its bytes (the encoding is texsyn's own and deterministic).
pub const SOURCE_MAP_FORMAT: &str = "source-map";

/// Runs `f`, turning a method's error or panic into the job's failure.
fn caught<T>(method: &dyn Method, f: impl FnOnce() -> Result<T, SynthError>) -> Result<T, JobFailure> {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)) {
        Ok(Ok(value)) => Ok(value),
        Ok(Err(source)) => Err(JobFailure::Synthesis { method: method.name(), source }),
        Err(panic) => {
            let what = panic
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "unknown panic".into());
            let at = PANIC_LOCATION.with(|p| p.borrow_mut().take());
            Err(JobFailure::Crashed { method: method.name(), what, at })
        }
    }
}

/// Outputs of at least this many pixels are rendered and written strip by strip where the method
/// can ([`Method::renders_in_strips`]: the tile fills), so that memory stays near the working set
/// instead of the whole image. Smaller ones are encoded whole, as before, byte for byte.
pub const STRIP_MIN_PIXELS: u64 = 8192 * 8192;

/// Whether a job's output is rendered and written in strips: a method that can, an 8-bit PNG of
/// at least [`STRIP_MIN_PIXELS`], and no metrics (they need the whole image). A function of the
/// job alone, never of the memory limit, so results do not depend on the limit.
pub fn renders_in_strips(method: &dyn Method, output: &OutputSpec, metrics: bool) -> bool {
    let pixels = u64::from(output.width) * u64::from(output.height);
    method.renders_in_strips() && !metrics && output.format == imageio::Format::Png && output.bit_depth == 8 && pixels >= STRIP_MIN_PIXELS
}

/// The metric values of a job (`None` for a metric undefined on this pair of images).
pub type Metrics = BTreeMap<String, Option<f64>>;

/// What executing a job produced.
pub struct Executed {
    /// Every file written, the main output first.
    pub outputs: Vec<OutputRecord>,
    pub synthesis: Synthesis,
    pub synthesis_seconds: f64,
    pub metrics: Option<Metrics>,
    pub metrics_seconds: f64,
}

/// Synthesises, scores and writes one job into `out`. The main output is written last: a job
/// whose main output is in place is complete. It is encoded straight into its file, so no
/// encoded copy of a large output is held beside its pixels.
pub fn execute(inputs: &JobInputs, metric_names: &[String], out: &OutDir) -> Result<Executed, JobFailure> {
    let (method, output) = (inputs.method, inputs.output);
    if !inputs.needs_placement() && renders_in_strips(method, output, !metric_names.is_empty()) {
        return execute_in_strips(inputs, out);
    }
    let (synthesis, synthesis_seconds) = synthesize(inputs)?;
    let metrics_started = Instant::now();
    let metrics = if metric_names.is_empty() {
        None
    } else {
        let names: Vec<&str> = metric_names.iter().map(String::as_str).collect();
        let sample = inputs.atlas.map_or(inputs.sample, |a| a.first);
        let scored = crate::metrics::evaluate_against(&names, &sample.image, &sample.metrics, &synthesis.image, synthesis.seams.as_ref());
        Some(scored.map_err(JobFailure::Metrics)?)
    };
    let metrics_seconds = metrics_started.elapsed().as_secs_f64();
    let mut written = Vec::new();
    for (record, bytes) in material_outputs(&synthesis, inputs)? {
        out.write(&record.path, &bytes).map_err(JobFailure::Write)?;
        written.push(record);
    }
    written.extend(write_extras(&synthesis, output, out)?);
    let main = write_main(output, out, |w| {
        encode_main(&synthesis, inputs, w).map_err(|e| match e {
            JobFailure::Encode(e) => e,
            other => ImageError::Encode(other.to_string()),
        })
    })?;
    let outputs = std::iter::once(main).chain(written).collect();
    Ok(Executed { outputs, synthesis, synthesis_seconds, metrics, metrics_seconds })
}

/// Writes a job's extra outputs (before its main output, which marks the job complete).
fn write_extras(synthesis: &Synthesis, output: &OutputSpec, out: &OutDir) -> Result<Vec<OutputRecord>, JobFailure> {
    let mut extras = Vec::new();
    for extra in &synthesis.extras {
        let (record, bytes) = encode_extra(&output.path, extra)?;
        out.write(&record.path, &bytes).map_err(JobFailure::Write)?;
        extras.push(record);
    }
    Ok(extras)
}

/// Writes the main output, `encode` streaming it straight into its (atomically renamed) file, and
/// records it. An encoding failure is reported as such, not as the write error it causes.
fn write_main(
    output: &OutputSpec,
    out: &OutDir,
    encode: impl FnOnce(&mut dyn std::io::Write) -> Result<Digest, ImageError>,
) -> Result<OutputRecord, JobFailure> {
    let mut encode_error = None;
    let written = out.write_streamed(&output.path, |w| {
        encode(w).map_err(|e| {
            let io = std::io::Error::other(e.to_string());
            encode_error = Some(e);
            io
        })
    });
    let (pixel_digest, file_digest) = match (written, encode_error) {
        (Ok(done), _) => done,
        (Err(_), Some(e)) => return Err(JobFailure::Encode(e)),
        (Err(e), None) => return Err(JobFailure::Write(e)),
    };
    Ok(OutputRecord {
        path: output.path.clone(),
        format: output.format.name().to_string(),
        bit_depth: output.bit_depth,
        width: output.width,
        height: output.height,
        file_digest,
        pixel_digest,
    })
}

/// [`execute`] of a job whose output is rendered strip by strip into its file as it is encoded:
/// the whole image is never held. The same pixels, diagnostics and extras; the rendering time is
/// in the job's total, not its synthesis seconds.
fn execute_in_strips(inputs: &JobInputs, out: &OutDir) -> Result<Executed, JobFailure> {
    let (method, output) = (inputs.method, inputs.output);
    let request = inputs.request();
    let started = Instant::now();
    let strips = caught(method, || method.synthesize_strips(&request))?;
    let synthesis_seconds = started.elapsed().as_secs_f64();
    let extras = write_extras(&strips.synthesis, output, out)?;
    let render = &strips.render;
    // Rendering happens while encoding: a panic there is the method's, caught like in synthesis.
    let main = caught(method, || {
        Ok(write_main(output, out, |w| {
            imageio::encode_png_strips(output.width, output.height, STRIP_ROWS, w, &mut |y0, rows| render(y0, rows))
        }))
    })??;
    let outputs = std::iter::once(main).chain(extras).collect();
    Ok(Executed { outputs, synthesis: strips.synthesis, synthesis_seconds, metrics: None, metrics_seconds: 0.0 })
}

/// Where an extra output of the job whose main output is `output_path` is stored:
/// `{output_path without its extension}.{name}`.
pub fn extra_path(output_path: &str, name: &str) -> Result<String, JobFailure> {
    let bad =
        name.is_empty() || name.starts_with('/') || name.contains('\\') || name.split('/').any(|c| c.is_empty() || c == "." || c == "..");
    if bad {
        return Err(JobFailure::ExtraName(name.to_string()));
    }
    Ok(format!("{}.{name}", crate::batch::job::output_stem(output_path)))
}

/// Encodes an extra output and describes it for the manifest. A JSON document's "pixel digest" is
/// the digest of its bytes (it has no pixels; golden files compare it all the same).
pub fn encode_extra(output_path: &str, extra: &ExtraOutput) -> Result<(OutputRecord, Vec<u8>), JobFailure> {
    let path = extra_path(output_path, &extra.name)?;
    match &extra.content {
        ExtraContent::Rgba8 { width, height, data } => {
            let encoded = imageio::encode_rgba8_png(*width, *height, data).map_err(JobFailure::Encode)?;
            let record = OutputRecord {
                path,
                format: "png".into(),
                bit_depth: 8,
                width: *width,
                height: *height,
                file_digest: Digest::of_bytes(&encoded.bytes),
                pixel_digest: encoded.pixels.pixel_digest(),
            };
            Ok((record, encoded.bytes))
        }
        ExtraContent::Json(value) => {
            let mut bytes = serde_json::to_vec_pretty(value)
                .map_err(|e| JobFailure::Encode(ImageError::Encode(format!("cannot encode `{}`: {e}", extra.name))))?;
            bytes.push(b'\n');
            let digest = Digest::of_bytes(&bytes);
            let record = OutputRecord {
                path,
                format: "json".into(),
                bit_depth: 0,
                width: 0,
                height: 0,
                file_digest: digest.clone(),
                pixel_digest: digest,
            };
            Ok((record, bytes))
        }
    }
}

/// Why a recorded job's files can no longer be trusted, if they cannot.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum OutputsProblem {
    NoneRecorded,
    Missing(String),
    Modified(String),
}

impl fmt::Display for OutputsProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            OutputsProblem::NoneRecorded => f.write_str("no output recorded"),
            OutputsProblem::Missing(p) => write!(f, "output `{p}` is missing"),
            OutputsProblem::Modified(p) => write!(f, "output `{p}` was modified"),
        }
    }
}

/// Whether every recorded output of `rec` is still on disk with the recorded bytes.
pub fn outputs_intact(out_dir: &Path, rec: &JobRecord) -> Result<(), OutputsProblem> {
    if rec.outputs.is_empty() {
        return Err(OutputsProblem::NoneRecorded);
    }
    for o in &rec.outputs {
        match crate::files::read_limited(&out_dir.join(&o.path), crate::files::MAX_IMAGE_FILE_BYTES) {
            Err(_) => return Err(OutputsProblem::Missing(o.path.clone())),
            Ok(bytes) if Digest::of_bytes(&bytes) != o.file_digest => return Err(OutputsProblem::Modified(o.path.clone())),
            Ok(_) => {}
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extras_go_next_to_the_output_and_stay_inside_it() {
        assert_eq!(extra_path("tiles/rw/bricks.png", "tiles/index.json").unwrap(), "tiles/rw/bricks.tiles/index.json");
        assert_eq!(extra_path("a.b/out", "tiles/t.png").unwrap(), "a.b/out.tiles/t.png");
        assert_eq!(extra_path("x.exr", "tiles/tile_00.png").unwrap(), "x.tiles/tile_00.png");
        for bad in ["", "/etc/passwd", "../x", "tiles/../../x", "tiles//x", "a\\b", "./x"] {
            assert!(extra_path("out.png", bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn json_extras_are_recorded_by_their_bytes() {
        let extra = ExtraOutput { name: "tiles/index.json".into(), content: ExtraContent::Json(serde_json::json!({"b": 1, "a": [1, 2]})) };
        let (rec, bytes) = encode_extra("o.png", &extra).unwrap();
        assert_eq!(rec.path, "o.tiles/index.json");
        assert_eq!((rec.format.as_str(), rec.width, rec.height), ("json", 0, 0));
        assert_eq!(rec.pixel_digest, Digest::of_bytes(&bytes));
        assert_eq!(serde_json::from_slice::<serde_json::Value>(&bytes).unwrap(), serde_json::json!({"a": [1, 2], "b": 1}));
        let img = ExtraOutput {
            name: "tiles/t.png".into(),
            content: ExtraContent::Rgba8 { width: 2, height: 1, data: vec![1, 2, 3, 255, 4, 5, 6, 0] },
        };
        let (rec, bytes) = encode_extra("o.png", &img).unwrap();
        let back = imageio::decode_output(&bytes, DecodeLimits::default()).unwrap();
        assert_eq!((rec.width, rec.height, back.channels), (2, 1, 4));
        assert_eq!(back.pixel_digest(), rec.pixel_digest);
    }
}
