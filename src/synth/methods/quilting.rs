//! Efros–Freeman image quilting with the minimum-error boundary cut (docs/methods.md §6): the
//! baseline every paper we follow compares against.
//!
//! Blocks are laid in raster order at stride `block − overlap`. Each new block is chosen at random
//! among the sample positions whose overlap error is within `(1 + tolerance)` of the best, found by
//! an exhaustive exact search (`primitives::overlap_search`) or, for big samples, the
//! coarse-to-fine one (`search = "pyramid"`, `primitives::pyramid_search`), and pasted along the minimum-error
//! cut through the overlap (B3). The output is the top-left `width × height` of the quilt, so the
//! last row and column of blocks are cropped.

use super::{BlockSearch, Engine, inpaint, untwinned};
use crate::image::RgbImage;
use crate::synth::constraints::nth_allowed;
use crate::synth::error::SynthError;
use crate::synth::method::{Method, Request, Synthesis, Uses};
use crate::synth::params::{self, Choice, Default, MethodConfig, ParamError, ParamKind, ParamSpec, ParamValue, Params};
use crate::synth::primitives::block_grid::{BlockCuts, BlockGrid, OverlapRule, block_cuts, paste_with_cuts};
use crate::synth::primitives::canvas::Canvas;
use crate::synth::primitives::overlap::Rect;
use crate::synth::primitives::overlap_search::OverlapSearch;
use crate::synth::primitives::torus::TorusGrid;
use crate::synth::rng::Stream;
use rayon::prelude::*;

pub struct Quilting;

/// The default `block` of texture transfer (a `[guide]` without `source`, no `[inpaint]`): the
/// plain default 50 less a third, Efros and Freeman's step between passes, so that the three
/// passes are 33, 22 and 15. With 50, 33 and 22 the blocks were too large to follow a target's
/// light and dark: onto the bundled rings target (seeds 2, 5, 9) the output's luminance in 16-px
/// cells correlated 0.78–0.80 (pebbles), 0.89–0.91 (grass), 0.85–0.87 (cork) with it, and the
/// rings barely showed, where Embark's `transfer-style` reaches 0.93, 0.975, 0.98. With 33:
/// 0.91–0.93, 0.97, 0.96–0.97, and paper 003's gray KL against the sample 0.027–0.068, still
/// under Embark's 0.053–0.126. Patch sampling's default block (30) already follows as well.
pub const TRANSFER_BLOCK: i64 = 33;

const PARAMS: &[ParamSpec] = &[
    ParamSpec {
        name: "block",
        kind: ParamKind::Int { min: 3, max: 4096 },
        default: Default::Int(50),
        doc: "side of the square blocks, in pixels (at most the sample's smaller side); 33 by default for a texture transfer (a [guide] without source, no [inpaint])",
    },
    ParamSpec {
        name: "overlap",
        kind: ParamKind::Int { min: 1, max: 2048 },
        default: Default::Derived {
            rule: "round(block / 6)",
            compute: |p| Some(ParamValue::Int(super::default_overlap(p.int("block").ok()?))),
        },
        doc: "width of the overlap between neighbouring blocks (at most block / 2)",
    },
    ParamSpec {
        name: "tolerance",
        kind: ParamKind::Float { min: 0.0, max: 100.0 },
        default: Default::Float(0.1),
        doc: "candidates within (1 + tolerance) x the best overlap error; one is picked at random",
    },
    ParamSpec {
        name: "search",
        kind: ParamKind::Choice(Engine::NAMES),
        default: Default::Str("auto"),
        doc: "how blocks are searched: fft (FFT correlation + exact re-check) or direct sums, the exact search (same pixels); pyramid: coarse-to-fine for big samples; auto: fft for samples of at most 512x512 pixels, pyramid above (recorded resolved)",
    },
    ParamSpec {
        name: "cut",
        kind: ParamKind::Choice(Cut::NAMES),
        default: Default::Str("dp"),
        doc: "dp: minimum-error boundary cut; none: paste the whole block over the overlap",
    },
    ParamSpec {
        name: "blend",
        kind: ParamKind::Choice(Blend::NAMES),
        default: Default::Str("none"),
        doc: "feather: linear blend across the overlap (Liang et al.) instead of a cut; needs cut = \"none\"",
    },
];

crate::choice! {
    /// How a block meets the output over its overlap (`cut`).
    pub enum Cut {
        /// The minimum-error boundary cut.
        Dp = "dp",
        /// No cut: the whole block is pasted over the overlap.
        None = "none",
    }
}

crate::choice! {
    /// Whether the overlap is blended instead of cut (`blend`).
    pub enum Blend {
        /// No blending: the cut (or the plain paste) decides.
        None = "none",
        /// Liang et al.'s linear blend across the overlap; needs [`Cut::None`].
        Feather = "feather",
    }
}

