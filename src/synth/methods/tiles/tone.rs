//! Tone-matched interiors (issue #30): a tile's own interior ([`super::interior`]) is brought to
//! the tone of the edge band around it, smoothly, so that the tile grid does not show as steps of
//! shade.
//!
//! Why: on a sample whose colour variance lies largely in features a quarter of a tile and more
//! across (weathered wood, mossy stone, brown rock, rock albedo), every tile's interior patch carries a shade of its own, and its
//! seam with the band, near the tile outline, is a step of shade along the same lines in every
//! tile: the fill shows its tile grid, Wang as squares and RW as rhombi, however well the cut
//! follows the fine texture. Feathering the two across the seam does not help: averaging two
//! unrelated textures flattens their contrast, and the flat band shows the grid as bright lines.
//!
//! What is done instead: around the interior's border, in [`SECTORS`] angular sectors, the band's
//! mean colour just outside the seam is compared with the interior's just inside; the difference
//! is spread over the interior by inverse-square-distance weights from the sectors' centres and
//! faded out [`FADE`] px into it. The fine texture is kept, only its shade moves.
//!
//! How it stays a placement (`synth::placement`): every output pixel must remain a chain of sample
//! pixels, so that a 16-bit or float output, a material's companions and `texsyn apply` render the
//! same composition. A shift `v → v + δ` is written as one blend step `v → (1 − a)·v + a·s` with a
//! sample pixel `s` whose colour is near `v + δ/a`, found through a colour table of the sample
//! ([`Palette`]), for the smallest weight `a` among [`WEIGHTS`] that keeps `v + δ/a` within the
//! sample's colours (the smaller `a`, the less the table's bin width shows), and kept only when
//! the result (rounded exactly as rendering rounds) lands nearer `v + δ` than `v` does. In a
//! companion map the same steps blend in the companion's pixels at those places, at a weight of at
//! most 1/2 and mostly far less.
//!
//! Cost: what every tile shares (which pixels are near the seam, in which sector, their weights)
//! is measured once per set ([`ToneGeometry`]); per pixel, a bilinear lookup of the field, one
//! table lookup and one blend. A set with `colors = "auto"` takes at most
//! `common::TONED_COLORS` colours when toned, so that a 2048² fill stays well over 10 times faster
//! than quilting.

use crate::image::RgbImage;
use crate::synth::primitives::feather;
use rayon::prelude::*;

/// The denominator of every tone blend's weight.
pub const DEN: u32 = 32;

/// The blend weights, as numerators over [`DEN`]: 1/8 to 1/2.
pub const WEIGHTS: [u8; 6] = [4, 5, 6, 8, 11, 16];

/// Angular sectors around an interior's border in which band and interior tones are compared.
pub const SECTORS: usize = 12;

/// How deep into the interior the correction reaches, fading linearly to nothing, in pixels.
pub const FADE: usize = 24;

/// How far the band and the interior are sampled from the seam, in pixels (4-neighbour steps).
pub const REACH: usize = 4;

/// Bits per channel of the colour table's bins (32 levels each way: bins 8 grey levels wide).
const BIN_BITS: u32 = 5;

/// For every colour bin, a sample pixel whose colour is in it or, for bins no sample pixel falls
/// in, in the nearest bin that has one (by 6-neighbour steps through the bin grid).
pub struct Palette {
    bins: Vec<u32>,
    /// Per channel and value `v`, `1 / room` up to the 99th percentile of the sample's values
    /// and down to the 1st (at least 1 level): how far a blend may push `v` without leaving
    /// the sample's gamut.
    up: [[f32; 256]; 3],
    down: [[f32; 256]; 3],
}

/// For `n = 0..=DEN`, the smallest of [`WEIGHTS`] at least `n` (the largest where none is).
const NUM_FOR: [u8; DEN as usize + 1] = {
    let mut t = [0u8; DEN as usize + 1];
    let mut n = 0;
    while n <= DEN as usize {
        let mut i = 0;
        t[n] = WEIGHTS[WEIGHTS.len() - 1];
        while i < WEIGHTS.len() {
            if WEIGHTS[i] as usize >= n {
                t[n] = WEIGHTS[i];
                break;
            }
            i += 1;
        }
        n += 1;
    }
    t
};

