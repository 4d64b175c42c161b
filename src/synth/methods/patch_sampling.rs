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
//! exhaustive search's criterion (`methods::guide`), with quilting's shrinking passes. Their
//! streams carry an `inpaint/` or `guided/…` prefix; plain syntheses keep their labels and pixels.
//!
//! **Threads.** A block depends only on blocks earlier in raster order that overlap its zone, so
//! the blocks with the same `2·bi + bj` ("waves") never touch each other's pixels and the swarm
//! searches of a wave run in parallel; every random draw comes from the block's own labelled
//! streams and every error is an exact integer, so the pixels are those of a raster-order run on
//! any number of threads.

use super::{BlockSearch, Engine};
use crate::image::RgbImage;
use crate::synth::error::SynthError;
use crate::synth::method::{Method, Request, Synthesis};
use crate::synth::params::{self, Choice, Default, MethodConfig, ParamError, ParamKind, ParamSpec, ParamValue, Params};
use crate::synth::primitives::block_grid::{BlockGrid, OverlapRule, paste_block};
use crate::synth::primitives::canvas::Canvas;
use crate::synth::primitives::overlap::{Rect, rect_ssd};
use crate::synth::primitives::overlap_search::{Candidates, OverlapSearch};
use crate::synth::primitives::pso::{self, ChaosParams, Outcome, SwarmParams};
use crate::synth::primitives::torus::{Sides, TorusGrid};
use crate::synth::primitives::zone_ssd::{PackedZone, SampleLines};
use crate::synth::rng::Stream;
use rayon::prelude::*;
use serde_json::{Value, json};
use std::borrow::Cow;

pub struct PatchSampling;

const PARAMS: &[ParamSpec] = &[
    ParamSpec {
        name: "block",
        kind: ParamKind::Int { min: 3, max: 4096 },
        default: Default::Int(30),
        doc: "B: side of the square patches, in pixels (paper: 30; at most the sample's smaller side)",
    },
    ParamSpec {
        name: "overlap",
        kind: ParamKind::Int { min: 1, max: 2048 },
        default: Default::Derived {
            rule: "round(block / 6)",
            compute: |p| Some(ParamValue::Int(super::default_overlap(p.int("block").ok()?))),
        },
        doc: "w_E: width of the boundary zone shared with the already synthesised output (paper: not given; at most block / 2)",
    },
    ParamSpec {
        name: "search",
        kind: ParamKind::Choice(Search::NAMES),
        default: Default::Str("cpso"),
        doc: "best-match search: cpso (paper 002), pso (its baseline), exhaustive (every position; with tolerance > 0 Liang et al.'s sampler)",
    },
    ParamSpec {
        name: "particles",
        kind: ParamKind::Int { min: 1, max: 100_000 },
        default: Default::Int(20),
        doc: "M: swarm size (pso, cpso; paper: 20, chosen from 10/20/30)",
    },
    ParamSpec {
        name: "iterations",
        kind: ParamKind::Int { min: 0, max: 1_000_000 },
        default: Default::Int(300),
        doc: "T_max: swarm iterations per block after the initial evaluation (paper: 300)",
    },
    ParamSpec {
        name: "c1",
        kind: ParamKind::Float { min: 0.0, max: 10.0 },
        default: Default::Float(1.47),
        doc: "cognitive acceleration coefficient (paper: 1.47)",
    },
    ParamSpec {
        name: "c2",
        kind: ParamKind::Float { min: 0.0, max: 10.0 },
        default: Default::Float(1.47),
        doc: "social acceleration coefficient (paper: 1.47)",
    },
    ParamSpec {
        name: "inertia",
        kind: ParamKind::Float { min: 0.0, max: 2.0 },
        default: Default::Float(0.729),
        doc: "ω: inertia weight (paper: not given; 0.729 is the standard value for c ≈ 1.47)",
    },
    ParamSpec {
        name: "vmax",
        kind: ParamKind::Float { min: 0.0, max: 1.0 },
        default: Default::Float(0.2),
        doc: "velocity clamp per axis as a fraction of the search range (paper: not given)",
    },
    ParamSpec {
        name: "distance_threshold",
        kind: ParamKind::Float { min: 0.0, max: 1.0 },
        default: Default::Float(0.01),
        doc: "T: premature convergence needs the mean particle distance / box diagonal below this (cpso; paper: 0.01)",
    },
    ParamSpec {
        name: "variance_threshold",
        kind: ParamKind::Float { min: 0.0, max: 1e12 },
        default: Default::Float(0.001),
        doc: "S: … and the normalised fitness variance (eqs. 4-5) below this (cpso; paper: 0.001)",
    },
    ParamSpec {
        name: "logistic_mu",
        kind: ParamKind::Float { min: 1.0, max: 4.0 },
        default: Default::Float(4.0),
        doc: "μ of the chaos search's logistic map z ← μz(1−z) (cpso; paper: not given; 4 is fully chaotic)",
    },
    ParamSpec {
        name: "chaos_steps",
        kind: ParamKind::Int { min: 1, max: 1_000_000 },
        default: Default::Int(200),
        doc: "N_c: chaotic points evaluated per chaos search, all of them unless one beats delta (cpso; paper: 200)",
    },
    ParamSpec {
        name: "rediversify",
        kind: ParamKind::Choice(Rediversify::NAMES),
        default: Default::Str("worse-half"),
        doc: "after a chaos search: worse-half restarts the worse half of the swarm at the next chaotic points; none only replaces the global best (cpso; reconstructed)",
    },
    ParamSpec {
        name: "update",
        kind: ParamKind::Choice(Update::NAMES),
        default: Default::Str("synchronous"),
        doc: "when the swarm's best is updated: after all particles moved (synchronous, as eq. 1's t−1 implies) or after each particle (pso, cpso; reconstructed)",
    },
    ParamSpec {
        name: "delta_rms",
        kind: ParamKind::Float { min: 0.0, max: 255.0 },
        default: Default::Float(10.0),
        doc: "early stop when the zone error d < A·3·delta_rms² (an RMS difference per channel); 0 disables (pso, cpso; paper: δ named, no value)",
    },
    ParamSpec {
        name: "tolerance",
        kind: ParamKind::Float { min: 0.0, max: 10.0 },
        default: Default::Float(0.2),
        doc: "ε of Liang et al.'s sampler: uniform among patches with RMS zone error < ε·RMS zone intensity, else the best; 0: always the best (exhaustive)",
    },
    ParamSpec {
        name: "candidates",
        kind: ParamKind::Choice(CandidateRule::NAMES),
        default: Default::Str("liang"),
        doc: "exhaustive with tolerance > 0: liang (RMS error below tolerance x RMS zone intensity, Liang et al.) or near-best (error within (1 + tolerance) x the best, Efros-Freeman's rule; not in the paper)",
    },
    ParamSpec {
        name: "engine",
        kind: ParamKind::Choice(Engine::NAMES),
        default: Default::Str("auto"),
        doc: "how exhaustive search scores positions: fft (FFT correlation + exact integer re-check) or direct (brute-force sums, the 'blind' search of paper 002's timing), identical results; pyramid: coarse-to-fine for big samples; auto: fft for samples of at most 512x512 pixels, pyramid above (recorded resolved)",
    },
    ParamSpec {
        name: "blend",
        kind: ParamKind::Choice(Blend::NAMES),
        default: Default::Str("feather"),
        doc: "how a block meets the output over its zone: feather (Liang's linear blend, the paper) or cut (not in the paper: Efros-Freeman minimum-error boundary cut, which hides mismatches instead of ghosting them)",
    },
    ParamSpec {
        name: "polish_radius",
        kind: ParamKind::Int { min: 0, max: 4096 },
        default: Default::Int(0),
        doc: "not in the paper: after the swarm, also try every position within this Chebyshev radius of its best (0: off, faithful)",
    },
    ParamSpec {
        name: "continuations",
        kind: ParamKind::Bool,
        default: Default::Bool(false),
        doc: "not in the paper: after the swarm, also score the natural continuations of the left and top neighbours (their sample positions one stride on) and keep one that is strictly better; on roofs, walls and tiles the swarm misses these exact matches and rows drift (false: faithful; always on with augment, whose turned copies joined by rough matches look mushy)",
    },
    ParamSpec {
        name: "first_x",
        kind: ParamKind::Int { min: -1, max: 65_535 },
        default: Default::Int(-1),
        doc: "sample x of the first block; -1: drawn from the seed (set with first_y, e.g. for paper 002's fixed-first-block experiment)",
    },
    ParamSpec {
        name: "first_y",
        kind: ParamKind::Int { min: -1, max: 65_535 },
        default: Default::Int(-1),
        doc: "sample y of the first block; -1: drawn from the seed",
    },
    ParamSpec {
        name: "diagnostics",
        kind: ParamKind::Bool,
        default: Default::Bool(false),
        doc: "record every block's search (position, error found, iterations, chaos searches, evaluations) in the manifest",
    },
    ParamSpec {
        name: "record_optimum",
        kind: ParamKind::Bool,
        default: Default::Bool(false),
        doc: "also record each block's exhaustive optimum (costs an exhaustive search per block; implies diagnostics)",
    },
];

