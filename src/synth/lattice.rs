//! Lattice extraction: the translation vectors `t1, t2` of a near-regular texture
//! (docs/methods.md §2.2, after Liu, Collins & Tsin's region-of-dominance peak selection).
//!
//! Lattice-aware methods (co-evolution, TES) need the texel lattice of the sample. It is read off
//! the autocorrelation of the gray plane: its dominant peaks, reduced to a short basis and checked
//! for reliability, so a stochastic sample fails loudly ("no lattice found; give t1/t2") instead of
//! producing a meaningless lattice. Everything is integer offsets of the ACF grid, as in the paper.
//!
//! Real walls and floors often hide their lattice in the gray plane itself: strong grain or
//! painted detail inside each brick, or shading across the sample, outweighs the joints in the
//! autocorrelation. When the gray plane yields no lattice, two views that keep the joints and drop
//! the rest are tried in turn (a band-passed gray, then the edge strength), under a stricter
//! test. A sample the gray plane already explains never reaches them, so its lattice is unchanged.

use crate::image::RgbImage;
use crate::metrics::{AcfForm, AcfPlanner, centred_gray};
use crate::synth::error::SynthError;
use crate::synth::params::{Default, ParamKind, ParamSpec, Params};
use std::sync::atomic::{AtomicBool, Ordering};

/// `t1_x, t1_y, t2_x, t2_y`: the lattice a job may give instead of having it extracted. Declared
/// once here for every method that uses a lattice (co-evolution, TES, lattice-aligned tiles).
pub const VECTOR_PARAMS: [ParamSpec; 4] = [
    ParamSpec {
        name: "t1_x",
        kind: ParamKind::Int { min: -4096, max: 4096 },
        default: Default::Int(0),
        doc: "lattice vector t1 (x); t1 = t2 = 0 (default) extracts the lattice from the sample",
    },
    ParamSpec { name: "t1_y", kind: ParamKind::Int { min: -4096, max: 4096 }, default: Default::Int(0), doc: "lattice vector t1 (y)" },
    ParamSpec { name: "t2_x", kind: ParamKind::Int { min: -4096, max: 4096 }, default: Default::Int(0), doc: "lattice vector t2 (x)" },
    ParamSpec { name: "t2_y", kind: ParamKind::Int { min: -4096, max: 4096 }, default: Default::Int(0), doc: "lattice vector t2 (y)" },
];

/// The lattice vectors a job gave ([`VECTOR_PARAMS`]), or `None` when all four are 0 (extract).
#[derive(Clone, Copy, Debug, PartialEq, Eq, std::default::Default)]
pub struct GivenVectors {
    pub t1: (i64, i64),
    pub t2: (i64, i64),
}

impl GivenVectors {
    /// Reads [`VECTOR_PARAMS`] from resolved parameters.
    pub fn from_params(p: &Params) -> Result<Option<GivenVectors>, crate::synth::error::SynthError> {
        let v = GivenVectors { t1: (p.int("t1_x")?, p.int("t1_y")?), t2: (p.int("t2_x")?, p.int("t2_y")?) };
        Ok(if v.t1 == (0, 0) && v.t2 == (0, 0) { None } else { Some(v) })
    }

    /// The four parameters, for a typed config's `to_params` (nothing when `None`: the defaults).
    pub fn to_params(v: Option<GivenVectors>) -> Vec<(String, crate::synth::params::ParamValue)> {
        use crate::synth::params::int;
        match v {
            None => Vec::new(),
            Some(v) => vec![int("t1_x", v.t1.0), int("t1_y", v.t1.1), int("t2_x", v.t2.0), int("t2_y", v.t2.1)],
        }
    }
}

/// Parameters of the extraction (docs/methods.md §2.2 defaults).
#[derive(Clone, Copy, Debug)]
pub struct LatticeOptions {
    /// Dominant peaks kept (peaks come in ± pairs).
    pub max_peaks: usize,
    /// Shortest vector accepted, in pixels.
    pub min_length: f64,
    /// Smallest angle between `t1` and `t2`, in degrees.
    pub min_angle_deg: f64,
    /// `A(t1)` and `A(t2)` must reach this (3×3 maximum around the vector).
    pub min_peak: f64,
}

impl std::default::Default for LatticeOptions {
    fn default() -> Self {
        LatticeOptions { max_peaks: 16, min_length: 4.0, min_angle_deg: 20.0, min_peak: 0.10 }
    }
}

/// A lattice found in a sample.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Lattice {
    pub t1: (i64, i64),
    pub t2: (i64, i64),
    /// `A(t1)`, `A(t2)` (biased ACF, 3×3 maximum around the vector).
    pub peak1: f64,
    pub peak2: f64,
    /// Dominant peaks considered, and how many of them the lattice explains.
    pub candidates: usize,
    pub explained: usize,
    /// The view of the sample the lattice was read from when the gray plane gave none
    /// ([`FallbackView::name`]); absent (and not serialised) for the gray plane itself.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub found_in: Option<&'static str>,
    /// `t1` and `t2` to a fraction of a pixel ([`refine`]): the same basis, read off the
    /// positions of the autocorrelation peaks at many of its combinations. `t1`, `t2` are these
    /// rounded (within a pixel), and stay what the methods cut texels on; the fine ones are for
    /// whatever adds periods up over a long distance (a tileable output's wrap, hundreds of px on).
    pub fine: FineVectors,
}

/// Lattice vectors to a fraction of a pixel (see [`refine`]).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct FineVectors {
    pub t1: (f64, f64),
    pub t2: (f64, f64),
    /// The autocorrelation peaks the vectors were fitted to (`m·t1 + n·t2`); 0 when too few
    /// clear peaks were found and the vectors are the whole-pixel ones.
    pub peaks: usize,
}

impl FineVectors {
    /// The whole-pixel vectors as they are (a lattice a job gave, or one made up in a test).
    pub fn exact(t1: (i64, i64), t2: (i64, i64)) -> FineVectors {
        let f = |v: (i64, i64)| (v.0 as f64, v.1 as f64);
        FineVectors { t1: f(t1), t2: f(t2), peaks: 0 }
    }

    /// Both vectors times `f` (the lattice of a copy reduced `f` times, in the original's pixels).
    pub fn scaled(self, f: f64) -> FineVectors {
        FineVectors { t1: (self.t1.0 * f, self.t1.1 * f), t2: (self.t2.0 * f, self.t2.1 * f), ..self }
    }
}

impl Lattice {
    /// `cross(t1, t2)`: the texel area, positive in canonical form.
    pub fn determinant(&self) -> i64 {
        cross(self.t1, self.t2)
    }
}

