//! Running a plan: sample loading, incremental checks, parallel deterministic execution, and a
//! manifest that is always consistent with the files on disk.
//!
//! Jobs run on a rayon pool (`--jobs`); a job's pixels depend only on its inputs, never on the
//! pool size, the order jobs are taken in, or which thread runs them. A failing or panicking job
//! is recorded and the others go on. The manifest is rewritten atomically as jobs finish (at most
//! a few times per second), so a run killed at any instant can be resumed: finished jobs are
//! recognised as up to date by their content key and the hash of their output file.

use crate::digest::Digest;
use crate::image::io::{self as imageio, DecodeLimits, Encoded};
use crate::batch::job::{self, InvalidJob, Job, JobError, OutputSpec};
use crate::batch::manifest::{self, FileRef, JobRecord, Manifest, OutputRecord, RunFacts, SampleRecord, Status, Timing};
use crate::synth::method::{ExtraContent, ExtraOutput, Method, Request, Synthesis};
use crate::batch::outdir::OutDir;
use crate::synth::params::Params;
use crate::batch::progress::Progress;
use crate::image::RgbImage;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// Options of `texsyn run`.
#[derive(Clone, Debug)]
pub struct RunOptions {
    pub out: PathBuf,
    /// Worker threads; `None` = all cores.
    pub threads: Option<usize>,
    pub dry_run: bool,
    pub force: bool,
    pub json: bool,
    pub quiet: bool,
    /// Take jobs in reverse id order (used by tests to show order independence).
    pub reverse: bool,
    /// Set from a Ctrl-C handler: no new job starts once it is set.
    pub interrupt: Option<Arc<AtomicBool>>,
}

impl RunOptions {
    pub fn new(out: impl Into<PathBuf>) -> RunOptions {
        RunOptions { out: out.into(), threads: None, dry_run: false, force: false, json: false, quiet: false, reverse: false, interrupt: None }
    }
}

/// What a run did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Summary {
    pub ran: usize,
    pub up_to_date: usize,
    pub failed: usize,
    pub invalid: usize,
    pub wall_seconds: f64,
    pub interrupted: bool,
}

impl Summary {
    pub fn all_good(&self) -> bool {
        self.failed == 0 && self.invalid == 0 && !self.interrupted
    }
}

/// A decoded sample and its digests.
pub struct LoadedSample {
    pub image: RgbImage,
    pub file_digest: Digest,
    pub pixel_digest: Digest,
}

/// Reads and decodes a sample; errors name the file and the reason.
pub fn load_sample(path: &Path) -> Result<LoadedSample, String> {
    let (image, bytes) = imageio::read_rgb8(path, DecodeLimits::default()).map_err(|e| format!("sample `{}`: {e}", path.display()))?;
    Ok(LoadedSample { pixel_digest: imageio::rgb_pixel_digest(&image), file_digest: Digest::of_bytes(&bytes), image })
}

thread_local! {
    static PANIC_LOCATION: std::cell::RefCell<Option<String>> = const { std::cell::RefCell::new(None) };
}

/// Replaces the default panic output (a backtrace per panicking job would bury the run's report)
/// with a record of where the panic happened, which the job's error message then includes.
pub fn install_panic_hook() {
    std::panic::set_hook(Box::new(|info| {
        let location = info.location().map(|l| format!("{}:{}", l.file(), l.line()));
        PANIC_LOCATION.with(|p| *p.borrow_mut() = location);
    }));
}

