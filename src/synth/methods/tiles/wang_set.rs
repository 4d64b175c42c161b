//! A built Cohen (Wang) tile set: the square tile geometry, the tiles, and filling an output
//! from them (placement on the square lattice and copying tile rows).
//!
//! `wang-tiles` builds such a set and the tile-set export ([`super::export`]) writes and reads
//! it back; both render through [`WangTileSet::render`]. Keeping the set here, below both, is what
//! lets the export render a loaded set without importing the method that imports the export.

use super::interior::INTERIOR;
use super::wang::{EdgeSet, Tiling, TilingOrder, Torus, tile_rect, tile_torus};
use crate::image::RgbImage;
use rayon::prelude::*;

/// Diamond (and edge) indices, clockwise from the top.
pub const N: usize = 0;
pub const E: usize = 1;
pub const S: usize = 2;
pub const W: usize = 3;

/// Geometry of a Cohen tile: side `t`, overlap `ov`, diamond half-diagonal `a = t/2 + ov/2`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Geometry {
    pub t: i32,
    pub ov: i32,
    pub a: i32,
}

impl Geometry {
    pub fn new(t: i32, ov: i32) -> Geometry {
        Geometry { t, ov, a: t / 2 + ov / 2 }
    }

    /// Tile coordinates of diamond `d`'s centre (the midpoint of edge N, E, S or W).
    pub fn centre(&self, d: usize) -> (i32, i32) {
        let (t, m) = (self.t, self.t / 2);
        [(m, 0), (t, m), (m, t), (0, m)][d]
    }

    /// Whether pixel `(x, y)` (centre at `(x + ½, y + ½)`) lies in diamond `d`.
    #[inline]
    pub fn in_diamond(&self, d: usize, x: i32, y: i32) -> bool {
        let (cx, cy) = self.centre(d);
        (2 * x + 1 - 2 * cx).abs() + (2 * y + 1 - 2 * cy).abs() <= 2 * self.a
    }

    /// The diamond an edge pixel is locked to (corners to the clockwise-first edge).
    pub fn lock(&self, x: i32, y: i32) -> Option<usize> {
        let l = self.t - 1;
        if y == 0 && x > 0 {
            Some(N)
        } else if x == l && y > 0 {
            Some(E)
        } else if y == l && x < l {
            Some(S)
        } else if x == 0 {
            Some(W)
        } else {
            None
        }
    }

    /// The sample pixel that tile pixel `(x, y)` reads from diamond `d` centred at sample pixel `q`.
    #[inline]
    pub fn sample_pixel(&self, d: usize, q: (u32, u32), x: i32, y: i32) -> (u32, u32) {
        let (cx, cy) = self.centre(d);
        ((q.0 as i32 + x - cx) as u32, (q.1 as i32 + y - cy) as u32)
    }

    /// Tile corner where the cut between diamonds `k` and `k + 1` starts.
    pub fn corner(&self, k: usize) -> (i32, i32) {
        let l = self.t - 1;
        [(l, 0), (l, l), (0, l), (0, 0)][k]
    }
}

/// One built tile.
#[derive(Clone, Debug)]
pub struct WangTile {
    /// Edge colours `[N, W, S, E]` (B12's `[a, b, c, d]`).
    pub colours: [u8; 4],
    /// `t × t` RGB raster.
    pub raster: Vec<u8>,
    /// `t × t` diamond labels (N, E, S, W = 0..3; [`INTERIOR`] for the tile's own interior).
    pub labels: Vec<u8>,
    /// Sum of `E` over each cut's pixels (N|E, E|S, S|W, W|N).
    pub cut_costs: [u64; 4],
    /// Pixels no flood reached (labelled with the first covering diamond); 0 in practice.
    pub fallback_pixels: usize,
    /// With an interior of its own ([`super::interior`]): the offset from tile pixels labelled
    /// [`INTERIOR`] to the sample pixels they copy.
    pub interior: Option<(i32, i32)>,
    /// `t × t` sample indices (`y · sample_width + x`) the raster's pixels are copies of: filled by
    /// [`WangTileSet::record_sources`] only when a job asks for its placement, empty otherwise.
    pub sources: Vec<u32>,
    /// `t × t` tone blends of its interior's pixels ([`super::tone`]): empty when not toned.
    pub tone: Vec<super::tone::ToneBlend>,
}

