//! A built RW tile set: the framework and rhombus geometry of a rotational Wang tile, the tiles,
//! and filling an output from them (locating pixels on the rhombus lattice and copying runs of
//! tile rows).
//!
//! `rw-tiles` builds such a set and the tile-set export ([`super::export`]) writes and reads it
//! back; both render through [`RwTileSet::render`]. Keeping the set here, below both, is what lets
//! the export render a loaded set without importing the method that imports the export.

use super::interior::INTERIOR;
use super::wang::{EdgeSet, Tiling, TilingOrder, Torus, tile_rect, tile_torus};
use crate::image::RgbImage;
use crate::synth::placement::UNCOVERED;
use rayon::prelude::*;

/// Geometry of one RW-tile's framework (§3.2): sub-block side `s`, overlap `ov`, `h = s − ov`,
/// framework side `f = 2s − ov`, rhombus `R = {u0 ≤ x+y < u0+2h, w0 ≤ y−x < w0+2h}`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Geometry {
    pub s: i32,
    pub ov: i32,
    pub h: i32,
    pub f: i32,
    pub u0: i32,
    pub w0: i32,
}

/// The block label of framework pixels outside the rhombus (block numbers are 0-based here:
/// `B1..B4` are 0..3).
pub const UNSET: u8 = u8::MAX;

impl Geometry {
    /// From the tile size `T` (even) and the overlap `ov` (even): `s = T/2 + ov`.
    pub fn new(tile: i32, ov: i32) -> Geometry {
        let h = tile / 2;
        let s = h + ov;
        Geometry { s, ov, h, f: 2 * s - ov, u0: s - 1, w0: -h }
    }

    pub fn tile(&self) -> i32 {
        2 * self.h
    }

    #[inline]
    pub fn in_r(&self, x: i32, y: i32) -> bool {
        let (u, w) = (x + y, y - x);
        u >= self.u0 && u < self.u0 + 2 * self.h && w >= self.w0 && w < self.w0 + 2 * self.h
    }

    /// Framework origin of block `k` (0-based, clockwise from the top left).
    pub fn origin(&self, k: usize) -> (i32, i32) {
        let h = self.h;
        [(0, 0), (h, 0), (h, h), (0, h)][k]
    }

    /// The block a tile-edge pixel is locked to (§3.2), for pixels of `R`.
    pub fn lock(&self, x: i32, y: i32) -> Option<usize> {
        let (u, w) = (x + y, y - x);
        let (u_last, w_last) = (self.u0 + 2 * self.h - 1, self.w0 + 2 * self.h - 1);
        // The E vertex (on the NE and SE edges) goes to B2 and the W vertex (SW and NW) to B4,
        // so test B2 before B3 and B4 before B1.
        if w == self.w0 {
            Some(1)
        } else if w == w_last {
            Some(3)
        } else if u == self.u0 {
            Some(0)
        } else if u == u_last {
            Some(2)
        } else {
            None
        }
    }

    /// Class of a coordinate: 0 below `h`, 1 in `[h, s)`, 2 from `s` on.
    #[inline]
    fn class(&self, v: i32) -> usize {
        if v < self.h {
            0
        } else if v < self.s {
            1
        } else {
            2
        }
    }

    /// The single block covering `(x, y)` when only one does.
    pub fn single(&self, x: i32, y: i32) -> Option<usize> {
        match (self.class(x), self.class(y)) {
            (0, 0) => Some(0),
            (2, 0) => Some(1),
            (2, 2) => Some(2),
            (0, 2) => Some(3),
            _ => None,
        }
    }

    /// The sample pixel that framework pixel `(x, y)` reads from block `k` cut at sample corner `p`.
    #[inline]
    pub fn sample_pixel(&self, k: usize, p: (u32, u32), x: i32, y: i32) -> (u32, u32) {
        let (ox, oy) = self.origin(k);
        ((p.0 as i32 + x - ox) as u32, (p.1 as i32 + y - oy) as u32)
    }

    /// Index of framework pixel `(x, y)` in the `f × f` rasters.
    #[inline]
    pub fn idx(&self, x: i32, y: i32) -> usize {
        (y * self.f + x) as usize
    }
}

