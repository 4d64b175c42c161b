//! Patch sampling with feathered overlaps whose best-match search is a particle swarm (paper 002,
//! docs/methods.md §4), with its baselines: plain PSO and exhaustive search / Liang et al.'s sampler.
//!
//! Blocks of `block × block` are laid in raster order on a grid of stride `block − overlap`. The
//! first block is a random sample block; every other one minimises the exact SSD over its boundary
//! zone (the left strip, the top strip or the L-shaped union of both, eq. 7), found by
//!
//! - `search = "cpso"`: the chaos PSO of §4.3 (premature-convergence test, logistic-map chaos
//!   search, re-diversification of the worse half of the swarm);
//! - `search = "pso"`: the same swarm without the chaos part, drawing from the same streams, so the
//!   two coincide draw for draw until CPSO's first chaos search;
//! - `search = "exhaustive"`: every position (exact, `primitives::overlap_search`); with
//!   `tolerance = ε > 0` it is Liang et al.'s sampler (uniform among the patches whose RMS zone
//!   error is below `ε` times the zone's RMS intensity, the best patch if there is none). With
//!   `engine = "pyramid"` (what `auto` gives samples above 512²) "every position" is every
//!   position the coarse-to-fine search re-scores (`primitives::pyramid_search`); the optimum
//!   recorded by `record_optimum` stays the exact one.
//!
//! The block is pasted with feathering over its zone (B5). The output is the top-left
//! `width × height` of the grid.
//!
//! **Tileable outputs** (`Request::tileable`): the grid is laid on a torus (`primitives::torus`);
//! a block's zone is every side that already holds content, the wrapped right and bottom sides of
//! the last column and row included, read through a wrapped window of the canvas; it is feathered
//! (or cut) on all of them. The waves are those of the torus, still one labelled stream per block.
//!
//! **Diagnostics** (the manifest's `diagnostics`, deterministic): always `search`, `blocks`
//! (`cols`, `rows`), `searched_blocks`, `mean_rms_error` (RMS difference per channel over the
//! zone, averaged over blocks); for swarms `mean_iterations`, `mean_evaluations`, `early_stops`,
//! `chaos_blocks`, `chaos_searches`; for exhaustive `mean_candidates`. With `diagnostics = true`
//! (or `record_optimum = true`) also `first` (`x`, `y`) and `per_block`: `bi`, `bj`, `x`, `y`,
//! `error` (d, eq. 7), `zone_pixels` (A), and for swarms `iterations`, `best_iteration` (when the
//! final best was first reached), `chaos_searches`, `first_chaos`, `evaluations`, `stopped_early`
//! (and `swarm_error` with `polish_radius > 0`); for exhaustive `candidates`. `record_optimum`
//! adds `optimum` (the exhaustive minimum of d) and `positions_within_3pct` per block, and
//! `mean_rms_optimum`. Paper 002's Table 2 is computed from these (see `examples/07_paper002_tables.rs`).
//!
//! **Options that are not in the paper** (all off by default): `blend = "cut"` (the minimum-error
//! boundary cut instead of feathering: feathering over a poor match ghosts, which shows as a faint
//! grid or as bands along block rows on stochastic samples), `candidates = "near-best"` (Liang's
//! tolerance is relative to the zone's intensity, so on bright low-contrast samples it admits almost
//! every patch), `polish_radius` (a local exhaustive search around the swarm's best).
//!
//! **Constraints** (issue #28). *Sample mask*: blocks are copied only from positions whose every
//! pixel the mask allows (so feathered blends, which mix two such blocks, do too); the swarms
//! move over every position but score and place each as its nearest allowed one ([`Allowed`]),
//! the exhaustive searches restrict their candidates, the first block is drawn among allowed
//! positions. *Several samples / `augment`* (the atlas): a block never shows a turned or
//! mirrored copy of the pixels a placed neighbour shows ([`Twins`]: the left one and the three
//! above, on a torus every placed one): the swarm treats such positions as masked ones, the
//! exhaustive searches leave them out of their candidates. *Inpainting*: `methods::inpaint`'s driver (blocks over the hole, known pixels never
//! written) with this method's search: patches meet pixels filled earlier along the minimum-error
//! cut (feathering there averaged rough matches into a washed-out fill), and the border polish
//! feathers its patches in from the known border (or cuts them in, with `blend = "cut"`). *Guide*: Efros–Freeman's weighed error ([`GuideTerm`]) is the swarm's fitness and the
//! exhaustive search's criterion (`methods::guide`), with quilting's shrinking passes, each on
//! its own torus when tileable; in a hole (one pass) the target is read where the window goes
//! ([`Zone::guide_at`]). Their streams carry an `inpaint/`, `inpaint/guided/` or `guided/…`
//! prefix; plain syntheses keep their labels and pixels.
//!
//! **Threads.** A block depends only on blocks earlier in raster order that overlap its zone, so
//! the blocks with the same `2·bi + bj` ("waves") never touch each other's pixels and the swarm
//! searches of a wave run in parallel; every random draw comes from the block's own labelled
//! streams and every error is an exact integer, so the pixels are those of a raster-order run on
//! any number of threads.

