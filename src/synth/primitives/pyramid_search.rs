//! Coarse-to-fine block search for big samples (docs/methods.md §6, `search = "pyramid"`): the
//! cost of a block's search stops growing with the sample's pixels.
//!
//! Why: the exact search ([`OverlapSearch`]) scores every sample position, so a 12 MP camera photo
//! costs about fifty times a 512² sample per block, and its FFT planes hold ~130 bytes per sample
//! pixel. Here the sample is reduced by 2×2 means, level after level (a box pyramid: the crudest
//! Gaussian pyramid, whose cells line up exactly with sample positions that are multiples of the
//! level's factor), up to the first level of at most [`COARSE_PIXELS`] pixels, unless the block
//! would shrink below [`MIN_COARSE_BLOCK`] pixels there. The coarse level itself describes each
//! cell by its mean luma, a yellow–blue mean and its luma's spread ([`coarse_features`]: means
//! alone confuse sharp and blurred regions). On it the exact FFT search finds each block's best
//! positions against the block's overlap reduced the same way (a cell of the overlap is made of
//! the known pixels in it, and counts when at least half of it is known); [`TRACKS`] of them, no two adjacent, are carried down level by level, each re-scored
//! exactly within ±[`REFINE`] of its position doubled and moved to the best there. At full
//! resolution every position of those last windows is scored exactly (the method's own integer
//! overlap error), and the method picks among them with its own rule (tolerance), as it would
//! among all positions.
//!
//! Deterministic: every choice is made on exact integers, ties broken by position, and no result
//! depends on how the blocks or tracks are split across threads. Memory: the reduced levels hold a
//! third of the sample's pixels, and the FFT search only the coarse level's; the sample itself is
//! the method's, borrowed.

use super::overlap::{Rect, bytes_ssd};
use super::overlap_search::{Candidates, OverlapSearch};
use crate::image::RgbImage;
use rayon::prelude::*;

/// The coarse level is the first of at most this many pixels (512²)…
///
/// Measured (benches/pyramid.rs, quality part: six bundled samples with structure enlarged to
/// 1024², 512² outputs): with 256² coarse levels, paper 003's four measures of the pyramid's
/// outputs summed over the samples were 1.40, 0.78, 0.85 and 1.74 × the exact search's (joints of
/// bricks broken: a coarse level 4× reduced misses the exact continuations an enlarged sample
/// has); with 512², 1.00, 0.99, 0.99 and 1.00 (128 tracks instead: 1.25, 1.28, 1.10, 0.93 at a
/// similar cost). A 12 MP sample's coarse level is bounded by [`MIN_COARSE_BLOCK`] either way.
pub const COARSE_PIXELS: u64 = 512 * 512;
/// … unless the block would be smaller than this there: a block of a few pixels ranks little.
pub const MIN_COARSE_BLOCK: u32 = 6;
/// Positions carried down from the coarse level per block.
pub const TRACKS: usize = 32;
/// A track is re-scored within this many positions of its doubled position, on every level.
pub const REFINE: u32 = 2;

/// The coarse level for a `block` in a `sample` (0: the sample is small enough to search whole).
pub fn coarse_level(sample: (u32, u32), block: u32) -> u32 {
    let mut level = 0;
    loop {
        if u64::from(sample.0 >> level) * u64::from(sample.1 >> level) <= COARSE_PIXELS {
            return level;
        }
        let next = level + 1;
        let b = block.div_ceil(1 << next);
        if b < MIN_COARSE_BLOCK || sample.0 >> next < b || sample.1 >> next < b {
            return level;
        }
        level = next;
    }
}

/// A sample's pyramid and the exact search of its coarse level, for blocks of one size.
pub struct PyramidSearch<'a> {
    sample: &'a RgbImage,
    block: u32,
    /// The coarse level's index (0: no reduction, the search is the exact one).
    top: u32,
    /// Levels `1..top` (means): `levels[l - 1]` is level `l`. The coarse level is `coarse`'s image
    /// ([`coarse_features`]).
    levels: Vec<RgbImage>,
    coarse: OverlapSearch<'a>,
}

