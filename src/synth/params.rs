//! Method parameters: their specifications, validation and resolution.
//!
//! Every method declares its parameters as a static table of [`ParamSpec`]s (name, type, range,
//! default, documentation). The same table drives job-file validation, default filling, the
//! `texsyn methods` listing and re-running from a manifest, so the four can never disagree.

pub use crate::synth::error::SynthError;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// A parameter value as written in a job file or a manifest.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum ParamValue {
    Bool(bool),
    Int(i64),
    Float(f64),
    Str(String),
}

impl ParamValue {
    pub fn type_name(&self) -> &'static str {
        match self {
            ParamValue::Bool(_) => "a boolean",
            ParamValue::Int(_) => "an integer",
            ParamValue::Float(_) => "a float",
            ParamValue::Str(_) => "a string",
        }
    }

    /// The value as it appears in templated output paths and job ids.
    pub fn display(&self) -> String {
        match self {
            ParamValue::Bool(b) => b.to_string(),
            ParamValue::Int(i) => i.to_string(),
            ParamValue::Float(f) => crate::digest::ecmascript_number(*f),
            ParamValue::Str(s) => s.clone(),
        }
    }
}

/// The type and allowed values of a parameter.
#[derive(Clone, Copy, Debug)]
pub enum ParamKind {
    Int {
        min: i64,
        max: i64,
    },
    Float {
        min: f64,
        max: f64,
    },
    Bool,
    Choice(&'static [&'static str]),
    /// An integer in `min..=max`, or the one word `word` for a value the method works out itself
    /// (e.g. `rows = "cover"`: as many lattice rows as cover the output), so that a literal 0
    /// never has to mean "automatic" and can be refused.
    IntOr {
        min: i64,
        max: i64,
        word: &'static str,
    },
}

impl ParamKind {
    /// Human description of the allowed values, for listings and errors.
    pub fn describe(&self) -> String {
        match self {
            ParamKind::Int { min, max } => format!("integer in {min}..={max}"),
            ParamKind::Float { min, max } => format!("float in [{}, {}]", fmt_f(*min), fmt_f(*max)),
            ParamKind::Bool => "boolean".into(),
            ParamKind::Choice(c) => format!("one of {}", c.join(" | ")),
            ParamKind::IntOr { min, max, word } => format!("integer in {min}..={max} or {word:?}"),
        }
    }
}

fn fmt_f(v: f64) -> String {
    crate::digest::ecmascript_number(v)
}

/// Where a parameter's default comes from.
#[derive(Clone, Copy)]
pub enum Default {
    Int(i64),
    Float(f64),
    Bool(bool),
    Str(&'static str),
    /// Computed from the other (already resolved) parameters, e.g. `overlap = round(block / 6)`.
    /// `compute` sees the explicitly given and fixed values; `None` when it cannot be derived.
    Derived {
        rule: &'static str,
        compute: fn(&Params) -> Option<ParamValue>,
    },
}

impl Default {
    pub fn describe(&self) -> String {
        match self {
            Default::Int(i) => i.to_string(),
            Default::Float(f) => fmt_f(*f),
            Default::Bool(b) => b.to_string(),
            Default::Str(s) => format!("{s:?}"),
            Default::Derived { rule, .. } => rule.to_string(),
        }
    }
}

/// One declared parameter of a method.
#[derive(Clone, Copy)]
pub struct ParamSpec {
    pub name: &'static str,
    pub kind: ParamKind,
    pub default: Default,
    pub doc: &'static str,
}

impl ParamSpec {
    /// Checks a value against this spec, converting integers to floats where a float is expected.
    pub fn check(&self, value: &ParamValue) -> Result<ParamValue, String> {
        match (&self.kind, value) {
            (ParamKind::Int { min, max }, ParamValue::Int(v)) => {
                if v < min || v > max {
                    Err(format!("{v} is out of range: allowed {min}..={max}"))
                } else {
                    Ok(value.clone())
                }
            }
            (ParamKind::Float { min, max }, ParamValue::Int(_) | ParamValue::Float(_)) => {
                let v = match value {
                    ParamValue::Int(i) => *i as f64,
                    ParamValue::Float(f) => *f,
                    _ => unreachable!(),
                };
                if !v.is_finite() {
                    Err(format!("{v} is not a finite number"))
                } else if v < *min || v > *max {
                    Err(format!("{} is out of range: allowed [{}, {}]", fmt_f(v), fmt_f(*min), fmt_f(*max)))
                } else {
                    Ok(ParamValue::Float(v))
                }
            }
            (ParamKind::Bool, ParamValue::Bool(_)) => Ok(value.clone()),
            (ParamKind::IntOr { min, max, word }, ParamValue::Int(v)) => {
                if v < min || v > max {
                    Err(format!("{v} is out of range: allowed {min}..={max}, or {word:?}"))
                } else {
                    Ok(value.clone())
                }
            }
            (ParamKind::IntOr { word, .. }, ParamValue::Str(s)) => {
                if s == word {
                    Ok(value.clone())
                } else {
                    Err(format!("{s:?} is not allowed: expected {}", self.kind.describe()))
                }
            }
            (ParamKind::Choice(choices), ParamValue::Str(s)) => {
                if choices.contains(&s.as_str()) {
                    Ok(value.clone())
                } else {
                    Err(format!("{s:?} is not allowed: expected {}", self.kind.describe()))
                }
            }
            (kind, v) => Err(format!("expected {}, found {}", kind_noun(kind), v.type_name())),
        }
    }
}

fn kind_noun(kind: &ParamKind) -> &'static str {
    match kind {
        ParamKind::Int { .. } => "an integer",
        ParamKind::Float { .. } => "a number",
        ParamKind::Bool => "a boolean (true or false)",
        ParamKind::Choice(_) => "a string",
        ParamKind::IntOr { .. } => "an integer or a word",
    }
}

