//! The exact SSD of one boundary zone at one sample position, made cheap for searches that score
//! positions one at a time (patch sampling's swarms score a few million per output).
//!
//! A zone is a few thin strips (the left strip of a block is `overlap` pixels wide and `block`
//! high). Read row by row, a tall strip is many short runs of bytes, which neither vectorise nor
//! amortise the per-row work. So each strip is read along its long side: a wide strip from the
//! sample's rows, a tall one from the rows of the sample's transpose, and the zone's output pixels
//! are packed once per block in the same order, each line padded to whole 16-byte chunks with a
//! mask that zeroes the padding's differences. A chunk's sum is written as a sum of squares of
//! 16-bit values, which compiles to multiply-adds of 16-bit lanes on plain x86-64. The total is the
//! same integer as `overlap::rect_ssd` over the same rectangles (integer addition does not depend
//! on order).
//!
//! On x86-64 with AVX2 (detected once, at run time) a strip is scored by `avx2::strip_ssd`
//! instead, 32 bytes a step: the same integer, only faster. Elsewhere the portable `strip_ssd`
//! runs.

use super::overlap::Rect;
use crate::image::RgbImage;

/// Bytes scored together; lines are padded to a multiple of this.
const CHUNK: usize = 16;

/// The most chunks a line may have so that its whole sum (at most `255²` per byte) fits an `i32`:
/// 2064, over 11 000 pixels (blocks are at most 4096).
const MAX_LINE_CHUNKS: usize = i32::MAX as usize / (255 * 255 * CHUNK);

/// The sample in the two layouts strips are read in, each followed by `CHUNK` bytes of padding so
/// that a padded line read at the end of the last row stays in bounds.
pub struct SampleLines {
    width: u32,
    height: u32,
    /// Row-major (line `y` is row `y`).
    rows: Vec<u8>,
    /// Transposed (line `x` is column `x`, top to bottom).
    columns: Vec<u8>,
}

impl SampleLines {
    pub fn new(sample: &RgbImage) -> SampleLines {
        let (w, h) = (sample.width() as usize, sample.height() as usize);
        let raw = sample.as_raw();
        let mut rows = Vec::with_capacity(w * h * 3 + CHUNK);
        rows.extend_from_slice(raw);
        rows.resize(w * h * 3 + CHUNK, 0);
        let mut columns = vec![0u8; w * h * 3 + CHUNK];
        for x in 0..w {
            for y in 0..h {
                columns[(x * h + y) * 3..(x * h + y) * 3 + 3].copy_from_slice(&raw[(y * w + x) * 3..(y * w + x) * 3 + 3]);
            }
        }
        SampleLines { width: sample.width(), height: sample.height(), rows, columns }
    }
}

/// One rectangle of a zone, packed along its longer side.
struct Strip {
    /// Read from the sample's transpose (the rectangle is taller than wide).
    transposed: bool,
    /// The rectangle's offset in the block: across lines, then along a line (pixels).
    first_line: u32,
    along: u32,
    lines: usize,
    /// Bytes per line, padded to a multiple of `CHUNK`.
    padded: usize,
    /// The output's bytes, `lines × padded`, zero in the padding.
    target: Vec<u8>,
    /// `0xFF` for a line's real bytes, `0` for its padding (`padded` bytes).
    mask: Vec<u8>,
    /// How many lines the AVX2 kernel sums in `i32` lanes before adding them into its `u64`
    /// total: as many as hold at most `MAX_LINE_CHUNKS` chunks, and at least one.
    group: usize,
}

/// A block's zone (rectangles relative to the block) with the output under it, packed for
/// [`PackedZone::ssd`].
pub struct PackedZone {
    strips: Vec<Strip>,
}

