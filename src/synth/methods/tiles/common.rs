//! What the two tile methods share beyond the Wang-tile colouring ([`super::wang`]) and the
//! lattice alignment ([`super::align`]): the per-pixel cut cost, the `patch_candidates` choice
//! among random patch draws, the `export_tiles` parameter, reading their typed configs, choosing
//! the tiling (wrapping or not), and rendering a filled tiling and its placement whole or strip by
//! strip.
//!
//! It sits below both methods and below the tile-set modules, so that `wang-tiles` does not have to
//! borrow these from `rw-tiles` (or the reverse) and the family's imports only go one way.

use super::fit::{Fit, Slots};
use super::wang::{Tiling, TilingOrder};
use crate::image::RgbImage;
use crate::synth::method::{Placement, Request, STRIP_ROWS, SourceRows, Strips, Synthesis, linear_memory};
use crate::synth::params::{Choice, Default, ParamKind, ParamSpec};
use crate::synth::primitives::overlap::pixel_error;
use crate::synth::rng::Stream;
use std::sync::Arc;
use std::time::Instant;

/// A tile set that renders a tiling's output rows: what both tile methods fill with.
pub trait TileRenderer: Send + Sync + 'static {
    /// Renders output rows `y0..` into `rows` (whole rows of a `width`-wide output).
    fn render_rows(&self, tiling: &Tiling, width: u32, y0: u32, rows: &mut [u8]);
    /// The sample index every pixel of output rows `y0..` copies, as [`TileRenderer::render_rows`]
    /// lays out the pixels; needs [`TileRenderer::record_sources`] first.
    fn source_rows(&self, tiling: &Tiling, width: u32, y0: u32, rows: &mut [u32]);
    /// The tone blend ([`super::tone::ToneBlend`]) of every pixel of output rows `y0..`, laid out
    /// as [`TileRenderer::source_rows`]; only for a set that [`TileRenderer::toned`].
    fn tone_rows(&self, tiling: &Tiling, width: u32, y0: u32, rows: &mut [super::tone::ToneBlend]);
    /// Whether the set's interiors were toned ([`super::tone`]): its placement then has blends.
    fn toned(&self) -> bool;
    /// Keeps, for every tile pixel, the sample index it copies (only when a placement is asked for:
    /// it is as large as the tiles' rasters again).
    fn record_sources(&mut self, sample_width: u32);
    /// The tiling of a `width × height` output in the job's `tiling` order.
    fn tile_output(&self, order: TilingOrder, width: u32, height: u32, seed: u64) -> Tiling;
    /// The tiling of an output that wraps with `period` (sizes already checked by [`tileable`]),
    /// over `cover` pixels: the output itself, or a larger area that shows the repeat.
    fn tile_torus(&self, period: (u32, u32), cover: (u32, u32), seed: u64) -> Tiling;
    /// The pixels a wrapping tiling repeats after, both ways (the tile size).
    fn unit(&self) -> u32;
    /// Where a [`Fit`] may leave out or repeat a column (row) of the torus: inside a tile, on one
    /// continuous patch of the sample.
    fn fit_slots(&self) -> Slots;

    /// The tiling a request asks for: wrapping when [`Request::tileable`], the job's order
    /// otherwise; a wrapping output of a size that is not whole tiles is shown from the torus of
    /// whole tiles nearest it ([`Fit`]).
    fn tiling(&self, order: TilingOrder, req: &Request) -> (Tiling, Option<Fit>) {
        let size = (req.width, req.height);
        if !req.tileable {
            return (self.tile_output(order, size.0, size.1, req.seed), None);
        }
        match Fit::new(size, self.unit(), self.fit_slots()) {
            None => (self.tile_torus(size, size, req.seed), None),
            Some(fit) => (self.tile_torus(fit.period, fit.period, req.seed), Some(fit)),
        }
    }
}

/// What a tile method's fill hands to rendering: the synthesis record, the tile set, the tiling
/// and, for a wrapping output that is not whole tiles, its [`Fit`].
pub type Filled<T> = (Synthesis, T, Tiling, Option<Fit>);

/// Output rows `y0..` of a tiling, through its fit when it has one.
fn rows_of<T: Copy + std::default::Default + Send + Sync>(
    fit: Option<&Fit>,
    width: u32,
    y0: u32,
    rows: &mut [T],
    ch: usize,
    render: impl Fn(u32, u32, &mut [T]),
) {
    match fit {
        None => render(width, y0, rows),
        Some(f) => super::fit::render_rows(f, y0, rows, ch, |v0, torus| render(f.period.0, v0, torus)),
    }
}

/// [`crate::synth::method::Method::synthesize`] of a tile method from its fill: the output
/// rendered whole (and its placement when asked for), the rendering time added to the `fill` phase.
pub fn render_whole(filled: Filled<impl TileRenderer>, req: &Request) -> Synthesis {
    let (mut synthesis, mut tiles, tiling, fit) = filled;
    let t = Instant::now();
    let mut image = RgbImage::new(req.width, req.height);
    // A fitted output goes STRIP_ROWS rows at a time, so that the torus it is shown from is never
    // rendered whole beside it.
    let step = if fit.is_some() { STRIP_ROWS as usize } else { req.height.max(1) as usize };
    let w = req.width as usize;
    for (k, chunk) in image.as_raw_mut().chunks_mut((w * 3 * step).max(1)).enumerate() {
        rows_of(fit.as_ref(), req.width, (k * step) as u32, chunk, 3, |width, y0, rows| tiles.render_rows(&tiling, width, y0, rows));
    }
    synthesis.image = image;
    if req.placement {
        tiles.record_sources(req.sample.width());
        let mut sources = vec![0u32; req.width as usize * req.height as usize];
        for (k, chunk) in sources.chunks_mut((w * step).max(1)).enumerate() {
            rows_of(fit.as_ref(), req.width, (k * step) as u32, chunk, 1, |width, y0, rows| tiles.source_rows(&tiling, width, y0, rows));
        }
        let mut placement = Placement::from_sources(req.width, req.height, req.sample.dimensions(), sources);
        if tiles.toned() {
            // Every tile of a toned set has its blends (`tone::tone_set`).
            let mut blends = vec![(0u32, 0u8); req.width as usize * req.height as usize];
            for (k, chunk) in blends.chunks_mut((w * step).max(1)).enumerate() {
                rows_of(fit.as_ref(), req.width, (k * step) as u32, chunk, 1, |width, y0, rows| tiles.tone_rows(&tiling, width, y0, rows));
            }
            let sw = req.sample.width();
            for (i, &(s, num)) in blends.iter().enumerate().filter(|(_, b)| b.1 > 0) {
                let (x, y) = ((i % w) as u32, (i / w) as u32);
                placement.blend(x, y, s % sw, s / sw, u32::from(num), super::tone::DEN);
            }
        }
        synthesis.placement = Some(placement);
    }
    if let Some(fill) = synthesis.phases.iter_mut().find(|p| p.0 == "fill") {
        fill.1 += t.elapsed().as_secs_f64();
    }
    synthesis
}

/// [`crate::synth::method::Method::synthesize_strips`] of a tile method from its fill.
pub fn render_in_strips(filled: Filled<impl TileRenderer>, req: &Request) -> Strips {
    let (synthesis, mut tiles, tiling, fit) = filled;
    let width = req.width;
    if req.placement {
        tiles.record_sources(req.sample.width());
    }
    let shared = Arc::new((tiles, tiling, fit));
    let sources: Option<SourceRows> = req.placement.then(|| {
        let shared = Arc::clone(&shared);
        Box::new(move |y0: u32, rows: &mut [u32]| {
            rows_of(shared.2.as_ref(), width, y0, rows, 1, |w, y0, rows| shared.0.source_rows(&shared.1, w, y0, rows))
        }) as SourceRows
    });
    Strips {
        synthesis,
        render: Box::new(move |y0, rows| {
            rows_of(shared.2.as_ref(), width, y0, rows, 3, |w, y0, rows| shared.0.render_rows(&shared.1, w, y0, rows))
        }),
        sources,
    }
}

