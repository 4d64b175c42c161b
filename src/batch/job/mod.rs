//! Job files: finding them, reading and validating them, expanding sweeps into runnable jobs.
//!
//! A job file names a sample, a method, a seed, an output and parameters (the schema is a
//! contract; see README.md). A `[sweep]` table turns one file into many jobs. Validation happens
//! before anything runs and collects *every* problem in every file, each pointing at the file,
//! line, column and key, so that a user fixes a job directory in one pass.
//!
//! This module holds the job model and discovery; `read` reads one file's TOML keys, `sweep`
//! reads `[sweep]` and expands it into jobs, `output_path` templates and checks output paths.

mod output_path;
mod read;
mod source;
mod sweep;

pub use output_path::{expand_template, normalise_output_path};
pub use read::parse_job_file;

use crate::digest::Digest;
use crate::error::Error;
use crate::image::io::Format;
use crate::synth::method::Method;
use crate::synth::params::Params;
use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};

/// The top-level keys of a job file.
pub const TOP_KEYS: &[&str] = &[
    "sample",
    "method",
    "seed",
    "output",
    "params",
    "sweep",
    "metrics",
    "companion",
    "sample_mask",
    "samples",
    "augment",
    "inpaint",
    "guide",
];
/// The keys of the `[guide]` table.
pub const GUIDE_KEYS: &[&str] = &["target", "source", "weight", "passes"];
/// `[guide] passes` when the file leaves it out: Efros and Freeman iterate three to five times.
pub const DEFAULT_GUIDE_PASSES: u32 = 3;
/// `[guide] weight` when the file leaves it out: the guide's share of a block's error.
pub const DEFAULT_GUIDE_WEIGHT: f64 = 0.7;
/// The keys of the `[inpaint]` table.
pub const INPAINT_KEYS: &[&str] = &["image", "mask", "channel"];
/// The keys of the `[output]` table.
pub const OUTPUT_KEYS: &[&str] = &["path", "width", "height", "bit_depth", "tileable", "source_map"];
/// The keys of a `[[companion]]` table.
pub const COMPANION_KEYS: &[&str] = &["sample", "path", "kind", "bit_depth"];
/// Largest output side accepted.
pub const MAX_OUTPUT_SIDE: i64 = 65_536;
/// Largest number of jobs one file may expand to (a guard against a typo like `to = 1e9`).
pub const MAX_SWEEP_POINTS: usize = 100_000;

/// One problem in a job file.
#[derive(Clone, Debug, PartialEq)]
pub struct JobError {
    /// The job file as the user named it (or as found under a directory they named).
    pub file: PathBuf,
    /// 1-based line and column, when the problem has a place in the file.
    pub position: Option<(usize, usize)>,
    /// The dotted key concerned, e.g. `params.block`.
    pub key: Option<String>,
    pub message: String,
}

impl fmt::Display for JobError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file.display())?;
        if let Some((l, c)) = self.position {
            write!(f, ":{l}:{c}")?;
        }
        write!(f, ": ")?;
        if let Some(k) = &self.key {
            write!(f, "`{k}`: ")?;
        }
        write!(f, "{}", self.message)
    }
}

/// What a job writes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OutputSpec {
    /// Relative to the output directory, `/`-separated, normalised.
    pub path: String,
    pub width: u32,
    pub height: u32,
    pub format: Format,
    /// 8 or 16 for PNG, 32 for EXR.
    pub bit_depth: u8,
    /// The job file gave no `bit_depth` for a PNG: the sample's precision decides (16 for a
    /// 16-bit or float sample), once the sample is read.
    pub native_depth: bool,
    /// `tileable = true`: the output wraps seamlessly.
    pub tileable: bool,
    /// `source_map`: where the placement is written (an EXR), relative to the output directory.
    pub source_map: Option<String>,
}

