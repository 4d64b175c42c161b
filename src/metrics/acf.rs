//! Autocorrelation by FFT with zero padding (docs/methods.md B9).
//!
//! For a plane `f` of `W × H` and offsets `|dx| ≤ Rx`, `|dy| ≤ Ry`:
//!
//! ```text
//! S(dx, dy) = Σ_{p, p+(dx,dy) both inside} f(p) · conj f(p + (dx, dy))
//! N(dx, dy) = (W − |dx|)(H − |dy|)
//! ```
//!
//! `S` is computed with a 2-D FFT of the plane zero-padded to at least `(W + Rx) × (H + Ry)`, so
//! there is no wrap-around. The FFT is rustfft's scalar planner (no SIMD-dependent algorithm
//! choice), so values do not depend on the CPU's instruction-set extensions, and nothing here is
//! multi-threaded. The computed `S` is made exactly (conjugate-)symmetric by computing one half of
//! the offset window and mirroring it: `S(−d) = conj S(d)`, and `S` is exactly real for a real
//! plane.

use rustfft::FftPlannerScalar;
use rustfft::num_complex::Complex64;

/// Which normalisation of `S` to return (B9).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AcfForm {
    /// `S / S(0,0)`.
    Biased,
    /// `(S/N) / (S(0,0)/(W·H))`: the mean over the overlap, 1 at the origin.
    OverlapMean,
    /// `S / N`: the mean over the overlap, not normalised.
    RawOverlapMean,
}

/// Why an autocorrelation could not be computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AcfError {
    /// `Rx ≥ W` or `Ry ≥ H` (including an empty plane): some offsets have no overlapping pixel.
    OffsetsOutsidePlane,
    /// A normalised form was asked of a plane that is identically zero (`S(0,0) = 0`), e.g. a
    /// constant image after mean subtraction.
    ZeroPlane,
}

impl std::fmt::Display for AcfError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            AcfError::OffsetsOutsidePlane => write!(f, "autocorrelation offsets reach outside the plane"),
            AcfError::ZeroPlane => write!(f, "autocorrelation of an identically zero plane is undefined"),
        }
    }
}

impl std::error::Error for AcfError {}

/// An autocorrelation over the offsets `−rx..=rx` × `−ry..=ry`, stored row-major with `dy` outer
/// (from `−ry`) and `dx` inner (from `−rx`).
#[derive(Clone, Debug, PartialEq)]
pub struct Acf<T> {
    rx: usize,
    ry: usize,
    values: Vec<T>,
}

impl<T: Copy> Acf<T> {
    pub fn rx(&self) -> usize {
        self.rx
    }
    pub fn ry(&self) -> usize {
        self.ry
    }
    /// Number of offsets along `x`: `2·rx + 1`.
    pub fn width(&self) -> usize {
        2 * self.rx + 1
    }
    /// Number of offsets along `y`: `2·ry + 1`.
    pub fn height(&self) -> usize {
        2 * self.ry + 1
    }
    /// All values, row-major (`dy` outer, `dx` inner, both ascending from the negative bound).
    pub fn values(&self) -> &[T] {
        &self.values
    }
    pub fn into_values(self) -> Vec<T> {
        self.values
    }
    /// The value at offset `(dx, dy)`; panics outside the window.
    pub fn get(&self, dx: i64, dy: i64) -> T {
        assert!(
            dx.unsigned_abs() as usize <= self.rx && dy.unsigned_abs() as usize <= self.ry,
            "offset ({dx}, {dy}) outside the ACF window ±({}, {})",
            self.rx,
            self.ry
        );
        let col = (dx + self.rx as i64) as usize;
        let row = (dy + self.ry as i64) as usize;
        self.values[row * self.width() + col]
    }
    /// The same offsets with `f` applied to every value.
    pub fn map<U>(&self, f: impl FnMut(&T) -> U) -> Acf<U> {
        Acf { rx: self.rx, ry: self.ry, values: self.values.iter().map(f).collect() }
    }
}

