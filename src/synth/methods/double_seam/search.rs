//! Double-seam's search: the bounds that prune candidates (FFT correlations of the lines'
//! statistics, `FftBounds`), the exact scores of the lines that survive (`score_lines`), and the
//! pick among the best (`choose`). The method's drivers in `mod.rs` ask it for one block at a
//! time; it lives apart because it is most of the method's code and none of its bookkeeping.

use super::*;
/// [`choose`] bounds the candidates by FFT when more than 1/this of them survive the edge bound:
/// the I-channel transforms cost about as much as scoring that many in full.
pub(super) const FFT_BEYOND: usize = 16;

/// [`choose`] computes the H and S cross sums too when more than 1/this of the candidates survive
/// the I-channel bounds: their correlations (two more inverse 1-D transforms per sample column and
/// row reached) cost about as much as scoring that many in full.
pub(super) const FULL_BOUNDS_BEYOND: usize = 32;

/// Slack added to an upper bound of `F` before it may rule a candidate out: far above the few
/// ulps by which a computed Pearson correlation can exceed 1, far below any score difference
/// that matters.
pub(super) const BOUND_SLACK: f64 = 1e-7;

/// Whether a candidate whose `F` is at most `bound` may reach `theta` (a NaN bound may).
pub(super) fn may_reach(bound: f64, theta: f64) -> bool {
    (bound + BOUND_SLACK).partial_cmp(&theta) != Some(std::cmp::Ordering::Less)
}

/// How many candidates [`choose`] scores in full at once: independent sums to interleave.
pub(super) const LANES: usize = 4;

/// The candidate set and the pick of one grid position: the same as [`score_lines`] followed by
/// [`pick`], without scoring every candidate in full where that is not needed. `hints` are
/// positions likely to score well (the natural continuations of the neighbours); they are scored
/// in full first, which bounds `F_max` from below and so `θ` from below. `D_HSI ≤ α + β + γ`
/// bounds each line's `F_i` by the edge term alone, from the edge mismatches (exact integers):
/// every candidate whose bound (plus [`BOUND_SLACK`]) stays under that `θ` is out (its `F` is
/// below `θ`, so it is neither a member nor the maximum), and the rest are scored in full. When
/// the bound rules out too few, [`FftBounds`] bounds every candidate. Every full score is
/// computed with the same operations in the same order as [`score_lines`] (per channel the cross
/// sums are independent sums in line order; the candidate's statistics come from the shape's
/// table or [`exact_line_stats`], the same bits), so `F_max`, `θ` and the set are bit for bit the
/// same. The table of every candidate's statistics is built only once some search has many
/// survivors: most searches score a handful.
/// Which candidate positions (the block's top-left corner in the sample) a block may take: those
/// whose copied pixels the sample mask allows, and on a tileable output that keeps a lattice, those
/// in the first block's lattice phase.
pub(super) type Allowed<'a> = dyn Fn(i32, i32) -> bool + Sync + 'a;

/// Whether a block at `at` would show a turned or mirrored copy of a neighbour's pixels
/// ([`crate::synth::atlas::Atlas::twins`]).
pub(super) fn twin_of(req: &Request, (x, y): (i32, i32), neighbours: &[(u32, u32)], block: u32) -> bool {
    x >= 0 && y >= 0 && req.constraints.is_twin((x as u32, y as u32), neighbours, block)
}

/// Picks (sample positions) as the twin test takes them.
pub(super) fn non_negative(picks: impl Iterator<Item = (i32, i32)>) -> Vec<(u32, u32)> {
    picks.filter(|&(x, y)| x >= 0 && y >= 0).map(|(x, y)| (x as u32, y as u32)).collect()
}

