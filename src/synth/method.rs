//! The interface every synthesis method implements, and what it returns.
//!
//! A method is a pure function of (sample pixels, resolved parameters, seed, output size): it
//! never sees file names, formats or the clock. That is what lets the batch layer cache, verify
//! and re-run results from the manifest alone.

use crate::image::RgbImage;
use crate::image::seam_grid::SeamGrid;
use crate::synth::constraints::Constraints;
use crate::synth::error::SynthError;
use crate::synth::params::{ParamError, ParamSpec, Params};
pub use crate::synth::placement::Placement;

/// What a method is asked to do.
pub struct Request<'a> {
    pub sample: &'a RgbImage,
    pub width: u32,
    pub height: u32,
    pub params: &'a Params,
    pub seed: u64,
    /// Also return the [`Placement`] ([`Synthesis::placement`]; [`Strips::sources`] in strips):
    /// asked for when the job renders its output from more than the 8-bit sample (a 16-bit or
    /// float sample, companions, a source map). Never changes the pixels.
    pub placement: bool,
    /// Make the output wrap seamlessly left↔right and top↔bottom. Only asked of a method whose
    /// [`Method::tileable`] says it can.
    pub tileable: bool,
    /// What the output must respect besides the sample (a sample mask). Only asked of a method
    /// that says it honours each one ([`Method::honours_sample_mask`]).
    pub constraints: Constraints<'a>,
}

/// What a method produces.
#[derive(Debug)]
pub struct Synthesis {
    /// The output, exactly `width × height`.
    pub image: RgbImage,
    /// Where block seams may be, for the seam-visibility metric (grid-based methods only).
    pub seams: Option<SeamGrid>,
    /// Method-specific diagnostics worth recording in the manifest (`null` when none). Must be
    /// deterministic: it is part of the reproducible record.
    pub diagnostics: serde_json::Value,
    /// Wall-clock seconds of named phases (e.g. table building vs iterations), for papers that
    /// report them separately. Not reproducible, so recorded with the job's timing, not its result.
    pub phases: Vec<(String, f64)>,
    /// Further products a job asked for (e.g. an exported tile set), written next to the main
    /// output and recorded, hashed and verified like it. Must be deterministic.
    pub extras: Vec<ExtraOutput>,
    /// Where each output pixel comes from, when [`Request::placement`] asked for it: rendered
    /// over the 8-bit sample it is `image`, pixel for pixel.
    pub placement: Option<Placement>,
}

impl Synthesis {
    pub fn new(image: RgbImage) -> Synthesis {
        Synthesis { image, seams: None, diagnostics: serde_json::Value::Null, phases: Vec::new(), extras: Vec::new(), placement: None }
    }
}

/// Output rows `y0..` rendered into a buffer of whole rows (`rows.len()` a multiple of `3·width`).
pub type RenderRows = Box<dyn Fn(u32, &mut [u8]) + Send + Sync>;

/// A synthesis whose pixels are rendered on demand, strip by strip ([`Method::synthesize_strips`]),
/// so that a large output never has to be held whole.
pub struct Strips {
    /// Everything but the pixels (its `image` is 0×0); the same seams, diagnostics and extras as
    /// [`Method::synthesize`] gives.
    pub synthesis: Synthesis,
    /// Renders any rows, the same pixels as those rows of [`Method::synthesize`]'s image.
    pub render: RenderRows,
    /// When [`Request::placement`] asked for it: the sample index every pixel of any rows copies
    /// (the strip-rendering methods only copy), row-major, as [`Placement::sources`] would hold.
    pub sources: Option<SourceRows>,
}

/// Output rows `y0..` as sample indices (`sources.len()` a multiple of `width`).
pub type SourceRows = Box<dyn Fn(u32, &mut [u32]) + Send + Sync>;

/// Rows per strip when an output is rendered in strips.
pub const STRIP_ROWS: u32 = 64;

/// A product besides the main image. The runner stores it at `{output path without its
/// extension}.{name}`: for output `tiles/bricks.png` and name `tiles/index.json`, the file is
/// `tiles/bricks.tiles/index.json`.
#[derive(Clone, Debug, PartialEq)]
pub struct ExtraOutput {
    /// Relative name: `/`-separated, no `..`, no leading `/`.
    pub name: String,
    pub content: ExtraContent,
}

