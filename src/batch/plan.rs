//! The plan: for every job, whether it runs and why — as data.
//!
//! Planning reads the job files, decodes each distinct sample once, runs each method's own
//! checks, computes content keys and compares them with the manifest already in the output
//! directory. It writes nothing, so `--dry-run` is just a printed plan, and `run` executes the
//! very plan it would have printed.

use crate::batch::execute::{LoadedSample, OutputsProblem, load_sample, outputs_intact};
use crate::batch::guide::GuideImages;
use crate::batch::inpaint::{MaskSource, fill_region};
use crate::batch::job::{self, InpaintMask, InvalidJob, Job, JobError, JobSet};
use crate::batch::manifest::{self, FileRef, JobRecord, Manifest, SampleRecord, Status};
use crate::batch::memory;
use crate::batch::samples::{AtlasSamples, assemble, pack_map};
use crate::batch::shard::{self, Shard};
use crate::digest::Digest;
use crate::error::Error;
use crate::synth::advice::{self, Analysis};
use crate::synth::atlas::{Atlas, Augment};
use crate::synth::constraints::{FillRegion, Guide, SampleMask};
use crate::synth::method::Uses;
use crate::synth::params::Choice;
use crate::synth::placement::MapKind;
use crate::synth::wrap;
use rayon::prelude::*;
use std::collections::{BTreeMap, BTreeSet};
use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// What planning needs to know.
#[derive(Clone, Debug)]
pub struct PlanOptions {
    /// The output directory: where the previous manifest is looked for.
    pub out: PathBuf,
    /// Run every valid job, up to date or not.
    pub force: bool,
    /// Plan only this worker's part of the job set.
    pub shard: Option<Shard>,
    /// Jobs whose estimated peak memory exceeds this many bytes are invalid (`None`: no limit).
    pub max_memory: Option<u64>,
    /// Run even when the output directory records jobs of another job root (`--allow-other-root`).
    pub allow_other_root: bool,
}

/// Why a job runs.
#[derive(Clone, Debug, PartialEq)]
pub enum Reason {
    Forced,
    NotInManifest,
    PreviousRun(Status),
    InputsChanged,
    MetricsNotRecorded,
    Outputs(OutputsProblem),
}

impl fmt::Display for Reason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Reason::Forced => f.write_str("--force"),
            Reason::NotInManifest => f.write_str("not in the manifest"),
            Reason::PreviousRun(s) => write!(f, "previous run {}", s.name()),
            Reason::InputsChanged => f.write_str("inputs changed (content key differs)"),
            Reason::MetricsNotRecorded => f.write_str("requested metrics are not recorded"),
            Reason::Outputs(p) => write!(f, "{p}"),
        }
    }
}

/// What will happen to a valid job.
#[derive(Clone, Debug, PartialEq)]
pub enum Action {
    Run(Reason),
    /// Its record in the previous manifest still describes its files: kept as it is.
    UpToDate,
}

/// A valid job with its decoded sample and the record it will get.
pub struct Entry {
    pub job: Job,
    pub sample: Arc<LoadedSample>,
    /// The decoded sample of each of `job.companions`, in order.
    pub companions: Vec<Arc<LoadedSample>>,
    /// `job.sample_mask` decoded, and the mask it makes.
    pub sample_mask: Option<(Arc<LoadedSample>, SampleMask)>,
    /// `job.inpaint`: its mask image decoded (none for a channel of the image), and the region it fills.
    pub fill: Option<(Option<Arc<LoadedSample>>, FillRegion)>,
    /// `job.guide`: its target and source images decoded, and the guide they make.
    pub guide: Option<(Arc<LoadedSample>, Option<Arc<LoadedSample>>, Guide)>,
    /// Several samples or `augment`: the atlas `sample` is, and what it was made from.
    pub atlas: Option<AtlasSamples>,
    pub content_key: Digest,
    /// The record's inputs (outputs, timing and status are filled in by execution).
    pub record: JobRecord,
    pub action: Action,
    /// Estimated peak memory of running it, in bytes ([`memory::job_estimate`]).
    pub memory: u64,
}

impl Entry {
    /// What executing the job reads: its method, decoded sample and companions, parameters,
    /// seed and output.
    pub fn inputs(&self) -> crate::batch::execute::JobInputs<'_> {
        let job = &self.job;
        let companions = match &self.atlas {
            Some(a) => job.companions.iter().zip(a.companions.iter()).collect(),
            None => job.companions.iter().zip(self.companions.iter().map(|c| &**c)).collect(),
        };
        crate::batch::execute::JobInputs {
            method: job.method,
            sample: &self.sample,
            params: &job.params,
            seed: job.seed,
            output: &job.output,
            companions,
            sample_mask: self.atlas.as_ref().map(|a| &a.mask).or(self.sample_mask.as_ref().map(|(_, m)| m)),
            atlas: self.atlas.as_ref().map(|a| crate::batch::execute::AtlasInputs { atlas: &a.atlas, first: &a.first }),
            fill: self.fill.as_ref().map(|(_, f)| f),
            guide: self.guide.as_ref().map(|(_, _, g)| g),
        }
    }
}

/// This worker's part of a split job set.
#[derive(Clone, Debug)]
pub struct ShardPlan {
    pub shard: Shard,
    /// Jobs (valid and invalid) in the whole set, over all shards.
    pub plan_jobs: usize,
    /// Digest of the whole set's sorted ids.
    pub plan_digest: Digest,
}