/// Whether a tile method's output of `output` size can wrap: at least two `period`-pixel tiles
/// each way, or a whole number of them (the tiling is then chosen on a torus of whole tiles,
/// [`Fit`] when the size is not whole tiles), and no tile-set export, whose index records the
/// position-keyed tiling `texsyn tiles render` reproduces, not the wrapping one.
pub fn tileable(method: &str, period: u32, export_tiles: bool, output: (u32, u32)) -> Result<(), String> {
    tileable_export(method, export_tiles)?;
    if !super::fit::fits(output.0, period) || !super::fit::fits(output.1, period) {
        let least = |v: u32| if super::fit::fits(v, period) { v } else { 2 * period };
        return Err(format!(
            "tileable {method} needs at least two tiles each way (or exactly one), {} pixels a side for tile {period}; {}x{} would work, or a smaller tile",
            2 * period,
            least(output.0),
            least(output.1)
        ));
    }
    Ok(())
}

/// The `tile` parameter of both tile methods: `Some(size)`, or `None` for `"auto"`.
pub fn tile_param(p: &crate::synth::params::Params) -> Result<Option<u32>, crate::synth::error::SynthError> {
    p.int_or_word("tile")?
        .map(|t| u32::try_from(t).map_err(|_| crate::synth::error::SynthError::param("tile", format!("{t} is not a size"))))
        .transpose()
}

/// A tileable output cannot also export the tile set.
pub fn tileable_export(method: &str, export_tiles: bool) -> Result<(), String> {
    if export_tiles {
        return Err(format!(
            "tileable {method} output cannot also export its tile set (export_tiles): the export records the position-keyed tiling, not the wrapping one; turn off one of them"
        ));
    }
    Ok(())
}

/// A [`tileable`] refusal, naming the size `tile = "auto"` chose when it chose one.
pub fn auto_named(why: String, choice: Option<&super::align::TileChoice>) -> String {
    match choice {
        Some(c) => format!(
            "{why}; the tile size {} is tile = \"auto\"'s choice for this sample ({}); give the output at least two tiles of it each way, or set tile",
            c.tile,
            c.record["how"].as_str().unwrap_or("auto")
        ),
        None => why,
    }
}

/// Peak memory of a tile fill rendered in strips: the tile set (built from sample-sized cost
/// planes), the tiling (one byte per tile) and one strip of output rows.
pub fn strip_peak_memory(sample: (u32, u32), output: (u32, u32)) -> u64 {
    let strip = u64::from(output.0) * u64::from(STRIP_ROWS) * 3;
    linear_memory(sample, output, 0.01, 64.0, 4 << 20) + strip
}

/// The `export_tiles` parameter of both tile methods.
pub const EXPORT_TILES_PARAM: ParamSpec = ParamSpec {
    name: "export_tiles",
    kind: ParamKind::Bool,
    default: Default::Bool(false),
    doc: "also write the tile set next to the output: one RGBA PNG per tile and index.json (edge colours, placement), in `{output}.tiles/`; `texsyn tiles render` renders any size from it",
};

crate::choice! {
    /// Per-pixel cut cost (B1, or its square root): the `pixel_error` parameter of both methods.
    pub enum PixelError {
        /// The squared RGB distance (eq. 3).
        Squared = "squared",
        /// `round(1024·sqrt(e))`: the Euclidean distance in fixed point with 10 fractional bits
        /// (IEEE `sqrt` is correctly rounded, so this is exact and platform independent).
        Euclidean = "euclidean",
    }
}

impl PixelError {
    #[inline]
    pub fn eval(self, a: [u8; 3], b: [u8; 3]) -> u32 {
        let e = pixel_error(a, b);
        match self {
            PixelError::Squared => e,
            PixelError::Euclidean => ((e as f64).sqrt() * 1024.0).round() as u32,
        }
    }
}

/// Mean squared deviation from the mean colour (summed over R, G, B) of the `w × h` rectangle at
/// `(x, y)`: its contrast, in the units of B1's pixel error. Exact integer sums.
pub fn contrast(sample: &RgbImage, (x, y): (u32, u32), w: u32, h: u32) -> f64 {
    let n = (w as u64 * h as u64) as f64;
    let mut sum = [0u64; 3];
    let mut sq = [0u64; 3];
    for yy in y..y + h {
        for xx in x..x + w {
            let p = sample.get(xx, yy);
            for c in 0..3 {
                sum[c] += p[c] as u64;
                sq[c] += p[c] as u64 * p[c] as u64;
            }
        }
    }
    (0..3).map(|c| sq[c] as f64 / n - (sum[c] as f64 / n) * (sum[c] as f64 / n)).sum()
}

/// Whether every patch of a candidate is representative for `patch_candidates`: its contrast is
/// at least half the whole sample's. Without this rule the cheapest seams come from flat patches
/// (nothing to cut through), which turns a brick wall into plain bricks.
pub fn representative(sample: &RgbImage, corners: &[(u32, u32)], side: u32) -> bool {
    let whole = contrast(sample, (0, 0), sample.width(), sample.height());
    corners.iter().all(|&p| contrast(sample, p, side, side) >= 0.5 * whole)
}

/// The candidate kept by `patch_candidates`: the smallest seam cost among the representative
/// candidates (all candidates if none is), ties to the earliest.
pub fn pick_candidate(costs: &[u64], representative: &[bool]) -> usize {
    let any = representative.iter().any(|&r| r);
    (0..costs.len()).filter(|&c| !any || representative[c]).min_by_key(|&c| (costs[c], c)).expect("at least one candidate")
}

/// One candidate's patches, one per colour of each edge class: `([A₀ .. A_{K−1}], [B₀ .. B_{K−1}])`
/// (Wang: the N/S and E/W diamond centres; RW: the "/" and "\" sub-block corners).
pub type Patches = (Vec<(u32, u32)>, Vec<(u32, u32)>);

/// The `colors` parameter of both tile methods: `K`, the colours per edge class.
pub const COLORS_PARAM: ParamSpec = ParamSpec {
    name: "colors",
    kind: ParamKind::IntOr { min: 2, max: MAX_COLORS as i64, word: AUTO_COLORS_WORD },
    default: Default::Str(AUTO_COLORS_WORD),
    doc: "K: colours per edge class; the tile set holds K³ (minimal) or K⁴ (complete) tiles built from 2K patches, so two tiles a tile apart repeat the same patch about once in K. 2: paper 001's sets (patches drawn anywhere, as the paper does); K ≥ 3: the 2K patches come from separate cells of the sample (each K needs 2K cells of the patch size). auto (default): 8 (4 for the complete set), at most what the sample has room for; the tile size (tile = \"auto\") then shrinks, down to 32, until the sample has room for them; the choice recorded as diagnostics.colors_choice",
};

/// The `interior` parameter of both tile methods.
pub const INTERIOR_PARAM: ParamSpec = ParamSpec {
    name: "interior",
    kind: ParamKind::Choice(InteriorMode::NAMES),
    default: Default::Str("auto"),
    doc: "own: each tile keeps only a narrow band along its edges (1 to about overlap/2 + 1 px deep, cut by a DP seam along each side) from its edge-colour patches and takes everything inside the seams from a sample patch of its own, the best-matching of 16 random positions (on tiles aligned to a lattice, positions in phase with the tile's edge patches: a lattice translate away, so the texels continue across the seam), so tiles that share an edge colour share only that band (not in the paper); edges: every pixel from the four edge-colour patches (paper 001). auto (default): own for more than two colours on tiles not aligned to a lattice, and for Wang tiles aligned to one (in phase; not for a tileable output, whose wrap lines then stood out against the tile joints on bricks_gray); edges otherwise (two unaligned colours keep paper 001's pixels; aligned RW tiles keep their edge patches, whose in-phase interiors chopped bricks); the choice recorded as diagnostics.interior",
};

