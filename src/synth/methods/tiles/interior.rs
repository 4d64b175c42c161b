//! Tile interiors of their own (issue #30): each tile keeps a narrow band along its edges from the
//! edge-colour patches (what makes neighbours match) and takes everything inside a closed seam from
//! a sample patch of its own.
//!
//! Why: in paper 001's tiles every pixel comes from one of the four edge-colour patches, so two
//! tiles whose edges share a colour share that patch over a quarter of their area. With `K`
//! colours a fill's autocorrelation at the tile period cannot fall below about `1/K`, while
//! quilting's falls to a few hundredths. With interiors of their own, only the band is shared,
//! so that floor is about `band area / K`, and the `K³` tiles of a set show `K³` distinct
//! interiors drawn all over the sample.
//!
//! Shared by both tile methods: a geometry is described only by its tile raster's side and, for each
//! pixel of the tile, its coordinates `(p, q)` relative to each of the tile's four sides (`p` along
//! the side, `q` the depth in from it), so the square Wang tiles and the rhombus RW tiles (sides at
//! 45°, `q` in steps of `x + y` or `y − x`) use the same seam. Each side gets a quilting-style DP
//! cut (B3: one depth per position, moving by at most one step) through its strip of depths
//! `q0 .. q1`; a pixel takes the tile's own patch when it lies at or beyond all four cuts and joins
//! the core. The cuts meet at the corners as quilting's left and top cuts do. Pixels shallower than `q0`, the
//! tile's edges among them, never change, so every valid tiling stays valid and seamless at the
//! tile edges. (A closed shortest path through the ring, B4, joins the sides more freely, but it
//! made a 2048² fill about 1.5 times slower than these four cuts.)

use super::align::Alignment;
use super::common::{InteriorMode, PixelError};
use crate::image::RgbImage;
use crate::synth::primitives::shortest_path::flood4;
use crate::synth::rng::Stream;
use rayon::prelude::*;

/// The label of a pixel that comes from the tile's own patch (edge-patch labels are 0..=3).
pub const INTERIOR: u8 = 4;

/// How many random patch positions are tried per tile; the one that agrees best with the band over
/// the ring (sum of pixel errors over every third ring pixel) is kept, as quilting keeps a block
/// that matches its overlap.
pub const CANDIDATES: usize = 16;

/// One side's strip: positions `p_lo ..= p_hi` along it, depths `q0 .. q1`, and the raster pixel at
/// each `(p, q)` (`NONE` where there is none: outside the tile, or a lattice parity gap).
#[derive(Clone, Debug)]
struct Strip {
    p_lo: i32,
    positions: usize,
    at: Vec<usize>,
}

const NONE: usize = usize::MAX;

/// The strips, ring and per-pixel side coordinates of one tile geometry: the same for every tile
/// of a set.
#[derive(Clone, Debug)]
pub struct Ring {
    side: usize,
    q0: i32,
    q1: i32,
    strips: [Strip; 4],
    /// Every pixel at depth `q0` or more, with its `(p, q)` for each side.
    inner: Vec<(usize, [(i32, i32); 4])>,
    /// Pixels of depth `q0 .. q1` (the smallest `q` over the sides), in raster order.
    ring: Vec<usize>,
    /// The ring's pixels with their side coordinates: the only ones a cut can leave out.
    ring_sides: Vec<(usize, [(i32, i32); 4])>,
    /// Whether each raster pixel is in the core.
    is_core: Vec<bool>,
    /// The core pixels with a 4-neighbour outside the core: a flood from the core can leave it
    /// only through them.
    core_border: Vec<usize>,
    /// The core as runs along raster rows (first pixel, length): copied from a patch a row
    /// slice at a time.
    core_runs: Vec<(usize, usize)>,
    /// The ring's pixels as `(x, y)`, in the order of `ring`.
    ring_xy: Vec<(i32, i32)>,
    /// Every third ring pixel ([`Ring::ring_cost`]), as `(x, y)`.
    probes: Vec<(i32, i32)>,
    /// Top-left of the bounding box of the inner pixels, and its size: what one patch covers.
    origin: (i32, i32),
    extent: (u32, u32),
}

/// A tile's interior: the offset from its raster's pixels to the sample pixels they copy, and the
/// cost of its cuts (sum of pixel errors along them).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Interior {
    pub offset: (i32, i32),
    pub cost: u64,
}