mod config;
mod diagnostics;
mod exhaustive;
mod positions;
mod swarm;
#[cfg(test)]
mod tests;

pub use config::{Blend, CandidateRule, ChaosConfig, ExhaustiveConfig, PatchSamplingConfig, Rediversify, Search, SwarmConfig, Update};

use super::{BlockSearch, Engine};
use crate::image::RgbImage;
use crate::synth::error::SynthError;
use crate::synth::method::{Method, Request, Synthesis, Uses};
use crate::synth::params::{Choice, MethodConfig, ParamError, ParamSpec, Params};
use crate::synth::primitives::block_grid::{BlockGrid, OverlapRule, paste_block};
use crate::synth::primitives::canvas::Canvas;
use crate::synth::primitives::overlap::Rect;
use crate::synth::primitives::overlap_search::OverlapSearch;
use crate::synth::primitives::pso::{Outcome, SwarmParams};
use crate::synth::primitives::torus::{Sides, TorusGrid};
use crate::synth::primitives::zone_ssd::SampleLines;
use crate::synth::rng::Stream;
use rayon::prelude::*;
use serde_json::json;
use std::borrow::Cow;

use config::PARAMS;
use diagnostics::diagnostics;
use exhaustive::{exhaustive_block, guided_block};
use positions::{Allowed, Twins};
use swarm::swarm_block;

pub struct PatchSampling;

/// Blocks in order of `2·bi + bj`: within a wave no two blocks overlap (needs `2·overlap ≤
/// block`), and every block a block's zone reads from is in an earlier wave.
fn waves(grid: &BlockGrid) -> Vec<Vec<(u32, u32)>> {
    let last = 2 * (grid.rows - 1) + (grid.cols - 1);
    (0..=last)
        .map(|t| (0..grid.rows).filter_map(|bi| t.checked_sub(2 * bi).filter(|&bj| bj < grid.cols).map(|bj| (bi, bj))).collect())
        .collect()
}

/// The settings of one synthesis, in the form the searches use.
struct Settings {
    search: Search,
    swarm: SwarmParams,
    delta_rms: f64,
    tolerance: f64,
    polish_radius: u32,
    continuations: bool,
    blend: OverlapRule,
    candidates: CandidateRule,
    engine: Engine,
    first: Option<(u32, u32)>,
    per_block: bool,
    optimum: bool,
    /// The positions blocks may be copied from, when a sample mask or an inpainted image's hole
    /// rules some out.
    allowed: Option<Allowed>,
    /// Prefixed to every stream label, so that inpainting's and each guided pass's draws are
    /// their own ("" for a plain synthesis, whose labels predate it).
    label: String,
}

/// The guide of a guided synthesis, as the searches use it (Efros–Freeman's error: the zone's
/// SSD per pixel and channel weighed by `1 − weight` against the guide's over the whole block
/// by `weight`, the guide read from `target` at the block's place; see `methods::guide`).
struct GuideTerm<'g> {
    source: &'g RgbImage,
    lines: SampleLines,
    /// The target guide over the whole canvas (the edge repeated past the output).
    target: RgbImage,
    weight: f64,
}

impl GuideTerm<'_> {
    /// The weights of the zone's and the guide's SSD for a zone of `area` pixels.
    fn weights(&self, area: u64, block: u32) -> (f64, f64) {
        let k_texture = if area == 0 { 0.0 } else { (1.0 - self.weight) / (3.0 * area as f64) };
        (k_texture, self.weight / (3.0 * f64::from(block) * f64::from(block)))
    }
}

impl Settings {
    fn of(cfg: &PatchSamplingConfig) -> Settings {
        let chaos = (cfg.search == Search::Cpso).then(|| cfg.chaos.params());
        Settings {
            search: cfg.search,
            swarm: cfg.swarm.params(chaos),
            delta_rms: cfg.swarm.delta_rms,
            tolerance: cfg.exhaustive.tolerance,
            polish_radius: cfg.swarm.polish_radius,
            continuations: cfg.swarm.continuations,
            blend: cfg.blend.into(),
            candidates: cfg.exhaustive.candidates,
            engine: cfg.exhaustive.engine,
            first: cfg.first_x.zip(cfg.first_y),
            per_block: cfg.diagnostics || cfg.record_optimum,
            optimum: cfg.record_optimum,
            allowed: None,
            label: String::new(),
        }
    }
}

