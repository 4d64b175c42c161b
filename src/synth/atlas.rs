//! Several samples, and turned or mirrored copies of them, as one image a method can search.
//!
//! A job may learn from several photos of a material (`samples = [...]`) and from their
//! rotations and mirror images (`augment = [...]`). Rather than teach every method's search about
//! lists of images, the pieces — each sample as it is, then each of its transformed copies — are
//! packed into one *atlas* with a forbidden one-pixel gutter between them, and the atlas's
//! [`SampleMask`] allows exactly the pieces' pixels (and, inside a piece, what its own sample
//! mask allows). A method that honours sample masks copies only blocks whose every pixel is
//! allowed, so no block can straddle two pieces, and every output pixel comes from one sample
//! under one transform. The placement is then in atlas coordinates; [`Atlas::locate`] turns
//! them back into (sample, transform, pixel of the original sample), which is what the source
//! map records (version 2) and `texsyn apply` renders from.
//!
//! The layout is a pure function of the samples' sizes and the transform list, so anyone holding
//! the samples rebuilds the same atlas.

use crate::image::io::{NativeImage, Samples};
use crate::synth::placement::MapKind;

crate::choice! {
    /// A transformed copy of every sample that is also searched (`augment` in a job file). The
    /// rotations are clockwise, as an image viewer shows them.
    pub enum Augment {
        Rot90 = "rot90",
        Rot180 = "rot180",
        Rot270 = "rot270",
        FlipH = "flip_h",
        FlipV = "flip_v",
    }
}

impl Augment {
    /// The size of a `w × h` image under the transform.
    pub fn size(self, w: u32, h: u32) -> (u32, u32) {
        match self {
            Augment::Rot90 | Augment::Rot270 => (h, w),
            _ => (w, h),
        }
    }

    /// The pixel of the original `w × h` image shown at `(u, v)` of the transformed copy.
    pub fn source_of(self, u: u32, v: u32, w: u32, h: u32) -> (u32, u32) {
        match self {
            Augment::Rot90 => (v, h - 1 - u),
            Augment::Rot180 => (w - 1 - u, h - 1 - v),
            Augment::Rot270 => (w - 1 - v, u),
            Augment::FlipH => (w - 1 - u, v),
            Augment::FlipV => (u, h - 1 - v),
        }
    }

    /// Where the original pixel `(x, y)` lands in the transformed copy (the inverse of
    /// [`Augment::source_of`]).
    pub fn target_of(self, x: u32, y: u32, w: u32, h: u32) -> (u32, u32) {
        match self {
            Augment::Rot90 => (h - 1 - y, x),
            Augment::Rot180 => (w - 1 - x, h - 1 - y),
            Augment::Rot270 => (y, w - 1 - x),
            Augment::FlipH => (w - 1 - x, y),
            Augment::FlipV => (x, h - 1 - y),
        }
    }

    /// The code the source map's `T` channel holds (0 is the sample as it is).
    pub fn code(self) -> u32 {
        match self {
            Augment::Rot90 => 1,
            Augment::Rot180 => 2,
            Augment::Rot270 => 3,
            Augment::FlipH => 4,
            Augment::FlipV => 5,
        }
    }

    /// The transform of a source map `T` code (`Some(None)`: as it is; `None`: no such code).
    pub fn from_code(code: u32) -> Option<Option<Augment>> {
        match code {
            0 => Some(None),
            1 => Some(Some(Augment::Rot90)),
            2 => Some(Some(Augment::Rot180)),
            3 => Some(Some(Augment::Rot270)),
            4 => Some(Some(Augment::FlipH)),
            5 => Some(Some(Augment::FlipV)),
            _ => None,
        }
    }

    /// A tangent-space normal's stored `(r, g)` (OpenGL convention, +y up the image; a value
    /// `v` on `max` holds `n = 2v/max − 1`) turned with the image, so that a turned bump still
    /// lights from the side it now faces. Negating `n` is `max − v`: exact in integers.
    fn turn_normal(self, r: f64, g: f64, max: f64) -> (f64, f64) {
        match self {
            Augment::Rot90 => (g, max - r),
            Augment::Rot180 => (max - r, max - g),
            Augment::Rot270 => (max - g, r),
            Augment::FlipH => (max - r, g),
            Augment::FlipV => (r, max - g),
        }
    }
}