impl Ring {
    /// The ring of depths `q0 .. q1` of a `side × side` raster whose tile pixels have side
    /// coordinates `sides(x, y)` (`None` outside the tile); `None` when the tile is too small for
    /// one (no pixel deeper than the ring).
    pub fn new(side: usize, q0: i32, q1: i32, sides: impl Fn(i32, i32) -> Option<[(i32, i32); 4]>) -> Option<Ring> {
        if q0 < 1 || q1 <= q0 + 1 {
            return None;
        }
        let coords: Vec<Option<[(i32, i32); 4]>> = (0..side * side).map(|i| sides((i % side) as i32, (i / side) as i32)).collect();
        let depth = |c: &[(i32, i32); 4]| c.iter().map(|pq| pq.1).min().expect("four sides");
        if !coords.iter().flatten().any(|c| depth(c) >= q1) {
            return None;
        }
        let inner: Vec<(usize, [(i32, i32); 4])> =
            coords.iter().enumerate().filter_map(|(i, c)| c.filter(|c| depth(c) >= q0).map(|c| (i, c))).collect();
        let ring: Vec<usize> = inner.iter().filter(|(_, c)| depth(c) < q1).map(|&(i, _)| i).collect();
        // Pixels of depth `q1` or more: beyond every cut.
        let core: Vec<usize> = inner.iter().filter(|(_, c)| depth(c) >= q1).map(|&(i, _)| i).collect();
        let strips = std::array::from_fn(|k| {
            let ps = coords.iter().flatten().map(|c| c[k].0);
            let (p_lo, p_hi) = (ps.clone().min().expect("tile pixels"), ps.max().expect("tile pixels"));
            let positions = (p_hi - p_lo + 1) as usize;
            let nq = (q1 - q0) as usize;
            let mut at = vec![NONE; positions * nq];
            for (i, c) in coords.iter().enumerate() {
                if let Some(c) = c
                    && (q0..q1).contains(&c[k].1)
                {
                    at[(c[k].0 - p_lo) as usize * nq + (c[k].1 - q0) as usize] = i;
                }
            }
            Strip { p_lo, positions, at }
        });
        let xs = inner.iter().map(|&(i, _)| (i % side) as i32);
        let ys = inner.iter().map(|&(i, _)| (i / side) as i32);
        let (x0, x1) = (xs.clone().min()?, xs.max()?);
        let (y0, y1) = (ys.clone().min()?, ys.max()?);
        let ring_sides: Vec<(usize, [(i32, i32); 4])> = inner.iter().filter(|(_, c)| depth(c) < q1).copied().collect();
        let mut is_core = vec![false; side * side];
        for &i in &core {
            is_core[i] = true;
        }
        let core_border = core
            .iter()
            .copied()
            .filter(|&i| {
                let (x, y) = (i % side, i / side);
                (x > 0 && !is_core[i - 1])
                    || (x + 1 < side && !is_core[i + 1])
                    || (y > 0 && !is_core[i - side])
                    || (y + 1 < side && !is_core[i + side])
            })
            .collect();
        let mut core_runs: Vec<(usize, usize)> = Vec::new();
        for &i in &core {
            match core_runs.last_mut() {
                Some((start, len)) if *start + *len == i && i % side != 0 => *len += 1,
                _ => core_runs.push((i, 1)),
            }
        }
        let ring_xy: Vec<(i32, i32)> = ring.iter().map(|&i| ((i % side) as i32, (i / side) as i32)).collect();
        let probes = ring_xy.iter().step_by(3).copied().collect();
        Some(Ring {
            side,
            q0,
            q1,
            strips,
            inner,
            ring,
            ring_sides,
            ring_xy,
            is_core,
            core_border,
            core_runs,
            probes,
            origin: (x0, y0),
            extent: ((x1 - x0 + 1) as u32, (y1 - y0 + 1) as u32),
        })
    }

    /// The ring's depths `(q0, q1)`.
    pub fn depths(&self) -> (i32, i32) {
        (self.q0, self.q1)
    }

    /// Whether each raster pixel lies beyond every cut: what a tile's own interior always replaces.
    pub fn core(&self) -> &[bool] {
        &self.is_core
    }

    /// The depth from which every pixel is interior: what a tile's own composition must reach.
    pub fn reach(&self) -> i32 {
        self.q1
    }

    /// How many patch corners a `sample`-sized sample has each way.
    pub fn range(&self, sample: (u32, u32)) -> (u32, u32) {
        (sample.0 - self.extent.0 + 1, sample.1 - self.extent.1 + 1)
    }

    /// Whether a patch of this ring's tiles fits in a `sample`-sized sample.
    pub fn fits(&self, sample: (u32, u32)) -> bool {
        self.extent.0 <= sample.0 && self.extent.1 <= sample.1
    }

    /// [`CANDIDATES`] patch corners for one tile, uniform over the sample (two draws each).
    pub fn draw(&self, st: &mut Stream, sample: (u32, u32)) -> Vec<(u32, u32)> {
        (0..CANDIDATES)
            .map(|_| {
                let x = st.below(u64::from(sample.0 - self.extent.0 + 1)) as u32;
                let y = st.below(u64::from(sample.1 - self.extent.1 + 1)) as u32;
                (x, y)
            })
            .collect()
    }

    /// [`CANDIDATES`] patch corners for one tile of a set aligned to `lattice`, in phase with the
    /// tile's band: among the corners whose offset (raster pixel to sample pixel) is one of
    /// `bands` (the offsets of the tile's four edge patches, which alignment put within its
    /// tolerance of each other's lattice translates) plus a lattice vector, and whose patch fits
    /// in the sample, drawn without replacement (one `below` draw each; all of them when there
    /// are fewer). So the interior's texels continue the band's across the cut, where an
    /// arbitrary position would put them out of phase and show the cut as a straight seam (issue
    /// #30). With no such corner at all, the corners nearest to one.
    pub fn draw_in_phase(&self, st: &mut Stream, sample: (u32, u32), lattice: &Alignment, bands: &[(i32, i32); 4]) -> Vec<(u32, u32)> {
        let (rw, rh) = self.range(sample);
        let hi = (i64::from(rw) - 1, i64::from(rh) - 1);
        let mut pool = self.in_phase(sample, lattice, bands);
        if pool.is_empty() {
            // A patch nearly as large as the sample has only a few corners, maybe none a lattice
            // translate away: the [`CANDIDATES`] nearest to one (ties row-major), no draws.
            let off = |o: &(i32, i32)| (i64::from(o.0 + self.origin.0), i64::from(o.1 + self.origin.1));
            let miss = |c: (i64, i64)| {
                bands
                    .iter()
                    .map(|o| {
                        let r = lattice.residual((c.0 - off(o).0, c.1 - off(o).1));
                        r.0 * r.0 + r.1 * r.1
                    })
                    .min()
                    .expect("four bands")
            };
            let mut all: Vec<(i64, (i64, i64))> = (0..=hi.1).flat_map(|y| (0..=hi.0).map(move |x| (x, y))).map(|c| (miss(c), c)).collect();
            all.sort_by_key(|&(m, c)| (m, c.1, c.0));
            return all.iter().take(CANDIDATES).map(|&(_, (x, y))| (x as u32, y as u32)).collect();
        }
        let n = CANDIDATES.min(pool.len());
        for i in 0..n {
            let j = i + st.below((pool.len() - i) as u64) as usize;
            pool.swap(i, j);
        }
        pool[..n].iter().map(|&(x, y)| (x as u32, y as u32)).collect()
    }