/// A block's overlap reduced to one level: the template image (`b × b`) and its regions.
type Template = (RgbImage, Vec<Rect>);

impl<'a> PyramidSearch<'a> {
    /// Builds the pyramid of `sample` for `block × block` blocks (the block must fit the sample).
    pub fn new(sample: &'a RgbImage, block: u32) -> PyramidSearch<'a> {
        let top = coarse_level(sample.dimensions(), block);
        let mut levels: Vec<RgbImage> = Vec::new();
        let coarse = if top == 0 {
            OverlapSearch::new(sample, block, block)
        } else {
            for _ in 1..top {
                let next = reduce(levels.last().unwrap_or(sample));
                levels.push(next);
            }
            let b = block.div_ceil(1 << top);
            OverlapSearch::owning(coarse_features(sample, top), b, b)
        };
        PyramidSearch { sample, block, top, levels, coarse }
    }

    /// The coarse level's index (its factor is `2^level`).
    pub fn coarse_level(&self) -> u32 {
        self.top
    }

    /// The candidate set of one block: among the positions re-scored at full resolution, those
    /// within `(1 + tolerance)` of the best of them, row-major. `target` holds the known pixels at
    /// `origin + region`, as for [`OverlapSearch::candidates`].
    pub fn candidates(&mut self, target: &RgbImage, origin: (u32, u32), regions: &[Rect], tolerance: f64) -> Candidates {
        if self.top == 0 {
            return self.coarse.candidates(target, origin, regions, tolerance);
        }
        within_tolerance(self.rescored(target, origin, regions, &[]), tolerance)
    }

    /// [`PyramidSearch::candidates`] of several blocks against the same `target`, in the order
    /// given; blocks are searched concurrently.
    pub fn candidates_many(&mut self, target: &RgbImage, queries: &[((u32, u32), Vec<Rect>)], tolerance: f64) -> Vec<Candidates> {
        self.candidates_many_hinted(target, queries, &[], tolerance)
    }

    /// [`PyramidSearch::candidates_many`], each block's re-scored positions joined by its
    /// `hints[i]` (when given): positions the method expects to match well, such as the natural
    /// continuations of the blocks already placed beside it. Why: an exact search finds a
    /// continuation whose overlap matches exactly (a photo's own next pixels, an enlarged
    /// sample's smooth neighbourhood), but at a deep coarse level an overlap of a few pixels is
    /// one cell wide, and the continuation need not be among the tracks: a 12 MP sample (level 3)
    /// came out in broken pebbles where the exact search kept them whole.
    pub fn candidates_many_hinted(
        &mut self,
        target: &RgbImage,
        queries: &[((u32, u32), Vec<Rect>)],
        hints: &[Vec<(u32, u32)>],
        tolerance: f64,
    ) -> Vec<Candidates> {
        if self.top == 0 {
            return self.coarse.candidates_many(target, queries, tolerance);
        }
        let pools = self.rescored_many(target, queries, hints);
        pools.into_iter().map(|p| within_tolerance(p, tolerance)).collect()
    }

    /// Every position re-scored at full resolution for one block, with its exact overlap error,
    /// row-major: what [`PyramidSearch::candidates`] picks among (for rules that are not relative
    /// to the best, such as Liang et al.'s).
    pub fn rescored(&mut self, target: &RgbImage, origin: (u32, u32), regions: &[Rect], hints: &[(u32, u32)]) -> Vec<(u32, u32, u64)> {
        if self.top == 0 {
            let all = self.coarse.all_ssd_direct(target, origin, regions);
            let nx = self.sample.width() - self.block + 1;
            return all.into_iter().enumerate().map(|(i, s)| (i as u32 % nx, i as u32 / nx, s)).collect();
        }
        self.rescored_many(target, &[(origin, regions.to_vec())], &[hints.to_vec()]).pop().expect("one pool per block")
    }

    fn rescored_many(
        &mut self,
        target: &RgbImage,
        queries: &[((u32, u32), Vec<Rect>)],
        hints: &[Vec<(u32, u32)>],
    ) -> Vec<Vec<(u32, u32, u64)>> {
        let top = self.top;
        let templates: Vec<Template> =
            queries.par_iter().map(|(origin, regions)| coarse_template(target, *origin, regions, self.block, top)).collect();
        let best = self.coarse.best_many(&templates, 4 * TRACKS);
        let this = &*self;
        let single = queries.len() == 1;
        let none = Vec::new();
        queries
            .par_iter()
            .zip(best.into_par_iter())
            .enumerate()
            .with_max_len(1)
            .map(|(i, ((origin, regions), best))| {
                this.refine(target, *origin, regions, &spread(&best), hints.get(i).unwrap_or(&none), single)
            })
            .collect()
    }

    /// Level `l`'s image (`0 ≤ l < top`: the coarse level's image is [`coarse_features`]).
    fn level(&self, l: u32) -> &RgbImage {
        match l {
            0 => self.sample,
            l => &self.levels[l as usize - 1],
        }
    }

    /// Carries `tracks` (coarse positions) down to full resolution; returns the last windows'
    /// positions with their exact errors, row-major, each once.
    fn refine(
        &self,
        target: &RgbImage,
        origin: (u32, u32),
        regions: &[Rect],
        tracks: &[(u32, u32)],
        hints: &[(u32, u32)],
        parallel: bool,
    ) -> Vec<(u32, u32, u64)> {
        let mut tracks = tracks.to_vec();
        for l in (1..self.top).rev() {
            let (t_img, t_regions) = template(target, origin, regions, self.block, l);
            let level = self.level(l);
            let b = self.block.div_ceil(1 << l);
            let best_in = |&(x, y): &(u32, u32)| {
                window(x, y, level, b)
                    .map(|(px, py)| (ssd(level, px, py, &t_img, (0, 0), &t_regions), py, px))
                    .min()
                    .map(|(_, py, px)| (px, py))
                    .expect("a window holds its centre")
            };
            tracks = if parallel { tracks.par_iter().map(best_in).collect() } else { tracks.iter().map(best_in).collect() };
            tracks.sort_by_key(|&(x, y)| (y, x));
            tracks.dedup();
        }
        let mut positions: Vec<(u32, u32)> = tracks.iter().flat_map(|&(x, y)| window(x, y, self.sample, self.block)).collect();
        let (nx, ny) = (self.sample.width() - self.block + 1, self.sample.height() - self.block + 1);
        positions.extend(hints.iter().filter(|&&(x, y)| x < nx && y < ny));
        positions.sort_by_key(|&(x, y)| (y, x));
        positions.dedup();
        let score = |&(x, y): &(u32, u32)| (x, y, ssd(self.sample, x, y, target, origin, regions));
        if parallel { positions.par_iter().map(score).collect() } else { positions.iter().map(score).collect() }
    }
}

/// The positions within ±[`REFINE`] of `(2x, 2y)` (a position one level up, doubled) where a
/// `block` fits in `image`.
fn window(x: u32, y: u32, image: &RgbImage, block: u32) -> impl Iterator<Item = (u32, u32)> {
    let (nx, ny) = (image.width() - block + 1, image.height() - block + 1);
    let span = |c: u32, n: u32| (2 * c).saturating_sub(REFINE).min(n - 1)..=(2 * c + 1 + REFINE).min(n - 1);
    let xs = span(x, nx);
    span(y, ny).flat_map(move |py| xs.clone().map(move |px| (px, py)))
}

/// Up to [`TRACKS`] of the coarse search's best positions (sorted by error), no two adjacent:
/// neighbours of one good match would otherwise fill the tracks with a single place.
fn spread(best: &[(u32, u32, u64)]) -> Vec<(u32, u32)> {
    let mut kept: Vec<(u32, u32)> = Vec::with_capacity(TRACKS);
    for &(x, y, _) in best {
        if kept.len() == TRACKS {
            break;
        }
        if kept.iter().all(|&(kx, ky)| kx.abs_diff(x) > 1 || ky.abs_diff(y) > 1) {
            kept.push((x, y));
        }
    }
    kept
}

/// The positions within `(1 + tolerance)` of the smallest error of `pool`.
fn within_tolerance(pool: Vec<(u32, u32, u64)>, tolerance: f64) -> Candidates {
    let min = pool.iter().map(|c| c.2).min().expect("at least one position is re-scored");
    let members = pool.into_iter().filter(|c| (c.2 as f64) <= (1.0 + tolerance) * (min as f64)).collect();
    Candidates { min_ssd: min, members }
}

/// The exact overlap error of the block at `(x, y)` of `image` against `target` at `origin`.
fn ssd(image: &RgbImage, x: u32, y: u32, target: &RgbImage, origin: (u32, u32), regions: &[Rect]) -> u64 {
    let run = |x: u32, w: u32| x as usize * 3..(x + w) as usize * 3;
    regions
        .iter()
        .flat_map(|r| (0..r.h).map(move |dy| (r, dy)))
        .map(|(r, dy)| bytes_ssd(&image.row(y + r.y + dy)[run(x + r.x, r.w)], &target.row(origin.1 + r.y + dy)[run(origin.0 + r.x, r.w)]))
        .sum()
}

/// One level down the pyramid: every 2×2 cell's mean, rounded (an odd last row or column is dropped).
pub(crate) fn reduce(image: &RgbImage) -> RgbImage {
    let (w, h) = (image.width() / 2, image.height() / 2);
    let mut out = RgbImage::new(w, h);
    let data = out.as_raw_mut();
    for (y, row) in data.chunks_exact_mut(3 * w as usize).enumerate() {
        let (a, b) = (image.row(2 * y as u32), image.row(2 * y as u32 + 1));
        for (x, p) in row.chunks_exact_mut(3).enumerate() {
            for (c, v) in p.iter_mut().enumerate() {
                let i = 6 * x + c;
                let sum = u32::from(a[i]) + u32::from(a[i + 3]) + u32::from(b[i]) + u32::from(b[i + 3]);
                *v = ((sum + 2) / 4) as u8;
            }
        }
    }
    out
}

/// A block's overlap (`regions` of `target` at `origin`) reduced to `level`: each `2^level` cell
/// the mean of its known pixels, kept when at least half of the cell (inside the block) is known;
/// when no cell is, every cell with a known pixel. Regions are the kept cells as rectangles.
fn template(target: &RgbImage, origin: (u32, u32), regions: &[Rect], block: u32, level: u32) -> Template {
    reduced_template(target, origin, regions, block, level, Cell::mean)
}

/// [`template`] in the coarse level's terms ([`coarse_features`]).
fn coarse_template(target: &RgbImage, origin: (u32, u32), regions: &[Rect], block: u32, level: u32) -> Template {
    reduced_template(target, origin, regions, block, level, Cell::features)
}

fn reduced_template(
    target: &RgbImage,
    origin: (u32, u32),
    regions: &[Rect],
    block: u32,
    level: u32,
    value: fn(&Cell) -> [u8; 3],
) -> Template {
    let f = 1u32 << level;
    let b = block.div_ceil(f);
    let mut cells = vec![Cell::default(); (b * b) as usize];
    for r in regions {
        for y in r.y..r.y + r.h {
            let row = target.row(origin.1 + y);
            for x in r.x..r.x + r.w {
                let i = ((origin.0 + x) * 3) as usize;
                cells[((y / f) * b + x / f) as usize].add(&row[i..i + 3]);
            }
        }
    }
    let cell_area = |i: u32| f.min(block - i * f);
    let mut keep: Vec<bool> = (0..b * b).map(|k| 2 * cells[k as usize].n >= cell_area(k % b) * cell_area(k / b)).collect();
    if !keep.contains(&true) {
        keep = cells.iter().map(|c| c.n > 0).collect();
    }
    let image = RgbImage::from_fn(b, b, |x, y| {
        let c = &cells[(y * b + x) as usize];
        if !keep[(y * b + x) as usize] || c.n == 0 { [0; 3] } else { value(c) }
    });
    (image, rectangles(&keep, b))
}

/// Sums over the known pixels of one cell of a reduced level.
#[derive(Clone, Default)]
struct Cell {
    rgb: [u32; 3],
    /// Σ of `r + 2g + b` (four times the luma) and of its square.
    luma4: u32,
    luma4_sq: u64,
    n: u32,
}

/// Weight of a cell's luma standard deviation against its means in [`coarse_features`].
const CONTRAST_GAIN: f64 = 2.0;

impl Cell {
    fn add(&mut self, p: &[u8]) {
        for (sum, &v) in self.rgb.iter_mut().zip(p) {
            *sum += u32::from(v);
        }
        let l = u32::from(p[0]) + 2 * u32::from(p[1]) + u32::from(p[2]);
        self.luma4 += l;
        self.luma4_sq += u64::from(l * l);
        self.n += 1;
    }

