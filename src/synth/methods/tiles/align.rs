//! Lattice alignment of the tile methods' patches (`align = "lattice"` of `wang-tiles` and
//! `rw-tiles`; not in paper 001).
//!
//! # Phase analysis
//!
//! Both tile methods build every tile from four patches of the sample. Inside one tile, the content
//! of patch `d` at tile pixel `x` is `sample(q_d + x − c_d)`, where `q_d` is the patch's position
//! in the sample and `c_d` its anchor in tile coordinates (Wang: the diamond centres at the edge
//! midpoints `(m,0), (t,m), (m,t), (0,m)`, `m = t/2`; RW: the sub-block origins `(0,0), (h,0),
//! (h,h), (0,h)` in the framework). On a sample periodic on the lattice `L = {a·t1 + b·t2}`, two
//! patches `d`, `e` show the same pattern where they meet (a cut between them joins in-phase
//! content, at zero cost on a perfectly periodic sample) exactly when their *phases* agree:
//! `ψ_d = q_d − c_d ≡ ψ_e = q_e − c_e (mod L)`.
//!
//! Each edge colour (a patch) plays two roles: a Wang N/S diamond is the N diamond of one tile and
//! the S diamond of another, anchored `(0, t)` apart; an E/W diamond is anchored `(t, 0)` apart; an
//! RW "/" patch is `B1` of one tile and `B3` of another, anchored `h(1,1)` apart; a "\" patch is
//! `B2` and `B4`, anchored `h(−1,1)` apart. These differences are exactly the tile translation
//! vectors `v_A, v_B`. If patch class A has phase `ψ_A` in its first role, it has `ψ_A − v_A` in its
//! second, and since phases only matter modulo `L`, `ψ_A − v_A ≡ ψ_A − ρ_A` with the *residual*
//! `ρ_A = v_A − (nearest lattice vector to v_A)`. So all four patches of every tile can be in
//! phase only when both translation vectors are lattice vectors (`ρ_A = ρ_B = 0`); otherwise some
//! cuts join content `|ρ|` pixels out of phase, whatever the patches are. The residual
//! ([`Alignment::residual`], `diagnostics.align.phase_residual_px`) is what a user reads to pick a
//! tile size ([`suggest`] lists good ones): for the lattice `(27, 0), (0, 26)`, Wang tile 54 leaves
//! 2 px, tile 64 leaves 12. It is measured on the integer lattice; a sample's real period can be
//! fractional (see below), so two sizes with equal residual can differ in practice.
//!
//! With the offset `δ = ψ_A − ψ_B` between the classes, the four cuts around a tile see the phase
//! errors (Wang, cuts N|E, E|S, S|W, W|N) `δ + ρ_B, ρ_A − ρ_B − δ, δ − ρ_A, −δ`, and (RW, strips
//! B1|B2, B2|B3, B3|B4, B4|B1) `δ, ρ_A − δ, δ − ρ_A + ρ_B, −δ − ρ_B` (the RW centre also joins the
//! diagonal pairs B1|B3 and B2|B4, whose errors are `ρ_A` and `ρ_B` whatever `δ`). The sum of the
//! squared errors is least at `δ = (ρ_A − ρ_B)/2` for both (`A` = N/S or "/", `B` = E/W or
//! "\"); [`best_offset`] takes the integer `δ` next to it with the smallest largest error. With
//! `ρ = 0` it is `δ = 0`: every patch in phase with the first.
//!
//! Placement: the first patch (Wang `DN[0]`, RW `PA[0]`) is drawn at random as in the faithful
//! mode; every other patch goes to a lattice translate of its ideal position `ψ + c` (`ψ` its
//! class's phase, `c` its first role's anchor), drawn from the same stream among the translates
//! whose patch fits in the sample and lie within two (longer) basis vectors of the ideal position,
//! preferring positions no other patch uses. If some patch has no translate in the sample, the
//! first patch is drawn again (up to [`FIRST_DRAWS`] times).
//!
//! Real samples are only near-regular: the extracted lattice is an integer approximation of a
//! period that also varies across the sample (on `metal_tread_studs` `(27, 0), (0, 26)` for
//! a local period of 25–27 px), so a translate a few cells away can be several pixels out of
//! phase, and the real residual of a translation vector is not the integer one. So each
//! class-B patch, and then the second class-A patch, is [`refine`]d: moved by at most a fifth of
//! the shortest lattice vector to where its overlap error against the other class's patches, in
//! every pair of roles that meet in a tile, is least. On an exactly periodic sample with zero
//! residual the translate itself has zero error and is kept, so the output is exactly in phase.
//! `patch_candidates` works on top: each candidate is another random first patch.

use crate::image::RgbImage;
use crate::synth::error::SynthError;
use crate::synth::lattice::{GivenVectors, LatticeOptions, extract};
use crate::synth::params::ParamError;
use crate::synth::rng::Stream;

pub type V = (i64, i64);

fn cross(a: V, b: V) -> i64 {
    a.0 * b.1 - a.1 * b.0
}
fn dot(a: V, b: V) -> i64 {
    a.0 * b.0 + a.1 * b.1
}
fn sub(a: V, b: V) -> V {
    (a.0 - b.0, a.1 - b.1)
}
/// Euclidean length in pixels.
pub fn norm(a: V) -> f64 {
    (dot(a, a) as f64).sqrt()
}

crate::choice! {
    /// The `align` parameter of both tile methods.
    pub enum Align {
        /// The four patches at independent random positions (the paper).
        None = "none",
        /// The first patch at random, the others at lattice translates of their in-phase positions.
        Lattice = "lattice",
        /// `lattice` when the sample has one (or the job gives `t1_x..t2_y`), `none` otherwise.
        Auto = "auto",
    }
}