fn cross(a: (i64, i64), b: (i64, i64)) -> i64 {
    a.0 * b.1 - a.1 * b.0
}
fn dot(a: (i64, i64), b: (i64, i64)) -> i64 {
    a.0 * b.0 + a.1 * b.1
}
fn len(a: (i64, i64)) -> f64 {
    (dot(a, a) as f64).sqrt()
}

const NONE: &str = "no lattice found; give t1/t2";

/// A view of the sample that keeps the joints between texels and suppresses what hides them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FallbackView {
    /// The gray plane smoothed over about a pixel (grain) minus its smoothing over about
    /// sixteen (shading across the sample): what remains is the texel-scale pattern.
    BandPassed,
    /// The gradient magnitude of the lightly smoothed gray plane: joints drawn as dark lines,
    /// as embossed edges or as colour changes between bricks all become the same bright lines,
    /// so bricks of varied colour no longer decorrelate the pattern.
    EdgeStrength,
}

impl FallbackView {
    /// Tried in this order when the gray plane yields no lattice.
    pub const ALL: [FallbackView; 2] = [FallbackView::BandPassed, FallbackView::EdgeStrength];

    pub fn name(self) -> &'static str {
        match self {
            FallbackView::BandPassed => "band-passed gray",
            FallbackView::EdgeStrength => "edge strength",
        }
    }

    /// The view of the centred gray `plane` (`w × h`), itself centred.
    pub fn of(self, plane: &[f64], w: usize, h: usize) -> Vec<f64> {
        self.of_grain_free(plane, &grain_free(plane, w, h), w, h)
    }

    /// [`FallbackView::of`], given `fine`, the plane's [`grain_free`] smoothing (shared by the
    /// views).
    fn of_grain_free(self, plane: &[f64], fine: &[f64], w: usize, h: usize) -> Vec<f64> {
        // Radius 16 (σ ≈ 16 px) is below the shortest texel this matters for, so subtracting it
        // removes shading without flattening the texels themselves.
        const SHADING_RADIUS: usize = 16;
        let view: Vec<f64> = match self {
            FallbackView::BandPassed => {
                let coarse = smooth(plane, w, h, SHADING_RADIUS);
                fine.iter().zip(&coarse).map(|(f, c)| f - c).collect()
            }
            FallbackView::EdgeStrength => {
                let at = |x: usize, y: usize| fine[y * w + x];
                let mut out = Vec::with_capacity(w * h);
                for y in 0..h {
                    for x in 0..w {
                        let gx = (at((x + 1).min(w - 1), y) - at(x.saturating_sub(1), y)) / 2.0;
                        let gy = (at(x, (y + 1).min(h - 1)) - at(x, y.saturating_sub(1))) / 2.0;
                        out.push((gx * gx + gy * gy).sqrt());
                    }
                }
                out
            }
        };
        let mean = view.iter().sum::<f64>() / view.len() as f64;
        view.into_iter().map(|v| v - mean).collect()
    }
}

/// The smoothing of the centred gray `plane` both views start from: radius 1 (three passes,
/// σ ≈ 1.4 px) removes pixel grain but not a 2-pixel joint.
fn grain_free(plane: &[f64], w: usize, h: usize) -> Vec<f64> {
    const GRAIN_RADIUS: usize = 1;
    smooth(plane, w, h, GRAIN_RADIUS)
}

/// Three passes of a `(2·radius + 1)`-pixel box mean along rows, then along columns, with the
/// border pixels repeated: close to a Gaussian, and as cheap for a wide radius as a narrow one.
fn smooth(plane: &[f64], w: usize, h: usize, radius: usize) -> Vec<f64> {
    let mut out = plane.to_vec();
    let mut line = Vec::new();
    let mut copy = vec![0.0; w * h];
    let mut sums = vec![0.0; w];
    for _ in 0..3 {
        for y in 0..h {
            line.clear();
            line.extend((0..w).map(|x| out[y * w + x]));
            box_mean(&line, radius, |x, v| out[y * w + x] = v);
        }
        copy.copy_from_slice(&out);
        box_mean_columns(&copy, w, h, radius, &mut sums, &mut out);
    }
    out
}

/// [`box_mean`] down every column of `src` (`w × h`) into `out`, a row at a time: each column's
/// running sum takes the same values, in the same order, as [`box_mean`] of the column would, but
/// the plane is walked along its rows. `sums` is `w` long.
fn box_mean_columns(src: &[f64], w: usize, h: usize, radius: usize, sums: &mut [f64], out: &mut [f64]) {
    let n = h as i64;
    let r = radius as i64;
    let row = |i: i64| &src[i.clamp(0, n - 1) as usize * w..][..w];
    for (x, sum) in sums.iter_mut().enumerate() {
        *sum = (-r..=r).map(|i| row(i)[x]).sum();
    }
    let width = (2 * r + 1) as f64;
    for i in 0..n {
        let (add, sub) = (row(i + r + 1), row(i - r));
        let dst = &mut out[i as usize * w..][..w];
        for (((d, s), &a), &b) in dst.iter_mut().zip(sums.iter_mut()).zip(add).zip(sub) {
            *d = *s / width;
            *s += a - b;
        }
    }
}

/// The running mean of `line` over `i − radius ..= i + radius` (indices clamped to the line),
/// handed to `put(i, mean)` in order.
fn box_mean(line: &[f64], radius: usize, mut put: impl FnMut(usize, f64)) {
    let n = line.len() as i64;
    let r = radius as i64;
    let at = |i: i64| line[i.clamp(0, n - 1) as usize];
    let mut sum: f64 = (-r..=r).map(at).sum();
    let width = (2 * r + 1) as f64;
    for i in 0..n {
        put(i as usize, sum / width);
        sum += at(i + r + 1) - at(i - r);
    }
}

/// Finds `t1, t2`; `Err` explains why the sample is not near-regular enough.
///
/// The gray plane is tried first, and its reason is the one reported when every view fails. The
/// fallback views (see the module comment) lower the bar for a weak pattern, so they must also
/// show it at least three times across the sample: both vectors at most a third of its smaller
/// side. A single feature (a window, two big tiles filling the sample) then cannot pass for a
/// lattice.
pub fn extract(img: &RgbImage, opts: &LatticeOptions) -> Result<Lattice, SynthError> {
    let (w, h) = (img.width() as usize, img.height() as usize);
    if w < 8 || h < 8 {
        return Err(SynthError::Sample(format!("{NONE} (the sample is too small to show a period)")));
    }
    extract_centred(&centred_gray(img), w, h, opts)
}