#[allow(clippy::too_many_arguments)]
pub(super) fn choose(
    prep: &Prepared,
    s: &Settings,
    shape: &Shape,
    out: &Canvas,
    origin: (i32, i32),
    hints: &[(i32, i32)],
    (seed, bi, bj): (u64, u32, u32),
    allowed: Option<&Allowed<'_>>,
) -> Result<((i32, i32), usize, f64), SynthError> {
    let (ls, (xs, ys)) = (&shape.ls, shape.ranges.clone());
    let ok = |x: i32, y: i32| allowed.is_none_or(|a| a(x, y));
    let everything = || -> Result<((i32, i32), usize, f64), SynthError> {
        let (positions, scores) = score_lines(prep, s, ls, (xs.clone(), ys.clone()), shape.exact(prep, s), out, origin);
        if allowed.is_none() {
            return pick(s, &positions, &scores, seed, bi, bj);
        }
        let (positions, scores): (Vec<(i32, i32)>, Vec<f64>) = positions.into_iter().zip(scores).filter(|(p, _)| ok(p.0, p.1)).unzip();
        if positions.is_empty() {
            return Err(SynthError::Failed(format!(
                "no candidate position at grid ({bi}, {bj}) is allowed (sample mask, lattice phase) with its seam lines in the sample"
            )));
        }
        pick(s, &positions, &scores, seed, bi, bj)
    };
    if s.circular {
        return everything();
    }
    let outs = [output_line(out, s, origin, &ls[0]), output_line(out, s, origin, &ls[1])];
    let nx = (xs.end() - xs.start() + 1) as usize;
    let (x0, y0) = (*xs.start(), *ys.start());
    let ny = (ys.end() - ys.start() + 1).max(0) as usize;
    let w = prep.w as i32;
    let ns = [ls[0].len() as f64, ls[1].len() as f64];
    // Line offsets relative to a candidate's (x, y) in the sample (y·w + x ≥ every negative one).
    let offsets: [Vec<isize>; 2] = [0, 1].map(|li| ls[li].iter().map(|&(c, r)| (r * w + c) as isize).collect());
    let base_of = |k: usize| ((y0 + (k / nx) as i32) * w + x0) as isize + (k % nx) as isize;
    let mismatches_of = |k: usize, li: usize| -> u32 {
        let base = base_of(k);
        let o = &outs[li];
        offsets[li].iter().zip(&o.edges).map(|(&off, &e1)| u32::from(e1 != prep.edges[(base + off) as usize])).sum()
    };
    // The full scores of LANES candidates at once, each in exactly score_lines' order of
    // operations (the lanes only interleave independent sums, so each is the same bits).
    let full_lanes = |ks: [usize; LANES], mism: [[u32; 2]; LANES]| -> [f64; LANES] {
        let bases = ks.map(base_of);
        let mut f = [0.0; LANES];
        for li in 0..2 {
            let o = &outs[li];
            // The shape's table when a search has needed it, else the same values computed here.
            let stx = match shape.exact.get() {
                Some(table) => ks.map(|k| table[li][k]),
                None => exact_line_stats(prep, &offsets[li], bases),
            };
            let mut d = [0.0; LANES];
            for (kk, plane) in [&prep.planes.h, &prep.planes.s, &prep.planes.i].into_iter().enumerate() {
                let m2 = stx.map(|st| st[2 * kk]);
                let mut acc = [0.0; LANES];
                for (&c, &off) in o.centred[kk].iter().zip(&offsets[li]) {
                    for l in 0..LANES {
                        acc[l] += c * (plane[(bases[l] + off) as usize] - m2[l]);
                    }
                }
                for l in 0..LANES {
                    d[l] += s.weights[kk] * pearson_from(o.mean[kk], o.ss[kk], stx[l][2 * kk], stx[l][2 * kk + 1], acc[l]);
                }
            }
            for l in 0..LANES {
                if s.clamp {
                    d[l] = d[l].max(0.0);
                }
                let de = mism[l][li] as f64 / ns[li];
                f[l] += d[l] / (1.0 + s.mu * de);
                if s.level_penalty > 0.0 {
                    f[l] -= s.level_penalty * (o.mean[2] - stx[l][4]).abs();
                }
            }
        }
        f
    };
    let full = |k: usize, mism: [u32; 2]| -> f64 { full_lanes([k; LANES], [mism; LANES])[0] };
    // A lower bound of F_max from the hints, hence a lower bound of θ.
    let mut f_low = f64::NEG_INFINITY;
    for &(x, y) in hints {
        if xs.contains(&x) && ys.contains(&y) && ok(x, y) {
            let k = (y - y0) as usize * nx + (x - x0) as usize;
            f_low = f_low.max(full(k, [mismatches_of(k, 0), mismatches_of(k, 1)]));
        }
    }
    let theta_low = s.tau.min(f_low - s.eps);
    let cap = {
        let c = s.weights[0] + s.weights[1] + s.weights[2];
        if s.clamp { c.max(0.0) } else { c }
    };
    if nx == 0 || ny == 0 {
        return everything();
    }
    // Whether candidate `k` may be picked (all may without a restriction).
    let ok_k = |k: usize| ok(x0 + (k % nx) as i32, y0 + (k / nx) as i32);
    if allowed.is_some() && !(0..nx * ny).any(ok_k) {
        return everything();
    }
    // Edge mismatches of both lines for every candidate, by rows.
    let counters = [0, 1].map(|li| MismatchCounter::new(&ls[li], &offsets[li], &outs[li].edges));
    let mut mism = vec![[0u32; 2]; nx * ny];
    mism.par_chunks_mut(nx).enumerate().for_each_init(
        || (vec![0u32; nx], vec![0u32; nx]),
        |(sums, m), (row, dst)| {
            with_avx2(
                #[inline(always)]
                || {
                    for (li, counter) in counters.iter().enumerate() {
                        counter.row(prep, (x0, y0 + row as i32), base_of(row * nx) as usize, sums, m);
                        for (d, &v) in dst.iter_mut().zip(m.iter()) {
                            d[li] = v;
                        }
                    }
                },
            )
        },
    );
    // The level penalty is subtracted from every bound below (zero without one).
    let penalty = (s.level_penalty > 0.0).then(|| shape.bounds.penalty_low(s.level_penalty, [outs[0].mean[2], outs[1].mean[2]]));
    let penalty_of = |k: usize| penalty.as_ref().map_or(0.0, |p| p[k]);
    let mut survivors: Vec<usize> = Vec::new();
    let most_penalty = penalty.as_ref().map_or(0.0, |p| p.iter().copied().fold(0.0, f64::max));
    if theta_low > cap - most_penalty + BOUND_SLACK {
        // Below that a candidate with perfect lines (and the least penalty) can always reach θ:
        // the edge bound rules nothing out.
        // Each line's term depends on its mismatch count alone: one table per line, the same
        // bits as computing it per candidate.
        let edge_cap: [Vec<f64>; 2] = [0, 1].map(|li| (0..=ls[li].len()).map(|m| cap / (1.0 + s.mu * (m as f64 / ns[li]))).collect());
        survivors = mism
            .iter()
            .enumerate()
            .filter(|&(k, m)| may_reach(edge_cap[0][m[0] as usize] + edge_cap[1][m[1] as usize] - penalty_of(k), theta_low) && ok_k(k))
            .map(|(k, _)| k)
            .collect();
    }
    if survivors.is_empty() || survivors.len() * FFT_BEYOND > mism.len() {
        // The bounds from approximate scores: cross sums by FFT, within a rigorous margin; the
        // I channel first, all three where that leaves too many to score (all three at once
        // where most of this shape's earlier searches needed them).
        let mut fb = FftBounds::new(prep, s, ls, &outs, &shape.bounds, (x0, y0, nx, ny), &mism);
        let mut history = shape.fft_history.lock().expect("history");
        let penalise = |mut u: Vec<f64>| {
            if let Some(p) = &penalty {
                u.iter_mut().zip(p).for_each(|(u, p)| *u -= p);
            }
            if allowed.is_some() {
                // A position that may not be picked bounds nothing and survives nothing.
                u.iter_mut().enumerate().filter(|(k, _)| !ok_k(*k)).for_each(|(_, u)| *u = f64::NEG_INFINITY);
            }
            u
        };
        let mut u = penalise(if history.1 * 2 > history.0 { fb.all() } else { fb.intensity() });
        let mut hs = history.1 * 2 > history.0;
        loop {
            // The last of the largest, as `max_by` would pick.
            assert!(!u.is_empty(), "candidates");
            let mut best = 0;
            for (k, v) in u.iter().enumerate().skip(1) {
                if v.total_cmp(&u[best]) != std::cmp::Ordering::Less {
                    best = k;
                }
            }
            f_low = f_low.max(full(best, mism[best]));
            let theta_low = s.tau.min(f_low - s.eps);
            survivors = (0..u.len()).filter(|&k| may_reach(u[k], theta_low) && ok_k(k)).collect();
            if hs {
                break;
            }
            history.0 += 1;
            if survivors.len() <= mism.len() / FULL_BOUNDS_BEYOND {
                break;
            }
            history.1 += 1;
            u = penalise(fb.full());
            hs = true;
        }
    }
    if survivors.len() > mism.len() / 8 {
        // The table costs one pass per candidate; with the FFT bounds most searches score a few
        // hundred at most, so it pays only where one search leaves this many (at 1/64 it was
        // built for every shape on bricks and grass and cost more than it saved: bricks 512²
        // 0.40 → 0.34 s CPU).
        shape.exact(prep, s);
    }
    let scores: Vec<f64> = survivors
        .par_chunks(LANES * 16)
        .flat_map_iter(|part| {
            part.chunks(LANES).flat_map(|ks| {
                // A short last group repeats its last candidate.
                let lanes: [usize; LANES] = std::array::from_fn(|l| ks[l.min(ks.len() - 1)]);
                full_lanes(lanes, lanes.map(|k| mism[k])).into_iter().take(ks.len())
            })
        })
        .collect();
    let f_max = scores.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let theta = s.tau.min(f_max - s.eps);
    let members: Vec<(i32, i32)> =
        survivors.iter().zip(&scores).filter(|(_, f)| **f >= theta).map(|(&k, _)| (x0 + (k % nx) as i32, y0 + (k / nx) as i32)).collect();
    if members.is_empty() {
        return everything();
    }
    let mut st = Stream::new(seed, &format!("seam/pick/bi={bi}/bj={bj}"));
    Ok((members[st.below_usize(members.len())], members.len(), f_max))
}