/// What `align` resolved to for a job, for `diagnostics.align_choice`: `auto` is a decision the
/// reader of the manifest should be able to see.
pub fn choice_record(mode: Align, chosen: Option<&Alignment>) -> serde_json::Value {
    let how = match (mode, chosen) {
        (Align::Auto, Some(a)) => format!("auto: lattice ({})", a.source),
        (Align::Auto, None) => "auto: none (no lattice found in the sample)".to_string(),
        (_, Some(a)) => format!("lattice ({})", a.source),
        (_, None) => "none".to_string(),
    };
    serde_json::Value::String(how)
}

/// The sample lattice used to align the patches.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Alignment {
    /// The lattice vectors as given by the job or found by [`crate::synth::lattice::extract`].
    pub t1: V,
    pub t2: V,
    /// `"given"` or `"extracted"`.
    pub source: &'static str,
    /// A Lagrange–Gauss reduced basis of the same lattice (nearest-vector searches need one).
    reduced: (V, V),
}

impl Alignment {
    /// From explicit vectors (`Err` when they do not span a lattice).
    pub fn new(t1: V, t2: V, source: &'static str) -> Result<Alignment, SynthError> {
        if cross(t1, t2) == 0 {
            return Err(SynthError::Failed(format!("t1 = {t1:?} and t2 = {t2:?} are parallel (or zero): they must span a lattice")));
        }
        let (mut a, mut b) = (t1, t2);
        loop {
            if dot(a, a) > dot(b, b) {
                std::mem::swap(&mut a, &mut b);
            }
            let mu = (dot(a, b) as f64 / dot(a, a) as f64).round() as i64;
            let shorter = (b.0 - mu * a.0, b.1 - mu * a.1);
            if mu == 0 || dot(shorter, shorter) >= dot(b, b) {
                break;
            }
            b = shorter;
        }
        Ok(Alignment { t1, t2, source, reduced: (a, b) })
    }

    /// For a job's `align` and `t1_x..t2_y`: `None` for `align = "none"`; the given `t1, t2`, or
    /// (none given) the lattice extracted from the sample — which `lattice` requires and `auto`
    /// uses only when there is one.
    pub fn for_job(mode: Align, given: Option<GivenVectors>, sample: &RgbImage) -> Result<Option<Alignment>, SynthError> {
        if mode == Align::None {
            return Ok(None);
        }
        if let Some(v) = given {
            Alignment::new(v.t1, v.t2, "given").map(Some)
        } else if mode == Align::Auto {
            // No lattice is not an error here: the sample simply gets the paper's random cuts.
            Ok(extract(sample, &LatticeOptions::default()).ok().and_then(|l| Alignment::new(l.t1, l.t2, "extracted").ok()))
        } else {
            let l = extract(sample, &LatticeOptions::default()).map_err(|e| {
                let e = e.to_string();
                let why = e.strip_prefix("no lattice found; give t1/t2").unwrap_or(&e).trim();
                SynthError::Sample(format!(
                    "align = \"lattice\": no lattice found in the sample; give t1_x..t2_y or use align = \"none\"{}",
                    if why.is_empty() { String::new() } else { format!(" {why}") }
                ))
            })?;
            Alignment::new(l.t1, l.t2, "extracted").map(Some)
        }
    }

    /// Real lattice coordinates `(α, β)` of `v = α·t1 + β·t2` in the reduced basis.
    fn coords(&self, v: V) -> (f64, f64) {
        let (a, b) = self.reduced;
        let d = cross(a, b) as f64;
        (cross(v, b) as f64 / d, cross(a, v) as f64 / d)
    }

    /// The lattice vector nearest to `v` (ties to the smallest coefficients, lexicographically).
    pub fn nearest(&self, v: V) -> V {
        let (a, b) = self.reduced;
        let (al, be) = self.coords(v);
        let mut best = (i64::MAX, (0i64, 0i64), (0i64, 0i64));
        for i in al.floor() as i64 - 1..=al.ceil() as i64 + 1 {
            for j in be.floor() as i64 - 1..=be.ceil() as i64 + 1 {
                let l = (i * a.0 + j * b.0, i * a.1 + j * b.1);
                let e = sub(v, l);
                let key = (dot(e, e), (i, j), l);
                if (key.0, key.1) < (best.0, best.1) {
                    best = key;
                }
            }
        }
        best.2
    }

    /// The length of the lattice's shortest vector, in pixels.
    pub fn shortest(&self) -> f64 {
        norm(self.reduced.0)
    }

    /// `v` minus its nearest lattice vector: how far out of phase `v` puts a pattern.
    pub fn residual(&self, v: V) -> V {
        sub(v, self.nearest(v))
    }

    /// Every `p0 + lattice vector` inside the rectangle `lo ..= hi`, in row-major order.
    pub fn translates(&self, p0: V, lo: V, hi: V) -> Vec<V> {
        let (a, b) = self.reduced;
        let corners = [lo, (hi.0, lo.1), (lo.0, hi.1), hi].map(|c| self.coords(sub(c, p0)));
        let amin = corners.iter().map(|c| c.0).fold(f64::INFINITY, f64::min).floor() as i64;
        let amax = corners.iter().map(|c| c.0).fold(f64::NEG_INFINITY, f64::max).ceil() as i64;
        let bmin = corners.iter().map(|c| c.1).fold(f64::INFINITY, f64::min).floor() as i64;
        let bmax = corners.iter().map(|c| c.1).fold(f64::NEG_INFINITY, f64::max).ceil() as i64;
        let mut out = Vec::new();
        for i in amin..=amax {
            for j in bmin..=bmax {
                let p = (p0.0 + i * a.0 + j * b.0, p0.1 + i * a.1 + j * b.1);
                if p.0 >= lo.0 && p.0 <= hi.0 && p.1 >= lo.1 && p.1 <= hi.1 {
                    out.push(p);
                }
            }
        }
        out.sort_by_key(|p| (p.1, p.0));
        out
    }