/// Every job of a run (or of this shard's part of it), sorted by id.
pub struct Plan {
    pub out: PathBuf,
    pub shard: Option<ShardPlan>,
    pub entries: Vec<Entry>,
    pub invalid: Vec<InvalidJob>,
    /// The manifest found in the output directory, by job id (empty when there was none).
    pub previous: BTreeMap<String, JobRecord>,
    /// The job roots the new manifest records: this run's and those of the records it keeps.
    pub job_roots: Vec<String>,
}

impl Plan {
    /// The jobs that will run, in id order.
    pub fn to_run(&self) -> impl Iterator<Item = &Entry> {
        self.entries.iter().filter(|e| matches!(e.action, Action::Run(_)))
    }

    pub fn up_to_date(&self) -> usize {
        self.entries.iter().filter(|e| e.action == Action::UpToDate).count()
    }

    /// One line per job, sorted by id, for `--dry-run`: `will run: <reason>`, `up to date` or `invalid`.
    pub fn lines(&self) -> Vec<(String, String)> {
        let mut lines: Vec<(String, String)> = self
            .entries
            .iter()
            .map(|e| {
                let what = match &e.action {
                    Action::Run(r) => format!("will run: {r}; needs about {}", memory::human(e.memory)),
                    Action::UpToDate => format!("up to date (would need about {})", memory::human(e.memory)),
                };
                (e.job.id.clone(), what)
            })
            .chain(self.invalid.iter().map(|i| (i.id.clone(), "invalid".to_string())))
            .collect();
        lines.sort();
        lines
    }
}

