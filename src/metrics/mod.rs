//! Objective metrics between a sample and a synthesised output (docs/methods.md §5.6, B9, B10).
//!
//! The four metrics of paper 003 (after Akl et al. 2018), lower is better for all of them:
//! - `kl_gray`: KL divergence of the 256-bin gray-level histograms, `D_KL(sample‖output)`;
//! - `kl_orientation`: KL divergence of the 180-bin local-orientation histograms;
//! - `acf_gray`: Euclidean distance between the 33 × 33 gray autocorrelations (overlap-mean form of
//!   the mean-subtracted gray plane);
//! - `acf_orientation`: Euclidean distance between the 33 × 33 moduli of the raw overlap-mean
//!   autocorrelations of the complex orientation field `V = C·e^{2jO}`;
//!
//! and two of ours:
//! - `verbatim`: fraction of output pixels whose 7 × 7 neighbourhood occurs verbatim in the sample;
//! - `seam_visibility`: mean colour jump at a block method's seam bands over the mean jump
//!   elsewhere (needs a [`SeamGrid`]).
//!
//! A metric that is undefined (a constant image for `acf_gray` / `kl_orientation`, an image too
//! small for the offsets or the window, no seam grid) is `None`; nothing here panics on it.
//! Everything is `f64` with a fixed summation order; no result depends on the number of threads.

pub mod acf;
pub mod histogram;
pub mod orientation;
pub mod repetition;
pub mod seams;
pub mod verbatim;

use std::cell::OnceCell;
use std::collections::BTreeMap;
use std::sync::OnceLock;

use serde::{Deserialize, Serialize};

use crate::image::RgbImage;
use crate::image::seam_grid::SeamGrid;

pub use acf::{Acf, AcfError, AcfForm, AcfPlanner, autocorrelation, autocorrelation_complex, autocorrelation_sums, euclidean_distance};
pub use histogram::{KL_EPSILON, gray_counts, gray_level, kl_divergence, kl_divergence_eps, normalise};
pub use orientation::{StructureTensor, orientation_bin, orientation_counts, structure_tensor};
pub use seams::{seam_visibility, wrap_visibility};
pub use verbatim::{SampleWindows, verbatim, verbatim_fraction};

/// Every metric name [`evaluate`] accepts, in report order.
pub const METRIC_NAMES: &[&str] =
    &["kl_gray", "kl_orientation", "acf_gray", "acf_orientation", "verbatim", "seam_visibility", "repetition"];

/// The metrics a job's `metrics = true` asks for: all but `repetition` (an FFT autocorrelation
/// of the whole output, asked for by name: `metrics = ["repetition", …]`).
pub const DEFAULT_METRICS: &[&str] = &["kl_gray", "kl_orientation", "acf_gray", "acf_orientation", "verbatim", "seam_visibility"];

/// The metrics' named parameters (§5.6 "Options"); record them in the manifest.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MetricParams {
    /// Offset radius of both ACFs: `|dx|, |dy| ≤ acf_radius` (16 → 33 × 33).
    pub acf_radius: usize,
    /// Gaussian `σ` of the structure tensor window (radius `floor(4σ + 0.5)`).
    pub sigma: f64,
    /// Number of orientation-histogram bins over 180°.
    pub orientation_bins: usize,
    /// `ε` of the KL divergence.
    pub epsilon: f64,
    /// Gray ACF as eq. 11 is printed: un-centred, `S / S(0,0)` (biased form) instead of the
    /// overlap-mean form of the mean-subtracted plane.
    pub acf_raw: bool,
    /// Side of the verbatim neighbourhood.
    pub verbatim_window: usize,
}

impl Default for MetricParams {
    fn default() -> Self {
        MetricParams {
            acf_radius: 16,
            sigma: 1.5,
            orientation_bins: 180,
            epsilon: KL_EPSILON,
            acf_raw: false,
            verbatim_window: verbatim::VERBATIM_WINDOW,
        }
    }
}