    /// The lattice translates of `ideal` inside `lo ..= hi`, nearest first (ties by row, then
    /// column), and how many of them are *near* (within two longer basis vectors; at least one),
    /// the ones [`Alignment::place`] and [`Alignment::place_apart`] draw from. `Err` when none fits.
    fn by_distance(&self, ideal: V, lo: V, hi: V) -> Result<(Vec<V>, usize), SynthError> {
        let mut all = self.translates(ideal, lo, hi);
        if all.is_empty() {
            return Err(SynthError::Failed(format!("no lattice translate fits in the sample (patch positions {lo:?}..={hi:?})")));
        }
        let d2 = |p: &V| dot(sub(*p, ideal), sub(*p, ideal));
        let reach = 4 * dot(self.reduced.1, self.reduced.1);
        all.sort_by_key(|p| (d2(p), p.1, p.0));
        let near = all.iter().take_while(|p| d2(p) <= reach).count().max(1);
        Ok((all, near))
    }

    /// A lattice translate of `ideal` inside `lo ..= hi`, drawn from `st` (one `below` draw) among
    /// the *near* ones not in `used` (at most two longer basis vectors from `ideal`, so that the
    /// lattice's approximation error, which grows with distance, stays within [`refine`]'s
    /// reach). When none is, the nearest unused one; when all are used, any near one. `Err` when
    /// none fits.
    pub fn place(&self, st: &mut Stream, ideal: V, lo: V, hi: V, used: &[V]) -> Result<V, SynthError> {
        let (all, near) = self.by_distance(ideal, lo, hi)?;
        let unused = |p: &&V| !used.contains(p);
        let mut pool: Vec<V> = all[..near].iter().filter(unused).copied().collect();
        if pool.is_empty() {
            pool = all.iter().find(unused).map_or_else(|| all[..near].to_vec(), |&p| vec![p]);
        }
        pool.sort_by_key(|p| (p.1, p.0));
        Ok(pool[st.below(pool.len() as u64) as usize])
    }

    /// [`Alignment::place`] for patches of `side` pixels that should share as little of the
    /// sample as they can: among the near translates not in `used`, those whose squares overlap
    /// the `used` ones' least (summed overlap area), one drawn from `st` (one `below` draw). When
    /// no near translate is unused, as [`Alignment::place`]: on tiles_terracotta only two
    /// translates fit, both taken by the first class, and the second class's patches share a
    /// place with one of them; spreading them over both anyway repeated less (1.44 -> 1.15 times
    /// quilting's with RW's defaults at 512²) but joined terracotta tiles whose grout differs, and
    /// the seams showed as grout lines that jog or double (tiles/rw_tiles_tiles_terracotta_aligned).
    pub fn place_apart(&self, st: &mut Stream, ideal: V, lo: V, hi: V, used: &[V], side: i64) -> Result<V, SynthError> {
        let (all, near) = self.by_distance(ideal, lo, hi)?;
        let pool: Vec<V> = all[..near].iter().filter(|p| !used.contains(p)).copied().collect();
        if pool.is_empty() {
            return self.place(st, ideal, lo, hi, used);
        }
        let shared = |p: &V| -> i64 { used.iter().map(|u| (side - (p.0 - u.0).abs()).max(0) * (side - (p.1 - u.1).abs()).max(0)).sum() };
        let least = pool.iter().map(shared).min().expect("a translate");
        let mut pool: Vec<V> = pool.into_iter().filter(|p| shared(p) == least).collect();
        pool.sort_by_key(|p| (p.1, p.0));
        Ok(pool[st.below(pool.len() as u64) as usize])
    }

    /// `k` translates of each of a tile method's two patch classes: the first class at `first`
    /// and `k − 1` lattice translates of it; the second at translates of its in-phase position
    /// `ideal_second`, each refined against the first class over `overlaps`; then the first
    /// class's added ones refined against the second. What both tile methods place.
    ///
    /// With `apart` (the patches' side), each added patch is placed by [`Alignment::place_apart`]
    /// against every patch placed before it, as drawn and as refined: without it (Wang tiles), a
    /// second-class translate may be drawn where an earlier one was drawn and refine to the same
    /// place, and with two colours on a brick wall the RW sets' two `PB` were one patch (issue
    /// #30: city_bricks, stk_generic_brickRoad_a, bricks_gray, tiles_terracotta).
    #[allow(clippy::too_many_arguments)]
    pub fn place_classes(
        &self,
        sample: &RgbImage,
        st: &mut Stream,
        first: V,
        ideal_second: V,
        (lo, hi): (V, V),
        radius: i64,
        overlaps: &[Overlap],
        k: usize,
        apart: Option<i64>,
    ) -> Result<(Vec<(u32, u32)>, Vec<(u32, u32)>), SynthError> {
        let mut a = vec![first];
        for _ in 1..k {
            a.push(match apart {
                None => self.place(st, first, lo, hi, &a)?,
                Some(side) => self.place_apart(st, first, lo, hi, &a, side)?,
            });
        }
        let fit = |p: V| refine(p, lo, hi, radius, |q| overlap_error(sample, q, &a, overlaps, true));
        let mut b: Vec<V> = Vec::with_capacity(k);
        let mut drawn: Vec<V> = Vec::with_capacity(k);
        for _ in 0..k {
            let mut used: Vec<V> = a.iter().chain(&b).copied().collect();
            let p = match apart {
                None => self.place(st, ideal_second, lo, hi, &used)?,
                Some(side) => {
                    used.extend(&drawn);
                    self.place_apart(st, ideal_second, lo, hi, &used, side)?
                }
            };
            drawn.push(p);
            b.push(fit(p));
        }
        for p in &mut a[1..] {
            *p = refine(*p, lo, hi, radius, |q| overlap_error(sample, q, &b, overlaps, false));
        }
        let u = |p: &V| (p.0 as u32, p.1 as u32);
        Ok((a.iter().map(u).collect(), b.iter().map(u).collect()))
    }
}