/// What the search of one block found.
#[derive(Clone, Debug)]
struct BlockResult {
    bi: u32,
    bj: u32,
    pos: (u32, u32),
    /// `d` at `pos`.
    error: u64,
    /// `A`, the zone's pixel count.
    zone_pixels: u64,
    /// Swarm searches only.
    swarm: Option<Outcome>,
    /// Exhaustive search only: how many candidates the choice was made among (0: none within
    /// tolerance, the best was taken).
    candidates: Option<usize>,
    /// The exhaustive optimum, when known.
    optimum: Option<u64>,
    /// Positions within `NEAR_OPTIMUM` of the optimum, when recorded.
    near_optimum: Option<usize>,
}

/// Paper 002's success band: a search succeeds if `d ≤ 1.03·d_opt`.
const NEAR_OPTIMUM: f64 = 0.03;

impl Method for PatchSampling {
    fn name(&self) -> &'static str {
        PatchSamplingConfig::METHOD
    }
    fn algorithm_version(&self) -> u32 {
        1
    }
    fn algorithm_version_of(&self, params: &Params, uses: Uses) -> u32 {
        // Version 3: inpainting cuts its patches into earlier fill (it feathered them), and with
        // turned copies continuations are always scored and twins left out (issue #28); version 9:
        // the hole's patches are made from its border inwards (11 led by a luminance guide); version 5:
        // a luminance guide is compared at a block's scale (7 for syntheses, whose later passes
        // follow the previous one through the target); plain syntheses keep version 1 and their pixels (2 is version 1 with the pyramid).
        let base = if uses.luminance_guide {
            super::luminance_guide_version(uses)
        } else if uses.inpaint {
            super::INPAINT_VERSION
        } else if uses.copies {
            super::COPIES_VERSION
        } else {
            self.algorithm_version()
        };
        super::engine_version(params, "engine", base)
    }
    fn summary(&self) -> &'static str {
        "Patch sampling with feathered overlaps; best match by chaos PSO (paper 002), PSO or exhaustive / Liang et al."
    }
    fn params(&self) -> &'static [ParamSpec] {
        PARAMS
    }

    fn check(&self, p: &Params, sample: (u32, u32), _output: (u32, u32)) -> Vec<ParamError> {
        let cfg: PatchSamplingConfig = match super::read_config(p) {
            Ok(c) => c,
            Err(e) => return e,
        };
        let block = i64::from(cfg.block);
        let smaller = sample.0.min(sample.1) as i64;
        let mut errors = super::check_block_and_overlap(cfg.block, cfg.overlap_or_derived(), sample);
        if cfg.search != Search::Exhaustive && cfg.swarm.vmax <= 0.0 {
            errors.push(ParamError::new("vmax", "vmax must be greater than 0: with 0 the particles never move"));
        }
        let (fx, fy) = (cfg.first_x, cfg.first_y);
        if fx.is_some() != fy.is_some() {
            let (set, unset) = if fx.is_some() { ("first_x", "first_y") } else { ("first_y", "first_x") };
            errors.push(ParamError::new(unset, format!("{set} is set but {unset} is not; give both or neither")));
        }
        if block <= smaller {
            for (key, v, limit) in [("first_x", fx, sample.0 as i64 - block), ("first_y", fy, sample.1 as i64 - block)] {
                let Some(v) = v.map(i64::from) else { continue };
                if v > limit {
                    errors.push(ParamError::new(
                        key,
                        format!(
                            "{key} {v} puts the first block outside the {}x{} sample; use 0..={limit} (or -1 for random)",
                            sample.0, sample.1
                        ),
                    ));
                }
            }
        }
        errors
    }

    fn resolve_for_sample(&self, params: &mut Params, sample: (u32, u32)) {
        super::resolve_engine(params, "engine", sample);
    }

    fn peak_memory(&self, _params: &Params, sample: (u32, u32), output: (u32, u32)) -> u64 {
        // Measured (VmHWM of `texsyn run`, bricks_gray 256², block 50): the canvas, trimmed in
        // place (3 B per output pixel), and the overlap search over the sample; 1024²: 15 MB,
        // 2048²: 34 MB in all (8 MB of it the process).
        crate::synth::method::linear_memory(sample, output, 3.5, 128.0, 4 << 20)
    }

    fn synthesize(&self, req: &Request) -> Result<Synthesis, SynthError> {
        let cfg = PatchSamplingConfig::from_params(req.params)?;
        let (block, overlap) = (cfg.block, cfg.overlap_or_derived());
        let sample = req.sample;
        if block > sample.width() || block > sample.height() {
            return Err(SynthError::Failed(format!("block {block} does not fit in the {}x{} sample", sample.width(), sample.height())));
        }
        if overlap * 2 > block || overlap == 0 {
            return Err(SynthError::Failed(format!("overlap {overlap} must be in 1..={}", block / 2)));
        }
        let mut settings = Settings::of(&cfg);
        // Transformed copies (`augment`) are lit from other sides: the swarm's rough matches
        // (RMS 45-47 per channel on pebbles, with or without copies) then join a copy lit from
        // the left to one lit from the right, and feathered together they look mushy. Scoring
        // the neighbours' continuations (same copy, one stride on) keeps runs of one copy and
        // its exact joins (RMS 47 -> 31): always on with copies, which the paper does not have.
        let copies = req.constraints.atlas.is_some_and(|a| a.has_copies());
        if copies && !settings.continuations {
            settings.continuations = true;
        }
        if let Some(region) = req.constraints.fill {
            return self.inpaint(req, &cfg, settings, region);
        }
        if let Some(guide) = req.constraints.guide {
            return self.synthesize_guided(req, &cfg, settings, &guide.at_block_scale(cfg.block));
        }
        settings.allowed = allowed_positions(req, block)?;
        let mut synthesis = self.grid(req, &settings, block, overlap, None, None)?;
        if copies && !cfg.swarm.continuations && settings.search != Search::Exhaustive {
            synthesis.diagnostics["continuations"] = json!("on: augment");
        }
        Ok(synthesis)
    }

    fn tileable(&self, p: &Params, sample: (u32, u32), output: (u32, u32)) -> Result<(), String> {
        let cfg = PatchSamplingConfig::from_params(p).map_err(|e| e.to_string())?;
        torus_of(&cfg, sample, output).map(|_| ())
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
}