/// Blocks in order of `2·bi + bj`: within a wave no two blocks overlap (needs `2·overlap ≤
/// block`), and every block a block's zone reads from is in an earlier wave.
fn waves(grid: &BlockGrid) -> Vec<Vec<(u32, u32)>> {
    let last = 2 * (grid.rows - 1) + (grid.cols - 1);
    (0..=last)
        .map(|t| (0..grid.rows).filter_map(|bi| t.checked_sub(2 * bi).filter(|&bj| bj < grid.cols).map(|bj| (bi, bj))).collect())
        .collect()
}

crate::choice! {
    /// The best-match search (`search`).
    pub enum Search {
        /// Chaos PSO, paper 002.
        Cpso = "cpso",
        /// Plain PSO, its baseline: the same swarm without the chaos part.
        Pso = "pso",
        /// Every position; with `tolerance > 0` Liang et al.'s sampler.
        Exhaustive = "exhaustive",
    }
}

crate::choice! {
    /// What happens to the swarm after a chaos search (`rediversify`); see [`pso::Rediversify`].
    pub enum Rediversify {
        /// The worse half of the swarm restarts at the next chaotic points.
        WorseHalf = "worse-half",
        /// Only the global best is replaced.
        None = "none",
    }
}

impl From<Rediversify> for pso::Rediversify {
    fn from(r: Rediversify) -> pso::Rediversify {
        match r {
            Rediversify::WorseHalf => pso::Rediversify::WorseHalf,
            Rediversify::None => pso::Rediversify::None,
        }
    }
}

crate::choice! {
    /// When the swarm's best is updated (`update`); see [`pso::UpdateOrder`].
    pub enum Update {
        /// After all particles moved.
        Synchronous = "synchronous",
        /// After each particle.
        Asynchronous = "asynchronous",
    }
}

impl From<Update> for pso::UpdateOrder {
    fn from(u: Update) -> pso::UpdateOrder {
        match u {
            Update::Synchronous => pso::UpdateOrder::Synchronous,
            Update::Asynchronous => pso::UpdateOrder::Asynchronous,
        }
    }
}

crate::choice! {
    /// Which positions an exhaustive search with `tolerance > 0` picks among (`candidates`).
    pub enum CandidateRule {
        /// RMS zone error below tolerance × RMS zone intensity (Liang et al.).
        Liang = "liang",
        /// Zone error within (1 + tolerance) × the best (Efros–Freeman's rule; not in the paper).
        NearBest = "near-best",
    }
}

crate::choice! {
    /// How a block meets the output over its zone (`blend`).
    pub enum Blend {
        /// Liang's linear blend, as in the paper.
        Feather = "feather",
        /// The minimum-error boundary cut (not in the paper).
        Cut = "cut",
    }
}

impl From<Blend> for OverlapRule {
    fn from(b: Blend) -> OverlapRule {
        match b {
            Blend::Feather => OverlapRule::Feather,
            Blend::Cut => OverlapRule::Cut,
        }
    }
}

/// Patch sampling's parameters, typed: one field per entry of its parameter table, the search
/// settings grouped by the search they belong to.
#[derive(Clone, Debug, PartialEq)]
pub struct PatchSamplingConfig {
    /// `block`: B, side of the square patches (3..=4096, at most the sample's smaller side).
    pub block: u32,
    /// `overlap`: w_E, width of the boundary zone (1..=2048, at most block / 2); `None`: derived,
    /// `round(block / 6)`.
    pub overlap: Option<u32>,
    /// `search`: chaos PSO, PSO or exhaustive.
    pub search: Search,
    /// The swarm's settings (`search` = cpso or pso).
    pub swarm: SwarmConfig,
    /// The chaos part of CPSO (`search` = cpso).
    pub chaos: ChaosConfig,
    /// Exhaustive search's settings (`search` = exhaustive).
    pub exhaustive: ExhaustiveConfig,
    /// `blend`: feathering (the paper) or the boundary cut.
    pub blend: Blend,
    /// `first_x`: sample x of the first block; `None` (-1 in a job file): drawn from the seed.
    pub first_x: Option<u32>,
    /// `first_y`: sample y of the first block; `None` (-1 in a job file): drawn from the seed.
    pub first_y: Option<u32>,
    /// `diagnostics`: record every block's search in the manifest.
    pub diagnostics: bool,
    /// `record_optimum`: also record each block's exhaustive optimum (implies `diagnostics`).
    pub record_optimum: bool,
}

/// The particle swarm of `search` = cpso and pso.
#[derive(Clone, Debug, PartialEq)]
pub struct SwarmConfig {
    /// `particles`: M, the swarm size (1..=100000).
    pub particles: u32,
    /// `iterations`: T_max, iterations per block after the initial evaluation (0..=1000000).
    pub iterations: u32,
    /// `c1`: cognitive acceleration coefficient (0..=10).
    pub c1: f64,
    /// `c2`: social acceleration coefficient (0..=10).
    pub c2: f64,
    /// `inertia`: ω, the inertia weight (0..=2).
    pub inertia: f64,
    /// `vmax`: velocity clamp per axis as a fraction of the search range (0..=1; must be > 0).
    pub vmax: f64,
    /// `update`: when the swarm's best is updated.
    pub update: Update,
    /// `delta_rms`: early stop below this RMS zone difference per channel; 0 disables (0..=255).
    pub delta_rms: f64,
    /// `polish_radius`: exhaustive search within this Chebyshev radius of the swarm's best; 0: off.
    pub polish_radius: u32,
    /// `continuations`: also score the neighbours' natural continuations after the swarm.
    pub continuations: bool,
}

/// The chaos search of `search` = cpso.
#[derive(Clone, Debug, PartialEq)]
pub struct ChaosConfig {
    /// `distance_threshold`: T, premature convergence needs the mean particle distance / box
    /// diagonal below this (0..=1).
    pub distance_threshold: f64,
    /// `variance_threshold`: S, … and the normalised fitness variance below this.
    pub variance_threshold: f64,
    /// `logistic_mu`: μ of the logistic map (1..=4).
    pub logistic_mu: f64,
    /// `chaos_steps`: N_c, chaotic points per chaos search (1..=1000000).
    pub chaos_steps: u32,
    /// `rediversify`: what happens to the swarm after a chaos search.
    pub rediversify: Rediversify,
}

/// Exhaustive search (`search` = exhaustive).
#[derive(Clone, Debug, PartialEq)]
pub struct ExhaustiveConfig {
    /// `tolerance`: ε of Liang et al.'s sampler; 0: always the best (0..=10).
    pub tolerance: f64,
    /// `candidates`: which positions a tolerance admits.
    pub candidates: CandidateRule,
    /// `engine`: the exact search (fft or direct, same results), the pyramid, or auto (by sample size).
    pub engine: Engine,
}

impl std::default::Default for PatchSamplingConfig {
    fn default() -> PatchSamplingConfig {
        PatchSamplingConfig {
            block: 30,
            overlap: None,
            search: Search::Cpso,
            swarm: SwarmConfig::default(),
            chaos: ChaosConfig::default(),
            exhaustive: ExhaustiveConfig::default(),
            blend: Blend::Feather,
            first_x: None,
            first_y: None,
            diagnostics: false,
            record_optimum: false,
        }
    }
}

impl std::default::Default for SwarmConfig {
    fn default() -> SwarmConfig {
        SwarmConfig {
            particles: 20,
            iterations: 300,
            c1: 1.47,
            c2: 1.47,
            inertia: 0.729,
            vmax: 0.2,
            update: Update::Synchronous,
            delta_rms: 10.0,
            polish_radius: 0,
            continuations: false,
        }
    }
}

impl std::default::Default for ChaosConfig {
    fn default() -> ChaosConfig {
        ChaosConfig {
            distance_threshold: 0.01,
            variance_threshold: 0.001,
            logistic_mu: 4.0,
            chaos_steps: 200,
            rediversify: Rediversify::WorseHalf,
        }
    }
}

impl std::default::Default for ExhaustiveConfig {
    fn default() -> ExhaustiveConfig {
        ExhaustiveConfig { tolerance: 0.2, candidates: CandidateRule::Liang, engine: Engine::Auto }
    }
}

impl PatchSamplingConfig {
    /// The zone width: the given one, else the derived default `round(block / 6)`.
    pub fn overlap_or_derived(&self) -> u32 {
        self.overlap.unwrap_or_else(|| super::default_overlap(i64::from(self.block)) as u32)
    }
}

impl SwarmConfig {
    /// The optimiser's parameters, with `chaos` for CPSO (no early stop: that is per block).
    pub fn params(&self, chaos: Option<ChaosParams>) -> SwarmParams {
        SwarmParams {
            particles: self.particles as usize,
            max_iterations: self.iterations,
            c1: self.c1,
            c2: self.c2,
            inertia: self.inertia,
            vmax_fraction: self.vmax,
            stop_below: None,
            update: self.update.into(),
            chaos,
            trace: false,
        }
    }
}

