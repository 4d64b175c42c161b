//! Where every output pixel comes from: a method's *placement*.
//!
//! Every method composes its output from sample pixels, copied (cuts, tiles, texels) or blended
//! (feathering). The placement makes that explicit, so that the same composition can be rendered
//! from any image of the sample's size, in that image's own precision and channel count: the
//! sample itself at 16 bits or in float (the main output of a 16-bit or EXR job), a normal map, a
//! gloss map (a material's companions), or later by `texsyn apply` from a saved source map.
//!
//! A pixel's placement is a *chain*: a base sample pixel it copies, then zero or more blend steps
//! `v ← (1 − a)·v + a·s` applied in order, each with a sample pixel `s` and a weight `a = num/den`.
//! A chain rather than a flat weighted sum because the methods blend step by step and round each
//! step to the output's precision (feathering an already feathered overlap); replaying the same
//! steps with the same rounding is what makes the 8-bit rendering equal, pixel for pixel, to the
//! image the method computed (`tests/it/placement.rs` proves it for every method). Weights are
//! stored as the integer ratio the methods compute them from, so a saved map replays exactly.

use crate::image::RgbImage;
use crate::image::io::{NativeImage, Samples};

/// The source index of an output pixel no sample pixel covers (rendered black).
pub const UNCOVERED: u32 = u32::MAX;
const NO_BLEND: u32 = u32::MAX;

/// One blend step: `v ← (1 − num/den)·v + (num/den)·sample[source]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Blend {
    /// Sample pixel index, `y · sample_width + x`.
    pub source: u32,
    pub num: u32,
    pub den: u32,
}

impl Blend {
    /// The weight of the new pixel, computed as the methods compute it (`num as f64 / den as f64`).
    #[inline]
    pub fn weight(&self) -> f64 {
        f64::from(self.num) / f64::from(self.den)
    }
}

#[derive(Clone, Copy, Debug)]
struct BlendEntry {
    /// The pixel's previous blend entry, or [`NO_BLEND`].
    prev: u32,
    blend: Blend,
}

/// How a rendered channel set is interpreted where pixels are blended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum MapKind {
    /// Values blend linearly (albedo, gloss, height, roughness…).
    #[default]
    Color,
    /// A tangent-space normal map, `n = 2v − 1` on unit scale in R, G, B: blended normals are
    /// renormalised to unit length (copied pixels are kept exactly).
    Normal,
}

impl MapKind {
    /// The name job files and `texsyn apply --kind` use.
    pub fn name(self) -> &'static str {
        match self {
            MapKind::Color => "color",
            MapKind::Normal => "normal",
        }
    }
    /// The kind called `name`, if any.
    pub fn from_name(name: &str) -> Option<MapKind> {
        [MapKind::Color, MapKind::Normal].into_iter().find(|k| k.name() == name)
    }
}

/// For each pixel of a `width × height` output, the sample pixels it is made of.
#[derive(Clone, Debug, PartialEq)]
pub struct Placement {
    width: u32,
    height: u32,
    sample_width: u32,
    sample_height: u32,
    /// Base source per pixel (row-major), [`UNCOVERED`] where none.
    source: Vec<u32>,
    /// Per pixel, the index of its latest blend entry or [`NO_BLEND`]; empty until the first blend
    /// (most methods never blend, and pay nothing for it).
    last_blend: Vec<u32>,
    blends: Vec<BlendEntry>,
}

impl PartialEq for BlendEntry {
    fn eq(&self, other: &Self) -> bool {
        self.prev == other.prev && self.blend == other.blend
    }
}

impl Placement {
    /// An output whose pixels are all uncovered.
    pub fn new(width: u32, height: u32, sample: (u32, u32)) -> Placement {
        Placement {
            width,
            height,
            sample_width: sample.0,
            sample_height: sample.1,
            source: vec![UNCOVERED; width as usize * height as usize],
            last_blend: Vec::new(),
            blends: Vec::new(),
        }
    }