/// A `[[companion]]`: another map of the sample (a normal map, gloss, height…) rendered with the
/// main output's placement.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Companion {
    /// The companion's sample (the first sample's map), resolved against the job file's directory.
    pub sample: PathBuf,
    /// With several `samples`: the other samples' maps, in their order (`sample = [...]`).
    pub more_samples: Vec<PathBuf>,
    /// Relative to the output directory, normalised.
    pub path: String,
    pub format: Format,
    pub bit_depth: u8,
    /// As [`OutputSpec::native_depth`], for the companion's own sample.
    pub native_depth: bool,
    pub kind: crate::synth::placement::MapKind,
}

impl Companion {
    pub fn encoding(&self) -> crate::image::io::Encoding {
        crate::image::io::Encoding { format: self.format, bit_depth: self.bit_depth }
    }
    pub fn kind_name(&self) -> &'static str {
        self.kind.name()
    }
}

impl OutputSpec {
    pub fn encoding(&self) -> crate::image::io::Encoding {
        crate::image::io::Encoding { format: self.format, bit_depth: self.bit_depth }
    }
    pub fn to_json(&self) -> serde_json::Value {
        let mut v = serde_json::json!({
            "path": self.path, "width": self.width, "height": self.height,
            "format": self.format.name(), "bit_depth": self.bit_depth,
        });
        // Only when asked for, so the content keys of jobs without them stay as they were.
        if self.tileable {
            v["tileable"] = serde_json::Value::Bool(true);
        }
        if let Some(m) = &self.source_map {
            v["source_map"] = serde_json::Value::String(m.clone());
        }
        v
    }
}

/// `[inpaint]`: repair an image instead of making a new one. The image is the job's first sample
/// ([`Job::sample`]) and the output has its size. With no `sample`/`samples` in the job file the
/// fill copies from the image itself (outside the mask); with them it copies from those, and
/// from the image too only when they list it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Inpaint {
    /// Which pixels to fill.
    pub mask: InpaintMask,
    /// Whether the fill may copy from the image (outside the mask, inside its sample mask).
    pub copy_from_image: bool,
}

/// Where an inpainting job's fill region comes from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum InpaintMask {
    /// `mask = "…"`: an image of the image's size, white (at least half) = fill.
    File(PathBuf),
    /// `channel = "a" | "r" | "g" | "b"`: one of the image's own channels, below half = fill (for
    /// `a`: the transparent pixels).
    Channel(MaskChannel),
}

crate::choice! {
    /// A channel of an image used as its inpaint mask (`[inpaint] channel`).
    pub enum MaskChannel {
        R = "r",
        G = "g",
        B = "b",
        A = "a",
    }
}

/// `[guide]`: guided synthesis and texture transfer.
#[derive(Clone, Debug, PartialEq)]
pub struct GuideSpec {
    /// The output's guide (the output's size); its luminance is followed.
    pub target: PathBuf,
    /// The sample's guide (the sample's size); `None`: the sample's own luminance.
    pub source: Option<PathBuf>,
    /// The guide's share of a block's error, 0..=1.
    pub weight: f64,
    /// Passes of the iteration, 1..=8.
    pub passes: u32,
}

/// A sample after the first of `samples = [...]`, with its `sample_mask` entry.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MoreSample {
    pub path: PathBuf,
    pub mask: Option<PathBuf>,
}