/// One sample, as it is or transformed, and where it lies in the atlas.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Piece {
    /// Index in the job's `samples`.
    pub sample: usize,
    pub transform: Option<Augment>,
    /// Top-left corner in the atlas.
    pub x: u32,
    pub y: u32,
    /// Its size in the atlas (the sample's, swapped by a quarter turn).
    pub width: u32,
    pub height: u32,
    /// The original sample's size.
    pub sample_size: (u32, u32),
}

#[cfg(test)]
impl Piece {
    fn contains(&self, ax: u32, ay: u32) -> bool {
        ax >= self.x && ay >= self.y && ax < self.x + self.width && ay < self.y + self.height
    }
}

/// Pieces packed into one image, in shelves, with a gutter of [`GUTTER`] pixels between pieces.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Atlas {
    width: u32,
    height: u32,
    pieces: Vec<Piece>,
    /// For each atlas pixel, its piece (`u32::MAX` in gutters and unused corners).
    owner: Vec<u32>,
}

/// Pixels between two pieces: one forbidden pixel keeps any block from straddling them.
pub const GUTTER: u32 = 1;

impl Atlas {
    /// Every sample as it is, then each transformed copy of it, in the order given: sample-major,
    /// transforms in `augment`'s order. Packed row by row into shelves no wider than the widest
    /// piece or the side of a square of the pieces' area, whichever is larger.
    pub fn layout(sample_sizes: &[(u32, u32)], augment: &[Augment]) -> Atlas {
        let mut pieces = Vec::new();
        for (i, &(w, h)) in sample_sizes.iter().enumerate() {
            for t in std::iter::once(None).chain(augment.iter().copied().map(Some)) {
                let (pw, ph) = t.map_or((w, h), |t| t.size(w, h));
                pieces.push(Piece { sample: i, transform: t, x: 0, y: 0, width: pw, height: ph, sample_size: (w, h) });
            }
        }
        let area: u64 = pieces.iter().map(|p| u64::from(p.width + GUTTER) * u64::from(p.height + GUTTER)).sum();
        let widest = pieces.iter().map(|p| p.width).max().unwrap_or(0);
        let shelf = widest.max((area as f64).sqrt().ceil() as u32);
        let (mut x, mut y, mut row_height, mut width) = (0u32, 0u32, 0u32, 0u32);
        for p in &mut pieces {
            if x > 0 && x + p.width > shelf {
                y += row_height + GUTTER;
                x = 0;
                row_height = 0;
            }
            (p.x, p.y) = (x, y);
            x += p.width + GUTTER;
            row_height = row_height.max(p.height);
            width = width.max(p.x + p.width);
        }
        let height = y + row_height;
        let mut owner = vec![u32::MAX; width as usize * height as usize];
        for (k, p) in pieces.iter().enumerate() {
            for py in p.y..p.y + p.height {
                let row = py as usize * width as usize;
                owner[row + p.x as usize..row + (p.x + p.width) as usize].fill(k as u32);
            }
        }
        Atlas { width, height, pieces, owner }
    }