/// Plans a run of job files and directories into `opts.out`. `Err` means nothing can run at all
/// (no job files, unreadable paths); problems of single jobs are in [`Plan::invalid`].
pub fn plan(inputs: &[PathBuf], opts: &PlanOptions) -> Result<Plan, Error> {
    let files = job::discover(inputs)?;
    if files.is_empty() {
        return Err(Error::NoJobFiles { inputs: inputs.to_vec() });
    }
    let mut set = job::read_all(&files);
    let shard = opts.shard.map(|s| keep_shard(&mut set, s));
    let mut invalid = set.invalid;
    let Previous { records: previous, same_tool, job_roots: previous_roots } = previous_records(&opts.out);
    let roots = job_roots(inputs);
    let foreign: Vec<&String> = roots.iter().filter(|r| !previous_roots.contains(*r)).collect();
    if !previous_roots.is_empty() && !foreign.is_empty() && !opts.allow_other_root {
        let list = |v: Vec<&String>| v.iter().map(|s| s.as_str()).collect::<Vec<_>>().join(", ");
        return Err(Error::Usage(format!(
            "{} records the jobs of {}, but this run's jobs come from {}: job ids are paths relative to their root, so a job of one \
             would silently replace the other's record of the same id. Use another output directory, or --allow-other-root to keep \
             both roots' records there (this run's replace only those with the same ids)",
            opts.out.display(),
            list(previous_roots.iter().collect()),
            list(foreign)
        )));
    }
    let job_roots: Vec<String> = previous_roots.into_iter().chain(roots).collect::<BTreeSet<_>>().into_iter().collect();

    // Decode every distinct sample once.
    let mut sample_paths: Vec<PathBuf> = set
        .jobs
        .iter()
        .flat_map(|j| {
            j.sample_paths()
                .into_iter()
                .chain(j.companions.iter().flat_map(|c| std::iter::once(c.sample.clone()).chain(c.more_samples.iter().cloned())))
                .chain(j.sample_mask_paths().into_iter().flatten())
                .chain(j.inpaint_mask_file())
                .chain(j.guide_files())
        })
        .collect();
    sample_paths.sort();
    sample_paths.dedup();
    let loaded: BTreeMap<PathBuf, Result<Arc<LoadedSample>, Error>> =
        sample_paths.par_iter().map(|p| (p.clone(), load_sample(p).map(Arc::new))).collect::<Vec<_>>().into_iter().collect();

    let mut entries = Vec::new();
    for mut job in set.jobs {
        let sample = match &loaded[&job.sample] {
            Ok(s) => s.clone(),
            Err(e) => {
                let errors = vec![job.error(Some("sample"), format!("sample {e}"))];
                invalid.push(InvalidJob { id: job.id.clone(), file: job.file.clone(), errors });
                continue;
            }
        };
        // An inpainting job with other samples or copies: its hole is known before the atlas is
        // made, since no piece may copy from it (neither the image nor its turned copies).
        let early_fill = if job.inpaint.is_some() && job.uses_atlas() {
            match fill_of(&job, &sample, &loaded, None, None) {
                Ok(f) => f,
                Err(errors) => {
                    invalid.push(InvalidJob { id: job.id.clone(), file: job.file.clone(), errors });
                    continue;
                }
            }
        } else {
            None
        };
        let image_copyable = early_fill
            .as_ref()
            .zip(job.inpaint.as_ref())
            .map(|((_, region), i)| crate::batch::samples::image_copyable(region, i.copy_from_image));
        let atlas = match atlas_of(&job, &sample, &loaded, image_copyable.as_ref()) {
            Ok(a) => a,
            Err(errors) => {
                invalid.push(InvalidJob { id: job.id.clone(), file: job.file.clone(), errors });
                continue;
            }
        };
        // The method searches the atlas when there is one: its parameters and checks see its size.
        let first = sample;
        let sample = atlas.as_ref().map_or_else(|| first.clone(), |a| a.search.clone());
        job.method.resolve_for_sample(&mut job.params, sample.image.dimensions());
        if let Some(Err((key, message))) = atlas.as_ref().map(|a| a.check_block(job.params.int("block").ok())) {
            invalid.push(InvalidJob { id: job.id.clone(), file: job.file.clone(), errors: vec![job.error(Some(key), message)] });
            continue;
        }
        if job.inpaint.is_some() && (job.output.width, job.output.height) != first.image.dimensions() {
            let (w, h) = first.image.dimensions();
            let errors = vec![job.error(
                Some("output.width"),
                format!(
                    "an inpainting job's output has its image's size: `{}` is {w}x{h} but the output asks for {}x{}; leave output.width and \
                     output.height out",
                    job.sample.display(),
                    job.output.width,
                    job.output.height
                ),
            )];
            invalid.push(InvalidJob { id: job.id.clone(), file: job.file.clone(), errors });
            continue;
        }
        let issues = job.method.check(&job.params, sample.image.dimensions(), (job.output.width, job.output.height));
        if !issues.is_empty() {
            let errors: Vec<JobError> = issues.into_iter().map(|e| job.error(Some(&format!("params.{}", e.key)), e.message)).collect();
            invalid.push(InvalidJob { id: job.id.clone(), file: job.file.clone(), errors });
            continue;
        }
        let companions = match materials(&mut job, &first, sample.image.dimensions(), &loaded) {
            Ok(c) => c,
            Err(errors) => {
                invalid.push(InvalidJob { id: job.id.clone(), file: job.file.clone(), errors });
                continue;
            }
        };
        // With several samples, each companion's maps of the other samples (materials checked
        // they decoded): packed with the first into the atlas, and recorded.
        let more_maps: Vec<Vec<Arc<LoadedSample>>> =
            job.companions.iter().map(|c| c.more_samples.iter().filter_map(|p| loaded[p].as_ref().ok().cloned()).collect()).collect();
        let mut atlas = atlas;
        if let Some(a) = &mut atlas {
            a.companions = job
                .companions
                .iter()
                .zip(&companions)
                .zip(&more_maps)
                .map(|((c, l), more)| {
                    let maps: Vec<&LoadedSample> = std::iter::once(&**l).chain(more.iter().map(|m| &**m)).collect();
                    pack_map(&a.atlas, &maps, c.kind)
                })
                .collect();
        }
        let sample_mask = match if atlas.is_some() { Ok(None) } else { sample_mask_of(&job, &sample, &loaded) } {
            Ok(m) => m,
            Err(errors) => {
                invalid.push(InvalidJob { id: job.id.clone(), file: job.file.clone(), errors });
                continue;
            }
        };
        let fill = match early_fill.map_or_else(
            || fill_of(&job, &sample, &loaded, sample_mask.as_ref().map(|(_, m)| m), job.params.int("block").ok()),
            |f| Ok(Some(f)),
        ) {
            Ok(f) => f,
            Err(errors) => {
                invalid.push(InvalidJob { id: job.id.clone(), file: job.file.clone(), errors });
                continue;
            }
        };
        let guide = match guide_of(&job, &sample, atlas.as_ref().map(|a| &a.atlas), &loaded) {
            Ok(g) => g,
            Err(errors) => {
                invalid.push(InvalidJob { id: job.id.clone(), file: job.file.clone(), errors });
                continue;
            }
        };
        let needs_placement = crate::batch::execute::needs_placement(&sample, job.companions.len(), &job.output);
        let materials =
            needs_placement.then_some(memory::Materials { companions: job.companions.len(), source_map: job.output.source_map.is_some() });
        let estimate =
            memory::job_estimate_with(job.method, &job.params, sample.image.dimensions(), &job.output, !job.metrics.is_empty(), materials);
        let masks = Masks {
            more_companions: &more_maps,
            samples: atlas.as_ref().map(|_| samples_of(&job, &loaded)),
            augment: &job.augment,
            sample_mask: sample_mask.as_ref().map(|(l, _)| &**l),
            inpaint: job.inpaint.as_ref().map(|i| inpaint_source(&i.mask, fill.as_ref().and_then(|(l, _)| l.as_deref()))),
            guide: job.guide.as_ref().zip(guide.as_ref()).map(|(spec, (t, s, _))| GuideImages {
                target: (spec.target.as_path(), &**t),
                source: spec.source.as_deref().zip(s.as_deref()),
                weight: spec.weight,
                passes: spec.passes,
            }),
        };
        let (content_key, record) = base_record(&job, &first, &companions, &masks, &opts.out);
        let action = decide(&job, &content_key, previous.get(&job.id), opts);
        // A job that would run but cannot fit under the limit is refused (one up to date needs nothing).
        if let Some(limit) = opts.max_memory.filter(|&l| estimate > l && action != Action::UpToDate) {
            let errors = vec![job.error(Some("output"), memory::too_large(estimate, limit))];
            invalid.push(InvalidJob { id: job.id.clone(), file: job.file.clone(), errors });
            continue;
        }
        entries.push(Entry { job, sample, companions, sample_mask, fill, guide, atlas, content_key, record, action, memory: estimate });
    }
    add_warnings(&mut entries, &previous, &same_tool, opts.max_memory);
    invalid.sort_by(|a, b| a.id.cmp(&b.id));
    Ok(Plan { out: opts.out.clone(), shard, entries, invalid, previous, job_roots })
}