/// One runnable job (a job file, or one point of its sweep).
#[derive(Clone)]
pub struct Job {
    /// The job file's path relative to the job root, plus `#k=v,…` for a sweep point.
    pub id: String,
    /// The job file as the user named it, for messages.
    pub file: PathBuf,
    /// The job file's path relative to the job root.
    pub file_rel: String,
    pub file_digest: Digest,
    /// The sample, resolved against the job file's directory.
    pub sample: PathBuf,
    /// `sample_mask`: which sample pixels may be copied (white), resolved like the sample (with
    /// `samples`, the first sample's; the others' are in [`Job::more_samples`]).
    pub sample_mask: Option<PathBuf>,
    /// `samples = [...]`: the samples after the first (which is [`Job::sample`]).
    pub more_samples: Vec<MoreSample>,
    /// `augment = [...]`: transformed copies of every sample that are searched too.
    pub augment: Vec<crate::synth::atlas::Augment>,
    /// `[inpaint]`: fill part of the sample (the image) and keep the rest.
    pub inpaint: Option<Inpaint>,
    /// `[guide]`: follow a target guide.
    pub guide: Option<GuideSpec>,
    pub method: &'static dyn Method,
    pub seed: u64,
    pub params: Params,
    pub output: OutputSpec,
    /// Metrics to compute after synthesis (`metrics = true` or a list); empty for none.
    pub metrics: Vec<String>,
    /// Further maps rendered with the output's placement (`[[companion]]`).
    pub companions: Vec<Companion>,
    /// Line and column of each key, to point errors found later (e.g. by `Method::check`) at it.
    pub positions: BTreeMap<String, (usize, usize)>,
}

impl fmt::Debug for Job {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Job").field("id", &self.id).field("method", &self.method.name()).finish()
    }
}

impl Job {
    /// Whether the job searches an atlas of pieces ([`crate::synth::atlas`]): several samples,
    /// or transformed copies of its sample.
    pub fn uses_atlas(&self) -> bool {
        !self.more_samples.is_empty() || !self.augment.is_empty()
    }

    /// Every sample, the first one first.
    pub fn sample_paths(&self) -> Vec<PathBuf> {
        std::iter::once(self.sample.clone()).chain(self.more_samples.iter().map(|m| m.path.clone())).collect()
    }

    /// Every sample's mask file, in the order of [`Job::sample_paths`].
    pub fn sample_mask_paths(&self) -> Vec<Option<PathBuf>> {
        std::iter::once(self.sample_mask.clone()).chain(self.more_samples.iter().map(|m| m.mask.clone())).collect()
    }

    /// The guide images, when the job is guided (decoded with the samples).
    pub fn guide_files(&self) -> Vec<PathBuf> {
        self.guide.iter().flat_map(|g| std::iter::once(g.target.clone()).chain(g.source.clone())).collect()
    }

    /// The inpaint mask image, when the job inpaints with one (decoded with the samples).
    pub fn inpaint_mask_file(&self) -> Option<PathBuf> {
        match &self.inpaint {
            Some(Inpaint { mask: InpaintMask::File(p), .. }) => Some(p.clone()),
            _ => None,
        }
    }

    /// Every file the job asks for by name: the output, its companions and its source map.
    pub fn written_paths(&self) -> Vec<&str> {
        let mut v = vec![self.output.path.as_str()];
        v.extend(self.companions.iter().map(|c| c.path.as_str()));
        v.extend(self.output.source_map.as_deref());
        v
    }

    /// Every file and folder the job writes, known before it runs: [`Job::written_paths`] as
    /// files, and the folders of its method's extras (`{output stem}.{folder}`, e.g. a tile-set
    /// export `t.tiles`), whose whole content is the job's.
    pub fn claims(&self) -> Claims {
        let folders =
            self.method.extra_folders(&self.params).into_iter().map(|f| format!("{}.{f}", output_stem(&self.output.path))).collect();
        Claims { files: self.written_paths().into_iter().map(str::to_string).collect(), folders }
    }

    /// An error about this job's key `key` (e.g. `params.block`), placed at the key's line.
    pub fn error(&self, key: Option<&str>, message: impl Into<String>) -> JobError {
        JobError {
            file: self.file.clone(),
            position: key.and_then(|k| self.positions.get(k).copied()),
            key: key.map(str::to_string),
            message: message.into(),
        }
    }
}

/// The output path without its extension: extras go to `{stem}.{name}`.
pub fn output_stem(output_path: &str) -> &str {
    let file_start = output_path.rfind('/').map_or(0, |i| i + 1);
    let stem_end = output_path[file_start..].rfind('.').map_or(output_path.len(), |i| file_start + i);
    &output_path[..stem_end]
}