    fn mean(&self) -> [u8; 3] {
        let n = self.n;
        self.rgb.map(|s| ((s + n / 2) / n) as u8)
    }

    /// Mean luma, mean yellow–blue opponent (`(r + g − 2b) / 4`, centred on 128) and the luma's
    /// standard deviation times [`CONTRAST_GAIN`]: what [`coarse_features`] compares.
    fn features(&self) -> [u8; 3] {
        let n = f64::from(self.n);
        let luma = f64::from(self.luma4) / (4.0 * n);
        let [r, g, b] = self.rgb.map(|s| f64::from(s) / n);
        let opponent = (r + g - 2.0 * b) / 4.0 + 128.0;
        let mean4 = f64::from(self.luma4) / n;
        let var = (self.luma4_sq as f64 / n - mean4 * mean4).max(0.0) / 16.0;
        let contrast = CONTRAST_GAIN * var.sqrt();
        [luma, opponent, contrast].map(|v| v.round().clamp(0.0, 255.0) as u8)
    }
}

/// The coarse level the candidates are ranked on: per `2^level` cell of the sample (an odd last
/// row or column dropped, as [`reduce`] does), its mean luma, its yellow–blue mean and its luma's
/// standard deviation ([`Cell::features`]). Why not the cells' mean colour alone: a mean cannot
/// tell a sharp region of a photo from a blurred one of the same tone (depth of field, a smooth
/// stain), and on a camera photo of wood boards (2560×1920, 8× reduced) the 32 best tracks of a
/// sharp grain overlap all fell in the larger blurred part, so the output lost the grain
/// (benches/pyramid.rs, photos part). The spread of the cell keeps them apart; one chroma axis
/// is given up for it.
fn coarse_features(sample: &RgbImage, level: u32) -> RgbImage {
    let f = 1u32 << level;
    let (w, h) = (sample.width() >> level, sample.height() >> level);
    let mut out = RgbImage::new(w, h);
    out.as_raw_mut().par_chunks_exact_mut(3 * w as usize).enumerate().for_each(|(cy, row)| {
        let mut cells = vec![Cell::default(); w as usize];
        for y in cy as u32 * f..(cy as u32 + 1) * f {
            let line = sample.row(y);
            for (cx, cell) in cells.iter_mut().enumerate() {
                let x0 = cx * f as usize * 3;
                for p in line[x0..x0 + 3 * f as usize].chunks_exact(3) {
                    cell.add(p);
                }
            }
        }
        for (p, cell) in row.chunks_exact_mut(3).zip(&cells) {
            p.copy_from_slice(&cell.features());
        }
    });
    out
}

/// The `true` cells of a `b × b` mask as disjoint rectangles: each row's runs, merged with the
/// same runs of the rows below.
fn rectangles(mask: &[bool], b: u32) -> Vec<Rect> {
    let runs = |y: u32| -> Vec<(u32, u32)> {
        let row = &mask[(y * b) as usize..((y + 1) * b) as usize];
        let mut out = Vec::new();
        let mut x = 0;
        while x < b {
            if row[x as usize] {
                let start = x;
                while x < b && row[x as usize] {
                    x += 1;
                }
                out.push((start, x - start));
            } else {
                x += 1;
            }
        }
        out
    };
    let mut rects = Vec::new();
    let mut y = 0;
    while y < b {
        let here = runs(y);
        let mut h = 1;
        while y + h < b && runs(y + h) == here {
            h += 1;
        }
        rects.extend(here.into_iter().map(|(x, w)| Rect::new(x, y, w, h)));
        y += h;
    }
    rects
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::rng::Stream;

    /// A smooth random texture (noise summed over 8×8 cells and single pixels): like a photo, it
    /// has structure at the coarse levels as well as at full resolution.
    fn texture(w: u32, h: u32, seed: u64) -> RgbImage {
        let mut s = Stream::new(seed, "test/texture");
        let cells: Vec<[u8; 3]> =
            (0..(w / 8 + 1) * (h / 8 + 1)).map(|_| [s.below(200) as u8, s.below(200) as u8, s.below(200) as u8]).collect();
        RgbImage::from_fn(w, h, |x, y| {
            let c = cells[((y / 8) * (w / 8 + 1) + x / 8) as usize];
            let n = s.below(56) as u8;
            [c[0] + n, c[1] + n / 2, c[2] + (55 - n)]
        })
    }

    #[test]
    fn the_coarse_level_is_small_but_keeps_the_block() {
        assert_eq!(coarse_level((256, 256), 50), 0);
        assert_eq!(coarse_level((512, 512), 50), 0);
        assert_eq!(coarse_level((1024, 1024), 50), 1);
        assert_eq!(coarse_level((2048, 2048), 50), 2);
        // 4000×3000 would be under 512² at level 3; block 50 is 7 pixels there, 4 at level 4.
        assert_eq!(coarse_level((4000, 3000), 50), 3);
        assert_eq!(coarse_level((8000, 6000), 100), 4);
        assert_eq!(coarse_level((4000, 3000), 8), 0);
    }

    #[test]
    fn an_l_shaped_overlap_reduces_to_its_cells() {
        let target = RgbImage::from_fn(20, 20, |x, y| [(x * 10) as u8, (y * 10) as u8, 7]);
        let regions = [Rect::new(0, 0, 4, 20), Rect::new(4, 0, 16, 4)];
        let (img, rects) = template(&target, (0, 0), &regions, 20, 2);
        assert_eq!(img.dimensions(), (5, 5));
        assert_eq!(rects, vec![Rect::new(0, 0, 5, 1), Rect::new(0, 1, 1, 4)]);
        // Cell (1, 0) is pixels x 4..8, y 0..4: means 55 and 15.
        assert_eq!(img.get(1, 0), [55, 15, 7]);
        // A 2-pixel overlap covers half of each cell of level 2: kept; at level 3 a quarter, so
        // every touched cell is kept instead.
        let thin = [Rect::new(0, 0, 2, 20)];
        assert_eq!(template(&target, (0, 0), &thin, 20, 2).1, vec![Rect::new(0, 0, 1, 5)]);
        assert_eq!(template(&target, (0, 0), &thin, 20, 3).1, vec![Rect::new(0, 0, 1, 3)]);
    }

    #[test]
    fn a_copy_of_the_sample_is_found_exactly() {
        let sample = texture(1100, 1000, 3);
        let mut search = PyramidSearch::new(&sample, 32);
        assert_eq!(search.coarse_level(), 2);
        for (x, y) in [(123, 77), (0, 0), (568, 488), (301, 250)] {
            let target = sample.crop(x, y, 32, 32);
            let regions = [Rect::new(0, 0, 6, 32), Rect::new(6, 0, 26, 6)];
            let c = search.candidates(&target, (0, 0), &regions, 0.0);
            assert_eq!((c.min_ssd, c.members[0].0, c.members[0].1), (0, x, y), "copy of ({x}, {y})");
        }
    }

    #[test]
    fn many_blocks_at_once_equal_one_at_a_time_on_any_pool() {
        let sample = texture(640, 480, 5);
        let target = texture(200, 200, 6);
        let queries: Vec<((u32, u32), Vec<Rect>)> = vec![
            ((3, 4), vec![Rect::new(0, 0, 8, 40)]),
            ((80, 2), vec![Rect::new(0, 0, 40, 8)]),
            ((30, 100), vec![Rect::new(0, 0, 8, 40), Rect::new(8, 0, 32, 8)]),
        ];
        let mut search = PyramidSearch::new(&sample, 40);
        let one_by_one: Vec<Candidates> = queries.iter().map(|(o, r)| search.candidates(&target, *o, r, 0.2)).collect();
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            assert_eq!(pool.install(|| search.candidates_many(&target, &queries, 0.2)), one_by_one, "{threads} threads");
        }
        // Every member's error is the exact one.
        let exact = OverlapSearch::new(&sample, 40, 40);
        for (c, (o, r)) in one_by_one.iter().zip(&queries) {
            assert!(c.members.iter().all(|m| m.2 == exact.exact_ssd(m.0, m.1, &target, *o, r)));
            assert!(c.members.iter().all(|m| m.2 as f64 <= 1.2 * c.min_ssd as f64));
        }
    }