impl ChaosConfig {
    /// The optimiser's chaos parameters.
    pub fn params(&self) -> ChaosParams {
        ChaosParams {
            distance_threshold: self.distance_threshold,
            variance_threshold: self.variance_threshold,
            mu: self.logistic_mu,
            steps: self.chaos_steps,
            rediversify: self.rediversify.into(),
        }
    }
}

impl MethodConfig for PatchSamplingConfig {
    const METHOD: &'static str = "patch-sampling";

    fn to_params(&self) -> Vec<(String, ParamValue)> {
        let (sw, ch, ex) = (&self.swarm, &self.chaos, &self.exhaustive);
        let mut v = vec![params::int("block", self.block)];
        v.extend(self.overlap.map(|o| params::int("overlap", o)));
        v.extend([
            params::word("search", self.search),
            params::int("particles", sw.particles),
            params::int("iterations", sw.iterations),
            params::float("c1", sw.c1),
            params::float("c2", sw.c2),
            params::float("inertia", sw.inertia),
            params::float("vmax", sw.vmax),
            params::float("distance_threshold", ch.distance_threshold),
            params::float("variance_threshold", ch.variance_threshold),
            params::float("logistic_mu", ch.logistic_mu),
            params::int("chaos_steps", ch.chaos_steps),
            params::word("rediversify", ch.rediversify),
            params::word("update", sw.update),
            params::float("delta_rms", sw.delta_rms),
            params::float("tolerance", ex.tolerance),
            params::word("candidates", ex.candidates),
            params::word("engine", ex.engine),
            params::word("blend", self.blend),
            params::int("polish_radius", sw.polish_radius),
            params::boolean("continuations", sw.continuations),
            params::int("first_x", self.first_x.map_or(-1, i64::from)),
            params::int("first_y", self.first_y.map_or(-1, i64::from)),
            params::boolean("diagnostics", self.diagnostics),
            params::boolean("record_optimum", self.record_optimum),
        ]);
        v
    }

    fn from_params(p: &Params) -> Result<PatchSamplingConfig, SynthError> {
        Ok(PatchSamplingConfig {
            block: p.uint("block")?,
            overlap: Some(p.uint("overlap")?),
            search: p.choice("search")?,
            swarm: SwarmConfig {
                particles: p.uint("particles")?,
                iterations: p.uint("iterations")?,
                c1: p.float("c1")?,
                c2: p.float("c2")?,
                inertia: p.float("inertia")?,
                vmax: p.float("vmax")?,
                update: p.choice("update")?,
                delta_rms: p.float("delta_rms")?,
                polish_radius: p.uint("polish_radius")?,
                continuations: p.bool("continuations")?,
            },
            chaos: ChaosConfig {
                distance_threshold: p.float("distance_threshold")?,
                variance_threshold: p.float("variance_threshold")?,
                logistic_mu: p.float("logistic_mu")?,
                chaos_steps: p.uint("chaos_steps")?,
                rediversify: p.choice("rediversify")?,
            },
            exhaustive: ExhaustiveConfig {
                tolerance: p.float("tolerance")?,
                candidates: p.choice("candidates")?,
                engine: p.choice("engine")?,
            },
            blend: p.choice("blend")?,
            first_x: first(p, "first_x")?,
            first_y: first(p, "first_y")?,
            diagnostics: p.bool("diagnostics")?,
            record_optimum: p.bool("record_optimum")?,
        })
    }
}

/// `first_x` / `first_y`: -1 for "drawn from the seed", else a sample coordinate.
fn first(p: &Params, name: &str) -> Result<Option<u32>, SynthError> {
    match p.int(name)? {
        -1 => Ok(None),
        _ => p.uint(name).map(Some),
    }
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

/// The block positions a search may copy from, when not every one: the flags (row-major over
/// the `nx`-wide grid of positions) and, for the swarms, which move over every position, the
/// allowed position each one stands for: the nearest in 4-connected steps, ties to the one a
/// breadth-first search from the allowed positions (started in row-major order) reaches first.
/// So a swarm is scored and placed only at allowed positions, and its draws stay those of its
/// streams.
struct Allowed {
    flags: Vec<bool>,
    nearest: Vec<u32>,
    nx: u32,
}

impl Allowed {
    fn new(flags: Vec<bool>, nx: u32) -> Allowed {
        let n = flags.len();
        let nxu = nx as usize;
        let mut nearest = vec![u32::MAX; n];
        let mut queue = std::collections::VecDeque::new();
        for (i, _) in flags.iter().enumerate().filter(|(_, a)| **a) {
            nearest[i] = i as u32;
            queue.push_back(i);
        }
        while let Some(p) = queue.pop_front() {
            let (x, y) = (p % nxu, p / nxu);
            for q in [(x > 0).then(|| p - 1), (x + 1 < nxu).then(|| p + 1), (y > 0).then(|| p - nxu), (p + nxu < n).then(|| p + nxu)]
                .into_iter()
                .flatten()
            {
                if nearest[q] == u32::MAX {
                    nearest[q] = nearest[p];
                    queue.push_back(q);
                }
            }
        }
        Allowed { flags, nearest, nx }
    }

    fn allows(&self, (x, y): (u32, u32)) -> bool {
        self.flags[(y * self.nx + x) as usize]
    }

    fn nearest(&self, (x, y): (u32, u32)) -> (u32, u32) {
        let i = self.nearest[(y * self.nx + x) as usize];
        (i % self.nx, i / self.nx)
    }
}

/// The twin rule of one block (several samples' atlas with `augment`): a block must not show a
/// turned or mirrored copy of the pixels a neighbour already placed shows
/// ([`crate::synth::atlas::Atlas::twins`]). The swarms treat such positions as they treat masked
/// ones (each stands for its nearest position that is allowed and no twin); the exhaustive
/// searches leave them out of their candidates.
struct Twins<'a> {
    constraints: &'a crate::synth::constraints::Constraints<'a>,
    /// The sample positions of the blocks placed around this one.
    neighbours: Vec<(u32, u32)>,
    block: u32,
}