/// The block positions the request's sample mask (and, when inpainting, the pixels outside the
/// hole) allow, or `None` when every position may be copied; an error naming the block and the
/// largest one that fits when none is allowed.
fn allowed_positions(req: &Request, block: u32) -> Result<Option<Allowed>, SynthError> {
    let Some(mask) = req.constraints.copyable() else { return Ok(None) };
    let flags = mask.block_positions(block, block);
    if !flags.contains(&true) {
        let what = if req.constraints.fill.is_some() { "the image outside the inpaint mask" } else { "the sample mask" };
        return Err(SynthError::param(
            "block",
            format!("{what} leaves no whole {block}x{block} block to copy; the largest block it allows is {}", mask.largest_block()),
        ));
    }
    Ok(Some(Allowed::new(flags, req.sample.width() - block + 1)))
}

impl PatchSampling {
    /// Inpainting (`methods::inpaint`'s driver) with patch sampling's own search (the swarm, or
    /// the exhaustive search and its candidate rule) over the positions outside the hole, and its
    /// join: cut into pixels filled earlier (never into known ones), the border polish feathered
    /// in (or cut, with `blend = "cut"`).
    fn inpaint(
        &self,
        req: &Request,
        cfg: &PatchSamplingConfig,
        mut settings: Settings,
        region: &crate::synth::constraints::FillRegion,
    ) -> Result<Synthesis, SynthError> {
        let (block, overlap, sample) = (cfg.block, cfg.overlap_or_derived(), req.sample);
        let allowed = allowed_positions(req, block)?.expect("a fill region always restricts the positions");
        let copyable = req.constraints.copyable().expect("a fill region always restricts the pixels");
        settings.label = "inpaint/".into();
        let flags = allowed.flags.clone();
        settings.allowed = Some(allowed);
        let mut search =
            (settings.search == Search::Exhaustive).then(|| BlockSearch::within(settings.engine, sample, block, Some(flags.clone())));
        let lines = (settings.search != Search::Exhaustive).then(|| SampleLines::new(sample));
        let how = super::inpaint::Fill {
            block,
            overlap,
            // The border polish (with `blend = "cut"`) picks among the patches within quilting's
            // default tolerance of the best.
            tolerance: 0.1,
            // Inside the hole a block meets what earlier blocks filled along the cut, whatever
            // `blend` says: feathered there, the swarm's rough matches averaged into a washed-out
            // fill (peers bench, round holes in the 8 bundled samples: the hole's gray KL up to
            // 2.9 times Embark's; summed measure ratios 5.2-5.6 -> 4.2-4.8 over seeds 1-3).
            // `blend` is how the border polish joins the fill to the known image.
            rule: OverlapRule::Cut,
            polish_rule: settings.blend,
            allowed: &flags,
            copyable: &copyable,
            engine: settings.engine,
            label: "cpso",
            polish_search: search.as_ref().and_then(|s| super::inpaint::polish_search(s, block, overlap, &copyable)).into(),
        };
        // With `[guide]`, every block of the hole weighs its match with the pixels around it
        // against the guides' (one pass: a hole is filled once), the target read where the block
        // goes: past the image's edge it wraps on a torus and goes on as its own edge otherwise.
        let scaled = req.constraints.guide.map(|g| g.at_block_scale(block));
        let term = match &scaled {
            Some(guide) => {
                let (w, h) = region.dimensions();
                if guide.target.dimensions() != (w, h) || guide.source.dimensions() != sample.dimensions() {
                    return Err(SynthError::Failed("the guides must have the image's and the sample's sizes".into()));
                }
                let target = guide.target_beyond(w + block, h + block, req.tileable);
                settings.label = "inpaint/guided/".into();
                Some(GuideTerm { source: &guide.source, lines: SampleLines::new(&guide.source), target, weight: guide.weight })
            }
            None => None,
        };
        let mut guided = match &term {
            Some(g) if settings.search == Search::Exhaustive => {
                search = None;
                Some(super::guide::GuidedSearch::new(sample, g.source, &g.target, block, g.weight, Some(flags.clone())))
            }
            _ => None,
        };
        let settings = &settings;
        let mut pick = |want: &super::inpaint::Want| {
            let (window, (bi, bj)) = (want.window, want.index);
            let zone = Zone {
                target: Cow::Borrowed(window),
                origin: (0, 0),
                regions: want.regions.to_vec(),
                block,
                sides: Sides::default(),
                guide_at: want.place,
            };
            // The blocks the window's content came from: the fill never mirrors them.
            let twins = Twins::of(&req.constraints, want.neighbours.to_vec(), block);
            let r = match (&mut guided, &mut search, &lines) {
                (Some(g), _, _) => guided_block(g, sample, &zone, bi, bj, settings, req.seed, twins.as_ref()),
                (None, Some(s), _) => exhaustive_block(s, sample, &zone, bi, bj, settings, req.seed, twins.as_ref()),
                (None, None, Some(lines)) => {
                    swarm_block(sample, lines, &zone, bi, bj, settings, req.seed, &[], term.as_ref(), twins.as_ref())
                }
                (None, None, None) => unreachable!("a search is prepared"),
            };
            (r.pos, r.candidates)
        };
        let mut synthesis = super::inpaint::fill(req, region, &how, &mut pick)?;
        synthesis.diagnostics["search"] = json!(settings.search.name());
        if let Some(g) = &term {
            synthesis.diagnostics["guided"] = json!({ "weight": g.weight });
        }
        Ok(synthesis)
    }