/// [`extract`] of a sample of at least 8 × 8 pixels given as its [`centred_gray`] plane.
///
/// The fallback views are tried while the gray plane is, and each other (on other threads when
/// there are some): a stochastic sample, which has no lattice, needs all three, and they were a
/// quarter of a tile method's call on one (issue #30). A view not yet started when the gray
/// plane has given a lattice is skipped, and the result is the one of trying them in order,
/// whichever finishes first.
pub(crate) fn extract_centred(plane: &[f64], w: usize, h: usize, opts: &LatticeOptions) -> Result<Lattice, SynthError> {
    let key = ExtractionKey::of(plane, w, h, opts);
    if let Some(known) = EXTRACTED.lock().unwrap_or_else(|e| e.into_inner()).iter().find(|(k, _)| *k == key) {
        return known.1.clone();
    }
    let result = extract_centred_anew(plane, w, h, opts);
    let mut extracted = EXTRACTED.lock().unwrap_or_else(|e| e.into_inner());
    // Two jobs on one sample may have extracted it at once: keep one entry.
    if !extracted.iter().any(|(k, _)| *k == key) {
        if extracted.len() >= EXTRACTIONS_KEPT {
            drop(extracted.remove(0));
        }
        extracted.push((key, result.clone()));
    }
    result
}

/// How many of the latest extractions [`extract_centred`] keeps.
const EXTRACTIONS_KEPT: usize = 16;

/// The latest extractions of this process, by plane and options. A job's advice and its method
/// each extract the sample's lattice, and every job on a sample does: keeping them took a default
/// 2048² `rw-tiles` fill of grass (`texsyn synth`) from 0.144 to 0.127 s of wall time (issue #30). The
/// extraction is a function of the plane and the options alone, so a kept result is the one
/// extracting again would give, whichever thread asks.
static EXTRACTED: std::sync::Mutex<Vec<(ExtractionKey, Result<Lattice, SynthError>)>> = std::sync::Mutex::new(Vec::new());

/// A plane (by its size and SHA-256) and the options it was searched with.
#[derive(Clone, PartialEq)]
struct ExtractionKey {
    size: (usize, usize),
    digest: crate::digest::Digest,
    options: (usize, u64, u64, u64),
}

impl ExtractionKey {
    fn of(plane: &[f64], w: usize, h: usize, opts: &LatticeOptions) -> ExtractionKey {
        let mut hasher = crate::digest::Hasher::new();
        let mut bytes = Vec::with_capacity(8 * 1024);
        for chunk in plane.chunks(1024) {
            bytes.clear();
            bytes.extend(chunk.iter().flat_map(|v| v.to_bits().to_le_bytes()));
            hasher.update(&bytes);
        }
        ExtractionKey {
            size: (w, h),
            digest: hasher.finish(),
            options: (opts.max_peaks, opts.min_length.to_bits(), opts.min_angle_deg.to_bits(), opts.min_peak.to_bits()),
        }
    }
}

/// The peak memory of [`extract_centred`] on a `w × h` plane, beside the plane itself: the gray
/// plane's extraction and, at the same time, a fallback view's (each its padded transform and
/// window, [`crate::metrics::acf::real_working_set`]), with the grain-free plane, the view and the band-pass's two
/// temporaries. The memory model counts it through the advice, which extracts every sample's lattice.
pub fn peak_memory(w: usize, h: usize) -> u64 {
    2 * crate::metrics::acf::real_working_set(w, h, w / 2, h / 2) + 4 * 8 * (w * h) as u64
}

/// [`extract_centred`] without looking among the kept results.
fn extract_centred_anew(plane: &[f64], w: usize, h: usize, opts: &LatticeOptions) -> Result<Lattice, SynthError> {
    let found = AtomicBool::new(false);
    let (gray, fallback) = rayon::join(
        || {
            let r = extract_from(plane, w, h, opts, &mut AcfPlanner::new(), None);
            found.store(r.is_ok(), Ordering::Relaxed);
            r
        },
        || {
            if found.load(Ordering::Relaxed) {
                return None;
            }
            let longest = w.min(h) as f64 / 3.0;
            let fine = grain_free(plane, w, h);
            // One view after the other, not side by side: the first that yields a lattice is
            // taken either way, and each extraction holds its padded transform (about 70 bytes
            // per plane pixel), so that at most two are held at once, beside the gray plane's
            // ([`peak_memory`]).
            let mut planner = AcfPlanner::new();
            FallbackView::ALL.iter().find_map(|&view| {
                if found.load(Ordering::Relaxed) {
                    return None;
                }
                let viewed = view.of_grain_free(plane, &fine, w, h);
                extract_from(&viewed, w, h, opts, &mut planner, Some(longest)).ok().map(|l| Lattice { found_in: Some(view.name()), ..l })
            })
        },
    );
    match (gray, fallback) {
        (Ok(l), _) => Ok(l),
        (Err(_), Some(l)) => Ok(l),
        (Err(e), None) => Err(e),
    }
}

/// The squared distance from `(px, py)` to the nearest point of the `aw × ah` grid `values`
/// (row-major) whose value is above `v`, if any.
///
/// Searched ring by ring (the points at Chebyshev distance `k`, for `k = 1, 2, …`), stopping once
/// a ring can hold no point nearer than the nearest found (every point of ring `k` is at least
/// `k` away) or lies wholly outside the grid: the same minimum as a scan of the whole grid, but a
/// noisy sample's thousands of peaks each find a higher value a few pixels away.
fn nearest_higher(values: &[f64], aw: usize, ah: usize, (px, py): (usize, usize), v: f64) -> Option<i64> {
    let (aw, ah, px, py) = (aw as i64, ah as i64, px as i64, py as i64);
    let mut best: Option<i64> = None;
    let consider = |x: i64, y: i64, best: &mut Option<i64>| {
        if values[(y * aw + x) as usize] > v {
            let d2 = (x - px) * (x - px) + (y - py) * (y - py);
            if best.is_none_or(|b| d2 < b) {
                *best = Some(d2);
            }
        }
    };
    for k in 1.. {
        if best.is_some_and(|b| b <= k * k) {
            break;
        }
        let (left, right, top, bottom) = (px - k, px + k, py - k, py + k);
        if left < 0 && right >= aw && top < 0 && bottom >= ah {
            break;
        }
        let (x0, x1) = (left.max(0), right.min(aw - 1));
        if top >= 0 {
            for x in x0..=x1 {
                consider(x, top, &mut best);
            }
        }
        if bottom < ah {
            for x in x0..=x1 {
                consider(x, bottom, &mut best);
            }
        }
        let (y0, y1) = ((top + 1).max(0), (bottom - 1).min(ah - 1));
        if left >= 0 {
            for y in y0..=y1 {
                consider(left, y, &mut best);
            }
        }
        if right < aw {
            for y in y0..=y1 {
                consider(right, y, &mut best);
            }
        }
    }
    best
}

