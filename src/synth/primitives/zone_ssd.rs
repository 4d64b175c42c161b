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
                Strip { transposed, first_line, along, lines: lines as usize, padded, target: packed, mask }
            })
            .collect();
        PackedZone { strips }
    }

    /// `Σ_Ω |sample(x + o) − target(origin + o)|²`, the same integer as `rect_ssd` summed over the
    /// regions. The caller keeps `(x, y)` such that the block lies inside the sample.
    pub fn ssd(&self, sample: &SampleLines, (x, y): (u32, u32)) -> u64 {
        let mut total = 0u64;
        for s in &self.strips {
            let (layout, stride, line0, along0) = if s.transposed {
                (&sample.columns, sample.height as usize * 3, x, y)
            } else {
                (&sample.rows, sample.width as usize * 3, y, x)
            };
            let start = (line0 + s.first_line) as usize * stride + (along0 + s.along) as usize * 3;
            total += strip_ssd(layout, stride, start, s);
        }
        total
    }
}

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
        // 255² per byte, over 2³² in all.
        for (w, h) in [(200u32, 900u32), (900, 200)] {
            let sample = RgbImage::from_fn(w, h, |_, _| [255, 255, 255]);
            let target = RgbImage::new(w, h);
            let zone = PackedZone::new(&target, (0, 0), &[Rect::new(0, 0, w, h)]);
            let expected = u64::from(w * h) * 3 * 255 * 255;
            assert!(expected > u64::from(u32::MAX));
            assert_eq!(zone.ssd(&SampleLines::new(&sample), (0, 0)), expected);
        }
    }
}