    /// Guided synthesis (texture transfer, Efros & Freeman 2001 §3): each block minimises its
    /// zone error weighed against its guide error ([`GuideTerm`]), with the method's own search;
    /// then, as quilting does, `passes − 1` more passes with blocks a third smaller (never below
    /// 6 px), at the same weight, each held to the previous pass: through the target with
    /// luminance guides ([`crate::synth::constraints::Guide::after_pass`]; the pass is then made
    /// as the first is), else matched over the whole block against it.
    fn synthesize_guided(
        &self,
        req: &Request,
        cfg: &PatchSamplingConfig,
        mut settings: Settings,
        guide: &crate::synth::constraints::Guide,
    ) -> Result<Synthesis, SynthError> {
        let sample = req.sample;
        if guide.target.dimensions() != (req.width, req.height) || guide.source.dimensions() != sample.dimensions() {
            return Err(SynthError::Failed("the guides must have the output's and the sample's sizes".into()));
        }
        let copyable = req.constraints.copyable();
        let mut previous: Option<RgbImage> = None;
        let mut passes = Vec::new();
        let mut last = None;
        for pass in 0..guide.passes.max(1) {
            let shrink = (2.0f64 / 3.0).powi(pass as i32);
            let block = ((f64::from(cfg.block) * shrink).round() as u32).max(6).min(cfg.block);
            let overlap = ((f64::from(cfg.overlap_or_derived()) * shrink).round() as u32).clamp(1, block / 2);
            settings.allowed = copyable.as_ref().map(|mask| Allowed::new(mask.block_positions(block, block), sample.width() - block + 1));
            if settings.allowed.as_ref().is_some_and(|a| !a.flags.contains(&true)) {
                return Err(SynthError::param("block", format!("the sample mask leaves no whole {block}x{block} block to copy")));
            }
            settings.label = if pass == 0 { "guided/".into() } else { format!("guided/pass={pass}/") };
            let (w, h) = (req.width, req.height);
            // Past the output the target goes on as its own edge (the last blocks are cropped),
            // or wraps with a tileable output's torus.
            let (cw, ch) = if req.tileable { (w + block, h + block) } else { BlockGrid::new(block, overlap, w, h).canvas() };
            let after = previous.as_ref().filter(|_| guide.luminance).map(|prev| guide.after_pass(prev, sample, cfg.block));
            let target = after.as_ref().unwrap_or(guide).target_beyond(cw, ch, req.tileable);
            let term = GuideTerm { source: &guide.source, lines: SampleLines::new(&guide.source), target, weight: guide.weight };
            let whole_block = previous.as_ref().filter(|_| after.is_none());
            let mut synthesis = self.grid(req, &settings, block, overlap, whole_block, Some(&term))?;
            passes.push(json!({ "block": block, "overlap": overlap, "weight": guide.weight, "mean_rms_error": synthesis.diagnostics["mean_rms_error"].clone() }));
            previous = Some(synthesis.image.clone());
            synthesis.diagnostics["guided"] = json!({ "weight": guide.weight });
            last = Some(synthesis);
        }
        let mut synthesis = last.expect("at least one pass");
        synthesis.diagnostics["guided"] = json!({ "weight": guide.weight, "passes": passes });
        Ok(synthesis)
    }