/// The absolute directories the job ids of `inputs` are relative to: a directory argument itself,
/// a job file's own directory.
fn job_roots(inputs: &[PathBuf]) -> BTreeSet<String> {
    inputs
        .iter()
        .map(|arg| {
            let dir =
                if arg.is_dir() { arg.as_path() } else { arg.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new(".")) };
            let abs = dir.canonicalize().or_else(|_| std::path::absolute(dir)).unwrap_or_else(|_| dir.to_path_buf());
            abs.to_string_lossy().into_owned()
        })
        .collect()
}

/// The job's sample mask, decoded and checked: the sample's size, something allowed, and room
/// for a whole block of the method's `block` parameter (when it has one).
fn sample_mask_of(
    job: &Job,
    sample: &LoadedSample,
    loaded: &BTreeMap<PathBuf, Result<Arc<LoadedSample>, Error>>,
) -> Result<Option<(Arc<LoadedSample>, SampleMask)>, Vec<JobError>> {
    let Some(path) = &job.sample_mask else { return Ok(None) };
    let l = match &loaded[path] {
        Ok(l) => l.clone(),
        Err(e) => return Err(vec![job.error(Some("sample_mask"), format!("sample mask {e}"))]),
    };
    let (w, h) = l.image.dimensions();
    let size = sample.image.dimensions();
    if (w, h) != size {
        return Err(vec![job.error(
            Some("sample_mask"),
            format!(
                "sample mask `{}` is {w}x{h} but the sample `{}` is {}x{}; the mask must have the sample's size",
                path.display(),
                job.sample.display(),
                size.0,
                size.1
            ),
        )]);
    }
    let mask = SampleMask::from_image(&l.image);
    if mask.allowed_pixels() == 0 {
        return Err(vec![job.error(
            Some("sample_mask"),
            format!("sample mask `{}` is black everywhere: it leaves nothing to copy (white = may be copied)", path.display()),
        )]);
    }
    if let Ok(block) = job.params.int("block") {
        let largest = mask.largest_block();
        if i64::from(largest) < block {
            return Err(vec![job.error(
                Some("sample_mask"),
                format!(
                    "sample mask `{}` leaves no whole {block}x{block} block (params.block) to copy; the largest block it allows is {largest}: use block = {largest} or less, or allow more of the sample",
                    path.display()
                ),
            )]);
        }
    }
    Ok(Some((l, mask)))
}

/// Every sample of the job with its mask, decoded (the plan has decoded them all by now).
fn samples_of(
    job: &Job,
    loaded: &BTreeMap<PathBuf, Result<Arc<LoadedSample>, Error>>,
) -> Vec<(PathBuf, Arc<LoadedSample>, Option<(PathBuf, Arc<LoadedSample>)>)> {
    job.sample_paths()
        .into_iter()
        .zip(job.sample_mask_paths())
        .filter_map(|(p, m)| {
            let s = loaded[&p].as_ref().ok()?.clone();
            let mask = match m {
                Some(mp) => Some((mp.clone(), loaded[&mp].as_ref().ok()?.clone())),
                None => None,
            };
            Some((p, s, mask))
        })
        .collect()
}

/// The atlas a job with several samples or `augment` searches, checked; `None` for a job with
/// one sample as it is.
fn atlas_of(
    job: &Job,
    first: &Arc<LoadedSample>,
    loaded: &BTreeMap<PathBuf, Result<Arc<LoadedSample>, Error>>,
    image_copyable: Option<&SampleMask>,
) -> Result<Option<AtlasSamples>, Vec<JobError>> {
    if !job.uses_atlas() {
        return Ok(None);
    }
    let mut errors = Vec::new();
    for p in job.sample_paths().iter().skip(1) {
        if let Err(e) = &loaded[p] {
            errors.push(job.error(Some("samples"), format!("sample {e}")));
        }
    }
    for p in job.sample_mask_paths().iter().flatten() {
        if let Err(e) = &loaded[p] {
            errors.push(job.error(Some("sample_mask"), format!("sample mask {e}")));
        }
    }
    if !errors.is_empty() {
        return Err(errors);
    }
    let all = samples_of(job, loaded);
    let samples: Vec<(&Path, Arc<LoadedSample>)> =
        all.iter().enumerate().map(|(i, (p, s, _))| (p.as_path(), if i == 0 { first.clone() } else { s.clone() })).collect();
    let masks: Vec<Option<(&Path, &LoadedSample)>> = all.iter().map(|(_, _, m)| m.as_ref().map(|(p, l)| (p.as_path(), &**l))).collect();
    assemble(&samples, &masks, &job.augment, image_copyable).map(Some).map_err(|(key, message)| vec![job.error(Some(key), message)])
}

/// The job's fill region when it inpaints, from its mask image or one of its image's channels,
/// checked ([`crate::batch::inpaint::fill_region`]).
fn fill_of(
    job: &Job,
    sample: &LoadedSample,
    loaded: &BTreeMap<PathBuf, Result<Arc<LoadedSample>, Error>>,
    sample_mask: Option<&SampleMask>,
    block: Option<i64>,
) -> Result<Option<(Option<Arc<LoadedSample>>, FillRegion)>, Vec<JobError>> {
    let Some(inpaint) = &job.inpaint else { return Ok(None) };
    let mask_file = match &inpaint.mask {
        InpaintMask::File(p) => match &loaded[p] {
            Ok(l) => Some(l.clone()),
            Err(e) => return Err(vec![job.error(Some("inpaint.mask"), format!("inpaint mask {e}"))]),
        },
        InpaintMask::Channel(_) => None,
    };
    let source = inpaint_source(&inpaint.mask, mask_file.as_deref());
    match fill_region(sample, &job.sample, &source, block, sample_mask) {
        Ok(region) => Ok(Some((mask_file, region))),
        Err(message) => Err(vec![job.error(Some(source.key()), message)]),
    }
}