/// Upper bounds of `F`, from cross sums computed for all positions at once by FFT, in two
/// stages: [`FftBounds::intensity`] correlates only the I channel and bounds `ρ_H` and `ρ_S` by 1;
/// γ being the largest weight, that alone rules out most candidates where `θ` is high.
/// [`FftBounds::full`] adds the H and S cross sums for when too many survive. A line is a few
/// straight groups of pixels (one column or one row each), so its cross sums at every position
/// are a sum of 1-D correlations along columns or rows: one 1-D inverse transform per sample
/// column or row a candidate reaches, per pair of groups, from the sample's 1-D spectra
/// ([`Spectra`]), in single precision. The margin added per line and channel covers each group's
/// transform error ([`Spectra::error_per_norms`] times the largest column or row norm and the
/// group's kernel norm) and the rounding of the exact sums; degenerate lines take B8's values,
/// which do not depend on the cross sum.
pub(super) struct FftBounds<'p> {
    prep: &'p Prepared<'p>,
    s: &'p Settings,
    outs: &'p [OutputLine; 2],
    bounds: &'p BoundStats,
    area: (i32, i32, usize, usize),
    mism: &'p [[u32; 2]],
    /// Each line's pixels grouped by column (vertical runs) and by row (the rest).
    groups: Vec<Group>,
    /// Per correlated (group, channel): where its correlations are (see [`FftBounds::correlate`]).
    terms: Vec<Term>,
    /// One plane-sized buffer per pair of terms (taken from `prep` and given back on drop).
    buffers: Vec<Vec<Complex32>>,
    /// Per line and channel: Σ centred and the error margin of the cross sum.
    sum_c: [[f64; 3]; 2],
    margin: [[f64; 3]; 2],
    /// Per line and channel 1/sqrt of the output side's sum of squares (0: a flat output line).
    inv_out: [[f64; 3]; 2],
    /// The edge factor 1/(1 + μ·m/n) of every mismatch count m.
    edge_factor: [Vec<f64>; 2],
}

/// The pixels of one line in one sample column (`vertical`, at window column `at`) or one row
/// (at window row `at`): `(j, i)` for line pixel `i` at offset `from + j` along it.
pub(super) struct Group {
    li: usize,
    vertical: bool,
    at: i32,
    from: i32,
    pixels: Vec<(usize, usize)>,
}

/// One group's correlation with one channel: the real (or imaginary) part of `buffer`, laid out
/// by columns (`x·h + y`) for a vertical group, by rows for a horizontal one.
pub(super) struct Term {
    group: usize,
    k: usize,
    buffer: usize,
    imag: bool,
}