fn bin_of(c: [f32; 3]) -> usize {
    let b = |v: f32| ((v.clamp(0.0, 255.0) as u32) >> (8 - BIN_BITS)) as usize;
    let n = 1usize << BIN_BITS;
    (b(c[0]) * n + b(c[1])) * n + b(c[2])
}

impl Palette {
    /// The table of `sample`: in each bin, the sample pixel nearest the bin's centre (ties to the
    /// first in raster order); empty bins filled breadth-first from the filled ones, in bin order.
    pub fn new(sample: &RgbImage) -> Palette {
        let n = 1usize << BIN_BITS;
        let half = f64::from(1u32 << (8 - BIN_BITS - 1));
        let mut best: Vec<(u32, u32)> = vec![(u32::MAX, u32::MAX); n * n * n];
        for (i, px) in sample.as_raw().chunks_exact(3).enumerate() {
            let c = [f64::from(px[0]), f64::from(px[1]), f64::from(px[2])];
            let b = bin_of([f32::from(px[0]), f32::from(px[1]), f32::from(px[2])]);
            let centre = |v: f64| f64::from((v as u32) >> (8 - BIN_BITS) << (8 - BIN_BITS)) + half;
            let d: f64 = c.iter().map(|&v| (v - centre(v)).powi(2)).sum();
            let d = (d * 4.0) as u32;
            if d < best[b].0 {
                best[b] = (d, i as u32);
            }
        }
        let mut bins: Vec<u32> = best.iter().map(|b| b.1).collect();
        let mut queue: std::collections::VecDeque<usize> = (0..bins.len()).filter(|&b| bins[b] != u32::MAX).collect();
        while let Some(b) = queue.pop_front() {
            let (r, g, bl) = (b / (n * n), (b / n) % n, b % n);
            let mut visit = |r2: usize, g2: usize, b2: usize| {
                let j = (r2 * n + g2) * n + b2;
                if bins[j] == u32::MAX {
                    bins[j] = bins[b];
                    queue.push_back(j);
                }
            };
            if r > 0 {
                visit(r - 1, g, bl);
            }
            if r + 1 < n {
                visit(r + 1, g, bl);
            }
            if g > 0 {
                visit(r, g - 1, bl);
            }
            if g + 1 < n {
                visit(r, g + 1, bl);
            }
            if bl > 0 {
                visit(r, g, bl - 1);
            }
            if bl + 1 < n {
                visit(r, g, bl + 1);
            }
        }
        let mut low = [0f32; 3];
        let mut high = [255f32; 3];
        for k in 0..3 {
            let mut hist = [0usize; 256];
            for px in sample.as_raw().chunks_exact(3) {
                hist[px[k] as usize] += 1;
            }
            let total: usize = hist.iter().sum();
            let level = |q: usize| {
                let mut acc = 0;
                (0..256).find(|&v| {
                    acc += hist[v];
                    acc * 100 >= total * q
                })
            };
            low[k] = level(1).unwrap_or(0) as f32;
            high[k] = level(99).unwrap_or(255) as f32;
        }
        let up = std::array::from_fn(|k| std::array::from_fn(|v| 1.0 / (high[k] - v as f32).max(1.0)));
        let down = std::array::from_fn(|k| std::array::from_fn(|v| 1.0 / (v as f32 - low[k]).max(1.0)));
        Palette { bins, up, down }
    }

    /// A sample pixel (its index, `y · width + x`) whose colour is near `c`.
    #[inline]
    fn near(&self, c: [f32; 3]) -> u32 {
        self.bins[bin_of(c)]
    }
}

/// A toned pixel's blend: the sample index blended in and its weight's numerator over [`DEN`];
/// `num = 0` where the pixel stays a copy.
pub type ToneBlend = (u32, u8);