/// The job's guide when it is guided: its images decoded and checked ([`GuideImages::guide`]).
fn guide_of(
    job: &Job,
    sample: &LoadedSample,
    atlas: Option<&Atlas>,
    loaded: &BTreeMap<PathBuf, Result<Arc<LoadedSample>, Error>>,
) -> Result<Option<(Arc<LoadedSample>, Option<Arc<LoadedSample>>, Guide)>, Vec<JobError>> {
    let Some(spec) = &job.guide else { return Ok(None) };
    let target = match &loaded[&spec.target] {
        Ok(l) => l.clone(),
        Err(e) => return Err(vec![job.error(Some("guide.target"), format!("target guide {e}"))]),
    };
    let source = match &spec.source {
        Some(p) => match &loaded[p] {
            Ok(l) => Some(l.clone()),
            Err(e) => return Err(vec![job.error(Some("guide.source"), format!("source guide {e}"))]),
        },
        None => None,
    };
    // With transformed copies, the source guide is packed like the sample.
    let packed = atlas.zip(source.as_deref()).map(|(a, s)| pack_map(a, &[s], MapKind::Color));
    let images = GuideImages {
        target: (&spec.target, &target),
        source: spec.source.as_deref().zip(packed.as_ref().or(source.as_deref())),
        weight: spec.weight,
        passes: spec.passes,
    };
    match images.guide(sample, &job.sample, (job.output.width, job.output.height)) {
        Ok(g) => Ok(Some((target.clone(), source.clone(), g))),
        Err((key, message)) => Err(vec![job.error(Some(key), message)]),
    }
}

/// An inpaint mask as [`crate::batch::inpaint`] takes it (`loaded`: the mask file's image).
fn inpaint_source<'a>(mask: &'a InpaintMask, loaded: Option<&'a LoadedSample>) -> MaskSource<'a> {
    match (mask, loaded) {
        (InpaintMask::File(path), Some(loaded)) => MaskSource::File { path, loaded },
        (InpaintMask::Channel(c), _) => MaskSource::Channel(*c),
        (InpaintMask::File(_), None) => unreachable!("a mask file is decoded before its job is recorded"),
    }
}

/// The masks a job's record and content key hold besides its sample.
struct Masks<'a> {
    /// Several samples or `augment`: every sample and its mask, decoded (the atlas is made of them).
    samples: Option<Vec<(PathBuf, Arc<LoadedSample>, Option<(PathBuf, Arc<LoadedSample>)>)>>,
    augment: &'a [Augment],
    sample_mask: Option<&'a LoadedSample>,
    inpaint: Option<MaskSource<'a>>,
    guide: Option<GuideImages<'a>>,
    /// With several samples: each companion's maps of the other samples, decoded.
    more_companions: &'a [Vec<Arc<LoadedSample>>],
}

/// Checks what a job renders besides its method's 8-bit image and decides what the job file left
/// open: each companion decoded and of the sample's size, `tileable` honoured by the method, the
/// bit depth of PNGs without one (the sample's precision). Returns the companions' samples.
fn materials(
    job: &mut Job,
    sample: &Arc<LoadedSample>,
    searched: (u32, u32),
    loaded: &BTreeMap<PathBuf, Result<Arc<LoadedSample>, Error>>,
) -> Result<Vec<Arc<LoadedSample>>, Vec<JobError>> {
    let mut errors = Vec::new();
    let mut companions = Vec::new();
    let size = sample.image.dimensions();
    for (k, c) in job.companions.iter().enumerate() {
        let key = format!("companion[{}].sample", k + 1);
        match &loaded[&c.sample] {
            Err(e) => errors.push(job.error(Some(&key), format!("companion sample {e}"))),
            Ok(l) if l.image.dimensions() != size => errors.push(job.error(
                Some(&key),
                format!(
                    "companion `{}` is {}x{} but the sample `{}` is {}x{}; a companion must have the sample's size, pixel for pixel",
                    c.sample.display(),
                    l.image.width(),
                    l.image.height(),
                    job.sample.display(),
                    size.0,
                    size.1
                ),
            )),
            Ok(l) => companions.push(l.clone()),
        }
        // The other samples' maps, each of its own sample's size.
        for (i, (map, s)) in c.more_samples.iter().zip(&job.more_samples).enumerate() {
            let Ok(other) = &loaded[&s.path] else { continue };
            match &loaded[map] {
                Err(e) => errors.push(job.error(Some(&key), format!("companion sample {e}"))),
                Ok(l) if l.image.dimensions() != other.image.dimensions() => errors.push(job.error(
                    Some(&key),
                    format!(
                        "companion `{}` (entry {}) is {}x{} but its sample `{}` is {}x{}; each map must have its sample's size",
                        map.display(),
                        i + 2,
                        l.image.width(),
                        l.image.height(),
                        s.path.display(),
                        other.image.width(),
                        other.image.height()
                    ),
                )),
                Ok(_) => {}
            }
        }
    }
    if job.output.tileable
        && let Err(why) = job.method.tileable(&job.params, searched, (job.output.width, job.output.height))
    {
        let can: Vec<&str> = crate::synth::methods::registry()
            .iter()
            .filter(|m| {
                let defaults = crate::synth::params::resolve(m.params(), &[]);
                defaults.is_ok_and(|p| m.tileable(&p, searched, (job.output.width, job.output.height)).is_ok())
            })
            .map(|m| m.name())
            .collect();
        let others = if can.is_empty() {
            "no method can wrap this size with its defaults".to_string()
        } else {
            format!("methods that can wrap a {}x{} output: {}", job.output.width, job.output.height, can.join(", "))
        };
        errors.push(job.error(Some("output.tileable"), format!("{why}; {others}")));
    }
    if !errors.is_empty() {
        return Err(errors);
    }
    if job.output.native_depth && job.output.format == crate::image::io::Format::Png {
        job.output.bit_depth = sample.native_png_depth();
    }
    for (c, l) in job.companions.iter_mut().zip(&companions) {
        if c.native_depth && c.format == crate::image::io::Format::Png {
            c.bit_depth = l.native_png_depth();
        }
    }
    Ok(companions)
}