    /// A copy-only placement from its source indices (row-major, [`UNCOVERED`] allowed).
    pub fn from_sources(width: u32, height: u32, sample: (u32, u32), source: Vec<u32>) -> Placement {
        assert_eq!(source.len(), width as usize * height as usize, "one source per pixel");
        Placement { width, height, sample_width: sample.0, sample_height: sample.1, source, last_blend: Vec::new(), blends: Vec::new() }
    }

    pub fn width(&self) -> u32 {
        self.width
    }
    pub fn height(&self) -> u32 {
        self.height
    }
    pub fn dimensions(&self) -> (u32, u32) {
        (self.width, self.height)
    }
    /// The size of the images it can be rendered from.
    pub fn sample_size(&self) -> (u32, u32) {
        (self.sample_width, self.sample_height)
    }

    #[inline]
    fn pixel(&self, x: u32, y: u32) -> usize {
        debug_assert!(x < self.width && y < self.height);
        y as usize * self.width as usize + x as usize
    }

    /// The sample index of sample pixel `(sx, sy)`.
    #[inline]
    pub fn index_of(&self, sx: u32, sy: u32) -> u32 {
        debug_assert!(sx < self.sample_width && sy < self.sample_height);
        sy * self.sample_width + sx
    }

    /// Output pixel `(x, y)` becomes a copy of sample pixel `(sx, sy)` (dropping any blends).
    #[inline]
    pub fn copy(&mut self, x: u32, y: u32, sx: u32, sy: u32) {
        let (i, s) = (self.pixel(x, y), self.index_of(sx, sy));
        self.source[i] = s;
        if !self.last_blend.is_empty() {
            self.last_blend[i] = NO_BLEND;
        }
    }

    /// Output pixel `(x, y)` takes the placement of another output pixel (a canvas copied onto
    /// itself, e.g. a texel extended from its neighbour).
    pub fn copy_pixel(&mut self, x: u32, y: u32, from: (u32, u32)) {
        let (i, j) = (self.pixel(x, y), self.pixel(from.0, from.1));
        self.source[i] = self.source[j];
        if !self.last_blend.is_empty() {
            // Blended pixels are re-linked by copying their chain's entries.
            let mut chain = Vec::new();
            let mut e = self.last_blend[j];
            while e != NO_BLEND {
                chain.push(self.blends[e as usize].blend);
                e = self.blends[e as usize].prev;
            }
            self.last_blend[i] = NO_BLEND;
            for b in chain.into_iter().rev() {
                self.push_blend(i, b);
            }
        }
    }

    /// Output pixel `(x, y)` is blended with sample pixel `(sx, sy)` at weight `num / den`.
    #[inline]
    pub fn blend(&mut self, x: u32, y: u32, sx: u32, sy: u32, num: u32, den: u32) {
        let (i, s) = (self.pixel(x, y), self.index_of(sx, sy));
        if self.last_blend.is_empty() {
            self.last_blend = vec![NO_BLEND; self.source.len()];
        }
        self.push_blend(i, Blend { source: s, num, den });
    }

    fn push_blend(&mut self, i: usize, blend: Blend) {
        let prev = self.last_blend[i];
        self.last_blend[i] = u32::try_from(self.blends.len()).expect("fewer than 2^32 blend steps");
        self.blends.push(BlendEntry { prev, blend });
    }

    /// The base source of pixel `(x, y)` ([`UNCOVERED`] where none).
    #[inline]
    pub fn source(&self, x: u32, y: u32) -> u32 {
        self.source[self.pixel(x, y)]
    }

    /// All base sources, row-major.
    pub fn sources(&self) -> &[u32] {
        &self.source
    }

    /// The blend steps of pixel `(x, y)`, in the order they apply.
    pub fn blends_at(&self, x: u32, y: u32) -> Vec<Blend> {
        self.chain(self.pixel(x, y))
    }