/// Two-pass city-block distance (4-neighbour steps) of every pixel of a `side × side` raster to
/// the nearest pixel where `from` holds; `usize::MAX / 2` where none.
fn distance_to(from: impl Fn(usize) -> bool, side: usize) -> Vec<usize> {
    let far = usize::MAX / 2;
    let mut d: Vec<usize> = (0..side * side).map(|i| if from(i) { 0 } else { far }).collect();
    for y in 0..side {
        for x in 0..side {
            let i = y * side + x;
            if x > 0 {
                d[i] = d[i].min(d[i - 1] + 1);
            }
            if y > 0 {
                d[i] = d[i].min(d[i - side] + 1);
            }
        }
    }
    for y in (0..side).rev() {
        for x in (0..side).rev() {
            let i = y * side + x;
            if x + 1 < side {
                d[i] = d[i].min(d[i + 1] + 1);
            }
            if y + 1 < side {
                d[i] = d[i].min(d[i + side] + 1);
            }
        }
    }
    d
}

/// The sector of direction `(dx, dy)` from an interior's centre: [`SECTORS`] equal steps of the
/// "diamond angle" (`0..4` once round, monotonic in the angle), cheaper than `atan2` and as good
/// for sorting the border into neighbourhoods.
fn sector_of(dx: f64, dy: f64) -> usize {
    let l = dx.abs() + dy.abs();
    if l == 0.0 {
        return 0;
    }
    let p = match (dx >= 0.0, dy >= 0.0) {
        (true, true) => dy / l,
        (false, true) => 1.0 - dx / l,
        (false, false) => 2.0 - dy / l,
        (true, false) => 3.0 + dx / l,
    };
    ((p / 4.0 * SECTORS as f64) as usize).min(SECTORS - 1)
}

/// Grid step, in pixels, at which the smooth tone field is evaluated and between which it is
/// interpolated bilinearly (the field varies over tens of pixels).
const NODE_STEP: usize = 4;

/// What every tile of a set shares: the seams differ from tile to tile only within the ring of
/// depths their cuts may take, a few pixels, so distances, sectors and weights are measured once
/// on the set's *core* (the pixels every tile's interior covers) and its *reach* (those some
/// tile's interior covers), and each tile only reads its labels against them.
pub struct ToneGeometry {
    side: usize,
    /// Pixels near the seam, each with its sector: a tile's band pixels among them (within
    /// [`REACH`] outside the reach) and its interior pixels (within [`REACH`] inside the core, or
    /// in the ring between) are what each sector's tones are measured on.
    zone: Vec<(u32, u8)>,
    /// Per grid node (`nodes × nodes`, every [`NODE_STEP`] px), each sector's inverse square
    /// distance weight, from the centre of the sector's zone pixels, where its difference is
    /// anchored.
    weights: Vec<[f32; SECTORS]>,
    nodes: usize,
    /// The pixels the correction reaches: raster index, fade (1 at the seam, falling to 0
    /// [`FADE`] px in), the top-left node of its grid cell and its place in the cell.
    work: Vec<(u32, f32, u32, f32, f32)>,
}