/// Image quilting's parameters, typed: one field per entry of its parameter table.
#[derive(Clone, Debug, PartialEq)]
pub struct QuiltingConfig {
    /// `block`: side of the square blocks, in pixels (3..=4096, at most the sample's smaller side).
    pub block: u32,
    /// `overlap`: width of the overlap between neighbouring blocks (1..=2048, at most block / 2);
    /// `None`: derived, `round(block / 6)`.
    pub overlap: Option<u32>,
    /// `tolerance`: candidates within `(1 + tolerance)` × the best overlap error (0..=100).
    pub tolerance: f64,
    /// `search`: the exact search (fft or direct, same pixels), the pyramid, or auto (by sample size).
    pub search: Engine,
    /// `cut`: the minimum-error boundary cut or none.
    pub cut: Cut,
    /// `blend`: feathering instead of a cut (with `cut = None`).
    pub blend: Blend,
}

impl std::default::Default for QuiltingConfig {
    fn default() -> QuiltingConfig {
        QuiltingConfig { block: 50, overlap: None, tolerance: 0.1, search: Engine::Auto, cut: Cut::Dp, blend: Blend::None }
    }
}

impl QuiltingConfig {
    /// The overlap: the given one, else the derived default `round(block / 6)`.
    pub fn overlap_or_derived(&self) -> u32 {
        self.overlap.unwrap_or_else(|| super::default_overlap(i64::from(self.block)) as u32)
    }

    /// How a block is pasted over its overlap: feathering wins over the cut setting.
    pub fn overlap_rule(&self) -> OverlapRule {
        match (self.blend, self.cut) {
            (Blend::Feather, _) => OverlapRule::Feather,
            (Blend::None, Cut::Dp) => OverlapRule::Cut,
            (Blend::None, Cut::None) => OverlapRule::Overwrite,
        }
    }
}

impl MethodConfig for QuiltingConfig {
    const METHOD: &'static str = "quilting";

    fn to_params(&self) -> Vec<(String, ParamValue)> {
        let mut v = vec![params::int("block", self.block)];
        v.extend(self.overlap.map(|o| params::int("overlap", o)));
        v.extend([
            params::float("tolerance", self.tolerance),
            params::word("search", self.search),
            params::word("cut", self.cut),
            params::word("blend", self.blend),
        ]);
        v
    }

    fn from_params(p: &Params) -> Result<QuiltingConfig, SynthError> {
        Ok(QuiltingConfig {
            block: p.uint("block")?,
            overlap: Some(p.uint("overlap")?),
            tolerance: p.float("tolerance")?,
            search: p.choice("search")?,
            cut: p.choice("cut")?,
            blend: p.choice("blend")?,
        })
    }
}