/// Steps 3–9 on one centred plane (`w × h`); `planner` serves all the views' autocorrelations,
/// `longest` bounds both vectors' lengths.
fn extract_from(
    plane: &[f64],
    w: usize,
    h: usize,
    opts: &LatticeOptions,
    planner: &mut AcfPlanner,
    longest: Option<f64>,
) -> Result<Lattice, SynthError> {
    let (rx, ry) = (w / 2, h / 2);
    let acf =
        planner.real(plane, w, h, rx, ry, AcfForm::Biased).map_err(|e| SynthError::Sample(format!("{NONE} ({e}: the sample is flat)")))?;
    let (rx, ry) = (rx as i64, ry as i64);
    let a = |dx: i64, dy: i64| acf.get(dx, dy);
    let inside = |dx: i64, dy: i64| dx.abs() <= rx && dy.abs() <= ry;
    let order = |dx: i64, dy: i64| (dy + ry) * (2 * rx + 1) + (dx + rx);

    // 3. Strict local maxima (plateaus: only their first pixel in row-major order). Only offsets
    // with all 8 neighbours in the window qualify: at the window's edge a value is "maximal" merely
    // because the window ends, and would then dominate a huge region.
    let (aw, ah) = (acf.width(), acf.height());
    let values = acf.values();
    let mut peaks = Vec::new();
    for row in 1..ah - 1 {
        for col in 1..aw - 1 {
            if (col, row) == (rx as usize, ry as usize) {
                continue;
            }
            // Row-major index order is `order`'s.
            let i = row * aw + col;
            let v = values[i];
            let mut is_max = true;
            'n: for ny in [-1isize, 0, 1] {
                for nx in [-1isize, 0, 1] {
                    if (nx, ny) == (0, 0) {
                        continue;
                    }
                    let j = i.wrapping_add_signed(ny * aw as isize + nx);
                    let q = values[j];
                    if q > v || (q == v && j < i) {
                        is_max = false;
                        break 'n;
                    }
                }
            }
            if is_max {
                peaks.push((col, row));
            }
        }
    }
    // 4. Region of dominance: distance to the nearest higher value ([`nearest_higher`]).
    let mut ranked: Vec<((i64, i64), f64, f64)> = peaks
        .iter()
        .map(|&(col, row)| {
            let v = values[row * aw + col];
            let best = nearest_higher(values, aw, ah, (col, row), v).map_or(f64::INFINITY, |d2| (d2 as f64).sqrt());
            ((col as i64 - rx, row as i64 - ry), best, v)
        })
        .collect();
    // 5. Dominant peaks.
    ranked.sort_by(|x, y| {
        y.1.partial_cmp(&x.1).unwrap().then(y.2.partial_cmp(&x.2).unwrap()).then(order(x.0.0, x.0.1).cmp(&order(y.0.0, y.0.1)))
    });
    ranked.truncate(opts.max_peaks);
    let c: Vec<((i64, i64), f64)> = ranked.into_iter().filter(|p| p.2 > 0.0 && len(p.0) >= opts.min_length).map(|p| (p.0, p.2)).collect();
    // 6. Shortest vector, then the shortest one far enough in angle.
    let shortest = |cands: &mut dyn Iterator<Item = &((i64, i64), f64)>| -> Option<(i64, i64)> {
        cands
            .min_by(|x, y| {
                dot(x.0, x.0).cmp(&dot(y.0, y.0)).then(y.1.partial_cmp(&x.1).unwrap()).then(order(x.0.0, x.0.1).cmp(&order(y.0.0, y.0.1)))
            })
            .map(|p| p.0)
    };
    let t1 = shortest(&mut c.iter()).ok_or_else(|| SynthError::Sample(format!("{NONE} (no dominant autocorrelation peak)")))?;
    let sin_min = opts.min_angle_deg.to_radians().sin();
    let t2 = shortest(&mut c.iter().filter(|p| (cross(t1, p.0).abs() as f64) >= len(t1) * len(p.0) * sin_min))
        .ok_or_else(|| SynthError::Sample(format!("{NONE} (the autocorrelation peaks lie along one direction only)")))?;
    // 7. Lagrange–Gauss reduction.
    let (t1, t2) = reduce(t1, t2);
    // 8. Reliability.
    let peak_at = |t: (i64, i64)| -> f64 {
        let mut m = f64::NEG_INFINITY;
        for ny in -1..=1 {
            for nx in -1..=1 {
                if inside(t.0 + nx, t.1 + ny) {
                    m = m.max(a(t.0 + nx, t.1 + ny));
                }
            }
        }
        m
    };
    let (peak1, peak2) = (peak_at(t1), peak_at(t2));
    let explained_by = |t1: (i64, i64), t2: (i64, i64)| -> usize {
        let tol = (0.1 * len(t1).min(len(t2))).max(2.0);
        let d = cross(t1, t2) as f64;
        c.iter()
            .filter(|p| {
                let q = p.0;
                let alpha = cross(q, t2) as f64 / d;
                let beta = cross(t1, q) as f64 / d;
                let mut best = f64::INFINITY;
                for m in [alpha.floor() as i64, alpha.ceil() as i64] {
                    for n in [beta.floor() as i64, beta.ceil() as i64] {
                        let lp = (m * t1.0 + n * t2.0, m * t1.1 + n * t2.1);
                        best = best.min(len((q.0 - lp.0, q.1 - lp.1)));
                    }
                }
                best <= tol
            })
            .count()
    };
    let explained = explained_by(t1, t2);
    if peak1 < opts.min_peak || peak2 < opts.min_peak {
        return Err(SynthError::Sample(format!(
            "{NONE} (the candidate vectors ({}, {}) and ({}, {}) have weak autocorrelation peaks {:.3} and {:.3}, below {}; the sample is not near-regular enough)",
            t1.0, t1.1, t2.0, t2.1, peak1, peak2, opts.min_peak
        )));
    }
    if explained * 2 < c.len() {
        return Err(SynthError::Sample(format!(
            "{NONE} (the lattice ({}, {}), ({}, {}) explains only {explained} of {} dominant peaks)",
            t1.0,
            t1.1,
            t2.0,
            t2.1,
            c.len()
        )));
    }
    if let Some(longest) = longest
        && len(t1).max(len(t2)) > longest
    {
        return Err(SynthError::Sample(format!(
            "{NONE} (the lattice ({}, {}), ({}, {}) repeats fewer than three times across the sample)",
            t1.0, t1.1, t2.0, t2.1
        )));
    }
    // 10. A coarser lattice where the sample repeats clearly better. In a running bond a shift
    // by half a brick, or by one course, lays the mortar lines onto mortar lines and the joints
    // onto the next course's joints: those offsets make peaks that a lattice of half bricks
    // explains along with the true ones, and it is the shortest. Cut on it, texels are half
    // bricks and the methods lay bricks of random lengths. Of its three sublattices of index 2,
    // the one whose weaker peak (as a mean over the overlap, so that longer vectors are not
    // penalised for overlapping less) is at least COARSER_BY times the fine lattice's is taken.
    // Gray plane only: the fallback views' peaks are weak by definition.
    let overlap_mean = |t: (i64, i64)| peak_at(t) / ((1.0 - t.0.abs() as f64 / w as f64) * (1.0 - t.1.abs() as f64 / h as f64));
    let weaker = |(a, b): ((i64, i64), (i64, i64))| overlap_mean(a).min(overlap_mean(b));
    let fits = |v: (i64, i64)| inside(v.0, v.1) && len(v) <= longest.unwrap_or(f64::INFINITY).min(w.min(h) as f64 / 2.0);
    let fine = weaker((t1, t2));
    let sum = (t1.0 + t2.0, t1.1 + t2.1);
    let difference = (t1.0 - t2.0, t1.1 - t2.1);
    let coarser = [((2 * t1.0, 2 * t1.1), t2), (t1, (2 * t2.0, 2 * t2.1)), (sum, difference)]
        .into_iter()
        .map(|(a, b)| reduce(a, b))
        .filter(|&(a, b)| fits(a) && fits(b))
        .map(|basis| (basis, weaker(basis)))
        .filter(|&(_, v)| v >= COARSER_BY * fine && fine > 0.0 && longest.is_none())
        .max_by(|x, y| x.1.total_cmp(&y.1));
    let (t1, t2, peak1, peak2, explained) = match coarser {
        Some(((a, b), _)) => (a, b, peak_at(a), peak_at(b), explained_by(a, b)),
        None => (t1, t2, peak1, peak2, explained),
    };
    let (t1, t2) = canonical(t1, t2);
    let fine = refine(plane, (w, h), planner, t1, t2);
    Ok(Lattice { t1, t2, peak1, peak2, candidates: c.len(), explained, found_in: None, fine })
}