crate::choice! {
    /// Where a tile's inside comes from (the `interior` parameter).
    pub enum InteriorMode {
        /// [`InteriorMode::Own`] for more than two colours or for tiles aligned to a lattice (each method may decline the latter), else [`InteriorMode::Edges`].
        Auto = "auto",
        /// Every pixel from the edge-colour patches (paper 001).
        Edges = "edges",
        /// A patch of its own inside a closed seam (`tiles/interior.rs`).
        Own = "own",
    }
}

impl InteriorMode {
    /// Whether tiles of `colors` colours, aligned to a lattice or not, get interiors of their own.
    pub fn own(self, colors: u32, aligned: bool) -> bool {
        match self {
            InteriorMode::Own => true,
            InteriorMode::Edges => false,
            InteriorMode::Auto => colors > 2 || aligned,
        }
    }
}

/// The `tone` parameter of both tile methods.
pub const TONE_PARAM: ParamSpec = ParamSpec {
    name: "tone",
    kind: ParamKind::Choice(ToneMode::NAMES),
    default: Default::Str("auto"),
    doc: "on: each tile's own interior is brought to the tone of the edge band around it, smoothly (12 sectors around its seam compared, the difference faded out 12 px into the interior; each shifted pixel is one blend step with a sample pixel of the right colour, so placements, companions and source maps still render it), so that tiles do not show as steps of shade; off: interiors as cut; auto (default): on where the sample's colour variance lies largely in features a quarter of a tile and more across (at least 28.5 %, where the tile grid showed as a patchwork) on tiles not aligned to a lattice, off otherwise; needs interiors of their own (`interior`); the choice recorded as diagnostics.tone",
};

crate::choice! {
    /// Whether tiles' own interiors are toned to their bands (the `tone` parameter).
    pub enum ToneMode {
        /// [`ToneMode::On`] on unaligned tiles of a sample with large features ([`tone_choice`]).
        Auto = "auto",
        /// Always, where tiles have interiors of their own.
        On = "on",
        /// Never: interiors as cut.
        Off = "off",
    }
}

/// [`ToneMode::Auto`] tones where this share of the sample's colour variance or more is left in
/// the means of windows a quarter of a tile wide: the share at which `texsyn advise` saw unaligned
/// tiles show their grid as a patchwork (`synth::advice::LARGE_FEATURES_FROM`; mossy stone 0.39,
/// brown rock 0.51, rock albedo 0.34), where grass, gravel and pebbles, at most 0.27, do not.
pub const TONE_FROM: f64 = 0.285;

/// Whether a set of `tile`-pixel tiles with interiors of their own, aligned to a lattice or not,
/// is toned ([`super::tone`]), and the record of why.
pub fn tone_choice(mode: ToneMode, sample: &RgbImage, tile: u32, aligned: bool) -> (bool, serde_json::Value) {
    match mode {
        ToneMode::On => (true, serde_json::json!({ "tone": "on", "how": "on, as set" })),
        ToneMode::Off => (false, serde_json::json!({ "tone": "off", "how": "off, as set" })),
        ToneMode::Auto if aligned => (false, serde_json::json!({ "tone": "off", "how": "auto: off for tiles aligned to a lattice" })),
        ToneMode::Auto => {
            // A quarter of the tile (advise's ladder of sides holds 16 for the default 64).
            let side = (tile as usize / 4).min(sample.width().min(sample.height()) as usize / 4).max(1);
            let share = sample.large_feature_shares(&[side])[0].1;
            let on = share >= TONE_FROM;
            let how = format!(
                "auto: {} ({:.1} % of the sample's colour variance in features {side} px and more across, {} {:.1} %)",
                if on { "on" } else { "off" },
                100.0 * share,
                if on { "at least" } else { "under" },
                100.0 * TONE_FROM
            );
            (on, serde_json::json!({ "tone": if on { "on" } else { "off" }, "large_feature_share": share, "window": side, "how": how }))
        }
    }
}

/// The most colours `colors = "auto"` picks for a set whose interiors are toned ([`tone_choice`]):
/// toning costs time per tile, and a set has `K³` (minimal) tiles. Measured on weathered wood at
/// 2048² (issue #30): with 8 colours (512 tiles) RW tiles took 0.083 s and Wang tiles 0.079 s,
/// 7.9 and 9.2 times faster than quilting (0.63 s), below the 10; with 6 (216 tiles) 0.034
/// and 0.051 s, while the fills' repetition stayed the same or fell (RW 0.096 to 0.074, Wang 0.176
/// to 0.172; quilting's 0.31: a sample with large features repeats them whatever fills it).
pub const TONED_COLORS: u32 = 6;

/// `colors = "auto"` (`choice` is its record) capped at [`TONED_COLORS`] for a `toned` set.
pub fn cap_toned_colors(k: u32, choice: Option<serde_json::Value>, toned: bool) -> (u32, Option<serde_json::Value>) {
    match choice {
        Some(_) if toned && k > TONED_COLORS => (
            TONED_COLORS,
            Some(serde_json::json!({
                "colors": TONED_COLORS,
                "how": format!("auto: {TONED_COLORS}; {k} would fit, but the interiors are toned (tone) and {TONED_COLORS} keep toning a fraction of the fill's time"),
            })),
        ),
        choice => (k, choice),
    }
}

/// The refusal of `tone = "on"` with `interior = "edges"`: nothing to tone.
pub fn check_tone(tone: ToneMode, interior: InteriorMode) -> Option<crate::synth::params::ParamError> {
    (tone == ToneMode::On && interior == InteriorMode::Edges).then(|| {
        crate::synth::params::ParamError::new(
            "tone",
            "tone = \"on\" brings tiles' own interiors to the tone of their bands, and interior = \"edges\" gives them none; use interior = \"own\" or \"auto\", or tone = \"off\"",
        )
    })
}

/// The refusal of `interior = "own"` when a tile of `tile` pixels with `overlap` has no room for
/// its ring or a `sample`-sized sample none for its patch.
pub fn no_interior(tile: i32, overlap: i32, sample: (u32, u32)) -> String {
    format!(
        "interior = \"own\" needs a tile with room for a seam ring of about overlap/2 + 1 = {} px inside each side and a core inside it, and a sample as large as that core plus the ring (tile {tile}, overlap {overlap}, {}x{} sample); use a larger tile, or interior = \"edges\"",
        overlap / 2 + 1,
        sample.0,
        sample.1
    )
}

/// `colors = "auto"`.
pub const AUTO_COLORS_WORD: &str = "auto";
/// The most colours `colors = "auto"` picks: with 8, two tiles a tile apart share a patch about
/// once in 8 (a fill's autocorrelation at the tile period about 1/8, near an unstructured
/// sample's), for a set of 512 minimal tiles, still built in a fraction of a second.
pub const AUTO_COLORS: u32 = 8;
/// The `colors` parameter's upper bound (a complete set of 16 colours is 65536 tiles).
pub const MAX_COLORS: u32 = 16;