/// Keeps the jobs [`shard::assign`] gives to `s`, from the whole set's ids and costs.
fn keep_shard(set: &mut JobSet, s: Shard) -> ShardPlan {
    let mut all: Vec<(&str, u64)> = set
        .jobs
        .iter()
        .map(|j| (j.id.as_str(), u64::from(j.output.width) * u64::from(j.output.height) * shard::method_cost(j.method.name())))
        .chain(set.invalid.iter().map(|i| (i.id.as_str(), 1)))
        .collect();
    all.sort();
    let ids: Vec<&str> = all.iter().map(|j| j.0).collect();
    let plan = ShardPlan { shard: s, plan_jobs: all.len(), plan_digest: Digest::of_json(&serde_json::json!(ids)) };
    let owner: BTreeMap<String, usize> = all.iter().map(|j| j.0.to_string()).zip(shard::assign(&all, s.count)).collect();
    set.jobs.retain(|j| owner[&j.id] == s.index);
    set.invalid.retain(|i| owner[&i.id] == s.index);
    plan
}

/// Whether each job's method fits its sample (`texsyn advise`): the `warnings` of its record. The
/// analysis runs once per distinct sample pixels, and only for samples with a job that runs or
/// whose earlier record another build wrote: an up-to-date job recorded by this very build keeps
/// its recorded warnings (the advice is a function of the sample, the job and the build), so a
/// re-run with nothing to do does not analyse every sample again. The analyses run side by side,
/// each taking its estimate from a budget of `max_memory`, as the jobs do later: a directory of
/// camera photos is analysed a few at a time under a limit.
fn add_warnings(entries: &mut [Entry], previous: &BTreeMap<String, JobRecord>, same_tool: &BTreeSet<String>, max_memory: Option<u64>) {
    let reuse = |e: &Entry| e.action == Action::UpToDate && same_tool.contains(&e.job.id);
    // What shows the texture: the (first) sample; for an inpainting job, the largest rectangle of
    // its image outside the hole (analysed whole, the hole's paint read as a flat area and as
    // large features, and the advice asked for blocks that no longer fit beside the hole), none
    // when that is smaller than `MIN_ADVISED` a side.
    const MIN_ADVISED: u32 = 32;
    let analysed = |e: &Entry| -> Option<(String, Arc<LoadedSample>, Option<(u32, u32, u32, u32)>)> {
        let s = e.atlas.as_ref().map_or(&e.sample, |a| &a.first).clone();
        match &e.fill {
            None => Some((s.pixel_digest.sha256.clone(), s, None)),
            Some((_, region)) => {
                let (x, y, w, h) = region.largest_known_rect().filter(|r| r.2 >= MIN_ADVISED && r.3 >= MIN_ADVISED)?;
                Some((format!("{}/{x},{y},{w}x{h}", s.pixel_digest.sha256), s, Some((x, y, w, h))))
            }
        }
    };
    // Once per entry (the hole's rectangle is a pass over the mask): what it is analysed as.
    let per_entry: Vec<Option<(String, Arc<LoadedSample>, Option<(u32, u32, u32, u32)>)>> =
        entries.iter().map(|e| if reuse(e) { None } else { analysed(e) }).collect();
    let mut wanted: Vec<(String, Arc<LoadedSample>, Option<(u32, u32, u32, u32)>)> = per_entry.iter().flatten().cloned().collect();
    wanted.sort_by(|a, b| a.0.cmp(&b.0));
    wanted.dedup_by(|a, b| a.0 == b.0);
    let budget = memory::Budget::new(max_memory);
    let analyses: BTreeMap<String, Analysis> = wanted
        .par_iter()
        .map(|(key, s, rect)| {
            let _memory = budget.acquire(memory::analysis_estimate(rect.map_or(s.image.dimensions(), |r| (r.2, r.3))));
            let analysis = match rect {
                Some((x, y, w, h)) => advice::analyse(&s.image.crop(*x, *y, *w, *h)),
                None => advice::analyse(&s.image),
            };
            (key.to_string(), analysis)
        })
        .collect::<Vec<_>>()
        .into_iter()
        .collect();
    for (e, analysed_as) in entries.iter_mut().zip(&per_entry) {
        e.record.warnings = if reuse(e) {
            previous[&e.job.id].warnings.clone()
        } else {
            let a = analysed_as.as_ref().map(|(key, _, _)| &analyses[key]);
            let wrap = a
                .and_then(|a| a.lattice.as_ref())
                .filter(|_| e.job.output.tileable)
                .and_then(|l| wrap::warning(l, (e.job.output.width, e.job.output.height)));
            let nothing_to_fill = e
                .fill
                .as_ref()
                .filter(|(_, f)| f.count() == 0)
                .map(|_| "the inpaint mask marks no pixel to fill (white = fill): the output is the image, unchanged".to_string());
            a.into_iter().flat_map(|a| advice::warning(a, e.job.method.name(), &e.job.params)).chain(wrap).chain(nothing_to_fill).collect()
        };
    }
}