impl ToneGeometry {
    /// The geometry of a set whose tiles have these labels (`side × side` each).
    pub fn new<'a>(side: usize, interior: u8, labels: impl Iterator<Item = &'a [u8]>) -> ToneGeometry {
        let n = side * side;
        let (mut every, mut some) = (vec![true; n], vec![false; n]);
        let mut any = false;
        for l in labels {
            any = true;
            for i in 0..n {
                let own = l[i] == interior;
                every[i] &= own;
                some[i] |= own;
            }
        }
        if !any {
            every.fill(false);
        }
        // Inside the core: distance from its edge; outside the reach: distance to it.
        let inside = distance_to(|i| !every[i], side);
        let outside = distance_to(|i| some[i], side);
        let (mut cx, mut cy, mut count) = (0.0, 0.0, 0.0);
        for i in (0..n).filter(|&i| some[i]) {
            cx += (i % side) as f64;
            cy += (i / side) as f64;
            count += 1.0;
        }
        let (cx, cy) = if count > 0.0 { (cx / count, cy / count) } else { (0.0, 0.0) };
        let zone: Vec<(u32, u8)> = (0..n)
            .filter(|&i| (some[i] && (!every[i] || inside[i] <= REACH)) || (!some[i] && outside[i] <= REACH))
            .map(|i| (i as u32, sector_of((i % side) as f64 - cx, (i / side) as f64 - cy) as u8))
            .collect();
        let mut sums = [(0f64, 0f64, 0f64); SECTORS];
        for &(i, k) in &zone {
            let s = &mut sums[k as usize];
            (s.0, s.1, s.2) = (s.0 + (i as usize % side) as f64, s.1 + (i as usize / side) as f64, s.2 + 1.0);
        }
        let centres = sums.map(|s| if s.2 > 0.0 { (s.0 / s.2, s.1 / s.2) } else { (cx, cy) });
        let nodes = side.div_ceil(NODE_STEP) + 1;
        let weights = (0..nodes * nodes)
            .map(|j| {
                let (x, y) = (((j % nodes) * NODE_STEP) as f64, ((j / nodes) * NODE_STEP) as f64);
                centres.map(|(sx, sy)| (1.0 / ((x - sx).powi(2) + (y - sy).powi(2) + 1.0)) as f32)
            })
            .collect();
        // A pixel of the ring lies next to its tile's seam (distance 1); one of the core is
        // about as far from it as from the core's edge.
        let work = (0..n)
            .filter(|&i| some[i])
            .filter_map(|i| {
                let d = if every[i] { inside[i] } else { 1 };
                (d <= FADE).then(|| {
                    let (x, y) = (i % side, i / side);
                    let node = (y / NODE_STEP) * nodes + x / NODE_STEP;
                    let cell = |v: usize| (v % NODE_STEP) as f32 / NODE_STEP as f32;
                    (i as u32, 1.0 - (d - 1) as f32 / FADE as f32, node as u32, cell(x), cell(y))
                })
            })
            .collect();
        ToneGeometry { side, zone, weights, nodes, work }
    }
}