    fn chain(&self, i: usize) -> Vec<Blend> {
        let mut out = Vec::new();
        if self.last_blend.is_empty() {
            return out;
        }
        let mut e = self.last_blend[i];
        while e != NO_BLEND {
            out.push(self.blends[e as usize].blend);
            e = self.blends[e as usize].prev;
        }
        out.reverse();
        out
    }

    /// Whether any pixel is blended.
    pub fn has_blends(&self) -> bool {
        !self.last_blend.is_empty() && self.last_blend.iter().any(|&b| b != NO_BLEND)
    }

    /// The longest chain of blend steps of any pixel.
    pub fn max_blends(&self) -> usize {
        (0..self.source.len()).map(|i| self.chain(i).len()).max().unwrap_or(0)
    }

    /// The top-left `w × h` (how the canvas methods trim their canvas to the output).
    pub fn into_top_left(self, w: u32, h: u32) -> Placement {
        assert!(w <= self.width && h <= self.height, "crop outside the placement");
        if (w, h) == (self.width, self.height) {
            return self;
        }
        let mut out = Placement::new(w, h, self.sample_size());
        for y in 0..h {
            let (src, dst) = (self.pixel(0, y), y as usize * w as usize);
            out.source[dst..dst + w as usize].copy_from_slice(&self.source[src..src + w as usize]);
        }
        if !self.last_blend.is_empty() {
            for y in 0..h {
                for x in 0..w {
                    for b in self.chain(self.pixel(x, y)) {
                        if out.last_blend.is_empty() {
                            out.last_blend = vec![NO_BLEND; out.source.len()];
                        }
                        let i = out.pixel(x, y);
                        out.push_blend(i, b);
                    }
                }
            }
        }
        out
    }

    /// Renders over the 8-bit RGB image methods work on: must equal the method's own image.
    pub fn render_rgb8(&self, sample: &RgbImage) -> RgbImage {
        assert_eq!(sample.dimensions(), self.sample_size(), "placement rendered over an image of another size");
        let native = NativeImage::from_rgb8(sample);
        let out = self.render(&native, MapKind::Color);
        match out.samples {
            Samples::U8(v) => RgbImage::from_raw(self.width, self.height, v).expect("rendered size"),
            _ => unreachable!("8-bit in, 8-bit out"),
        }
    }

    /// Renders over `image` (which must have the sample's size), in its precision and channel
    /// count: copied pixels are exactly the image's; blended ones follow the chain, rounding each
    /// step to the nearest level (`floor(v + 0.5)`, clamped) for integer images and keeping float
    /// values as they are (no clamping: HDR and negative values survive).
    pub fn render(&self, image: &NativeImage, kind: MapKind) -> NativeImage {
        self.render_rows(image, kind, 0, self.height)
    }

    /// Rows `y0 .. y0 + rows` of [`Placement::render`].
    pub fn render_rows(&self, image: &NativeImage, kind: MapKind, y0: u32, rows: u32) -> NativeImage {
        assert_eq!((image.width, image.height), self.sample_size(), "placement rendered over an image of another size");
        let w = self.width as usize;
        let start = y0 as usize * w;
        let end = start + rows as usize * w;
        let blended = |i: usize| -> Vec<Blend> { self.chain(i) };
        let samples = render_pixels(image, kind, start..end, |i| self.source[i], blended);
        NativeImage { width: self.width, height: rows, channels: image.channels, samples }
    }
}