impl super::tone::Toneable for WangTile {
    fn labels(&self) -> &[u8] {
        &self.labels
    }
    fn tone_parts(&mut self) -> (&mut [u8], &[u8], &mut Vec<super::tone::ToneBlend>) {
        (&mut self.raster, &self.labels, &mut self.tone)
    }
}

/// The sample centres of a tile's diamonds in N, E, S, W order, from its colours `[N, W, S, E]`.
pub fn diamonds_of(colours: [u8; 4], dn: &[(u32, u32)], de: &[(u32, u32)]) -> [(u32, u32); 4] {
    [dn[colours[0] as usize], de[colours[3] as usize], dn[colours[2] as usize], de[colours[1] as usize]]
}

/// A built tile set.
#[derive(Clone, Debug)]
pub struct WangTileSet {
    pub geometry: Geometry,
    pub set: EdgeSet,
    /// Sample centres of the N/S diamonds (`DN[0] .. DN[K−1]`, one per colour) and of the E/W
    /// diamonds.
    pub dn: Vec<(u32, u32)>,
    pub de: Vec<(u32, u32)>,
    pub tiles: Vec<WangTile>,
}

impl WangTileSet {
    /// Tile `k` as a `t × t` image (the building block for a tile-set export).
    pub fn tile_image(&self, k: usize) -> RgbImage {
        let t = self.geometry.t as u32;
        RgbImage::from_raw(t, t, self.tiles[k].raster.clone()).expect("t × t raster")
    }

    /// Tile `k`'s diamond labels as colours (N red, E green, S blue, W yellow, own interior
    /// grey), for inspection.
    pub fn label_image(&self, k: usize) -> RgbImage {
        const COLOURS: [[u8; 3]; 5] = [[230, 60, 50], [60, 170, 70], [50, 90, 220], [240, 200, 40], [128, 128, 128]];
        let t = self.geometry.t as u32;
        RgbImage::from_fn(t, t, |x, y| COLOURS[self.tiles[k].labels[(y * t + x) as usize] as usize])
    }

    /// Places the tiles for a `width × height` output (rows `0..`, columns `0..`, B12).
    pub fn tile_output(&self, order: TilingOrder, width: u32, height: u32, seed: u64) -> Tiling {
        let t = self.geometry.t as i64;
        let rows = (height as i64 - 1) / t;
        let cols = (width as i64 - 1) / t;
        tile_rect(self.set, order, (0, rows), (0, cols), 0, seed, "wang/tiling")
    }

    /// Renders by copying tile rows; output rows are filled in parallel.
    pub fn render(&self, tiling: &Tiling, width: u32, height: u32) -> RgbImage {
        let mut out = RgbImage::new(width, height);
        self.render_rows(tiling, width, 0, out.as_raw_mut());
        out
    }

    /// Renders output rows `y0..` into `rows` (whole rows of a `width`-wide output), the same
    /// pixels as those rows of [`WangTileSet::render`]: how a large fill is written strip by strip.
    pub fn render_rows(&self, tiling: &Tiling, width: u32, y0: u32, rows: &mut [u8]) {
        self.copy_rows(tiling, width, y0, rows, 3, |tile| &tile.raster);
    }