/// How many first patches [`first_fitting`] draws before giving up.
pub const FIRST_DRAWS: usize = 1000;

/// Draws first patches with `attempt` until one lets every other patch sit at a lattice translate
/// inside the sample (on a sample only a little larger than the patches, some first positions
/// leave another patch no translate): the first success, or a clear error after [`FIRST_DRAWS`].
pub fn first_fitting<T>(al: &Alignment, mut attempt: impl FnMut() -> Result<T, SynthError>) -> Result<T, SynthError> {
    let mut last = String::new();
    for _ in 0..FIRST_DRAWS {
        match attempt() {
            Ok(v) => return Ok(v),
            Err(e) => last = e.to_string(),
        }
    }
    Err(SynthError::Failed(format!(
        "align = \"lattice\": with the lattice t1 = {:?}, t2 = {:?} no first patch of {FIRST_DRAWS} drawn lets the other patches sit in phase inside the sample ({last}); use a smaller tile or overlap, or align = \"none\"",
        al.t1, al.t2
    )))
}

/// How far [`refine`] moves a lattice translate: a fifth of the shortest lattice vector, at least
/// 2 pixels (well under the half-cell distance at which another texel would match).
pub fn refine_radius(al: &Alignment) -> i64 {
    ((norm(al.reduced.0) / 5.0).round() as i64).max(2)
}

/// Corrects a lattice translate for the sample not being exactly periodic on the integer lattice:
/// the extracted lattice is an integer approximation of the period (on `metal_tread_studs`,
/// `(27, 0), (0, 26)` for a local period of 25–27 px), and a patch's two roles are a real
/// translation vector apart, whose real residual the integer lattice does not know. Among the
/// positions `q` within `radius` of `p` (and inside `lo ..= hi`), returns the one with the
/// smallest `cost(q) = (error, pixels)` as a mean (the overlap error against the patches already
/// placed, in every role where they meet), ties to the smaller shift, then row-major.
pub fn refine(p: V, lo: V, hi: V, radius: i64, cost: impl Fn(V) -> (u64, u64)) -> V {
    // (error, pixels), tie key, position.
    type Best = ((u64, u64), (i64, i64, i64), V);
    let mut best: Option<Best> = None;
    for dy in -radius..=radius {
        for dx in -radius..=radius {
            let q = (p.0 + dx, p.1 + dy);
            if q.0 < lo.0 || q.0 > hi.0 || q.1 < lo.1 || q.1 > hi.1 {
                continue;
            }
            let (e, n) = cost(q);
            let n = n.max(1);
            let tie = (dx * dx + dy * dy, dy, dx);
            let better = match &best {
                None => true,
                Some(((be, bn), bt, _)) => (e as u128 * *bn as u128, tie) < (*be as u128 * n as u128, *bt),
            };
            if better {
                best = Some(((e, n), tie, q));
            }
        }
    }
    best.map_or(p, |b| b.2)
}

/// Where a class-B role and a class-A role of a tile overlap: the two anchors (tile coordinates)
/// and the tile pixels covered by both patches, where a cut between them can run.
pub struct Overlap {
    pub anchors: (V, V),
    pub pixels: Vec<V>,
}

/// The overlap error (squared RGB distance, summed, and the pixel count) of a patch at `q` against
/// the `partners` in every role pair of `overlaps`: the patch in the class-B role when `class_b`,
/// else in the class-A role. Positions must keep every patch inside the sample.
pub fn overlap_error(sample: &RgbImage, q: V, partners: &[V], overlaps: &[Overlap], class_b: bool) -> (u64, u64) {
    let (mut err, mut count) = (0u64, 0u64);
    for o in overlaps {
        let (own, other) = if class_b { o.anchors } else { (o.anchors.1, o.anchors.0) };
        for &d in partners {
            for &(x, y) in &o.pixels {
                let a = sample.get((q.0 - own.0 + x) as u32, (q.1 - own.1 + y) as u32);
                let b = sample.get((d.0 - other.0 + x) as u32, (d.1 - other.1 + y) as u32);
                err += crate::synth::primitives::overlap::pixel_error(a, b) as u64;
                count += 1;
            }
        }
    }
    (err, count)
}

/// The integer class offset `δ` next to the real optimum `centre` whose phase errors (from
/// `errors(δ)`) have the smallest largest length, then the smallest sum of squares.
pub fn best_offset(centre: (f64, f64), errors: impl Fn(V) -> Vec<V>) -> V {
    let xs = [centre.0.floor() as i64, centre.0.ceil() as i64];
    let ys = [centre.1.floor() as i64, centre.1.ceil() as i64];
    let mut best: Option<((i64, i64, V), V)> = None;
    for &x in &xs {
        for &y in &ys {
            let e = errors((x, y));
            let key = (e.iter().map(|&v| dot(v, v)).max().unwrap_or(0), e.iter().map(|&v| dot(v, v)).sum::<i64>(), (x, y));
            if best.as_ref().is_none_or(|b| key < b.0) {
                best = Some((key, (x, y)));
            }
        }
    }
    best.expect("four candidates").1
}