impl MetricParams {
    pub fn validate(&self) -> Result<(), MetricError> {
        if !(self.sigma > 0.0 && self.sigma.is_finite()) {
            return Err(MetricError::Parameter(format!("sigma must be positive and finite, got {}", self.sigma)));
        }
        if self.orientation_bins == 0 {
            return Err(MetricError::Parameter("orientation_bins must be at least 1".into()));
        }
        if !(self.epsilon >= 0.0 && self.epsilon.is_finite()) {
            return Err(MetricError::Parameter(format!("epsilon must be ≥ 0 and finite, got {}", self.epsilon)));
        }
        if self.verbatim_window == 0 {
            return Err(MetricError::Parameter("verbatim_window must be at least 1".into()));
        }
        Ok(())
    }
}

/// Per-image quantities shared by several metrics, each computed at most once.
struct Analysis<'a> {
    img: &'a RgbImage,
    params: &'a MetricParams,
    tensor: OnceCell<StructureTensor>,
}

impl<'a> Analysis<'a> {
    fn new(img: &'a RgbImage, params: &'a MetricParams) -> Self {
        Analysis { img, params, tensor: OnceCell::new() }
    }
    fn dims(&self) -> (usize, usize) {
        (self.img.width() as usize, self.img.height() as usize)
    }
    fn tensor(&self) -> &StructureTensor {
        self.tensor.get_or_init(|| {
            let (w, h) = self.dims();
            structure_tensor(&self.img.gray_unit(), w, h, self.params.sigma)
        })
    }
    fn orientation_histogram(&self) -> Vec<f64> {
        normalise(&orientation_counts(self.tensor(), self.params.orientation_bins))
    }
    fn orientation_acf(&self) -> Option<Acf<f64>> {
        let (w, h) = self.dims();
        let r = self.params.acf_radius;
        let v = self.tensor().complex_orientation();
        let acf = autocorrelation_complex(&v, w, h, r, r, AcfForm::RawOverlapMean).ok()?;
        Some(acf.map(|c| c.norm()))
    }
}

/// The gray plane `(R+G+B)/(3·255)` minus its mean, row-major.
///
/// Centred in integers first: with `s = R+G+B`, each value is `(s − mean(s)) / 765`, where
/// `Σ s` is an exact integer; so a constant image gives an exactly zero plane (an undefined ACF)
/// rather than rounding noise.
pub fn centred_gray(img: &RgbImage) -> Vec<f64> {
    let sums: Vec<u32> = img.as_raw().chunks_exact(3).map(|p| p[0] as u32 + p[1] as u32 + p[2] as u32).collect();
    if sums.is_empty() {
        return Vec::new();
    }
    let total: u64 = sums.iter().map(|&s| s as u64).sum();
    let mean = total as f64 / sums.len() as f64;
    sums.iter().map(|&s| (s as f64 - mean) / 765.0).collect()
}

/// Normalised 256-bin gray-level histogram (§5.6 item 1).
pub fn gray_histogram(img: &RgbImage) -> Vec<f64> {
    normalise(&gray_counts(img))
}

/// Normalised local-orientation histogram (§5.6 item 2): all zero for an image without a valid
/// pixel.
pub fn orientation_histogram(img: &RgbImage, params: &MetricParams) -> Vec<f64> {
    Analysis::new(img, params).orientation_histogram()
}

/// The gray ACF `c(dx, dy)` of §5.6 item 3 (`None` for a constant image, or with `acf_raw` a black
/// one, and for an image not larger than the offset radius).
pub fn gray_acf(img: &RgbImage, params: &MetricParams) -> Option<Acf<f64>> {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let r = params.acf_radius;
    if params.acf_raw {
        autocorrelation(&img.gray_unit(), w, h, r, r, AcfForm::Biased).ok()
    } else {
        autocorrelation(&centred_gray(img), w, h, r, r, AcfForm::OverlapMean).ok()
    }
}