/// The smallest `n' ≥ n` of the form `2^a·3^b·5^c` (fast FFT lengths).
/// The bytes one [`AcfPlanner`] holds at its peak for an autocorrelation of a `w × h` plane with
/// offsets up to `(rx, ry)` ([`AcfPlanner::real`]): the row and column planes of the padded
/// transform (complex), the FFTs' scratch and the window it returns. The memory model counts the
/// lattice extraction by it.
pub fn real_working_set(w: usize, h: usize, rx: usize, ry: usize) -> u64 {
    let (pw, ph) = (fft_size(w + rx), fft_size(h + ry));
    let complex = std::mem::size_of::<Complex64>() as u64;
    complex * (h.max(ry + 1) * pw + pw * ph + pw.max(ph)) as u64 + 8 * ((2 * rx + 1) * (2 * ry + 1)) as u64
}

fn fft_size(n: usize) -> usize {
    let mut m = n.max(1);
    loop {
        let mut r = m;
        for p in [2, 3, 5] {
            while r.is_multiple_of(p) {
                r /= p;
            }
        }
        if r == 1 {
            return m;
        }
        m += 1;
    }
}

/// The raw sums `S(dx, dy)` of B9 for a complex plane (`w × h`, row-major), by FFT.
///
/// Panics if `plane.len() != w·h`.
pub fn autocorrelation_sums(plane: &[Complex64], w: usize, h: usize, rx: usize, ry: usize) -> Result<Acf<Complex64>, AcfError> {
    AcfPlanner::new().sums(plane, w, h, rx, ry)
}

/// Autocorrelation of a real plane (`w × h`, row-major) in the requested form (B9).
///
/// Errors: [`AcfError::OffsetsOutsidePlane`] when `rx ≥ w` or `ry ≥ h`; [`AcfError::ZeroPlane`]
/// for a normalised form of an identically zero plane. Panics if `plane.len() != w·h`.
pub fn autocorrelation(plane: &[f64], w: usize, h: usize, rx: usize, ry: usize, form: AcfForm) -> Result<Acf<f64>, AcfError> {
    AcfPlanner::new().real(plane, w, h, rx, ry, form)
}

/// Autocorrelation of a complex plane (`w × h`, row-major) in the requested form (B9); the value
/// at `−d` is the conjugate of the value at `d`.
///
/// Errors and panics as for [`autocorrelation`].
pub fn autocorrelation_complex(
    plane: &[Complex64],
    w: usize,
    h: usize,
    rx: usize,
    ry: usize,
    form: AcfForm,
) -> Result<Acf<Complex64>, AcfError> {
    AcfPlanner::new().complex(plane, w, h, rx, ry, form)
}

/// Computes several autocorrelations with the same FFT plans and buffers: a caller taking the
/// autocorrelations of several planes (the lattice extraction's views of one sample) plans each
/// FFT length once and allocates its buffers once. The values are those of the free functions
/// ([`autocorrelation`], [`autocorrelation_complex`], [`autocorrelation_sums`]), bit for bit: the
/// same FFTs on the same data, and the same operations on each value.
pub struct AcfPlanner {
    planner: FftPlannerScalar<f64>,
    /// The padded plane transformed along rows, `h × pw`; once transposed into `cols`, the same
    /// buffer takes the rows `dy ∈ 0..=ry` of the inverse transform, `(ry + 1) × pw` (`ry < h`),
    /// so that a transform holds two planes, not three ([`real_working_set`]).
    rows: Vec<Complex64>,
    /// Its transpose, `pw × ph`.
    cols: Vec<Complex64>,
    scratch: Vec<Complex64>,
}

impl std::default::Default for AcfPlanner {
    fn default() -> Self {
        AcfPlanner::new()
    }
}

impl AcfPlanner {
    pub fn new() -> Self {
        AcfPlanner { planner: FftPlannerScalar::new(), rows: Vec::new(), cols: Vec::new(), scratch: Vec::new() }
    }