/// The algorithm version of a tile method's pixels for these (resolved) parameters
/// ([`crate::synth::method::Method::algorithm_version_of`]). Version 2 (issue #30): tiles with
/// interiors of their own pick their patches away from those earlier tiles took
/// ([`super::interior::CROWDING`]), and sets of more than two colours split their spread edge
/// patches between the classes so that the bands average to the sample's mean
/// ([`super::interior::balance_bands`]). Version 3 (issue #30): tiles with interiors of their own
/// also pick their patches so that the interiors, averaged over the set, carry no shading of the
/// sample's ([`super::interior::SHADING`]). Two colours without an interior of their own make the
/// same pixels as before: version 1, so that their records still verify and keep their content
/// keys; `interior = "edges"` never has interiors of its own, so it stays at version 2.
/// `colors = "auto"` may resolve to more, and `interior = "auto"` then to interiors of their own,
/// so those are version 3. Version 4 (issue #30): tiles aligned to a lattice take interiors of
/// their own in phase with it ([`super::interior::Ring::draw_in_phase`]), and `interior = "auto"`
/// gives them such interiors whatever the colours: every job that may be aligned (`align` other
/// than `"none"`: whether `"auto"` aligns depends on the sample) and may have interiors of its own
/// (`interior` other than `"edges"`) is version 4. Version 5 (issue #30), RW tiles only (`rw`):
/// an aligned two-colour set's patches are placed apart ([`super::align::Alignment::place_apart`];
/// the two "\" patches on a brick wall were one patch drawn twice), whatever the interior: every
/// RW job that may be aligned is version 5 (`colors = "auto"` may resolve to two); Wang tiles place
/// theirs as before. Version 6 for RW tiles, 5 for Wang tiles (issue #30): interiors of their
/// own may be toned to their bands ([`super::tone`]): every job that may have such interiors
/// (`interior = "own"`, or `"auto"` with more than two colours or a lattice possible) and does not
/// set `tone = "off"` (whether `"auto"` tones depends on the sample).
pub fn algorithm_version_of(p: &crate::synth::params::Params, rw: bool) -> u32 {
    let two = matches!(colors_param(p), Ok(Some(2)));
    let interior = p.choice::<InteriorMode>("interior");
    let own = matches!(interior, Ok(InteriorMode::Own));
    let edges = matches!(interior, Ok(InteriorMode::Edges));
    let may_align = !matches!(p.choice::<super::align::Align>("align"), Ok(super::align::Align::None));
    let may_have_interiors = own || (!edges && (!two || may_align));
    let may_tone = may_have_interiors && !matches!(p.choice::<ToneMode>("tone"), Ok(ToneMode::Off));
    if may_tone {
        if rw { ALGORITHM_VERSION } else { WANG_ALGORITHM_VERSION }
    } else if rw && may_align {
        5
    } else if may_align && !edges {
        4
    } else if two && !own {
        1
    } else if edges {
        2
    } else {
        3
    }
}

/// The tile methods' newest algorithm version ([`algorithm_version_of`]): RW tiles'.
pub const ALGORITHM_VERSION: u32 = 6;

/// Wang tiles' newest algorithm version ([`algorithm_version_of`]).
pub const WANG_ALGORITHM_VERSION: u32 = 5;

/// The `colors` parameter: `Some(K)`, or `None` for `"auto"`.
pub fn colors_param(p: &crate::synth::params::Params) -> Result<Option<u32>, crate::synth::error::SynthError> {
    p.int_or_word("colors")?
        .map(|k| u32::try_from(k).map_err(|_| crate::synth::error::SynthError::param("colors", format!("{k} is not a number of colours"))))
        .transpose()
}

/// How many disjoint `side × side` cells of a grid the sample holds.
pub fn cells(sample: (u32, u32), side: u32) -> u32 {
    (sample.0 / side.max(1)) * (sample.1 / side.max(1))
}

/// The most colours a `sample` has room for with patches of `side` pixels: `K` needs `2K` separate
/// cells ([`spread`]). Two colours always fit: paper 001's patches are drawn anywhere, overlapping
/// or not.
pub fn room(sample: (u32, u32), side: u32) -> u32 {
    (cells(sample, side) / 2).clamp(2, MAX_COLORS)
}

/// What `colors = "auto"` aims at: [`AUTO_COLORS`] for the minimal rule; the complete rule's
/// `K⁴` tiles stop at 4 (256 tiles). Not the output size: a keyed fill's smaller output stays
/// exactly a crop of a larger one with the same seed (and `texsyn tiles render` of an export
/// reproduces any size), which a size-dependent set would break.
pub fn wanted_colors(rule: super::wang::TileSet) -> u32 {
    match rule {
        super::wang::TileSet::Minimal => AUTO_COLORS,
        super::wang::TileSet::Complete => AUTO_COLORS.min(4),
    }
}

/// The number of colours of a job: `given`, or for `auto` [`wanted_colors`] within the room the
/// sample has for patches of `side` pixels; with the `diagnostics.colors_choice` record for `auto`.
pub fn resolve_colors(given: Option<u32>, rule: super::wang::TileSet, sample: (u32, u32), side: u32) -> (u32, Option<serde_json::Value>) {
    match given {
        Some(k) => (k, None),
        None => {
            let (want, fits) = (wanted_colors(rule), room(sample, side));
            let k = want.min(fits);
            let how = if k < want {
                format!(
                    "auto: {k}; {want} wanted, but the {}x{} sample has room for {fits} ({side}-pixel patches, 2 per colour)",
                    sample.0, sample.1
                )
            } else {
                format!("auto: {k}, the most auto picks for a {} set", rule.name())
            };
            (k, Some(serde_json::json!({ "colors": k, "how": how })))
        }
    }
}

/// The check of `colors` against the room the sample has: `side` is the patch side of the tile
/// size `tile_words` names (for `tile = "auto"` its smallest, [`super::align::AUTO_MIN_TILE`]).
pub fn check_colors(colors: Option<u32>, sample: (u32, u32), side: u32, tile_words: &str) -> Option<crate::synth::params::ParamError> {
    let k = colors?;
    let fits = room(sample, side);
    (k > fits).then(|| {
        crate::synth::params::ParamError::new(
            "colors",
            format!(
                "colors {k} needs {} separate {side}x{side} patches of the sample ({tile_words}); the {}x{} sample holds {}: use colors at most {fits}, or a smaller tile",
                2 * k,
                sample.0,
                sample.1,
                cells(sample, side)
            ),
        )
    })
}

/// An upper bound of the bytes a tile set of more than two colours adds to a job's peak memory
/// (16 B per tile pixel: raster, labels, sources, tone blends): the largest over the tile `sizes` the job may
/// use (those whose patch fits in the sample and, for `K` given, has room for it), with `K` given
/// or as `colors = "auto"` would choose for that size; 0 for two colours,
/// which the methods' measured estimates already hold. `patch(t)` is a size-`t` tile's patch side,
/// `raster(t)` its pixels.
pub fn tile_set_bytes(
    colors: Option<u32>,
    sample: (u32, u32),
    sizes: &[i64],
    patch: impl Fn(i64) -> i64,
    raster: impl Fn(i64) -> i64,
    rule: super::wang::TileSet,
) -> u64 {
    let fits = |t: &i64| patch(*t) >= 1 && patch(*t) <= i64::from(sample.0.min(sample.1));
    sizes
        .iter()
        .filter(|t| fits(t))
        .map(|&t| {
            let space = room(sample, patch(t) as u32);
            let k = colors.map_or_else(|| wanted_colors(rule).min(space), |k| if k <= space { k } else { 2 });
            if k <= 2 { 0 } else { rule.with_colors(k as u8).len() as u64 * raster(t) as u64 * 16 }
        })
        .max()
        .unwrap_or(0)
}

/// `n` corners of `side × side` patches in separate cells of the sample (`K ≥ 3`): the sample is
/// cut into a grid of cells at least `side` wide, `n` cells are drawn without replacement from `st`
/// (a partial Fisher–Yates shuffle: one `below` each) and each patch is placed in its cell at a
/// random offset (two draws), so the patches never overlap and come from all over the sample.
/// Needs `cells(sample, side) ≥ n`.
pub fn spread(st: &mut Stream, sample: (u32, u32), side: u32, n: usize) -> Vec<(u32, u32)> {
    let (cols, rows) = (sample.0 / side, sample.1 / side);
    let total = (cols * rows) as usize;
    assert!(total >= n, "{n} patches of {side} pixels do not fit in {sample:?}");
    let (cw, ch) = (sample.0 / cols, sample.1 / rows);
    let mut order: Vec<usize> = (0..total).collect();
    (0..n)
        .map(|i| {
            let j = i + st.below_usize(total - i);
            order.swap(i, j);
            let (col, row) = ((order[i] % cols as usize) as u32, (order[i] / cols as usize) as u32);
            let x = col * cw + st.below(u64::from(cw - side + 1)) as u32;
            let y = row * ch + st.below(u64::from(ch - side + 1)) as u32;
            (x, y)
        })
        .collect()
}