impl<'p> FftBounds<'p> {
    fn new(
        prep: &'p Prepared<'p>,
        s: &'p Settings,
        ls: &'p [Vec<(i32, i32)>; 2],
        outs: &'p [OutputLine; 2],
        bounds: &'p BoundStats,
        area: (i32, i32, usize, usize),
        mism: &'p [[u32; 2]],
    ) -> FftBounds<'p> {
        let sp = &prep.spectra;
        let (w, h) = (sp.w, sp.h);
        let mut groups: Vec<Group> = Vec::new();
        // (group, first offset along, first line pixel, length) of every run.
        let mut along = Vec::new();
        for (li, line) in ls.iter().enumerate() {
            let mut i = 0;
            for run in runs_of(line) {
                let (vertical, at, start) = if run.horizontal { (false, run.r, run.c) } else { (true, run.c, run.r) };
                let g = match groups.iter().position(|g| g.li == li && g.vertical == vertical && g.at == at) {
                    Some(g) => g,
                    None => {
                        groups.push(Group { li, vertical, at, from: start, pixels: Vec::new() });
                        groups.len() - 1
                    }
                };
                groups[g].from = groups[g].from.min(start);
                along.push((g, start, i, run.len));
                i += run.len as usize;
            }
        }
        for (g, start, i, len) in along {
            let skip = (start - groups[g].from) as usize;
            groups[g].pixels.extend((0..len as usize).map(|t| (skip + t, i + t)));
        }
        let mut sum_c = [[0.0; 3]; 2];
        let mut margin = [[0.0; 3]; 2];
        for li in 0..2 {
            for k in 0..3 {
                let c = &outs[li].centred[k];
                sum_c[li][k] = c.iter().sum::<f64>();
                let abs: f64 = c.iter().map(|v| v.abs()).sum();
                // The exact sums' rounding, as before the transforms were single precision.
                margin[li][k] = 1e-9 * (abs + 1e-3);
            }
        }
        // Each group's correlation errs by at most its transform's bound times the norms of the
        // sample column (row) and of the group's kernel ([`Spectra::error_per_norms`]).
        for g in &groups {
            let (n, peak_norm) = if g.vertical { (h, &sp.col_norms) } else { (w, &sp.row_norms) };
            for k in 0..3 {
                let kernel = g.pixels.iter().map(|&(_, i)| outs[g.li].centred[k][i].powi(2)).sum::<f64>().sqrt();
                margin[g.li][k] += Spectra::error_per_norms(n) * peak_norm[k] * kernel;
            }
        }
        let inv_out = [0, 1].map(|li| outs[li].ss.map(|v| if v >= FLAT { 1.0 / v.sqrt() } else { 0.0 }));
        let edge_factor: [Vec<f64>; 2] =
            [0, 1].map(|li| (0..=ls[li].len()).map(|m| 1.0 / (1.0 + s.mu * (m as f64 / ls[li].len() as f64))).collect());
        let buffers = std::mem::take(&mut *prep.fft_buffers.lock().expect("buffers"));
        FftBounds { prep, s, outs, bounds, area, mism, groups, terms: Vec::new(), buffers, sum_c, margin, inv_out, edge_factor }
    }

    /// Correlates every group with the channels `ks`: the terms in pairs of the same orientation,
    /// each pair one complex 1-D correlation per sample column (row) its candidates reach, the
    /// first term in the real part and the second in the imaginary part.
    fn correlate(&mut self, ks: &[usize]) {
        let prep = self.prep;
        let sp = &prep.spectra;
        let (w, h) = (sp.w, sp.h);
        let (x0, y0, nx, ny) = self.area;
        let first = self.terms.len();
        let first_buffer = self.terms.iter().map(|t| t.buffer + 1).max().unwrap_or(0);
        let mut next = first_buffer;
        for vertical in [true, false] {
            let new: Vec<(usize, usize)> = (0..self.groups.len())
                .filter(|&g| self.groups[g].vertical == vertical)
                .flat_map(|g| ks.iter().map(move |&k| (g, k)))
                .collect();
            for pair in new.chunks(2) {
                for (t, &(group, k)) in pair.iter().enumerate() {
                    self.terms.push(Term { group, k, buffer: next, imag: t == 1 });
                }
                next += 1;
            }
        }
        while self.buffers.len() < next {
            self.buffers.push(vec![Complex32::new(0.0, 0.0); w * h]);
        }
        for b in first_buffer..next {
            let pair: Vec<&Term> = self.terms[first..].iter().filter(|u| u.buffer == b).collect();
            let g0 = &self.groups[pair[0].group];
            let vertical = g0.vertical;
            let (n, count, planes, fwd, inv) =
                if vertical { (h, w, &sp.cols, &sp.col[0], &sp.col[1]) } else { (w, h, &sp.rows, &sp.row[0], &sp.row[1]) };
            let half = n / 2 + 1;
            // The columns (rows) the candidates reach.
            let reach = |g: &Group| -> std::ops::Range<usize> {
                let start = g.at + if vertical { x0 } else { y0 };
                start as usize..start as usize + if vertical { nx } else { ny }
            };
            let mut lo = count;
            let mut hi = 0;
            let mut kernels: Vec<(usize, Vec<Complex32>)> = Vec::new();
            for term in &pair {
                let g = &self.groups[term.group];
                let r = reach(g);
                lo = lo.min(r.start);
                hi = hi.max(r.end);
                let mut z = vec![Complex32::new(0.0, 0.0); n];
                for &(j, i) in &g.pixels {
                    z[j].re = self.outs[g.li].centred[term.k][i] as f32;
                }
                fwd.process(&mut z);
                // Conjugated for a correlation, and scaled by 1/n for the unnormalised inverse
                // transform.
                let scale = 1.0 / n as f32;
                kernels.push((term.k, z[..half].iter().map(|v| v.conj() * scale).collect::<Vec<_>>()));
            }
            let out = &mut self.buffers[b][lo * n..hi * n];
            out.par_chunks_mut(n * 16).enumerate().for_each_init(
                || vec![0.0f32; 4 * half],
                |scratch, (ci, chunk)| {
                    with_avx2(
                        #[inline(always)]
                        || {
                            for (cj, dst) in chunk.chunks_exact_mut(n).enumerate() {
                                let line = lo + ci * 16 + cj;
                                let (ka, fa) = (&kernels[0].1, &planes[kernels[0].0][line * half..(line + 1) * half]);
                                let b = kernels.get(1).map(|(k, kb)| (&planes[*k][line * half..(line + 1) * half], &kb[..]));
                                hermitian_products(fa, ka, b, dst, scratch);
                            }
                        },
                    );
                    inv.process(chunk);
                },
            );
        }
    }

    /// The cross sums of candidate rows `row0..row0 + rows`, per line and channel correlated,
    /// term by term into `cross[li][k][r·nx + x]`: a vertical term's values lie down a column of its
    /// buffer, so they are read a column run at a time.
    #[inline(always)]
    fn cross_sums(&self, row0: usize, rows: usize, cross: &mut [[Vec<f64>; 3]; 2]) {
        let (x0, y0, nx, _) = self.area;
        let sp = &self.prep.spectra;
        let (w, h) = (sp.w, sp.h);
        let y = y0 + row0 as i32;
        // Only the sums some term adds to are read (the others' channels are not bounded).
        for term in &self.terms {
            cross[self.groups[term.group].li][term.k][..nx * rows].fill(0.0);
        }
        for term in &self.terms {
            let g = &self.groups[term.group];
            let buf = &self.buffers[term.buffer];
            let acc = &mut cross[g.li][term.k][..nx * rows];
            let add = |part: fn(&Complex32) -> f64, acc: &mut [f64]| {
                if g.vertical {
                    let (col, r) = ((x0 + g.at) as usize, (y + g.from) as usize);
                    for x in 0..nx {
                        let run = &buf[(col + x) * h + r..(col + x) * h + r + rows];
                        for (a, v) in acc[x..].iter_mut().step_by(nx).zip(run) {
                            *a += part(v);
                        }
                    }
                } else {
                    for (rr, acc) in acc.chunks_exact_mut(nx).enumerate() {
                        let at = (y + rr as i32 + g.at) as usize * w + (x0 + g.from) as usize;
                        for (a, v) in acc.iter_mut().zip(&buf[at..at + nx]) {
                            *a += part(v);
                        }
                    }
                }
            };
            if term.imag {
                add(|v| f64::from(v.im), acc);
            } else {
                add(|v| f64::from(v.re), acc);
            }
        }
    }

    /// The bounds of one row of candidates from its cross sums `cross[li][k]`, with the H and S
    /// channels when `hs` (else `ρ_H, ρ_S ≤ 1`).
    #[inline(always)]
    fn bound_row(&self, row: usize, hs: bool, u: &mut [f64], cross: [[&[f64]; 3]; 2], d: &mut [f64]) {
        let nx = self.area.2;
        let cap = 1.0 + 1e-9;
        let mism = &self.mism[row * nx..(row + 1) * nx];
        u.fill(0.0);
        for li in 0..2 {
            let ef = &self.edge_factor[li];
            // The part of D_HSI not bounded per candidate: ρ ≤ 1 for the channels not correlated.
            let d0 = if hs { 0.0 } else { (self.s.weights[0] + self.s.weights[1]) * cap };
            let channels = if hs { 0..3 } else { 2..3 };
            d.fill(d0);
            for k in channels {
                let (io, sc, mg, wk) = (self.inv_out[li][k], self.sum_c[li][k], self.margin[li][k], self.s.weights[k]);
                let inv_his = self.bounds.inv_hi(li, row, k);
                // ρ is 1 for two flat lines with close means and 0 for one flat line (B8);
                // otherwise c/sqrt(v1·v2), at most 1.
                if io == 0.0 {
                    for (dd, &inv_hi) in d.iter_mut().zip(inv_his) {
                        *dd += wk * if inv_hi == f64::INFINITY { cap } else { 0.0 };
                    }
                } else {
                    // The cross sum is Σ c·(v − m2) = Σ c·(v − μ) + (μ − m2)·Σ c, the transforms
                    // giving the first term (μ the plane's mean), and Σ c (the output line's
                    // centred values) is all but zero: |μ − m2|·|Σ c| ≤ peak·|Σ c| joins the
                    // margin, so the candidate's mean is not needed.
                    let mg = (mg + self.prep.spectra.peaks[k] * sc.abs()) * io;
                    for ((dd, &c), &inv_hi) in d.iter_mut().zip(cross[li][k]).zip(inv_his) {
                        let c = c * io + mg;
                        let rho = (c * inv_hi * if c >= 0.0 { 1.0 } else { 1.0 - INV_SPREAD }).min(cap);
                        *dd += wk * if inv_hi == f64::INFINITY { cap } else { rho };
                    }
                }
            }
            for ((uu, dd), m) in u.iter_mut().zip(&*d).zip(mism) {
                let dd = if self.s.clamp { dd.max(0.0) } else { *dd };
                *uu += dd * ef[m[li] as usize];
            }
        }
    }

    /// Bounds of every candidate, row-major, from the I channel alone, or from all three after
    /// [`FftBounds::intensity`] when `hs`.
    fn bounds(&self, hs: bool) -> Vec<f64> {
        let (_, _, nx, ny) = self.area;
        let mut u = vec![0.0; nx * ny];
        const ROWS: usize = 16;
        u.par_chunks_mut(nx * ROWS).enumerate().for_each_init(
            || ([0, 1].map(|_| [0, 1, 2].map(|_| vec![0.0; nx * ROWS])), vec![0.0; nx]),
            |(cross, d), (chunk, us)| {
                with_avx2(
                    #[inline(always)]
                    || {
                        let rows = us.len() / nx;
                        self.cross_sums(chunk * ROWS, rows, cross);
                        for (r, u) in us.chunks_exact_mut(nx).enumerate() {
                            let c = [0, 1].map(|li| [0, 1, 2].map(|k| &cross[li][k][r * nx..(r + 1) * nx]));
                            self.bound_row(chunk * ROWS + r, hs, u, c, d);
                        }
                    },
                )
            },
        );
        u
    }

    /// Bounds of every candidate from the I channel alone.
    fn intensity(&mut self) -> Vec<f64> {
        self.correlate(&[2]);
        self.bounds(false)
    }

    /// Bounds of every candidate from all three channels (after [`FftBounds::intensity`]).
    fn full(&mut self) -> Vec<f64> {
        self.correlate(&[0, 1]);
        self.bounds(true)
    }

    /// Bounds of every candidate from all three channels at once.
    fn all(&mut self) -> Vec<f64> {
        self.correlate(&[0, 1, 2]);
        self.bounds(true)
    }
}

