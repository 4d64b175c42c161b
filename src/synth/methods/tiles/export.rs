//! Exported tile sets: a tile method's tiles as standalone images plus a machine-readable index,
//! and rendering a texture of any size back from such an export.
//!
//! A tile set is a product of its own (paper 001): a renderer that knows the placement rule can
//! fill any area by copying tiles, with no synthesis at all. With `export_tiles = true`,
//! `wang-tiles` and `rw-tiles` jobs write, next to their output, a folder `{output}.tiles/` with
//! one RGBA PNG per tile (transparent outside a rhombus tile) and `index.json` (format
//! [`FORMAT`]): the geometry, each tile's edge colours, and where tile `(row, col)` goes. The index
//! also records the tiling rule and seed the job used, so `texsyn tiles render` reproduces the
//! job's output pixel for pixel from the export alone, and renders any other size or arrangement.
//!
//! Placement (both lattices): tile `(row, col)`'s image has its top-left pixel at
//! `col·col_step + row·row_step + offset` in output pixels, and the opaque pixels of all placed
//! tiles partition the plane. Edge colours follow B12: a tile's colour `a` equals the colour `c`
//! of the tile one row up, and its `b` equals the `d` of the tile one column to the left.
//!
//! The export knows the built tile sets ([`super::wang_set`], [`super::rw_set`]) and not the
//! methods: the methods call [`export_wang`] / [`export_rw`], never the reverse.

use super::common::MAX_COLORS;
use super::rw_set::{self, RwTile, RwTileSet};
use super::wang::{TileSet, TilingOrder};
use super::wang_set::{self, WangTile, WangTileSet};
use crate::image::RgbImage;
use crate::image::io::{self as imageio, DecodeLimits};
use crate::synth::method::{ExtraContent, ExtraOutput};
use crate::synth::params::Choice;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The index's format tag; bumped on any incompatible change.
pub const FORMAT: &str = "texsyn-tileset/1";

/// `index.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Index {
    pub format: String,
    /// `wang-tiles` or `rw-tiles`.
    pub method: String,
    /// `minimal` (`K³` tiles, `a + b ≡ c + d (mod K)`; for `K = 2` the 8 with `a ⊕ b ⊕ c ⊕ d = 0`)
    /// or `complete` (`K⁴`).
    pub tile_set: String,
    /// `K`, the colours per edge class: absent for paper 001's 2, so that those exports stay as
    /// they were.
    #[serde(default = "two", skip_serializing_if = "is_two")]
    pub colors: u8,
    /// The method's `tile` and `overlap` parameters.
    pub tile: u32,
    pub overlap: u32,
    /// `square` (Wang tiles) or `rhombus` (RW-Tiles, squares standing on a vertex).
    pub lattice: String,
    /// Output pixels between columns and between rows of the tile lattice.
    pub col_step: [i64; 2],
    pub row_step: [i64; 2],
    /// What the four colours of each tile are, in B12's `[a, b, c, d]` order.
    pub edges: [String; 4],
    /// The arrangement the job used: `keyed` or `scanline`, its seed and output size.
    pub tiling: String,
    pub seed: u64,
    pub output: [u32; 2],
    pub tiles: Vec<IndexTile>,
}

/// One tile of the index, in tile-set order.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IndexTile {
    /// The image, relative to the index.
    pub file: String,
    /// Edge colours in the order of [`Index::edges`].
    pub colours: [u8; 4],
    /// Where the image's top-left pixel is relative to the tile's lattice point.
    pub offset: [i64; 2],
    pub width: u32,
    pub height: u32,
}

fn two() -> u8 {
    2
}

fn is_two(k: &u8) -> bool {
    *k == 2
}

fn tile_file(k: usize) -> String {
    format!("tile_{k:02}.png")
}

fn finish(index: Index, images: Vec<(u32, u32, Vec<u8>)>) -> Vec<ExtraOutput> {
    let mut extras: Vec<ExtraOutput> = images
        .into_iter()
        .enumerate()
        .map(|(k, (width, height, data))| ExtraOutput {
            name: format!("tiles/{}", tile_file(k)),
            content: ExtraContent::Rgba8 { width, height, data },
        })
        .collect();
    let json = serde_json::to_value(&index).expect("the index serialises");
    extras.push(ExtraOutput { name: "tiles/index.json".into(), content: ExtraContent::Json(json) });
    extras
}