/// What an extra output holds.
#[derive(Clone, Debug, PartialEq)]
pub enum ExtraContent {
    /// An 8-bit RGBA image (`width × height × 4`, row-major), stored as PNG.
    Rgba8 { width: u32, height: u32, data: Vec<u8> },
    /// A JSON document, stored pretty-printed.
    Json(serde_json::Value),
}

/// What a job asks of its method beyond parameters, where that decides which version of the
/// method's pixels it gets ([`Method::algorithm_version_of`]). Read from the job's output spec
/// (the content key's), so a run, `verify` and the library agree on it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Uses {
    /// `[inpaint]`: a hole is filled.
    pub inpaint: bool,
    /// `augment`: the search sees turned or mirrored copies of the samples.
    pub copies: bool,
    /// `[guide]` without a `source`: the guides are luminance, compared at a block's scale
    /// ([`crate::synth::constraints::Guide::at_block_scale`]).
    pub luminance_guide: bool,
}

impl Uses {
    /// What an output spec (`output_spec` of a record) asks for.
    pub fn of_spec(spec: &serde_json::Value) -> Uses {
        Uses {
            inpaint: spec.get("inpaint").is_some_and(|v| !v.is_null()),
            copies: spec.get("augment").and_then(|a| a.as_array()).is_some_and(|a| !a.is_empty()),
            luminance_guide: spec.get("guide").and_then(|g| g.get("source")).is_some_and(|s| s == "luminance"),
        }
    }
}