    /// [`autocorrelation`].
    pub fn real(&mut self, plane: &[f64], w: usize, h: usize, rx: usize, ry: usize, form: AcfForm) -> Result<Acf<f64>, AcfError> {
        assert_eq!(plane.len(), w * h, "plane length does not match {w}x{h}");
        let (r, pw, scale) = self.transform(w, h, rx, ry, |y, row| {
            for (c, &v) in row.iter_mut().zip(&plane[y * w..(y + 1) * w]) {
                *c = Complex64::new(v, 0.0);
            }
        })?;
        // As `sums_to_acf` then `normalise` then `.re`, on the real parts only: `S(d)` is
        // `conj R(d)` (`d` in the canonical half) or `R(−d)`, with `R` scaled by `1 / scale`
        // per part, and dividing a complex value by a real one divides each part.
        let s00 = r[0].re / scale;
        let is_zero = plane.iter().all(|&v| v == 0.0);
        if form != AcfForm::RawOverlapMean && (is_zero || s00.is_nan() || s00 <= 0.0) {
            return Err(AcfError::ZeroPlane);
        }
        let (aw, ah) = (2 * rx + 1, 2 * ry + 1);
        let whf = (w * h) as f64;
        let mut values = vec![0.0; aw * ah];
        // The rows dy ≥ 0, dx ascending from −rx: `R` at (dx, dy) in the canonical half (dy > 0,
        // or dy = 0 and dx ≥ 0), at (−dx, 0) on the rest of row 0 (dx < 0: column pw + dx of
        // R's rows).
        for dy in 0..=ry {
            let r_row = &r[dy * pw..(dy + 1) * pw];
            let out = &mut values[(ry + dy) * aw..(ry + dy + 1) * aw];
            let (neg, nonneg) = out.split_at_mut(rx);
            let neg_src: Vec<f64> =
                if dy == 0 { r_row[1..=rx].iter().rev().map(|c| c.re).collect() } else { r_row[pw - rx..].iter().map(|c| c.re).collect() };
            let rows_n = h - dy;
            for (i, (o, &re)) in neg.iter_mut().zip(&neg_src).enumerate() {
                let adx = rx - i;
                *o = finish(re / scale, s00, form, || ((w - adx) * rows_n) as f64, whf);
            }
            for (adx, (o, c)) in nonneg.iter_mut().zip(&r_row[..=rx]).enumerate() {
                *o = finish(c.re / scale, s00, form, || ((w - adx) * rows_n) as f64, whf);
            }
        }
        // The rows dy < 0 mirror them: the value at −d is computed from the same `R` value with
        // the same overlap, so it is the same.
        for dy in 1..=ry {
            let (top, bottom) = values.split_at_mut(ry * aw);
            let src = &bottom[dy * aw..(dy + 1) * aw];
            let dst = &mut top[(ry - dy) * aw..(ry - dy + 1) * aw];
            for (d, &v) in dst.iter_mut().zip(src.iter().rev()) {
                *d = v;
            }
        }
        Ok(Acf { rx, ry, values })
    }

    /// [`autocorrelation_complex`].
    pub fn complex(
        &mut self,
        plane: &[Complex64],
        w: usize,
        h: usize,
        rx: usize,
        ry: usize,
        form: AcfForm,
    ) -> Result<Acf<Complex64>, AcfError> {
        let sums = self.sums(plane, w, h, rx, ry)?;
        let is_zero = plane.iter().all(|v| v.re == 0.0 && v.im == 0.0);
        normalise(sums, w, h, form, is_zero)
    }