    pub fn dimensions(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    pub fn pieces(&self) -> &[Piece] {
        &self.pieces
    }

    /// How many samples it was made from.
    pub fn samples(&self) -> usize {
        self.pieces.iter().map(|p| p.sample + 1).max().unwrap_or(0)
    }

    /// The size of each sample it was made from, in order.
    pub fn sample_sizes(&self) -> Vec<(u32, u32)> {
        let mut sizes = vec![(0, 0); self.samples()];
        for p in &self.pieces {
            sizes[p.sample] = p.sample_size;
        }
        sizes
    }

    /// The transforms of every sample's copies, in order (`augment`).
    pub fn augment(&self) -> Vec<Augment> {
        self.pieces.iter().filter(|p| p.sample == 0).filter_map(|p| p.transform).collect()
    }

    /// The piece an atlas pixel belongs to and the pixel of the original sample it shows; `None`
    /// in a gutter.
    pub fn locate(&self, ax: u32, ay: u32) -> Option<(&Piece, (u32, u32))> {
        if ax >= self.width || ay >= self.height {
            return None;
        }
        let k = self.owner[ay as usize * self.width as usize + ax as usize];
        let p = self.pieces.get(k as usize)?;
        let (u, v) = (ax - p.x, ay - p.y);
        let (w, h) = p.sample_size;
        Some((p, p.transform.map_or((u, v), |t| t.source_of(u, v, w, h))))
    }

    /// The atlas pixel showing pixel `(x, y)` of sample `sample` under `transform`; `None` when
    /// the atlas has no such piece or the pixel lies outside the sample.
    pub fn position(&self, sample: usize, transform: Option<Augment>, x: u32, y: u32) -> Option<(u32, u32)> {
        let p = self.pieces.iter().find(|p| p.sample == sample && p.transform == transform)?;
        let (w, h) = p.sample_size;
        if x >= w || y >= h {
            return None;
        }
        let (u, v) = transform.map_or((x, y), |t| t.target_of(x, y, w, h));
        Some((p.x + u, p.y + v))
    }

    /// Which atlas pixels may be copied (row-major flags): the pieces', less what
    /// `allows(sample, x, y)` forbids in each sample's own pixels (its sample mask).
    pub fn allowed(&self, allows: impl Fn(usize, u32, u32) -> bool) -> Vec<bool> {
        (0..self.height)
            .flat_map(|y| (0..self.width).map(move |x| (x, y)))
            .map(|(x, y)| match self.locate(x, y) {
                None => false,
                Some((p, (sx, sy))) => allows(p.sample, sx, sy),
            })
            .collect()
    }

    /// The rectangle `[x0, x1) × [y0, y1)` of its own sample that a `block × block` block at
    /// atlas position `(ax, ay)` shows, with its piece; `None` when the block is not wholly in
    /// one piece.
    fn source_rect(&self, ax: u32, ay: u32, block: u32) -> Option<(&Piece, (u32, u32, u32, u32))> {
        let (p, a) = self.locate(ax, ay)?;
        let (q, b) = self.locate(ax + block - 1, ay + block - 1)?;
        (p == q).then_some((p, (a.0.min(b.0), a.1.min(b.1), a.0.max(b.0) + 1, a.1.max(b.1) + 1)))
    }

    /// Whether two blocks at atlas positions `a` and `b` show overlapping pixels of one sample
    /// under different transforms: a block next to such a twin continues its neighbour's mirror
    /// image or turned copy, which shows as a symmetric motif. (The same transform is plain
    /// continuation, and fine.)
    pub fn twins(&self, a: (u32, u32), b: (u32, u32), block: u32) -> bool {
        let (Some((p, ra)), Some((q, rb))) = (self.source_rect(a.0, a.1, block), self.source_rect(b.0, b.1, block)) else {
            return false;
        };
        p.sample == q.sample && p.transform != q.transform && ra.0 < rb.2 && rb.0 < ra.2 && ra.1 < rb.3 && rb.1 < ra.3
    }

    /// Whether any piece is a transformed copy (only then can blocks be twins).
    pub fn has_copies(&self) -> bool {
        self.pieces.iter().any(|p| p.transform.is_some())
    }

    /// The atlas of `images` (one per sample, each of its sample's size and all of one channel
    /// count and precision): every piece's pixels from its sample, transformed; a normal map's
    /// vectors turned with it (`kind`). Gutters and unused corners hold the pieces' mean value,
    /// so that a search's coarse levels and a guide's statistics are not pulled by black lines.
    pub fn compose(&self, images: &[&NativeImage], kind: MapKind) -> NativeImage {
        // Every stored precision is exact in f64: compose there, store back in the first's.
        let as_f64 = |s: &Samples| -> Vec<f64> {
            match s {
                Samples::U8(v) => v.iter().map(|&x| f64::from(x)).collect(),
                Samples::U16(v) => v.iter().map(|&x| f64::from(x)).collect(),
                Samples::F32(v) => v.iter().map(|&x| f64::from(x)).collect(),
            }
        };
        let channels = images[0].channels as usize;
        let max = match images[0].samples {
            Samples::U8(_) => 255.0,
            Samples::U16(_) => 65535.0,
            Samples::F32(_) => 1.0,
        };
        let per_sample: Vec<Vec<f64>> = images.iter().map(|i| as_f64(&i.samples)).collect();
        let mut data = vec![None; self.width as usize * self.height as usize * channels];
        for y in 0..self.height {
            for x in 0..self.width {
                let Some((p, (sx, sy))) = self.locate(x, y) else { continue };
                let from = (sy as usize * p.sample_size.0 as usize + sx as usize) * channels;
                let to = (y as usize * self.width as usize + x as usize) * channels;
                for c in 0..channels {
                    data[to + c] = Some(per_sample[p.sample][from + c]);
                }
            }
        }
        let values = self.finish(data, self.width as usize * self.height as usize, channels, kind, max);
        let samples = match images[0].samples {
            Samples::U8(_) => Samples::U8(values.into_iter().map(|v| v as u8).collect()),
            Samples::U16(_) => Samples::U16(values.into_iter().map(|v| v as u16).collect()),
            Samples::F32(_) => Samples::F32(values.into_iter().map(|v| v as f32).collect()),
        };
        NativeImage { width: self.width, height: self.height, channels: channels as u32, samples }
    }

    /// Turns normals with their pieces, then fills gutters with the pieces' mean.
    fn finish(&self, mut data: Vec<Option<f64>>, n: usize, channels: usize, kind: MapKind, max: f64) -> Vec<f64> {
        if kind == MapKind::Normal && channels >= 2 {
            for i in 0..n {
                let (x, y) = ((i % self.width as usize) as u32, (i / self.width as usize) as u32);
                let Some((Piece { transform: Some(t), .. }, _)) = self.locate(x, y) else { continue };
                let (Some(r), Some(g)) = (data[i * channels], data[i * channels + 1]) else { continue };
                let (r, g) = t.turn_normal(r, g, max);
                (data[i * channels], data[i * channels + 1]) = (Some(r), Some(g));
            }
        }
        let mut mean = vec![0.0; channels];
        let mut count = 0u64;
        for px in data.chunks(channels) {
            if px[0].is_some() {
                for (m, v) in mean.iter_mut().zip(px) {
                    *m += v.unwrap_or(0.0);
                }
                count += 1;
            }
        }
        let integer = max > 1.0;
        for m in &mut mean {
            *m /= count.max(1) as f64;
            if integer {
                *m = m.round();
            }
        }
        data.chunks(channels).flat_map(|px| px.iter().zip(&mean).map(|(v, m)| v.unwrap_or(*m)).collect::<Vec<_>>()).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gradient(w: u32, h: u32) -> NativeImage {
        let samples = (0..h).flat_map(|y| (0..w).flat_map(move |x| [x as u8, y as u8, (x * 7 + y) as u8])).collect();
        NativeImage { width: w, height: h, channels: 3, samples: Samples::U8(samples) }
    }

    #[test]
    fn every_transform_inverts_and_stays_inside() {
        let (w, h) = (5, 3);
        for t in [Augment::Rot90, Augment::Rot180, Augment::Rot270, Augment::FlipH, Augment::FlipV] {
            let (tw, th) = t.size(w, h);
            let mut seen = std::collections::BTreeSet::new();
            for v in 0..th {
                for u in 0..tw {
                    let (x, y) = t.source_of(u, v, w, h);
                    assert!(x < w && y < h, "{t:?}");
                    assert_eq!(t.target_of(x, y, w, h), (u, v), "{t:?}");
                    seen.insert((x, y));
                }
            }
            assert_eq!(seen.len(), (w * h) as usize, "{t:?} is a bijection");
            assert_eq!(Augment::from_code(t.code()), Some(Some(t)));
        }
        // A clockwise quarter turn puts the bottom-left pixel at the top-left.
        assert_eq!(Augment::Rot90.source_of(0, 0, w, h), (0, h - 1));
        assert_eq!(Augment::Rot270.source_of(0, 0, w, h), (w - 1, 0));
    }

    #[test]
    fn pieces_do_not_overlap_and_are_separated_by_forbidden_gutters() {
        let atlas = Atlas::layout(&[(40, 30), (25, 50)], &[Augment::Rot90, Augment::FlipH]);
        assert_eq!(atlas.pieces().len(), 6);
        assert_eq!(atlas.samples(), 2);
        let (w, h) = atlas.dimensions();
        let allowed = atlas.allowed(|_, _, _| true);
        let at = |x: u32, y: u32| allowed[(y * w + x) as usize];
        for y in 0..h {
            for x in 0..w {
                let inside: Vec<_> = atlas.pieces().iter().filter(|p| p.contains(x, y)).collect();
                assert!(inside.len() <= 1);
                assert_eq!(at(x, y), inside.len() == 1);
            }
        }
        // No 2x2 block of allowed pixels straddles two pieces: a gutter lies between any two.
        for y in 0..h - 1 {
            for x in 0..w - 1 {
                if at(x, y) && at(x + 1, y) && at(x, y + 1) && at(x + 1, y + 1) {
                    assert_eq!(atlas.locate(x, y).unwrap().0, atlas.locate(x + 1, y + 1).unwrap().0);
                }
            }
        }
        // Roughly square, not one long row.
        assert!(w < 3 * h && h < 3 * w, "{w}x{h}");
    }

    #[test]
    fn twins_are_overlapping_pixels_of_one_sample_under_two_transforms() {
        let atlas = Atlas::layout(&[(40, 30), (40, 30)], &[Augment::FlipH]);
        let at = |s, t, x, y| atlas.position(s, t, x, y).unwrap();
        // A 10-px block over pixels 5..15 of the sample, and its mirror image: the copy's
        // top-left pixel shows pixel 14.
        let a = at(0, None, 5, 5);
        let mirrored = at(0, Some(Augment::FlipH), 14, 5);
        assert!(atlas.twins(a, mirrored, 10));
        // The mirror image of pixels 30..40: no longer twins.
        assert!(!atlas.twins(a, at(0, Some(Augment::FlipH), 39, 5), 10));
        // The same transform (continuation) and another sample are never twins.
        assert!(!atlas.twins(a, at(0, None, 8, 5), 10));
        assert!(!atlas.twins(a, at(1, Some(Augment::FlipH), 14, 5), 10));
        assert!(atlas.has_copies() && !Atlas::layout(&[(4, 4), (4, 4)], &[]).has_copies());
    }

    #[test]
    fn composed_pixels_are_the_transformed_samples() {
        let (a, b) = (gradient(6, 4), gradient(3, 5));
        let atlas = Atlas::layout(&[(6, 4), (3, 5)], &[Augment::Rot90, Augment::FlipV]);
        let img = atlas.compose(&[&a, &b], MapKind::Color);
        let Samples::U8(data) = &img.samples else { panic!() };
        for p in atlas.pieces() {
            let src = if p.sample == 0 { &a } else { &b };
            let Samples::U8(s) = &src.samples else { panic!() };
            for v in 0..p.height {
                for u in 0..p.width {
                    let (ax, ay) = (p.x + u, p.y + v);
                    let (loc, (sx, sy)) = atlas.locate(ax, ay).unwrap();
                    assert_eq!(loc, p);
                    assert_eq!(atlas.position(p.sample, p.transform, sx, sy), Some((ax, ay)));
                    let at = ((ay * img.width + ax) * 3) as usize;
                    let from = ((sy * src.width + sx) * 3) as usize;
                    assert_eq!(&data[at..at + 3], &s[from..from + 3]);
                }
            }
        }
    }

    #[test]
    fn normals_turn_with_their_piece() {
        // One pixel whose normal leans right (+x): turned a quarter clockwise it leans down (−y).
        let n = NativeImage { width: 1, height: 1, channels: 3, samples: Samples::U16(vec![65535, 32768, 65535]) };
        let atlas = Atlas::layout(&[(1, 1)], &[Augment::Rot90, Augment::FlipH]);
        let img = atlas.compose(&[&n], MapKind::Normal);
        let Samples::U16(d) = &img.samples else { panic!() };
        let at = |k: usize| {
            let p = atlas.pieces()[k];
            let i = ((p.y * img.width + p.x) * 3) as usize;
            (d[i], d[i + 1], d[i + 2])
        };
        assert_eq!(at(0), (65535, 32768, 65535));
        assert_eq!(at(1), (32768, 0, 65535), "rot90: right becomes down");
        assert_eq!(at(2), (0, 32768, 65535), "flip_h: right becomes left");
    }

    #[test]
    fn per_sample_masks_carry_into_their_pieces() {
        let atlas = Atlas::layout(&[(4, 3)], &[Augment::Rot180]);
        let allowed = atlas.allowed(|_, x, y| (x, y) != (0, 0));
        let (x, y) = atlas.position(0, Some(Augment::Rot180), 0, 0).unwrap();
        assert!(!allowed[(y * atlas.dimensions().0 + x) as usize]);
        assert_eq!(allowed.iter().filter(|&&a| a).count(), 2 * 11);
    }
}