/// Runs the method (catching panics) and encodes the result as the job asked.
pub fn synthesize_and_encode(
    method: &dyn Method,
    sample: &RgbImage,
    params: &Params,
    seed: u64,
    output: &OutputSpec,
) -> Result<(Synthesis, Encoded, f64), String> {
    let request = Request { sample, width: output.width, height: output.height, params, seed };
    let started = Instant::now();
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| method.synthesize(&request)));
    let seconds = started.elapsed().as_secs_f64();
    let synthesis = match result {
        Ok(Ok(s)) => s,
        Ok(Err(e)) => return Err(format!("{} failed: {e}", method.name())),
        Err(panic) => {
            let what = panic
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "unknown panic".into());
            let at = PANIC_LOCATION.with(|p| p.borrow_mut().take()).map(|l| format!(" at {l}")).unwrap_or_default();
            return Err(format!("{} crashed: {what}{at} (this is a bug in texsyn; please report it)", method.name()));
        }
    };
    if synthesis.image.dimensions() != (output.width, output.height) {
        return Err(format!(
            "{} produced {}x{} instead of {}x{} (a bug in the method)",
            method.name(),
            synthesis.image.width(),
            synthesis.image.height(),
            output.width,
            output.height
        ));
    }
    let encoded = imageio::encode(&synthesis.image, output.encoding())?;
    Ok((synthesis, encoded, seconds))
}

fn now_unix() -> u64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map(|d| d.as_secs()).unwrap_or(0)
}

/// A job ready to run, with everything the manifest needs.
struct Prepared<'a> {
    job: &'a Job,
    sample: Arc<LoadedSample>,
    content_key: Digest,
    base: JobRecord,
}

fn invalid_record(inv: &InvalidJob, manifest_dir: &Path) -> JobRecord {
    let digest = std::fs::read(&inv.file).map(|b| Digest::of_bytes(&b)).unwrap_or_else(|_| Digest::of_bytes(b""));
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
    }
}