/// One built tile.
#[derive(Clone, Debug)]
pub struct RwTile {
    /// Edge colours `[NW, NE, SE, SW]`.
    pub colours: [u8; 4],
    /// `f × f` RGB raster; only pixels of `R` are meaningful.
    pub raster: Vec<u8>,
    /// `f × f` block labels (0..3; [`INTERIOR`] for the tile's own interior), `UNSET` outside `R`.
    pub labels: Vec<u8>,
    /// The centre block `k*` (0-based).
    pub centre_block: usize,
    /// With an interior of its own ([`super::interior`]): the offset from framework pixels
    /// labelled [`INTERIOR`] to the sample pixels they copy.
    pub interior: Option<(i32, i32)>,
    /// Path costs of the four strip seams (N, E, S, W) and of the three centre pockets.
    pub strip_costs: [u64; 4],
    pub pocket_costs: Vec<u64>,
    /// `f × f` sample indices (`y · sample_width + x`) the raster's pixels of `R` are copies of
    /// ([`UNCOVERED`] outside `R`): filled by [`RwTileSet::record_sources`] only when a job asks
    /// for its placement, empty otherwise.
    pub sources: Vec<u32>,
    /// `f × f` tone blends of its interior's pixels ([`super::tone`]): empty when not toned.
    pub tone: Vec<super::tone::ToneBlend>,
}

impl super::tone::Toneable for RwTile {
    fn labels(&self) -> &[u8] {
        &self.labels
    }
    fn tone_parts(&mut self) -> (&mut [u8], &[u8], &mut Vec<super::tone::ToneBlend>) {
        (&mut self.raster, &self.labels, &mut self.tone)
    }
}

/// The sample corners of a tile's blocks `B1..B4`, from its colours `[NW, NE, SE, SW]`.
pub fn patches_of(colours: [u8; 4], pa: &[(u32, u32)], pb: &[(u32, u32)]) -> [(u32, u32); 4] {
    [pa[colours[0] as usize], pb[colours[1] as usize], pa[colours[2] as usize], pb[colours[3] as usize]]
}

/// A built tile set.
#[derive(Clone, Debug)]
pub struct RwTileSet {
    pub geometry: Geometry,
    pub set: EdgeSet,
    /// Patch corners, one per colour: `PA[0] .. PA[K−1]` ("/" edges, NW and SE) and `PB[..]` ("\"
    /// edges).
    pub pa: Vec<(u32, u32)>,
    pub pb: Vec<(u32, u32)>,
    pub tiles: Vec<RwTile>,
}

/// Colours for block labels in [`RwTileSet::label_image`] (B1..B4, own interior, outside `R`).
const LABEL_COLOURS: [[u8; 3]; 6] = [[230, 60, 50], [60, 170, 70], [50, 90, 220], [240, 200, 40], [128, 128, 128], [0, 0, 0]];

impl RwTileSet {
    /// Tile `k` as an image: its `f × f` framework with the pixels outside the rhombus black
    /// (the building block for a tile-set export).
    pub fn tile_image(&self, k: usize) -> RgbImage {
        let f = self.geometry.f as u32;
        RgbImage::from_raw(f, f, self.tiles[k].raster.clone()).expect("f × f raster")
    }

    /// Tile `k`'s block labels as colours (B1 red, B2 green, B3 blue, B4 yellow), for inspection.
    pub fn label_image(&self, k: usize) -> RgbImage {
        let f = self.geometry.f as u32;
        let labels = &self.tiles[k].labels;
        RgbImage::from_fn(f, f, |x, y| LABEL_COLOURS[(labels[(y * f + x) as usize] as usize).min(5)])
    }

    /// Places the tiles for a `width × height` output (B12 on the rhombus lattice, §3.6).
    pub fn tile_output(&self, order: TilingOrder, width: u32, height: u32, seed: u64) -> Tiling {
        let (i, j) = lattice_range(&self.geometry, width, height);
        // Pixel (0, 0) lies in lattice column j = 0 (w0 = −h), the keyed order's anchor.
        let anchor = locate(&self.geometry, 0, 0).0.1;
        tile_rect(self.set, order, i, j, anchor, seed, "rwtiles/tiling")
    }