/// Combinations `m·t1 + n·t2` [`refine`] looks for: `|m|, |n|` up to this (and inside the window).
const REFINE_COEFFICIENT: i64 = 12;
/// A combination's peak is used when its overlap mean reaches this share of the weaker of the
/// two vectors' own: far out, or where the sample's texels vary, a peak is too weak and flat to
/// place to a fraction of a pixel.
const REFINE_PEAK_SHARE: f64 = 0.5;

/// How far [`refine`] climbs from where it looks for a peak, in pixels.
const CLIMB_STEPS: usize = 2;
/// How far from where [`refine`] looked for it a peak may lie and still be taken as the
/// lattice's: a pixel. Past the third period metal_tread_studs' peaks split in two, one where
/// the first three put them (106.8 px across) and one 5 px short (101.5 px: the sample's
/// texels shift by that much somewhere across it); the nearer share of the sample is the one
/// the fit should follow, not a blend of the two.
const REFINE_MISS_PX: f64 = 1.0;

/// `t1, t2` to a fraction of a pixel: the positions of the autocorrelation peaks at the
/// combinations `m·t1 + n·t2` (up to [`REFINE_COEFFICIENT`], within the ACF window), each the
/// local maximum near where the vectors found so far put it, placed between pixels by a parabola
/// through it and its two neighbours along each axis; then the least-squares `t1, t2` of
/// `p(m, n) ≈ m·t1 + n·t2`, peak `(m, n)`'s error divided by `m, n`. Rings `max(|m|, |n|) = 1,
/// 2, …` are added in turn and the vectors refitted after each, so a peak far out is looked for
/// where the nearer ones put it (the whole-pixel vectors are up to half a pixel off: 8 periods
/// on that is 4 px, the next peak over on a short lattice).
///
/// The autocorrelation is the sample's under a taper ([`taper`]), divided by the taper's own. Untapered,
/// the overlap at a shift `d` ends part-way through a period, and where it ends moves with `d`:
/// that tilts every peak by a tenth of a pixel or so (blobs 26.7 px apart read 26.63 from their
/// first peak), always the same way on a given sample, so more peaks do not average it out. The
/// taper lets the overlap fade out instead of ending (blobs 26.7 px apart then read 26.70);
/// dividing by the taper's autocorrelation removes its fall-off away from the origin, which would
/// pull every peak towards it. The taper stays flat over the middle half: one falling all the
/// way to the centre (Hann) weighs the middle most, and where a sample's texels jump there (the
/// 6 px half-way across metal_tread_studs) reads a period no part of the sample has (26.49 px
/// against 26.6 on either side of the jump).
///
/// metal_tread_studs (27, 0), (0, 26): 26.57 px across and 25.96 down, which its whole-pixel
/// vectors call 27 and 26 (16 periods across are 425 px, not 432).
fn refine(plane: &[f64], (w, h): (usize, usize), planner: &mut AcfPlanner, t1: (i64, i64), t2: (i64, i64)) -> FineVectors {
    let (hx, hy) = (taper(w), taper(h));
    let tapered: Vec<f64> = plane.iter().enumerate().map(|(i, v)| v * hx[i % w] * hy[i / w]).collect();
    let Ok(acf) = planner.real(&tapered, w, h, w / 2, h / 2, AcfForm::Biased) else { return FineVectors::exact(t1, t2) };
    let (rx, ry) = (acf.rx() as i64, acf.ry() as i64);
    // The taper's own autocorrelation, separable: what the sample's is divided by.
    let lagged = |t: &[f64], d: usize| -> f64 { t.iter().zip(&t[d..]).map(|(a, b)| a * b).sum() };
    let (ax, ay): (Vec<f64>, Vec<f64>) = ((0..=w / 2).map(|d| lagged(&hx, d)).collect(), (0..=h / 2).map(|d| lagged(&hy, d)).collect());
    let mean = |dx: i64, dy: i64| acf.get(dx, dy) / (ax[dx.unsigned_abs() as usize] * ay[dy.unsigned_abs() as usize]);
    // A peak needs its 8 neighbours inside the window.
    let inner = |x: i64, y: i64| x.abs() < rx && y.abs() < ry;
    let mut fine = FineVectors::exact(t1, t2);
    if !inner(t1.0, t1.1) || !inner(t2.0, t2.1) {
        return fine;
    }
    let floor = REFINE_PEAK_SHARE * mean(t1.0, t1.1).min(mean(t2.0, t2.1));
    // The local maximum reached by climbing from `start` (ties: the first neighbour in row-major
    // order), at most `steps` pixels away.
    let climb = |start: (i64, i64), steps: usize| -> Option<(i64, i64)> {
        let mut at = start;
        for _ in 0..=steps {
            let mut best = at;
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let q = (at.0 + dx, at.1 + dy);
                    if inner(q.0, q.1) && mean(q.0, q.1) > mean(best.0, best.1) {
                        best = q;
                    }
                }
            }
            if best == at {
                return Some(at);
            }
            at = best;
        }
        None
    };
    // The vertex of the parabola through three values, as an offset from the middle one.
    let vertex = |l: f64, c: f64, r: f64| -> f64 {
        let curvature = l - 2.0 * c + r;
        if curvature < 0.0 { ((l - r) / (2.0 * curvature)).clamp(-0.5, 0.5) } else { 0.0 }
    };
    let mut found: Vec<((f64, f64), (f64, f64))> = Vec::new();
    for ring in 1..=REFINE_COEFFICIENT {
        let before = found.len();
        for n in -ring..=ring {
            for m in -ring..=ring {
                // One of each ± pair (the ACF is symmetric), on this ring only.
                if m.abs().max(n.abs()) != ring || n < 0 || (n == 0 && m < 0) {
                    continue;
                }
                let (mf, nf) = (m as f64, n as f64);
                let guess = (mf * fine.t1.0 + nf * fine.t2.0, mf * fine.t1.1 + nf * fine.t2.1);
                let start = (guess.0.round() as i64, guess.1.round() as i64);
                if !inner(start.0, start.1) {
                    continue;
                }
                let Some(p) = climb(start, CLIMB_STEPS) else { continue };
                let v = mean(p.0, p.1);
                if v < floor {
                    continue;
                }
                let px = p.0 as f64 + vertex(mean(p.0 - 1, p.1), v, mean(p.0 + 1, p.1));
                let py = p.1 as f64 + vertex(mean(p.0, p.1 - 1), v, mean(p.0, p.1 + 1));
                if (px - guess.0).abs().max((py - guess.1).abs()) > REFINE_MISS_PX {
                    continue;
                }
                found.push(((mf, nf), (px, py)));
            }
        }
        if found.len() == before {
            break;
        }
        if let Some((a, b)) = least_squares(&found) {
            fine = FineVectors { t1: a, t2: b, peaks: found.len() };
        }
    }
    // Trusted when more peaks than the two it needs agree with it within half a pixel (root
    // mean square), and it stays within a pixel of the whole-pixel vectors (further, it has
    // followed other peaks than the lattice's). Ridges instead of peaks (courses of random-length
    // bricks) give two peaks or none: the whole-pixel vectors stay.
    let residual = {
        let sum: f64 = found
            .iter()
            .map(|&((m, n), p)| {
                let (x, y) = (p.0 - m * fine.t1.0 - n * fine.t2.0, p.1 - m * fine.t1.1 - n * fine.t2.1);
                x * x + y * y
            })
            .sum();
        (sum / found.len().max(1) as f64).sqrt()
    };
    let near = |f: (f64, f64), t: (i64, i64)| (f.0 - t.0 as f64).abs() < 1.0 && (f.1 - t.1 as f64).abs() < 1.0;
    if found.len() >= REFINE_MIN_PEAKS && residual <= REFINE_RESIDUAL_PX && near(fine.t1, t1) && near(fine.t2, t2) {
        fine
    } else {
        FineVectors::exact(t1, t2)
    }
}