/// What the tests of both tile methods check of a wrapping output, in one place.
#[cfg(test)]
pub(crate) mod testing {
    use super::{TileRenderer, Tiling};
    use crate::image::RgbImage;
    use crate::metrics::seams::{seam_visibility, wrap_visibility};
    use crate::synth::method::{Method, Request};
    use crate::synth::methods::tiles::wang::{EdgeSet, TileSet};
    use crate::synth::params::{ParamValue, Params, resolve};

    /// A bundled sample, `jobs/samples/{name}`.
    pub fn sample(name: &str) -> RgbImage {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/samples").join(name);
        crate::image::io::read_rgb8(&path, crate::image::io::DecodeLimits::default()).expect("a bundled sample").0
    }

    /// How crowded a tile set's own interiors are (issue #30's banding): the mean number of other
    /// tiles whose patch lies within 8 px each way of a tile's, over what uniform draws among
    /// `range` corners each way would give (about 1). Picked by ring cost alone, Wang tiles on
    /// grass_gray came to 1.71: one dark clump of the sample recurred at one place in many tiles.
    pub fn crowding(offsets: &[(i32, i32)], range: (u32, u32)) -> f64 {
        let n = offsets.len();
        let near: usize =
            offsets.iter().map(|a| offsets.iter().filter(|b| (a.0 - b.0).abs().max((a.1 - b.1).abs()) <= 8).count() - 1).sum();
        let uniform = (n - 1) as f64 * 17.0 * 17.0 / (f64::from(range.0) * f64::from(range.1));
        near as f64 / n as f64 / uniform
    }

    /// Issue #30's tile-grid lines, measured on a tile set: for each side of the tile and each
    /// depth `0 .. q1` in from it (a pixel counts for its nearest side, as
    /// [`super::super::interior::balance_bands`] counts it), the mean grey level over every tile's
    /// pixels there, less the sample's; returns the largest magnitude. Every tile of a fill shows
    /// one of its set's bands along each side, so a set whose bands are dark along a side draws a
    /// dark line along every tile row or column of the fill.
    pub fn band_deviation(
        sample: &RgbImage,
        rasters: &[&[u8]],
        side: usize,
        q1: i32,
        sides: impl Fn(i32, i32) -> Option<[(i32, i32); 4]>,
    ) -> f64 {
        let grey = |p: &[u8]| (f64::from(p[0]) + f64::from(p[1]) + f64::from(p[2])) / 3.0;
        let mean = sample.as_raw().chunks(3).map(grey).sum::<f64>() / f64::from(sample.width() * sample.height());
        let mut sums = vec![(0f64, 0usize); 4 * q1 as usize];
        for y in 0..side as i32 {
            for x in 0..side as i32 {
                let Some(c) = sides(x, y) else { continue };
                let (s, q) = (0..4).map(|s| (s, c[s].1)).min_by_key(|&(s, q)| (q, s)).unwrap();
                if (0..q1).contains(&q) {
                    let i = (y as usize * side + x as usize) * 3;
                    let slot = &mut sums[s * q1 as usize + q as usize];
                    for raster in rasters {
                        slot.0 += grey(&raster[i..i + 3]);
                        slot.1 += 1;
                    }
                }
            }
        }
        sums.iter().filter(|s| s.1 > 0).map(|s| (s.0 / s.1 as f64 - mean).abs()).fold(0.0, f64::max)
    }

    /// Issue #30's tile-periodic shading, measured on a tile set: the mean grey level over every
    /// tile's pixels at each raster position at least `depth` in from every side, and the plane
    /// fitted to it by least squares; returns how much that plane rises across those pixels' extent
    /// in `x` and in `y` (grey levels). Every tile of a fill has one of these rasters, so a plane
    /// that rises across the tile draws a step at every tile edge of the fill. On grass_gray, whose
    /// left quarter is darker, tiles whose patches were picked without regard to it rose by 6–9
    /// grey levels from left to right.
    pub fn interior_shading(rasters: &[&[u8]], side: usize, depth: i32, sides: impl Fn(i32, i32) -> Option<[(i32, i32); 4]>) -> (f64, f64) {
        let grey = |p: &[u8]| (f64::from(p[0]) + f64::from(p[1]) + f64::from(p[2])) / 3.0;
        let mut pts = Vec::new();
        for y in 0..side as i32 {
            for x in 0..side as i32 {
                let Some(c) = sides(x, y) else { continue };
                if c.iter().all(|pq| pq.1 >= depth) {
                    let i = (y as usize * side + x as usize) * 3;
                    let v = rasters.iter().map(|r| grey(&r[i..i + 3])).sum::<f64>() / rasters.len() as f64;
                    pts.push((f64::from(x), f64::from(y), v));
                }
            }
        }
        let n = pts.len() as f64;
        let (mx, my, mv) = pts.iter().fold((0.0, 0.0, 0.0), |a, p| (a.0 + p.0 / n, a.1 + p.1 / n, a.2 + p.2 / n));
        let (mut sxx, mut sxy, mut syy, mut sxv, mut syv) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for &(x, y, v) in &pts {
            let (dx, dy, dv) = (x - mx, y - my, v - mv);
            (sxx, sxy, syy, sxv, syv) = (sxx + dx * dx, sxy + dx * dy, syy + dy * dy, sxv + dx * dv, syv + dy * dv);
        }
        let det = sxx * syy - sxy * sxy;
        let (a, b) = ((sxv * syy - syv * sxy) / det, (syv * sxx - sxv * sxy) / det);
        let extent = |f: fn(&(f64, f64, f64)) -> f64| {
            let (lo, hi) = pts.iter().map(f).fold((f64::MAX, f64::MIN), |m, v| (m.0.min(v), m.1.max(v)));
            hi - lo + 1.0
        };
        (a * extent(|p| p.0), b * extent(|p| p.1))
    }

    /// A 256² sample of blotchy noise (4×4-pixel blocks of grey 88..168, from `seed`) whose top
    /// quarter is 30 grey levels darker, fading in over 16 rows, and whose left quarter is 20
    /// darker likewise: low-frequency shading as a photograph's light leaves it.
    pub fn shaded_noise(seed: u64) -> RgbImage {
        let mut st = crate::synth::rng::Stream::new(seed, "test/shaded_noise");
        let blocks: Vec<u8> = (0..64 * 64).map(|_| 88 + st.below(81) as u8).collect();
        let ramp = |v: u32| (f64::from(v).clamp(56.0, 72.0) - 72.0) / 16.0;
        RgbImage::from_fn(256, 256, |x, y| {
            let v = f64::from(blocks[(y / 4 * 64 + x / 4) as usize]) + 30.0 * ramp(y) + 20.0 * ramp(x);
            let v = v.round().clamp(0.0, 255.0) as u8;
            [v, v, v]
        })
    }

    /// The 2×2 tiling of `image`: what a user sees when the output is repeated.
    pub fn two_by_two(image: &RgbImage) -> RgbImage {
        let (w, h) = image.dimensions();
        RgbImage::from_fn(2 * w, 2 * h, |x, y| image.get(x % w, y % h))
    }