impl Drop for FftBounds<'_> {
    fn drop(&mut self) {
        *self.prep.fft_buffers.lock().expect("buffers") = std::mem::take(&mut self.buffers);
    }
}

/// `dst = A + i·B` for `A = fa·ka` and `B = fb·kb` (pointwise; `B = 0` without `b`), from
/// frequencies `0..=n/2` of four spectra of real sequences (`n = dst.len()`): `A` and `B` are
/// then spectra of real sequences too, so frequency `n − j` is `conj(A_j) + i·conj(B_j)` and each
/// product is computed for half of the frequencies only. The products go through `scratch`
/// (at least `4·(n/2 + 1)` values) as separate real and imaginary parts, so that every loop runs
/// on whole vectors, the mirrored half's reversed order included.
#[inline(always)]
pub(super) fn hermitian_products(
    fa: &[Complex32],
    ka: &[Complex32],
    b: Option<(&[Complex32], &[Complex32])>,
    dst: &mut [Complex32],
    scratch: &mut [f32],
) {
    let n = dst.len();
    let half = n / 2 + 1;
    let (ar, rest) = scratch.split_at_mut(half);
    let (ai, rest) = rest.split_at_mut(half);
    let (br, rest) = rest.split_at_mut(half);
    let bi = &mut rest[..half];
    let product = |f: &[Complex32], k: &[Complex32], re: &mut [f32], im: &mut [f32]| {
        for (((re, im), f), k) in re.iter_mut().zip(im.iter_mut()).zip(&f[..half]).zip(&k[..half]) {
            *re = f.re * k.re - f.im * k.im;
            *im = f.re * k.im + f.im * k.re;
        }
    };
    product(fa, ka, ar, ai);
    match b {
        Some((fb, kb)) => product(fb, kb, br, bi),
        None => {
            br.fill(0.0);
            bi.fill(0.0);
        }
    }
    let (lower, upper) = dst.split_at_mut(half);
    for (j, lo) in lower.iter_mut().enumerate() {
        *lo = Complex32::new(ar[j] - bi[j], ai[j] + br[j]);
    }
    // Frequencies 1..=mirrored have their partner n − j in the upper part, in reverse order;
    // 0 and (for even n) n/2 are their own.
    let mirrored = n - half;
    for (i, up) in upper.iter_mut().enumerate() {
        let j = mirrored - i;
        *up = Complex32::new(ar[j] + bi[j], br[j] - ai[j]);
    }
}