impl PackedZone {
    /// The zone `regions` of the output block whose top-left is `origin` in `target`.
    pub fn new(target: &RgbImage, origin: (u32, u32), regions: &[Rect]) -> PackedZone {
        let strips = regions
            .iter()
            .filter(|r| r.w > 0 && r.h > 0)
            .map(|r| {
                let transposed = r.h > r.w;
                let (lines, len) = if transposed { (r.w, r.h) } else { (r.h, r.w) };
                let bytes = len as usize * 3;
                let padded = bytes.div_ceil(CHUNK) * CHUNK;
                assert!(padded / CHUNK <= MAX_LINE_CHUNKS, "a zone strip of {len} pixels is too long to score");
                let mut packed = vec![0u8; lines as usize * padded];
                for l in 0..lines {
                    let line = &mut packed[l as usize * padded..l as usize * padded + bytes];
                    for k in 0..len {
                        let (dx, dy) = if transposed { (l, k) } else { (k, l) };
                        let p = target.get(origin.0 + r.x + dx, origin.1 + r.y + dy);
                        line[k as usize * 3..k as usize * 3 + 3].copy_from_slice(&p);
                    }
                }
                let mut mask = vec![0u8; padded];
                mask[..bytes].fill(0xFF);
                let (first_line, along) = if transposed { (r.x, r.y) } else { (r.y, r.x) };
                let group = MAX_LINE_CHUNKS / (padded / CHUNK);
                Strip { transposed, first_line, along, lines: lines as usize, padded, target: packed, mask, group }
            })
            .collect();
        PackedZone { strips }
    }

    /// `Σ_Ω |sample(x + o) − target(origin + o)|²`, the same integer as `rect_ssd` summed over the
    /// regions. The caller keeps `(x, y)` such that the block lies inside the sample.
    pub fn ssd(&self, sample: &SampleLines, pos: (u32, u32)) -> u64 {
        #[cfg(target_arch = "x86_64")]
        if has_avx2() {
            return self.ssd_with(sample, pos, avx2::strip_ssd);
        }
        self.ssd_with(sample, pos, strip_ssd)
    }

    /// [`PackedZone::ssd`] with the strip kernel `score` (one of the same integer's kernels).
    #[inline(always)]
    fn ssd_with(&self, sample: &SampleLines, (x, y): (u32, u32), score: impl Fn(&[u8], usize, usize, &Strip) -> u64) -> u64 {
        let mut total = 0u64;
        for s in &self.strips {
            let (layout, stride, line0, along0) = if s.transposed {
                (&sample.columns, sample.height as usize * 3, x, y)
            } else {
                (&sample.rows, sample.width as usize * 3, y, x)
            };
            let start = (line0 + s.first_line) as usize * stride + (along0 + s.along) as usize * 3;
            total += score(layout, stride, start, s);
        }
        total
    }
}

#[cfg(target_arch = "x86_64")]
use super::simd::has_avx2;

/// The masked SSD of one strip. Each line is summed in 16 lanes of `i32`, one per byte of a
/// chunk, added up once per line: the lanes map onto 16-bit multiply-adds, and a horizontal sum
/// per chunk cost more than the chunk's arithmetic. A line has at most `MAX_LINE_CHUNKS` chunks
/// (checked when packing), so its sum fits an `i32`; the strip's total is kept in a `u64`.
fn strip_ssd(layout: &[u8], stride: usize, start: usize, s: &Strip) -> u64 {
    let mut total = 0u64;
    for l in 0..s.lines {
        let a = &layout[start + l * stride..start + l * stride + s.padded];
        let b = &s.target[l * s.padded..(l + 1) * s.padded];
        let mut lanes = [0i32; CHUNK];
        for ((ca, cb), cm) in a.chunks_exact(CHUNK).zip(b.chunks_exact(CHUNK)).zip(s.mask.chunks_exact(CHUNK)) {
            let ca: &[u8; CHUNK] = ca.try_into().expect("chunk");
            let cb: &[u8; CHUNK] = cb.try_into().expect("chunk");
            let cm: &[u8; CHUNK] = cm.try_into().expect("chunk");
            for j in 0..CHUNK {
                let d = i32::from(i16::from(ca[j].abs_diff(cb[j]) & cm[j]));
                lanes[j] += d * d;
            }
        }
        total += lanes.iter().sum::<i32>() as u64;
    }
    total
}