/// Renders output pixels `range` (row-major indices) from `image`: `source(i)` is a pixel's base,
/// `blends(i)` its chain. Shared by placements held whole and source rows rendered in strips.
pub fn render_pixels(
    image: &NativeImage,
    kind: MapKind,
    range: std::ops::Range<usize>,
    source: impl Fn(usize) -> u32,
    blends: impl Fn(usize) -> Vec<Blend>,
) -> Samples {
    let c = image.channels as usize;
    let n = range.len();
    match &image.samples {
        Samples::U8(v) => Samples::U8(render_int(v, c, n, range, &source, &blends, kind, 255.0)),
        Samples::U16(v) => Samples::U16(render_int(v, c, n, range, &source, &blends, kind, 65535.0)),
        Samples::F32(v) => {
            let mut out = vec![0f32; n * c];
            for (k, i) in range.enumerate() {
                let s = source(i);
                let px = &mut out[k * c..(k + 1) * c];
                if s == UNCOVERED {
                    continue;
                }
                px.copy_from_slice(&v[s as usize * c..(s as usize + 1) * c]);
                let chain = blends(i);
                if chain.is_empty() {
                    continue;
                }
                let mut acc: Vec<f64> = px.iter().map(|&p| f64::from(p)).collect();
                for b in &chain {
                    let a = b.weight();
                    let new = &v[b.source as usize * c..(b.source as usize + 1) * c];
                    for (o, &nv) in acc.iter_mut().zip(new) {
                        *o = (1.0 - a) * *o + a * f64::from(nv);
                    }
                    // Each step is stored at the image's precision, as an integer image rounds.
                    for o in acc.iter_mut() {
                        *o = f64::from(*o as f32);
                    }
                }
                if kind == MapKind::Normal && c >= 3 {
                    renormalise(&mut acc, 1.0);
                }
                for (p, a) in px.iter_mut().zip(&acc) {
                    *p = *a as f32;
                }
            }
            Samples::F32(out)
        }
    }
}

/// Integer sample types: `u8` and `u16`.
trait Level: Copy + Default {
    fn to_f64(self) -> f64;
    fn from_f64_rounded(v: f64, max: f64) -> Self;
}

impl Level for u8 {
    #[inline]
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
    #[inline]
    fn from_f64_rounded(v: f64, max: f64) -> u8 {
        (v + 0.5).floor().clamp(0.0, max) as u8
    }
}

impl Level for u16 {
    #[inline]
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
    #[inline]
    fn from_f64_rounded(v: f64, max: f64) -> u16 {
        (v + 0.5).floor().clamp(0.0, max) as u16
    }
}

#[allow(clippy::too_many_arguments)]
fn render_int<T: Level>(
    v: &[T],
    c: usize,
    n: usize,
    range: std::ops::Range<usize>,
    source: &impl Fn(usize) -> u32,
    blends: &impl Fn(usize) -> Vec<Blend>,
    kind: MapKind,
    max: f64,
) -> Vec<T> {
    let mut out = vec![T::default(); n * c];
    for (k, i) in range.enumerate() {
        let s = source(i);
        if s == UNCOVERED {
            continue;
        }
        let px = &mut out[k * c..(k + 1) * c];
        px.copy_from_slice(&v[s as usize * c..(s as usize + 1) * c]);
        let chain = blends(i);
        if chain.is_empty() {
            continue;
        }
        for b in &chain {
            let a = b.weight();
            let new = &v[b.source as usize * c..(b.source as usize + 1) * c];
            for (o, &nv) in px.iter_mut().zip(new) {
                // The same expression as `feather::blend`, so 8-bit renders equal the methods' images.
                *o = T::from_f64_rounded((1.0 - a) * o.to_f64() + a * nv.to_f64(), max);
            }
        }
        if kind == MapKind::Normal && c >= 3 {
            let mut acc: Vec<f64> = px.iter().map(|p| p.to_f64() / max).collect();
            renormalise(&mut acc, 1.0);
            for (p, a) in px.iter_mut().zip(&acc) {
                *p = T::from_f64_rounded(a * max, max);
            }
        }
    }
    out
}