impl Method for Quilting {
    fn name(&self) -> &'static str {
        QuiltingConfig::METHOD
    }
    fn algorithm_version(&self) -> u32 {
        1
    }
    fn algorithm_version_of(&self, params: &Params, uses: Uses) -> u32 {
        // Version 3: inpainting prefers blocks that repeat little of what the hole already copied
        // (`inpaint::Reuse`, issue #28); version 9: the hole's blocks are made from its border
        // inwards (11 led by a luminance guide); version 5: a luminance guide is compared at a block's
        // scale (7 for syntheses, whose later passes follow the previous one through the target);
        // plain syntheses keep version 1 and their pixels (2 is version 1 with the pyramid).
        let base = if uses.luminance_guide {
            super::luminance_guide_version(uses)
        } else if uses.inpaint {
            super::INPAINT_VERSION
        } else {
            self.algorithm_version()
        };
        super::engine_version(params, "search", base)
    }
    fn summary(&self) -> &'static str {
        "Efros-Freeman image quilting: exact exhaustive block search, minimum-error boundary cut"
    }
    fn params(&self) -> &'static [ParamSpec] {
        PARAMS
    }

    fn check(&self, p: &Params, sample: (u32, u32), _output: (u32, u32)) -> Vec<ParamError> {
        let cfg: QuiltingConfig = match super::read_config(p) {
            Ok(c) => c,
            Err(e) => return e,
        };
        let mut errors = super::check_block_and_overlap(cfg.block, cfg.overlap_or_derived(), sample);
        if cfg.blend == Blend::Feather && cfg.cut != Cut::None {
            errors.push(ParamError::new("blend", "blend = \"feather\" replaces the boundary cut; also set cut = \"none\""));
        }
        errors
    }

    fn resolve_for_sample(&self, params: &mut Params, sample: (u32, u32)) {
        super::resolve_engine(params, "search", sample);
    }

    fn defaults_for(&self, uses: Uses) -> Vec<(String, ParamValue)> {
        if uses.luminance_guide && !uses.inpaint { vec![params::int("block", TRANSFER_BLOCK)] } else { Vec::new() }
    }

    fn peak_memory(&self, params: &Params, sample: (u32, u32), output: (u32, u32)) -> u64 {
        super::search_memory(memory_engine(params, sample), sample, output, memory_block(params))
    }

    fn thread_memory(&self, params: &Params, sample: (u32, u32)) -> u64 {
        super::search_thread_memory(memory_engine(params, sample), sample, memory_block(params))
    }

    fn synthesize(&self, req: &Request) -> Result<Synthesis, SynthError> {
        let cfg = QuiltingConfig::from_params(req.params)?;
        let (block, overlap, tolerance) = (cfg.block, cfg.overlap_or_derived(), cfg.tolerance);
        let rule = cfg.overlap_rule();
        let sample = req.sample;
        if block > sample.width() || block > sample.height() {
            return Err(SynthError::Failed(format!("block {block} does not fit in the {}x{} sample", sample.width(), sample.height())));
        }
        let allowed = allowed_positions(req, block)?;
        if let Some(guide) = req.constraints.guide
            && req.constraints.fill.is_none()
        {
            return self.synthesize_guided(req, &cfg, &guide.at_block_scale(cfg.block));
        }
        if let Some(region) = req.constraints.fill {
            if rule == OverlapRule::Feather {
                return Err(SynthError::param("blend", "inpainting cannot feather: a blend would change known pixels; use cut = \"dp\""));
            }
            let allowed = allowed.expect("a fill region always restricts the positions");
            let copyable = req.constraints.copyable().expect("a fill region always restricts the pixels");
            let mut search = BlockSearch::within(cfg.search, sample, block, Some(allowed.clone()));
            let how = inpaint::Fill {
                block,
                overlap,
                tolerance,
                rule,
                polish_rule: rule,
                allowed: &allowed,
                copyable: &copyable,
                engine: cfg.search,
                label: "quilt",
                polish_search: inpaint::polish_search(&search, block, overlap, &copyable).into(),
            };
            let mut synthesis = match req.constraints.guide {
                None => inpaint::fill(
                    req,
                    region,
                    &how,
                    &mut inpaint::pick_among_candidates(req, &mut search, tolerance, block, inpaint::Reuse::new(block, overlap), "quilt"),
                )?,
                Some(guide) => {
                    let guide = &guide.at_block_scale(block);
                    // The target guide read at any window's place: past the image's edge it
                    // wraps on a torus and goes on as its own edge otherwise (windows stay inside).
                    let (w, h) = region.dimensions();
                    if guide.target.dimensions() != (w, h) || guide.source.dimensions() != sample.dimensions() {
                        return Err(SynthError::Failed("the guides must have the image's and the sample's sizes".into()));
                    }
                    let target = guide.target_beyond(w + block, h + block, req.tileable);
                    let mut guided =
                        super::guide::GuidedSearch::new(sample, &guide.source, &target, block, guide.weight, Some(allowed.clone()));
                    let mut synthesis = inpaint::fill(
                        req,
                        region,
                        &how,
                        &mut inpaint::pick_guided(req, &mut guided, tolerance, block, inpaint::Reuse::new(block, overlap), "quilt"),
                    )?;
                    synthesis.diagnostics["guided"] = serde_json::json!({ "weight": guide.weight });
                    synthesis
                }
            };
            if let Some(level) = search.coarse_level() {
                synthesis.diagnostics["pyramid_level"] = serde_json::json!(level);
            }
            return Ok(synthesis);
        }
        if req.tileable {
            return self.synthesize_torus(req, &cfg, allowed);
        }
        let layout = BlockGrid::new(block, overlap, req.width, req.height);
        let (cw, ch) = layout.canvas();
        let mut canvas = Canvas::new(cw, ch, sample.dimensions(), req.placement);
        let first = first_block(req.seed, sample, block, allowed.as_deref());
        let mut search = BlockSearch::within(cfg.search, sample, block, allowed);
        let mut candidate_counts = Vec::with_capacity((layout.rows * layout.cols) as usize);

        // Raster order, but the blocks of one front are searched together: what each one reads
        // was pasted by earlier fronts (`BlockGrid::fronts`), and each pick has its own stream.
        // Each block's source, for the pyramid's hints: the natural continuations of its left and
        // upper neighbours (the exact search scores them with every other position).
        let mut sources: Vec<Option<(u32, u32)>> = vec![None; (layout.rows * layout.cols) as usize];
        let stride = layout.stride();
        for front in layout.fronts() {
            let searched: Vec<(u32, u32)> = front.iter().copied().filter(|&b| b != (0, 0)).collect();
            let queries: Vec<((u32, u32), Vec<Rect>)> =
                searched.iter().map(|&(bi, bj)| (layout.origin(bi, bj), layout.overlap_regions(bi, bj))).collect();
            let hints: Vec<Vec<(u32, u32)>> = searched
                .iter()
                .map(|&(bi, bj)| {
                    let left = (bj > 0).then(|| sources[(bi * layout.cols + bj - 1) as usize]).flatten().map(|(x, y)| (x + stride, y));
                    let up = (bi > 0).then(|| sources[((bi - 1) * layout.cols + bj) as usize]).flatten().map(|(x, y)| (x, y + stride));
                    left.into_iter().chain(up).collect()
                })
                .collect();
            let mut found = search.candidates_many_hinted(&canvas.image, &queries, &hints, tolerance).into_iter();
            let placed: Vec<((u32, u32), (u32, u32))> = front
                .iter()
                .map(|&(bi, bj)| {
                    let src = if bi == 0 && bj == 0 {
                        first
                    } else {
                        let c = found.next().expect("one candidate set per searched block");
                        candidate_counts.push(c.members.len());
                        // The blocks already placed around it: left, and the three above.
                        let (i, j, n) = (i64::from(bi), i64::from(bj), i64::from(layout.cols));
                        let neighbours: Vec<(u32, u32)> = [(i, j - 1), (i - 1, j - 1), (i - 1, j), (i - 1, j + 1)]
                            .into_iter()
                            .filter(|&(i, j)| i >= 0 && j >= 0 && j < n)
                            .filter_map(|(i, j)| sources[(i * n + j) as usize])
                            .collect();
                        let origin = layout.origin(bi, bj);
                        let members = untwinned(
                            req,
                            &mut search,
                            &canvas.image,
                            origin,
                            &layout.overlap_regions(bi, bj),
                            tolerance,
                            c.members,
                            &neighbours,
                            block,
                        );
                        pick(req.seed, bi, bj, &members)
                    };
                    ((bi, bj), src)
                })
                .collect();
            // The cuts read only the canvas under their own block, which no block of this front
            // touches: they are found together, then the blocks pasted in raster order.
            let image = &canvas.image;
            let cuts: Vec<BlockCuts> = placed
                .par_iter()
                .map(|&((bi, bj), src)| block_cuts(image, sample, src, layout.origin(bi, bj), block, overlap, bj > 0, bi > 0, rule))
                .collect();
            for &((bi, bj), src) in &placed {
                sources[(bi * layout.cols + bj) as usize] = Some(src);
            }
            for (&((bi, bj), src), cut) in placed.iter().zip(&cuts) {
                paste_with_cuts(&mut canvas, sample, src, layout.origin(bi, bj), block, overlap, bj > 0, bi > 0, rule, cut);
            }
        }
        let (image, placement) = canvas.into_top_left(req.width, req.height).finish();
        let seams = layout.seam_grid(req.width, req.height);
        let mut diagnostics = serde_json::json!({
            "blocks": { "cols": layout.cols, "rows": layout.rows },
            "mean_candidates": if candidate_counts.is_empty() { 0.0 } else {
                candidate_counts.iter().sum::<usize>() as f64 / candidate_counts.len() as f64
            },
        });
        if let Some(level) = search.coarse_level() {
            diagnostics["pyramid_level"] = serde_json::json!(level);
        }
        Ok(Synthesis { image, seams: Some(seams), diagnostics, phases: Vec::new(), extras: Vec::new(), placement })
    }

    fn honours_sample_mask(&self) -> bool {
        true
    }

    fn honours_inpaint(&self) -> bool {
        true
    }

    fn honours_guide(&self) -> bool {
        true
    }

    fn tileable(&self, p: &Params, sample: (u32, u32), output: (u32, u32)) -> Result<(), String> {
        let cfg = QuiltingConfig::from_params(p).map_err(|e| e.to_string())?;
        torus_of(&cfg, sample, output).map(|_| ())
    }
}

