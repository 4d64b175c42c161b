//! Pixel colour error and overlap error (docs/methods.md B1).
//!
//! Everything here is exact integer arithmetic: `u32` per pixel, `u64` per region. Methods that
//! search faster (FFT correlation, pruning) must agree with these functions exactly; tests compare
//! against them.

use crate::image::RgbImage;

/// Squared RGB distance of two pixels, `0..=195075`.
#[inline]
pub fn pixel_error(a: [u8; 3], b: [u8; 3]) -> u32 {
    let d0 = a[0] as i32 - b[0] as i32;
    let d1 = a[1] as i32 - b[1] as i32;
    let d2 = a[2] as i32 - b[2] as i32;
    (d0 * d0 + d1 * d1 + d2 * d2) as u32
}

/// Bytes summed together by [`bytes_ssd`].
const RUN_CHUNK: usize = 16;

/// The last `RUN_CHUNK` bytes of a run of `n ≥ RUN_CHUNK` bytes hold `n % RUN_CHUNK` bytes not yet
/// summed, at its end: `TAIL_MASKS[n % RUN_CHUNK]` keeps those.
const TAIL_MASKS: [[u8; RUN_CHUNK]; RUN_CHUNK] = {
    let mut masks = [[0u8; RUN_CHUNK]; RUN_CHUNK];
    let mut k = 0;
    while k < RUN_CHUNK {
        let mut j = RUN_CHUNK - k;
        while j < RUN_CHUNK {
            masks[k][j] = 0xFF;
            j += 1;
        }
        k += 1;
    }
    masks
};

/// `Σ (a[i] − b[i])²` over two runs of bytes of the same length: the SSD of two pixel runs (RGB
/// interleaved), the same integer as summing [`pixel_error`]. Whole 16-byte chunks are summed in
/// 16 `i32` lanes (16-bit multiply-adds, one horizontal sum per piece); a ragged end is the run's
/// last 16 bytes with the ones already summed masked off, so a short run of a strip costs no
/// scalar loop. A piece of at most 2¹⁵ bytes keeps every sum below 2³¹.
pub fn bytes_ssd(a: &[u8], b: &[u8]) -> u64 {
    assert_eq!(a.len(), b.len(), "runs of different lengths");
    let n = a.len();
    if n < RUN_CHUNK {
        return a.iter().zip(b).map(|(x, y)| u64::from(x.abs_diff(*y)) * u64::from(x.abs_diff(*y))).sum();
    }
    const PIECE: usize = 1 << 15;
    let full = n / RUN_CHUNK * RUN_CHUNK;
    let mut total = 0u64;
    for (pa, pb) in a[..full].chunks(PIECE).zip(b[..full].chunks(PIECE)) {
        let mut lanes = [0i32; RUN_CHUNK];
        for (ca, cb) in pa.chunks_exact(RUN_CHUNK).zip(pb.chunks_exact(RUN_CHUNK)) {
            let ca: &[u8; RUN_CHUNK] = ca.try_into().expect("chunk");
            let cb: &[u8; RUN_CHUNK] = cb.try_into().expect("chunk");
            for j in 0..RUN_CHUNK {
                let d = i32::from(i16::from(ca[j].abs_diff(cb[j])));
                lanes[j] += d * d;
            }
        }
        total += lanes.iter().sum::<i32>() as u64;
    }
    if full < n {
        let ca: &[u8; RUN_CHUNK] = a[n - RUN_CHUNK..].try_into().expect("chunk");
        let cb: &[u8; RUN_CHUNK] = b[n - RUN_CHUNK..].try_into().expect("chunk");
        let cm = &TAIL_MASKS[n % RUN_CHUNK];
        let mut lanes = [0i32; RUN_CHUNK];
        for j in 0..RUN_CHUNK {
            let d = i32::from(i16::from(ca[j].abs_diff(cb[j]) & cm[j]));
            lanes[j] += d * d;
        }
        total += lanes.iter().sum::<i32>() as u64;
    }
    total
}

/// A rectangle `[x, x+w) × [y, y+h)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rect {
    pub x: u32,
    pub y: u32,
    pub w: u32,
    pub h: u32,
}

impl Rect {
    pub fn new(x: u32, y: u32, w: u32, h: u32) -> Rect {
        Rect { x, y, w, h }
    }
    pub fn area(&self) -> u64 {
        self.w as u64 * self.h as u64
    }
}