    /// Every patch corner in phase with a tile's band ([`Ring::draw_in_phase`]), row-major.
    pub fn in_phase(&self, sample: (u32, u32), lattice: &Alignment, bands: &[(i32, i32); 4]) -> Vec<(i64, i64)> {
        let (rw, rh) = self.range(sample);
        let hi = (i64::from(rw) - 1, i64::from(rh) - 1);
        let mut pool: Vec<(i64, i64)> = bands
            .iter()
            .flat_map(|o| lattice.translates((i64::from(o.0 + self.origin.0), i64::from(o.1 + self.origin.1)), (0, 0), hi))
            .collect();
        pool.sort_by_key(|p| (p.1, p.0));
        pool.dedup();
        pool
    }

    /// The DP cut of strip `k` through `error` (per raster pixel): the cut depth at each position.
    /// Depth `q` at position `p` may follow `q − 1`, `q` or `q + 1` at `p − 1`, where pixels exist;
    /// ties go to the shallower depth.
    fn cut(&self, k: usize, error: &[u32]) -> (Vec<i32>, u64) {
        let st = &self.strips[k];
        let nq = (self.q1 - self.q0) as usize;
        let mut cost = vec![u64::MAX; st.positions * nq];
        for p in 0..st.positions {
            let (done, row) = cost.split_at_mut(p * nq);
            let prev = done.get((p.max(1) - 1) * nq..).unwrap_or(&[]);
            for (q, (c, &i)) in row[..nq].iter_mut().zip(&st.at[p * nq..(p + 1) * nq]).enumerate() {
                if i == NONE {
                    continue;
                }
                let before =
                    if p == 0 { 0 } else { prev[q.saturating_sub(1)..=(q + 1).min(nq - 1)].iter().copied().min().expect("a depth") };
                if before != u64::MAX {
                    *c = before + u64::from(error[i]);
                }
            }
        }
        let last = (st.positions - 1) * nq;
        let mut q = (0..nq).min_by_key(|&q| (cost[last + q], q)).expect("a depth");
        let total = cost[last + q];
        let mut depths = vec![0i32; st.positions];
        for p in (0..st.positions).rev() {
            depths[p] = self.q0 + q as i32;
            if p > 0 {
                let lo = q.saturating_sub(1);
                q = (lo..=(q + 1).min(nq - 1)).min_by_key(|&q2| (cost[(p - 1) * nq + q2], q2)).expect("a depth");
            }
        }
        (depths, total)
    }

    /// The pixel error between the tile's band and the patch at `offset`, over every third ring
    /// pixel: how well a candidate agrees with the band. Every third ring pixel tells the
    /// candidates apart about as well as all of them, for a third of the cost (the choice is a
    /// large part of a 2048² fill's time). `band`: the tile's colours at [`Ring::probes`];
    /// `reads`: where each probe's pixel lies in the sample's raw bytes, less the patch's start.
    fn ring_cost(band: &[[u8; 3]], reads: &[usize], data: &[u8], start: usize, err: PixelError) -> u64 {
        band.iter().zip(reads).map(|(&b, &r)| u64::from(err.eval(b, [data[start + r], data[start + r + 1], data[start + r + 2]]))).sum()
    }

    fn offset_of(&self, c: (u32, u32)) -> (i32, i32) {
        (c.0 as i32 - self.origin.0, c.1 as i32 - self.origin.1)
    }

    /// Each candidate's [`Ring::ring_cost`] against the tile's band.
    pub fn costs(&self, sample: &RgbImage, raster: &[u8], candidates: &[(u32, u32)], err: PixelError) -> Vec<u64> {
        let w = sample.width() as usize;
        let (ox, oy) = (self.origin.0 as usize, self.origin.1 as usize);
        let band: Vec<[u8; 3]> = self
            .probes
            .iter()
            .map(|&(x, y)| {
                let i = 3 * (y as usize * self.side + x as usize);
                [raster[i], raster[i + 1], raster[i + 2]]
            })
            .collect();
        // Probes lie in the patch's box (from `origin`), so these never go below the patch's start.
        let reads: Vec<usize> = self.probes.iter().map(|&(x, y)| 3 * ((y as usize - oy) * w + (x as usize - ox))).collect();
        candidates
            .iter()
            .map(|&(cx, cy)| Ring::ring_cost(&band, &reads, sample.as_raw(), 3 * (cy as usize * w + cx as usize), err))
            .collect()
    }

    /// Gives the tile (`raster`, RGB, and `labels`, both `side × side`) the interior of the
    /// candidate patch that agrees best with it over the ring (ties to the earliest), beyond the
    /// four cuts. Pixels shallower than `q0` are unchanged.
    pub fn apply(&self, sample: &RgbImage, raster: &mut [u8], labels: &mut [u8], candidates: &[(u32, u32)], err: PixelError) -> Interior {
        let costs = self.costs(sample, raster, candidates, err);
        let best = (0..candidates.len()).min_by_key(|&j| (costs[j], j)).expect("at least one candidate");
        self.apply_at(sample, raster, labels, candidates[best], err)
    }