/// A problem with one parameter; `key` is the parameter name so callers can point at its line.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamError {
    pub key: String,
    pub message: String,
}

/// A typed config that cannot be read, for a method's `check` (which reports [`ParamError`]s): the
/// key it names, or `params` when it names none.
impl From<SynthError> for ParamError {
    fn from(e: SynthError) -> ParamError {
        match e {
            SynthError::Param { key, message } => ParamError { key, message },
            other => ParamError::new("params", other.to_string()),
        }
    }
}

impl ParamError {
    pub fn new(key: &str, message: impl Into<String>) -> ParamError {
        ParamError { key: key.to_string(), message: message.into() }
    }
}

/// Fully resolved parameters of one job: every declared parameter has a value.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Params(pub BTreeMap<String, ParamValue>);

impl Params {
    pub fn get(&self, name: &str) -> Option<&ParamValue> {
        self.0.get(name)
    }

    /// An integer parameter. Params are resolved against the method's own table before a method
    /// reads them, so a wrong type here means the table and the reader disagree: reported as a
    /// [`SynthError::Param`] naming the key, never a panic.
    pub fn int(&self, name: &str) -> Result<i64, SynthError> {
        match self.0.get(name) {
            Some(ParamValue::Int(v)) => Ok(*v),
            other => Err(not_resolved(name, "an integer", other)),
        }
    }

    pub fn float(&self, name: &str) -> Result<f64, SynthError> {
        match self.0.get(name) {
            Some(ParamValue::Float(v)) => Ok(*v),
            Some(ParamValue::Int(v)) => Ok(*v as f64),
            other => Err(not_resolved(name, "a number", other)),
        }
    }

    /// An integer parameter that is a size or a count.
    pub fn uint(&self, name: &str) -> Result<u32, SynthError> {
        let v = self.int(name)?;
        u32::try_from(v).map_err(|_| SynthError::param(name, format!("{v} is not in 0..={}", u32::MAX)))
    }

    /// An [`ParamKind::IntOr`] parameter: `Some(n)`, or `None` for its word.
    pub fn int_or_word(&self, name: &str) -> Result<Option<i64>, SynthError> {
        match self.0.get(name) {
            Some(ParamValue::Int(v)) => Ok(Some(*v)),
            Some(ParamValue::Str(_)) => Ok(None),
            other => Err(not_resolved(name, "an integer or a word", other)),
        }
    }

    pub fn bool(&self, name: &str) -> Result<bool, SynthError> {
        match self.0.get(name) {
            Some(ParamValue::Bool(v)) => Ok(*v),
            other => Err(not_resolved(name, "a boolean", other)),
        }
    }

    pub fn str(&self, name: &str) -> Result<&str, SynthError> {
        match self.0.get(name) {
            Some(ParamValue::Str(v)) => Ok(v),
            other => Err(not_resolved(name, "a string", other)),
        }
    }