/// The orientation ACF `A_v(dx, dy) = |S/N|` of `V` (§5.6 item 4; `None` only for an image not
/// larger than the offset radius).
pub fn orientation_acf(img: &RgbImage, params: &MetricParams) -> Option<Acf<f64>> {
    Analysis::new(img, params).orientation_acf()
}

fn defined(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

/// Gray-level histogram KL, `D_KL(sample‖output)` (§5.6 item 1).
pub fn kl_gray(sample: &RgbImage, output: &RgbImage) -> Option<f64> {
    kl_gray_with(sample, output, &MetricParams::default())
}
pub fn kl_gray_with(sample: &RgbImage, output: &RgbImage, params: &MetricParams) -> Option<f64> {
    score("kl_gray", sample, &SampleReference::new(params.clone()), &Analysis::new(output, params), None)
}

/// Local-orientation histogram KL (§5.6 item 2); `None` when either image has no valid pixel.
pub fn kl_orientation(sample: &RgbImage, output: &RgbImage) -> Option<f64> {
    kl_orientation_with(sample, output, &MetricParams::default())
}
pub fn kl_orientation_with(sample: &RgbImage, output: &RgbImage, params: &MetricParams) -> Option<f64> {
    score("kl_orientation", sample, &SampleReference::new(params.clone()), &Analysis::new(output, params), None)
}

/// Gray autocorrelation distance (§5.6 item 3); `None` when either image is constant.
pub fn acf_gray(sample: &RgbImage, output: &RgbImage) -> Option<f64> {
    acf_gray_with(sample, output, &MetricParams::default())
}
pub fn acf_gray_with(sample: &RgbImage, output: &RgbImage, params: &MetricParams) -> Option<f64> {
    score("acf_gray", sample, &SampleReference::new(params.clone()), &Analysis::new(output, params), None)
}

/// Orientation autocorrelation distance (§5.6 item 4).
pub fn acf_orientation(sample: &RgbImage, output: &RgbImage) -> Option<f64> {
    acf_orientation_with(sample, output, &MetricParams::default())
}
pub fn acf_orientation_with(sample: &RgbImage, output: &RgbImage, params: &MetricParams) -> Option<f64> {
    score("acf_orientation", sample, &SampleReference::new(params.clone()), &Analysis::new(output, params), None)
}

/// Why metrics could not be computed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum MetricError {
    /// A name that is not one of [`METRIC_NAMES`].
    Unknown(String),
    /// A [`MetricParams`] value out of its domain.
    Parameter(String),
}

impl std::fmt::Display for MetricError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            MetricError::Unknown(name) => write!(f, "unknown metric `{name}`; valid metrics: {}", METRIC_NAMES.join(", ")),
            MetricError::Parameter(m) => write!(f, "metric parameter {m}"),
        }
    }
}

impl std::error::Error for MetricError {}

/// Evaluates the named metrics with the default parameters: each name maps to `Some(value)` or to
/// `None` when the metric is undefined for these images. `Err` for an unknown name (the message
/// lists the valid ones).
pub fn evaluate(
    names: &[&str],
    sample: &RgbImage,
    output: &RgbImage,
    grid: Option<&SeamGrid>,
) -> Result<BTreeMap<String, Option<f64>>, MetricError> {
    evaluate_with(names, sample, output, grid, &MetricParams::default())
}

/// [`evaluate`] with explicit parameters (`Err` also for invalid parameters).
pub fn evaluate_with(
    names: &[&str],
    sample: &RgbImage,
    output: &RgbImage,
    grid: Option<&SeamGrid>,
    params: &MetricParams,
) -> Result<BTreeMap<String, Option<f64>>, MetricError> {
    evaluate_against(names, sample, &SampleReference::new(params.clone()), output, grid)
}