/// Renormalises the normal encoded in the first three values (`n = 2v − 1`, unit scale `one`);
/// a zero vector stays as it is.
fn renormalise(px: &mut [f64], one: f64) {
    let n: Vec<f64> = px[..3].iter().map(|&v| 2.0 * v / one - 1.0).collect();
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    if len > 1e-12 {
        for k in 0..3 {
            px[k] = (n[k] / len + 1.0) / 2.0 * one;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::primitives::feather;

    fn sample() -> RgbImage {
        RgbImage::from_fn(4, 3, |x, y| [(x * 60) as u8, (y * 100) as u8, (x * y * 20) as u8])
    }

    #[test]
    fn copies_and_blends_replay_the_feather_arithmetic() {
        let s = sample();
        let mut p = Placement::new(3, 2, s.dimensions());
        p.copy(0, 0, 3, 2);
        p.copy(1, 0, 0, 0);
        p.blend(1, 0, 3, 1, 2, 5);
        p.blend(1, 0, 2, 2, 1, 3);
        p.copy(2, 1, 1, 1);
        let img = p.render_rgb8(&s);
        assert_eq!(img.get(0, 0), s.get(3, 2));
        let once = feather::blend(s.get(0, 0), s.get(3, 1), feather::new_weight(1, 4));
        assert_eq!(img.get(1, 0), feather::blend(once, s.get(2, 2), feather::new_weight(0, 2)));
        assert_eq!(img.get(2, 1), s.get(1, 1));
        assert_eq!(img.get(0, 1), [0, 0, 0], "uncovered is black");
        // A copy after blending drops the blends.
        p.copy(1, 0, 2, 0);
        assert_eq!(p.render_rgb8(&s).get(1, 0), s.get(2, 0));
        assert_eq!(p.max_blends(), 0);
    }

    #[test]
    fn sixteen_bit_and_float_keep_their_values_where_copied() {
        let mut p = Placement::new(2, 1, (2, 1));
        p.copy(0, 0, 1, 0);
        p.copy(1, 0, 0, 0);
        p.blend(1, 0, 1, 0, 1, 2);
        let img16 = NativeImage { width: 2, height: 1, channels: 1, samples: Samples::U16(vec![1001, 40_003]) };
        assert_eq!(p.render(&img16, MapKind::Color).samples, Samples::U16(vec![40_003, 20_502]));
        let f = NativeImage { width: 2, height: 1, channels: 1, samples: Samples::F32(vec![-0.5, 7.25]) };
        assert_eq!(p.render(&f, MapKind::Color).samples, Samples::F32(vec![7.25, 3.375]));
    }

    #[test]
    fn blended_normals_are_renormalised_and_copied_ones_kept() {
        // Two unit normals 90 degrees apart: their plain average is shorter than 1.
        let enc = |n: [f64; 3]| n.map(|v| ((v + 1.0) / 2.0 * 255.0).round() as u8);
        let a = enc([1.0, 0.0, 0.0]);
        let b = enc([0.0, 0.0, 1.0]);
        let img = NativeImage { width: 2, height: 1, channels: 3, samples: Samples::U8([a, b].concat()) };
        let mut p = Placement::new(2, 1, (2, 1));
        p.copy(0, 0, 0, 0);
        p.copy(1, 0, 0, 0);
        p.blend(1, 0, 1, 0, 1, 2);
        let Samples::U8(out) = p.render(&img, MapKind::Normal).samples else { unreachable!() };
        assert_eq!(&out[..3], &a);
        let n: Vec<f64> = out[3..].iter().map(|&v| v as f64 / 255.0 * 2.0 - 1.0).collect();
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        assert!((len - 1.0).abs() < 0.01, "renormalised, got length {len}");
        let Samples::U8(plain) = p.render(&img, MapKind::Color).samples else { unreachable!() };
        assert_ne!(&plain[3..], &out[3..], "colour maps are not renormalised");
    }

    #[test]
    fn crop_keeps_chains() {
        let s = sample();
        let mut p = Placement::new(4, 3, s.dimensions());
        for y in 0..3 {
            for x in 0..4 {
                p.copy(x, y, 3 - x, 2 - y);
            }
        }
        p.blend(1, 1, 0, 0, 1, 4);
        let full = p.render_rgb8(&s);
        let c = p.into_top_left(2, 2);
        assert_eq!(c.render_rgb8(&s), full.crop(0, 0, 2, 2));
        assert_eq!(c.blends_at(1, 1), vec![Blend { source: 0, num: 1, den: 4 }]);
    }
}