/// [`refine`] keeps its fit when at least this many peaks went into it (one more than the two
/// vectors need, so that they check each other) ...
const REFINE_MIN_PEAKS: usize = 3;
/// ... and they lie within this many pixels of it (root mean square).
const REFINE_RESIDUAL_PX: f64 = 0.5;

/// The taper over `n` pixels: flat in the middle half, falling to 0 along half a cosine over the
/// outer quarter on each side (a Tukey window).
fn taper(n: usize) -> Vec<f64> {
    let edge = 0.25 * n as f64;
    (0..n)
        .map(|i| {
            let from_edge = (i as f64 + 0.5).min(n as f64 - i as f64 - 0.5);
            if from_edge >= edge { 1.0 } else { (std::f64::consts::FRAC_PI_2 * from_edge / edge).sin().powi(2) }
        })
        .collect()
}

/// The `t1, t2` minimising `Σ |p − (m·t1 + n·t2)|²` over `((m, n), p)`, or `None` when the
/// coefficients do not span both vectors.
fn least_squares(found: &[((f64, f64), (f64, f64))]) -> Option<((f64, f64), (f64, f64))> {
    let (mut smm, mut smn, mut snn) = (0.0, 0.0, 0.0);
    let (mut smp, mut snp) = ((0.0, 0.0), (0.0, 0.0));
    for &((m, n), p) in found {
        smm += m * m;
        smn += m * n;
        snn += n * n;
        smp = (smp.0 + m * p.0, smp.1 + m * p.1);
        snp = (snp.0 + n * p.0, snp.1 + n * p.1);
    }
    let det = smm * snn - smn * smn;
    if det.abs() < 1e-9 {
        return None;
    }
    let solve = |a: f64, b: f64| ((snn * a - smn * b) / det, (smm * b - smn * a) / det);
    let (t1x, t2x) = solve(smp.0, snp.0);
    let (t1y, t2y) = solve(smp.1, snp.1);
    Some(((t1x, t1y), (t2x, t2y)))
}

/// How much more clearly a sublattice must repeat than the lattice found before it is taken
/// (step 10 of [`extract`]). On a running bond of red bricks the whole-brick lattice repeats 1.44
/// times as clearly as the half-brick one; on a synthetic beige wall whose sample is a 2 × 2
/// tiling, the doubled lattice repeats 1.16 times as clearly (the exact tiling) and the bricks
/// lattice is the right one; every other sample in the repository stays under 1.2.
const COARSER_BY: f64 = 1.3;

/// Step 9: `t1` the more horizontal vector, pointing right (or down), `cross(t1, t2) > 0`.
/// Lagrange–Gauss reduction of a basis (shortest first). Stops as soon as a step no longer
/// shortens `t2`: when `t1·t2 / t1·t1` is exactly ±½ rounding alone would flip `t2` between two
/// equally long vectors forever (e.g. (16, 0), (8, 16)).
pub fn reduce(t1: (i64, i64), t2: (i64, i64)) -> ((i64, i64), (i64, i64)) {
    let (mut t1, mut t2) = (t1, t2);
    loop {
        if dot(t1, t1) > dot(t2, t2) {
            std::mem::swap(&mut t1, &mut t2);
        }
        let mu = (dot(t1, t2) as f64 / dot(t1, t1) as f64).round() as i64;
        let next = (t2.0 - mu * t1.0, t2.1 - mu * t1.1);
        if mu == 0 || dot(next, next) >= dot(t2, t2) {
            return (t1, t2);
        }
        t2 = next;
    }
}