/// The sample's H, S and I planes, less their means, as 1-D spectra of every column and every
/// row, in single precision, with the plans. The bounds only need the cross sums within a proven
/// margin, and single precision halves the memory the correlations stream through and doubles the
/// lanes of each vector operation; centring keeps the planes' large constant part (and with it
/// the rounding error) out of the transforms.
pub(super) struct Spectra {
    w: usize,
    h: usize,
    /// `cols[k][x·(h/2 + 1) + v]`: frequency `v` of column `x` of plane `k` (H, S, I), for
    /// `v ≤ h/2` (the rest are their conjugates: the planes are real).
    cols: [Vec<Complex32>; 3],
    /// `rows[k][y·(w/2 + 1) + u]`: frequency `u ≤ w/2` of row `y`.
    rows: [Vec<Complex32>; 3],
    /// The largest Euclidean norm of a centred column (row) of each plane.
    col_norms: [f64; 3],
    row_norms: [f64; 3],
    /// The largest absolute value in each centred plane.
    peaks: [f64; 3],
    /// Forward and inverse plans along columns (length `h`) and rows (length `w`).
    col: [Arc<dyn Fft<f32>>; 2],
    row: [Arc<dyn Fft<f32>>; 2],
}

impl Spectra {
    pub(super) fn new(planes: &HsiPlanes, w: usize, h: usize) -> Spectra {
        // The spectra are computed in double precision and rounded once.
        let mut planner = FftPlanner::<f64>::new();
        let (col64, row64) = (planner.plan_fft_forward(h), planner.plan_fft_forward(w));
        let mut planner = FftPlanner::<f32>::new();
        let col = [planner.plan_fft_forward(h), planner.plan_fft_inverse(h)];
        let row = [planner.plan_fft_forward(w), planner.plan_fft_inverse(w)];
        let centred = [&planes.h, &planes.s, &planes.i].map(|p| {
            let mean = p.iter().sum::<f64>() / p.len() as f64;
            p.iter().map(|v| v - mean).collect::<Vec<f64>>()
        });
        let single = |z: &[Complex64], n: usize| -> Vec<Complex32> {
            z.chunks_exact(n).flat_map(|c| &c[..n / 2 + 1]).map(|v| Complex32::new(v.re as f32, v.im as f32)).collect()
        };
        let cols = [0, 1, 2].map(|k| {
            let p = &centred[k];
            let mut z: Vec<Complex64> = (0..w).flat_map(|x| (0..h).map(move |y| Complex64::new(p[y * w + x], 0.0))).collect();
            col64.process(&mut z);
            single(&z, h)
        });
        let rows = [0, 1, 2].map(|k| {
            let mut z: Vec<Complex64> = centred[k].iter().map(|&v| Complex64::new(v, 0.0)).collect();
            row64.process(&mut z);
            single(&z, w)
        });
        let col_norms =
            centred.each_ref().map(|p| (0..w).map(|x| (0..h).map(|y| p[y * w + x] * p[y * w + x]).sum::<f64>().sqrt()).fold(0.0, f64::max));
        let row_norms =
            centred.each_ref().map(|p| p.chunks_exact(w).map(|r| r.iter().map(|v| v * v).sum::<f64>().sqrt()).fold(0.0, f64::max));
        let peaks = centred.each_ref().map(|p| p.iter().fold(0.0, |m: f64, v| m.max(v.abs())));
        Spectra { w, h, cols, rows, col_norms, row_norms, peaks, col, row }
    }