/// The phase residual of a tile size: the larger of its two translation vectors' residuals.
pub fn residual_px(al: &Alignment, vectors: [V; 2]) -> f64 {
    vectors.iter().map(|&v| norm(al.residual(v))).fold(0.0, f64::max)
}

/// Up to `n` tile sizes from `sizes` with the smallest phase residual (ties to the size closest to
/// `current`, then the smaller): `(tile, residual in px)`.
pub fn suggest(
    al: &Alignment,
    sizes: impl Iterator<Item = i64>,
    vectors: impl Fn(i64) -> [V; 2],
    current: i64,
    n: usize,
) -> Vec<(i64, f64)> {
    let mut all: Vec<(i64, f64)> = sizes.map(|t| (t, residual_px(al, vectors(t)))).collect();
    all.sort_by(|a, b| a.1.partial_cmp(&b.1).unwrap().then((a.0 - current).abs().cmp(&(b.0 - current).abs())).then(a.0.cmp(&b.0)));
    all.truncate(n);
    all
}

/// The word of `tile = "auto"` (the default of both tile methods).
pub const AUTO_TILE: &str = "auto";

/// The size `tile = "auto"` uses when nothing calls for another: the paper's 64.
pub const FALLBACK_TILE: i64 = 64;

/// The smallest size `tile = "auto"` picks: smaller tiles hold too little of a texel to keep
/// the tiling's variety (a 26 px tile in phase with a 26 px lattice is one texel per tile).
pub const AUTO_MIN_TILE: i64 = 32;

/// How many texels (the longer lattice vector) a tile's shorter translation should span when the
/// sample has room for such tiles. At about one texel per tile an aligned tiling repeats a few
/// texels in a visibly regular pattern (a roof of identical slates, a brick road of one motif);
/// from two on it keeps the sample's variety.
pub const AUTO_MIN_TEXELS: f64 = 2.0;

/// Aligned tiles look right only when the tiles' translation vectors are (nearly) lattice
/// vectors: a phase residual above this fraction of the shorter lattice vector cuts texels apart
/// (`texsyn advise` warns; `tile = "auto"` does not pick such a size).
pub const PHASE_TOLERANCE: f64 = 0.2;

/// The phase residual up to which a tile size counts as in phase with `al`
/// ([`PHASE_TOLERANCE`] of its shortest vector).
pub fn in_phase_px(al: &Alignment) -> f64 {
    PHASE_TOLERANCE * norm(al.reduced.0)
}

/// The `tile` parameter's range (`8..=4096`).
pub const TILE_RANGE: (i64, i64) = (8, 4096);

/// What a tile set of more than two colours asks of `tile = "auto"`: sizes whose patches leave the
/// sample room for `need` colours (the `colors` given, else 2), and among them the ones with room
/// for most of `want` (what `colors = "auto"` aims at); `room(t)` is the most colours the sample
/// holds with size-`t` tiles.
pub struct ColorRoom<'a> {
    pub need: u32,
    pub want: u32,
    pub room: &'a dyn Fn(i64) -> u32,
}

/// What `tile = "auto"` resolved to for a job: the size and, for `diagnostics.tile_choice`, why.
#[derive(Clone, Debug, PartialEq)]
pub struct TileChoice {
    pub tile: i64,
    pub record: serde_json::Value,
}