    /// Gives the tile the interior of the patch at `corner` (one of its candidates), beyond the
    /// four cuts.
    pub fn apply_at(&self, sample: &RgbImage, raster: &mut [u8], labels: &mut [u8], corner: (u32, u32), err: PixelError) -> Interior {
        let side = self.side;
        let patch = |off: (i32, i32), i: usize| sample.get(((i % side) as i32 + off.0) as u32, ((i / side) as i32 + off.1) as u32);
        let band = |raster: &[u8], i: usize| [raster[3 * i], raster[3 * i + 1], raster[3 * i + 2]];
        let best = self.offset_of(corner);
        let (w, data) = (sample.width() as usize, sample.as_raw());
        let mut error = vec![0u32; side * side];
        for (&i, &(x, y)) in self.ring.iter().zip(&self.ring_xy) {
            let j = 3 * (((y + best.1) as u32) as usize * w + ((x + best.0) as u32) as usize);
            error[i] = err.eval(band(raster, i), [data[j], data[j + 1], data[j + 2]]);
        }
        let cuts: Vec<(Vec<i32>, u64)> = (0..4).map(|k| self.cut(k, &error)).collect();
        // The core lies deeper than any cut, so only the ring's pixels can fall short of one.
        let mut beyond = vec![false; side * side];
        for &(i, c) in &self.ring_sides {
            beyond[i] = (0..4).all(|k| c[k].1 >= cuts[k].0[(c[k].0 - self.strips[k].p_lo) as usize]);
        }
        // Where two sides meet, both cuts may run shallow and leave a corner pocket beyond both
        // but cut off from the rest: only what joins the core is interior. A path out of the core
        // leaves it last through a border pixel, so flooding the ring from those alone reaches
        // the same pixels as flooding from the whole core.
        let joined = flood4(side, side, &self.core_border, |i| beyond[i] && !self.is_core[i]);
        for &(i, _) in &self.ring_sides {
            if joined[i] {
                raster[3 * i..3 * i + 3].copy_from_slice(&patch(best, i));
                labels[i] = INTERIOR;
            }
        }
        for &(i, len) in &self.core_runs {
            let (x, y) = ((i % side) as i32 + best.0, (i / side) as i32 + best.1);
            let j = 3 * ((y as u32) as usize * w + (x as u32) as usize);
            raster[3 * i..3 * (i + len)].copy_from_slice(&data[j..j + 3 * len]);
            labels[i..i + len].fill(INTERIOR);
        }
        Interior { offset: best, cost: cuts.iter().map(|c| c.1).sum() }
    }
}

/// How strongly a tile's patch avoids the sample places earlier tiles took ([`choose`]).
/// Measured on grass_gray at 2048² (issue #30): picking by ring cost alone sent the Wang tiles'
/// interiors to the sample's low-contrast left part (3.6 times as many patch corners in the
/// densest eighth of `x` as in the sparsest; twice uniform's neighbours within 8 px), so that
/// one dark clump recurred at one place in many tiles, in rows along the tile rows. With 1 the
/// corners are as spread as uniform draws (9.6 neighbours against 9.4) for ring costs 10% higher.
pub const CROWDING: f64 = 1.0;

/// The ring of a tile with overlap `ov`, in depth steps of `step` pixels (1 for square tiles,
/// √2/2 for the rhombus' diagonal steps): from 1 to about `ov / 2` pixels in, at least two steps
/// wide. Only the outermost pixel line is always the edge patches'. Measured on grass, gravel and
/// pebbles at 2048² (issue #30): a ring of `ov` pixels left a fill's repetition 1.3–2.7× quilting's,
/// `ov / 2` brings it to 0.6–1.8×, and `ov / 4` shows the tile outlines.
pub fn band(ov: i32, step: f64) -> (i32, i32) {
    (1, ((f64::from(ov) / 2.0 / step).round() as i32 + 1).max(3))
}

/// The ring of a tile aligned to `lattice` ([`band`] otherwise): deep enough, at least
/// `ALIGNED_RING` of the lattice's shortest vector, for the cuts to find the joints the band and
/// the in-phase patch share ([`Ring::draw_in_phase`]) instead of crossing texels whose colours
/// differ.
pub fn aligned_band(ov: i32, step: f64, lattice: &Alignment) -> (i32, i32) {
    let (q0, q1) = band(ov, step);
    (q0, q1.max((lattice.shortest() * ALIGNED_RING / step).round() as i32 + 1))
}

/// [`aligned_band`]'s share of the shortest lattice vector. Measured on city_bricks and
/// stk_generic_brickRoad_a at 512² (issue #30): with [`band`]'s ring (4–7 px) the cuts run
/// straight across bricks of another colour and the RW tiles show their rhombus outlines; with a
/// quarter of the shortest vector they follow more of the joints, and the repetition of RW fills
/// falls (city 0.82 to 0.78, brickRoad 0.69 to 0.63); 0.4 gave no better.
pub const ALIGNED_RING: f64 = 0.25;

/// How strongly a tile's patch is steered so that the set's interiors, averaged, have no shading
/// of their own ([`Shading`], [`choose`]). Measured on grass_gray (issue #30): every patch
/// position being equally likely, the tile pixel at `x` averages the sample's columns `x ..
/// x + range`, and the sample is darker along its left quarter, so the tiles' left halves came
/// out darker than their right halves and a fill showed faint lines at the tile edges: a plane
/// fitted to a 2048² fill's mean over the tile period (inside the tiles, 8 px from their edges)
/// fell by 6.0 grey levels across a Wang tile and 8.6 across an RW tile; with 0.5 by 1 or less,
/// for ring costs about 10% higher (1.0 balanced no better and cost 15%; 0.3 left 1.7).
pub const SHADING: f64 = 0.5;

/// How many cells each way [`Shading`] divides a tile's patch into.
pub const SHADING_CELLS: usize = 4;