    /// A [`ParamKind::Choice`] parameter parsed into its enum (see [`choice!`]). A word the enum
    /// does not know is an error naming the key, never a silent fallback.
    pub fn choice<C: Choice>(&self, name: &str) -> Result<C, SynthError> {
        let word = self.str(name)?;
        C::parse(word).ok_or_else(|| SynthError::param(name, format!("{word:?} is not one of {}", C::NAMES.join(" | "))))
    }

    pub fn to_json(&self) -> serde_json::Value {
        serde_json::to_value(self).expect("params serialise")
    }
}

/// Resolves the given values against `specs`: rejects unknown names (suggesting the nearest),
/// checks types and ranges, then fills defaults (fixed ones first, then derived ones in
/// declaration order, so a derived default can use any explicitly given or fixed value).
pub fn resolve(specs: &[ParamSpec], given: &[(String, ParamValue)]) -> Result<Params, Vec<ParamError>> {
    let mut errors = Vec::new();
    let mut out = BTreeMap::new();
    let names: Vec<&str> = specs.iter().map(|s| s.name).collect();
    // The nearest-name suggestion costs an edit distance per valid name: given for the first
    // unknown keys only, the rest are counted, so that 80 000 of them cost nothing noticeable.
    let mut unknown = 0;
    for (name, value) in given {
        match specs.iter().find(|s| s.name == name) {
            None => {
                unknown += 1;
                if unknown <= MAX_SUGGESTED_UNKNOWN {
                    errors.push(ParamError::new(name, unknown_key_message(name, &names)));
                }
            }
            Some(spec) => match spec.check(value) {
                Ok(v) => {
                    out.insert(name.clone(), v);
                }
                Err(e) => errors.push(ParamError::new(name, e)),
            },
        }
    }
    if unknown > MAX_SUGGESTED_UNKNOWN {
        let first = given.iter().map(|(n, _)| n.as_str()).filter(|n| !names.contains(n)).nth(MAX_SUGGESTED_UNKNOWN).unwrap_or("?");
        errors.push(ParamError::new(
            first,
            format!(
                "… and {} more unknown key(s) after the first {MAX_SUGGESTED_UNKNOWN}; valid keys: {}",
                unknown - MAX_SUGGESTED_UNKNOWN,
                names.join(", ")
            ),
        ));
    }
    for spec in specs {
        if out.contains_key(spec.name) {
            continue;
        }
        let v = match spec.default {
            Default::Int(i) => ParamValue::Int(i),
            Default::Float(f) => ParamValue::Float(f),
            Default::Bool(b) => ParamValue::Bool(b),
            Default::Str(s) => ParamValue::Str(s.to_string()),
            Default::Derived { .. } => continue,
        };
        out.insert(spec.name.to_string(), v);
    }
    if !errors.is_empty() {
        return Err(errors);
    }
    for spec in specs {
        if let Default::Derived { rule, compute } = spec.default {
            if out.contains_key(spec.name) {
                continue;
            }
            let Some(v) = compute(&Params(out.clone())) else {
                errors.push(ParamError::new(
                    spec.name,
                    format!("its default ({rule}) cannot be computed from the other parameters; set it explicitly"),
                ));
                continue;
            };
            match spec.check(&v) {
                Ok(v) => {
                    out.insert(spec.name.to_string(), v);
                }
                Err(e) => {
                    errors.push(ParamError::new(spec.name, format!("its default ({rule}) gives {}: {e}; set it explicitly", v.display())))
                }
            }
        }
    }
    if errors.is_empty() { Ok(Params(out)) } else { Err(errors) }
}

/// How many unknown keys of one table get a nearest-name suggestion (the rest are counted).
pub const MAX_SUGGESTED_UNKNOWN: usize = 20;

/// "unknown key `x`", plus the nearest valid name when one is close, else the list of names.
pub fn unknown_key_message(key: &str, valid: &[&str]) -> String {
    match nearest(key, valid) {
        Some(n) => format!("unknown key `{key}`; did you mean `{n}`?"),
        None => format!("unknown key `{key}`; valid keys: {}", valid.join(", ")),
    }
}