/// The tile size of `tile = "auto"` (in phase with the lattice when the tiles are aligned to one).
///
/// `sizes` are the method's valid tile sizes for its overlap (even, room for the overlap),
/// `patch(t)` the side of the square of sample pixels one patch of a size-`t` tile reads, and
/// `vectors(t)` its tile translation vectors. With a lattice, the candidates are the sizes from
/// [`AUTO_MIN_TILE`] whose patch fits in the sample with a lattice cell to spare (so every patch
/// has lattice translates to be placed at), narrowed to those whose translations span
/// [`AUTO_MIN_TEXELS`] texels when any of these is in phase, and the choice is [`suggest`]'s first (the smallest
/// phase residual, ties to the size nearest [`FALLBACK_TILE`]) — the size `texsyn advise` and
/// `diagnostics.align.suggested_tiles` name, within these bounds — when it is in phase (residual at
/// most [`in_phase_px`]). Without a lattice, or when no candidate fits or is in phase, it is
/// [`FALLBACK_TILE`]. `wrap` (a tileable output's size) keeps only the sizes
/// that divide it; without a lattice that is the dividing size nearest [`FALLBACK_TILE`], and when
/// none divides, [`FALLBACK_TILE`] (the method's tileable check then refuses, naming it).
/// `colors` (a set of more than two colours, [`ColorRoom`]) keeps only the sizes with room for its
/// `need`, and without an in-phase size takes the size nearest [`FALLBACK_TILE`] among those with
/// room for the most of its `want`: on a 256² sample Wang tiles of 64 leave room for 4 colours,
/// of 56 for 8.
pub fn auto_tile(
    al: Option<&Alignment>,
    sample: (u32, u32),
    sizes: impl Iterator<Item = i64>,
    patch: impl Fn(i64) -> i64,
    vectors: fn(i64) -> [V; 2],
    wrap: Option<(u32, u32)>,
    colors: Option<ColorRoom>,
) -> TileChoice {
    let (sw, sh) = (i64::from(sample.0), i64::from(sample.1));
    let divides = |t: i64| wrap.is_none_or(|(w, h)| i64::from(w) % t == 0 && i64::from(h) % t == 0);
    let has_room = |t: i64| colors.as_ref().is_none_or(|c| (c.room)(t) >= c.need);
    let pool: Vec<i64> = sizes.filter(|&t| (AUTO_MIN_TILE..=TILE_RANGE.1).contains(&t) && patch(t) <= sw.min(sh) && has_room(t)).collect();
    let dividing: Vec<i64> = pool.iter().copied().filter(|&t| divides(t)).collect();
    // A tileable output that no size divides is fitted ([`fit::Fit`]): the sizes that change the
    // fewest of its columns and rows, or any within [`fit::AUTO_FIT_TOLERANCE`] of them.
    let fitted = match wrap {
        Some(w) if dividing.is_empty() => {
            let usable: Vec<i64> =
                pool.iter().copied().filter(|&t| super::fit::fits(w.0, t as u32) && super::fit::fits(w.1, t as u32)).collect();
            let cost = |t: i64| super::fit::cost2(w, t as u32);
            let least = usable.iter().map(|&t| cost(t)).fold(f64::INFINITY, f64::min);
            Some(usable.iter().copied().filter(|&t| cost(t) <= least.max(super::fit::AUTO_FIT_TOLERANCE)).collect::<Vec<i64>>())
        }
        _ => None,
    };
    let is_fitted = fitted.is_some();
    let sizes = fitted.unwrap_or(dividing);
    let r3 = |x: f64| (x * 1000.0).round() / 1000.0;
    let wrapping = match wrap {
        Some(_) if is_fitted => " fitting the tileable output (none divides it)",
        Some(_) => " dividing the tileable output",
        None => "",
    };
    if let Some(al) = al {
        let (a, b) = al.reduced;
        let (mx, my) = (a.0.abs() + b.0.abs(), a.1.abs() + b.1.abs());
        let fit: Vec<i64> = sizes.iter().copied().filter(|&t| patch(t) + mx <= sw && patch(t) + my <= sh).collect();
        // Prefer tiles that span a few texels: when the sample has room for them, smaller sizes
        // are left out even if they are in phase.
        let texel = norm(a).max(norm(b));
        let spans = |t: i64| vectors(t).iter().map(|&v| norm(v)).fold(f64::INFINITY, f64::min) >= AUTO_MIN_TEXELS * texel;
        let roomy: Vec<i64> = fit.iter().copied().filter(|&t| spans(t)).collect();
        let in_phase =
            |c: &[i64]| suggest(al, c.iter().copied(), vectors, FALLBACK_TILE, 1).first().copied().filter(|b| b.1 <= in_phase_px(al));
        let best = in_phase(&roomy).or_else(|| in_phase(&fit));
        if let Some((tile, residual)) = best {
            let fallback = residual_px(al, vectors(FALLBACK_TILE));
            let how = format!(
                "auto: {tile}, the size{wrapping} that misses the lattice t1 = {:?}, t2 = {:?} least ({:.1} px; {FALLBACK_TILE} would miss it by {:.1} px)",
                al.t1, al.t2, residual, fallback
            );
            return TileChoice { tile, record: serde_json::json!({ "tile": tile, "residual_px": r3(residual), "how": how }) };
        }
    }
    let why = match al {
        Some(_) if sizes.is_empty() => format!("no size from {AUTO_MIN_TILE}{wrapping} fits in the sample"),
        Some(al) => format!(
            "no size from {AUTO_MIN_TILE}{wrapping} that fits in the sample with a lattice cell to spare misses the lattice t1 = {:?}, t2 = {:?} by at most {:.1} px",
            al.t1,
            al.t2,
            in_phase_px(al)
        ),
        None => "no lattice alignment".to_string(),
    };
    let many = colors.as_ref().filter(|c| c.want.max(c.need) > 2 && !sizes.is_empty());
    if let Some(c) = many {
        // More colours than two: the size nearest FALLBACK_TILE among those with room for the
        // most of the colours wanted (2K separate patches).
        let k = |t: i64| c.want.max(c.need).min((c.room)(t));
        let tile = sizes.iter().copied().min_by_key(|&t| (std::cmp::Reverse(k(t)), (t - FALLBACK_TILE).abs(), t)).expect("sizes");
        let how = format!(
            "auto: {tile}, the size{wrapping} nearest {FALLBACK_TILE} whose patches leave the sample room for {} colours ({why})",
            k(tile)
        );
        return TileChoice { tile, record: serde_json::json!({ "tile": tile, "how": how }) };
    }
    let tile = match wrap {
        Some(_) if is_fitted || !divides(FALLBACK_TILE) => {
            sizes.iter().copied().min_by_key(|&t| ((t - FALLBACK_TILE).abs(), t)).unwrap_or(FALLBACK_TILE)
        }
        _ => FALLBACK_TILE,
    };
    let how = if is_fitted {
        format!(
            "auto: {tile}, the size nearest {FALLBACK_TILE} among those{wrapping} with the fewest columns and rows left out or repeated ({why})"
        )
    } else if tile == FALLBACK_TILE {
        format!("auto: {tile} ({why})")
    } else {
        format!("auto: {tile}, the size nearest {FALLBACK_TILE} that divides the tileable output ({why})")
    };
    TileChoice { tile, record: serde_json::json!({ "tile": tile, "how": how }) }
}