    /// Synthesises a wrapping `size` output, checks that its placement (whole and in strips)
    /// renders it exactly and that strips render the same pixels, and returns it with its
    /// `(wrap visibility, interior seam visibility)` and its tile size.
    pub fn wrapping(m: &dyn Method, params: &Params, sample: &RgbImage, size: (u32, u32), seed: u64) -> (RgbImage, f64, f64, u32) {
        let req = Request {
            sample,
            width: size.0,
            height: size.1,
            params,
            seed,
            placement: true,
            tileable: true,
            constraints: std::default::Default::default(),
        };
        m.tileable(params, sample.dimensions(), size).expect("a tileable size");
        let out = m.synthesize(&req).expect("synthesis");
        let placement = out.placement.as_ref().expect("the placement asked for");
        assert_eq!(placement.render_rgb8(sample), out.image, "{}: the placement renders the wrapping output", m.name());
        let strips = m.synthesize_strips(&req).expect("strips");
        let (mut pixels, mut sources) = (vec![0u8; (size.0 * size.1 * 3) as usize], vec![0u32; (size.0 * size.1) as usize]);
        for (y0, chunk) in (0..size.1).step_by(37).zip(pixels.chunks_mut(37 * 3 * size.0 as usize)) {
            (strips.render)(y0, chunk);
        }
        for (y0, chunk) in (0..size.1).step_by(37).zip(sources.chunks_mut(37 * size.0 as usize)) {
            (strips.sources.as_ref().expect("source rows asked for"))(y0, chunk);
        }
        assert_eq!(pixels, out.image.as_raw().to_vec(), "{}: strips render the wrapping output", m.name());
        assert_eq!(sources, placement.sources(), "{}: strips' sources are the placement's", m.name());
        let wrap = wrap_visibility(&out.image).expect("an image with texture");
        let interior = seam_visibility(&out.image, out.seams.as_ref().expect("tile seams")).unwrap_or(0.0);
        let tile = out.diagnostics["geometry"]["tile"].as_u64().expect("diagnostics.geometry.tile") as u32;
        (out.image, wrap, interior, tile)
    }

    /// The mean jump `|ΔR| + |ΔG| + |ΔB|` across column boundary `k` (between columns `k − 1` and
    /// `k mod W`, so `k = W` is the wrap) when `columns`, else across row boundary `k`.
    fn line_jump(img: &RgbImage, k: u32, columns: bool) -> f64 {
        let (w, h) = img.dimensions();
        let jump = |a: [u8; 3], b: [u8; 3]| (0..3).map(|c| (a[c] as i32 - b[c] as i32).unsigned_abs()).sum::<u32>() as f64;
        if columns {
            (0..h).map(|y| jump(img.get(k - 1, y), img.get(k % w, y))).sum::<f64>() / f64::from(h)
        } else {
            (0..w).map(|x| jump(img.get(x, k - 1), img.get(x, k % h))).sum::<f64>() / f64::from(w)
        }
    }

    /// The wrap lines against the interior lines in the same place of the tile grid, one
    /// orientation at a time: `[(wrap column, mean of the columns at multiples of the tile),
    /// (wrap row, mean of the rows likewise)]` (mean jumps). On a torus tiling the wrap lines are
    /// tile edges like those, so they are compared with them and not with the seam bands.
    pub fn wrap_and_same_place_lines(img: &RgbImage, tile: u32) -> [(f64, f64); 2] {
        let (w, h) = img.dimensions();
        let side = |n: u32, columns: bool| {
            let inner: Vec<f64> = (1..n / tile).map(|i| line_jump(img, i * tile, columns)).collect();
            (line_jump(img, n, columns), inner.iter().sum::<f64>() / inner.len().max(1) as f64)
        };
        [side(w, true), side(h, false)]
    }

    /// The exact form of "a 2×2 tiling shows no seam": a wrapping `period` fill rendered over
    /// twice its size is its 2×2 tiling, so the wrap lines are ordinary tile edges of one tiling
    /// (whose colours the caller checks). Returns that tiling.
    pub fn repeat_is_one_tiling(tiles: &impl TileRenderer, period: (u32, u32), seed: u64) -> Tiling {
        let render = |tiling: &Tiling, (w, h): (u32, u32)| {
            let mut image = RgbImage::new(w, h);
            tiles.render_rows(tiling, w, 0, image.as_raw_mut());
            image
        };
        let once = render(&tiles.tile_torus(period, period, seed), period);
        let twice = tiles.tile_torus(period, (2 * period.0, 2 * period.1), seed);
        assert_eq!(render(&twice, (2 * period.0, 2 * period.1)), two_by_two(&once), "the 2×2 tiling of a {period:?} wrap");
        twice
    }

    fn params(m: &dyn Method, given: &[(&str, ParamValue)]) -> Params {
        let given: Vec<(String, ParamValue)> = given.iter().map(|(k, v)| (k.to_string(), v.clone())).collect();
        resolve(m.params(), &given).unwrap()
    }

    /// A wrapping output's wrap is no more visible than its interior tile edges, on real samples,
    /// with the defaults (K > 2 colours). The wrap is one column and one row, so it is compared
    /// with the interior lines in the same place of the tile grid (the columns and rows at
    /// multiples of the tile), one orientation at a time: the seam bands of `seam_visibility`
    /// average nine boundaries around each edge, and on bricks a horizontal line's jump depends on
    /// whether it runs along a mortar course (interior rows of one output measured 0.25 to 1.52
    /// of the image's mean jump), so a single wrap line against the bands scatters far (wang,
    /// bricks, complete, seed 4: wrap 0.785 against bands 0.341, yet its row is 1.145 against
    /// interior rows 0.67, 0.25, 1.52, and its column 0.246 against 0.21–0.25). Measured with
    /// the defaults over these samples, sets and seeds 1–5, both methods: a wrap line over the
    /// mean of its orientation's interior lines 0.32–1.52 per output, 0.73–1.17 over five seeds.
    /// A wrap that did not match would jump like the ordinary fill's, printed for comparison.
    pub fn wraps_as_seamlessly_as_the_tiles_join(m: &dyn Method) {
        for (name, size) in [("bricks_gray.png", (384, 256)), ("pebbles_beige.png", (256, 320))] {
            let s = sample(name);
            for set in ["minimal", "complete"] {
                let p = params(m, &[("tile_set", ParamValue::Str(set.into()))]);
                let mut sums = [(0.0, 0.0); 2];
                for seed in 1..6 {
                    let (image, wrap, interior, tile) = wrapping(m, &p, &s, size, seed);
                    let lines = wrap_and_same_place_lines(&image, tile);
                    let req = Request {
                        sample: &s,
                        width: size.0,
                        height: size.1,
                        params: &p,
                        seed,
                        placement: false,
                        tileable: false,
                        constraints: std::default::Default::default(),
                    };
                    let ordinary = wrap_and_same_place_lines(&m.synthesize(&req).unwrap().image, tile);
                    eprintln!(
                        "{} {name} {set} seed {seed} tile {tile}: wrap column {:.2} vs same-place columns {:.2}, wrap row {:.2} vs rows \
                         {:.2} (ordinary fill's wrap column {:.2}, row {:.2}); wrap visibility {wrap:.3}, seam bands {interior:.3}",
                        m.name(),
                        lines[0].0,
                        lines[0].1,
                        lines[1].0,
                        lines[1].1,
                        ordinary[0].0,
                        ordinary[1].0
                    );
                    for (i, (w, inner)) in lines.into_iter().enumerate() {
                        assert!(w <= 1.6 * inner, "{name} {set} seed {seed}: wrap line {w:.2} > 1.6 × same-place lines {inner:.2} ({i})");
                        sums[i] = (sums[i].0 + w, sums[i].1 + inner);
                    }
                }
                for (w, inner) in sums {
                    assert!(w <= 1.25 * inner, "{name} {set}: over five seeds wrap lines {w:.2} > 1.25 × same-place lines {inner:.2}");
                }
            }
        }
    }