/// Runs job files and directories into `opts.out`. `Err` means the run could not start at all
/// (no job files, output directory locked or not creatable).
pub fn run(inputs: &[PathBuf], opts: &RunOptions) -> Result<Summary, String> {
    let started = Instant::now();
    let started_at = now_unix();
    let files = job::discover(inputs)?;
    if files.is_empty() {
        return Err(format!(
            "no job files (*.toml) found in {}",
            inputs.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", ")
        ));
    }
    let mut plan = job::plan(&files);
    let threads = opts.threads.unwrap_or_else(|| std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1)).max(1);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().map_err(|e| format!("cannot start threads: {e}"))?;

    let out = if opts.dry_run { None } else { Some(OutDir::open(&opts.out)?) };
    let manifest_dir = opts.out.clone();
    let manifest_path = opts.out.join(manifest::FILE_NAME);
    let previous: BTreeMap<String, JobRecord> = match Manifest::load(&manifest_path) {
        Ok(m) => m.jobs.into_iter().map(|j| (j.id.clone(), j)).collect(),
        Err(_) => BTreeMap::new(),
    };

    // Decode every distinct sample once.
    let mut sample_paths: Vec<PathBuf> = plan.jobs.iter().map(|j| j.sample.clone()).collect();
    sample_paths.sort();
    sample_paths.dedup();
    let loaded: BTreeMap<PathBuf, Result<Arc<LoadedSample>, String>> = pool.install(|| {
        sample_paths.par_iter().map(|p| (p.clone(), load_sample(p).map(Arc::new))).collect::<Vec<_>>().into_iter().collect()
    });

    // Checks that need the sample: decoding, and the method's own checks.
    let mut prepared = Vec::new();
    for job in &plan.jobs {
        let sample = match &loaded[&job.sample] {
            Ok(s) => s.clone(),
            Err(e) => {
                plan.invalid.push(InvalidJob { id: job.id.clone(), file: job.file.clone(), errors: vec![job.error(Some("sample"), e.clone())] });
                continue;
            }
        };
        let issues = job.method.check(&job.params, sample.image.dimensions(), (job.output.width, job.output.height));
        if !issues.is_empty() {
            let errors: Vec<JobError> = issues.into_iter().map(|e| job.error(Some(&format!("params.{}", e.key)), e.message)).collect();
            plan.invalid.push(InvalidJob { id: job.id.clone(), file: job.file.clone(), errors });
            continue;
        }
        let params_json = job.params.to_json();
        let output_json = job.output.to_json();
        let content_key =
            manifest::content_key(job.method.name(), job.method.algorithm_version(), &params_json, job.seed, &sample.pixel_digest, &output_json);
        let base = JobRecord {
            id: job.id.clone(),
            job_file: FileRef { path: manifest::relative_path(&job.file, &manifest_dir), digest: job.file_digest.clone() },
            status: Status::Ok,
            error: None,
            method: Some(job.method.name().to_string()),
            algorithm_version: Some(job.method.algorithm_version()),
            params_digest: Some(Digest::of_json(&params_json)),
            params: Some(params_json.clone()),
            seed: Some(job.seed),
            sample: Some(SampleRecord {
                path: manifest::relative_path(&job.sample, &manifest_dir),
                file_digest: sample.file_digest.clone(),
                pixel_digest: sample.pixel_digest.clone(),
                width: sample.image.width(),
                height: sample.image.height(),
            }),
            output_spec: Some(output_json),
            content_key: Some(content_key.clone()),
            outputs: Vec::new(),
            seams: None,
            diagnostics: serde_json::Value::Null,
            metrics: None,
            timing: None,
        };
        prepared.push(Prepared { job, sample, content_key, base });
    }
    plan.invalid.sort_by(|a, b| a.id.cmp(&b.id));

    // Incremental: up to date when the content key matches and the output still hashes as recorded.
    let mut to_run = Vec::new();
    let mut records: BTreeMap<String, JobRecord> = BTreeMap::new();
    let mut reasons: Vec<(String, String)> = Vec::new();
    for p in prepared {
        let reason = if opts.force {
            Some("--force".to_string())
        } else {
            match previous.get(&p.job.id) {
                None => Some("not in the manifest".into()),
                Some(prev) if !prev.status.is_success() => Some(format!("previous run {}", prev.status.name())),
                Some(prev) if prev.content_key.as_ref() != Some(&p.content_key) => Some("inputs changed (content key differs)".into()),
                Some(prev) if !metrics_recorded(prev, &p.job.metrics) => Some("requested metrics are not recorded".into()),
                Some(prev) => match outputs_intact(&opts.out, prev) {
                    Ok(()) => None,
                    Err(why) => Some(why),
                },
            }
        };
        match reason {
            Some(r) => {
                reasons.push((p.job.id.clone(), format!("will run: {r}")));
                to_run.push(p);
            }
            None => {
                let mut rec = previous[&p.job.id].clone();
                rec.status = Status::UpToDate;
                // Provenance of this run's job file (it may have been renamed or edited harmlessly).
                rec.job_file = p.base.job_file.clone();
                reasons.push((p.job.id.clone(), "up to date".into()));
                records.insert(p.job.id.clone(), rec);
            }
        }
    }
    for inv in &plan.invalid {
        records.insert(inv.id.clone(), invalid_record(inv, &manifest_dir));
        reasons.push((inv.id.clone(), "invalid".into()));
    }
    let progress = Progress::new(to_run.len(), opts.json, opts.quiet);
    for inv in &plan.invalid {
        for e in &inv.errors {
            progress.message(&format!("error: {e}"));
        }
        progress.event(serde_json::json!({"event": "invalid", "id": inv.id, "errors": inv.errors.iter().map(|e| e.to_string()).collect::<Vec<_>>()}));
    }

    if opts.dry_run {
        reasons.sort();
        for (id, why) in &reasons {
            if opts.json {
                progress.event(serde_json::json!({"event": "plan", "id": id, "action": why}));
            } else {
                println!("{id}: {why}");
            }
        }
        return Ok(Summary {
            ran: 0,
            up_to_date: records.values().filter(|r| r.status == Status::UpToDate).count(),
            failed: 0,
            invalid: plan.invalid.len(),
            wall_seconds: started.elapsed().as_secs_f64(),
            interrupted: false,
        });
    }
    let out = out.expect("opened unless dry run");

    // Earlier records of jobs not in this run stay (they still describe files in the directory),
    // unless this run now writes their output path.
    let this_run_outputs: std::collections::BTreeSet<&str> = plan.jobs.iter().map(|j| j.output.path.as_str()).collect();
    for (id, rec) in &previous {
        let in_plan = plan.jobs.iter().any(|j| &j.id == id) || plan.invalid.iter().any(|j| &j.id == id);
        let clobbered = rec.outputs.iter().any(|o| this_run_outputs.contains(o.path.as_str()));
        if !in_plan && !clobbered {
            records.insert(id.clone(), rec.clone());
        }
    }

    let argv: Vec<String> = std::env::args().collect();
    let host = hostname();
    let facts = |summary: &Summary, in_progress: bool| RunFacts {
        started_at,
        finished_at: now_unix(),
        wall_seconds: started.elapsed().as_secs_f64(),
        host: host.clone(),
        argv: argv.clone(),
        threads,
        ran: summary.ran,
        up_to_date: summary.up_to_date,
        failed: summary.failed,
        invalid: summary.invalid,
        in_progress,
    };
    let state = Mutex::new(State {
        records,
        summary: Summary { invalid: plan.invalid.len(), ..Summary::default() },
        last_write: Instant::now() - Duration::from_secs(10),
    });
    {
        let mut s = state.lock().expect("state");
        s.summary.up_to_date = s.records.values().filter(|r| r.status == Status::UpToDate).count();
        let f = facts(&s.summary, true);
        write_manifest(&out, &s.records, f).map_err(|e| format!("cannot write the manifest: {e}"))?;
    }

    if opts.reverse {
        to_run.reverse();
    }
    let interrupted = AtomicBool::new(false);
    pool.install(|| {
        to_run.par_iter().with_max_len(1).for_each(|p| {
            if opts.interrupt.as_ref().is_some_and(|f| f.load(Ordering::SeqCst)) {
                interrupted.store(true, Ordering::SeqCst);
                return;
            }
            progress.event(serde_json::json!({"event": "start", "id": p.job.id}));
            let job_started = Instant::now();
            let mut rec = p.base.clone();
            match execute(p, &out) {
                Ok((outputs, synthesis, seconds, metrics, metrics_seconds)) => {
                    rec.outputs = outputs;
                    rec.seams = synthesis.seams.clone();
                    rec.diagnostics = synthesis.diagnostics.clone();
                    rec.metrics = metrics;
                    rec.timing = Some(Timing {
                        synthesis_seconds: seconds,
                        metrics_seconds,
                        phases: synthesis.phases.iter().cloned().collect(),
                        total_seconds: job_started.elapsed().as_secs_f64(),
                        finished_at: now_unix(),
                    });
                }
                Err(e) => {
                    rec.status = Status::Failed;
                    rec.error = Some(e.clone());
                    progress.message(&format!("error: {}: {}: {e}", p.job.file.display(), p.job.id));
                }
            }
            progress.event(serde_json::json!({
                "event": "finish", "id": rec.id, "status": rec.status.name(), "error": rec.error,
                "seconds": job_started.elapsed().as_secs_f64(),
                "outputs": rec.outputs.iter().map(|o| &o.path).collect::<Vec<_>>(),
            }));
            progress.job_done(&rec.id, rec.status == Status::Failed);
            let mut s = state.lock().expect("state");
            if rec.status == Status::Failed {
                s.summary.failed += 1;
            } else {
                s.summary.ran += 1;
            }
            s.records.insert(rec.id.clone(), rec);
            if s.last_write.elapsed() >= Duration::from_millis(250) {
                s.last_write = Instant::now();
                let f = facts(&s.summary, true);
                if let Err(e) = write_manifest(&out, &s.records, f) {
                    progress.message(&format!("warning: cannot write the manifest yet: {e}"));
                }
            }
        });
    });
    progress.finish();
    let mut s = state.into_inner().expect("state");
    s.summary.interrupted = interrupted.load(Ordering::SeqCst);
    s.summary.wall_seconds = started.elapsed().as_secs_f64();
    let f = facts(&s.summary, false);
    write_manifest(&out, &s.records, f).map_err(|e| format!("cannot write the manifest: {e}"))?;
    progress.event(serde_json::json!({
        "event": "summary", "ran": s.summary.ran, "up_to_date": s.summary.up_to_date, "failed": s.summary.failed,
        "invalid": s.summary.invalid, "interrupted": s.summary.interrupted, "wall_seconds": s.summary.wall_seconds,
        "manifest": manifest_path.display().to_string(),
    }));
    Ok(s.summary)
}