/// The AVX2 strip kernel: with [`crate::synth::primitives::simd::with_avx2`], the only `unsafe`
/// code of the crate (the crate denies `unsafe_code`; these two alone allow it). Patch sampling
/// scores a few million zone positions per output, and this kernel is most of that time; the
/// portable kernel is held to SSE2's 16 bytes a step, because code compiled for baseline x86-64
/// may not use AVX2 without a run-time check, and calling a `#[target_feature]` function or
/// loading through a pointer needs `unsafe`. Every load is of 16 or 32 bytes inside a slice
/// whose bounds were checked (see the `SAFETY` comments), so nothing here reads outside memory
/// safe code could read.
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
mod avx2 {
    use super::{CHUNK, MAX_LINE_CHUNKS, Strip};
    use std::arch::x86_64::*;

    /// The masked SSD of one strip, the same integer as [`super::strip_ssd`].
    ///
    /// # Panics
    /// If the CPU lacks AVX2 (callers check [`super::has_avx2`] first).
    pub(super) fn strip_ssd(layout: &[u8], stride: usize, start: usize, s: &Strip) -> u64 {
        assert!(super::has_avx2(), "the AVX2 kernel needs AVX2");
        // SAFETY: AVX2 was just found on this CPU, so the instructions `strip_ssd_avx2` is
        // compiled with exist; it has no other precondition.
        unsafe { strip_ssd_avx2(layout, stride, start, s) }
    }

    /// Each line's `padded` bytes (a multiple of `CHUNK` = 16) are read 32 at a time, then one
    /// last 16-byte step where `padded` is an odd number of chunks. The sample's bytes are
    /// ANDed with the mask, so their padding is 0 like the target's and adds nothing. Per byte,
    /// `|a − b|` (u8, from two saturating subtractions) is widened to 16 bits and squared and
    /// paired by `madd` into `i32` lanes (at most `2·255²` per `madd` lane). The lanes run over
    /// `s.group` lines and are then added into the `u64` total, before they could overflow: a
    /// group holds at most `MAX_LINE_CHUNKS` chunks (`PackedZone::new` asserts that one line
    /// does), so its whole sum, and so any lane and the horizontal sum, is at most
    /// `MAX_LINE_CHUNKS · CHUNK · 255² ≤ i32::MAX`.
    #[target_feature(enable = "avx2")]
    fn strip_ssd_avx2(layout: &[u8], stride: usize, start: usize, s: &Strip) -> u64 {
        let padded = s.padded;
        let group = s.group;
        debug_assert!(padded.is_multiple_of(CHUNK) && group >= 1 && group * padded <= MAX_LINE_CHUNKS * CHUNK);
        let mask = &s.mask[..padded];
        let zero = _mm256_setzero_si256();
        let mut total = 0u64;
        let mut l = 0;
        while l < s.lines {
            let mut acc = _mm256_setzero_si256();
            for l in l..(l + group).min(s.lines) {
                // Bounds-checked slices of exactly `padded` bytes: every load below stays in them.
                let a = &layout[start + l * stride..start + l * stride + padded];
                let b = &s.target[l * padded..(l + 1) * padded];
                let mut i = 0;
                while i + 32 <= padded {
                    // SAFETY: `i + 32 <= padded` = the length of `a`, `b` and `mask`, so each
                    // unaligned 32-byte load reads bytes `i..i + 32` of its slice.
                    let (va, vb, vm) = unsafe {
                        (
                            _mm256_loadu_si256(a.as_ptr().add(i).cast()),
                            _mm256_loadu_si256(b.as_ptr().add(i).cast()),
                            _mm256_loadu_si256(mask.as_ptr().add(i).cast()),
                        )
                    };
                    let va = _mm256_and_si256(va, vm);
                    let d = _mm256_or_si256(_mm256_subs_epu8(va, vb), _mm256_subs_epu8(vb, va));
                    let lo = _mm256_unpacklo_epi8(d, zero);
                    let hi = _mm256_unpackhi_epi8(d, zero);
                    acc = _mm256_add_epi32(acc, _mm256_madd_epi16(lo, lo));
                    acc = _mm256_add_epi32(acc, _mm256_madd_epi16(hi, hi));
                    i += 32;
                }
                if i < padded {
                    // SAFETY: `padded` is a multiple of 16 and `i < padded`, so `i + 16 <= padded`
                    // and each unaligned 16-byte load reads bytes `i..i + 16` of its slice.
                    let (va, vb, vm) = unsafe {
                        (
                            _mm_loadu_si128(a.as_ptr().add(i).cast()),
                            _mm_loadu_si128(b.as_ptr().add(i).cast()),
                            _mm_loadu_si128(mask.as_ptr().add(i).cast()),
                        )
                    };
                    let va = _mm_and_si128(va, vm);
                    let d = _mm_or_si128(_mm_subs_epu8(va, vb), _mm_subs_epu8(vb, va));
                    let d = _mm256_cvtepu8_epi16(d);
                    acc = _mm256_add_epi32(acc, _mm256_madd_epi16(d, d));
                }
            }
            total += horizontal_sum(acc) as u64;
            l += group;
        }
        total
    }

