//! RGB → HSI (docs/methods.md B6, paper 003 eq. 1 with its two typos fixed).
//!
//! Paper 003 compares seams in HSI space. Its method copies pixels verbatim, so only the forward
//! conversion exists: the RGB pixels travel alongside the HSI planes.

use crate::image::RgbImage;

/// `(H/360, S, I)` of one pixel, each in `[0, 1]`.
pub fn hsi(p: [u8; 3]) -> (f64, f64, f64) {
    let (r, g, b) = (p[0] as f64 / 255.0, p[1] as f64 / 255.0, p[2] as f64 / 255.0);
    let sum = r + g + b;
    let i = sum / 3.0;
    let s = if sum == 0.0 { 0.0 } else { 1.0 - 3.0 * r.min(g).min(b) / sum };
    let num = ((r - g) + (r - b)) / 2.0;
    let den = ((r - g) * (r - g) + (r - b) * (g - b)).sqrt();
    let theta = if den == 0.0 { 0.0 } else { (num / den).clamp(-1.0, 1.0).acos().to_degrees() };
    let mut h = if b <= g { theta } else { 360.0 - theta };
    if h >= 360.0 {
        h = 0.0;
    }
    (h / 360.0, s, i)
}

/// The three planes of an image, row-major.
pub struct HsiPlanes {
    pub h: Vec<f64>,
    pub s: Vec<f64>,
    pub i: Vec<f64>,
}

impl HsiPlanes {
    pub fn of(img: &RgbImage) -> HsiPlanes {
        let n = img.as_raw().len() / 3;
        let mut planes = HsiPlanes { h: Vec::with_capacity(n), s: Vec::with_capacity(n), i: Vec::with_capacity(n) };
        for p in img.as_raw().chunks_exact(3) {
            let (h, s, i) = hsi([p[0], p[1], p[2]]);
            planes.h.push(h);
            planes.s.push(s);
            planes.i.push(i);
        }
        planes
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn primaries_and_gray() {
        let close = |a: f64, b: f64| (a - b).abs() < 1e-12;
        let (h, s, i) = hsi([255, 0, 0]);
        assert!(close(h, 0.0) && close(s, 1.0) && close(i, 1.0 / 3.0));
        let (h, s, _) = hsi([0, 255, 0]);
        assert!(close(h * 360.0, 120.0) && close(s, 1.0));
        let (h, s, _) = hsi([0, 0, 255]);
        assert!(close(h * 360.0, 240.0) && close(s, 1.0));
        let (h, s, i) = hsi([128, 128, 128]);
        assert!(close(h, 0.0) && close(s, 0.0) && close(i, 128.0 / 255.0));
        let (h, s, i) = hsi([0, 0, 0]);
        assert!(close(h, 0.0) && close(s, 0.0) && close(i, 0.0));
    }
}