struct State {
    records: BTreeMap<String, JobRecord>,
    summary: Summary,
    last_write: Instant,
}

fn write_manifest(out: &OutDir, records: &BTreeMap<String, JobRecord>, facts: RunFacts) -> Result<(), String> {
    let m = Manifest::new(records.values().cloned().collect(), facts);
    crate::batch::outdir::write_atomic(&out.root().join(manifest::FILE_NAME), &m.to_bytes())
}

type Metrics = Option<BTreeMap<String, Option<f64>>>;

fn execute(p: &Prepared, out: &OutDir) -> Result<(Vec<OutputRecord>, Synthesis, f64, Metrics, f64), String> {
    let job = p.job;
    let (synthesis, encoded, seconds) = synthesize_and_encode(job.method, &p.sample.image, &job.params, job.seed, &job.output)?;
    let metrics_started = Instant::now();
    let metrics = if job.metrics.is_empty() {
        None
    } else {
        let names: Vec<&str> = job.metrics.iter().map(String::as_str).collect();
        Some(
            crate::metrics::evaluate(&names, &p.sample.image, &synthesis.image, synthesis.seams.as_ref())
                .map_err(|e| format!("metrics: {e}"))?,
        )
    };
    let metrics_seconds = metrics_started.elapsed().as_secs_f64();
    let mut records = vec![OutputRecord {
        path: job.output.path.clone(),
        format: job.output.format.name().to_string(),
        bit_depth: job.output.bit_depth,
        width: job.output.width,
        height: job.output.height,
        file_digest: Digest::of_bytes(&encoded.bytes),
        pixel_digest: encoded.pixels.pixel_digest(),
    }];
    // Extras first, the main output last: a job whose main output is in place is complete.
    for extra in &synthesis.extras {
        let (record, bytes) = encode_extra(&job.output.path, extra)?;
        out.write(&record.path, &bytes)?;
        records.push(record);
    }
    out.write(&job.output.path, &encoded.bytes)?;
    Ok((records, synthesis, seconds, metrics, metrics_seconds))
}