/// Whether `tile = "auto"` can make a tileable `output` wrap: some size from [`AUTO_MIN_TILE`] whose
/// `patch` fits in the sample divides it (which one, the lattice decides: [`auto_tile`]); the
/// refusal names the sizes tried.
pub fn auto_tileable(
    method: &str,
    sample: (u32, u32),
    sizes: impl Iterator<Item = i64>,
    patch: impl Fn(i64) -> i64,
    output: (u32, u32),
) -> Result<(), String> {
    let side = i64::from(sample.0.min(sample.1));
    let fit: Vec<i64> = sizes.filter(|&t| (AUTO_MIN_TILE..=TILE_RANGE.1).contains(&t) && patch(t) <= side).collect();
    let fits = |t: i64| super::fit::fits(output.0, t as u32) && super::fit::fits(output.1, t as u32);
    if fit.iter().any(|&t| fits(t)) {
        return Ok(());
    }
    let smallest = fit.first().copied().unwrap_or(AUTO_MIN_TILE);
    let least = |v: u32| if super::fit::fits(v, smallest as u32) { i64::from(v) } else { 2 * smallest };
    Err(format!(
        "tileable {method} needs at least two tiles each way (or exactly one), and with tile = \"auto\" the smallest tile size that fits this sample is {smallest} ({}..={}), {} pixels a side; {}x{} would work, or set a smaller tile",
        smallest,
        fit.last().copied().unwrap_or(AUTO_MIN_TILE),
        2 * smallest,
        least(output.0),
        least(output.1)
    ))
}

/// The `diagnostics.align` record: the lattice, each tile translation vector's residual, the class
/// offset, each cut's phase error and suggested tile sizes.
pub fn diagnostics(al: &Alignment, vectors: [V; 2], offset: V, errors: &[(&str, V)], suggested: &[(i64, f64)]) -> serde_json::Value {
    let r3 = |x: f64| (x * 1000.0).round() / 1000.0;
    serde_json::json!({
        "mode": "lattice",
        "lattice": { "t1": [al.t1.0, al.t1.1], "t2": [al.t2.0, al.t2.1], "source": al.source },
        "translations": vectors.iter().map(|&v| {
            let l = al.nearest(v);
            let r = sub(v, l);
            serde_json::json!({ "vector": [v.0, v.1], "nearest_lattice_vector": [l.0, l.1], "residual": [r.0, r.1], "residual_px": r3(norm(r)) })
        }).collect::<Vec<_>>(),
        "phase_residual_px": r3(residual_px(al, vectors)),
        "class_offset": [offset.0, offset.1],
        "cut_phase_errors_px": errors.iter().map(|(k, v)| (k.to_string(), serde_json::json!(r3(norm(*v))))).collect::<serde_json::Map<_, _>>(),
        "suggested_tiles": suggested.iter().map(|&(t, r)| serde_json::json!({ "tile": t, "residual_px": r3(r) })).collect::<Vec<_>>(),
    })
}