pub fn canonical(t1: (i64, i64), t2: (i64, i64)) -> ((i64, i64), (i64, i64)) {
    let horizontality = |v: (i64, i64)| v.0.abs() as f64 / len(v);
    let (mut t1, mut t2) = if horizontality(t2) > horizontality(t1) { (t2, t1) } else { (t1, t2) };
    if t1.0 < 0 || (t1.0 == 0 && t1.1 < 0) {
        t1 = (-t1.0, -t1.1);
    }
    if cross(t1, t2) < 0 {
        t2 = (-t2.0, -t2.1);
    }
    (t1, t2)
}

/// The sample with the lattice drawn over it (lines along `t1` and `t2` through the origin
/// `(0, 0)`), so a user can check it by eye.
pub fn overlay(img: &RgbImage, lat: &Lattice) -> RgbImage {
    let mut out = img.clone();
    let (w, h) = (img.width() as i64, img.height() as i64);
    let d = lat.determinant();
    if d == 0 {
        return out;
    }
    // A pixel is on a lattice line when its lattice coordinate α or β is within half a pixel
    // (measured along the other vector) of an integer: exact integer arithmetic as in B11.
    let (t1, t2) = (lat.t1, lat.t2);
    let half_width = |t: (i64, i64)| (d.abs() as f64 / len(t) * 0.5 / d.abs() as f64) * d.abs() as f64;
    let (hw1, hw2) = (half_width(t2), half_width(t1));
    for y in 0..h {
        for x in 0..w {
            let alpha = cross((x, y), t2) as f64 / d as f64; // coordinate along t1
            let beta = cross(t1, (x, y)) as f64 / d as f64;
            let da = (alpha - alpha.round()).abs() * d.abs() as f64 / len(t2);
            let db = (beta - beta.round()).abs() * d.abs() as f64 / len(t1);
            if da <= hw1.min(0.75) || db <= hw2.min(0.75) {
                out.put(x as u32, y as u32, [255, 40, 40]);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    #[test]
    fn reduction_terminates_on_half_ties_and_shortens() {
        assert_eq!(reduce((16, 0), (8, 16)), ((16, 0), (8, 16)));
        assert_eq!(reduce((16, 0), (-8, 16)), ((16, 0), (-8, 16)));
        assert_eq!(reduce((27, 0), (27 * 3, 26)), ((0, 26), (27, 0)));
        assert_eq!(reduce((38, -24), (74, 0)), ((36, 24), (38, -24)));
    }

    use super::*;

    fn periodic(w: u32, h: u32, t1: (i64, i64), t2: (i64, i64)) -> RgbImage {
        // A blob pattern repeating on the lattice t1, t2 (with a little deterministic texture).
        let d = cross(t1, t2) as f64;
        RgbImage::from_fn(w, h, |x, y| {
            let (x, y) = (x as i64, y as i64);
            let a = cross((x, y), t2) as f64 / d;
            let b = cross(t1, (x, y)) as f64 / d;
            let (fa, fb) = (a - a.floor() - 0.5, b - b.floor() - 0.5);
            let blob = (fa * fa + fb * fb) < 0.08;
            let v = if blob { 200 } else { 60 } + ((x * 31 + y * 17) % 7) as u8;
            [v, v, v]
        })
    }

    #[test]
    fn finds_a_rectangular_and_a_slanted_lattice() {
        let l = extract(&periodic(160, 160, (20, 0), (0, 16)), &LatticeOptions::default()).unwrap();
        assert_eq!((l.t1, l.t2), ((20, 0), (0, 16)));
        let s = extract(&periodic(200, 200, (24, 0), (12, 20)), &LatticeOptions::default()).unwrap();
        assert!(s.determinant() == 24 * 20, "{s:?}");
        assert!(s.t1.0 > 0 && s.determinant() > 0);
    }

    #[test]
    fn an_extraction_is_kept_and_given_again_only_for_the_same_plane_and_options() {
        let img = periodic(120, 96, (20, 0), (0, 16));
        let (w, h) = (120, 96);
        let plane = centred_gray(&img);
        let strict = LatticeOptions { min_peak: 0.99, ..LatticeOptions::default() };
        let kept = |opts: &LatticeOptions| {
            let key = ExtractionKey::of(&plane, w, h, opts);
            EXTRACTED.lock().unwrap().iter().find(|(k, _)| *k == key).map(|(_, r)| r.clone())
        };
        let found = extract(&img, &LatticeOptions::default());
        assert_eq!(kept(&LatticeOptions::default()), Some(found.clone()), "the result is kept by plane and options");
        assert_eq!(extract_centred(&plane, w, h, &LatticeOptions::default()), found);
        assert_eq!(
            extract_centred(&plane, w, h, &LatticeOptions::default()),
            extract_centred_anew(&plane, w, h, &LatticeOptions::default())
        );
        // Other options are another search, not the kept one.
        assert_eq!(extract_centred(&plane, w, h, &strict), extract_centred_anew(&plane, w, h, &strict));
        assert!(kept(&strict).is_some_and(|r| r.is_err()) && found.is_ok(), "{found:?}");
    }

    /// Round blobs on the lattice `t1, t2` given to a fraction of a pixel.
    fn blobs(w: u32, h: u32, t1: (f64, f64), t2: (f64, f64)) -> RgbImage {
        let d = t1.0 * t2.1 - t1.1 * t2.0;
        RgbImage::from_fn(w, h, |x, y| {
            let (x, y) = (f64::from(x), f64::from(y));
            let a = (x * t2.1 - y * t2.0) / d;
            let b = (t1.0 * y - t1.1 * x) / d;
            let (fa, fb) = (a - a.round(), b - b.round());
            // A smooth bump, so its position between pixels shows in the pixel values.
            let v = 60.0 + 150.0 * (-(fa * fa + fb * fb) / 0.06).exp();
            let v = v as u8;
            [v, v, v]
        })
    }

    #[test]
    fn the_fine_vectors_find_a_period_between_whole_pixels() {
        for (t1, t2) in [((26.7, 0.0), (0.0, 23.4)), ((30.3, 0.0), (15.15, 21.6)), ((26.62, -0.03), (-0.03, 25.96))] {
            let l = extract(&blobs(256, 256, t1, t2), &LatticeOptions::default()).unwrap();
            let f = l.fine;
            assert!(f.peaks >= 8, "{l:?}");
            // The same lattice (the basis may be another one): each true vector is a whole
            // combination of the fine ones within 0.05 px, and the texel areas agree.
            let det = |a: (f64, f64), b: (f64, f64)| a.0 * b.1 - a.1 * b.0;
            let d = det(f.t1, f.t2);
            for t in [t1, t2] {
                let (a, b) = ((det(t, f.t2) / d).round(), (det(f.t1, t) / d).round());
                let r = (t.0 - a * f.t1.0 - b * f.t2.0, t.1 - a * f.t1.1 - b * f.t2.1);
                assert!(r.0.abs().max(r.1.abs()) <= 0.05, "{t:?}: residual {r:?} ({l:?})");
            }
            assert!((d.abs() / det(t1, t2).abs() - 1.0).abs() < 0.005, "{l:?}");
            for (fine, whole) in [(f.t1, l.t1), (f.t2, l.t2)] {
                assert!((fine.0 - whole.0 as f64).abs() < 1.0 && (fine.1 - whole.1 as f64).abs() < 1.0, "{l:?}");
            }
        }
        // Whole-pixel lattices stay whole.
        let l = extract(&periodic(160, 160, (20, 0), (0, 16)), &LatticeOptions::default()).unwrap();
        assert!((l.fine.t1.0 - 20.0).abs() < 0.02 && l.fine.t1.1.abs() < 0.02 && (l.fine.t2.1 - 16.0).abs() < 0.02, "{l:?}");
    }

    #[test]
    fn least_squares_recovers_exact_vectors() {
        let (t1, t2) = ((26.7, 0.1), (-0.2, 25.9));
        let found: Vec<((f64, f64), (f64, f64))> = [(1.0, 0.0), (0.0, 1.0), (2.0, 1.0), (-1.0, 3.0)]
            .into_iter()
            .map(|(m, n)| ((m, n), (m * t1.0 + n * t2.0, m * t1.1 + n * t2.1)))
            .collect();
        let (a, b) = least_squares(&found).unwrap();
        assert!((a.0 - t1.0).abs() < 1e-9 && (a.1 - t1.1).abs() < 1e-9 && (b.0 - t2.0).abs() < 1e-9 && (b.1 - t2.1).abs() < 1e-9);
        assert!(least_squares(&found[..1]).is_none(), "one peak cannot give two vectors");
    }

    #[test]
    fn rejects_noise_and_flat_samples() {
        let mut st = crate::synth::rng::Stream::new(1, "noise");
        let noise = RgbImage::from_fn(128, 128, |_, _| {
            let v = st.below(256) as u8;
            [v, v, v]
        });
        assert!(extract(&noise, &LatticeOptions::default()).unwrap_err().to_string().contains("no lattice found; give t1/t2"));
        let flat = RgbImage::from_fn(64, 64, |_, _| [9, 9, 9]);
        assert!(extract(&flat, &LatticeOptions::default()).unwrap_err().to_string().contains("no lattice found"));
    }

    #[test]
    fn smoothing_keeps_a_constant_and_spreads_an_impulse_symmetrically() {
        let (w, h) = (21, 17);
        assert!(smooth(&vec![0.25; w * h], w, h, 3).iter().all(|&v| (v - 0.25).abs() < 1e-12));
        let mut impulse = vec![0.0; w * h];
        impulse[8 * w + 10] = 1.0;
        let s = smooth(&impulse, w, h, 1);
        let at = |x: usize, y: usize| s[y * w + x];
        assert!((at(9, 8) - at(11, 8)).abs() < 1e-12 && (at(10, 7) - at(10, 9)).abs() < 1e-12);
        assert!(at(10, 8) > at(11, 8) && at(11, 8) > at(13, 8) && at(14, 8) == 0.0, "three passes of radius 1 reach 3 px");
        assert!((s.iter().sum::<f64>() - 1.0).abs() < 1e-12, "away from the border nothing is lost");
    }

    #[test]
    fn fallback_views_are_centred_and_the_gray_plane_keeps_its_json() {
        let img = periodic(96, 80, (16, 0), (0, 20));
        let plane = centred_gray(&img);
        for view in FallbackView::ALL {
            let v = view.of(&plane, 96, 80);
            assert!(v.iter().sum::<f64>().abs() < 1e-9 && v.iter().any(|&x| x != 0.0), "{view:?}");
        }
        let l = extract(&img, &LatticeOptions::default()).unwrap();
        assert_eq!(l.found_in, None);
        assert!(serde_json::to_value(&l).unwrap().get("found_in").is_none(), "absent, so existing output is unchanged");
    }

    #[test]
    fn a_fallback_lattice_longer_than_allowed_is_refused() {
        let img = periodic(160, 160, (20, 0), (0, 16));
        let plane = centred_gray(&img);
        let opts = LatticeOptions::default();
        let mut planner = AcfPlanner::new();
        assert!(extract_from(&plane, 160, 160, &opts, &mut planner, Some(20.0)).is_ok());
        let err = extract_from(&plane, 160, 160, &opts, &mut planner, Some(19.0)).unwrap_err().to_string();
        assert!(err.contains("repeats fewer than three times"), "{err}");
    }

    #[test]
    fn canonical_form() {
        assert_eq!(canonical((0, -26), (-27, 0)), ((27, 0), (0, 26)));
        let (a, b) = canonical((-36, -24), (-38, 24));
        assert!(a.0 > 0 && cross(a, b) > 0);
    }

    #[test]
    fn the_ring_search_finds_the_nearest_higher_value_of_a_whole_scan() {
        let mut st = crate::synth::rng::Stream::new(2, "ring");
        for (aw, ah, levels) in [(9, 9, 3), (17, 11, 5), (33, 21, 40), (21, 33, 1000)] {
            let values: Vec<f64> = (0..aw * ah).map(|_| st.below(levels) as f64).collect();
            for py in 0..ah {
                for px in 0..aw {
                    let v = values[py * aw + px];
                    let scan = (0..aw * ah)
                        .filter(|&j| values[j] > v)
                        .map(|j| {
                            let (dx, dy) = ((j % aw) as i64 - px as i64, (j / aw) as i64 - py as i64);
                            dx * dx + dy * dy
                        })
                        .min();
                    assert_eq!(nearest_higher(&values, aw, ah, (px, py), v), scan, "{aw}x{ah} at ({px}, {py})");
                }
            }
        }
    }

    #[test]
    fn column_smoothing_is_the_per_column_running_mean() {
        let mut st = crate::synth::rng::Stream::new(3, "columns");
        let (w, h) = (13, 29);
        let src: Vec<f64> = (0..w * h).map(|_| st.below(1000) as f64 / 7.0 - 60.0).collect();
        for radius in [1, 4, 16, 40] {
            let mut out = vec![0.0; w * h];
            box_mean_columns(&src, w, h, radius, &mut vec![0.0; w], &mut out);
            for x in 0..w {
                let line: Vec<f64> = (0..h).map(|y| src[y * w + x]).collect();
                box_mean(&line, radius, |y, v| assert_eq!(out[y * w + x].to_bits(), v.to_bits(), "r {radius} at ({x}, {y})"));
            }
        }
    }
}