    #[test]
    fn a_sharp_overlap_is_not_matched_to_a_blurred_region_of_its_tone() {
        // Left half flat 128, right half 2-px stripes of 64 and 192 (a grain whose blur is the
        // left half): every 4-px cell of either has mean 128, so a coarse level of means ties the
        // halves and, ties going to the first position, sends a striped overlap's tracks to the
        // flat half. The cells' spread keeps them on the stripes, where it is found exactly.
        let stripes = |x: u32| if (x / 2).is_multiple_of(2) { 64 } else { 192 };
        let sample = RgbImage::from_fn(1100, 1000, |x, _| {
            let v = if x < 550 { 128 } else { stripes(x) };
            [v, v, v]
        });
        let target = RgbImage::from_fn(32, 32, |x, _| [stripes(x); 3]);
        let mut search = PyramidSearch::new(&sample, 32);
        assert_eq!(search.coarse_level(), 2);
        let regions = [Rect::new(0, 0, 6, 32), Rect::new(6, 0, 26, 6)];
        let c = search.candidates(&target, (0, 0), &regions, 0.0);
        let (x, y) = (c.members[0].0, c.members[0].1);
        assert!(x >= 550 && c.min_ssd == 0, "picked ({x}, {y}), error {}", c.min_ssd);
    }

