//! Patch sampling's parameters: the table a job file's `[params]` is checked against, the
//! words of its choices, and the typed configuration (`PatchSamplingConfig`) the method reads
//! them into and writes them back from. Kept apart from the synthesis so that the contract of
//! the job keys reads in one place.

use crate::synth::error::SynthError;
use crate::synth::methods::Engine;
use crate::synth::params::{self, Choice, Default, MethodConfig, ParamKind, ParamSpec, ParamValue, Params};
use crate::synth::primitives::block_grid::OverlapRule;
use crate::synth::primitives::pso::{self, ChaosParams, SwarmParams};

pub(super) const PARAMS: &[ParamSpec] = &[
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
            compute: |p| Some(ParamValue::Int(crate::synth::methods::default_overlap(p.int("block").ok()?))),
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
        self.overlap.unwrap_or_else(|| crate::synth::methods::default_overlap(i64::from(self.block)) as u32)
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