    /// [`autocorrelation_sums`].
    pub fn sums(&mut self, plane: &[Complex64], w: usize, h: usize, rx: usize, ry: usize) -> Result<Acf<Complex64>, AcfError> {
        assert_eq!(plane.len(), w * h, "plane length does not match {w}x{h}");
        let (r, pw, scale) = self.transform(w, h, rx, ry, |y, row| row.copy_from_slice(&plane[y * w..(y + 1) * w]))?;
        // R(dx, dy) = Σ_p f(p + d) · conj f(p) (circular, but no wrap thanks to the padding);
        // S(d) = conj R(d), and S(−d) = conj S(d) = R(d): every value comes from a row dy ≥ 0.
        let r_at = |dx: i64, dy: i64| -> Complex64 {
            debug_assert!(dy >= 0);
            let v = r[dy as usize * pw + dx.rem_euclid(pw as i64) as usize];
            Complex64::new(v.re / scale, v.im / scale)
        };
        let aw = 2 * rx + 1;
        let ah = 2 * ry + 1;
        let mut values = vec![Complex64::new(0.0, 0.0); aw * ah];
        let (rxi, ryi) = (rx as i64, ry as i64);
        for dy in -ryi..=ryi {
            for dx in -rxi..=rxi {
                // Canonical half: dy > 0, or dy = 0 and dx ≥ 0; the other half mirrors it.
                let canonical = dy > 0 || (dy == 0 && dx >= 0);
                let s = if canonical { r_at(dx, dy).conj() } else { r_at(-dx, -dy) };
                values[(dy + ryi) as usize * aw + (dx + rxi) as usize] = s;
            }
        }
        // S(0,0) = Σ |f|² is real.
        values[ry * aw + rx].im = 0.0;
        Ok(Acf { rx, ry, values })
    }

    /// The unscaled circular autocorrelation `R` of the plane whose row `y` `fill(y, row)` writes
    /// into `row`, zero-padded to `pw × ph`: its rows `dy ∈ 0..=ry` (`(ry + 1) × pw`, row-major),
    /// with `pw` and the scale `pw·ph` that divides it.
    fn transform(
        &mut self,
        w: usize,
        h: usize,
        rx: usize,
        ry: usize,
        fill: impl Fn(usize, &mut [Complex64]),
    ) -> Result<(&[Complex64], usize, f64), AcfError> {
        if rx >= w || ry >= h {
            return Err(AcfError::OffsetsOutsidePlane);
        }
        let pw = fft_size(w + rx);
        let ph = fft_size(h + ry);
        let zero = Complex64::new(0.0, 0.0);
        let row_fwd = self.planner.plan_fft_forward(pw);
        let row_inv = self.planner.plan_fft_inverse(pw);
        let col_fwd = self.planner.plan_fft_forward(ph);
        let col_inv = self.planner.plan_fft_inverse(ph);
        let scratch_len = [&row_fwd, &row_inv, &col_fwd, &col_inv].iter().map(|f| f.get_inplace_scratch_len()).max().unwrap_or(0);
        if self.scratch.len() < scratch_len {
            self.scratch.resize(scratch_len, zero);
        }
        let scratch = &mut self.scratch[..scratch_len];

        // The padded plane's rows 0..h (rows h.. are zero, and stay zero along rows), forward
        // along rows.
        let buf = &mut self.rows;
        buf.clear();
        buf.resize(h * pw, zero);
        for y in 0..h {
            fill(y, &mut buf[y * pw..y * pw + w]);
        }
        row_fwd.process_with_scratch(buf, scratch);
        // Transpose to pw rows of ph, forward along columns, power spectrum, inverse along columns.
        // Copied in square tiles so that both planes are walked a cache line at a time; rows h..
        // are zero.
        let t = &mut self.cols;
        t.resize(pw * ph, zero);
        let t = &mut t[..pw * ph];
        const TILE: usize = 32;
        for y0 in (0..h).step_by(TILE) {
            for x0 in (0..pw).step_by(TILE) {
                for y in y0..(y0 + TILE).min(h) {
                    let src = &buf[y * pw..(y + 1) * pw];
                    for x in x0..(x0 + TILE).min(pw) {
                        t[x * ph + y] = src[x];
                    }
                }
            }
        }
        for column in t.chunks_exact_mut(ph) {
            column[h..].fill(zero);
        }
        col_fwd.process_with_scratch(t, scratch);
        for v in t.iter_mut() {
            *v = Complex64::new(v.re * v.re + v.im * v.im, 0.0);
        }
        col_inv.process_with_scratch(t, scratch);
        // Back to row-major, but only the rows dy ∈ 0..=ry are needed: the autocorrelation of
        // the other half of the window is read off these (`S(−d) = conj S(d)`).
        let rows = &mut self.rows;
        rows.clear();
        rows.resize((ry + 1) * pw, zero);
        for r0 in (0..=ry).step_by(TILE) {
            for x0 in (0..pw).step_by(TILE) {
                for x in x0..(x0 + TILE).min(pw) {
                    let src = &t[x * ph..(x + 1) * ph];
                    for r in r0..(r0 + TILE).min(ry + 1) {
                        rows[r * pw + x] = src[r];
                    }
                }
            }
        }
        row_inv.process_with_scratch(rows, scratch);
        Ok((&self.rows, pw, (pw * ph) as f64))
    }
}