/// The valid name closest to `key` by edit distance, if it is plausibly a typo of it.
pub fn nearest<'a>(key: &str, valid: &[&'a str]) -> Option<&'a str> {
    let best = valid.iter().map(|v| (edit_distance(key, v), *v)).min_by_key(|(d, v)| (*d, *v))?;
    let limit = (key.chars().count().max(best.1.len()) / 3).max(1) + 1;
    (best.0 <= limit).then_some(best.1)
}

/// Levenshtein distance over chars.
pub fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut cur = vec![i + 1; b.len() + 1];
        for (j, cb) in b.iter().enumerate() {
            let sub = prev[j] + usize::from(ca != *cb);
            cur[j + 1] = sub.min(prev[j + 1] + 1).min(cur[j] + 1);
        }
        prev = cur;
    }
    prev[b.len()]
}

fn not_resolved(name: &str, expected: &str, found: Option<&ParamValue>) -> SynthError {
    let found = found.map_or("nothing", ParamValue::type_name);
    SynthError::param(name, format!("expected {expected}, found {found} (the method's parameter table and its reader disagree)"))
}

/// A parameter whose value is one of a fixed set of words, as an enum. Declared with [`choice!`],
/// which gives the words once: the same list is the [`ParamKind::Choice`] of the method's table
/// (what job files may say) and the parser of its typed config.
pub trait Choice: Sized + Copy + 'static {
    /// The words, in declaration order.
    const NAMES: &'static [&'static str];
    fn parse(word: &str) -> Option<Self>;
    fn name(self) -> &'static str;
}