/// What one job writes: files by name, and folders it owns whole.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Claims {
    pub files: Vec<String>,
    pub folders: Vec<String>,
}

impl Claims {
    /// Whether `path` (a file relative to the output directory) is one of these files or lies in
    /// one of these folders.
    pub fn covers(&self, path: &str) -> bool {
        self.files.iter().any(|f| f == path) || self.folders.iter().any(|d| in_folder(path, d))
    }
}

/// Whether `path` lies under the folder `dir` (both relative, `/`-separated), or is the folder.
pub fn in_folder(path: &str, dir: &str) -> bool {
    path.strip_prefix(dir).is_some_and(|rest| rest.is_empty() || rest.starts_with('/'))
}

/// A job that cannot run, with every reason.
#[derive(Clone, Debug)]
pub struct InvalidJob {
    pub id: String,
    pub file: PathBuf,
    pub errors: Vec<JobError>,
}

/// The result of reading job files: runnable jobs and invalid ones, both sorted by id.
#[derive(Debug, Default)]
pub struct JobSet {
    pub jobs: Vec<Job>,
    pub invalid: Vec<InvalidJob>,
}

/// A job file found under a root.
#[derive(Clone, Debug)]
pub struct JobFile {
    /// As the user will recognise it (the argument, or the argument joined with the found path).
    pub path: PathBuf,
    /// Relative to the job root, `/`-separated.
    pub rel: String,
}

/// Finds job files: each argument is a `.toml` file (its root is its directory) or a directory
/// searched recursively for `*.toml` (its root is itself). Sorted, without duplicates.
pub fn discover(args: &[PathBuf]) -> Result<Vec<JobFile>, Error> {
    let mut found: BTreeMap<String, JobFile> = BTreeMap::new();
    for arg in args {
        let meta = std::fs::metadata(arg).map_err(|e| Error::io(arg, "read", e))?;
        if meta.is_dir() {
            let mut files = Vec::new();
            walk(arg, &mut files).map_err(|e| Error::io(arg, "search", e))?;
            for f in files {
                let rel = slash_path(f.strip_prefix(arg).expect("walk stays under root"));
                add(&mut found, JobFile { path: f, rel })?;
            }
        } else {
            let rel = arg.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
            add(&mut found, JobFile { path: arg.clone(), rel })?;
        }
    }
    Ok(found.into_values().collect())
}

/// Adds a job file unless it is already there; two *different* files with the same id (same path
/// relative to their roots) would make ids, outputs and golden files ambiguous, so that is refused.
fn add(found: &mut BTreeMap<String, JobFile>, f: JobFile) -> Result<(), Error> {
    match found.get(&f.rel) {
        None => {
            found.insert(f.rel.clone(), f);
            Ok(())
        }
        Some(existing) => {
            let same = match (existing.path.canonicalize(), f.path.canonicalize()) {
                (Ok(a), Ok(b)) => a == b,
                _ => existing.path == f.path,
            };
            if same {
                Ok(())
            } else {
                Err(Error::Usage(format!(
                    "{} and {} both have the job id `{}` (ids are paths relative to the directory given); run them from a common parent directory",
                    existing.path.display(),
                    f.path.display(),
                    f.rel
                )))
            }
        }
    }
}

fn walk(dir: &Path, out: &mut Vec<PathBuf>) -> std::io::Result<()> {
    let mut entries: Vec<_> = std::fs::read_dir(dir)?.collect::<Result<_, _>>()?;
    entries.sort_by_key(|e| e.file_name());
    for e in entries {
        let name = e.file_name();
        if name.to_string_lossy().starts_with('.') {
            continue;
        }
        let path = e.path();
        let ft = e.file_type()?;
        if ft.is_dir() {
            walk(&path, out)?;
        } else if path.extension().is_some_and(|x| x == "toml") {
            out.push(path);
        }
    }
    Ok(())
}

fn slash_path(p: &Path) -> String {
    p.components().map(|c| c.as_os_str().to_string_lossy().into_owned()).collect::<Vec<_>>().join("/")
}