/// A synthesis method.
pub trait Method: Send + Sync {
    /// The name used in job files (`method = "…"`).
    fn name(&self) -> &'static str;
    /// Bumped whenever a change alters the pixels produced for the same inputs; part of the
    /// content key, so outputs made by an older algorithm are recomputed, not trusted.
    fn algorithm_version(&self) -> u32;
    /// The algorithm version of the pixels these (resolved) parameters make for a job that asks
    /// for `uses`: what the record and the content key hold. [`Method::algorithm_version`],
    /// unless one of the method's searches (quilting's and patch sampling's pyramid) or one of
    /// its ways with inpainting or transformed copies changed its pixels on its own, so that only
    /// the jobs it made are re-made and reported by `verify`, not every job of the method.
    fn algorithm_version_of(&self, _params: &Params, _uses: Uses) -> u32 {
        self.algorithm_version()
    }
    /// One line for `texsyn methods`.
    fn summary(&self) -> &'static str;
    /// The declared parameters.
    fn params(&self) -> &'static [ParamSpec];
    /// Defaults that differ for a job using these features (a `[guide]`, an `[inpaint]`…): put
    /// among the job's parameters when it leaves them out, before they are resolved, so that they
    /// are recorded (and re-made by `verify`) like any given one. Most methods have none.
    fn defaults_for(&self, _uses: Uses) -> Vec<(String, crate::synth::params::ParamValue)> {
        Vec::new()
    }
    /// Makes concrete the parameters whose resolved value depends on the sample's size (a search
    /// `auto` chooses by it), before the job is checked, estimated and recorded: the recorded
    /// parameters then say what made the pixels. Most methods have none.
    fn resolve_for_sample(&self, _params: &mut Params, _sample: (u32, u32)) {}
    /// Checks that need several parameters together or the sample and output sizes (e.g. a block
    /// larger than the sample). Runs before anything is synthesised.
    fn check(&self, _params: &Params, _sample: (u32, u32), _output: (u32, u32)) -> Vec<ParamError> {
        Vec::new()
    }
    /// The peak memory of [`Method::synthesize`] for a job of these sizes, in bytes: the method's
    /// own working set at its largest, its output image included (not the sample, which the caller
    /// holds). Stated from measured peak RSS, not guessed, and rather too large than too small:
    /// the runner refuses a job whose estimate exceeds `--max-memory` and never starts jobs whose
    /// estimates together exceed it (`tests/it/memory.rs` checks every method against real runs).
    fn peak_memory(&self, params: &Params, sample: (u32, u32), output: (u32, u32)) -> u64;
    /// What each thread of the pool adds to [`Method::peak_memory`] while the method runs on it
    /// (its work arrays, one set per concurrent task, and what the thread's allocator arena keeps
    /// of them), in bytes; the runner counts it once per thread. By default [`THREAD_MEMORY`].
    fn thread_memory(&self, _params: &Params, _sample: (u32, u32)) -> u64 {
        THREAD_MEMORY
    }
    /// Synthesises. Errors are reported as the job's failure; panics are caught by the runner.
    fn synthesize(&self, request: &Request) -> Result<Synthesis, SynthError>;
    /// Whether the method can honour [`Request::tileable`] with these parameters and sizes:
    /// `Err` says why not (shown to the user when a job asks for it, with the methods that can).
    fn tileable(&self, _params: &Params, _sample: (u32, u32), _output: (u32, u32)) -> Result<(), String> {
        Err(format!("{} cannot make its output wrap", self.name()))
    }
    /// Whether the method honours [`Constraints::sample_mask`](crate::synth::constraints::Constraints):
    /// it copies only sample pixels the mask allows.
    fn honours_sample_mask(&self) -> bool {
        false
    }
    /// Whether the method can inpaint ([`Constraints::fill`](crate::synth::constraints::Constraints)):
    /// fill those pixels of its sample (the image) and keep every other one, bit for bit.
    fn honours_inpaint(&self) -> bool {
        false
    }
    /// Whether the method follows a guide ([`Constraints::guide`](crate::synth::constraints::Constraints)):
    /// guided synthesis and texture transfer.
    fn honours_guide(&self) -> bool {
        false
    }
    /// Recorded parameters as a manifest written before some of today's parameters existed holds
    /// them: each missing one gets the value that reproduces what the method did then (not
    /// today's default, which may differ), so that `verify` re-makes old records. Manifests
    /// record every resolved parameter, so a missing key can only mean an older texsyn.
    fn fill_older_record(&self, _given: &mut Vec<(String, crate::synth::params::ParamValue)>) {}
    /// The folders of extra files ([`Synthesis::extras`] named `folder/…`) a job with these
    /// parameters writes next to its output (`{output without extension}.{folder}/`). Known before
    /// the job runs, so that the plan can refuse another job whose files would land in them.
    fn extra_folders(&self, _params: &Params) -> Vec<&'static str> {
        Vec::new()
    }
    /// Whether [`Method::synthesize_strips`] works: the method can render its output strip by
    /// strip (tile fills), for outputs too large to hold.
    fn renders_in_strips(&self) -> bool {
        false
    }
    /// [`Method::peak_memory`] when the output is rendered in strips of [`STRIP_ROWS`] rows: the
    /// working set without the whole output image.
    fn strip_peak_memory(&self, params: &Params, sample: (u32, u32), output: (u32, u32)) -> u64 {
        self.peak_memory(params, sample, output)
    }
    /// Synthesises everything but the pixels, and returns a renderer of any output rows: the same
    /// result as [`Method::synthesize`], pixel for pixel. Only where [`Method::renders_in_strips`].
    fn synthesize_strips(&self, _request: &Request) -> Result<Strips, SynthError> {
        Err(SynthError::Failed(format!("{} does not render in strips", self.name())))
    }
}

/// [`Method::thread_memory`]'s default: what a thread's allocator arena keeps between tasks.
/// Measured (peak RSS of one job with `-j 16` against `-j 2`, 256² samples): double-seam, TES,
/// Wang and RW tiles, coevolution and patch sampling took 0.2 to 0.9 MiB more a thread.
pub const THREAD_MEMORY: u64 = 1 << 20;

/// Bytes of `per_output_pixel` per output pixel, plus `per_sample_pixel` per sample pixel, plus
/// `fixed`: the shape every method's [`Method::peak_memory`] takes (their tables, canvases and
/// search buffers grow with one size or the other).
pub fn linear_memory(sample: (u32, u32), output: (u32, u32), per_output_pixel: f64, per_sample_pixel: f64, fixed: u64) -> u64 {
    let out = f64::from(output.0) * f64::from(output.1);
    let smp = f64::from(sample.0) * f64::from(sample.1);
    (per_output_pixel * out + per_sample_pixel * smp).ceil() as u64 + fixed
}