    /// Patch sampling over the output's grid (or its torus): the paper's synthesis. With
    /// `previous` (a guided pass after the first) the canvas starts as that image and every block,
    /// the first included, is matched over its whole area against it; with `guide` every block's
    /// error weighs the guide's too, and the first block is searched as well.
    fn grid(
        &self,
        req: &Request,
        settings: &Settings,
        block: u32,
        overlap: u32,
        previous: Option<&RgbImage>,
        guide: Option<&GuideTerm>,
    ) -> Result<Synthesis, SynthError> {
        let sample = req.sample;
        let torus = if req.tileable {
            // This pass's blocks (a guided pass after the first has smaller ones than `cfg`'s).
            Some(
                TorusGrid::of_blocks("patch sampling", block, overlap, sample.dimensions(), (req.width, req.height))
                    .map_err(SynthError::Failed)?,
            )
        } else {
            None
        };
        let layout = BlockGrid::new(block, overlap, req.width, req.height);
        let (cw, ch) = torus.as_ref().map_or(layout.canvas(), |t| t.size());
        let mut canvas = Canvas::new(cw, ch, sample.dimensions(), req.placement);
        if let Some(prev) = previous {
            // Every pixel is written again by this pass's blocks: the previous pass is only what
            // the blocks are matched against where this pass has not been yet.
            canvas.image = RgbImage::from_fn(cw, ch, |x, y| prev.get(x.min(prev.width() - 1), y.min(prev.height() - 1)));
        }
        let (nx, ny) = (sample.width() - block + 1, sample.height() - block + 1);
        let first = match settings.first {
            Some((x, y)) => {
                if x >= nx || y >= ny {
                    return Err(SynthError::Failed(format!("the first block ({x}, {y}) does not fit in the sample")));
                }
                if settings.allowed.as_ref().is_some_and(|a| !a.allows((x, y))) {
                    return Err(SynthError::param("first_x", format!("the first block ({x}, {y}) is not wholly inside the sample mask")));
                }
                (x, y)
            }
            None => {
                let mut s = Stream::new(req.seed, &format!("{}cpso/first", settings.label));
                match &settings.allowed {
                    Some(a) => {
                        let count = a.flags.iter().filter(|&&f| f).count() as u64;
                        crate::synth::constraints::nth_allowed(&a.flags, nx, s.below(count)).expect("an allowed position")
                    }
                    None => {
                        let x = s.below(nx as u64) as u32;
                        let y = s.below(ny as u64) as u32;
                        (x, y)
                    }
                }
            }
        };
        let flags = settings.allowed.as_ref().map(|a| a.flags.clone());
        let mut search = (settings.search == Search::Exhaustive && guide.is_none())
            .then(|| BlockSearch::within(settings.engine, sample, block, flags.clone()));
        let mut guided = match guide {
            Some(g) if settings.search == Search::Exhaustive => {
                Some(super::guide::GuidedSearch::new(sample, g.source, &g.target, block, g.weight, flags.clone()))
            }
            _ => None,
        };
        // The recorded optimum is the exact one whatever the engine: an exact search's, else its own.
        let shares = matches!(search, Some(BlockSearch::Exact(..)));
        let mut exact = (settings.optimum && !shares).then(|| {
            let mut s = OverlapSearch::new(sample, block, block);
            if let Some(f) = &flags {
                s.restrict_to(f.clone());
            }
            s
        });
        let lines = (settings.search != Search::Exhaustive).then(|| SampleLines::new(sample));
        let (cols, rows) = torus.as_ref().map_or((layout.cols, layout.rows), |t| (t.cols, t.rows));
        let mut results: Vec<BlockResult> = Vec::with_capacity((rows * cols) as usize);
        let mut done = vec![false; (rows * cols) as usize];
        let mut placed: Vec<Option<(u32, u32)>> = vec![None; (rows * cols) as usize];
        let schedule = match &torus {
            Some(t) => t.waves(),
            None => waves(&layout),
        };

        for wave in schedule {
            // What each block of the wave is compared with: the canvas itself on the plain grid; on
            // a torus a wrapped window of it, over every side that already holds content.
            let zones: Vec<Zone> = wave
                .iter()
                .map(|&(bi, bj)| match &torus {
                    Some(t) => {
                        let sides = t.sides(&done, bi, bj);
                        Zone {
                            target: Cow::Owned(t.window(&canvas.image, bi, bj)),
                            origin: (0, 0),
                            regions: if previous.is_some() { vec![Rect::new(0, 0, block, block)] } else { t.regions(bi, bj, sides) },
                            block,
                            sides,
                            guide_at: t.origin(bi, bj),
                        }
                    }
                    None => Zone {
                        target: Cow::Borrowed(&canvas.image),
                        origin: layout.origin(bi, bj),
                        regions: if previous.is_some() { vec![Rect::new(0, 0, block, block)] } else { layout.overlap_regions(bi, bj) },
                        block,
                        sides: Sides { left: bj > 0, top: bi > 0, ..Sides::default() },
                        guide_at: layout.origin(bi, bj),
                    },
                })
                .collect();
            // Where the left and top neighbours' sample patches continue, one stride on (only
            // with `continuations`): the exact matches a swarm tends to miss on regular samples.
            let hints: Vec<Vec<(u32, u32)>> = wave
                .iter()
                .map(|&(bi, bj)| {
                    if !settings.continuations {
                        return Vec::new();
                    }
                    let stride = block - overlap;
                    let (nx, ny) = (sample.width() - block + 1, sample.height() - block + 1);
                    // Left, then top; on a torus the row or column before the first wraps, and a
                    // fitted torus spaces some blocks a pixel closer.
                    let (neighbours, steps) = match &torus {
                        Some(t) => {
                            let (left, up) = ((bj + cols - 1) % cols, (bi + rows - 1) % rows);
                            ([Some((bi, left)), Some((up, bj))], [t.spacing_x(left), t.spacing_y(up)])
                        }
                        None => ([(bj > 0).then(|| (bi, bj - 1)), (bi > 0).then(|| (bi - 1, bj))], [stride, stride]),
                    };
                    neighbours
                        .into_iter()
                        .zip([(steps[0], 0), (0, steps[1])])
                        .filter_map(|(n, (dx, dy))| n.and_then(|(ni, nj)| placed[(ni * cols + nj) as usize]).map(|p| (p.0 + dx, p.1 + dy)))
                        .filter(|&(x, y)| x < nx && y < ny)
                        .filter(|&p| settings.allowed.as_ref().is_none_or(|a| a.allows(p)))
                        .collect()
                })
                .collect();
            // The twin rule's neighbours: the blocks already placed around each one (on the plain
            // grid the left one and the three above; on a torus every placed one, through the wrap).
            let twins: Vec<Option<Twins>> = wave
                .iter()
                .map(|&(bi, bj)| {
                    let (i, j, r, c) = (i64::from(bi), i64::from(bj), i64::from(rows), i64::from(cols));
                    let around: Vec<(i64, i64)> = match &torus {
                        Some(_) => (-1..=1)
                            .flat_map(|di| (-1..=1).map(move |dj| (di, dj)))
                            .filter(|&d| d != (0, 0))
                            .map(|(di, dj)| ((i + di).rem_euclid(r), (j + dj).rem_euclid(c)))
                            .collect(),
                        None => vec![(i, j - 1), (i - 1, j - 1), (i - 1, j), (i - 1, j + 1)],
                    };
                    let neighbours = around
                        .into_iter()
                        .filter(|&(i, j)| i >= 0 && j >= 0 && i < r && j < c)
                        .filter_map(|(i, j)| placed[(i * c + j) as usize])
                        .collect();
                    Twins::of(&req.constraints, neighbours, block)
                })
                .collect();
            let mut found: Vec<BlockResult> = if wave == [(0, 0)] && guide.is_none() && previous.is_none() {
                vec![BlockResult {
                    bi: 0,
                    bj: 0,
                    pos: first,
                    error: 0,
                    zone_pixels: 0,
                    swarm: None,
                    candidates: None,
                    optimum: None,
                    near_optimum: None,
                }]
            } else if let Some(g) = guided.as_mut() {
                wave.iter()
                    .zip(&zones)
                    .zip(&twins)
                    .map(|((&(bi, bj), zone), twins)| guided_block(g, sample, zone, bi, bj, settings, req.seed, twins.as_ref()))
                    .collect()
            } else if settings.search == Search::Exhaustive {
                let s = search.as_mut().expect("exhaustive search prepared");
                wave.iter()
                    .zip(&zones)
                    .zip(&twins)
                    .map(|((&(bi, bj), zone), twins)| exhaustive_block(s, sample, zone, bi, bj, settings, req.seed, twins.as_ref()))
                    .collect()
            } else {
                let lines = lines.as_ref().expect("sample lines prepared");
                wave.par_iter()
                    .zip(zones.par_iter().zip(hints.par_iter()).zip(twins.par_iter()))
                    .with_max_len(1)
                    .map(|(&(bi, bj), ((zone, hints), twins))| {
                        swarm_block(sample, lines, zone, bi, bj, settings, req.seed, hints, guide, twins.as_ref())
                    })
                    .collect()
            };
            if settings.optimum {
                let s = match (&mut exact, &mut search) {
                    (Some(s), _) | (None, Some(BlockSearch::Exact(s, _))) => s,
                    _ => unreachable!("an exact search is prepared for the optimum"),
                };
                for (r, zone) in found.iter_mut().zip(&zones).filter(|(r, _)| (r.bi, r.bj) != (0, 0)) {
                    // The optimum, and how many positions are within 3 % of it (paper 002's
                    // success criterion, Table 2): how hard the block problem is for a swarm.
                    let c = s.candidates(&zone.target, zone.origin, &zone.regions, NEAR_OPTIMUM);
                    r.optimum = Some(c.min_ssd);
                    r.near_optimum = Some(c.members.len());
                }
            }
            let sides: Vec<Sides> = zones.into_iter().map(|z| z.sides).collect();
            for (r, sides) in found.iter().zip(sides) {
                match &torus {
                    Some(t) => t.paste(&mut canvas, sample, r.pos, r.bi, r.bj, sides, settings.blend),
                    None => {
                        let dst = (r.bj * layout.stride(), r.bi * layout.stride());
                        paste_block(&mut canvas, sample, r.pos, dst, block, overlap, r.bj > 0, r.bi > 0, settings.blend);
                    }
                }
                done[(r.bi * cols + r.bj) as usize] = true;
                placed[(r.bi * cols + r.bj) as usize] = Some(r.pos);
            }
            results.extend(found);
        }
        results.sort_by_key(|r| (r.bi, r.bj));
        let (image, placement, seams) = match &torus {
            Some(t) => {
                let (image, placement) = canvas.finish();
                (image, placement, t.seam_grid())
            }
            None => {
                let (image, placement) = canvas.into_top_left(req.width, req.height).finish();
                (image, placement, layout.seam_grid(req.width, req.height))
            }
        };
        let mut diagnostics = diagnostics((cols, rows), settings, &results);
        if let Some(t) = &torus {
            diagnostics["tileable"] = json!(true);
            t.record_fit(&mut diagnostics);
        }
        Ok(Synthesis { image, seams: Some(seams), diagnostics, phases: Vec::new(), extras: Vec::new(), placement })
    }
}

/// The torus a tileable output is made on, or why there is none.
fn torus_of(cfg: &PatchSamplingConfig, sample: (u32, u32), output: (u32, u32)) -> Result<TorusGrid, String> {
    TorusGrid::of_blocks("patch sampling", cfg.block, cfg.overlap_or_derived(), sample, output)
}

/// What a block's search compares candidates with: the output over its zone, at
/// `origin + region` of `target` (the canvas itself, or on a torus a wrapped window of it), and
/// the sides the paste will cut or feather.
struct Zone<'a> {
    target: Cow<'a, RgbImage>,
    origin: (u32, u32),
    regions: Vec<Rect>,
    block: u32,
    sides: Sides,
    /// Where the block goes in the guide's target (guided synthesis only): the zone's origin on
    /// the plain grid; a hole's window or a torus block reads its own place, not the window's.
    guide_at: (u32, u32),
}