/// The real part of [`normalise`]'s value from the real part `s` of a sum, `s00` the origin's
/// and `n` the overlap: dividing a complex value by a real one divides each part alone.
#[inline(always)]
fn finish(s: f64, s00: f64, form: AcfForm, n: impl Fn() -> f64, whf: f64) -> f64 {
    match form {
        AcfForm::Biased => s / s00,
        AcfForm::OverlapMean => (s / n()) / (s00 / whf),
        AcfForm::RawOverlapMean => s / n(),
    }
}

fn normalise(sums: Acf<Complex64>, w: usize, h: usize, form: AcfForm, plane_is_zero: bool) -> Result<Acf<Complex64>, AcfError> {
    let s00 = sums.get(0, 0).re;
    if form != AcfForm::RawOverlapMean && (plane_is_zero || s00.is_nan() || s00 <= 0.0) {
        return Err(AcfError::ZeroPlane);
    }
    let (rx, ry) = (sums.rx as i64, sums.ry as i64);
    let whf = (w * h) as f64;
    let mut out = sums.clone();
    let aw = sums.width();
    for dy in -ry..=ry {
        for dx in -rx..=rx {
            let i = (dy + ry) as usize * aw + (dx + rx) as usize;
            let s = sums.values[i];
            let n = ((w - dx.unsigned_abs() as usize) * (h - dy.unsigned_abs() as usize)) as f64;
            out.values[i] = match form {
                AcfForm::Biased => s / s00,
                AcfForm::OverlapMean => (s / n) / (s00 / whf),
                AcfForm::RawOverlapMean => s / n,
            };
        }
    }
    Ok(out)
}