/// The first block's sample position, drawn uniformly (stream `quilt/first`).
/// With a sample mask, drawn uniformly among the positions it allows (`allowed`, row-major).
fn first_block(seed: u64, sample: &RgbImage, block: u32, allowed: Option<&[bool]>) -> (u32, u32) {
    let mut s = Stream::new(seed, "quilt/first");
    let nx = sample.width() - block + 1;
    if let Some(allowed) = allowed {
        let count = allowed.iter().filter(|&&a| a).count() as u64;
        return nth_allowed(allowed, nx, s.below(count)).expect("an allowed position");
    }
    let x = s.below(nx as u64) as u32;
    let y = s.below((sample.height() - block + 1) as u64) as u32;
    (x, y)
}

/// The block positions the request's sample mask (and, when inpainting, the pixels outside the
/// hole) allow, or `None` when every one may be copied; an error naming the block and the
/// largest one that fits when none is allowed.
fn allowed_positions(req: &Request, block: u32) -> Result<Option<Vec<bool>>, SynthError> {
    let Some(mask) = req.constraints.copyable() else { return Ok(None) };
    let allowed = mask.block_positions(block, block);
    if !allowed.contains(&true) {
        let what = if req.constraints.fill.is_some() { "the image outside the inpaint mask" } else { "the sample mask" };
        return Err(SynthError::param(
            "block",
            format!("{what} leaves no whole {block}x{block} block to copy; the largest block it allows is {}", mask.largest_block()),
        ));
    }
    Ok(Some(allowed))
}

