//! Double-seam's parameters: their table (names, ranges, defaults, what each does) and the
//! typed configuration read from a job's resolved parameters. Apart from `mod.rs` so that the
//! method's drivers read as the algorithm.

use super::*;
/// `level_penalty`'s default. The paper's criterion (0) ignores a line's brightness, so blocks of
/// another tone pass as consistent and leave steps (docs/methods.md §5, gap 5). Seen at 384² from
/// 256² on the 35 samples of the advice test: 3 to 5 remove most steps (a gray stone wall, cream
/// tiles, terracotta, a lit wall, a blotchy stone) and lower the seams' colour jumps by 4 % on
/// average (geometric mean of seam visibility against 0); 10 weighs tone over pattern, ends more
/// cracks and mortar lines at block edges (a carved wall, cream tiles) and raises the jumps by 2 %.
pub const DEFAULT_LEVEL_PENALTY: f64 = 4.0;

pub(super) const PARAMS: &[ParamSpec] = &[
    ParamSpec { name: "block", kind: ParamKind::Int { min: 3, max: 4096 }, default: Default::Int(50), doc: "block side B" },
    ParamSpec {
        name: "overlap",
        kind: ParamKind::Int { min: 1, max: 2048 },
        default: Default::Derived {
            rule: "round(block / 6)",
            compute: |p| Some(ParamValue::Int(super::super::default_overlap(p.int("block").ok()?))),
        },
        doc: "virtual overlap g: grid stride is block − g (paper: 8 for B = 50, 17 for B = 100)",
    },
    ParamSpec {
        name: "aux_dist",
        kind: ParamKind::Int { min: 1, max: 2048 },
        default: Default::Derived { rule: "overlap", compute: |p| Some(ParamValue::Int(p.int("overlap").ok()?)) },
        doc: "spacing of the auxiliary seam line from the true one, 1..=overlap (overlap − 1 keeps it inside the window)",
    },
    ParamSpec {
        name: "alpha",
        kind: ParamKind::Float { min: 0.0, max: 1.0 },
        default: Default::Float(0.25),
        doc: "weight of the hue correlation (alpha + beta + gamma = 1)",
    },
    ParamSpec {
        name: "beta",
        kind: ParamKind::Float { min: 0.0, max: 1.0 },
        default: Default::Float(0.25),
        doc: "weight of the saturation correlation",
    },
    ParamSpec {
        name: "gamma",
        kind: ParamKind::Float { min: 0.0, max: 1.0 },
        default: Default::Float(0.5),
        doc: "weight of the intensity correlation",
    },
    ParamSpec {
        name: "mu",
        kind: ParamKind::Float { min: 0.0, max: 1.0e6 },
        default: Default::Float(2.0),
        doc: "edge-mismatch penalty: F_i = D_HSI / (1 + mu·D_E)",
    },
    ParamSpec {
        name: "tau_f",
        kind: ParamKind::Float { min: -2.0, max: 2.0 },
        default: Default::Float(1.6),
        doc: "candidates need F ≥ min(tau_f, F_max − eps_f)",
    },
    ParamSpec {
        name: "eps_f",
        kind: ParamKind::Float { min: 0.0, max: 4.0 },
        default: Default::Float(0.05),
        doc: "near-best margin when no position reaches tau_f",
    },
    ParamSpec {
        name: "hue_mode",
        kind: ParamKind::Choice(HueMode::NAMES),
        default: Default::Str("linear"),
        doc: "linear: Pearson on H/360 (faithful); circular: circular correlation (hue is an angle)",
    },
    ParamSpec {
        name: "clamp_negative",
        kind: ParamKind::Bool,
        default: Default::Bool(false),
        doc: "use max(D_HSI, 0) so a negative correlation is not softened by the edge term",
    },
    ParamSpec {
        name: "level_penalty",
        kind: ParamKind::Float { min: 0.0, max: 1000.0 },
        default: Default::Float(DEFAULT_LEVEL_PENALTY),
        doc: "0 = faithful (paper 003). Pearson ignores brightness offsets, so blocks of another tone pass as consistent and leave colour steps; > 0 subtracts level_penalty·|mean I difference| per line (default 4)",
    },
];

crate::choice! {
    /// How hue, an angle, is correlated (`hue_mode`).
    pub enum HueMode {
        /// Pearson correlation of H / 360, as in the paper.
        Linear = "linear",
        /// Circular correlation.
        Circular = "circular",
    }
}

