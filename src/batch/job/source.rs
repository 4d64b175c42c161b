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

/// Byte offsets → 1-based (line, column), in logarithmic time: every key of a job file gets a
/// position, and scanning the text from its start for each would make a 10 MB file of 80 000
/// keys take minutes.
pub(super) struct LineIndex {
    /// Byte offset of each line's first byte.
    line_starts: Vec<usize>,
    /// (byte offset, chars before it) at char boundaries about every [`Self::STRIDE`] bytes, so
    /// that a column on a very long line is counted from a nearby mark.
    marks: Vec<(usize, usize)>,
}

impl LineIndex {
    const STRIDE: usize = 4096;

    pub(super) fn new(src: &str) -> LineIndex {
        let line_starts = std::iter::once(0).chain(src.match_indices('\n').map(|(i, _)| i + 1)).collect();
        let mut marks = vec![(0, 0)];
        for (chars, (i, _)) in src.char_indices().enumerate() {
            if i >= marks.last().expect("one mark").0 + Self::STRIDE {
                marks.push((i, chars));
            }
        }
        LineIndex { line_starts, marks }
    }

    /// Chars of `src` before byte `offset` (a char boundary).
    fn chars_before(&self, src: &str, offset: usize) -> usize {
        let k = self.marks.partition_point(|m| m.0 <= offset) - 1;
        let (at, count) = self.marks[k];
        count + src[at..offset].chars().count()
    }

    pub(super) fn line_col(&self, src: &str, offset: usize) -> (usize, usize) {
        let mut offset = offset.min(src.len());
        while !src.is_char_boundary(offset) {
            offset -= 1;
        }
        let line = self.line_starts.partition_point(|&s| s <= offset);
        let start = self.line_starts[line - 1];
        (line, self.chars_before(src, offset) - self.chars_before(src, start) + 1)
    }
}

/// At most this many problems are listed per job file; the rest are counted in one last line.
/// A file with 80 000 unknown keys gets a readable answer in well under a second.
pub(super) const MAX_LISTED_ERRORS: usize = 50;

pub(super) struct Ctx<'a> {
    pub(super) file: &'a JobFile,
    pub(super) src: &'a str,
    pub(super) errors: Vec<JobError>,
    /// Problems found beyond [`MAX_LISTED_ERRORS`].
    pub(super) unlisted: usize,
    pub(super) positions: BTreeMap<String, (usize, usize)>,
    lines: LineIndex,
}

impl<'a> Ctx<'a> {
    pub(super) fn new(file: &'a JobFile, src: &'a str) -> Ctx<'a> {
        Ctx { file, src, errors: Vec::new(), unlisted: 0, positions: BTreeMap::new(), lines: LineIndex::new(src) }
    }
    pub(super) fn err(&mut self, span: Option<std::ops::Range<usize>>, key: Option<&str>, message: impl Into<String>) {
        let e = JobError {
            file: self.file.path.clone(),
            position: span.map(|s| self.lines.line_col(self.src, s.start)),
            key: key.map(str::to_string),
            message: message.into(),
        };
        self.push(e);
    }
    /// Records a problem unless it is already listed; beyond [`MAX_LISTED_ERRORS`], counts it.
    pub(super) fn push(&mut self, e: JobError) {
        if self.errors.len() >= MAX_LISTED_ERRORS {
            self.unlisted += 1;
        } else if !self.errors.contains(&e) {
            self.errors.push(e);
        }
    }
    pub(super) fn at(&mut self, key: &str, span: std::ops::Range<usize>) {
        let pos = self.lines.line_col(self.src, span.start);
        self.positions.insert(key.to_string(), pos);
    }
    /// The problems, in file order, with the count of unlisted ones as a last line.
    pub(super) fn into_errors(mut self) -> Vec<JobError> {
        // Errors without a place (missing keys) come last.
        self.errors.sort_by_key(|e| e.position.unwrap_or((usize::MAX, 0)));
        if self.unlisted > 0 {
            self.errors.push(JobError {
                file: self.file.path.clone(),
                position: None,
                key: None,
                message: format!(
                    "… and {} more problem(s) in this file, not listed (the first {MAX_LISTED_ERRORS} are above)",
                    self.unlisted
                ),
            });
        }
        self.errors
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
    /// `sample_mask` as a string (one sample's mask).
    pub(super) sample_mask: Option<(String, std::ops::Range<usize>)>,
    /// `samples = [...]` as read: each path with its span, and the list's span.
    pub(super) samples: Option<(Vec<(String, std::ops::Range<usize>)>, std::ops::Range<usize>)>,
    /// `sample_mask = [...]`, a list parallel to `samples` (`""` for a sample without a mask).
    pub(super) sample_masks: Option<(Vec<(String, std::ops::Range<usize>)>, std::ops::Range<usize>)>,
    /// `augment = [...]`, checked word by word, and the list's span.
    pub(super) augment: Option<(Vec<crate::synth::atlas::Augment>, std::ops::Range<usize>)>,
    /// `[inpaint]`: the image (path, span) and the mask as read; checked in `read`.
    pub(super) inpaint: Option<RawInpaint>,
    /// `[guide]` as read: target and source (path, span), weight; checked in `read`.
    pub(super) guide: Option<RawGuide>,
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

/// `[guide]` as read, each key checked for type.
#[derive(Default)]
pub(super) struct RawGuide {
    pub(super) span: std::ops::Range<usize>,
    pub(super) target: Option<(String, std::ops::Range<usize>)>,
    pub(super) source: Option<(String, std::ops::Range<usize>)>,
    pub(super) weight: Option<f64>,
    pub(super) passes: Option<u32>,
    pub(super) passes_span: Option<std::ops::Range<usize>>,
}

/// `[inpaint]` as read, each key checked for type.
#[derive(Default)]
pub(super) struct RawInpaint {
    pub(super) span: std::ops::Range<usize>,
    pub(super) image: Option<(String, std::ops::Range<usize>)>,
    pub(super) mask: Option<(String, std::ops::Range<usize>)>,
    pub(super) channel: Option<super::MaskChannel>,
    /// `channel` is in the file, valid or not (a bad word is reported once, not also as missing).
    pub(super) channel_given: bool,
}

/// A `[[companion]]` as read, checked key by key; `index` is its place (0-based) in the file.
pub(super) struct RawCompanion {
    pub(super) index: usize,
    pub(super) sample: Option<PathBuf>,
    /// `sample = [...]`: the other samples' maps, and the list's length and span (checked
    /// against `samples` once both are read).
    pub(super) more: Vec<PathBuf>,
    pub(super) listed: Option<(usize, std::ops::Range<usize>)>,
    pub(super) path: Option<(String, std::ops::Range<usize>)>,
    pub(super) kind: crate::synth::placement::MapKind,
    pub(super) bit_depth: Option<(i64, std::ops::Range<usize>)>,
}

/// What a job needs before its sweep points can be made into jobs: every required key present
/// and valid.
pub(super) struct Ready {
    pub method: &'static dyn Method,
    pub sample: PathBuf,
    /// `sample_mask`, resolved against the job file's directory.
    pub sample_mask: Option<PathBuf>,
    /// `samples[1..]`, each with its mask.
    pub more_samples: Vec<super::MoreSample>,
    pub augment: Vec<crate::synth::atlas::Augment>,
    pub inpaint: Option<super::Inpaint>,
    pub guide: Option<super::GuideSpec>,
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