/// Block `(bi, bj)`'s pick among its tolerance set (stream `quilt/pick/bi=…/bj=…`).
fn pick(seed: u64, bi: u32, bj: u32, members: &[(u32, u32, u64)]) -> (u32, u32) {
    let mut s = Stream::new(seed, &format!("quilt/pick/bi={bi}/bj={bj}"));
    let p = members[s.below_usize(members.len())];
    (p.0, p.1)
}

/// The blocks of one guided pass: the plain raster, or a torus when the output wraps.
enum Grid {
    Plain(BlockGrid),
    Torus(TorusGrid),
}

/// The torus a tileable output is made on, or why there is none.
fn torus_of(cfg: &QuiltingConfig, sample: (u32, u32), output: (u32, u32)) -> Result<TorusGrid, String> {
    TorusGrid::of_blocks("quilting", cfg.block, cfg.overlap_or_derived(), sample, output)
}

impl Quilting {
    /// Guided quilting (texture transfer): the same raster of blocks and cuts, each block chosen
    /// by its overlap error weighed against its guide error (`methods::guide`), one at a time;
    /// with several passes (Efros and Freeman's iteration), each pass's blocks a third smaller and
    /// held to the previous pass: through the target with luminance guides
    /// ([`crate::synth::constraints::Guide::after_pass`]), else matched over the whole block
    /// against it. The guide keeps its weight in every pass.
    /// Tileable, every pass is laid on its own torus (`synthesize_torus`'s sides and cuts) and
    /// the target guide wraps with it.
    fn synthesize_guided(
        &self,
        req: &Request,
        cfg: &QuiltingConfig,
        guide: &crate::synth::constraints::Guide,
    ) -> Result<Synthesis, SynthError> {
        let sample = req.sample;
        let (w, h) = (req.width, req.height);
        if guide.target.dimensions() != (w, h) || guide.source.dimensions() != sample.dimensions() {
            return Err(SynthError::Failed("the guides must have the output's and the sample's sizes".into()));
        }
        let rule = cfg.overlap_rule();
        let passes = guide.passes.max(1);
        let mut previous: Option<RgbImage> = None;
        let mut finished = None;
        let mut pass_diagnostics = Vec::new();
        let copyable = req.constraints.copyable();
        // The sample's and its guide's spectra, made in the first pass and shared by the later
        // ones (whose blocks are smaller): the same searches without transforming either again.
        let mut spectra: Option<(OverlapSearch, OverlapSearch)> = None;
        for pass in 0..passes {
            // Blocks a third smaller each pass, the overlap in proportion; never below 6 px.
            let shrink = (2.0f64 / 3.0).powi(pass as i32);
            let block = ((f64::from(cfg.block) * shrink).round() as u32).max(6).min(cfg.block);
            let overlap = ((f64::from(cfg.overlap_or_derived()) * shrink).round() as u32).clamp(1, block / 2);
            let weight = guide.weight;
            // Blocks only shrink, so a mask that left room for the first pass's leaves room here.
            let allowed = copyable.as_ref().map(|mask| mask.block_positions(block, block));
            let grid = if req.tileable {
                Grid::Torus(TorusGrid::of_blocks("quilting", block, overlap, sample.dimensions(), (w, h)).map_err(SynthError::Failed)?)
            } else {
                Grid::Plain(BlockGrid::new(block, overlap, w, h))
            };
            // The last blocks reach past the output: the target guide goes on there as its own
            // edge (those blocks are cropped, but still guided where they show), or wraps.
            let (tw, th) = match &grid {
                Grid::Plain(layout) => layout.canvas(),
                Grid::Torus(_) => (w + block, h + block),
            };
            // A luminance guide's later passes follow the previous pass through the target; a
            // given source's match it pixel by pixel over the whole block (`Guide::passes`).
            let after = previous.as_ref().filter(|_| guide.luminance).map(|prev| guide.after_pass(prev, sample, cfg.block));
            let whole_block = previous.is_some() && after.is_none();
            let target = after.as_ref().unwrap_or(guide).target_beyond(tw, th, req.tileable);
            let (texture, by_guide) = match &spectra {
                Some((t, g)) => (t.for_block(block, block), g.for_block(block, block)),
                None => (OverlapSearch::new(sample, block, block), OverlapSearch::new(&guide.source, block, block)),
            };
            if spectra.is_none() {
                spectra = Some((texture.for_block(block, block), by_guide.for_block(block, block)));
            }
            let mut search = super::guide::GuidedSearch::of(texture, by_guide, &target, block, weight, allowed);
            let (cw, ch) = match &grid {
                Grid::Plain(layout) => layout.canvas(),
                Grid::Torus(t) => t.size(),
            };
            let mut canvas = Canvas::new(cw, ch, sample.dimensions(), req.placement);
            if let Some(prev) = &previous {
                // Every pixel is written again by this pass's blocks: the previous pass is only
                // what the blocks are matched against where this pass has not been yet.
                canvas.image = RgbImage::from_fn(cw, ch, |x, y| prev.get(x.min(w - 1), y.min(h - 1)));
            }
            let whole = || vec![Rect::new(0, 0, block, block)];
            let mut candidate_counts = Vec::new();
            let mut choose = |search: &mut super::guide::GuidedSearch, window: &RgbImage, origin, regions: &[Rect], place, bi, bj| {
                let members = search.candidates(window, origin, regions, place, cfg.tolerance);
                candidate_counts.push(members.len());
                let label =
                    if pass == 0 { format!("quilt/guided/bi={bi}/bj={bj}") } else { format!("quilt/guided/pass={pass}/bi={bi}/bj={bj}") };
                let mut s = Stream::new(req.seed, &label);
                members[s.below_usize(members.len())]
            };
            match &grid {
                Grid::Plain(layout) => {
                    for bi in 0..layout.rows {
                        for bj in 0..layout.cols {
                            let origin = layout.origin(bi, bj);
                            let regions = if whole_block { whole() } else { layout.overlap_regions(bi, bj) };
                            let src = choose(&mut search, &canvas.image, origin, &regions, origin, bi, bj);
                            let cut = block_cuts(&canvas.image, sample, src, origin, block, overlap, bj > 0, bi > 0, rule);
                            paste_with_cuts(&mut canvas, sample, src, origin, block, overlap, bj > 0, bi > 0, rule, &cut);
                        }
                    }
                }
                Grid::Torus(torus) => {
                    let mut done = vec![false; (torus.rows * torus.cols) as usize];
                    for (bi, bj) in torus.raster() {
                        let sides = torus.sides(&done, bi, bj);
                        let window = torus.window(&canvas.image, bi, bj);
                        let regions = if whole_block { whole() } else { torus.regions(bi, bj, sides) };
                        let src = choose(&mut search, &window, (0, 0), &regions, torus.origin(bi, bj), bi, bj);
                        torus.paste(&mut canvas, sample, src, bi, bj, sides, rule);
                        done[torus.index(bi, bj)] = true;
                    }
                }
            }
            pass_diagnostics.push(serde_json::json!({
                "block": block, "overlap": overlap, "weight": weight,
                "mean_candidates": candidate_counts.iter().sum::<usize>() as f64 / candidate_counts.len().max(1) as f64,
            }));
            let done = match &grid {
                Grid::Plain(_) => canvas.into_top_left(w, h),
                Grid::Torus(_) => canvas,
            };
            previous = Some(done.image.clone());
            finished = Some((done, grid));
        }
        let (canvas, grid) = finished.expect("at least one pass");
        let (image, placement) = canvas.finish();
        let (cols, rows, seams) = match &grid {
            Grid::Plain(layout) => (layout.cols, layout.rows, layout.seam_grid(w, h)),
            Grid::Torus(t) => (t.cols, t.rows, t.seam_grid()),
        };
        let mut diagnostics = serde_json::json!({
            "blocks": { "cols": cols, "rows": rows },
            "guided": { "weight": guide.weight, "passes": pass_diagnostics },
        });
        if let Grid::Torus(t) = &grid {
            diagnostics["tileable"] = serde_json::json!(true);
            t.record_fit(&mut diagnostics);
        }
        Ok(Synthesis { image, seams: Some(seams), diagnostics, phases: Vec::new(), extras: Vec::new(), placement })
    }