    /// A bound of the absolute error of one single-precision correlation of length `n` (a column
    /// or row `x` with a kernel `k`: the kernel's transform, the product with `x`'s rounded
    /// spectrum, the inverse transform) per `‖x‖₂·‖k‖₂`. A transform of length `n` errs by at most
    /// `log₂(n)·η` relative to its output's 2-norm (Higham, *Accuracy and Stability of Numerical
    /// Algorithms*, §24.1; `η ≈ 7u` for single precision's `u = 2⁻²⁴` with accurate twiddles).
    /// Through the product (`‖X‖∞ ≤ √n·‖x‖₂`, the same for `k`) and the scaled inverse transform
    /// that gives at most `(2·log₂(n)·η + 6u)·√n` for any one output; this takes
    /// `64·u·log₂(n)·√n`, over four times that (transforms of lengths with large prime factors
    /// take a few more steps).
    fn error_per_norms(n: usize) -> f64 {
        let u = f64::from(f32::EPSILON) / 2.0;
        let log = (n as f64).log2().max(1.0);
        64.0 * u * log * (n as f64).sqrt()
    }
}

/// How far [`Prepared::edges`] extends past the sample: one register block of [`MismatchCounter::row`].
pub(super) const EDGE_PAD: usize = 32;

/// The edge mismatches of one line at every candidate. With `n₁` edge pixels on the output line
/// and `S` on the candidate's, the mismatches are `n₁ + S − 2·T`, `T` the candidate's edge bits
/// under the line's edge pixels, or equally `n₁ − S + 2·Z` over its non-edge pixels: `S` is a few
/// prefix-sum lookups per run ([`Prefixes::add_edge_run`]), so only the smaller of the two pixel
/// sets is read per candidate, at most half the line.
pub(super) struct MismatchCounter {
    runs: Vec<Run>,
    /// The line offsets of the pixels summed, and whether they are the edge pixels.
    summed: Vec<isize>,
    ones: bool,
    n1: u32,
}

impl MismatchCounter {
    fn new(line: &[(i32, i32)], offsets: &[isize], edges: &[u8]) -> MismatchCounter {
        let n1 = edges.iter().filter(|&&e| e == 1).count();
        let ones = 2 * n1 <= edges.len();
        let summed = offsets.iter().zip(edges).filter(|&(_, &e)| (e == 1) == ones).map(|(&o, _)| o).collect();
        MismatchCounter { runs: runs_of(line), summed, ones, n1: n1 as u32 }
    }

    /// The mismatches of `m.len()` consecutive candidates from `(x, y)`, whose line pixels are at
    /// sample index `base` plus each offset (`sums`: scratch of the same length).
    #[inline(always)]
    fn row(&self, prep: &Prepared, (x, y): (i32, i32), base: usize, sums: &mut [u32], m: &mut [u32]) {
        const LANES: usize = 32;
        let n = m.len();
        sums.fill(0);
        for run in &self.runs {
            prep.prefixes.add_edge_run(run, x, y, sums);
        }
        // Counted in 8 bits, LANES candidates at a time in registers, in runs of pixels short
        // enough not to overflow; the last block reads past the row into the padding.
        for x in (0..n).step_by(LANES) {
            let mut count = [0u32; LANES];
            for part in self.summed.chunks(u8::MAX as usize) {
                let mut acc = [0u8; LANES];
                for &off in part {
                    let b = (base as isize + off) as usize + x;
                    let bits: &[u8; LANES] = prep.edges[b..b + LANES].try_into().expect("lanes");
                    for (a, &e) in acc.iter_mut().zip(bits) {
                        *a += e;
                    }
                }
                for (c, &a) in count.iter_mut().zip(&acc) {
                    *c += u32::from(a);
                }
            }
            let lanes = LANES.min(n - x);
            for ((mm, &s), &c) in m[x..x + lanes].iter_mut().zip(&sums[x..x + lanes]).zip(&count) {
                *mm = if self.ones { self.n1 + s - 2 * c } else { self.n1 + 2 * c - s };
            }
        }
    }
}