/// What the output directory already records.
pub struct Previous {
    /// Its manifest's and shard fragments' records by job id (for an id recorded twice, the more
    /// recently finished record).
    pub records: BTreeMap<String, JobRecord>,
    /// The ids of the records this build of texsyn wrote (same version and commit).
    pub same_tool: BTreeSet<String>,
    /// The job roots those manifests record (none for manifests of texsyn before 0.1 roots).
    pub job_roots: BTreeSet<String>,
}

/// What the output directory already records: its manifest and any shard fragments. Unreadable
/// files count as absent: the jobs they described simply run again.
pub fn previous_records(out: &Path) -> Previous {
    let mut files = vec![out.join(manifest::FILE_NAME)];
    if let Ok(entries) = std::fs::read_dir(out) {
        let mut fragments: Vec<PathBuf> = entries.flatten().map(|e| e.path()).filter(|p| is_fragment(p)).collect();
        fragments.sort();
        files.extend(fragments);
    }
    let current = manifest::Tool::current();
    let mut records: BTreeMap<String, (JobRecord, bool)> = BTreeMap::new();
    let mut job_roots = BTreeSet::new();
    for f in files {
        let Ok(m) = Manifest::load(&f) else { continue };
        if !m.jobs.is_empty() {
            job_roots.extend(m.run.job_roots.iter().cloned());
        }
        let same = m.tool == current;
        for j in m.jobs {
            let finished = |r: &JobRecord| r.timing.as_ref().map_or(0, |t| t.finished_at);
            match records.get(&j.id) {
                Some((old, _)) if finished(old) >= finished(&j) => {}
                _ => {
                    records.insert(j.id.clone(), (j, same));
                }
            }
        }
    }
    let same_tool = records.iter().filter(|(_, (_, same))| *same).map(|(id, _)| id.clone()).collect();
    Previous { records: records.into_iter().map(|(id, (r, _))| (id, r)).collect(), same_tool, job_roots }
}

/// Whether `path` is named like a shard's manifest fragment (`manifest.shard-I-of-N.json`).
pub fn is_fragment(path: &Path) -> bool {
    let Some(name) = path.file_name().and_then(|n| n.to_str()) else { return false };
    let Some(mid) = name.strip_prefix("manifest.shard-").and_then(|r| r.strip_suffix(".json")) else { return false };
    let Some((i, n)) = mid.split_once("-of-") else { return false };
    i.parse::<usize>().is_ok() && n.parse::<usize>().is_ok()
}