/// Declares a [`Choice`] enum: `choice! { pub enum Cut { Dp = "dp", None = "none" } }`.
#[macro_export]
#[doc(hidden)]
macro_rules! choice {
    ($(#[$meta:meta])* $vis:vis enum $name:ident { $($(#[$vmeta:meta])* $variant:ident = $word:literal),+ $(,)? }) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq)]
        $vis enum $name { $($(#[$vmeta])* $variant),+ }
        impl $crate::synth::params::Choice for $name {
            const NAMES: &'static [&'static str] = &[$($word),+];
            fn parse(word: &str) -> Option<Self> {
                match word { $($word => Some($name::$variant),)+ _ => None }
            }
            fn name(self) -> &'static str {
                match self { $($name::$variant => $word),+ }
            }
        }
    };
}
pub use choice;

/// A method's typed configuration: the same parameters as its [`ParamSpec`] table, as Rust
/// fields. `Default` gives the table's defaults (derived ones as `None`: computed at resolution);
/// [`MethodConfig::to_params`] feeds the table's validation, so a bad value gets the same message
/// from Rust as from a job file; [`MethodConfig::from_params`] reads resolved parameters back.
pub trait MethodConfig: Sized + Clone + std::fmt::Debug + std::default::Default {
    /// The method's name in job files.
    const METHOD: &'static str;
    /// The given values, as a job file's `[params]` would hold them (unset derived ones omitted).
    fn to_params(&self) -> Vec<(String, ParamValue)>;
    /// Reads fully resolved parameters.
    fn from_params(p: &Params) -> Result<Self, SynthError>;
}

/// Shorthands for [`MethodConfig::to_params`].
pub fn int(name: &str, v: impl Into<i64>) -> (String, ParamValue) {
    (name.to_string(), ParamValue::Int(v.into()))
}
pub fn float(name: &str, v: f64) -> (String, ParamValue) {
    (name.to_string(), ParamValue::Float(v))
}
pub fn boolean(name: &str, v: bool) -> (String, ParamValue) {
    (name.to_string(), ParamValue::Bool(v))
}
pub fn word<C: Choice>(name: &str, v: C) -> (String, ParamValue) {
    (name.to_string(), ParamValue::Str(v.name().to_string()))
}
/// An [`ParamKind::IntOr`] value: the number, or the word when `None`.
pub fn int_or(name: &str, v: Option<i64>, word: &str) -> (String, ParamValue) {
    (name.to_string(), v.map_or_else(|| ParamValue::Str(word.to_string()), ParamValue::Int))
}

#[cfg(test)]
mod tests {
    use super::*;

    const SPECS: &[ParamSpec] = &[
        ParamSpec { name: "block", kind: ParamKind::Int { min: 4, max: 100 }, default: Default::Int(50), doc: "" },
        ParamSpec {
            name: "overlap",
            kind: ParamKind::Int { min: 2, max: 50 },
            default: Default::Derived {
                rule: "round(block / 6)",
                compute: |p| Some(ParamValue::Int((p.int("block").ok()? as f64 / 6.0).round() as i64)),
            },
            doc: "",
        },
        ParamSpec { name: "tolerance", kind: ParamKind::Float { min: 0.0, max: 1.0 }, default: Default::Float(0.1), doc: "" },
        ParamSpec { name: "cut", kind: ParamKind::Choice(&["dp", "none"]), default: Default::Str("dp"), doc: "" },
    ];

    fn given(v: &[(&str, ParamValue)]) -> Vec<(String, ParamValue)> {
        v.iter().map(|(k, v)| (k.to_string(), v.clone())).collect()
    }

    #[test]
    fn fills_fixed_and_derived_defaults() {
        let p = resolve(SPECS, &given(&[("block", ParamValue::Int(30))])).unwrap();
        assert_eq!(p.int("overlap").unwrap(), 5);
        assert_eq!(p.float("tolerance").unwrap(), 0.1);
        assert_eq!(p.str("cut").unwrap(), "dp");
        assert!(p.int("cut").unwrap_err().to_string().contains("`cut`"));
    }

    #[test]
    fn integers_are_accepted_for_floats() {
        let p = resolve(SPECS, &given(&[("tolerance", ParamValue::Int(0))])).unwrap();
        assert_eq!(p.get("tolerance"), Some(&ParamValue::Float(0.0)));
    }

    #[test]
    fn reports_every_problem_with_its_key() {
        let errs = resolve(
            SPECS,
            &given(&[
                ("blok", ParamValue::Int(3)),
                ("tolerance", ParamValue::Float(2.0)),
                ("cut", ParamValue::Str("zigzag".into())),
                ("overlap", ParamValue::Str("8".into())),
            ]),
        )
        .unwrap_err();
        let keys: Vec<&str> = errs.iter().map(|e| e.key.as_str()).collect();
        assert_eq!(keys, vec!["blok", "tolerance", "cut", "overlap"]);
        assert!(errs[0].message.contains("did you mean `block`"), "{}", errs[0].message);
        assert!(errs[1].message.contains("[0, 1]"), "{}", errs[1].message);
        assert!(errs[2].message.contains("dp | none"), "{}", errs[2].message);
        assert!(errs[3].message.contains("expected an integer, found a string"), "{}", errs[3].message);
    }

    #[test]
    fn derived_default_out_of_range_is_explained() {
        let errs = resolve(SPECS, &given(&[("block", ParamValue::Int(4))])).unwrap_err();
        assert_eq!(errs[0].key, "overlap");
        assert!(errs[0].message.contains("(round(block / 6)) gives 1"), "{}", errs[0].message);
        assert!(errs[0].message.contains("set it explicitly"));
    }

    #[test]
    fn int_or_word_takes_a_number_in_range_or_its_word_only() {
        const S: &[ParamSpec] = &[ParamSpec {
            name: "rows",
            kind: ParamKind::IntOr { min: 1, max: 64, word: "cover" },
            default: Default::Str("cover"),
            doc: "",
        }];
        assert_eq!(resolve(S, &[]).unwrap().int_or_word("rows").unwrap(), None);
        assert_eq!(resolve(S, &given(&[("rows", ParamValue::Int(8))])).unwrap().int_or_word("rows").unwrap(), Some(8));
        let zero = resolve(S, &given(&[("rows", ParamValue::Int(0))])).unwrap_err();
        assert!(zero[0].message.contains("out of range: allowed 1..=64, or \"cover\""), "{}", zero[0].message);
        let word = resolve(S, &given(&[("rows", ParamValue::Str("auto".into()))])).unwrap_err();
        assert!(word[0].message.contains("integer in 1..=64 or \"cover\""), "{}", word[0].message);
        let float = resolve(S, &given(&[("rows", ParamValue::Float(2.5))])).unwrap_err();
        assert!(float[0].message.contains("expected an integer or a word"), "{}", float[0].message);
    }

    #[test]
    fn nearest_name_only_for_plausible_typos() {
        assert_eq!(nearest("tolerence", &["tolerance", "block"]), Some("tolerance"));
        assert_eq!(nearest("zzzzzz", &["tolerance", "block"]), None);
        assert_eq!(edit_distance("kitten", "sitting"), 3);
    }
}