/// Tones the interior (`labels == interior`) of one tile raster (RGB) of a set with geometry `g`
/// to its band (labels `0..=3`; other labels lie outside the tile). Changes the interior pixels
/// of `raster` and returns each raster pixel's [`ToneBlend`] (all `num = 0` when nothing changed).
pub fn tone_tile(raster: &mut [u8], labels: &[u8], g: &ToneGeometry, interior: u8, sample: &RgbImage, palette: &Palette) -> Vec<ToneBlend> {
    let n = g.side * g.side;
    let mut blends = vec![(0u32, 0u8); n];
    let mut band = [([0f64; 3], 0f64); SECTORS];
    let mut inner = [([0f64; 3], 0f64); SECTORS];
    for &(i, k) in &g.zone {
        let i = i as usize;
        let acc = match labels[i] {
            l if l == interior => &mut inner[k as usize],
            l if l <= 3 => &mut band[k as usize],
            _ => continue,
        };
        for c in 0..3 {
            acc.0[c] += f64::from(raster[3 * i + c]);
        }
        acc.1 += 1.0;
    }
    // Each sector seen on both sides: its tone difference.
    let steps: Vec<(usize, [f32; 3])> = (0..SECTORS)
        .filter(|&k| band[k].1 > 0.0 && inner[k].1 > 0.0)
        .map(|k| (k, std::array::from_fn(|c| (band[k].0[c] / band[k].1 - inner[k].0[c] / inner[k].1) as f32)))
        .collect();
    if steps.is_empty() {
        return blends;
    }
    // The field (before fading) at the grid nodes, inverse-square-distance weighted from the
    // sectors' centres.
    let field: Vec<[f32; 3]> = g
        .weights
        .iter()
        .map(|w| {
            let (mut sum, mut wsum) = ([0f32; 3], 0f32);
            for &(k, d) in &steps {
                for c in 0..3 {
                    sum[c] += w[k] * d[c];
                }
                wsum += w[k];
            }
            sum.map(|v| v / wsum)
        })
        .collect();
    let data = sample.as_raw();
    let nodes = g.nodes;
    for &(i, fade, node, fx, fy) in &g.work {
        let i = i as usize;
        if labels[i] != interior {
            continue;
        }
        let node = node as usize;
        let (f00, f10, f01, f11) = (&field[node], &field[node + 1], &field[node + nodes], &field[node + nodes + 1]);
        let delta: [f32; 3] =
            std::array::from_fn(|k| fade * ((1.0 - fy) * ((1.0 - fx) * f00[k] + fx * f10[k]) + fy * ((1.0 - fx) * f01[k] + fx * f11[k])));
        if delta.iter().all(|d| d.abs() < 0.5) {
            continue;
        }
        let v = [raster[3 * i], raster[3 * i + 1], raster[3 * i + 2]];
        // The smallest weight whose colour to blend in, `v + δ/a`, stays within the sample's
        // colours (the smaller the weight, the less a colour bin's width shows): `a ≥ |δ| / room`
        // in every channel.
        let need = (0..3).fold(0f32, |m, k| {
            m.max(delta[k].abs() * if delta[k] > 0.0 { palette.up[k][v[k] as usize] } else { palette.down[k][v[k] as usize] })
        });
        let num = NUM_FOR[((need * DEN as f32).ceil() as usize).min(DEN as usize)];
        let scale = DEN as f32 / f32::from(num);
        let s = palette.near(std::array::from_fn(|k| f32::from(v[k]) + delta[k] * scale));
        let j = 3 * s as usize;
        // Rounded as rendering rounds a blend step (`synth::placement`), so that the tile's
        // raster is what its placement renders.
        let r = feather::blend(v, [data[j], data[j + 1], data[j + 2]], f64::from(num) / f64::from(DEN));
        let miss = |r: [u8; 3]| -> f32 { (0..3).map(|k| (f32::from(r[k]) - f32::from(v[k]) - delta[k]).powi(2)).sum() };
        if miss(r) < miss(v) {
            raster[3 * i..3 * i + 3].copy_from_slice(&r);
            blends[i] = (s, num);
        }
    }
    blends
}

/// A built tile as toning sees it: its square raster, its labels and where its blends go. Both
/// tile methods' tiles are.
pub trait Toneable: Send + Sync {
    fn labels(&self) -> &[u8];
    /// The raster to tone, the labels, and the blends to fill.
    fn tone_parts(&mut self) -> (&mut [u8], &[u8], &mut Vec<ToneBlend>);
}