/// [`score_all`] for given lines and position ranges.
pub(super) fn score_lines(
    prep: &Prepared,
    s: &Settings,
    ls: &[Vec<(i32, i32)>; 2],
    (xs, ys): Ranges,
    stats: &[LineStats; 2],
    out: &Canvas,
    origin: (i32, i32),
) -> (Vec<(i32, i32)>, Vec<f64>) {
    let outs = [output_line(out, s, origin, &ls[0]), output_line(out, s, origin, &ls[1])];
    let nx = (xs.end() - xs.start() + 1) as usize;
    let x0 = *xs.start();
    let w = prep.w as i32;
    let rows: Vec<i32> = ys.collect();
    let scores: Vec<f64> = rows
        .par_iter()
        .enumerate()
        .flat_map_iter(|(row_index, &y)| {
            let mut f = vec![0.0; nx];
            for (li, line) in ls.iter().enumerate() {
                let o = &outs[li];
                let st = &stats[li][row_index * nx..(row_index + 1) * nx];
                let mut cross = [vec![0.0; nx], vec![0.0; nx], vec![0.0; nx]];
                let mut mismatches = vec![0u32; nx];
                if s.circular {
                    // Slow path: a sine per pixel.
                    for (i, &(c, r)) in line.iter().enumerate() {
                        let base = ((y + r) * w + x0 + c) as usize;
                        for (k, plane) in [&prep.planes.h, &prep.planes.s, &prep.planes.i].into_iter().enumerate() {
                            let ci = o.centred[k][i];
                            let row = &plane[base..base + nx];
                            for ((a, v), stx) in cross[k].iter_mut().zip(row).zip(st) {
                                *a += if k == 0 { ci * (TAU * v - stx[0]).sin() } else { ci * (v - stx[2 * k]) };
                            }
                        }
                        let e1 = o.edges[i];
                        for (m, e2) in mismatches.iter_mut().zip(&prep.edges[base..base + nx]) {
                            *m += u32::from(e1 != *e2);
                        }
                    }
                } else {
                    let offsets: Vec<usize> = line.iter().map(|&(c, r)| ((y + r) * w + x0 + c) as usize).collect();
                    cross_row(prep, o, st, &offsets, &mut cross, &mut mismatches);
                }
                let n = line.len() as f64;
                for x in 0..nx {
                    let stx = &st[x];
                    let mut d = 0.0;
                    for k in 0..3 {
                        let rho = if k == 0 && s.circular {
                            let mut diff = (o.mean[0] - stx[0]).abs() % TAU;
                            if diff > TAU / 2.0 {
                                diff = TAU - diff;
                            }
                            pearson_from(0.0, o.ss[0], diff / TAU, stx[1], cross[0][x])
                        } else {
                            pearson_from(o.mean[k], o.ss[k], stx[2 * k], stx[2 * k + 1], cross[k][x])
                        };
                        d += s.weights[k] * rho;
                    }
                    if s.clamp {
                        d = d.max(0.0);
                    }
                    let de = mismatches[x] as f64 / n;
                    f[x] += d / (1.0 + s.mu * de);
                    if s.level_penalty > 0.0 {
                        f[x] -= s.level_penalty * (o.mean[2] - stx[4]).abs();
                    }
                }
            }
            f
        })
        .collect();
    let positions = rows.iter().flat_map(|&y| (0..nx as i32).map(move |dx| (x0 + dx, y))).collect();
    (positions, scores)
}

/// The linear-hue cross sums and edge mismatches of one line at `cross[k].len()` consecutive
/// candidates (`offsets`: the line's sample indices for the first of them). Candidates in
/// register blocks of LANES, line pixels in index order inside: the same sums in the same order
/// as the two-pass formula, without round-tripping accumulators through memory for every pixel.
pub(super) fn cross_row(
    prep: &Prepared,
    o: &OutputLine,
    st: &[[f64; 6]],
    offsets: &[usize],
    cross: &mut [Vec<f64>; 3],
    mismatches: &mut [u32],
) {
    const LANES: usize = 8;
    let nx = mismatches.len();
    let mut x = 0;
    while x < nx {
        let lanes = LANES.min(nx - x);
        let mut m2 = [[0.0f64; LANES]; 3];
        for l in 0..lanes {
            for k in 0..3 {
                m2[k][l] = st[x + l][2 * k];
            }
        }
        let mut acc = [[0.0f64; LANES]; 3];
        let mut mism = [0u32; LANES];
        for (i, &base) in offsets.iter().enumerate() {
            let b = base + x;
            for (k, plane) in [&prep.planes.h, &prep.planes.s, &prep.planes.i].into_iter().enumerate() {
                let ci = o.centred[k][i];
                if lanes == LANES {
                    let v: &[f64; LANES] = plane[b..b + LANES].try_into().expect("lanes");
                    for l in 0..LANES {
                        acc[k][l] += ci * (v[l] - m2[k][l]);
                    }
                } else {
                    for l in 0..lanes {
                        acc[k][l] += ci * (plane[b + l] - m2[k][l]);
                    }
                }
            }
            let e1 = o.edges[i];
            for (m, e2) in mism[..lanes].iter_mut().zip(&prep.edges[b..b + lanes]) {
                *m += u32::from(e1 != *e2);
            }
        }
        for l in 0..lanes {
            for k in 0..3 {
                cross[k][x + l] = acc[k][l];
            }
            mismatches[x + l] = mism[l];
        }
        x += lanes;
    }
}
