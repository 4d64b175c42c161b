//! The one in-memory pixel representation every method works on.
//!
//! Samples are reduced to 8-bit RGB on decode (alpha dropped, 16-bit and float inputs quantised),
//! so that colour errors are exact integers (docs/methods.md §0) and so that a method never needs to
//! know what format the job asked for on output: bit depth and file format are chosen at encode
//! time by `imageio`.

/// An 8-bit RGB image, row-major, `y` downwards, 3 bytes per pixel.
#[derive(Clone, PartialEq, Eq)]
pub struct RgbImage {
    width: u32,
    height: u32,
    data: Vec<u8>,
}

impl std::fmt::Debug for RgbImage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "RgbImage({}x{})", self.width, self.height)
    }
}

impl RgbImage {
    /// A black image.
    pub fn new(width: u32, height: u32) -> Self {
        RgbImage { width, height, data: vec![0; width as usize * height as usize * 3] }
    }

    /// Wraps raw RGB bytes; `None` when the length does not match the size.
    pub fn from_raw(width: u32, height: u32, data: Vec<u8>) -> Option<Self> {
        (data.len() == width as usize * height as usize * 3).then_some(RgbImage { width, height, data })
    }

    /// Builds an image from a per-pixel function (row-major order of calls).
    pub fn from_fn(width: u32, height: u32, mut f: impl FnMut(u32, u32) -> [u8; 3]) -> Self {
        let mut img = RgbImage::new(width, height);
        for y in 0..height {
            for x in 0..width {
                img.put(x, y, f(x, y));
            }
        }
        img
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
    /// All pixels, row-major RGB.
    pub fn as_raw(&self) -> &[u8] {
        &self.data
    }
    pub fn as_raw_mut(&mut self) -> &mut [u8] {
        &mut self.data
    }
    pub fn into_raw(self) -> Vec<u8> {
        self.data
    }

    #[inline]
    fn index(&self, x: u32, y: u32) -> usize {
        debug_assert!(x < self.width && y < self.height, "({x},{y}) outside {}x{}", self.width, self.height);
        (y as usize * self.width as usize + x as usize) * 3
    }

    #[inline]
    pub fn get(&self, x: u32, y: u32) -> [u8; 3] {
        let i = self.index(x, y);
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }

    #[inline]
    pub fn put(&mut self, x: u32, y: u32, p: [u8; 3]) {
        let i = self.index(x, y);
        self.data[i..i + 3].copy_from_slice(&p);
    }

    /// One row as RGB bytes.
    #[inline]
    pub fn row(&self, y: u32) -> &[u8] {
        let w = self.width as usize * 3;
        &self.data[y as usize * w..(y as usize + 1) * w]
    }

    /// The top-left `w × h` of the image, made in place: the same pixels as `crop(0, 0, w, h)`
    /// without a second image in memory (how the canvas methods trim their canvas to the output).
    pub fn into_top_left(mut self, w: u32, h: u32) -> RgbImage {
        assert!(w <= self.width && h <= self.height, "crop outside the image");
        if w == self.width && h == self.height {
            return self;
        }
        let (src_w, dst_w) = (self.width as usize * 3, w as usize * 3);
        // Row r moves from r·src_w to r·dst_w ≤ r·src_w: front to back never overwrites a row
        // before it has moved.
        for r in 0..h as usize {
            self.data.copy_within(r * src_w..r * src_w + dst_w, r * dst_w);
        }
        self.data.truncate(dst_w * h as usize);
        self.data.shrink_to_fit();
        RgbImage { width: w, height: h, data: self.data }
    }

    /// A copy of the rectangle `[x, x+w) × [y, y+h)`, which must lie inside the image.
    pub fn crop(&self, x: u32, y: u32, w: u32, h: u32) -> RgbImage {
        assert!(x + w <= self.width && y + h <= self.height, "crop outside the image");
        let mut out = RgbImage::new(w, h);
        for r in 0..h {
            let src = &self.row(y + r)[x as usize * 3..(x + w) as usize * 3];
            let dst_w = w as usize * 3;
            out.data[r as usize * dst_w..(r as usize + 1) * dst_w].copy_from_slice(src);
        }
        out
    }

    /// Per box side in `sides` (each at most the image's shorter side): the share of the image's
    /// colour variance left in the means of `side × side` windows, i.e. carried by features that
    /// large: the variance of the window means over all windows inside the image, summed over the
    /// channels, over the channels' summed variance.
    pub fn large_feature_shares(&self, sides: &[usize]) -> Vec<(usize, f64)> {
        let (w, h) = (self.width as usize, self.height as usize);
        let raw = &self.data;
        let (mut total, mut low) = (0.0, vec![0.0; sides.len()]);
        for c in 0..3 {
            // Summed-area table of the channel, (w + 1) × (h + 1); integer, so exact.
            let mut sat = vec![0u64; (w + 1) * (h + 1)];
            for y in 0..h {
                let mut row = 0u64;
                for x in 0..w {
                    row += u64::from(raw[(y * w + x) * 3 + c]);
                    sat[(y + 1) * (w + 1) + x + 1] = sat[y * (w + 1) + x + 1] + row;
                }
            }
            let sq: u64 = raw.iter().skip(c).step_by(3).map(|&v| u64::from(v) * u64::from(v)).sum();
            let n = (w * h) as f64;
            let mean = sat[(w + 1) * (h + 1) - 1] as f64 / n;
            total += (sq as f64 / n - mean * mean).max(0.0);
            for (k, &b) in sides.iter().enumerate() {
                let (mut s, mut s2, mut count) = (0.0, 0.0, 0.0);
                for y in 0..=h - b {
                    for x in 0..=w - b {
                        let (a, d) = (y * (w + 1), (y + b) * (w + 1));
                        let m = (sat[d + x + b] + sat[a + x] - sat[d + x] - sat[a + x + b]) as f64 / (b * b) as f64;
                        s += m;
                        s2 += m * m;
                        count += 1.0;
                    }
                }
                let m = s / count;
                low[k] += (s2 / count - m * m).max(0.0);
            }
        }
        sides.iter().zip(low).map(|(&b, l)| (b, if total > 0.0 { l / total } else { 0.0 })).collect()
    }

    /// Gray level `(R+G+B)/3` on unit scale, row-major (docs/methods.md B6: gray is `I`, not luma).
    pub fn gray_unit(&self) -> Vec<f64> {
        self.data.chunks_exact(3).map(|p| (p[0] as f64 + p[1] as f64 + p[2] as f64) / (3.0 * 255.0)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crop_copies_the_right_pixels() {
        let img = RgbImage::from_fn(5, 4, |x, y| [x as u8, y as u8, (x * y) as u8]);
        let c = img.crop(1, 2, 3, 2);
        for (w, h) in [(5, 4), (3, 2), (5, 1), (1, 4), (2, 3)] {
            assert_eq!(img.clone().into_top_left(w, h), img.crop(0, 0, w, h), "{w}x{h}");
        }
        assert_eq!(c.dimensions(), (3, 2));
        assert_eq!(c.get(0, 0), [1, 2, 2]);
        assert_eq!(c.get(2, 1), [3, 3, 9]);
    }

    #[test]
    fn from_raw_checks_length() {
        assert!(RgbImage::from_raw(2, 2, vec![0; 12]).is_some());
        assert!(RgbImage::from_raw(2, 2, vec![0; 11]).is_none());
    }
}