    /// One tile wraps with itself, and a placement asked of an ordinary fill only adds it.
    pub fn one_tile_wraps_and_ordinary_fills_do_not_change(m: &dyn Method) {
        let s = sample("bricks_gray.png");
        let p = params(m, &[("tile", ParamValue::Int(48))]);
        wrapping(m, &p, &s, (48, 48), 2);
        wrapping(m, &p, &s, (48, 192), 2);
        let plain = Request {
            sample: &s,
            width: 96,
            height: 96,
            params: &p,
            seed: 2,
            placement: false,
            tileable: false,
            constraints: std::default::Default::default(),
        };
        let without = m.synthesize(&plain).unwrap();
        let with = m.synthesize(&Request { placement: true, ..plain }).unwrap();
        assert!(without.placement.is_none() && without.diagnostics.get("wraps").is_none());
        assert_eq!(with.image, without.image);
        assert_eq!(with.placement.unwrap().render_rgb8(&s), without.image);
    }

    /// `tileable` (and `synthesize` asked to wrap anyway) refuse sizes below two tiles that are not
    /// one tile, naming the smallest that works, and the tile-set export; any size of two tiles or
    /// more wraps (fitted when it is not whole tiles), its placement and strips exact, the wrap
    /// as seamless as a whole-tile torus's tile edges, the fit recorded.
    pub fn refuses_what_cannot_wrap(m: &dyn Method) {
        let p = params(m, &[("tile", ParamValue::Int(64))]);
        assert_eq!(m.tileable(&p, (256, 256), (640, 128)), Ok(()));
        assert_eq!(m.tileable(&p, (256, 256), (700, 129)), Ok(()));
        let e = m.tileable(&p, (256, 256), (700, 100)).unwrap_err();
        assert!(e.contains("at least two tiles each way") && e.contains("128 pixels a side for tile 64; 700x128 would work"), "{e}");
        let s = sample("bricks_gray.png");
        let req = Request {
            sample: &s,
            width: 700,
            height: 100,
            params: &p,
            seed: 1,
            placement: false,
            tileable: true,
            constraints: std::default::Default::default(),
        };
        assert!(m.synthesize(&req).unwrap_err().to_string().contains("700x128 would work"));
        let export = params(m, &[("export_tiles", ParamValue::Bool(true))]);
        assert!(m.tileable(&export, (256, 256), (128, 128)).unwrap_err().contains("export_tiles"));
        // `tile = "auto"` (the default) keeps the sizes that divide the output: 700x100 wraps
        // with 50 or 100, chosen with the sample's lattice and recorded, and not fitted.
        let auto = params(m, &[]);
        assert_eq!(m.tileable(&auto, (256, 256), (700, 100)), Ok(()));
        let req = Request {
            sample: &s,
            width: 700,
            height: 100,
            params: &auto,
            seed: 1,
            placement: false,
            tileable: true,
            constraints: std::default::Default::default(),
        };
        let out = m.synthesize(&req).unwrap();
        let t = out.diagnostics["tile_choice"]["tile"].as_u64().unwrap();
        assert!(700 % t == 0 && 100 % t == 0, "{}", out.diagnostics["tile_choice"]);
        assert!(out.diagnostics.get("tileable_fit").is_none(), "{}", out.diagnostics);
        // No size divides 701x433: fitted, with exact placement and strips, recorded.
        assert_eq!(m.tileable(&auto, (256, 256), (701, 433)), Ok(()));
        let pebbles = sample("pebbles_beige.png");
        let (image, wrap, interior, tile) = wrapping(m, &auto, &pebbles, (701, 433), 3);
        assert_eq!(image.dimensions(), (701, 433));
        eprintln!("{} 701x433 fitted, tile {tile}: wrap visibility {wrap:.3}, seam bands {interior:.3}", m.name());
        assert!(wrap <= 1.5 * interior, "{}: wrap {wrap} vs seams {interior}", m.name());
        let out = m.synthesize(&Request { width: 701, height: 433, sample: &pebbles, seed: 3, ..req }).unwrap();
        let fit = &out.diagnostics["tileable_fit"];
        assert!(fit["x"]["torus"].as_u64().unwrap().is_multiple_of(u64::from(tile)), "{fit}");
        assert!(out.diagnostics["tile_choice"]["how"].as_str().unwrap().contains("fitting"), "{}", out.diagnostics["tile_choice"]);
        // A given size below two tiles: refused naming the smallest that works, also by the fill.
        let e = m.tileable(&auto, (256, 256), (47, 433)).unwrap_err();
        assert!(e.contains("tile = \"auto\"") && e.contains("64x433 would work"), "{e}");
        let req = Request { width: 47, height: 433, ..req };
        let e = m.synthesize(&req).unwrap_err().to_string();
        assert!(e.contains("at least two tiles each way") && e.contains("tile = \"auto\"'s choice"), "{e}");
    }

    /// What `colors` promises, for a method whose parameters `params` resolves: the default fill of
    /// a stochastic sample (grass_gray, 512²) repeats much less than two colours' (issue #30's
    /// measure, [`crate::metrics::repetition`]) and at most twice as much as quilting's; K = 5
    /// fills (plain and wrapping) do not depend on the thread count; `colors = 1` and more colours
    /// than the sample has room for are refused naming `colors` and the largest that fits.
    pub fn colors_repeat_less_and_are_checked(m: &dyn Method, params: impl Fn(&[(&str, ParamValue)]) -> Params) {
        use crate::metrics::repetition::max_autocorrelation;
        let grass = sample("grass_gray.png");
        let fill = |p: &Params, tileable: bool| {
            let req = Request {
                sample: &grass,
                width: 512,
                height: 512,
                params: p,
                seed: 5,
                placement: false,
                tileable,
                constraints: std::default::Default::default(),
            };
            m.synthesize(&req).expect("synthesis")
        };
        let default = fill(&params(&[]), false);
        assert_eq!(default.diagnostics["colors_choice"]["colors"], 8, "{}", default.diagnostics["colors_choice"]);
        let two = fill(&params(&[("colors", ParamValue::Int(2))]), false);
        let quilting = crate::synth::methods::find("quilting").expect("quilting");
        let qp = resolve(quilting.params(), &[]).unwrap();
        let q = quilting
            .synthesize(&Request {
                sample: &grass,
                width: 512,
                height: 512,
                params: &qp,
                seed: 5,
                placement: false,
                tileable: false,
                constraints: std::default::Default::default(),
            })
            .unwrap();
        let [d, t, q] = [&default.image, &two.image, &q.image].map(|i| max_autocorrelation(i).unwrap());
        assert!(d < 0.5 * t, "{}: default {d:.3}, two colours {t:.3}", m.name());
        assert!(d <= 2.0 * q, "{}: default {d:.3}, quilting {q:.3}", m.name());
        let five = params(&[("colors", ParamValue::Int(5)), ("tile", ParamValue::Int(32))]);
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        for tileable in [false, true] {
            let many = fill(&five, tileable);
            let single = one.install(|| fill(&five, tileable));
            assert_eq!(many.image, single.image, "{} tileable {tileable}", m.name());
            assert_eq!(many.diagnostics, single.diagnostics);
        }
        let refused = |given: &[(&str, ParamValue)]| -> String {
            let g: Vec<(String, ParamValue)> = given.iter().map(|(k, v)| (k.to_string(), v.clone())).collect();
            match resolve(m.params(), &g) {
                Err(e) => e.iter().map(|e| format!("{}: {}", e.key, e.message)).collect::<Vec<_>>().join("; "),
                Ok(p) => {
                    m.check(&p, (256, 256), (512, 512)).iter().map(|e| format!("{}: {}", e.key, e.message)).collect::<Vec<_>>().join("; ")
                }
            }
        };
        let e = refused(&[("colors", ParamValue::Int(1))]);
        assert!(e.contains("colors"), "{e}");
        let e = refused(&[("colors", ParamValue::Int(16)), ("tile", ParamValue::Int(128))]);
        assert!(e.starts_with("colors: colors 16 needs 32 separate") && e.contains("use colors at most"), "{e}");
    }