impl<'a> Twins<'a> {
    /// The rule for a block whose placed neighbours are at `neighbours`; `None` when no block can
    /// be a twin (no transformed copies, or no neighbour yet).
    fn of(constraints: &'a crate::synth::constraints::Constraints<'a>, neighbours: Vec<(u32, u32)>, block: u32) -> Option<Twins<'a>> {
        let copies = constraints.atlas.is_some_and(|a| a.has_copies());
        (copies && !neighbours.is_empty()).then_some(Twins { constraints, neighbours, block })
    }

    fn is_twin(&self, at: (u32, u32)) -> bool {
        self.constraints.is_twin(at, &self.neighbours, self.block)
    }

    /// The position `p` stands for: itself unless it is a twin, else the nearest position (in
    /// 4-connected steps over the `nx × ny` grid of positions) that `allowed` allows and that is
    /// no twin, ring by ring, each ring in a fixed order (up, right, down, left of each step);
    /// `p` itself when there is none.
    fn resolve(&self, p: (u32, u32), (nx, ny): (u32, u32), allowed: Option<&Allowed>) -> (u32, u32) {
        if !self.is_twin(p) {
            return p;
        }
        let ok = |q: (u32, u32)| allowed.is_none_or(|a| a.allows(q)) && !self.is_twin(q);
        let (px, py) = (i64::from(p.0), i64::from(p.1));
        for d in 1..=i64::from(nx + ny) {
            // The ring at Manhattan distance d, from the top going clockwise.
            for k in 0..4 * d {
                let (side, t) = (k / d, k % d);
                let (dx, dy) = match side {
                    0 => (t, t - d),
                    1 => (d - t, t),
                    2 => (-t, d - t),
                    _ => (t - d, -t),
                };
                let (x, y) = (px + dx, py + dy);
                if x < 0 || y < 0 || x >= i64::from(nx) || y >= i64::from(ny) {
                    continue;
                }
                if ok((x as u32, y as u32)) {
                    return (x as u32, y as u32);
                }
            }
        }
        p
    }
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
    fn algorithm_version_of(&self, params: &Params) -> u32 {
        super::engine_version(params, "engine", self.algorithm_version())
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
        if let Some(guide) = req.constraints.guide {
            if req.constraints.fill.is_some() || req.tileable {
                return Err(SynthError::Failed("guided synthesis does not combine with inpainting or tileable output yet".into()));
            }
            return self.synthesize_guided(req, &cfg, settings, guide);
        }
        if let Some(region) = req.constraints.fill {
            return self.inpaint(req, &cfg, settings, region);
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
        };
        let settings = &settings;
        let mut pick = |window: &RgbImage, regions: &[Rect], (bi, bj): (u32, u32)| {
            let zone = Zone { target: Cow::Borrowed(window), origin: (0, 0), regions: regions.to_vec(), block, sides: Sides::default() };
            let r = match (&mut search, &lines) {
                (Some(s), _) => exhaustive_block(s, sample, &zone, bi, bj, settings, req.seed, None),
                (None, Some(lines)) => swarm_block(sample, lines, &zone, bi, bj, settings, req.seed, &[], None, None),
                (None, None) => unreachable!("a search is prepared"),
            };
            (r.pos, r.candidates)
        };
        let mut synthesis = super::inpaint::fill(req, region, &how, &mut pick)?;
        synthesis.diagnostics["search"] = json!(settings.search.name());
        Ok(synthesis)
    }

    /// Guided synthesis (texture transfer, Efros & Freeman 2001 §3): each block minimises its
    /// zone error weighed against its guide error ([`GuideTerm`]), with the method's own search;
    /// then, as quilting does, `passes − 1` more passes with blocks a third smaller (never below
    /// 6 px), each matched over the whole block against the previous pass, at the same weight.
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
            let layout = BlockGrid::new(block, overlap, req.width, req.height);
            let (cw, ch) = layout.canvas();
            let term = GuideTerm {
                source: &guide.source,
                lines: SampleLines::new(&guide.source),
                target: RgbImage::from_fn(cw, ch, |x, y| guide.target.get(x.min(req.width - 1), y.min(req.height - 1))),
                weight: guide.weight,
            };
            let mut synthesis = self.grid(req, &settings, block, overlap, previous.as_ref(), Some(&term))?;
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
            let cfg = PatchSamplingConfig::from_params(req.params)?;
            Some(torus_of(&cfg, sample.dimensions(), (req.width, req.height)).map_err(SynthError::Failed)?)
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
                            regions: t.regions(bi, bj, sides),
                            block,
                            sides,
                        }
                    }
                    None => Zone {
                        target: Cow::Borrowed(&canvas.image),
                        origin: layout.origin(bi, bj),
                        regions: if previous.is_some() { vec![Rect::new(0, 0, block, block)] } else { layout.overlap_regions(bi, bj) },
                        block,
                        sides: Sides { left: bj > 0, top: bi > 0, ..Sides::default() },
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

/// `SSD(sample block at (x, y), output block, Ω)` (eq. 7), rectangle by rectangle: the reference
/// the swarms' packed evaluation ([`PackedZone::ssd`]) is checked against.
fn zone_error(sample: &RgbImage, canvas: &RgbImage, (x, y): (u32, u32), origin: (u32, u32), regions: &[Rect]) -> u64 {
    regions.iter().map(|r| rect_ssd(sample, x + r.x, y + r.y, canvas, origin.0 + r.x, origin.1 + r.y, r.w, r.h)).sum()
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
}

/// The swarm search of one block (§4.2 step 5, §4.3).
#[allow(clippy::too_many_arguments)]
fn swarm_block(
    sample: &RgbImage,
    lines: &SampleLines,
    zone: &Zone,
    bi: u32,
    bj: u32,
    settings: &Settings,
    seed: u64,
    hints: &[(u32, u32)],
    guide: Option<&GuideTerm>,
    twins: Option<&Twins>,
) -> BlockResult {
    // A thread searches one block at a time and the search starts no parallel work, so the
    // thread's memo is never borrowed twice; should that change, a fresh memo is still correct.
    MEMO.with(|m| match m.try_borrow_mut() {
        Ok(mut memo) => swarm_search(sample, lines, zone, (bi, bj), settings, seed, hints, guide, twins, &mut memo),
        Err(_) => swarm_search(sample, lines, zone, (bi, bj), settings, seed, hints, guide, twins, &mut Memo::default()),
    })
}

#[allow(clippy::too_many_arguments)]
fn swarm_search(
    sample: &RgbImage,
    lines: &SampleLines,
    zone: &Zone,
    (bi, bj): (u32, u32),
    settings: &Settings,
    seed: u64,
    hints: &[(u32, u32)],
    guide: Option<&GuideTerm>,
    twins: Option<&Twins>,
    memo: &mut Memo,
) -> BlockResult {
    let packed = PackedZone::new(&zone.target, zone.origin, &zone.regions);
    let zone_pixels: u64 = zone.regions.iter().map(|r| r.area()).sum();
    let (nx, ny) = (sample.width() - zone.block + 1, sample.height() - zone.block + 1);
    let hi = [(nx - 1) as f64, (ny - 1) as f64];
    let mut params = settings.swarm;
    if settings.delta_rms > 0.0 && guide.is_none() {
        params.stop_below = Some(zone_pixels as f64 * 3.0 * settings.delta_rms * settings.delta_rms);
    }
    // Guided: the guide's SSD over the whole block where it goes, weighed against the zone's.
    let guide_zone = guide.map(|g| (g, PackedZone::new(&g.target, zone.origin, &[Rect::new(0, 0, zone.block, zone.block)])));
    let (k_texture, k_guide) = guide.map_or((1.0, 0.0), |g| g.weights(zone_pixels, zone.block));
    // A position stands for its nearest allowed one when a mask rules some out, and a twin of a
    // neighbour for the nearest allowed position that is none.
    let at = |pos: (u32, u32)| {
        let pos = settings.allowed.as_ref().map_or(pos, |a| a.nearest(pos));
        twins.map_or(pos, |t| t.resolve(pos, (nx, ny), settings.allowed.as_ref()))
    };
    let value = |pos: (u32, u32)| {
        let pos = at(pos);
        match &guide_zone {
            None => packed.ssd(lines, pos) as f64,
            Some((g, gz)) => k_texture * packed.ssd(lines, pos) as f64 + k_guide * gz.ssd(&g.lines, pos) as f64,
        }
    };
    // The fitness at a position is a pure function of the rounded position: memoise it. This
    // changes nothing but the time (the swarm often revisits positions once it has converged).
    // (An SSD is an integer below 2^53: exact as an f64, so plain searches order as before.)
    memo.start(nx as usize * ny as usize);
    let mut fitness_at =
        |pos: (u32, u32)| f64::from_bits(memo.get_or_insert(pos.1 as usize * nx as usize + pos.0 as usize, || value(pos).to_bits()));
    let label = &settings.label;
    let mut swarm = Stream::new(seed, &format!("{label}cpso/swarm/bi={bi}/bj={bj}"));
    let mut chaos = Stream::new(seed, &format!("{label}cpso/chaos/bi={bi}/bj={bj}"));
    let outcome = pso::optimise(&[0.0, 0.0], &hi, &params, &mut swarm, &mut chaos, |x| fitness_at(round_position(x, hi)));
    let mut pos = round_position(&outcome.best, hi);
    let mut best = outcome.best_fitness;
    let r = settings.polish_radius;
    if r > 0 {
        // Row-major over the window; strictly better only, so ties keep the swarm's choice.
        let (x0, y0) = (pos.0.saturating_sub(r), pos.1.saturating_sub(r));
        let (x1, y1) = ((pos.0 + r).min(nx - 1), (pos.1 + r).min(ny - 1));
        for y in y0..=y1 {
            for x in x0..=x1 {
                let e = fitness_at((x, y));
                if e < best {
                    best = e;
                    pos = (x, y);
                }
            }
        }
    }
    // In the given order, strictly better only, so ties keep the swarm's (or polish's) choice.
    for &h in hints {
        let e = fitness_at(h);
        if e < best {
            best = e;
            pos = h;
        }
    }
    let pos = at(pos);
    let error = if guide.is_none() { best as u64 } else { packed.ssd(lines, pos) };
    BlockResult { bi, bj, pos, error, zone_pixels, swarm: Some(outcome), candidates: None, optimum: None, near_optimum: None }
}

/// The exhaustive search of one block of a guided synthesis ([`super::guide::GuidedSearch`], exact
/// over the allowed positions): the best weighted error (row-major first on ties) with `tolerance
/// = 0`, else uniform among the positions within `(1 + tolerance)` of it (Efros–Freeman's rule:
/// Liang's threshold is relative to the zone's intensity, which a guided error does not have).
/// A neighbour's twins ([`Twins`]) are left out.
#[allow(clippy::too_many_arguments)]
fn guided_block(
    search: &mut super::guide::GuidedSearch,
    sample: &RgbImage,
    zone: &Zone,
    bi: u32,
    bj: u32,
    settings: &Settings,
    seed: u64,
    twins: Option<&Twins>,
) -> BlockResult {
    let tolerance = settings.tolerance.max(0.0);
    let mut members = search.candidates(&zone.target, zone.origin, &zone.regions, zone.origin, tolerance);
    if let Some(t) = twins {
        // Without the neighbours' twins; when every member is one, a wider set (as quilting).
        let untwinned = |m: &[(u32, u32)]| -> Vec<(u32, u32)> { m.iter().copied().filter(|&p| !t.is_twin(p)).collect() };
        let mut kept = untwinned(&members);
        for wider in [0.25, 1.0, 4.0] {
            if !kept.is_empty() {
                break;
            }
            kept = untwinned(&search.candidates(&zone.target, zone.origin, &zone.regions, zone.origin, tolerance + wider));
        }
        if !kept.is_empty() {
            members = kept;
        }
    }
    let pos = if settings.tolerance <= 0.0 || members.len() == 1 {
        members[0]
    } else {
        let mut s = Stream::new(seed, &format!("{}liang/pick/bi={bi}/bj={bj}", settings.label));
        members[s.below_usize(members.len())]
    };
    let zone_pixels: u64 = zone.regions.iter().map(|r| r.area()).sum();
    let error = zone_error(sample, &zone.target, pos, zone.origin, &zone.regions);
    BlockResult { bi, bj, pos, error, zone_pixels, swarm: None, candidates: Some(members.len()), optimum: None, near_optimum: None }
}

thread_local! {
    /// Each thread's memo of zone errors, reused from block to block.
    static MEMO: std::cell::RefCell<Memo> = std::cell::RefCell::default();
}

/// Zone errors of one block by position index, kept across blocks so that a block neither
/// allocates nor clears a table the size of the search box: only a bit per position, "known in
/// this block", is cleared. The bits are small enough to stay in the nearest cache, so a first
/// visit learns that it must compute without waiting for the value's cache line.
#[derive(Default)]
struct Memo {
    known: Vec<u64>,
    values: Vec<u64>,
}

impl Memo {
    /// Forgets the previous block; `positions` entries.
    fn start(&mut self, positions: usize) {
        self.known.clear();
        self.known.resize(positions.div_ceil(64), 0);
        if self.values.len() < positions {
            self.values.resize(positions, 0);
        }
    }

    #[inline]
    fn get_or_insert(&mut self, index: usize, compute: impl FnOnce() -> u64) -> u64 {
        let (word, bit) = (index / 64, 1u64 << (index % 64));
        if self.known[word] & bit != 0 {
            return self.values[index];
        }
        let value = compute();
        self.known[word] |= bit;
        self.values[index] = value;
        value
    }
}

/// A particle's patch: its position rounded half away from zero, clamped to the box. The same
/// positions as `v.round().clamp(0.0, h)`, without a call to the C library's `round`: clamping
/// first changes nothing (`h` is an integer), and for `0 ≤ c ≤ h`, `t = trunc(c)` and `c − t` are
/// exact, so `c − t ≥ 0.5` is exactly where `round` goes up, and then `t + 1 ≤ h` (NaN gives 0
/// either way).
#[inline]
fn round_position(x: &[f64], hi: [f64; 2]) -> (u32, u32) {
    let r = |v: f64, h: f64| {
        let c = v.clamp(0.0, h);
        let t = c as u32;
        if c - f64::from(t) >= 0.5 { t + 1 } else { t }
    };
    (r(x[0], hi[0]), r(x[1], hi[1]))
}

/// Exhaustive search of one block (§4.4). `tolerance = 0`: the best position (row-major first on
/// ties). `tolerance = ε > 0`, `candidates = "liang"`: Liang et al.'s choice, uniform among
/// `{ d < ε²·Σ_Ω |out(p)|² }` (the same set as `sqrt(d/A) < ε·sqrt(Σ|out|²/A)`, decided on exact
/// integers against one `f64` threshold), the best position if that set is empty.
/// `candidates = "near-best"`: uniform among `{ d ≤ (1 + ε)·d_min }`. A neighbour's twins
/// ([`Twins`]) are never candidates: when the best positions are all twins, the best that is
/// none among a near-best set widened by 0.25, 1 and 4 (as quilting), and a twin only when that
/// finds none.
#[allow(clippy::too_many_arguments)]
fn exhaustive_block(
    search: &mut BlockSearch,
    sample: &RgbImage,
    zone: &Zone,
    bi: u32,
    bj: u32,
    settings: &Settings,
    seed: u64,
    twins: Option<&Twins>,
) -> BlockResult {
    let no_twin = |m: &(u32, u32, u64)| twins.is_none_or(|t| !t.is_twin((m.0, m.1)));
    let (canvas, origin, regions) = (&*zone.target, zone.origin, zone.regions.clone());
    let allows = |m: &(u32, u32, u64)| settings.allowed.as_ref().is_none_or(|a| a.allows((m.0, m.1)));
    let zone_pixels: u64 = regions.iter().map(|r| r.area()).sum();
    let mut result =
        BlockResult { bi, bj, pos: (0, 0), error: 0, zone_pixels, swarm: None, candidates: Some(0), optimum: None, near_optimum: None };
    let eps = settings.tolerance;
    let mut best: Option<Candidates> = None;
    let members: Vec<(u32, u32, u64)> = if eps <= 0.0 {
        Vec::new()
    } else if settings.candidates == CandidateRule::NearBest {
        let c = search.candidates(canvas, origin, &regions, eps);
        result.optimum = Some(c.min_ssd);
        c.members
    } else {
        let energy: u64 = regions
            .iter()
            .flat_map(|r| (0..r.h).flat_map(move |dy| (0..r.w).map(move |dx| (r.x + dx, r.y + dy))))
            .map(|(dx, dy)| canvas.get(origin.0 + dx, origin.1 + dy).iter().map(|&c| c as u64 * c as u64).sum::<u64>())
            .sum();
        let threshold = eps * eps * energy as f64;
        // The exact minimum first (one FFT search); the set is a tolerance set around it.
        let c = search.candidates(canvas, origin, &regions, 0.0);
        let min = c.min_ssd;
        result.optimum = Some(min);
        best = Some(c);
        if (min as f64) >= threshold {
            Vec::new()
        } else if min == 0 {
            // A tolerance relative to 0 cannot express the bound: scan every position, pruned (or
            // every position the pyramid re-scored).
            match search {
                BlockSearch::Pyramid(p, _) => {
                    p.rescored(canvas, origin, &regions, &[]).into_iter().filter(|m| (m.2 as f64) < threshold && allows(m)).collect()
                }
                BlockSearch::Exact(..) => {
                    members_below(sample, canvas, origin, &regions, zone.block, threshold).into_iter().filter(allows).collect()
                }
            }
        } else {
            // A superset of the bound (the margin covers rounding of threshold / min), then the exact rule.
            let tol = (threshold / min as f64 - 1.0) * (1.0 + 1e-9) + 1e-9;
            let c = search.candidates(canvas, origin, &regions, tol);
            c.members.into_iter().filter(|m| (m.2 as f64) < threshold && allows(m)).collect()
        }
    };
    let members: Vec<(u32, u32, u64)> = members.into_iter().filter(no_twin).collect();
    if members.is_empty() {
        let best = best.unwrap_or_else(|| search.candidates(canvas, origin, &regions, 0.0));
        // The first (row-major) of the lowest errors that is no twin.
        let untwinned = |c: &Candidates| c.members.iter().copied().filter(no_twin).min_by_key(|m| m.2);
        let (x, y, d) = match twins {
            None => best.members[0],
            Some(_) => untwinned(&best)
                .or_else(|| [0.25, 1.0, 4.0].into_iter().find_map(|wider| untwinned(&search.candidates(canvas, origin, &regions, wider))))
                .unwrap_or(best.members[0]),
        };
        result.pos = (x, y);
        result.error = d;
        result.optimum = Some(d);
        if eps <= 0.0 {
            result.candidates = Some(best.members.len());
        }
        return result;
    }
    let mut s = Stream::new(seed, &format!("{}liang/pick/bi={bi}/bj={bj}", settings.label));
    let pick = members[s.below_usize(members.len())];
    result.pos = (pick.0, pick.1);
    result.error = pick.2;
    result.candidates = Some(members.len());
    result
}

/// Every position whose zone error is `< threshold`, row-major, with its exact error. Each
/// position's sum is abandoned as soon as it reaches the bound, so a tight bound costs little.
fn members_below(
    sample: &RgbImage,
    canvas: &RgbImage,
    origin: (u32, u32),
    regions: &[Rect],
    block: u32,
    threshold: f64,
) -> Vec<(u32, u32, u64)> {
    // For an integer d (exact in f64 below 2^53), d < threshold ⟺ d < ceil(threshold).
    let limit = threshold.ceil() as u64;
    let (nx, ny) = (sample.width() - block + 1, sample.height() - block + 1);
    (0..ny)
        .into_par_iter()
        .flat_map_iter(|y| {
            (0..nx).filter_map(move |x| {
                let mut sum = 0u64;
                for r in regions {
                    for dy in 0..r.h {
                        sum += rect_ssd(sample, x + r.x, y + r.y + dy, canvas, origin.0 + r.x, origin.1 + r.y + dy, r.w, 1);
                        if sum >= limit {
                            return None;
                        }
                    }
                }
                Some((x, y, sum))
            })
        })
        .collect()
}

/// The manifest's diagnostics: a summary always, every searched block with `diagnostics = true`.
fn diagnostics((cols, rows): (u32, u32), settings: &Settings, results: &[BlockResult]) -> Value {
    let searched: Vec<&BlockResult> = results.iter().filter(|r| (r.bi, r.bj) != (0, 0)).collect();
    let n = searched.len();
    let mean = |f: &dyn Fn(&BlockResult) -> f64| if n == 0 { 0.0 } else { searched.iter().map(|r| f(r)).sum::<f64>() / n as f64 };
    let mut summary = json!({
        "search": settings.search.name(),
        "blocks": { "cols": cols, "rows": rows },
        "searched_blocks": n,
        "mean_rms_error": mean(&|r| rms(r.error, r.zone_pixels)),
    });
    let obj = summary.as_object_mut().expect("object");
    if settings.search == Search::Exhaustive {
        obj.insert("mean_candidates".into(), json!(mean(&|r| r.candidates.unwrap_or(0) as f64)));
    } else {
        let sw = |r: &BlockResult| r.swarm.clone().expect("swarm outcome");
        obj.insert("mean_iterations".into(), json!(mean(&|r| sw(r).iterations as f64)));
        obj.insert("mean_evaluations".into(), json!(mean(&|r| sw(r).evaluations as f64)));
        obj.insert("early_stops".into(), json!(searched.iter().filter(|r| sw(r).stopped_early).count()));
        obj.insert("chaos_blocks".into(), json!(searched.iter().filter(|r| sw(r).chaos_searches > 0).count()));
        obj.insert("chaos_searches".into(), json!(searched.iter().map(|r| sw(r).chaos_searches as u64).sum::<u64>()));
    }
    if settings.optimum {
        obj.insert("mean_rms_optimum".into(), json!(mean(&|r| rms(r.optimum.unwrap_or(0), r.zone_pixels))));
        // Per-run figures of paper 002's Table 2, tabulated by `texsyn report` (mean over seeds =
        // success rate): success = every searched block within 3 % of the exhaustive optimum;
        // iterations to the final best, only for successful runs (null otherwise).
        let success = searched.iter().all(|r| (r.error as f64) <= (1.0 + NEAR_OPTIMUM) * r.optimum.unwrap_or(0) as f64);
        let iterations = if success && settings.search != Search::Exhaustive {
            json!(mean(&|r| r.swarm.as_ref().map_or(0.0, |s| s.best_iteration as f64)))
        } else {
            Value::Null
        };
        obj.insert("summary".into(), json!({ "success": if success { 1.0 } else { 0.0 }, "iterations_when_successful": iterations }));
    }
    if settings.per_block {
        let first = &results[0];
        obj.insert("first".into(), json!({ "x": first.pos.0, "y": first.pos.1 }));
        let list: Vec<Value> = searched
            .iter()
            .map(|r| {
                let mut b = json!({
                    "bi": r.bi, "bj": r.bj, "x": r.pos.0, "y": r.pos.1,
                    "error": r.error, "zone_pixels": r.zone_pixels,
                });
                let o = b.as_object_mut().expect("object");
                if let Some(s) = &r.swarm {
                    o.insert("iterations".into(), json!(s.iterations));
                    o.insert("best_iteration".into(), json!(s.best_iteration));
                    o.insert("chaos_searches".into(), json!(s.chaos_searches));
                    o.insert("first_chaos".into(), json!(s.first_chaos));
                    o.insert("evaluations".into(), json!(s.evaluations));
                    o.insert("stopped_early".into(), json!(s.stopped_early));
                    if settings.polish_radius > 0 {
                        o.insert("swarm_error".into(), json!(s.best_fitness as u64));
                    }
                }
                if let Some(c) = r.candidates {
                    o.insert("candidates".into(), json!(c));
                }
                if settings.optimum {
                    o.insert("optimum".into(), json!(r.optimum));
                    o.insert("positions_within_3pct".into(), json!(r.near_optimum));
                }
                b
            })
            .collect();
        obj.insert("per_block".into(), Value::Array(list));
    }
    summary
}

/// RMS difference per channel over a zone of `pixels` pixels.
fn rms(ssd: u64, pixels: u64) -> f64 {
    if pixels == 0 { 0.0 } else { (ssd as f64 / (3 * pixels) as f64).sqrt() }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::params::resolve;

    fn params(given: &[(&str, ParamValue)]) -> Params {
        let g: Vec<(String, ParamValue)> = given.iter().map(|(k, v)| (k.to_string(), v.clone())).collect();
        resolve(PARAMS, &g).unwrap()
    }

    fn noise(w: u32, h: u32, seed: u64) -> RgbImage {
        let mut s = Stream::new(seed, "test/noise");
        RgbImage::from_fn(w, h, |_, _| [s.below(256) as u8, s.below(256) as u8, s.below(256) as u8])
    }

    /// A smooth-ish texture with structure at several scales (the swarm has something to follow).
    fn texture(w: u32, h: u32) -> RgbImage {
        RgbImage::from_fn(w, h, |x, y| {
            let v = ((x / 7 + y / 5) % 3) as u8 * 60 + ((x * 13 + y * 7) % 17) as u8 * 4 + (x % 11) as u8;
            [v, (v / 2).wrapping_add((y % 9) as u8 * 9), 200 - v / 2]
        })
    }

    fn run(sample: &RgbImage, w: u32, h: u32, p: &Params, seed: u64) -> Synthesis {
        PatchSampling
            .synthesize(&Request {
                sample,
                width: w,
                height: h,
                params: p,
                seed,
                placement: false,
                tileable: false,
                constraints: std::default::Default::default(),
            })
            .unwrap()
    }

    #[test]
    fn continuations_find_the_exact_matches_the_swarm_misses_and_stay_off_by_default() {
        // A periodic sample (period 24 both ways, irregular within): every neighbour's
        // continuation is an exact match as long as it stays inside the sample.
        let mut st = Stream::new(5, "test/period");
        let cell: Vec<[u8; 3]> = (0..24 * 24).map(|_| [st.below(256) as u8, st.below(256) as u8, st.below(256) as u8]).collect();
        let sample = RgbImage::from_fn(120, 120, |x, y| cell[((y % 24) * 24 + x % 24) as usize]);
        let given = |c: bool| {
            params(&[("block", ParamValue::Int(30)), ("iterations", ParamValue::Int(10)), ("continuations", ParamValue::Bool(c))])
        };
        let error = |s: &Synthesis| s.diagnostics["mean_rms_error"].as_f64().unwrap();
        let (off, on) = (run(&sample, 150, 150, &given(false), 3), run(&sample, 150, 150, &given(true), 3));
        // Not zero: a continuation that leaves the sample is not scored, and corner zones also meet
        // the other neighbour.
        assert!(error(&on) < 0.7 * error(&off), "continuations {} vs swarm alone {}", error(&on), error(&off));
        // The default is the paper's search: identical to asking for no continuations.
        assert_eq!(
            run(&sample, 150, 150, &params(&[("block", ParamValue::Int(30)), ("iterations", ParamValue::Int(10))]), 3).image,
            off.image
        );
    }

    #[test]
    fn a_twin_stands_for_the_nearest_allowed_position_that_is_none() {
        use crate::synth::atlas::{Atlas, Augment};
        use crate::synth::constraints::Constraints;
        let block = 10;
        let atlas = Atlas::layout(&[(40, 30)], &[Augment::FlipH]);
        let (aw, ah) = atlas.dimensions();
        let (nx, ny) = (aw - block + 1, ah - block + 1);
        let mask = crate::synth::constraints::SampleMask::new(aw, ah, atlas.allowed(|_, _, _| true));
        let allowed = Allowed::new(mask.block_positions(block, block), nx);
        let constraints = Constraints { atlas: Some(&atlas), ..Constraints::default() };
        // The neighbour shows sample pixels 5..15 as they are; its mirror image starts at 14.
        let neighbour = atlas.position(0, None, 5, 5).unwrap();
        let twins = Twins::of(&constraints, vec![neighbour], block).expect("copies and a neighbour");
        assert!(Twins::of(&constraints, Vec::new(), block).is_none());
        let mirrored = atlas.position(0, Some(Augment::FlipH), 14, 5).unwrap();
        assert!(twins.is_twin(mirrored) && !twins.is_twin(neighbour));
        let mut resolved = 0;
        for y in 0..ny {
            for x in 0..nx {
                let p = allowed.nearest((x, y));
                let q = twins.resolve(p, (nx, ny), Some(&allowed));
                if !twins.is_twin(p) {
                    assert_eq!(q, p);
                    continue;
                }
                resolved += 1;
                assert!(allowed.allows(q) && !twins.is_twin(q), "{p:?} -> {q:?}");
                // Nothing nearer is allowed and no twin.
                let d = |a: (u32, u32), b: (u32, u32)| a.0.abs_diff(b.0) + a.1.abs_diff(b.1);
                for yy in 0..ny {
                    for xx in 0..nx {
                        if d((xx, yy), p) < d(q, p) {
                            assert!(!allowed.allows((xx, yy)) || twins.is_twin((xx, yy)), "{p:?} -> {q:?}, but ({xx}, {yy}) is nearer");
                        }
                    }
                }
            }
        }
        assert!(resolved > 0, "the test reaches twins");
    }

    #[test]
    fn round_position_is_round_then_clamp() {
        let hi = [226.0, 100.0];
        let reference = |v: f64, h: f64| v.round().clamp(0.0, h) as u32;
        let mut values = vec![f64::NAN, f64::INFINITY, f64::NEG_INFINITY, -0.0, 0.0, -0.5, -0.49999999999999994, 0.49999999999999994];
        for k in -4..=240 {
            let v = f64::from(k);
            values.extend([v, v + 0.5, v - 0.5, v + 0.25, v + 0.5 - 1e-13, v + 0.5 + 1e-13, v.next_up(), v.next_down()]);
            values.extend([(v + 0.5).next_down(), (v + 0.5).next_up()]);
        }
        let mut s = Stream::new(1, "test/round");
        values.extend((0..10_000).map(|_| s.uniform_range(-3.0, 230.0)));
        for &a in &values {
            for &b in &values[..40] {
                assert_eq!(round_position(&[a, b], hi), (reference(a, hi[0]), reference(b, hi[1])), "({a}, {b})");
            }
        }
    }

    #[test]
    fn paper_layout_and_defaults() {
        let p = params(&[]);
        let i = |k: &str| p.int(k).unwrap();
        let f = |k: &str| p.float(k).unwrap();
        assert_eq!((i("block"), i("overlap"), i("particles"), i("iterations")), (30, 5, 20, 300));
        assert_eq!((f("c1"), f("c2"), f("inertia"), f("vmax")), (1.47, 1.47, 0.729, 0.2));
        assert_eq!((f("distance_threshold"), f("variance_threshold")), (0.01, 0.001));
        assert_eq!((f("logistic_mu"), i("chaos_steps"), f("delta_rms")), (4.0, 200, 10.0));
        assert_eq!(p.str("search").unwrap(), "cpso");
        // 256 px with B = 30, w_E = 5 needs 11 × 11 blocks (§4.2 step 2).
        let l = BlockGrid::new(30, 5, 256, 256);
        assert_eq!((l.cols, l.rows), (11, 11));
        assert_eq!(l.canvas(), (280, 280));
    }

    #[test]
    fn waves_cover_every_block_once_and_respect_dependencies() {
        let l = BlockGrid::new(30, 5, 200, 130);
        let waves = waves(&l);
        let mut seen = std::collections::HashMap::new();
        for (t, wave) in waves.iter().enumerate() {
            for &b in wave {
                assert!(seen.insert(b, t).is_none());
            }
        }
        assert_eq!(seen.len(), (l.rows * l.cols) as usize);
        for (&(bi, bj), &t) in &seen {
            // Every earlier block that overlaps this one is in an earlier wave.
            for (di, dj) in [(-1i64, -1i64), (-1, 0), (-1, 1), (0, -1)] {
                let (i, j) = (bi as i64 + di, bj as i64 + dj);
                if let Some(&u) = (i >= 0 && j >= 0).then(|| seen.get(&(i as u32, j as u32))).flatten() {
                    assert!(u < t, "({i},{j}) must precede ({bi},{bj})");
                }
            }
        }
    }

    #[test]
    fn output_size_determinism_and_seed_dependence() {
        let s = texture(80, 70);
        for search in Search::NAMES {
            let p = params(&[("block", ParamValue::Int(16)), ("search", ParamValue::Str(search.to_string()))]);
            let a = run(&s, 75, 50, &p, 3);
            assert_eq!(a.image.dimensions(), (75, 50));
            assert_eq!(a.image, run(&s, 75, 50, &p, 3).image, "{search}");
            assert_eq!(a.diagnostics, run(&s, 75, 50, &p, 3).diagnostics, "{search}");
            assert_ne!(a.image, run(&s, 75, 50, &p, 4).image, "{search}");
        }
    }

    #[test]
    fn pixels_do_not_depend_on_the_thread_count() {
        let s = texture(90, 90);
        for (search, blend) in [("cpso", "feather"), ("pso", "feather"), ("exhaustive", "feather"), ("cpso", "cut"), ("exhaustive", "cut")]
        {
            let p = params(&[
                ("block", ParamValue::Int(18)),
                ("search", ParamValue::Str(search.to_string())),
                ("blend", ParamValue::Str(blend.to_string())),
                ("diagnostics", ParamValue::Bool(true)),
            ]);
            let runs: Vec<Synthesis> = [1, 2, 5]
                .iter()
                .map(|&n| rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap().install(|| run(&s, 120, 100, &p, 9)))
                .collect();
            for r in &runs[1..] {
                assert_eq!(r.image, runs[0].image, "{search}");
                assert_eq!(r.diagnostics, runs[0].diagnostics, "{search}");
            }
        }
    }

    /// The wave schedule gives exactly the raster-order result: replay the recorded choices in
    /// raster order and compare.
    #[test]
    fn waves_equal_raster_order() {
        let s = texture(90, 90);
        let p =
            params(&[("block", ParamValue::Int(20)), ("search", ParamValue::Str("pso".into())), ("diagnostics", ParamValue::Bool(true))]);
        let out = run(&s, 130, 110, &p, 2);
        let l = BlockGrid::new(20, 3, 130, 110);
        let mut canvas = Canvas::new(l.canvas().0, l.canvas().1, s.dimensions(), false);
        let d = &out.diagnostics;
        let first = (d["first"]["x"].as_u64().unwrap() as u32, d["first"]["y"].as_u64().unwrap() as u32);
        paste_block(&mut canvas, &s, first, (0, 0), 20, 3, false, false, OverlapRule::Feather);
        for b in d["per_block"].as_array().unwrap() {
            let g = |k: &str| b[k].as_u64().unwrap() as u32;
            let (bi, bj) = (g("bi"), g("bj"));
            let dst = (bj * l.stride(), bi * l.stride());
            // The recorded error is the zone error against the raster-order canvas.
            assert_eq!(zone_error(&s, &canvas.image, (g("x"), g("y")), dst, &l.overlap_regions(bi, bj)), b["error"].as_u64().unwrap());
            paste_block(&mut canvas, &s, (g("x"), g("y")), dst, 20, 3, bj > 0, bi > 0, OverlapRule::Feather);
        }
        assert_eq!(canvas.image.crop(0, 0, 130, 110), out.image);
    }

    #[test]
    fn exhaustive_finds_a_unique_perfect_match() {
        // Noise has a unique perfect continuation of the first block: the block one stride to its
        // right in the sample. Exhaustive search must find it with d = 0.
        let s = noise(60, 40, 4);
        let p = params(&[
            ("block", ParamValue::Int(12)),
            ("overlap", ParamValue::Int(3)),
            ("search", ParamValue::Str("exhaustive".into())),
            ("tolerance", ParamValue::Float(0.0)),
            ("first_x", ParamValue::Int(5)),
            ("first_y", ParamValue::Int(7)),
            ("record_optimum", ParamValue::Bool(true)),
        ]);
        let out = run(&s, 21, 12, &p, 1);
        let b = &out.diagnostics["per_block"][0];
        assert_eq!((b["x"].as_u64(), b["y"].as_u64()), (Some(5 + 9), Some(7)));
        assert_eq!(b["error"].as_u64(), Some(0));
        assert_eq!(b["optimum"].as_u64(), Some(0));
        assert_eq!(b["candidates"].as_u64(), Some(1));
        // The output is the sample itself there.
        assert_eq!(out.image, s.crop(5, 7, 21, 12));
    }

    #[test]
    fn liang_candidates_follow_the_relative_rule() {
        let s = texture(64, 64);
        let p = |eps: f64| {
            params(&[
                ("block", ParamValue::Int(16)),
                ("search", ParamValue::Str("exhaustive".into())),
                ("tolerance", ParamValue::Float(eps)),
                ("diagnostics", ParamValue::Bool(true)),
            ])
        };
        let best = run(&s, 60, 60, &p(0.0), 1);
        let liang = run(&s, 60, 60, &p(0.3), 1);
        // Every Liang pick is within the bound, and the bound admits more than one patch somewhere.
        let blocks = liang.diagnostics["per_block"].as_array().unwrap();
        assert!(blocks.iter().any(|b| b["candidates"].as_u64().unwrap() > 1));
        for b in blocks {
            assert!(b["error"].as_u64() >= b["optimum"].as_u64());
        }
        assert_ne!(best.image, liang.image);
    }

    #[test]
    fn direct_engine_equals_fft_engine_for_every_rule() {
        let s = texture(64, 64);
        for (rule, eps) in [("liang", 0.0), ("liang", 0.3), ("liang", 0.05), ("near-best", 0.2)] {
            let p = |engine: &str| {
                params(&[
                    ("block", ParamValue::Int(16)),
                    ("search", ParamValue::Str("exhaustive".into())),
                    ("candidates", ParamValue::Str(rule.into())),
                    ("tolerance", ParamValue::Float(eps)),
                    ("engine", ParamValue::Str(engine.into())),
                    ("diagnostics", ParamValue::Bool(true)),
                ])
            };
            let a = run(&s, 70, 60, &p("fft"), 2);
            let b = run(&s, 70, 60, &p("direct"), 2);
            assert_eq!(a.image, b.image, "{rule} {eps}");
            assert_eq!(a.diagnostics, b.diagnostics, "{rule} {eps}");
        }
    }

    #[test]
    fn near_best_candidates_are_within_the_relative_tolerance() {
        let s = texture(64, 64);
        let p = params(&[
            ("block", ParamValue::Int(16)),
            ("search", ParamValue::Str("exhaustive".into())),
            ("candidates", ParamValue::Str("near-best".into())),
            ("tolerance", ParamValue::Float(0.5)),
            ("record_optimum", ParamValue::Bool(true)),
        ]);
        let out = run(&s, 70, 60, &p, 2);
        for b in out.diagnostics["per_block"].as_array().unwrap() {
            let (e, o) = (b["error"].as_u64().unwrap() as f64, b["optimum"].as_u64().unwrap() as f64);
            assert!(e >= o && e <= 1.5 * o, "{b}");
            assert!(b["candidates"].as_u64().unwrap() >= 1);
        }
    }

    #[test]
    fn a_cut_paste_copies_sample_pixels_only() {
        let s = texture(64, 64);
        let colours: std::collections::HashSet<[u8; 3]> =
            (0..64).flat_map(|y| (0..64).map(move |x| (x, y))).map(|(x, y)| s.get(x, y)).collect();
        let p = params(&[("block", ParamValue::Int(16)), ("blend", ParamValue::Str("cut".into()))]);
        let out = run(&s, 70, 60, &p, 2).image;
        for y in 0..60 {
            for x in 0..70 {
                assert!(colours.contains(&out.get(x, y)), "({x},{y})");
            }
        }
    }

    #[test]
    fn polish_never_makes_a_block_worse() {
        let s = texture(80, 80);
        let p = params(&[
            ("block", ParamValue::Int(16)),
            ("search", ParamValue::Str("pso".into())),
            ("iterations", ParamValue::Int(5)),
            ("polish_radius", ParamValue::Int(3)),
            ("diagnostics", ParamValue::Bool(true)),
        ]);
        let out = run(&s, 60, 60, &p, 2);
        let blocks = out.diagnostics["per_block"].as_array().unwrap();
        assert!(blocks.iter().all(|b| b["error"].as_u64() <= b["swarm_error"].as_u64()));
        assert!(blocks.iter().any(|b| b["error"].as_u64() < b["swarm_error"].as_u64()));
    }

    #[test]
    fn swarm_diagnostics_are_consistent() {
        let s = texture(100, 100);
        let p = params(&[
            ("block", ParamValue::Int(20)),
            ("search", ParamValue::Str("cpso".into())),
            ("delta_rms", ParamValue::Float(0.0)),
            ("iterations", ParamValue::Int(60)),
            ("record_optimum", ParamValue::Bool(true)),
        ]);
        let out = run(&s, 60, 60, &p, 5);
        let d = &out.diagnostics;
        assert_eq!(d["search"], "cpso");
        for b in d["per_block"].as_array().unwrap() {
            assert_eq!(b["iterations"].as_u64(), Some(60), "no early stop with delta_rms = 0");
            assert!(b["best_iteration"].as_u64().unwrap() <= 60);
            assert!(b["error"].as_u64().unwrap() >= b["optimum"].as_u64().unwrap());
            assert!(!b["stopped_early"].as_bool().unwrap());
        }
    }

    #[test]
    fn pso_and_cpso_blocks_coincide_until_a_chaos_search() {
        // Same streams: with the test unable to fire, CPSO's output is PSO's.
        let s = texture(90, 90);
        let base = [("block", ParamValue::Int(18)), ("diagnostics", ParamValue::Bool(true))];
        let mut pso = base.to_vec();
        pso.push(("search", ParamValue::Str("pso".into())));
        let mut cpso = base.to_vec();
        cpso.push(("search", ParamValue::Str("cpso".into())));
        cpso.push(("distance_threshold", ParamValue::Float(0.0)));
        let a = run(&s, 100, 100, &params(&pso), 8);
        let b = run(&s, 100, 100, &params(&cpso), 8);
        assert_eq!(a.image, b.image);
        assert_eq!(a.diagnostics["per_block"], b.diagnostics["per_block"]);
    }

    #[test]
    fn bad_parameters_name_their_key() {
        let p = params(&[("block", ParamValue::Int(80)), ("overlap", ParamValue::Int(50))]);
        let keys: Vec<String> = PatchSampling.check(&p, (64, 64), (100, 100)).into_iter().map(|e| e.key).collect();
        assert_eq!(keys, vec!["block", "overlap"]);
        let p = params(&[("vmax", ParamValue::Float(0.0)), ("first_x", ParamValue::Int(300))]);
        let errs = PatchSampling.check(&p, (256, 256), (100, 100));
        let keys: Vec<&str> = errs.iter().map(|e| e.key.as_str()).collect();
        assert_eq!(keys, vec!["vmax", "first_y", "first_x"]);
        assert!(errs[2].message.contains("0..=226"), "{}", errs[2].message);
        // Particle count 0 is refused by the range with the key named.
        let g = vec![("particles".to_string(), ParamValue::Int(0))];
        let e = resolve(PARAMS, &g).unwrap_err();
        assert_eq!(e[0].key, "particles");
        assert!(e[0].message.contains("1..="), "{}", e[0].message);
        // Exhaustive does not need a moving swarm.
        let p = params(&[("vmax", ParamValue::Float(0.0)), ("search", ParamValue::Str("exhaustive".into()))]);
        assert!(PatchSampling.check(&p, (64, 64), (100, 100)).is_empty());
    }

    #[test]
    fn default_config_is_the_table_defaults() {
        let cfg = PatchSamplingConfig::default();
        assert_eq!(resolve(PARAMS, &cfg.to_params()).unwrap(), resolve(PARAMS, &[]).unwrap());
        let back = PatchSamplingConfig::from_params(&resolve(PARAMS, &[]).unwrap()).unwrap();
        assert_eq!(back, PatchSamplingConfig { overlap: Some(5), ..cfg });
    }

    #[test]
    fn a_non_default_config_round_trips() {
        let cfg = PatchSamplingConfig {
            block: 24,
            overlap: Some(6),
            search: Search::Pso,
            swarm: SwarmConfig {
                particles: 30,
                iterations: 150,
                c1: 2.0,
                c2: 1.2,
                inertia: 0.5,
                vmax: 0.3,
                update: Update::Asynchronous,
                delta_rms: 0.0,
                polish_radius: 2,
                continuations: true,
            },
            chaos: ChaosConfig {
                distance_threshold: 0.02,
                variance_threshold: 0.5,
                logistic_mu: 3.9,
                chaos_steps: 50,
                rediversify: Rediversify::None,
            },
            exhaustive: ExhaustiveConfig { tolerance: 0.0, candidates: CandidateRule::NearBest, engine: Engine::Direct },
            blend: Blend::Cut,
            first_x: Some(3),
            first_y: Some(0),
            diagnostics: true,
            record_optimum: true,
        };
        // Every job-file parameter is given and differs from its default.
        let given = cfg.to_params();
        let defaults = resolve(PARAMS, &[]).unwrap();
        assert_eq!(given.len(), PARAMS.len());
        for (k, v) in &given {
            assert_ne!(defaults.get(k), Some(v), "{k} keeps its default");
        }
        let p = resolve(PARAMS, &given).unwrap();
        assert_eq!(PatchSamplingConfig::from_params(&p).unwrap(), cfg);
        let s = Settings::of(&cfg);
        assert_eq!(s.swarm.update, pso::UpdateOrder::Asynchronous);
        assert!(s.swarm.chaos.is_none(), "pso has no chaos part");
        assert_eq!(
            Settings::of(&PatchSamplingConfig { search: Search::Cpso, ..cfg.clone() }).swarm.chaos.unwrap().rediversify,
            pso::Rediversify::None
        );
        assert_eq!((s.blend, s.first), (OverlapRule::Cut, Some((3, 0))));
    }

    #[test]
    fn an_unknown_word_is_an_error_naming_its_key() {
        let mut p = params(&[]);
        p.0.insert("search".into(), ParamValue::Str("genetic".into()));
        let errs = PatchSampling.check(&p, (64, 64), (100, 100));
        assert_eq!(errs.len(), 1);
        assert_eq!(errs[0].key, "search");
        let s = texture(64, 64);
        let e = PatchSampling
            .synthesize(&Request {
                sample: &s,
                width: 40,
                height: 40,
                params: &p,
                seed: 1,
                placement: false,
                tileable: false,
                constraints: std::default::Default::default(),
            })
            .unwrap_err();
        assert!(matches!(&e, SynthError::Param { key, .. } if key == "search"), "{e}");
    }
}