    /// The sum of the eight `i32` lanes (the caller keeps it within `i32`).
    #[target_feature(enable = "avx2")]
    fn horizontal_sum(v: __m256i) -> i32 {
        let s = _mm_add_epi32(_mm256_castsi256_si128(v), _mm256_extracti128_si256::<1>(v));
        let s = _mm_add_epi32(s, _mm_shuffle_epi32::<0b01_00_11_10>(s));
        let s = _mm_add_epi32(s, _mm_shuffle_epi32::<0b10_11_00_01>(s));
        _mm_cvtsi128_si32(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::primitives::overlap::rect_ssd;
    use crate::synth::rng::Stream;

    fn noise(w: u32, h: u32, seed: u64) -> RgbImage {
        let mut s = Stream::new(seed, "test/zone-ssd");
        RgbImage::from_fn(w, h, |_, _| [s.below(256) as u8, s.below(256) as u8, s.below(256) as u8])
    }

    #[test]
    fn equals_rect_ssd_at_every_position() {
        let sample = noise(41, 37, 1);
        let target = noise(60, 50, 2);
        let lines = SampleLines::new(&sample);
        let block = 13;
        // Strips, the L, a square, and rectangles of several padding remainders.
        let zones: Vec<Vec<Rect>> = vec![
            vec![Rect::new(0, 0, 3, block)],
            vec![Rect::new(0, 0, block, 3)],
            vec![Rect::new(0, 0, 3, block), Rect::new(3, 0, block - 3, 3)],
            vec![Rect::new(2, 2, 7, 7)],
            vec![Rect::new(0, 0, 1, 1), Rect::new(block - 2, 0, 2, block), Rect::new(0, block - 4, block, 4)],
        ];
        let origin = (9, 11);
        for regions in &zones {
            let zone = PackedZone::new(&target, origin, regions);
            for y in 0..=sample.height() - block {
                for x in 0..=sample.width() - block {
                    let expected: u64 = regions
                        .iter()
                        .map(|r| rect_ssd(&sample, x + r.x, y + r.y, &target, origin.0 + r.x, origin.1 + r.y, r.w, r.h))
                        .sum();
                    assert_eq!(zone.ssd(&lines, (x, y)), expected, "{regions:?} at ({x}, {y})");
                }
            }
        }
    }

    #[test]
    fn extreme_differences_do_not_overflow() {
        // 255² per byte, over 2³² in all; lines of 2700 bytes (12 of them fill the AVX2 kernel's
        // i32 lanes to within 2 % of their limit) and of 600.
        for (w, h) in [(200u32, 900u32), (900, 200)] {
            let sample = RgbImage::from_fn(w, h, |_, _| [255, 255, 255]);
            let target = RgbImage::new(w, h);
            let zone = PackedZone::new(&target, (0, 0), &[Rect::new(0, 0, w, h)]);
            let expected = u64::from(w * h) * 3 * 255 * 255;
            assert!(expected > u64::from(u32::MAX));
            let lines = SampleLines::new(&sample);
            assert_eq!(zone.ssd(&lines, (0, 0)), expected);
            for (name, kernel) in kernels() {
                assert_eq!(zone.ssd_with(&lines, (0, 0), kernel), expected, "{name} kernel, {w}x{h}");
            }
        }
    }

    type Kernel = fn(&[u8], usize, usize, &Strip) -> u64;

    /// The strip kernels this machine can run: the portable one always, AVX2 where the CPU has it.
    fn kernels() -> Vec<(&'static str, Kernel)> {
        let mut k: Vec<(&'static str, Kernel)> = vec![("portable", strip_ssd)];
        #[cfg(target_arch = "x86_64")]
        if has_avx2() {
            k.push(("avx2", avx2::strip_ssd));
        }
        k
    }

    #[test]
    fn every_kernel_equals_rect_ssd_on_odd_strips() {
        // `ssd` runs the fastest kernel; the portable one is checked here on every machine.
        let ks = kernels();
        #[cfg(target_arch = "x86_64")]
        assert_eq!(ks.len(), if std::arch::is_x86_feature_detected!("avx2") { 2 } else { 1 });
        // Random bytes, and bytes of 0 or 255 only against their inverses (each difference 255).
        let (sw, sh, tw, th) = (71u32, 67u32, 90u32, 80u32);
        let mut bits = Stream::new(9, "test/zone-ssd/extreme");
        let extreme = RgbImage::from_fn(sw, sh, |_, _| [0, 0, 0].map(|_: u8| if bits.below(2) == 0 { 0 } else { 255 }));
        let cases = [
            (noise(sw, sh, 3), noise(tw, th, 4)),
            (extreme.clone(), RgbImage::from_fn(tw, th, |x, y| extreme.get(x % sw, y % sh).map(|v| 255 - v))),
            (RgbImage::from_fn(sw, sh, |_, _| [255, 255, 255]), RgbImage::new(tw, th)),
        ];
        let block = 47;
        // Line lengths of 1 to 47 pixels: 3 to 141 bytes, every padding remainder, an even and an
        // odd number of 16-byte chunks (one 32-byte step plus a 16-byte one, and so on).
        let mut zones: Vec<Vec<Rect>> =
            (1..=block).step_by(2).map(|len| vec![Rect::new(0, 0, len, 5), Rect::new(0, 5, 3, len.min(block - 5))]).collect();
        zones.push(vec![Rect::new(0, 0, block, block)]);
        zones.push(vec![Rect::new(0, 0, 7, block), Rect::new(7, 0, block - 7, 7), Rect::new(block - 11, block - 13, 11, 13)]);
        let origin = (5, 8);
        for (ci, (sample, target)) in cases.iter().enumerate() {
            let lines = SampleLines::new(sample);
            for regions in &zones {
                let zone = PackedZone::new(target, origin, regions);
                // Every third position, and the last row and column (the sample's last bytes).
                let xs = (0..=sw - block).filter(|x| x % 3 == 0 || *x == sw - block);
                for x in xs {
                    for y in (0..=sh - block).filter(|y| y % 3 == 1 || *y == sh - block) {
                        let expected: u64 = regions
                            .iter()
                            .map(|r| rect_ssd(sample, x + r.x, y + r.y, target, origin.0 + r.x, origin.1 + r.y, r.w, r.h))
                            .sum();
                        assert_eq!(zone.ssd(&lines, (x, y)), expected, "case {ci}, {regions:?} at ({x}, {y})");
                        for (name, kernel) in &ks {
                            assert_eq!(
                                zone.ssd_with(&lines, (x, y), kernel),
                                expected,
                                "{name} kernel, case {ci}, {regions:?} at ({x}, {y})"
                            );
                        }
                    }
                }
            }
        }
    }
}