/// The low-frequency shading of a tile's patch: the mean grey level, less the sample's, in each
/// of [`SHADING_CELLS`]² cells of the patch (the ring's inner pixels). Measured on 4×4-pixel box
/// means of the sample (a summed-area table) at every fourth inner pixel each way, so that a
/// cell's mean is that of (nearly) all its pixels, at a sixteenth of the reads.
///
/// Why not correct the shading instead (subtract each patch's low-pass deviation): a tile's
/// pixels are copies of sample pixels, which its placement (source maps, `texsyn apply`, the
/// 16-bit and float renderings of a job) records and replays exactly; a shifted pixel is no
/// sample pixel. Choosing patches keeps every pixel a copy.
pub struct Shading {
    /// Summed-area table of `r + g + b`, `(w + 1) × (h + 1)`.
    sat: Vec<u64>,
    size: (u32, u32),
    /// The sample's mean grey level.
    mean: f64,
    /// Raster pixels measured, with their cell.
    points: Vec<(i32, i32, usize)>,
    /// The ring's `origin`, and each point's index in the table relative to it.
    origin: (i32, i32),
    at: Vec<usize>,
    /// One past the largest `x` and `y` a point's box reaches before the patch's offset.
    reach: (i32, i32),
    /// Each cell's weight in [`Shading::norm`]: its share of the points, times the cell count.
    weights: Vec<f64>,
}

/// One patch's shading: per cell, its mean grey level less the sample's.
pub type Shade = [f64; SHADING_CELLS * SHADING_CELLS];

impl Shading {
    pub fn new(ring: &Ring, sample: &RgbImage) -> Shading {
        let (w, h) = sample.dimensions();
        let mut sat = vec![0u64; (w as usize + 1) * (h as usize + 1)];
        let row = w as usize + 1;
        for y in 0..h as usize {
            let mut acc = 0u64;
            for x in 0..w as usize {
                let p = sample.get(x as u32, y as u32);
                acc += u64::from(p[0]) + u64::from(p[1]) + u64::from(p[2]);
                sat[(y + 1) * row + x + 1] = sat[y * row + x + 1] + acc;
            }
        }
        let mean = sat[h as usize * row + w as usize] as f64 / 3.0 / (f64::from(w) * f64::from(h)).max(1.0);
        let g = SHADING_CELLS as i32;
        let (ox, oy) = ring.origin;
        let (ew, eh) = (ring.extent.0 as i32, ring.extent.1 as i32);
        let side = ring.side;
        let points: Vec<(i32, i32, usize)> = ring
            .inner
            .iter()
            .map(|&(i, _)| ((i % side) as i32, (i / side) as i32))
            .filter(|&(x, y)| (x - ox) % 4 == 0 && (y - oy) % 4 == 0)
            .map(|(x, y)| (x, y, (((y - oy) * g / eh) * g + (x - ox) * g / ew) as usize))
            .collect();
        let mut counts = [0usize; SHADING_CELLS * SHADING_CELLS];
        for p in &points {
            counts[p.2] += 1;
        }
        let weights = counts.iter().map(|&c| c as f64 * counts.len() as f64 / points.len().max(1) as f64).collect();
        let at = points.iter().map(|&(x, y, _)| (y - oy) as usize * row + (x - ox) as usize).collect();
        let reach = points.iter().fold((0, 0), |(rx, ry), &(x, y, _)| (rx.max(x + 4), ry.max(y + 4)));
        Shading { sat, size: (w, h), mean, points, origin: ring.origin, at, reach, weights }
    }

    /// The shading of the patch whose raster pixel `(x, y)` copies sample pixel `(x, y) + off`.
    pub fn of(&self, off: (i32, i32)) -> Shade {
        let (w, h) = self.size;
        let row = w as usize + 1;
        let mut sums = [0f64; SHADING_CELLS * SHADING_CELLS];
        let mut counts = [0u32; SHADING_CELLS * SHADING_CELLS];
        if self.reach.0 + off.0 <= w as i32 && self.reach.1 + off.1 <= h as i32 {
            // No box is clipped by the sample's edge: the same sums over whole 4×4 boxes, from
            // table offsets found once.
            let base = (off.1 + self.origin.1) as usize * row + (off.0 + self.origin.0) as usize;
            let (dx, dy) = (4, 4 * row);
            for (&at, &(_, _, cell)) in self.at.iter().zip(&self.points) {
                let i = base + at;
                let s = self.sat[i + dy + dx] + self.sat[i] - self.sat[i + dx] - self.sat[i + dy];
                sums[cell] += s as f64 / 3.0 / 16.0 - self.mean;
                counts[cell] += 1;
            }
            return std::array::from_fn(|c| if counts[c] == 0 { 0.0 } else { sums[c] / f64::from(counts[c]) });
        }
        for &(x, y, cell) in &self.points {
            let (x0, y0) = ((x + off.0) as usize, (y + off.1) as usize);
            let (x1, y1) = ((x0 + 4).min(w as usize), (y0 + 4).min(h as usize));
            let s = self.sat[y1 * row + x1] + self.sat[y0 * row + x0] - self.sat[y0 * row + x1] - self.sat[y1 * row + x0];
            let area = ((x1 - x0) * (y1 - y0)) as f64;
            sums[cell] += s as f64 / 3.0 / area - self.mean;
            counts[cell] += 1;
        }
        std::array::from_fn(|c| if counts[c] == 0 { 0.0 } else { sums[c] / f64::from(counts[c]) })
    }

    /// The weighted sum of squares of a shading (or a sum of shadings).
    pub fn norm(&self, v: &Shade) -> f64 {
        v.iter().zip(&self.weights).map(|(a, w)| w * a * a).sum()
    }
}