    /// `interior`: on grass at 512², eight colours with insides of their own repeat less than with
    /// the edge patches' tiles (whose tiling and edge patches are the same draws), the placement
    /// renders the fill exactly, `auto` is `own` for eight colours and `edges` for two (no
    /// `diagnostics.interior`), thread counts do not matter, and a sample with no room for a
    /// tile's own patch is refused naming `interior`. Returns the fills (own, edges) and their
    /// tile size for the method's own check of the tile edges.
    pub fn own_interiors_repeat_less(m: &dyn Method, params: impl Fn(&[(&str, ParamValue)]) -> Params) -> (RgbImage, RgbImage, u32) {
        use crate::metrics::repetition::max_autocorrelation;
        let grass = sample("grass_gray.png");
        let fill = |p: &Params, placement: bool| {
            let req = Request {
                sample: &grass,
                width: 512,
                height: 512,
                params: p,
                seed: 5,
                placement,
                tileable: false,
                constraints: std::default::Default::default(),
            };
            m.synthesize(&req).expect("synthesis")
        };
        let word = |v: &str| ParamValue::Str(v.into());
        let own_p = params(&[("interior", word("own")), ("colors", ParamValue::Int(8))]);
        let own = fill(&own_p, true);
        let edges = fill(&params(&[("interior", word("edges")), ("colors", ParamValue::Int(8))]), false);
        let [o, e] = [&own.image, &edges.image].map(|i| max_autocorrelation(i).unwrap());
        assert!(o < 0.6 * e, "{}: own interiors {o:.3}, edge patches {e:.3}", m.name());
        let placement = own.placement.as_ref().expect("the placement asked for");
        assert_eq!(placement.render_rgb8(&grass), own.image, "{}: the placement renders the fill", m.name());
        assert_eq!(own.diagnostics["interior"]["interior"], "own", "{}", own.diagnostics);
        let auto = fill(&params(&[("colors", ParamValue::Int(8))]), false);
        assert_eq!(auto.image, own.image, "{}: auto is own for eight colours", m.name());
        let two = fill(&params(&[("colors", ParamValue::Int(2))]), false);
        let two_edges = fill(&params(&[("colors", ParamValue::Int(2)), ("interior", word("edges"))]), false);
        assert_eq!(two.image, two_edges.image, "{}: auto keeps two colours' pixels", m.name());
        assert!(two.diagnostics.get("interior").is_none(), "{}", two.diagnostics);
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        assert_eq!(one.install(|| fill(&own_p, true)).image, own.image, "{}: one thread", m.name());
        // A 64-px tile from a sample 40 px wide: no room for its own 62-px patch.
        let narrow = RgbImage::from_fn(40, 256, |x, y| grass.get(x, y));
        let small = params(&[
            ("interior", word("own")),
            ("tile", ParamValue::Int(64)),
            ("overlap", ParamValue::Int(2)),
            ("colors", ParamValue::Int(2)),
        ]);
        let e = m
            .synthesize(&Request {
                sample: &narrow,
                width: 128,
                height: 128,
                params: &small,
                seed: 1,
                placement: false,
                tileable: false,
                constraints: std::default::Default::default(),
            })
            .map(|_| ())
            .unwrap_err()
            .to_string();
        assert!(e.contains("interior") && e.contains("interior = \"edges\""), "{}: {e}", m.name());
        if m.name() == "rw-tiles" {
            // Refused before the run too.
            let checked = m.check(&small, (40, 256), (128, 128));
            assert!(checked.iter().any(|c| c.key == "interior"), "{checked:?}");
        }
        let tile = own.diagnostics["geometry"]["tile"].as_u64().expect("diagnostics.geometry.tile") as u32;
        (own.image, edges.image, tile)
    }

    /// [`repeat_is_one_tiling`] for sets built by `build` (from bricks_gray), at several periods,
    /// with two colours and with three.
    pub fn repeats_are_single_tilings<T: TileRenderer>(build: impl Fn(&RgbImage, EdgeSet) -> T) {
        let s = sample("bricks_gray.png");
        for set in [TileSet::Minimal.with_colors(2), TileSet::Complete.with_colors(2), TileSet::Minimal.with_colors(3)] {
            let tiles = build(&s, set);
            for (period, seed) in [((384, 256), 1), ((64, 64), 2), ((64, 320), 3), ((512, 128), 4)] {
                let twice = repeat_is_one_tiling(&tiles, period, seed);
                assert_eq!(twice.violations(set), 0, "{set:?} {period:?}");
            }
        }
    }
}

/// What both tile methods record of how a fill was made beyond its tiles: whether and how it
/// wraps, and what each `auto` chose. Each entry only where it applies (a `tile_choice` only for
/// `tile = "auto"`…), so that the records of jobs without it stay as they were.
pub struct ChoiceRecords {
    pub wraps: bool,
    pub tileable_fit: Option<serde_json::Value>,
    pub align_choice: serde_json::Value,
    pub align: Option<serde_json::Value>,
    pub tile_choice: Option<serde_json::Value>,
    pub colors_choice: Option<serde_json::Value>,
    pub interior: Option<serde_json::Value>,
    /// `diagnostics.tone` (only with interiors of their own) and how many pixels toning changed.
    pub tone: Option<(serde_json::Value, usize)>,
}

impl ChoiceRecords {
    pub fn add_to(self, diagnostics: &mut serde_json::Value) {
        if self.wraps {
            diagnostics["wraps"] = serde_json::Value::Bool(true);
        }
        diagnostics["align_choice"] = self.align_choice;
        let optional = [
            ("tileable_fit", self.tileable_fit),
            ("align", self.align),
            ("tile_choice", self.tile_choice),
            ("colors_choice", self.colors_choice),
            ("interior", self.interior),
        ];
        for (key, value) in optional {
            if let Some(v) = value {
                diagnostics[key] = v;
            }
        }
        if let Some((mut record, toned)) = self.tone {
            record["toned_pixels"] = serde_json::json!(toned);
            diagnostics["tone"] = record;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn euclidean_error_is_the_fixed_point_square_root() {
        let (a, b) = ([10, 20, 30], [13, 24, 30]);
        assert_eq!(PixelError::Squared.eval(a, b), 25);
        assert_eq!(PixelError::Euclidean.eval(a, b), 5 * 1024);
    }

    #[test]
    fn candidates_prefer_representative_then_cheap_then_early() {
        assert_eq!(pick_candidate(&[5, 3, 3, 9], &[true, false, true, true]), 2);
        assert_eq!(pick_candidate(&[5, 3, 3], &[false, false, false]), 1);
        let flat = RgbImage::from_fn(8, 8, |x, _| if x < 4 { [0, 0, 0] } else { [200, 200, 200] });
        assert!(representative(&flat, &[(2, 0)], 4));
        assert!(!representative(&flat, &[(0, 0)], 4));
    }

    #[test]
    fn tileable_sizes_are_two_tiles_or_whole_tiles_and_the_refusals_say_what_would_work() {
        assert_eq!(tileable("wang-tiles", 64, false, (768, 128)), Ok(()));
        assert_eq!(tileable("wang-tiles", 64, false, (750, 790)), Ok(()));
        assert_eq!(tileable("wang-tiles", 64, false, (64, 129)), Ok(()));
        let e = tileable("wang-tiles", 64, false, (750, 100)).unwrap_err();
        assert_eq!(
            e,
            "tileable wang-tiles needs at least two tiles each way (or exactly one), 128 pixels a side for tile 64; 750x128 would work, or a smaller tile"
        );
        assert!(tileable("rw-tiles", 48, false, (20, 48)).unwrap_err().contains("96x48 would work"));
        assert!(tileable("rw-tiles", 48, true, (96, 48)).unwrap_err().contains("export_tiles"));
    }
}