/// Where an extra output of the job whose main output is `output_path` is stored:
/// `{output_path without its extension}.{name}`.
pub fn extra_path(output_path: &str, name: &str) -> Result<String, String> {
    let bad = name.is_empty() || name.starts_with('/') || name.contains('\\') || name.split('/').any(|c| c.is_empty() || c == "." || c == "..");
    if bad {
        return Err(format!("extra output name `{name}` is not a plain relative path (a bug in the method)"));
    }
    let file_start = output_path.rfind('/').map_or(0, |i| i + 1);
    let stem_end = output_path[file_start..].rfind('.').map_or(output_path.len(), |i| file_start + i);
    Ok(format!("{}.{name}", &output_path[..stem_end]))
}

/// Encodes an extra output and describes it for the manifest. A JSON document's "pixel digest" is
/// the digest of its bytes (it has no pixels; golden files compare it all the same).
pub fn encode_extra(output_path: &str, extra: &ExtraOutput) -> Result<(OutputRecord, Vec<u8>), String> {
    let path = extra_path(output_path, &extra.name)?;
    match &extra.content {
        ExtraContent::Rgba8 { width, height, data } => {
            let encoded = imageio::encode_rgba8_png(*width, *height, data)?;
            let record = OutputRecord {
                path,
                format: "png".into(),
                bit_depth: 8,
                width: *width,
                height: *height,
                file_digest: Digest::of_bytes(&encoded.bytes),
                pixel_digest: encoded.pixels.pixel_digest(),
            };
            Ok((record, encoded.bytes))
        }
        ExtraContent::Json(value) => {
            let mut bytes = serde_json::to_vec_pretty(value).map_err(|e| format!("cannot encode `{}`: {e}", extra.name))?;
            bytes.push(b'\n');
            let digest = Digest::of_bytes(&bytes);
            let record = OutputRecord { path, format: "json".into(), bit_depth: 0, width: 0, height: 0, file_digest: digest.clone(), pixel_digest: digest };
            Ok((record, bytes))
        }
    }
}