/// Gives every tile its own interior in `ring` ([`Ring::apply`]); `parts` lends a tile's raster,
/// labels and interior offset. Each tile's [`CANDIDATES`] patch positions come from stream `label`
/// (seeded by the job seed), in tile order, before any tile is cut, so the result does not depend
/// on the thread count. With `phase` (a set aligned to a lattice: the lattice and each tile's four
/// edge-patch offsets), the candidates are in phase with the tile's band ([`Ring::draw_in_phase`]).
/// Returns the seams' total cost.
#[allow(clippy::too_many_arguments)]
pub fn give<T: Send>(
    tiles: &mut [T],
    ring: &Ring,
    sample: &RgbImage,
    err: PixelError,
    seed: u64,
    label: &str,
    phase: Option<(&Alignment, &[[(i32, i32); 4]])>,
    only_in_phase: bool,
    parts: impl Fn(&mut T) -> (&mut [u8], &mut [u8], &mut Option<(i32, i32)>) + Sync,
) -> Option<u64> {
    // `only_in_phase` (`interior = "auto"`): when some tile of an aligned set has no patch
    // position in phase with its band in the sample (a tile nearly as large as the sample, on a
    // large lattice), no tile gets an interior (`None`, the tiles untouched): one out of phase
    // would show its seam as a line through every texel it crosses.
    if let Some((lattice, bands)) = phase
        && only_in_phase
        && bands.iter().any(|b| ring.in_phase(sample.dimensions(), lattice, b).is_empty())
    {
        return None;
    }
    let mut st = Stream::new(seed, label);
    let draws: Vec<Vec<(u32, u32)>> = match phase {
        None => tiles.iter().map(|_| ring.draw(&mut st, sample.dimensions())).collect(),
        Some((lattice, bands)) => bands.iter().map(|b| ring.draw_in_phase(&mut st, sample.dimensions(), lattice, b)).collect(),
    };
    let costs: Vec<Vec<u64>> = tiles
        .par_iter_mut()
        .zip(draws.par_iter())
        .map(|(tile, candidates)| {
            let (raster, _, _) = parts(tile);
            ring.costs(sample, raster, candidates, err)
        })
        .collect();
    let shading = Shading::new(ring, sample);
    let shades: Vec<Vec<Shade>> = draws.par_iter().map(|cands| cands.iter().map(|&c| shading.of(ring.offset_of(c))).collect()).collect();
    let picks = choose(&draws, &costs, ring.range(sample.dimensions()), CROWDING, Some((&shading, &shades[..], SHADING)));
    let cut_costs: Vec<u64> = tiles
        .par_iter_mut()
        .zip(draws.par_iter().zip(picks.par_iter()))
        .map(|(tile, (candidates, &pick))| {
            let (raster, labels, interior) = parts(tile);
            let got = ring.apply_at(sample, raster, labels, candidates[pick], err);
            *interior = Some(got.offset);
            got.cost
        })
        .collect();
    Some(cut_costs.iter().sum())
}

/// Picks each tile's patch among its candidates, in tile order: the one of least ring cost
/// times `1 + lambda · crowding`, where crowding is how many earlier tiles took a patch corner
/// near the candidate's, relative to how many would at uniform density; with `shading`
/// (`(measure, each candidate's shade, mu)`), also times `exp(mu · (|S + s|² − |S|²) / ν)`, where
/// `S` is the sum of the shades earlier tiles took, `s` the candidate's and `ν` the mean `|s|²`
/// over every candidate: each tile leans towards a patch whose shading cancels what the earlier
/// ones summed to (and towards flat patches), more strongly the further the sum has drifted, so
/// that the set's interiors average to no shading at all (a factor bounded like `1 + …` lost its
/// pull as `S` grew, and left grass_gray's tiles as shaded as before). Scores are compared as
/// logarithms. `range`: how many patch corners there are each way.
fn choose(
    draws: &[Vec<(u32, u32)>],
    costs: &[Vec<u64>],
    range: (u32, u32),
    lambda: f64,
    shading: Option<(&Shading, &[Vec<Shade>], f64)>,
) -> Vec<usize> {
    let n = draws.len().max(1);
    let area = f64::from(range.0) * f64::from(range.1);
    let cell = ((area / n as f64).sqrt().floor() as u32).max(1);
    let (gw, gh) = (range.0.div_ceil(cell) as usize, range.1.div_ceil(cell) as usize);
    let mut counts = vec![0u32; gw * gh];
    let near = |counts: &[u32], (x, y): (u32, u32)| -> u32 {
        let (cx, cy) = ((x / cell) as usize, (y / cell) as usize);
        let mut sum = 0;
        for gy in cy.saturating_sub(1)..(cy + 2).min(gh) {
            for gx in cx.saturating_sub(1)..(cx + 2).min(gw) {
                sum += counts[gy * gw + gx];
            }
        }
        sum
    };
    let window = 9.0 * f64::from(cell) * f64::from(cell) / area;
    // ν: the mean |s|² over every candidate of every tile, summed in tile order.
    let nu = shading.map_or(1.0, |(m, shades, _)| {
        let (sum, k) = shades.iter().flatten().fold((0.0, 0usize), |(s, k), v| (s + m.norm(v), k + 1));
        (sum / k.max(1) as f64).max(1e-9)
    });
    let mut total: Shade = [0.0; SHADING_CELLS * SHADING_CELLS];
    draws
        .iter()
        .zip(costs)
        .enumerate()
        .map(|(i, (cands, cost))| {
            let expected = i as f64 * window;
            // The logarithm of the score, so that the shading's factor may grow without bound.
            let score = |j: usize| {
                let mut s = (cost[j] as f64).ln() + (1.0 + lambda * f64::from(near(&counts, cands[j])) / (expected + 1.0)).ln();
                if let Some((m, shades, mu)) = shading {
                    let v: Shade = std::array::from_fn(|c| total[c] + shades[i][j][c]);
                    s += mu * (m.norm(&v) - m.norm(&total)) / nu;
                }
                s
            };
            let mut best = 0;
            let mut best_score = score(0);
            for j in 1..cands.len() {
                let sj = score(j);
                if sj < best_score {
                    (best, best_score) = (j, sj);
                }
            }
            let (x, y) = cands[best];
            counts[(y / cell) as usize * gw + (x / cell) as usize] += 1;
            if let Some((_, shades, _)) = shading {
                for (t, v) in total.iter_mut().zip(&shades[i][best]) {
                    *t += v;
                }
            }
            best
        })
        .collect()
}