    /// Renders the output by copying runs of tile rows (§3.6); rows are filled in parallel.
    pub fn render(&self, tiling: &Tiling, width: u32, height: u32) -> RgbImage {
        let mut out = RgbImage::new(width, height);
        self.render_rows(tiling, width, 0, out.as_raw_mut());
        out
    }

    /// Renders output rows `y0..` into `rows` (whole rows of a `width`-wide output), the same
    /// pixels as those rows of [`RwTileSet::render`]: how a large fill is written strip by strip.
    pub fn render_rows(&self, tiling: &Tiling, width: u32, y0: u32, rows: &mut [u8]) {
        self.copy_rows(tiling, width, y0, rows, 3, |tile| &tile.raster);
    }

    /// Lays a tiling of `f × f` planes of `ch` values per pixel (a tile's raster or its sources)
    /// into output rows `y0..`, copying runs of tile rows (§3.6); rows are filled in parallel.
    fn copy_rows<T: Copy + Send + Sync>(
        &self,
        tiling: &Tiling,
        width: u32,
        y0: u32,
        rows: &mut [T],
        ch: usize,
        plane: impl Fn(&RwTile) -> &[T] + Sync,
    ) {
        let g = self.geometry;
        let (f, h2) = (g.f as usize, 2 * g.h as i64);
        rows.par_chunks_mut(width as usize * ch).enumerate().for_each(|(y, row)| {
            let y = y as i64 + i64::from(y0);
            let mut x = 0i64;
            while x < width as i64 {
                let ((i, j), (fx, fy)) = locate(&g, x, y);
                let to_i = h2 - (x + y - g.u0 as i64).rem_euclid(h2);
                let to_j = (y - x - g.w0 as i64).rem_euclid(h2) + 1;
                let run = to_i.min(to_j).min(width as i64 - x) as usize;
                let tile = plane(&self.tiles[tiling.at(i, j)]);
                let src = (fy as usize * f + fx as usize) * ch;
                row[x as usize * ch..(x as usize + run) * ch].copy_from_slice(&tile[src..src + run * ch]);
                x += run as i64;
            }
        });
    }

    /// Places the tiles for a `period` output that wraps, both sizes multiples of the tile
    /// `T = 2h` ([`tile_torus`], stream `rwtiles/torus`), over an output of `cover` size (the
    /// period itself, or more to see it repeat). Shifting the output by `(W, 0) = 2h·(m, 0)` moves
    /// [`locate`]'s lattice by `(m, −m)` and leaves framework coordinates alone; `(0, H) =
    /// 2h·(0, n)` moves it by `(n, n)`: the tiling is periodic on those two.
    pub fn tile_torus(&self, period: (u32, u32), cover: (u32, u32), seed: u64) -> Tiling {
        let t = self.geometry.tile() as i64;
        let (m, n) = (period.0 as i64 / t, period.1 as i64 / t);
        assert!(m * t == period.0 as i64 && n * t == period.1 as i64, "{period:?} is not a whole number of {t}-pixel tiles");
        let (i, j) = lattice_range(&self.geometry, cover.0, cover.1);
        tile_torus(self.set, &Torus::new((m, -m), (n, n)), i, j, seed, "rwtiles/torus")
    }

    /// Fills every tile's [`RwTile::sources`] from its block labels, the same sample pixels its
    /// raster was composed of.
    pub fn record_sources(&mut self, sample_width: u32) {
        let g = self.geometry;
        for tile in &mut self.tiles {
            let p = patches_of(tile.colours, &self.pa, &self.pb);
            tile.sources = (0..g.f * g.f)
                .map(|i| match (tile.labels[i as usize], tile.interior) {
                    (UNSET, _) => UNCOVERED,
                    (INTERIOR, Some(off)) => ((i / g.f + off.1) as u32) * sample_width + (i % g.f + off.0) as u32,
                    (k, _) => {
                        let (sx, sy) = g.sample_pixel(k as usize, p[k as usize], i % g.f, i / g.f);
                        sy * sample_width + sx
                    }
                })
                .collect();
        }
    }
}