/// Whether every metric the job now asks for is in the record.
fn metrics_recorded(rec: &JobRecord, wanted: &[String]) -> bool {
    wanted.is_empty() || rec.metrics.as_ref().is_some_and(|m| wanted.iter().all(|w| m.contains_key(w)))
}

/// Whether every recorded output of `rec` is still on disk with the recorded bytes.
pub fn outputs_intact(out_dir: &Path, rec: &JobRecord) -> Result<(), String> {
    if rec.outputs.is_empty() {
        return Err("no output recorded".into());
    }
    for o in &rec.outputs {
        let path = out_dir.join(&o.path);
        match std::fs::read(&path) {
            Err(_) => return Err(format!("output `{}` is missing", o.path)),
            Ok(bytes) if Digest::of_bytes(&bytes) != o.file_digest => return Err(format!("output `{}` was modified", o.path)),
            Ok(_) => {}
        }
    }
    Ok(())
}

fn hostname() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .or_else(|_| std::fs::read_to_string("/etc/hostname"))
        .map(|s| s.trim().to_string())
        .unwrap_or_else(|_| "unknown".into())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extras_go_next_to_the_output_and_stay_inside_it() {
        assert_eq!(extra_path("tiles/rw/bricks.png", "tiles/index.json").unwrap(), "tiles/rw/bricks.tiles/index.json");
        assert_eq!(extra_path("a.b/out", "tiles/t.png").unwrap(), "a.b/out.tiles/t.png");
        assert_eq!(extra_path("x.exr", "tiles/tile_00.png").unwrap(), "x.tiles/tile_00.png");
        for bad in ["", "/etc/passwd", "../x", "tiles/../../x", "tiles//x", "a\\b", "./x"] {
            assert!(extra_path("out.png", bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn json_extras_are_recorded_by_their_bytes() {
        let extra = ExtraOutput { name: "tiles/index.json".into(), content: ExtraContent::Json(serde_json::json!({"b": 1, "a": [1, 2]})) };
        let (rec, bytes) = encode_extra("o.png", &extra).unwrap();
        assert_eq!(rec.path, "o.tiles/index.json");
        assert_eq!((rec.format.as_str(), rec.width, rec.height), ("json", 0, 0));
        assert_eq!(rec.pixel_digest, Digest::of_bytes(&bytes));
        assert_eq!(serde_json::from_slice::<serde_json::Value>(&bytes).unwrap(), serde_json::json!({"a": [1, 2], "b": 1}));
        let img = ExtraOutput { name: "tiles/t.png".into(), content: ExtraContent::Rgba8 { width: 2, height: 1, data: vec![1, 2, 3, 255, 4, 5, 6, 0] } };
        let (rec, bytes) = encode_extra("o.png", &img).unwrap();
        let back = imageio::decode_output(&bytes, DecodeLimits::default()).unwrap();
        assert_eq!((rec.width, rec.height, back.channels), (2, 1, 4));
        assert_eq!(back.pixel_digest(), rec.pixel_digest);
    }
}