/// SSD between the `w × h` rectangle of `a` at `(ax, ay)` and of `b` at `(bx, by)`.
pub fn rect_ssd(a: &RgbImage, ax: u32, ay: u32, b: &RgbImage, bx: u32, by: u32, w: u32, h: u32) -> u64 {
    let mut sum = 0u64;
    for r in 0..h {
        let ra = &a.row(ay + r)[ax as usize * 3..(ax + w) as usize * 3];
        let rb = &b.row(by + r)[bx as usize * 3..(bx + w) as usize * 3];
        let mut row_sum = 0u32;
        // A row of at most ~20k values keeps the u32 partial sum exact only for short rows, so
        // accumulate per row in u64 when rows are long.
        if w <= 20 {
            for (x, y) in ra.iter().zip(rb) {
                let d = *x as i32 - *y as i32;
                row_sum += (d * d) as u32;
            }
            sum += row_sum as u64;
        } else {
            let mut s = 0u64;
            for (x, y) in ra.iter().zip(rb) {
                let d = *x as i32 - *y as i32;
                s += (d * d) as u64;
            }
            sum += s;
        }
    }
    sum
}

/// SSD over a set of offsets: `Σ e(a(pa + o), b(pb + o))` for `o` in `offsets`.
pub fn masked_ssd(a: &RgbImage, pa: (u32, u32), b: &RgbImage, pb: (u32, u32), offsets: &[(u32, u32)]) -> u64 {
    offsets.iter().map(|&(dx, dy)| pixel_error(a.get(pa.0 + dx, pa.1 + dy), b.get(pb.0 + dx, pb.1 + dy)) as u64).sum()
}

/// Per-pixel error surface `E(p) = e(a(pa + p), b(pb + p))` over a `w × h` rectangle, row-major.
pub fn error_surface(a: &RgbImage, pa: (u32, u32), b: &RgbImage, pb: (u32, u32), w: u32, h: u32) -> Vec<u32> {
    let mut out = Vec::with_capacity(w as usize * h as usize);
    for y in 0..h {
        for x in 0..w {
            out.push(pixel_error(a.get(pa.0 + x, pa.1 + y), b.get(pb.0 + x, pb.1 + y)));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::rng::Stream;

    #[test]
    fn bytes_ssd_is_the_sum_of_pixel_errors() {
        let mut s = Stream::new(3, "test/bytes-ssd");
        let a: Vec<u8> = (0..3 * 12_000).map(|_| s.below(256) as u8).collect();
        let b: Vec<u8> = (0..3 * 12_000).map(|_| s.below(256) as u8).collect();
        // Short runs, every ragged end, and runs of several pieces.
        for (start, len) in (0..40).map(|n| (n % 7, n)).chain([(5, 100), (0, 3 * 12_000), (1, 3 * 11_999 - 1)]) {
            let (ra, rb) = (&a[start..start + len], &b[start..start + len]);
            let expected: u64 = ra.iter().zip(rb).map(|(x, y)| (i64::from(*x) - i64::from(*y)).pow(2) as u64).sum();
            assert_eq!(bytes_ssd(ra, rb), expected, "run of {len} from {start}");
        }
        // The largest differences, over 2³² in all.
        let (hi, lo) = (vec![255u8; 3 * 30_000], vec![0u8; 3 * 30_000]);
        assert_eq!(bytes_ssd(&hi, &lo), 3 * 30_000 * 255 * 255);
    }

    #[test]
    fn pixel_error_is_squared_rgb_distance() {
        assert_eq!(pixel_error([0, 0, 0], [255, 255, 255]), 195075);
        assert_eq!(pixel_error([10, 20, 30], [13, 16, 30]), 9 + 16);
        assert_eq!(pixel_error([5, 5, 5], [5, 5, 5]), 0);
    }

    #[test]
    fn rect_ssd_matches_masked_and_surface_sums() {
        let a = RgbImage::from_fn(30, 20, |x, y| [(x * 7 + y) as u8, (x * y) as u8, (200 - x) as u8]);
        let b = RgbImage::from_fn(30, 20, |x, y| [(y * 11) as u8, (x + y * 3) as u8, (x * x) as u8]);
        for &(w, h) in &[(5u32, 4u32), (25, 10)] {
            let direct = rect_ssd(&a, 2, 3, &b, 4, 1, w, h);
            let offsets: Vec<(u32, u32)> = (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).collect();
            assert_eq!(direct, masked_ssd(&a, (2, 3), &b, (4, 1), &offsets));
            let surface: u64 = error_surface(&a, (2, 3), &b, (4, 1), w, h).iter().map(|&e| e as u64).sum();
            assert_eq!(direct, surface);
        }
        assert_eq!(rect_ssd(&a, 0, 0, &a, 0, 0, 30, 20), 0);
    }
}