/// Euclidean norm of the element-wise difference of two equally shaped arrays, summed in index
/// order.
pub fn euclidean_distance(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len(), "arrays of different lengths");
    let mut sum = 0.0f64;
    for (x, y) in a.iter().zip(b) {
        let d = x - y;
        sum += d * d;
    }
    sum.sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Brute-force double sum of B9.
    fn brute_sums(plane: &[Complex64], w: usize, h: usize, rx: usize, ry: usize) -> Vec<Complex64> {
        let mut out = Vec::new();
        for dy in -(ry as i64)..=ry as i64 {
            for dx in -(rx as i64)..=rx as i64 {
                let mut s = Complex64::new(0.0, 0.0);
                for y in 0..h as i64 {
                    for x in 0..w as i64 {
                        let (x2, y2) = (x + dx, y + dy);
                        if x2 >= 0 && y2 >= 0 && x2 < w as i64 && y2 < h as i64 {
                            s += plane[(y * w as i64 + x) as usize] * plane[(y2 * w as i64 + x2) as usize].conj();
                        }
                    }
                }
                out.push(s);
            }
        }
        out
    }

    fn lcg_plane(n: usize, seed: u64) -> Vec<f64> {
        // A tiny local generator: the test must not depend on stream layouts elsewhere.
        let mut s = seed;
        (0..n)
            .map(|_| {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                ((s >> 11) as f64 / (1u64 << 53) as f64) - 0.5
            })
            .collect()
    }

    #[test]
    fn the_stated_working_set_covers_the_planners_buffers() {
        // The memory model counts the lattice extraction by `real_working_set`: it must cover what
        // a planner really holds after an autocorrelation, and not by a wide margin.
        for (w, h) in [(64usize, 48usize), (200, 150), (257, 129)] {
            let (rx, ry) = (w / 2, h / 2);
            let mut planner = AcfPlanner::new();
            let acf = planner.real(&lcg_plane(w * h, 3), w, h, rx, ry, AcfForm::Biased).unwrap();
            let complex = std::mem::size_of::<Complex64>();
            let held =
                complex * (planner.rows.capacity() + planner.cols.capacity() + planner.scratch.capacity()) + 8 * acf.width() * acf.height();
            let stated = real_working_set(w, h, rx, ry) as usize;
            assert!(held <= stated && stated <= held + held / 8, "{w}x{h}: holds {held} B, stated {stated} B");
        }
    }

    #[test]
    fn fft_sizes_are_smooth_and_minimal() {
        assert_eq!(fft_size(272), 288);
        assert_eq!(fft_size(402), 405);
        assert_eq!(fft_size(7), 8);
        assert_eq!(fft_size(1), 1);
    }

    #[test]
    fn real_forms_match_brute_force() {
        let (w, h, rx, ry) = (11usize, 7usize, 4usize, 6usize);
        let plane = lcg_plane(w * h, 1);
        let cplx: Vec<Complex64> = plane.iter().map(|&v| Complex64::new(v, 0.0)).collect();
        let brute = brute_sums(&cplx, w, h, rx, ry);
        let s00 = brute[ry * (2 * rx + 1) + rx].re;
        for form in [AcfForm::Biased, AcfForm::OverlapMean, AcfForm::RawOverlapMean] {
            let acf = autocorrelation(&plane, w, h, rx, ry, form).unwrap();
            let mut i = 0;
            for dy in -(ry as i64)..=ry as i64 {
                for dx in -(rx as i64)..=rx as i64 {
                    let n = ((w - dx.unsigned_abs() as usize) * (h - dy.unsigned_abs() as usize)) as f64;
                    let s = brute[i].re;
                    let expect = match form {
                        AcfForm::Biased => s / s00,
                        AcfForm::OverlapMean => (s / n) / (s00 / (w * h) as f64),
                        AcfForm::RawOverlapMean => s / n,
                    };
                    let got = acf.get(dx, dy);
                    assert!((got - expect).abs() < 1e-12, "{form:?} ({dx},{dy}): {got} vs {expect}");
                    assert_eq!(got, acf.get(-dx, -dy), "real ACF must be exactly symmetric");
                    i += 1;
                }
            }
        }
        // Origin of the normalised forms is exactly 1.
        assert_eq!(autocorrelation(&plane, w, h, rx, ry, AcfForm::Biased).unwrap().get(0, 0), 1.0);
        assert_eq!(autocorrelation(&plane, w, h, rx, ry, AcfForm::OverlapMean).unwrap().get(0, 0), 1.0);
    }

    #[test]
    fn complex_forms_match_brute_force() {
        let (w, h, rx, ry) = (9usize, 10usize, 8usize, 3usize);
        let re = lcg_plane(w * h, 2);
        let im = lcg_plane(w * h, 3);
        let plane: Vec<Complex64> = re.iter().zip(&im).map(|(&a, &b)| Complex64::new(a, b)).collect();
        let brute = brute_sums(&plane, w, h, rx, ry);
        let s00 = brute[ry * (2 * rx + 1) + rx].re;
        for form in [AcfForm::Biased, AcfForm::OverlapMean, AcfForm::RawOverlapMean] {
            let acf = autocorrelation_complex(&plane, w, h, rx, ry, form).unwrap();
            let mut i = 0;
            for dy in -(ry as i64)..=ry as i64 {
                for dx in -(rx as i64)..=rx as i64 {
                    let n = ((w - dx.unsigned_abs() as usize) * (h - dy.unsigned_abs() as usize)) as f64;
                    let s = brute[i];
                    let expect = match form {
                        AcfForm::Biased => s / s00,
                        AcfForm::OverlapMean => (s / n) / (s00 / (w * h) as f64),
                        AcfForm::RawOverlapMean => s / n,
                    };
                    let got = acf.get(dx, dy);
                    assert!((got - expect).norm() < 1e-12, "{form:?} ({dx},{dy}): {got} vs {expect}");
                    assert_eq!(got, acf.get(-dx, -dy).conj(), "complex ACF must be conjugate-symmetric");
                    i += 1;
                }
            }
        }
    }

    #[test]
    fn the_real_path_is_the_complex_one_bit_for_bit_and_a_planner_can_be_reused() {
        let mut planner = AcfPlanner::new();
        for (k, (w, h, rx, ry)) in
            [(11usize, 7usize, 4usize, 6usize), (40, 33, 20, 16), (9, 10, 8, 3), (40, 33, 20, 16), (64, 48, 0, 24)].into_iter().enumerate()
        {
            let plane = lcg_plane(w * h, 10 + k as u64);
            let cplx: Vec<Complex64> = plane.iter().map(|&v| Complex64::new(v, 0.0)).collect();
            for form in [AcfForm::Biased, AcfForm::OverlapMean, AcfForm::RawOverlapMean] {
                let real = planner.real(&plane, w, h, rx, ry, form).unwrap();
                let complex = AcfPlanner::new().complex(&cplx, w, h, rx, ry, form).unwrap();
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(real.values()), bits(complex.map(|c| c.re).values()), "{w}x{h} ±({rx}, {ry}) {form:?}");
                assert_eq!(real, autocorrelation(&plane, w, h, rx, ry, form).unwrap());
                assert_eq!(planner.complex(&cplx, w, h, rx, ry, form).unwrap(), complex);
            }
        }
    }

    #[test]
    fn periodic_plane_has_acf_peaks_at_the_period() {
        // Period 6 along x, 4 along y; mean zero.
        let (w, h) = (60usize, 40usize);
        let plane: Vec<f64> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                (2.0 * std::f64::consts::PI * x / 6.0).cos() + (2.0 * std::f64::consts::PI * y / 4.0).cos()
            })
            .collect();
        let acf = autocorrelation(&plane, w, h, 13, 9, AcfForm::OverlapMean).unwrap();
        // The overlap mean of a perfectly periodic plane repeats with the period.
        for (dx, dy) in [(6, 0), (12, 0), (0, 4), (0, 8), (6, 4), (-6, 8), (12, -4)] {
            assert!((acf.get(dx, dy) - 1.0).abs() < 0.02, "({dx},{dy}) = {}", acf.get(dx, dy));
        }
        // Half a period is a trough.
        assert!(acf.get(3, 0) < 0.1);
        assert!(acf.get(0, 2) < 0.1);
        // x peaks: strict local maxima along the dx axis at multiples of 6.
        for dx in 1..=12i64 {
            let v = acf.get(dx, 0);
            if dx % 6 == 0 {
                assert!(v > acf.get(dx - 1, 0) && v > acf.get(dx + 1, 0));
            } else {
                assert!(v < acf.get(6, 0));
            }
        }
    }

    #[test]
    fn zero_plane_and_oversized_radius_are_errors() {
        let zero = vec![0.0; 20 * 20];
        assert_eq!(autocorrelation(&zero, 20, 20, 5, 5, AcfForm::OverlapMean), Err(AcfError::ZeroPlane));
        assert_eq!(autocorrelation(&zero, 20, 20, 5, 5, AcfForm::Biased), Err(AcfError::ZeroPlane));
        let raw = autocorrelation(&zero, 20, 20, 5, 5, AcfForm::RawOverlapMean).unwrap();
        assert!(raw.values().iter().all(|&v| v == 0.0));
        let plane = lcg_plane(20 * 20, 4);
        assert_eq!(autocorrelation(&plane, 20, 20, 20, 5, AcfForm::Biased), Err(AcfError::OffsetsOutsidePlane));
        assert!(autocorrelation(&plane, 20, 20, 19, 19, AcfForm::Biased).is_ok());
    }
}