/// Checks of `align` and `t1_x..t2_y` shared by both tile methods.
pub fn check(mode: Align, given: Option<GivenVectors>, sample: (u32, u32)) -> Vec<ParamError> {
    let mut errors = Vec::new();
    let Some(GivenVectors { t1, t2 }) = given else {
        return errors;
    };
    if mode == Align::None {
        errors.push(ParamError::new(
            "t1_x",
            "t1_x..t2_y are only used with align = \"lattice\" or \"auto\"; set align = \"lattice\" or remove them",
        ));
    }
    if cross(t1, t2) == 0 {
        errors.push(ParamError::new("t1_x", format!("t1 = {t1:?} and t2 = {t2:?} are parallel (or zero): they must span a lattice")));
    }
    if t1.0.abs() + t2.0.abs() > sample.0 as i64 || t1.1.abs() + t2.1.abs() > sample.1 as i64 {
        errors.push(ParamError::new(
            "t1_x",
            format!("a lattice cell spanned by t1 = {t1:?}, t2 = {t2:?} does not fit in the {}x{} sample", sample.0, sample.1),
        ));
    }
    errors
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_vectors_residuals_and_suggestions() {
        let al = Alignment::new((27, 0), (0, 26), "given").unwrap();
        assert_eq!(al.residual((54, 0)), (0, 0));
        assert_eq!(al.residual((0, 54)), (0, 2));
        assert_eq!(residual_px(&al, [(54, 0), (0, 54)]), 2.0);
        assert_eq!(residual_px(&al, [(64, 0), (0, 64)]), 12.0);
        // A skewed, unreduced basis of the lattice (16, 0), (8, 16).
        let sk = Alignment::new((16, 0), (40, 16), "given").unwrap();
        assert_eq!(sk.residual((0, 32)), (0, 0));
        assert_eq!(norm(sk.residual((0, 16))), 8.0);
        let s = suggest(&al, (8..=100).step_by(2), |t| [(t, 0), (0, t)], 64, 3);
        assert_eq!(s[0], (26, 1.0));
        assert!(s.iter().all(|&(_, r)| r <= 2.0), "{s:?}");
    }

    #[test]
    fn translates_stay_inside_and_are_congruent() {
        let al = Alignment::new((38, -24), (36, 24), "given").unwrap();
        let t = al.translates((500, -300), (10, 20), (150, 140));
        assert!(t.len() > 5);
        for &p in &t {
            assert!(p.0 >= 10 && p.0 <= 150 && p.1 >= 20 && p.1 <= 140);
            assert_eq!(al.residual(sub(p, (500, -300))), (0, 0));
        }
        let all = Alignment::new((38, -24), (36, 24), "given").unwrap().translates((0, 0), (-200, -200), (200, 200));
        assert!(all.contains(&(74, 0)) && all.contains(&(0, 0)));
    }

    #[test]
    fn patches_placed_apart_take_the_translate_that_overlaps_the_earlier_ones_least() {
        // Translates of (0, 0) on a 20-px square lattice within 0..=60: 16 places, those within
        // 40 px near. With 30-px patches at (0, 0) and (20, 20), the place drawn is one of the
        // near ones that overlap them least, whatever the seed.
        let al = Alignment::new((20, 0), (0, 20), "given").unwrap();
        let used = [(0, 0), (20, 20)];
        let shared = |p: V| -> i64 { used.iter().map(|u| (30 - (p.0 - u.0).abs()).max(0) * (30 - (p.1 - u.1).abs()).max(0)).sum() };
        for seed in 0..20 {
            let mut st = Stream::new(seed, "test");
            let p = al.place_apart(&mut st, (0, 0), (0, 0), (60, 60), &used, 30).unwrap();
            assert!(!used.contains(&p), "{p:?}");
            assert_eq!(al.residual(p), (0, 0));
            let near = al.translates((0, 0), (0, 0), (60, 60)).into_iter().filter(|q| !used.contains(q) && dot(*q, *q) <= 1600);
            let least = near.map(shared).min().unwrap();
            assert_eq!(shared(p), least, "{p:?}");
        }
        // Every translate used: as `place`, one of them.
        let mut st = Stream::new(1, "test");
        assert_eq!(al.place_apart(&mut st, (0, 0), (0, 0), (20, 0), &[(0, 0), (20, 0)], 30).map(|p| p.1), Ok(0));
        assert!(al.place_apart(&mut st, (0, 0), (3, 3), (5, 5), &[], 30).is_err());
    }

    #[test]
    fn no_fitting_translate_is_a_clear_error() {
        let al = Alignment::new((10, 0), (0, 10), "given").unwrap();
        let mut st = Stream::new(1, "test");
        assert!(al.place(&mut st, (0, 0), (3, 3), (5, 5), &[]).is_err());
        assert_eq!(al.place(&mut st, (0, 0), (3, 3), (12, 12), &[(10, 10)]), Ok((10, 10)));
        let e = first_fitting::<()>(&al, || Err(SynthError::Failed("no lattice translate fits".into()))).unwrap_err().to_string();
        assert!(e.contains("no first patch of 1000 drawn") && e.contains("use a smaller tile or overlap, or align = \"none\""), "{e}");
    }

    #[test]
    fn auto_tile_is_in_phase_bounded_and_divides_a_tileable_output() {
        let al = Alignment::new((27, 0), (0, 26), "given").unwrap();
        let wang = |t: i64| [(t, 0), (0, t)];
        let sizes = || (16..=4096).filter(|t| t % 2 == 0);
        let patch = |t: i64| t + 8;
        // 26 misses the lattice least (1 px) but is below the smallest automatic size.
        let c = auto_tile(Some(&al), (256, 256), sizes(), patch, wang, None, None);
        assert_eq!(c.tile, 54, "{}", c.record);
        assert_eq!(c.record["residual_px"], 2.0);
        assert!(c.record["how"].as_str().unwrap().contains("64 would miss it by 12.0 px"), "{}", c.record);
        // No lattice: the paper's 64; a sample too small for any in-phase size with a cell to spare: 64.
        assert_eq!(auto_tile(None, (256, 256), sizes(), patch, wang, None, None).tile, 64);
        let small = auto_tile(Some(&al), (60, 60), sizes(), patch, wang, None, None);
        assert_eq!(small.tile, 64);
        assert!(small.record.get("residual_px").is_none(), "{}", small.record);
        // A tileable 640x130 output: no even size from 32 divides both, so the sizes that fit
        // it changing at most 3 % of its columns and rows, the one nearest the lattice (130)…
        let w = auto_tile(Some(&al), (256, 256), sizes(), patch, wang, Some((640, 130)), None);
        assert!(crate::synth::methods::tiles::fit::cost2((640, 130), w.tile as u32) <= 0.03, "{}", w.record);
        assert_eq!(auto_tile(Some(&al), (256, 256), sizes(), patch, wang, Some((640, 128)), None).tile, 64);
        // …and 700x100 without a lattice: the divisor nearest 64.
        assert_eq!(auto_tile(None, (256, 256), sizes(), patch, wang, Some((700, 100)), None).tile, 50);
        // No size divides 701x701 or 1001x601: fitted, the sizes that change the fewest columns
        // and rows (or at most 3 % of them) nearest 64.
        assert_eq!(auto_tileable("wang-tiles", (256, 256), sizes(), patch, (701, 701)), Ok(()));
        let f = auto_tile(None, (256, 256), sizes(), patch, wang, Some((1001, 601)), None);
        assert!(crate::synth::methods::tiles::fit::cost2((1001, 601), f.tile as u32) <= 0.03, "{}", f.record);
        assert!(f.record["how"].as_str().unwrap().contains("fitting the tileable output"), "{}", f.record);
        // Below two tiles of the smallest size each way: refused, naming the size that works.
        let e = auto_tileable("wang-tiles", (256, 256), sizes(), patch, (47, 701)).unwrap_err();
        assert!(e.contains("64 pixels a side; 64x701 would work"), "{e}");
    }

    #[test]
    fn offset_splits_the_residual() {
        let d = best_offset((1.0, -1.0), |d| vec![d, (2 - d.0, 0 - d.1)]);
        assert_eq!(d, (1, -1));
        assert_eq!(best_offset((0.0, 0.0), |d| vec![d]), (0, 0));
    }
}