/// Lattice position `(i, j)` of output pixel `(X, Y)` and its framework coordinates (§3.6).
#[inline]
pub fn locate(g: &Geometry, x: i64, y: i64) -> ((i64, i64), (i32, i32)) {
    let (h, h2) = (g.h as i64, 2 * g.h as i64);
    let i = (x + y - g.u0 as i64).div_euclid(h2);
    let j = (y - x - g.w0 as i64).div_euclid(h2);
    ((i, j), ((x - h * (i - j)) as i32, (y - h * (i + j)) as i32))
}

/// The lattice range covering a `width × height` output with its top-left pixel at the origin.
pub fn lattice_range(g: &Geometry, width: u32, height: u32) -> ((i64, i64), (i64, i64)) {
    let corners = [(0i64, 0i64), (width as i64 - 1, 0), (0, height as i64 - 1), (width as i64 - 1, height as i64 - 1)];
    let ij: Vec<(i64, i64)> = corners.iter().map(|&(x, y)| locate(g, x, y).0).collect();
    let i = (ij.iter().map(|p| p.0).min().unwrap(), ij.iter().map(|p| p.0).max().unwrap());
    let j = (ij.iter().map(|p| p.1).min().unwrap(), ij.iter().map(|p| p.1).max().unwrap());
    (i, j)
}

impl super::common::TileRenderer for RwTileSet {
    fn render_rows(&self, tiling: &Tiling, width: u32, y0: u32, rows: &mut [u8]) {
        RwTileSet::render_rows(self, tiling, width, y0, rows)
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
        RwTileSet::record_sources(self, sample_width)
    }
    fn tile_output(&self, order: TilingOrder, width: u32, height: u32, seed: u64) -> Tiling {
        RwTileSet::tile_output(self, order, width, height, seed)
    }
    fn tile_torus(&self, period: (u32, u32), cover: (u32, u32), seed: u64) -> Tiling {
        RwTileSet::tile_torus(self, period, cover, seed)
    }
    fn unit(&self) -> u32 {
        self.geometry.tile() as u32
    }
    /// Halfway between the seam strips (columns and rows `≡ 0..ov (mod h)`): inside one sub-block.
    fn fit_slots(&self) -> super::fit::Slots {
        let (h, ov) = (self.geometry.h as u32, self.geometry.ov as u32);
        super::fit::Slots { step: h, phase: ov + (h - ov) / 2 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn geometry_matches_the_spec_example() {
        // s = 40, ov = 8: the rhombus spans x ∈ [4, 67], y ∈ [4, 66] and has 2h² pixels.
        let g = Geometry::new(64, 8);
        assert_eq!((g.s, g.h, g.f, g.u0, g.w0), (40, 32, 72, 39, -32));
        let pts: Vec<(i32, i32)> = (0..g.f).flat_map(|y| (0..g.f).map(move |x| (x, y))).filter(|&(x, y)| g.in_r(x, y)).collect();
        assert_eq!(pts.len(), 2 * 32 * 32);
        assert_eq!(pts.iter().map(|p| p.0).min(), Some(4));
        assert_eq!(pts.iter().map(|p| p.0).max(), Some(67));
        assert_eq!(pts.iter().map(|p| p.1).min(), Some(4));
        assert_eq!(pts.iter().map(|p| p.1).max(), Some(66));
        // E vertex (67, 35) → B2, W vertex (4, 35) → B4.
        assert_eq!(g.lock(67, 35), Some(1));
        assert_eq!(g.lock(4, 35), Some(3));
        // Every pixel of R is covered by the block it is locked to.
        for &(x, y) in &pts {
            if let Some(k) = g.lock(x, y) {
                let (ox, oy) = g.origin(k);
                assert!(x >= ox && x < ox + g.s && y >= oy && y < oy + g.s);
            }
        }
    }

    #[test]
    fn every_output_pixel_maps_into_r() {
        let g = Geometry::new(20, 4);
        for y in -30..60i64 {
            for x in -30..60i64 {
                let ((i, j), (fx, fy)) = locate(&g, x, y);
                assert!(g.in_r(fx, fy), "({x},{y}) → tile ({i},{j}) at ({fx},{fy})");
            }
        }
    }
}