    /// Quilting on a torus (`primitives::torus`): the same raster order, search and streams, but
    /// a block's overlap is every side that already holds content, the wrapped right and bottom
    /// sides of the last column and row included, and it is cut (or feathered) on all of them.
    fn synthesize_torus(&self, req: &Request, cfg: &QuiltingConfig, allowed: Option<Vec<bool>>) -> Result<Synthesis, SynthError> {
        let sample = req.sample;
        let torus = torus_of(cfg, sample.dimensions(), (req.width, req.height)).map_err(SynthError::Failed)?;
        let (block, rule) = (cfg.block, cfg.overlap_rule());
        let (w, h) = torus.size();
        let mut canvas = Canvas::new(w, h, sample.dimensions(), req.placement);
        let first = first_block(req.seed, sample, block, allowed.as_deref());
        let mut search = BlockSearch::within(cfg.search, sample, block, allowed);
        let mut done = vec![false; (torus.rows * torus.cols) as usize];
        let mut sources: Vec<Option<(u32, u32)>> = vec![None; done.len()];
        let mut candidate_counts = Vec::with_capacity(done.len());
        for (bi, bj) in torus.raster() {
            let sides = torus.sides(&done, bi, bj);
            let (sx, sy) = if bi == 0 && bj == 0 {
                first
            } else {
                let window = torus.window(&canvas.image, bi, bj);
                let c = search.candidates(&window, (0, 0), &torus.regions(bi, bj, sides), cfg.tolerance);
                candidate_counts.push(c.members.len());
                let (rows, cols) = (torus.rows, torus.cols);
                // Every block already placed around it, through the wrap too.
                let neighbours: Vec<(u32, u32)> = [rows - 1, 0, 1]
                    .into_iter()
                    .flat_map(|di| [cols - 1, 0, 1].into_iter().map(move |dj| ((bi + di) % rows, (bj + dj) % cols)))
                    .filter(|&n| n != (bi, bj))
                    .filter_map(|(i, j)| sources[(i * cols + j) as usize])
                    .collect();
                let members = untwinned(
                    req,
                    &mut search,
                    &window,
                    (0, 0),
                    &torus.regions(bi, bj, sides),
                    cfg.tolerance,
                    c.members,
                    &neighbours,
                    block,
                );
                pick(req.seed, bi, bj, &members)
            };
            sources[(bi * torus.cols + bj) as usize] = Some((sx, sy));
            torus.paste(&mut canvas, sample, (sx, sy), bi, bj, sides, rule);
            done[torus.index(bi, bj)] = true;
        }
        let (image, placement) = canvas.finish();
        let mut diagnostics = serde_json::json!({
            "blocks": { "cols": torus.cols, "rows": torus.rows },
            "tileable": true,
            "mean_candidates": candidate_counts.iter().sum::<usize>() as f64 / candidate_counts.len().max(1) as f64,
        });
        if let Some(level) = search.coarse_level() {
            diagnostics["pyramid_level"] = serde_json::json!(level);
        }
        torus.record_fit(&mut diagnostics);
        Ok(Synthesis { image, seams: Some(torus.seam_grid()), diagnostics, phases: Vec::new(), extras: Vec::new(), placement })
    }
}