/// The export of a Cohen tile set: `T × T` opaque tiles on a square lattice.
pub fn export_wang(set: &WangTileSet, order: TilingOrder, seed: u64, output: (u32, u32)) -> Vec<ExtraOutput> {
    let t = set.geometry.t as u32;
    let images: Vec<(u32, u32, Vec<u8>)> =
        set.tiles.iter().map(|tile| (t, t, tile.raster.chunks_exact(3).flat_map(|p| [p[0], p[1], p[2], 255]).collect())).collect();
    let index = Index {
        format: FORMAT.into(),
        method: "wang-tiles".into(),
        tile_set: set.set.rule.name().into(),
        colors: set.set.colors,
        tile: t,
        overlap: set.geometry.ov as u32,
        lattice: "square".into(),
        col_step: [t as i64, 0],
        row_step: [0, t as i64],
        edges: ["N", "W", "S", "E"].map(String::from),
        tiling: order.name().into(),
        seed,
        output: [output.0, output.1],
        tiles: set
            .tiles
            .iter()
            .enumerate()
            .map(|(k, tile)| IndexTile { file: tile_file(k), colours: tile.colours, offset: [0, 0], width: t, height: t })
            .collect(),
    };
    finish(index, images)
}

/// The rhombus's bounding box inside the `f × f` framework: `(x0, y0, width, height)`.
fn rhombus_box(g: &rw_set::Geometry) -> (i32, i32, i32, i32) {
    let pts = (0..g.f).flat_map(|y| (0..g.f).map(move |x| (x, y))).filter(|&(x, y)| g.in_r(x, y));
    let (mut x0, mut y0, mut x1, mut y1) = (i32::MAX, i32::MAX, i32::MIN, i32::MIN);
    for (x, y) in pts {
        (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
    }
    (x0, y0, x1 - x0 + 1, y1 - y0 + 1)
}

/// The export of an RW tile set: rhombus tiles, cut to their bounding box, transparent outside.
pub fn export_rw(set: &RwTileSet, order: TilingOrder, seed: u64, output: (u32, u32)) -> Vec<ExtraOutput> {
    let g = set.geometry;
    let (x0, y0, w, h) = rhombus_box(&g);
    let images: Vec<(u32, u32, Vec<u8>)> = set
        .tiles
        .iter()
        .map(|tile| {
            let mut data = vec![0u8; (w * h * 4) as usize];
            for y in 0..h {
                for x in 0..w {
                    let (fx, fy) = (x0 + x, y0 + y);
                    if g.in_r(fx, fy) {
                        let s = ((fy * g.f + fx) * 3) as usize;
                        let d = ((y * w + x) * 4) as usize;
                        data[d..d + 3].copy_from_slice(&tile.raster[s..s + 3]);
                        data[d + 3] = 255;
                    }
                }
            }
            (w as u32, h as u32, data)
        })
        .collect();
    let half = g.h as i64;
    let index = Index {
        format: FORMAT.into(),
        method: "rw-tiles".into(),
        tile_set: set.set.rule.name().into(),
        colors: set.set.colors,
        tile: g.tile() as u32,
        overlap: g.ov as u32,
        lattice: "rhombus".into(),
        // Lattice row i = the rhombus index along x + y, column j = along y − x (docs/methods.md §3.6).
        col_step: [-half, half],
        row_step: [half, half],
        edges: ["NW", "NE", "SE", "SW"].map(String::from),
        tiling: order.name().into(),
        seed,
        output: [output.0, output.1],
        tiles: set
            .tiles
            .iter()
            .enumerate()
            .map(|(k, tile)| IndexTile {
                file: tile_file(k),
                colours: tile.colours,
                offset: [x0 as i64, y0 as i64],
                width: w as u32,
                height: h as u32,
            })
            .collect(),
    };
    finish(index, images)
}

/// A tile set read back from an export.
pub enum Loaded {
    Wang(Index, WangTileSet),
    Rw(Index, RwTileSet),
}

impl Loaded {
    pub fn index(&self) -> &Index {
        match self {
            Loaded::Wang(i, _) | Loaded::Rw(i, _) => i,
        }
    }

    /// Renders `width × height` with the given arrangement. With the index's own tiling, seed and
    /// output size this is exactly the job's output.
    pub fn render(&self, width: u32, height: u32, seed: u64, order: TilingOrder) -> RgbImage {
        let mut out = RgbImage::new(width, height);
        self.rows(width, height, seed, order)(0, out.as_raw_mut());
        out
    }

    /// A renderer of any whole output rows of the same fill as [`Loaded::render`]: `f(y0, rows)`
    /// fills `rows` (a multiple of `3 × width` bytes) with rows `y0..`. How a fill too large to
    /// hold is written strip by strip; only the tiling is made here.
    pub fn rows(&self, width: u32, height: u32, seed: u64, order: TilingOrder) -> Box<dyn Fn(u32, &mut [u8]) + Send + Sync + '_> {
        match self {
            Loaded::Wang(_, set) => {
                let tiling = set.tile_output(order, width, height, seed);
                Box::new(move |y0, rows| set.render_rows(&tiling, width, y0, rows))
            }
            Loaded::Rw(_, set) => {
                let tiling = set.tile_output(order, width, height, seed);
                Box::new(move |y0, rows| set.render_rows(&tiling, width, y0, rows))
            }
        }
    }

    /// Bytes the loaded tile set holds (its tiles' pixels and masks, as decoded: at most RGBA).
    pub fn tile_bytes(&self) -> u64 {
        self.index().tiles.iter().map(|t| 8 * u64::from(t.width) * u64::from(t.height)).sum()
    }
}