/// The record of a job's inputs, and its content key.
fn base_record(
    job: &Job,
    sample: &LoadedSample,
    companions: &[Arc<LoadedSample>],
    masks: &Masks,
    manifest_dir: &Path,
) -> (Digest, JobRecord) {
    let sample_mask = masks.sample_mask;
    let params_json = job.params.to_json();
    let mut output_json = job.output.to_json();
    if !job.companions.is_empty() {
        // The companions' pixels are inputs of the job's outputs: part of the content key.
        output_json["companions"] = job
            .companions
            .iter()
            .zip(companions)
            .zip(masks.more_companions)
            .map(|((c, l), more)| {
                let mut spec = serde_json::json!({
                    "path": c.path, "format": c.format.name(), "bit_depth": c.bit_depth, "kind": c.kind_name(),
                    "sample_pixels": l.pixel_digest,
                });
                if !c.more_samples.is_empty() {
                    // The other samples' maps are inputs too.
                    spec["more_sample_pixels"] = more.iter().map(|m| serde_json::json!(m.pixel_digest)).collect();
                }
                spec
            })
            .collect();
    }
    if let Some(m) = sample_mask {
        // Which sample pixels may be copied decides the output: part of the content key.
        output_json["sample_mask"] = serde_json::json!({ "pixels": m.pixel_digest });
    }
    if let Some(samples) = &masks.samples {
        // Every sample's pixels and mask, and the transforms searched, decide the output: part
        // of the content key (the first sample's pixels are in it as the sample's, as always).
        output_json["samples"] = samples
            .iter()
            .map(|(_, l, m)| {
                let mut v = serde_json::json!({ "pixels": l.pixel_digest });
                if let Some((_, m)) = m {
                    v["mask"] = serde_json::json!(m.pixel_digest);
                }
                v
            })
            .collect();
        if !masks.augment.is_empty() {
            output_json["augment"] = masks.augment.iter().map(|a| serde_json::json!(a.name())).collect();
        }
    }
    if let Some(source) = &masks.inpaint {
        // Which pixels are filled decides the output: part of the content key.
        output_json["inpaint"] = source.spec();
        if job.inpaint.as_ref().is_some_and(|i| !i.copy_from_image) {
            // Only the other samples are copied from (left out when the image is, as before).
            output_json["inpaint"]["copy_from_image"] = false.into();
        }
    }
    if let Some(g) = &masks.guide {
        // Where the output is to be dark or light, and how much that weighs: part of the content key.
        output_json["guide"] = g.spec();
    }
    let content_key = manifest::content_key(
        job.method.name(),
        job.method.algorithm_version_of(&job.params, Uses::of_spec(&output_json)),
        &params_json,
        job.seed,
        &sample.pixel_digest,
        &output_json,
    );
    let sample_record = |path: &Path, l: &LoadedSample| SampleRecord {
        path: manifest::relative_path(path, manifest_dir),
        file_digest: l.file_digest.clone(),
        pixel_digest: l.pixel_digest.clone(),
        width: l.image.width(),
        height: l.image.height(),
    };
    let record = JobRecord {
        id: job.id.clone(),
        job_file: FileRef { path: manifest::relative_path(&job.file, manifest_dir), digest: job.file_digest.clone() },
        status: Status::Ok,
        error: None,
        method: Some(job.method.name().to_string()),
        algorithm_version: Some(job.method.algorithm_version_of(&job.params, Uses::of_spec(&output_json))),
        params_digest: Some(Digest::of_json(&params_json)),
        params: Some(params_json),
        seed: Some(job.seed),
        sample: Some(sample_record(&job.sample, sample)),
        output_spec: Some(output_json),
        content_key: Some(content_key.clone()),
        outputs: Vec::new(),
        seams: None,
        diagnostics: serde_json::Value::Null,
        metrics: None,
        timing: None,
        warnings: Vec::new(),
        companions: job.companions.iter().zip(companions).map(|(c, l)| sample_record(&c.sample, l)).collect(),
        more_companions: if job.companions.iter().any(|c| !c.more_samples.is_empty()) {
            job.companions
                .iter()
                .zip(masks.more_companions)
                .map(|(c, more)| c.more_samples.iter().zip(more).map(|(p, l)| sample_record(p, l)).collect())
                .collect()
        } else {
            Vec::new()
        },
        sample_mask: job.sample_mask.as_deref().zip(sample_mask).map(|(p, l)| sample_record(p, l)),
        inpaint_mask: match &masks.inpaint {
            Some(MaskSource::File { path, loaded }) => Some(sample_record(path, loaded)),
            _ => None,
        },
        guide_target: masks.guide.as_ref().map(|g| sample_record(g.target.0, g.target.1)),
        guide_source: masks.guide.as_ref().and_then(|g| g.source).map(|(p, l)| sample_record(p, l)),
        samples: masks.samples.iter().flatten().map(|(p, l, _)| sample_record(p, l)).collect(),
        sample_masks: match &masks.samples {
            Some(all) if all.iter().any(|(_, _, m)| m.is_some()) => {
                all.iter().map(|(_, _, m)| m.as_ref().map(|(p, l)| sample_record(p, l))).collect()
            }
            _ => Vec::new(),
        },
    };
    (content_key, record)
}

/// Incremental: up to date when the content key matches, the requested metrics are recorded and
/// the outputs still hash as recorded.
fn decide(job: &Job, content_key: &Digest, previous: Option<&JobRecord>, opts: &PlanOptions) -> Action {
    if opts.force {
        return Action::Run(Reason::Forced);
    }
    let Some(prev) = previous else { return Action::Run(Reason::NotInManifest) };
    if !prev.status.is_success() {
        return Action::Run(Reason::PreviousRun(prev.status));
    }
    if prev.content_key.as_ref() != Some(content_key) {
        return Action::Run(Reason::InputsChanged);
    }
    let metrics_recorded = job.metrics.is_empty() || prev.metrics.as_ref().is_some_and(|m| job.metrics.iter().all(|w| m.contains_key(w)));
    if !metrics_recorded {
        return Action::Run(Reason::MetricsNotRecorded);
    }
    match outputs_intact(&opts.out, prev) {
        Ok(()) => Action::UpToDate,
        Err(p) => Action::Run(Reason::Outputs(p)),
    }
}

/// The manifest record of a job that cannot run.
pub fn invalid_record(inv: &InvalidJob, manifest_dir: &Path) -> JobRecord {
    let digest = crate::files::read_limited(&inv.file, crate::files::MAX_JOB_FILE_BYTES)
        .map(|b| Digest::of_bytes(&b))
        .unwrap_or_else(|_| Digest::of_bytes(b""));
    JobRecord {
        id: inv.id.clone(),
        job_file: FileRef { path: manifest::relative_path(&inv.file, manifest_dir), digest },
        status: Status::Invalid,
        error: Some(inv.errors.iter().map(|e| e.to_string()).collect::<Vec<_>>().join("\n")),
        method: None,
        algorithm_version: None,
        params: None,
        params_digest: None,
        seed: None,
        sample: None,
        output_spec: None,
        content_key: None,
        outputs: Vec::new(),
        seams: None,
        diagnostics: serde_json::Value::Null,
        metrics: None,
        timing: None,
        warnings: Vec::new(),
        companions: Vec::new(),
        more_companions: Vec::new(),
        sample_mask: None,
        inpaint_mask: None,
        guide_target: None,
        guide_source: None,
        samples: Vec::new(),
        sample_masks: Vec::new(),
    }
}