/// The search the memory estimate assumes: the job's, `auto` resolved for the sample.
fn memory_engine(params: &Params, sample: (u32, u32)) -> Engine {
    params.choice::<Engine>("search").unwrap_or(Engine::Auto).for_sample(sample)
}

/// The block the memory estimate assumes: the job's, or the smallest a transfer defaults to (a
/// smaller block keeps a big sample's pyramid at full resolution, the costlier search).
fn memory_block(params: &Params) -> u32 {
    params.int("block").ok().and_then(|b| u32::try_from(b).ok()).unwrap_or(TRANSFER_BLOCK as u32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::params::resolve;

    fn params(given: &[(&str, ParamValue)]) -> Params {
        let g: Vec<(String, ParamValue)> = given.iter().map(|(k, v)| (k.to_string(), v.clone())).collect();
        resolve(PARAMS, &g).unwrap()
    }

    fn sample() -> RgbImage {
        RgbImage::from_fn(64, 64, |x, y| {
            let v = ((x / 8 + y / 8) % 2) as u8 * 120 + ((x * 7 + y * 3) % 13) as u8 * 5;
            [v, v / 2 + 20, 255 - v]
        })
    }

    #[test]
    fn output_has_the_requested_size_and_is_deterministic() {
        let s = sample();
        let p = params(&[("block", ParamValue::Int(16)), ("overlap", ParamValue::Int(4))]);
        let req = Request {
            sample: &s,
            width: 70,
            height: 45,
            params: &p,
            seed: 3,
            placement: false,
            tileable: false,
            constraints: std::default::Default::default(),
        };
        let a = Quilting.synthesize(&req).unwrap();
        let b = Quilting.synthesize(&req).unwrap();
        assert_eq!(a.image.dimensions(), (70, 45));
        assert_eq!(a.image, b.image);
        let other = Quilting.synthesize(&Request { seed: 4, ..req }).unwrap();
        assert_ne!(a.image, other.image);
    }

    #[test]
    fn fft_and_direct_search_give_the_same_pixels() {
        let s = sample();
        let fft = params(&[("block", ParamValue::Int(18)), ("tolerance", ParamValue::Float(0.3))]);
        let direct =
            params(&[("block", ParamValue::Int(18)), ("tolerance", ParamValue::Float(0.3)), ("search", ParamValue::Str("direct".into()))]);
        let a = Quilting
            .synthesize(&Request {
                sample: &s,
                width: 80,
                height: 80,
                params: &fft,
                seed: 9,
                placement: false,
                tileable: false,
                constraints: std::default::Default::default(),
            })
            .unwrap();
        let b = Quilting
            .synthesize(&Request {
                sample: &s,
                width: 80,
                height: 80,
                params: &direct,
                seed: 9,
                placement: false,
                tileable: false,
                constraints: std::default::Default::default(),
            })
            .unwrap();
        assert_eq!(a.image, b.image);
    }

    #[test]
    fn every_output_pixel_comes_from_the_sample_without_blending() {
        let s = sample();
        let colours: std::collections::HashSet<[u8; 3]> =
            (0..64).flat_map(|y| (0..64).map(move |x| (x, y))).map(|(x, y)| s.get(x, y)).collect();
        let p = params(&[("block", ParamValue::Int(20))]);
        let out = Quilting
            .synthesize(&Request {
                sample: &s,
                width: 90,
                height: 90,
                params: &p,
                seed: 1,
                placement: false,
                tileable: false,
                constraints: std::default::Default::default(),
            })
            .unwrap();
        for y in 0..90 {
            for x in 0..90 {
                assert!(colours.contains(&out.image.get(x, y)), "pixel ({x},{y}) is not a sample colour");
            }
        }
    }

    #[test]
    fn a_periodic_sample_is_continued_seamlessly() {
        // A texture with period 8 in both directions: with tolerance 0 every block must continue
        // the pattern exactly, so the output is itself periodic.
        let s = RgbImage::from_fn(48, 48, |x, y| [(x % 8 * 30) as u8, (y % 8 * 30) as u8, ((x + y) % 8 * 20) as u8]);
        let p = params(&[("block", ParamValue::Int(16)), ("overlap", ParamValue::Int(4)), ("tolerance", ParamValue::Float(0.0))]);
        let out = Quilting
            .synthesize(&Request {
                sample: &s,
                width: 60,
                height: 60,
                params: &p,
                seed: 5,
                placement: false,
                tileable: false,
                constraints: std::default::Default::default(),
            })
            .unwrap()
            .image;
        for y in 0..52 {
            for x in 0..52 {
                assert_eq!(out.get(x, y), out.get(x + 8, y + 8), "({x},{y})");
            }
        }
    }

    #[test]
    fn rejects_blocks_larger_than_the_sample_and_wide_overlaps() {
        let p = params(&[("block", ParamValue::Int(80)), ("overlap", ParamValue::Int(50))]);
        let errs = Quilting.check(&p, (64, 64), (100, 100));
        let keys: Vec<&str> = errs.iter().map(|e| e.key.as_str()).collect();
        assert_eq!(keys, vec!["block", "overlap"]);
        assert!(errs[0].message.contains("larger than the sample"));
    }

    #[test]
    fn feather_needs_cut_none() {
        let p = params(&[("blend", ParamValue::Str("feather".into()))]);
        let errs = Quilting.check(&p, (64, 64), (100, 100));
        assert_eq!(errs.len(), 1);
        assert_eq!(errs[0].key, "blend");
        let p = params(&[("blend", ParamValue::Str("feather".into())), ("cut", ParamValue::Str("none".into()))]);
        assert!(Quilting.check(&p, (64, 64), (100, 100)).is_empty());
    }

    #[test]
    fn default_config_is_the_table_defaults() {
        let cfg = QuiltingConfig::default();
        assert_eq!(resolve(PARAMS, &cfg.to_params()).unwrap(), resolve(PARAMS, &[]).unwrap());
        let back = QuiltingConfig::from_params(&resolve(PARAMS, &[]).unwrap()).unwrap();
        assert_eq!(back, QuiltingConfig { overlap: Some(8), ..cfg });
    }

    #[test]
    fn a_non_default_config_round_trips() {
        let cfg =
            QuiltingConfig { block: 40, overlap: Some(7), tolerance: 0.3, search: Engine::Direct, cut: Cut::None, blend: Blend::Feather };
        let d = QuiltingConfig::default();
        assert!(
            cfg.block != d.block
                && cfg.overlap != d.overlap
                && cfg.tolerance != d.tolerance
                && cfg.search != d.search
                && cfg.cut != d.cut
                && cfg.blend != d.blend
        );
        let p = resolve(PARAMS, &cfg.to_params()).unwrap();
        assert_eq!(QuiltingConfig::from_params(&p).unwrap(), cfg);
        assert_eq!(cfg.overlap_rule(), OverlapRule::Feather);
    }

    #[test]
    fn an_unknown_word_is_an_error_naming_its_key() {
        let mut p = params(&[]);
        p.0.insert("cut".into(), ParamValue::Str("zigzag".into()));
        let e = QuiltingConfig::from_params(&p).unwrap_err();
        assert!(matches!(&e, SynthError::Param { key, .. } if key == "cut"), "{e}");
        let errs = Quilting.check(&p, (64, 64), (100, 100));
        assert_eq!(errs.len(), 1);
        assert_eq!(errs[0].key, "cut");
        let s = sample();
        assert!(
            Quilting
                .synthesize(&Request {
                    sample: &s,
                    width: 20,
                    height: 20,
                    params: &p,
                    seed: 1,
                    placement: false,
                    tileable: false,
                    constraints: std::default::Default::default()
                })
                .is_err()
        );
    }
}