/// Splits `cells`, the `2K` patch positions of a set's edge patches (the first `K` for the class
/// that plays sides 0 and 2, the rest for sides 1 and 3), between the two classes so that each
/// side's band, averaged over the `K` patches that may fill it, has the sample's mean colour at
/// every depth: swaps one patch of each class at a time, the swap that brings the bands' average
/// closest to the mean, while one helps (ties to the earliest pair).
///
/// Why: with interiors of their own, a tile keeps from its edge patches only the band within
/// `q1` of its sides (made of edge patches only, its band is its outer part), and every tile of a
/// fill shows one of only `K` bands along each side. Their
/// average lies on the tile grid, every tile period: when those `K` strips of the sample happen to
/// be darker (or lighter) than the sample, a fill shows lines along the tile rows and columns (on
/// grass_gray the bottom rows of every Wang tile were 6 grey levels dark). Which cells the patches
/// take is not changed, only which class uses each, so the patches stay as spread over the
/// sample as before.
///
/// `sides(x, y)`: a `side × side` tile raster's side coordinates `(p, q)` (as [`Ring::new`]);
/// `read(k, cell, x, y)`: the sample pixel that raster pixel `(x, y)` reads from the patch at
/// `cell` playing side `k`. Only a pixel's nearest side counts it (the first, at a tie).
pub fn balance_bands(
    sample: &RgbImage,
    side: usize,
    q1: i32,
    sides: impl Fn(i32, i32) -> Option<[(i32, i32); 4]>,
    read: impl Fn(usize, (u32, u32), i32, i32) -> (u32, u32),
    cells: &mut [(u32, u32)],
) {
    let k = cells.len() / 2;
    if k == 0 || q1 < 1 {
        return;
    }
    let depths = q1 as usize;
    // groups[s][d]: the raster pixels whose nearest side is `s`, at depth `d`.
    let mut groups = vec![vec![Vec::new(); depths]; 4];
    for y in 0..side as i32 {
        for x in 0..side as i32 {
            if let Some(c) = sides(x, y) {
                let (s, q) = (0..4).map(|s| (s, c[s].1)).min_by_key(|&(s, q)| (q, s)).expect("four sides");
                if (0..q1).contains(&q) {
                    groups[s][q as usize].push((x, y));
                }
            }
        }
    }
    let (w, h) = sample.dimensions();
    let mut mean = [0f64; 3];
    for (i, v) in sample.as_raw().iter().enumerate() {
        mean[i % 3] += f64::from(*v);
    }
    let mean = mean.map(|m| m / f64::from(w) / f64::from(h));
    // profile(class, cell): the mean colour, less the sample's, of each band pixel group of the
    // class's two sides, at each depth.
    let profile = |class: usize, cell: (u32, u32)| -> Vec<f64> {
        let mut out = Vec::with_capacity(2 * depths * 3);
        for s in [class, class + 2] {
            for group in &groups[s] {
                let (mut sum, mut n) = ([0f64; 3], 0usize);
                for &(x, y) in group {
                    let (sx, sy) = read(s, cell, x, y);
                    if sx < w && sy < h {
                        let p = sample.get(sx, sy);
                        for c in 0..3 {
                            sum[c] += f64::from(p[c]);
                        }
                        n += 1;
                    }
                }
                out.extend((0..3).map(|c| if n == 0 { 0.0 } else { sum[c] / n as f64 - mean[c] }));
            }
        }
        out
    };
    let profiles: Vec<[Vec<f64>; 2]> = cells.iter().map(|&c| [profile(0, c), profile(1, c)]).collect();
    let len = profiles[0][0].len();
    let mut order: Vec<usize> = (0..2 * k).collect();
    let total = |order: &[usize], class: usize| -> Vec<f64> {
        let mut t = vec![0f64; len];
        for &i in &order[class * k..(class + 1) * k] {
            for (a, b) in t.iter_mut().zip(&profiles[i][class]) {
                *a += b;
            }
        }
        t
    };
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>();
    let (mut s0, mut s1) = (total(&order, 0), total(&order, 1));
    let mut score = norm(&s0) + norm(&s1);
    for _ in 0..4 * k {
        let mut best: Option<(f64, usize, usize)> = None;
        for a in 0..k {
            for b in k..2 * k {
                let (i, j) = (order[a], order[b]);
                let t0: Vec<f64> = (0..len).map(|e| s0[e] - profiles[i][0][e] + profiles[j][0][e]).collect();
                let t1: Vec<f64> = (0..len).map(|e| s1[e] - profiles[j][1][e] + profiles[i][1][e]).collect();
                let v = norm(&t0) + norm(&t1);
                if v < best.map_or(score, |b| b.0) {
                    best = Some((v, a, b));
                }
            }
        }
        let Some((v, a, b)) = best else { break };
        order.swap(a, b);
        (s0, s1, score) = (total(&order, 0), total(&order, 1), v);
    }
    let was = cells.to_vec();
    for (slot, &i) in cells.iter_mut().zip(&order) {
        *slot = was[i];
    }
}