    /// Lays a tiling of `t × t` planes of `ch` values per pixel (a tile's raster or its sources)
    /// into output rows `y0..`; output rows are filled in parallel.
    fn copy_rows<T: Copy + Send + Sync>(
        &self,
        tiling: &Tiling,
        width: u32,
        y0: u32,
        rows: &mut [T],
        ch: usize,
        plane: impl Fn(&WangTile) -> &[T] + Sync,
    ) {
        let t = self.geometry.t as usize;
        rows.par_chunks_mut(width as usize * ch).enumerate().for_each(|(y, row)| {
            let y = y + y0 as usize;
            let (r, ty) = (y / t, y % t);
            let mut x = 0usize;
            while x < width as usize {
                let run = (t - x % t).min(width as usize - x);
                let tile = plane(&self.tiles[tiling.at(r as i64, (x / t) as i64)]);
                let src = (ty * t + x % t) * ch;
                row[x * ch..(x + run) * ch].copy_from_slice(&tile[src..src + run * ch]);
                x += run;
            }
        });
    }

    /// Places the tiles on the torus of a `period` output that wraps, both sizes multiples of the
    /// tile side ([`tile_torus`], stream `wang/torus`), over an output of `cover` size (the period
    /// itself, or more to see it repeat).
    pub fn tile_torus(&self, period: (u32, u32), cover: (u32, u32), seed: u64) -> Tiling {
        let t = self.geometry.t as i64;
        let (rows, cols) = (period.1 as i64 / t, period.0 as i64 / t);
        assert!(rows * t == period.1 as i64 && cols * t == period.0 as i64, "{period:?} is not a whole number of {t}-pixel tiles");
        let range = |size: u32| (0, (size as i64 - 1) / t);
        tile_torus(self.set, &Torus::new((rows, 0), (0, cols)), range(cover.1), range(cover.0), seed, "wang/torus")
    }

    /// Fills every tile's [`WangTile::sources`] from its diamond labels, the same sample pixels
    /// its raster was composed of.
    pub fn record_sources(&mut self, sample_width: u32) {
        let g = self.geometry;
        for tile in &mut self.tiles {
            let q = diamonds_of(tile.colours, &self.dn, &self.de);
            tile.sources = (0..g.t * g.t)
                .map(|i| {
                    let (x, y) = (i % g.t, i / g.t);
                    let (sx, sy) = match (tile.labels[i as usize], tile.interior) {
                        (INTERIOR, Some(off)) => ((x + off.0) as u32, (y + off.1) as u32),
                        (d, _) => g.sample_pixel(d as usize, q[d as usize], x, y),
                    };
                    sy * sample_width + sx
                })
                .collect();
        }
    }
}

impl super::common::TileRenderer for WangTileSet {
    fn render_rows(&self, tiling: &Tiling, width: u32, y0: u32, rows: &mut [u8]) {
        WangTileSet::render_rows(self, tiling, width, y0, rows)
    }
    fn source_rows(&self, tiling: &Tiling, width: u32, y0: u32, rows: &mut [u32]) {
        self.copy_rows(tiling, width, y0, rows, 1, |tile| &tile.sources)
    }
    fn tone_rows(&self, tiling: &Tiling, width: u32, y0: u32, rows: &mut [super::tone::ToneBlend]) {
        self.copy_rows(tiling, width, y0, rows, 1, |tile| &tile.tone)
    }
    fn toned(&self) -> bool {
        self.tiles.iter().any(|t| !t.tone.is_empty())
    }
    fn record_sources(&mut self, sample_width: u32) {
        WangTileSet::record_sources(self, sample_width)
    }
    fn tile_output(&self, order: TilingOrder, width: u32, height: u32, seed: u64) -> Tiling {
        WangTileSet::tile_output(self, order, width, height, seed)
    }
    fn tile_torus(&self, period: (u32, u32), cover: (u32, u32), seed: u64) -> Tiling {
        WangTileSet::tile_torus(self, period, cover, seed)
    }
    fn unit(&self) -> u32 {
        self.geometry.t as u32
    }
    /// A tile's last column (row): locked to the E (S) diamond, which the next tile's first
    /// column continues, so leaving it out steps one pixel inside that diamond.
    fn fit_slots(&self) -> super::fit::Slots {
        super::fit::Slots { step: self.geometry.t as u32, phase: self.geometry.t as u32 - 1 }
    }
}