/// The sample's half of the metrics (its histograms, autocorrelations and verbatim windows),
/// each computed the first time a metric asks for it and then kept. A batch keeps one per
/// sample, so the hundred jobs made from one sample analyse it once instead of a hundred times;
/// the values are the ones a fresh evaluation computes, bit for bit.
pub struct SampleReference {
    params: MetricParams,
    gray_histogram: OnceLock<Vec<f64>>,
    gray_acf: OnceLock<Option<Acf<f64>>>,
    /// The orientation histogram and ACF, made together from one structure tensor that is then
    /// dropped (it is a dozen times the sample's size).
    orientation: OnceLock<(Vec<f64>, Option<Acf<f64>>)>,
    windows: OnceLock<SampleWindows>,
}

impl SampleReference {
    /// An empty reference for metrics with `params` (checked when it is used).
    pub fn new(params: MetricParams) -> SampleReference {
        SampleReference {
            params,
            gray_histogram: OnceLock::new(),
            gray_acf: OnceLock::new(),
            orientation: OnceLock::new(),
            windows: OnceLock::new(),
        }
    }

    fn gray_histogram(&self, sample: &RgbImage) -> &[f64] {
        self.gray_histogram.get_or_init(|| gray_histogram(sample))
    }
    fn gray_acf(&self, sample: &RgbImage) -> Option<&Acf<f64>> {
        self.gray_acf.get_or_init(|| gray_acf(sample, &self.params)).as_ref()
    }
    fn orientation(&self, sample: &RgbImage) -> &(Vec<f64>, Option<Acf<f64>>) {
        self.orientation.get_or_init(|| {
            let a = Analysis::new(sample, &self.params);
            (a.orientation_histogram(), a.orientation_acf())
        })
    }
    fn windows(&self, sample: &RgbImage) -> &SampleWindows {
        self.windows.get_or_init(|| SampleWindows::new(sample, self.params.verbatim_window))
    }
}

/// [`evaluate_with`] against a [`SampleReference`] of `sample` (with its parameters): `sample`
/// must be the image every earlier use of `reference` passed.
pub fn evaluate_against(
    names: &[&str],
    sample: &RgbImage,
    reference: &SampleReference,
    output: &RgbImage,
    grid: Option<&SeamGrid>,
) -> Result<BTreeMap<String, Option<f64>>, MetricError> {
    if let Some(bad) = names.iter().find(|n| !METRIC_NAMES.contains(n)) {
        return Err(MetricError::Unknown(bad.to_string()));
    }
    let params = &reference.params;
    params.validate()?;
    let q = Analysis::new(output, params);
    Ok(names.iter().map(|&name| (name.to_string(), score(name, sample, reference, &q, grid))).collect())
}

/// One metric (a name of [`METRIC_NAMES`]) of the output `q` against `sample` through its
/// reference: the single definition every entry point uses.
fn score(name: &str, sample: &RgbImage, reference: &SampleReference, q: &Analysis, grid: Option<&SeamGrid>) -> Option<f64> {
    let (output, params) = (q.img, &reference.params);
    match name {
        "kl_gray" => defined(kl_divergence_eps(reference.gray_histogram(sample), &gray_histogram(output), params.epsilon)),
        "kl_orientation" => defined(kl_divergence_eps(&reference.orientation(sample).0, &q.orientation_histogram(), params.epsilon)),
        "acf_gray" => {
            reference.gray_acf(sample).zip(gray_acf(output, params)).and_then(|(a, b)| defined(euclidean_distance(a.values(), b.values())))
        }
        "acf_orientation" => reference
            .orientation(sample)
            .1
            .as_ref()
            .zip(q.orientation_acf())
            .and_then(|(a, b)| defined(euclidean_distance(a.values(), b.values()))),
        "verbatim" => reference.windows(sample).fraction(sample, output),
        "seam_visibility" => grid.and_then(|g| seam_visibility(output, g)),
        "repetition" => repetition::max_autocorrelation(output),
        _ => unreachable!("names are checked before scoring"),
    }
}

#[cfg(test)]
mod tests;