/// `diagnostics.interior` of a job whose tiles have interiors of their own.
pub fn record(mode: InteriorMode, (d0, d1): (i32, i32), seam_cost: u64) -> serde_json::Value {
    let how = match mode {
        InteriorMode::Auto => "auto: own, for more than two colours or tiles aligned to a lattice (in phase with it)",
        _ => "own, as set",
    };
    serde_json::json!({ "interior": "own", "ring_depths": [d0, d1], "candidates": CANDIDATES, "seam_cost": seam_cost, "how": how })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(t: i32) -> impl Fn(i32, i32) -> Option<[(i32, i32); 4]> {
        move |x, y| Some([(x, y), (y, t - 1 - x), (x, t - 1 - y), (y, x)])
    }

    #[test]
    fn the_cuts_enclose_the_core_and_never_touch_the_band() {
        let t = 32usize;
        let depth = |i: usize| {
            let (x, y) = (i % t, i / t);
            x.min(y).min(t - 1 - x).min(t - 1 - y) as i32
        };
        let ring = Ring::new(t, 2, 8, square(t as i32)).unwrap();
        let sample = RgbImage::from_fn(64, 64, |x, y| [(x * 4) as u8, (y * 4) as u8, ((x ^ y) * 8) as u8]);
        let mut raster = vec![7u8; t * t * 3];
        let mut labels = vec![0u8; t * t];
        let mut st = Stream::new(1, "test");
        let cands = ring.draw(&mut st, (64, 64));
        let inter = ring.apply(&sample, &mut raster, &mut labels, &cands, PixelError::Squared);
        for i in 0..t * t {
            if depth(i) < 2 {
                assert_eq!((labels[i], &raster[3 * i..3 * i + 3]), (0, &[7u8, 7, 7][..]), "band pixel {i} unchanged");
            }
            if labels[i] == INTERIOR || depth(i) >= 8 {
                assert_eq!(labels[i], INTERIOR, "core pixel {i}");
                let (x, y) = ((i % t) as i32 + inter.offset.0, (i / t) as i32 + inter.offset.1);
                assert_eq!(&raster[3 * i..3 * i + 3], &sample.get(x as u32, y as u32)[..]);
            }
        }
        // The interior is one 4-connected region, and so is the band around it.
        let first = (0..t * t).find(|&i| labels[i] == INTERIOR).unwrap();
        let inside = flood4(t, t, &[first], |i| labels[i] == INTERIOR);
        let outside = flood4(t, t, &[0], |i| labels[i] != INTERIOR);
        assert!((0..t * t).all(|i| inside[i] == (labels[i] == INTERIOR) && outside[i] == (labels[i] != INTERIOR)));
    }

    #[test]
    #[allow(clippy::needless_range_loop)]
    fn each_cut_follows_the_cheapest_depths() {
        // The tile matches the patch exactly at depth 5 along every side and nowhere else: every
        // cut runs at depth 5 (where two sides meet, through pixels outside the other cut).
        let t = 40usize;
        let ring = Ring::new(t, 1, 9, square(t as i32)).unwrap();
        let sample = RgbImage::from_fn(64, 64, |_, _| [200, 200, 200]);
        let mut raster = vec![0u8; t * t * 3];
        for i in 0..t * t {
            let (x, y) = (i % t, i / t);
            if x.min(y).min(t - 1 - x).min(t - 1 - y) == 5 {
                raster[3 * i..3 * i + 3].copy_from_slice(&[200, 200, 200]);
            }
        }
        let mut labels = vec![0u8; t * t];
        ring.apply(&sample, &mut raster, &mut labels, &[(0, 0)], PixelError::Squared);
        for i in 0..t * t {
            let (x, y) = (i % t, i / t);
            let d = x.min(y).min(t - 1 - x).min(t - 1 - y);
            assert_eq!(labels[i] == INTERIOR, d >= 5, "({x},{y})");
        }
    }

    #[test]
    fn aligned_candidates_are_lattice_translates_of_the_band() {
        // A tile's interior candidates on an aligned set sit a lattice vector from one of its
        // band's offsets, inside the sample; where none fits, the nearest corners (no draws).
        let t = 40usize;
        let ring = Ring::new(t, 1, 6, square(t as i32)).unwrap();
        let lattice = Alignment::new((13, 0), (5, 11), "given").unwrap();
        let bands = [(17, 9), (30, 9), (22, 20), (4, 9)];
        let sample = (160, 120);
        let mut st = Stream::new(3, "test");
        let cands = ring.draw_in_phase(&mut st, sample, &lattice, &bands);
        assert_eq!(cands.len(), CANDIDATES);
        let (rw, rh) = ring.range(sample);
        for &c in &cands {
            assert!(c.0 < rw && c.1 < rh, "{c:?}");
            let off = ring.offset_of(c);
            assert!(
                bands.iter().any(|b| lattice.residual((i64::from(off.0 - b.0), i64::from(off.1 - b.1))) == (0, 0)),
                "{off:?} is no lattice translate of {bands:?}"
            );
        }
        let mut distinct = cands.clone();
        distinct.sort_unstable();
        distinct.dedup();
        assert_eq!(distinct.len(), cands.len(), "drawn without replacement");
        // A sample only as large as the patch: one corner, the nearest to a translate.
        let (ew, eh) = (ring.extent.0, ring.extent.1);
        assert_eq!(ring.draw_in_phase(&mut st, (ew, eh), &lattice, &bands), vec![(0, 0)]);
    }

    #[test]
    fn a_tile_too_small_for_a_ring_has_none() {
        assert!(Ring::new(8, 2, 8, square(8)).is_none());
        assert!(Ring::new(32, 1, 2, square(32)).is_none());
    }
}
