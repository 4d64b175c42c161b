//! Verbatim copying: the fraction of output pixels whose `k × k` neighbourhood occurs, exactly,
//! somewhere in the sample.
//!
//! Every `k × k` window of the sample is hashed (a polynomial hash of each window row, mod 2⁶⁴,
//! rolled along `x`, then a mixed combination of the `k` row hashes); the hashes are sorted, and an
//! output window counts only after an exact byte comparison with a sample window of equal hash, so
//! hash collisions can cost time but never change the result. The count is an integer, so the
//! value does not depend on the number of threads.
//!
//! Two shortcuts keep the lookups cheap without touching the count: the sorted table is indexed
//! by the top bits of the hash (about one window per bucket, instead of a binary search through
//! cache misses), and an output window right of a matched one is first compared with the sample
//! window right of its match, which settles most windows of a copied region with one comparison.

use crate::image::RgbImage;
use rayon::prelude::*;

/// Side of the neighbourhood (7 × 7, i.e. radius 3 around the pixel).
pub const VERBATIM_WINDOW: usize = 7;

const ROW_BASE: u64 = 0x9E37_79B9_7F4A_7C15 | 1;
const COL_BASE: u64 = 0xC2B2_AE3D_27D4_EB4F | 1;

#[inline]
fn mix(mut z: u64) -> u64 {
    // splitmix64 finaliser.
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[inline]
fn pixel_word(img: &RgbImage, x: usize, y: usize) -> u64 {
    let i = (y * img.width() as usize + x) * 3;
    let d = img.as_raw();
    ((d[i] as u64) << 16) | ((d[i + 1] as u64) << 8) | d[i + 2] as u64
}

/// Mixed hashes of all `k`-wide row segments: entry `y·(W−k+1) + x` covers `[x, x+k) × {y}`.
fn row_hashes(img: &RgbImage, k: usize) -> Vec<u64> {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let nx = w + 1 - k;
    let top = (1..k).fold(1u64, |a, _| a.wrapping_mul(ROW_BASE)); // ROW_BASE^(k−1)
    let mut out = vec![0u64; nx * h];
    for y in 0..h {
        let mut hsh = 0u64;
        for x in 0..k {
            hsh = hsh.wrapping_mul(ROW_BASE).wrapping_add(pixel_word(img, x, y));
        }
        out[y * nx] = mix(hsh);
        for x in 1..nx {
            hsh = hsh.wrapping_sub(pixel_word(img, x - 1, y).wrapping_mul(top)).wrapping_mul(ROW_BASE).wrapping_add(pixel_word(
                img,
                x + k - 1,
                y,
            ));
            out[y * nx + x] = mix(hsh);
        }
    }
    out
}

/// The bucket of a hash: its top `64 − shift` bits.
#[inline]
fn bucket(hsh: u64, shift: u32) -> usize {
    hsh.checked_shr(shift).unwrap_or(0) as usize
}

#[inline]
fn window_hash(rows: &[u64], nx: usize, x: usize, y: usize, k: usize) -> u64 {
    let mut hsh = 0u64;
    for j in 0..k {
        hsh = hsh.wrapping_mul(COL_BASE).wrapping_add(rows[(y + j) * nx + x]);
    }
    mix(hsh)
}

fn windows_equal(a: &RgbImage, ax: usize, ay: usize, b: &RgbImage, bx: usize, by: usize, k: usize) -> bool {
    (0..k).all(|j| {
        let ra = &a.row((ay + j) as u32)[ax * 3..(ax + k) * 3];
        let rb = &b.row((by + j) as u32)[bx * 3..(bx + k) * 3];
        ra == rb
    })
}

/// Fraction of the output pixels whose `k × k` window lies inside the output and occurs verbatim
/// (exact RGB) somewhere in the sample; pixels whose window leaves the output count in neither the
/// numerator nor the denominator. `None` when the output has no such pixel. Panics if `k = 0`.
pub fn verbatim_fraction(sample: &RgbImage, output: &RgbImage, k: usize) -> Option<f64> {
    verbatim_fraction_masked(sample, output, k, u64::MAX)
}

/// [`verbatim_fraction`] with the window hashes reduced to `hash_mask` (tests force collisions).
fn verbatim_fraction_masked(sample: &RgbImage, output: &RgbImage, k: usize, hash_mask: u64) -> Option<f64> {
    SampleWindows::build(sample, k, hash_mask).fraction(sample, output)
}

/// Every `k × k` window of a sample, hashed and sorted: the sample's half of the verbatim metric.
/// A batch builds it once per sample and asks it about each output made from that sample.
pub struct SampleWindows {
    k: usize,
    hash_mask: u64,
    /// Number of window positions along `x` in the sample.
    nx: usize,
    /// `(hash, x, y)` of every window, sorted; empty when the sample is smaller than a window.
    table: Vec<(u64, u32, u32)>,
    /// `table[starts[b]..starts[b + 1]]` are the windows whose hash has top bits `b`.
    starts: Vec<u32>,
    /// How far a hash is shifted right to give its bucket (64: a single bucket).
    shift: u32,
}

impl SampleWindows {
    /// Hashes every window of `sample`. Panics if `k = 0`.
    pub fn new(sample: &RgbImage, k: usize) -> SampleWindows {
        SampleWindows::build(sample, k, u64::MAX)
    }

    fn build(sample: &RgbImage, k: usize, hash_mask: u64) -> SampleWindows {
        assert!(k > 0, "window side must be positive");
        let (sw, sh) = (sample.width() as usize, sample.height() as usize);
        let mut table = Vec::new();
        let mut nx = 0;
        if sw >= k && sh >= k {
            let (snx, sny) = (sw + 1 - k, sh + 1 - k);
            nx = snx;
            let srows = row_hashes(sample, k);
            table.reserve_exact(snx * sny);
            for y in 0..sny {
                for x in 0..snx {
                    table.push((window_hash(&srows, snx, x, y, k) & hash_mask, x as u32, y as u32));
                }
            }
            table.sort_unstable();
        }
        let shift = 64 - table.len().next_power_of_two().trailing_zeros();
        let mut starts = vec![0u32; (1usize << (64 - shift)) + 1];
        for e in &table {
            starts[bucket(e.0, shift) + 1] += 1;
        }
        for b in 1..starts.len() {
            starts[b] += starts[b - 1];
        }
        SampleWindows { k, hash_mask, nx, table, starts, shift }
    }

    /// The windows whose hash is `hsh`, among a few others of its bucket.
    fn bucket_of(&self, hsh: u64) -> &[(u64, u32, u32)] {
        let b = bucket(hsh, self.shift);
        &self.table[self.starts[b] as usize..self.starts[b + 1] as usize]
    }

    /// The window side.
    pub fn window(&self) -> usize {
        self.k
    }

    /// [`verbatim_fraction`] of `output` against `sample`, which must be the image these windows
    /// were built from.
    pub fn fraction(&self, sample: &RgbImage, output: &RgbImage) -> Option<f64> {
        let k = self.k;
        let (ow, oh) = (output.width() as usize, output.height() as usize);
        if ow < k || oh < k {
            return None;
        }
        let (onx, ony) = (ow + 1 - k, oh + 1 - k);
        let total = (onx * ony) as u64;
        if self.table.is_empty() {
            return Some(0.0);
        }
        let orows = row_hashes(output, k);
        let matches: u64 = (0..ony)
            .into_par_iter()
            .map(|y| {
                let mut n = 0u64;
                // The sample window equal to the previous output window, if there was one.
                let mut previous: Option<(usize, usize)> = None;
                for x in 0..onx {
                    if let Some((sx, sy)) = previous
                        && sx + 1 < self.nx
                        && windows_equal(output, x, y, sample, sx + 1, sy, k)
                    {
                        previous = Some((sx + 1, sy));
                        n += 1;
                        continue;
                    }
                    let hsh = window_hash(&orows, onx, x, y, k) & self.hash_mask;
                    previous = self
                        .bucket_of(hsh)
                        .iter()
                        .find(|e| e.0 == hsh && windows_equal(output, x, y, sample, e.1 as usize, e.2 as usize, k))
                        .map(|e| (e.1 as usize, e.2 as usize));
                    n += previous.is_some() as u64;
                }
                n
            })
            .sum();
        Some(matches as f64 / total as f64)
    }
}

/// [`verbatim_fraction`] with the 7 × 7 neighbourhood.
pub fn verbatim(sample: &RgbImage, output: &RgbImage) -> Option<f64> {
    verbatim_fraction(sample, output, VERBATIM_WINDOW)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise(w: u32, h: u32, seed: u64) -> RgbImage {
        let mut s = seed;
        RgbImage::from_fn(w, h, |_, _| {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            let v = (s >> 40) as u32;
            [v as u8, (v >> 8) as u8, (v >> 16) as u8]
        })
    }

    /// Brute force: every output window against every sample window.
    fn brute(sample: &RgbImage, output: &RgbImage, k: usize) -> Option<f64> {
        let (ow, oh) = (output.width() as usize, output.height() as usize);
        let (sw, sh) = (sample.width() as usize, sample.height() as usize);
        if ow < k || oh < k {
            return None;
        }
        let mut n = 0;
        for y in 0..=oh - k {
            for x in 0..=ow - k {
                let hit =
                    sw >= k && sh >= k && (0..=sh - k).any(|sy| (0..=sw - k).any(|sx| windows_equal(output, x, y, sample, sx, sy, k)));
                n += hit as usize;
            }
        }
        Some(n as f64 / ((ow - k + 1) * (oh - k + 1)) as f64)
    }

    #[test]
    fn crop_of_the_sample_is_fully_verbatim() {
        let s = noise(64, 48, 1);
        let out = s.crop(10, 5, 40, 30);
        assert_eq!(verbatim(&s, &out), Some(1.0));
        assert_eq!(verbatim(&s, &s), Some(1.0));
    }

    #[test]
    fn unrelated_noise_is_not_verbatim() {
        let s = noise(64, 64, 2);
        let out = noise(80, 80, 3);
        assert_eq!(verbatim(&s, &out), Some(0.0));
    }

    #[test]
    fn partial_copies_match_brute_force() {
        // Left half copied from the sample, right half noise; also a low-entropy image where
        // many windows repeat.
        let s = noise(30, 30, 4);
        let n = noise(40, 25, 5);
        let out = RgbImage::from_fn(40, 25, |x, y| if x < 20 { s.get(x + 3, y + 2) } else { n.get(x, y) });
        let got = verbatim(&s, &out).unwrap();
        assert_eq!(Some(got), brute(&s, &out, 7));
        assert!(got > 0.3 && got < 0.6, "{got}");
        let s2 = RgbImage::from_fn(20, 20, |x, y| [((x / 3 + y / 5) % 2) as u8 * 200, 0, 0]);
        let o2 = RgbImage::from_fn(26, 22, |x, y| [((x / 3 + y / 4) % 2) as u8 * 200, 0, 0]);
        assert_eq!(verbatim(&s2, &o2), brute(&s2, &o2, 7));
        assert_eq!(verbatim_fraction(&s2, &o2, 3), brute(&s2, &o2, 3));
    }

    #[test]
    fn hash_collisions_never_count_as_matches() {
        // With only 4 distinct hash values nearly every lookup collides; the exact comparison
        // must keep the result equal to brute force.
        let s = noise(30, 30, 8);
        let n = noise(40, 25, 9);
        let out = RgbImage::from_fn(40, 25, |x, y| if y < 12 { s.get(x / 2 + 5, y + 10) } else { n.get(x, y) });
        let exact = brute(&s, &out, 7);
        assert_eq!(verbatim_fraction_masked(&s, &out, 7, 0b11), exact);
        assert_eq!(verbatim_fraction_masked(&s, &out, 7, 0), exact);
        assert_eq!(verbatim_fraction(&s, &out, 7), exact);
        let copy = s.crop(2, 3, 20, 20);
        assert_eq!(verbatim_fraction_masked(&s, &copy, 7, 0b11), Some(1.0));
    }

    #[test]
    fn small_images() {
        let s = noise(6, 20, 6);
        let out = noise(10, 10, 7);
        assert_eq!(verbatim(&s, &out), Some(0.0));
        assert_eq!(verbatim(&out, &s), None);
    }
}