/// Tones every tile of a set ([`tone_tile`]), in parallel (each tile on its own, so the result
/// does not depend on the thread count); each tile's raster is `side × side`, its interior's
/// pixels labelled `interior`. Returns how many pixels changed.
pub fn tone_set<T: Toneable>(tiles: &mut [T], side: usize, interior: u8, sample: &RgbImage) -> usize {
    let palette = Palette::new(sample);
    let geometry = ToneGeometry::new(side, interior, tiles.iter().map(T::labels));
    tiles
        .par_iter_mut()
        .map(|tile| {
            let (raster, labels, blends) = tile.tone_parts();
            *blends = tone_tile(raster, labels, &geometry, interior, sample, &palette);
            blends.iter().filter(|b| b.1 > 0).count()
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_palette_finds_a_pixel_of_a_colour_near_the_one_asked() {
        let sample = RgbImage::from_fn(16, 16, |x, y| [(x * 16) as u8, (y * 16) as u8, 100]);
        let p = Palette::new(&sample);
        for c in [[0.0f32, 0.0, 100.0], [120.0, 200.0, 100.0], [250.0, 250.0, 250.0], [37.0, 91.0, 0.0]] {
            let s = p.near(c);
            let got = sample.get(s % 16, s / 16);
            // Every colour in the sample's gamut has a pixel within a bin or so of it.
            let near: [f32; 3] = [c[0].min(240.0), c[1].min(240.0), 100.0];
            for k in 0..3 {
                assert!((f32::from(got[k]) - near[k]).abs() <= 16.0, "{c:?} -> {got:?}");
            }
        }
    }

    /// A tile whose band is 40 grey levels lighter than its interior: toned, the interior next to
    /// the band comes within a few levels of it, the centre (beyond the fade) is untouched, the
    /// fine texture is kept, and every changed pixel is the recorded blend step, rounded as
    /// rendering rounds.
    #[test]
    fn an_interior_takes_its_bands_tone_and_the_blends_replay_it() {
        let side = 48usize;
        let noise = |x: usize, y: usize| ((x * 37 + y * 91) % 17) as i32 - 8;
        let sample = RgbImage::from_fn(64, 64, |x, y| {
            let v = (60 + x as i32 * 2 + noise(x as usize, y as usize)).clamp(0, 255) as u8;
            [v, v, v]
        });
        let palette = Palette::new(&sample);
        let mut raster = vec![0u8; side * side * 3];
        let mut labels = vec![0u8; side * side];
        for y in 0..side {
            for x in 0..side {
                let i = y * side + x;
                let edge = x.min(y).min(side - 1 - x).min(side - 1 - y);
                let (v, l) = if edge < 4 { (140 + noise(x, y), 0) } else { (100 + noise(x, y), 4) };
                raster[3 * i..3 * i + 3].fill(v as u8);
                labels[i] = l;
            }
        }
        let before = raster.clone();
        let geometry = ToneGeometry::new(side, 4, std::iter::once(&labels[..]));
        let blends = tone_tile(&mut raster, &labels, &geometry, 4, &sample, &palette);
        let mean = |r: &[u8], pick: &dyn Fn(usize, usize) -> bool| {
            let (mut s, mut c) = (0.0, 0.0);
            for y in 0..side {
                for x in 0..side {
                    if pick(x, y) {
                        s += f64::from(r[3 * (y * side + x)]);
                        c += 1.0;
                    }
                }
            }
            s / c
        };
        let edge = |x: usize, y: usize| x.min(y).min(side - 1 - x).min(side - 1 - y);
        let next_to_band = |x: usize, y: usize| (4..6).contains(&edge(x, y));
        assert!(mean(&before, &next_to_band) < 105.0);
        let toned = mean(&raster, &next_to_band);
        assert!((toned - 140.0).abs() < 8.0, "next to the band: {toned}");
        for y in 0..side {
            for x in 0..side {
                let i = y * side + x;
                if edge(x, y) >= 4 + FADE {
                    assert_eq!(raster[3 * i], before[3 * i], "beyond the fade ({x}, {y})");
                }
                if labels[i] == 0 {
                    assert_eq!(raster[3 * i], before[3 * i], "the band never changes");
                }
                let (s, num) = blends[i];
                if num == 0 {
                    assert_eq!(raster[3 * i..3 * i + 3], before[3 * i..3 * i + 3]);
                } else {
                    let sp = sample.get(s % 64, s / 64);
                    let old = [before[3 * i], before[3 * i + 1], before[3 * i + 2]];
                    assert_eq!(raster[3 * i..3 * i + 3], feather::blend(old, sp, f64::from(num) / f64::from(DEN)));
                }
            }
        }
        // The texture's detail survives: neighbouring differences inside the fade zone stay.
        let detail = |r: &[u8]| {
            (6..side - 6).map(|x| (i32::from(r[3 * (10 * side + x + 1)]) - i32::from(r[3 * (10 * side + x)])).abs()).sum::<i32>()
        };
        assert!(detail(&raster) * 2 > detail(&before), "{} vs {}", detail(&raster), detail(&before));
    }
}