    #[test]
    fn hints_join_the_rescored_positions_with_their_exact_error() {
        let sample = texture(1100, 1000, 21);
        let target = texture(120, 120, 22);
        let regions = vec![Rect::new(0, 0, 8, 48), Rect::new(8, 0, 40, 8)];
        let mut search = PyramidSearch::new(&sample, 48);
        let hint = (1051, 3);
        let plain = search.rescored(&target, (10, 20), &regions, &[]);
        assert!(!plain.iter().any(|p| (p.0, p.1) == hint), "the hint is not a track's position here");
        let hinted = search.rescored(&target, (10, 20), &regions, &[hint, (1053, 0)]);
        let exact = OverlapSearch::new(&sample, 48, 48).exact_ssd(hint.0, hint.1, &target, (10, 20), &regions);
        assert!(hinted.contains(&(hint.0, hint.1, exact)), "{:?}", hinted.len());
        // A hint where the block does not fit is dropped; the rest of the pool is unchanged.
        assert_eq!(hinted.len(), plain.len() + 1);
        // candidates_many_hinted: a hint that matches exactly becomes the best candidate.
        let copy = sample.crop(1051, 3, 48, 48);
        let c = search.candidates_many_hinted(&copy, &[((0, 0), regions.clone())], &[vec![hint]], 0.0);
        assert_eq!((c[0].min_ssd, c[0].members[0].0, c[0].members[0].1), (0, 1051, 3));
    }

    #[test]
    fn a_small_sample_is_searched_exactly() {
        let sample = texture(200, 180, 8);
        let target = texture(60, 60, 9);
        let regions = [Rect::new(0, 0, 5, 30), Rect::new(5, 0, 25, 5)];
        let mut pyramid = PyramidSearch::new(&sample, 30);
        assert_eq!(pyramid.coarse_level(), 0);
        let exact = OverlapSearch::new(&sample, 30, 30).candidates_direct(&target, (10, 10), &regions, 0.1);
        assert_eq!(pyramid.candidates(&target, (10, 10), &regions, 0.1), exact);
    }
}
