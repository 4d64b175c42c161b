//! A job file being read: its text, where each key is, the problems found so far, and the
//! values read from it. Shared by `read` (the keys) and `sweep` (the expansion).

use super::{JobError, JobFile};
use crate::digest::Digest;
use crate::image::io::Format;
use crate::synth::method::Method;
use crate::synth::params::ParamValue;
use std::collections::BTreeMap;
use std::path::PathBuf;
use toml::de::DeValue;

/// Where a byte offset is, as 1-based (line, column).
pub(super) fn line_col(src: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(src.len());
    let before = &src[..offset];
    let line = before.matches('\n').count() + 1;
    let col = before.rfind('\n').map_or(before.chars().count(), |nl| before[nl + 1..].chars().count()) + 1;
    (line, col)
}

pub(super) struct Ctx<'a> {
    pub(super) file: &'a JobFile,
    pub(super) src: &'a str,
    pub(super) errors: Vec<JobError>,
    pub(super) positions: BTreeMap<String, (usize, usize)>,
}

impl Ctx<'_> {
    pub(super) fn err(&mut self, span: Option<std::ops::Range<usize>>, key: Option<&str>, message: impl Into<String>) {
        let e = JobError {
            file: self.file.path.clone(),
            position: span.map(|s| line_col(self.src, s.start)),
            key: key.map(str::to_string),
            message: message.into(),
        };
        if !self.errors.contains(&e) {
            self.errors.push(e);
        }
    }
    pub(super) fn at(&mut self, key: &str, span: std::ops::Range<usize>) {
        self.positions.insert(key.to_string(), line_col(self.src, span.start));
    }
}

pub(super) fn type_name(v: &DeValue) -> &'static str {
    match v {
        DeValue::String(_) => "a string",
        DeValue::Integer(_) => "an integer",
        DeValue::Float(_) => "a float",
        DeValue::Boolean(_) => "a boolean",
        DeValue::Datetime(_) => "a datetime",
        DeValue::Array(_) => "an array",
        DeValue::Table(_) => "a table",
    }
}

pub(super) fn de_int(v: &DeValue) -> Option<Result<i64, String>> {
    match v {
        DeValue::Integer(i) => {
            Some(i64::from_str_radix(i.as_str(), i.radix()).map_err(|_| format!("integer {} is out of range", i.as_str())))
        }
        _ => None,
    }
}

pub(super) fn de_param(v: &DeValue) -> Result<ParamValue, String> {
    match v {
        DeValue::String(s) => Ok(ParamValue::Str(s.to_string())),
        DeValue::Integer(_) => de_int(v).expect("integer").map(ParamValue::Int),
        DeValue::Float(f) => {
            let s = f.as_str().replace('_', "");
            s.parse::<f64>().map(ParamValue::Float).map_err(|_| format!("invalid float {s}"))
        }
        DeValue::Boolean(b) => Ok(ParamValue::Bool(*b)),
        other => Err(format!("expected a number, string or boolean, found {}", type_name(other))),
    }
}

pub(super) struct Raw<'a> {
    pub(super) sample: Option<(String, std::ops::Range<usize>)>,
    pub(super) method: Option<&'static dyn Method>,
    pub(super) seed: Option<u64>,
    pub(super) output_path: Option<(String, std::ops::Range<usize>)>,
    pub(super) width: Option<u32>,
    pub(super) height: Option<u32>,
    pub(super) bit_depth: Option<(i64, std::ops::Range<usize>)>,
    pub(super) tileable: bool,
    pub(super) source_map: Option<(String, std::ops::Range<usize>)>,
    pub(super) companions: Vec<RawCompanion>,
    pub(super) params: Vec<(String, ParamValue)>,
    pub(super) metrics: Vec<String>,
    pub(super) sweep: Vec<(String, Vec<(ParamValue, std::ops::Range<usize>)>)>,
    pub(super) _src: std::marker::PhantomData<&'a ()>,
}

/// A `[[companion]]` as read, checked key by key; `index` is its place (0-based) in the file.
pub(super) struct RawCompanion {
    pub(super) index: usize,
    pub(super) sample: Option<PathBuf>,
    pub(super) path: Option<(String, std::ops::Range<usize>)>,
    pub(super) kind: crate::synth::placement::MapKind,
    pub(super) bit_depth: Option<(i64, std::ops::Range<usize>)>,
}

/// What a job needs before its sweep points can be made into jobs: every required key present
/// and valid.
pub(super) struct Ready {
    pub method: &'static dyn Method,
    pub sample: PathBuf,
    pub path_template: String,
    pub path_span: std::ops::Range<usize>,
    pub width: u32,
    pub height: u32,
    pub format: Format,
    pub bit_depth: u8,
    pub native_depth: bool,
    pub file_digest: Digest,
    /// Companions with their format and bit depth decided; paths still templates.
    pub companions: Vec<super::Companion>,
}