/// Double-seam splicing's parameters, typed: one field per entry of its parameter table.
#[derive(Clone, Debug, PartialEq)]
pub struct DoubleSeamConfig {
    /// `block`: block side B, in pixels (3..=4096, at most the sample's smaller side).
    pub block: u32,
    /// `overlap`: virtual overlap g, the grid stride being `block − g` (1..=2048, at most
    /// block / 2); `None`: derived, `round(block / 6)`.
    pub overlap: Option<u32>,
    /// `aux_dist`: spacing of the auxiliary seam line from the true one (1..=overlap); `None`:
    /// derived, equal to the overlap.
    pub aux_dist: Option<u32>,
    /// `alpha`: weight of the hue correlation (strictly between 0 and 1; alpha + beta + gamma = 1).
    pub alpha: f64,
    /// `beta`: weight of the saturation correlation.
    pub beta: f64,
    /// `gamma`: weight of the intensity correlation.
    pub gamma: f64,
    /// `mu`: edge-mismatch penalty, `F_i = D_HSI / (1 + mu·D_E)` (0..=1e6).
    pub mu: f64,
    /// `tau_f`: candidates need `F ≥ min(tau_f, F_max − eps_f)` (-2..=2).
    pub tau_f: f64,
    /// `eps_f`: near-best margin when no position reaches `tau_f` (0..=4).
    pub eps_f: f64,
    /// `hue_mode`: linear (faithful) or circular hue correlation.
    pub hue_mode: HueMode,
    /// `clamp_negative`: use `max(D_HSI, 0)`.
    pub clamp_negative: bool,
    /// `level_penalty`: subtract `level_penalty·|mean I difference|` per line; 0 is faithful
    /// (0..=1000). The default is [`DEFAULT_LEVEL_PENALTY`], not the paper's 0.
    pub level_penalty: f64,
}

impl std::default::Default for DoubleSeamConfig {
    fn default() -> DoubleSeamConfig {
        DoubleSeamConfig {
            block: 50,
            overlap: None,
            aux_dist: None,
            alpha: 0.25,
            beta: 0.25,
            gamma: 0.5,
            mu: 2.0,
            tau_f: 1.6,
            eps_f: 0.05,
            hue_mode: HueMode::Linear,
            clamp_negative: false,
            level_penalty: DEFAULT_LEVEL_PENALTY,
        }
    }
}

impl DoubleSeamConfig {
    /// The virtual overlap: the given one, else the derived default `round(block / 6)`.
    pub fn overlap_or_derived(&self) -> u32 {
        self.overlap.unwrap_or_else(|| super::super::default_overlap(i64::from(self.block)) as u32)
    }

    /// The auxiliary line's spacing: the given one, else the derived default (the overlap).
    pub fn aux_dist_or_derived(&self) -> u32 {
        self.aux_dist.unwrap_or_else(|| self.overlap_or_derived())
    }
}

impl MethodConfig for DoubleSeamConfig {
    const METHOD: &'static str = "double-seam";

    fn to_params(&self) -> Vec<(String, ParamValue)> {
        let mut v = vec![params::int("block", self.block)];
        v.extend(self.overlap.map(|o| params::int("overlap", o)));
        v.extend(self.aux_dist.map(|a| params::int("aux_dist", a)));
        v.extend([
            params::float("alpha", self.alpha),
            params::float("beta", self.beta),
            params::float("gamma", self.gamma),
            params::float("mu", self.mu),
            params::float("tau_f", self.tau_f),
            params::float("eps_f", self.eps_f),
            params::word("hue_mode", self.hue_mode),
            params::boolean("clamp_negative", self.clamp_negative),
            params::float("level_penalty", self.level_penalty),
        ]);
        v
    }

    fn from_params(p: &Params) -> Result<DoubleSeamConfig, SynthError> {
        Ok(DoubleSeamConfig {
            block: p.uint("block")?,
            overlap: Some(p.uint("overlap")?),
            aux_dist: Some(p.uint("aux_dist")?),
            alpha: p.float("alpha")?,
            beta: p.float("beta")?,
            gamma: p.float("gamma")?,
            mu: p.float("mu")?,
            tau_f: p.float("tau_f")?,
            eps_f: p.float("eps_f")?,
            hue_mode: p.choice("hue_mode")?,
            clamp_negative: p.bool("clamp_negative")?,
            level_penalty: p.float("level_penalty")?,
        })
    }
}