/// Reads, validates and expands job files into a plan. Problems never abort the plan: they make
/// the affected jobs invalid, with all their errors.
pub fn read_all(files: &[JobFile]) -> JobSet {
    let mut plan = JobSet::default();
    for f in files {
        match read::read_job_file(f) {
            Ok(jobs) => plan.jobs.extend(jobs),
            Err(errors) => plan.invalid.push(InvalidJob { id: f.rel.clone(), file: f.path.clone(), errors }),
        }
    }
    reject_shared_outputs(&mut plan);
    plan.jobs.sort_by(|a, b| a.id.cmp(&b.id));
    plan.invalid.sort_by(|a, b| a.id.cmp(&b.id));
    plan
}

/// Two jobs writing the same file would race; all of them are made invalid. "The same file"
/// covers every file a job writes ([`Job::claims`]): its output, companions and source map, and
/// anything inside the folder of its extras (a tile-set export), which another job's output must
/// not land in either.
fn reject_shared_outputs(plan: &mut JobSet) {
    let claims: Vec<Claims> = plan.jobs.iter().map(Job::claims).collect();
    let mut by_output: BTreeMap<String, Vec<usize>> = BTreeMap::new();
    for (i, c) in claims.iter().enumerate() {
        for p in &c.files {
            by_output.entry(p.clone()).or_default().push(i);
        }
    }
    let mut bad: BTreeMap<usize, String> = BTreeMap::new();
    for (path, idx) in &by_output {
        if idx.len() > 1 {
            for &i in idx {
                let others: Vec<&str> = idx.iter().filter(|&&k| k != i).map(|&k| plan.jobs[k].id.as_str()).collect();
                bad.insert(
                    i,
                    format!(
                        "output `{path}` is also written by {}; give each job its own output path (e.g. with {{seed}} in a sweep)",
                        others.join(", ")
                    ),
                );
            }
        }
    }
    // Folders: every file under one, from the sorted map (a range from the folder's name), and
    // every other job's folder of the same name or inside it.
    for (i, c) in claims.iter().enumerate() {
        for dir in &c.folders {
            let inside = by_output.range(dir.clone()..).take_while(|(p, _)| p.starts_with(dir.as_str())).filter(|(p, _)| in_folder(p, dir));
            let mut writers: Vec<(usize, String)> =
                inside.flat_map(|(p, idx)| idx.iter().filter(|&&k| k != i).map(move |&k| (k, format!("`{p}`")))).collect();
            for (k, other) in claims.iter().enumerate().filter(|&(k, _)| k != i) {
                writers.extend(
                    other.folders.iter().filter(|d| in_folder(d, dir) || in_folder(dir, d)).map(|d| (k, format!("the folder `{d}/`"))),
                );
            }
            for (k, what) in writers {
                let folder_owner = plan.jobs[i].id.clone();
                let writer = plan.jobs[k].id.clone();
                bad.insert(k, format!("{what} lies in `{dir}/`, the folder job {folder_owner} writes its extras to (export_tiles); give each job its own output path"));
                bad.entry(i).or_insert_with(|| format!("its extras folder `{dir}/` (export_tiles) would also receive {what} from job {writer}; give each job its own output path"));
            }
        }
    }
    for (i, msg) in bad.into_iter().rev() {
        let job = plan.jobs.remove(i);
        let err = job.error(Some("output.path"), msg);
        plan.invalid.push(InvalidJob { id: job.id, file: job.file, errors: vec![err] });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, body: &str) -> JobFile {
        let p = dir.join(name);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(&p, body).unwrap();
        JobFile { path: p, rel: name.to_string() }
    }

    fn tmpdir(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("texsyn-job-test-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        std::fs::write(d.join("s.png"), b"not decoded here").unwrap();
        d
    }

    #[test]
    fn a_complete_job_parses_with_defaults_filled() {
        let d = tmpdir("ok");
        let f = write(
            &d,
            "a.toml",
            "sample = \"s.png\"\nmethod = \"quilting\"\nseed = 7\n[output]\npath = \"x/a.png\"\nwidth = 100\nheight = 80\n[params]\nblock = 30\n",
        );
        let plan = read_all(&[f]);
        assert!(plan.invalid.is_empty(), "{:?}", plan.invalid);
        let j = &plan.jobs[0];
        assert_eq!(j.id, "a.toml");
        assert_eq!(j.params.int("overlap").unwrap(), 5);
        assert_eq!(j.output.bit_depth, 8);
        assert_eq!(j.positions["params.block"], (9, 1));
    }

    #[test]
    fn sweeps_expand_with_stable_ids_and_templated_paths() {
        let d = tmpdir("sweep");
        let f = write(
            &d,
            "s.toml",
            "sample = \"s.png\"\nmethod = \"quilting\"\n[output]\npath = \"o/{block}_{seed}.png\"\nwidth = 60\nheight = 60\n[sweep]\nseed = { from = 1, to = 3 }\nblock = [20, 30]\n",
        );
        let plan = read_all(&[f]);
        assert!(plan.invalid.is_empty(), "{:?}", plan.invalid);
        let ids: Vec<&str> = plan.jobs.iter().map(|j| j.id.as_str()).collect();
        assert_eq!(ids.len(), 6);
        assert!(ids.contains(&"s.toml#block=20,seed=1"));
        let j = plan.jobs.iter().find(|j| j.id == "s.toml#block=30,seed=3").unwrap();
        assert_eq!(j.output.path, "o/30_3.png");
        assert_eq!(j.seed, 3);
    }

    #[test]
    fn every_problem_is_reported_with_line_and_key() {
        let d = tmpdir("bad");
        let f = write(
            &d,
            "bad.toml",
            "sample = \"missing.png\"\nmethod = \"quilting\"\nseed = -1\ncolour = 1\n[output]\npath = \"../x.png\"\nwidth = 0\nheight = 10\n[params]\nblok = 3\n",
        );
        let plan = read_all(&[f]);
        let errs = &plan.invalid[0].errors;
        let text: Vec<String> = errs.iter().map(|e| e.to_string()).collect();
        let all = text.join("\n");
        assert!(all.contains("bad.toml:3:8: `seed`"), "{all}");
        assert!(all.contains("bad.toml:4:1: `colour`: unknown key"), "{all}");
        assert!(all.contains("`output.width`: 0 is out of range"), "{all}");
        assert!(all.contains("missing.png` does not exist"), "{all}");
        assert!(all.contains("blok") && all.contains("did you mean `block`"), "{all}");
    }

    #[test]
    fn metrics_key_accepts_true_or_a_list_and_rejects_unknown_names() {
        let d = tmpdir("metrics");
        let head = "sample = \"s.png\"\nmethod = \"quilting\"\nseed = 1\n[output]\npath = \"o.png\"\nwidth = 60\nheight = 60\n";
        let all = write(&d, "all.toml", &format!("metrics = true\n{head}"));
        let some = write(&d, "some.toml", &format!("metrics = [\"kl_gray\", \"verbatim\"]\n{head}").replace("o.png", "p.png"));
        let bad = write(&d, "bad.toml", &format!("metrics = [\"kl_grey\"]\n{head}").replace("o.png", "q.png"));
        let plan = read_all(&[all, some, bad]);
        assert_eq!(plan.jobs[0].metrics, crate::metrics::DEFAULT_METRICS);
        assert_eq!(plan.jobs[1].metrics, vec!["kl_gray", "verbatim"]);
        let msg = plan.invalid[0].errors[0].to_string();
        assert!(msg.contains("bad.toml:1:12: `metrics`: unknown metric `kl_grey` (did you mean `kl_gray`?)"), "{msg}");
    }

    #[test]
    fn a_symlink_loop_or_a_dangling_link_as_sample_is_named_as_such() {
        let d = tmpdir("links");
        std::os::unix::fs::symlink(d.join("loop_b.png"), d.join("loop_a.png")).unwrap();
        std::os::unix::fs::symlink(d.join("loop_a.png"), d.join("loop_b.png")).unwrap();
        std::os::unix::fs::symlink(d.join("gone.png"), d.join("dangling.png")).unwrap();
        let job = |sample: &str| {
            format!("sample = \"{sample}\"\nmethod = \"quilting\"\nseed = 1\n[output]\npath = \"{sample}\"\nwidth = 8\nheight = 8\n")
        };
        let a = write(&d, "a.toml", &job("loop_a.png"));
        let b = write(&d, "b.toml", &job("dangling.png"));
        let plan = read_all(&[a, b]);
        let text: Vec<String> = plan.invalid.iter().flat_map(|i| i.errors.iter().map(|e| e.to_string())).collect();
        let all = text.join("\n");
        assert!(all.contains("loop_a.png` is a symbolic link loop"), "{all}");
        assert!(all.contains("dangling.png` is a symbolic link to nothing"), "{all}");
    }

    #[test]
    fn a_huge_sweep_is_refused_before_it_is_expanded() {
        let d = tmpdir("huge");
        let f = write(
            &d,
            "huge.toml",
            "sample = \"s.png\"\nmethod = \"quilting\"\n[output]\npath = \"q_{block}_{seed}.png\"\nwidth = 8\nheight = 8\n[sweep]\nseed = { from = 1, to = 100000 }\nblock = { from = 10, to = 109 }\n",
        );
        let started = std::time::Instant::now();
        let plan = read_all(&[f]);
        let all: Vec<String> = plan.invalid[0].errors.iter().map(|e| e.to_string()).collect();
        let all = all.join("\n");
        assert!(all.contains("expands to more than 100000 jobs") && all.contains("seed: 100000") && all.contains("block: 100"), "{all}");
        // Not a timing assertion on the machine's speed: expanding 10^7 points takes seconds and
        // gigabytes, counting them takes microseconds; a minute means the count was skipped.
        assert!(started.elapsed().as_secs() < 60);
    }

    #[test]
    fn malformed_toml_names_line_and_column() {
        let d = tmpdir("toml");
        let f = write(&d, "m.toml", "sample = \"s.png\"\nmethod = quilting\n");
        let plan = read_all(&[f]);
        let e = &plan.invalid[0].errors[0];
        assert_eq!(e.position.unwrap().0, 2);
        assert!(e.message.contains("malformed TOML"), "{}", e.message);
    }

    #[test]
    fn two_files_with_one_id_are_refused() {
        let d = tmpdir("ids");
        let a = write(&d, "x/same.toml", "");
        let b = write(&d, "y/same.toml", "");
        let err = discover(&[d.join("x"), d.join("y")]).unwrap_err();
        assert!(err.to_string().contains("both have the job id `same.toml`"), "{err}");
        // The same file named twice is fine.
        assert_eq!(discover(&[a.path.clone(), a.path.clone(), d.join("x")]).unwrap().len(), 1);
        let _ = b;
    }

    #[test]
    fn output_paths_must_stay_inside() {
        assert!(normalise_output_path("/etc/x.png").is_err());
        assert!(normalise_output_path("a/../../x.png").is_err());
        assert_eq!(normalise_output_path("./a//b.png").unwrap(), "a/b.png");
        assert!(normalise_output_path("manifest.json").is_err());
    }

    #[test]
    fn shared_outputs_invalidate_every_writer() {
        let d = tmpdir("shared");
        let body = "sample = \"s.png\"\nmethod = \"quilting\"\nseed = 1\n[output]\npath = \"same.png\"\nwidth = 60\nheight = 60\n";
        let a = write(&d, "a.toml", body);
        let b = write(&d, "b.toml", body);
        let plan = read_all(&[a, b]);
        assert!(plan.jobs.is_empty());
        assert_eq!(plan.invalid.len(), 2);
        assert!(plan.invalid[0].errors[0].message.contains("also written by b.toml"));
    }
}