/// Why an exported tile set cannot be used: the file (the index or one tile) and the reason.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ExportError {
    pub file: std::path::PathBuf,
    pub reason: String,
}

impl std::fmt::Display for ExportError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.file.display(), self.reason)
    }
}

impl std::error::Error for ExportError {}

/// Reads `index.json` and its tile images, checking everything a renderer relies on: the
/// format, the geometry, that the tiles are the set's tiles in order with their edge colours, and
/// each image's size and (for rhombi) its alpha mask.
pub fn load(index_path: &Path) -> Result<Loaded, ExportError> {
    let at = |reason: String| ExportError { file: index_path.to_path_buf(), reason };
    let bytes = crate::files::read_limited(index_path, crate::files::MAX_JSON_BYTES).map_err(|e| at(format!("cannot read: {e}")))?;
    let index: Index = serde_json::from_slice(&bytes).map_err(|e| at(format!("not a tile-set index: {e}")))?;
    if index.format != FORMAT {
        return Err(at(format!("format `{}` is not `{FORMAT}`; it was written by another texsyn version", index.format)));
    }
    let rule = TileSet::parse(&index.tile_set).ok_or_else(|| at(format!("tile_set `{}` is not minimal or complete", index.tile_set)))?;
    if !(2..=MAX_COLORS).contains(&u32::from(index.colors)) {
        return Err(at(format!("colors {} is not in 2..={MAX_COLORS}", index.colors)));
    }
    let set = rule.with_colors(index.colors);
    if index.tiles.len() != set.len() {
        return Err(at(format!("a {} set has {} tiles, the index lists {}", index.tile_set, set.len(), index.tiles.len())));
    }
    for (k, t) in index.tiles.iter().enumerate() {
        if t.colours != set.colours(k) {
            return Err(at(format!(
                "tile {k} ({}) has colours {:?}; tile {k} of a {} set must have {:?}",
                t.file,
                t.colours,
                index.tile_set,
                set.colours(k)
            )));
        }
    }
    // Bounded before anything is sized from them: the tile geometry allocates tile² masks.
    if i64::from(index.tile) > super::align::TILE_RANGE.1 || index.overlap > index.tile {
        return Err(at(format!(
            "tile {} / overlap {}: the tile must be at most {} and the overlap at most the tile",
            index.tile,
            index.overlap,
            super::align::TILE_RANGE.1
        )));
    }
    let (tile, ov) = (index.tile as i32, index.overlap as i32);
    if tile < 8 || tile % 2 != 0 || ov < 2 || ov % 2 != 0 {
        return Err(at(format!("tile {tile} / overlap {ov} must be even, tile at least 8, overlap at least 2")));
    }
    let dir = index_path.parent().unwrap_or(Path::new("."));
    let read_tile = |t: &IndexTile| -> Result<Vec<u8>, ExportError> {
        if t.file.contains("..") || Path::new(&t.file).is_absolute() {
            return Err(at(format!("tile file `{}` must be a name inside the export folder", t.file)));
        }
        let path = dir.join(&t.file);
        let bytes = crate::files::read_limited(&path, crate::files::MAX_IMAGE_FILE_BYTES)
            .map_err(|e| ExportError { file: path.clone(), reason: format!("cannot read: {e}") })?;
        let (w, h, data) = imageio::decode_rgba8(&bytes, DecodeLimits::default())
            .map_err(|e| ExportError { file: path.clone(), reason: e.to_string() })?;
        if (w, h) != (t.width, t.height) {
            return Err(ExportError { file: path, reason: format!("is {w}x{h}; the index says {}x{}", t.width, t.height) });
        }
        Ok(data)
    };
    match index.method.as_str() {
        "wang-tiles" => {
            if ov * 2 > tile {
                return Err(at(format!("overlap {ov} is more than half the tile ({tile})")));
            }
            let g = wang_set::Geometry::new(tile, ov);
            let mut tiles = Vec::new();
            for t in &index.tiles {
                if (t.width, t.height) != (index.tile, index.tile) || t.offset != [0, 0] {
                    return Err(at(format!("tile `{}` must be {tile}x{tile} at offset [0, 0]", t.file)));
                }
                let data = read_tile(t)?;
                let raster = data.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect();
                tiles.push(WangTile {
                    colours: t.colours,
                    raster,
                    labels: Vec::new(),
                    cut_costs: [0; 4],
                    fallback_pixels: 0,
                    interior: None,
                    sources: Vec::new(),
                    tone: Vec::new(),
                });
            }
            Ok(Loaded::Wang(index, WangTileSet { geometry: g, set, dn: Vec::new(), de: Vec::new(), tiles }))
        }
        "rw-tiles" => {
            if 2 * ov + 4 > tile {
                return Err(at(format!("overlap {ov} is too wide for tile {tile}")));
            }
            let g = rw_set::Geometry::new(tile, ov);
            let (x0, y0, w, h) = rhombus_box(&g);
            let mut tiles = Vec::new();
            for t in &index.tiles {
                if (t.width, t.height) != (w as u32, h as u32) || t.offset != [x0 as i64, y0 as i64] {
                    return Err(at(format!("tile `{}` must be {w}x{h} at offset [{x0}, {y0}] for tile {tile} / overlap {ov}", t.file)));
                }
                let data = read_tile(t)?;
                let mut raster = vec![0u8; (g.f * g.f * 3) as usize];
                for y in 0..h {
                    for x in 0..w {
                        let (fx, fy) = (x0 + x, y0 + y);
                        let s = ((y * w + x) * 4) as usize;
                        let inside = g.in_r(fx, fy);
                        if inside != (data[s + 3] == 255) && (inside || data[s + 3] != 0) {
                            return Err(ExportError {
                                file: dir.join(&t.file),
                                reason: format!(
                                    "pixel ({x}, {y}) has alpha {}; a rhombus tile is opaque (255) exactly inside the rhombus and transparent (0) outside",
                                    data[s + 3]
                                ),
                            });
                        }
                        if inside {
                            let d = ((fy * g.f + fx) * 3) as usize;
                            raster[d..d + 3].copy_from_slice(&data[s..s + 3]);
                        }
                    }
                }
                tiles.push(RwTile {
                    colours: t.colours,
                    raster,
                    labels: Vec::new(),
                    centre_block: 0,
                    interior: None,
                    strip_costs: [0; 4],
                    pocket_costs: Vec::new(),
                    sources: Vec::new(),
                    tone: Vec::new(),
                });
            }
            Ok(Loaded::Rw(index, RwTileSet { geometry: g, set, pa: Vec::new(), pb: Vec::new(), tiles }))
        }
        other => Err(at(format!("method `{other}` has no tile sets (expected wang-tiles or rw-tiles)"))),
    }
}
