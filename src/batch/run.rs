//! Running a plan: parallel deterministic execution and a manifest that is always consistent
//! with the files on disk.
//!
//! Jobs run on a rayon pool (`threads`), started in id order as their estimated peak memory fits
//! under `--max-memory` beside the jobs already running ([`memory::Budget`]); a job's pixels
//! depend only on its inputs, never on the pool size, the limit, the order jobs are taken in, or
//! which thread runs them. A failing or panicking job
//! is recorded and the others go on. The manifest is rewritten atomically as jobs finish (at most
//! a few times per second), so a run killed at any instant can be resumed: finished jobs are
//! recognised as up to date by their content key and the hash of their output file.

use crate::batch::execute::{Executed, JobFailure, execute};
use crate::batch::manifest::{self, JobRecord, Manifest, RunFacts, ShardFacts, Status, Timing};
use crate::batch::memory::{self, Budget};
pub use crate::batch::observer::Summary;
use crate::batch::observer::{Event, Observer};
use crate::batch::outdir::OutDir;
use crate::batch::plan::{self, Action, Entry, Plan, PlanOptions};
use crate::batch::shard::Shard;
use crate::error::Error;
use std::collections::{BTreeMap, BTreeSet};
use std::path::PathBuf;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// Options of a run.
#[derive(Clone, Debug, Default)]
pub struct RunOptions {
    pub out: PathBuf,
    /// Worker threads; `None` = all cores.
    pub threads: Option<usize>,
    /// Run every job even if it is up to date.
    pub force: bool,
    /// Take jobs in reverse id order (used by tests to show order independence).
    pub reverse: bool,
    /// Set from a signal handler: no new job starts once it is set.
    pub interrupt: Option<std::sync::Arc<AtomicBool>>,
    /// Run only this worker's part and record it in its own manifest fragment
    /// (`manifest.shard-I-of-N.json`), for `texsyn merge` to join.
    pub shard: Option<Shard>,
    /// Memory limit in bytes (`--max-memory`): jobs estimated to need more are invalid, and jobs
    /// whose estimates together exceed it never run at once. `None`: no limit.
    pub max_memory: Option<u64>,
    /// Run even when the output directory records jobs of another job root.
    pub allow_other_root: bool,
}

impl RunOptions {
    pub fn new(out: impl Into<PathBuf>) -> RunOptions {
        RunOptions { out: out.into(), ..RunOptions::default() }
    }

    fn plan_options(&self) -> PlanOptions {
        PlanOptions {
            out: self.out.clone(),
            force: self.force,
            shard: self.shard,
            max_memory: self.max_memory,
            allow_other_root: self.allow_other_root,
        }
    }
}

/// A rayon pool of `threads` workers (all cores when `None`).
pub fn pool(threads: Option<usize>) -> Result<rayon::ThreadPool, Error> {
    let threads = threads.unwrap_or_else(|| std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1)).max(1);
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().map_err(|e| Error::Usage(format!("cannot start {threads} threads: {e}")))
}

/// Plans without taking the output directory's lock or writing anything (`--dry-run`).
pub fn plan_only(inputs: &[PathBuf], opts: &RunOptions) -> Result<Plan, Error> {
    pool(opts.threads)?.install(|| plan::plan(inputs, &opts.plan_options()))
}

/// Runs job files and directories into `opts.out`: takes the directory's lock, plans, executes.
/// `Err` means the run could not start at all (no job files, directory locked or not creatable).
pub fn run(inputs: &[PathBuf], opts: &RunOptions, observer: &dyn Observer) -> Result<Summary, Error> {
    let started = Instant::now();
    let part = opts.shard.map(|s| format!("shard-{}-of-{}", s.index, s.count));
    let out = OutDir::open_part(&opts.out, part.as_deref())?;
    let pool = pool(opts.threads)?;
    let plan = pool.install(|| plan::plan(inputs, &opts.plan_options()))?;
    // The plan's analyses of the samples left their large buffers, freed, in the arenas of the
    // threads that ran them, where the jobs that follow on other threads cannot reuse them.
    memory::release_freed();
    pool.install(|| execute_plan(plan, &out, opts, observer, started))
}

pub fn now_unix() -> u64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map(|d| d.as_secs()).unwrap_or(0)
}

/// Which job of this run writes a file: by name, or because it lies in a job's extras folder.
struct Writes<'a> {
    files: BTreeMap<&'a str, &'a str>,
    folders: BTreeMap<String, &'a str>,
}

impl<'a> Writes<'a> {
    fn of(entries: &'a [Entry]) -> Writes<'a> {
        let mut w = Writes { files: BTreeMap::new(), folders: BTreeMap::new() };
        for e in entries {
            w.files.extend(e.job.written_paths().into_iter().map(|p| (p, e.job.id.as_str())));
            w.folders.extend(e.job.claims().folders.into_iter().map(|f| (f, e.job.id.as_str())));
        }
        w
    }

    /// The id of the job of this run that writes `path`, if any.
    fn by(&self, path: &str) -> Option<&'a str> {
        if let Some(id) = self.files.get(path) {
            return Some(id);
        }
        // Each folder above the path, longest first.
        let mut end = path.len();
        while let Some(i) = path[..end].rfind('/') {
            if let Some(id) = self.folders.get(&path[..i]) {
                return Some(id);
            }
            end = i;
        }
        None
    }
}

struct State {
    rerunning: BTreeSet<String>,
    records: BTreeMap<String, JobRecord>,
    summary: Summary,
    last_write: Instant,
}

/// Executes a plan on the current rayon pool, recording every job in the manifest.
fn execute_plan(plan: Plan, out: &OutDir, opts: &RunOptions, observer: &dyn Observer, started: Instant) -> Result<Summary, Error> {
    let started_at = now_unix();
    let manifest_name = plan.shard.as_ref().map_or_else(|| manifest::FILE_NAME.to_string(), |s| s.shard.fragment_name());
    let manifest_path = out.root().join(&manifest_name);
    for inv in &plan.invalid {
        observer.event(&Event::Invalid { id: &inv.id, errors: &inv.errors });
    }

    let mut records: BTreeMap<String, JobRecord> = BTreeMap::new();
    for e in plan.entries.iter().filter(|e| e.action == Action::UpToDate) {
        let mut rec = plan.previous[&e.job.id].clone();
        rec.status = Status::UpToDate;
        // Provenance of this run's job file (it may have been renamed or edited harmlessly).
        rec.job_file = e.record.job_file.clone();
        rec.warnings = e.record.warnings.clone();
        records.insert(e.job.id.clone(), rec);
    }
    for inv in &plan.invalid {
        records.insert(inv.id.clone(), plan::invalid_record(inv, &plan.out));
    }
    // Earlier records of jobs not in this run stay (they still describe files in the directory),
    // unless this run now writes one of their files. A shard's fragment holds its own jobs only.
    // The earlier record of a job this run re-does stays too until the job finishes: its files
    // are still the earlier ones, and a run killed before it gets there must not lose the record
    // (listed in `run.rerunning` meanwhile).
    let writes = Writes::of(&plan.entries);
    let planned: BTreeSet<&str> =
        plan.entries.iter().map(|e| e.job.id.as_str()).chain(plan.invalid.iter().map(|j| j.id.as_str())).collect();
    let carried = if plan.shard.is_some() { None } else { Some(&plan.previous) };
    for (id, rec) in carried.into_iter().flatten() {
        if !planned.contains(id.as_str()) && !rec.outputs.iter().any(|o| writes.by(&o.path).is_some()) {
            records.insert(id.clone(), rec.clone());
        }
    }
    let mut rerunning = BTreeSet::new();
    for e in plan.to_run() {
        let id = e.job.id.as_str();
        if let Some(rec) = plan.previous.get(id)
            && !rec.outputs.iter().any(|o| writes.by(&o.path).is_some_and(|who| who != id))
        {
            records.insert(id.to_string(), rec.clone());
            rerunning.insert(id.to_string());
        }
    }

    let argv: Vec<String> = std::env::args().collect();
    let host = hostname();
    let shard_facts = plan.shard.as_ref().map(|s| ShardFacts {
        index: s.shard.index,
        count: s.shard.count,
        plan_jobs: s.plan_jobs,
        plan_digest: s.plan_digest.clone(),
        assigned: plan.entries.len() + plan.invalid.len(),
        host: host.clone(),
        scheduler: ["SLURM_ARRAY_JOB_ID", "SLURM_ARRAY_TASK_ID", "SLURM_JOB_ID", "JOB_COMPLETION_INDEX"]
            .iter()
            .filter_map(|k| std::env::var(k).ok().map(|v| (k.to_string(), v)))
            .collect(),
    });
    let threads = rayon::current_num_threads();
    let facts = |summary: &Summary, in_progress: bool, rerunning: &BTreeSet<String>| RunFacts {
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
        shard: shard_facts.clone(),
        not_run: Vec::new(),
        merged_from: Vec::new(),
        max_memory_bytes: opts.max_memory,
        peak_rss_bytes: memory::peak_rss(),
        job_roots: plan.job_roots.clone(),
        rerunning: rerunning.iter().cloned().collect(),
    };
    let summary = Summary { invalid: plan.invalid.len(), up_to_date: plan.up_to_date(), ..Summary::default() };
    write_manifest(out, &manifest_name, &records, facts(&summary, true, &rerunning))?;
    let state = Mutex::new(State { rerunning, records, summary, last_write: Instant::now() - Duration::from_secs(10) });

    let mut to_run: Vec<_> = plan.to_run().collect();
    if opts.reverse {
        to_run.reverse();
    }
    for e in &to_run {
        for w in &e.record.warnings {
            observer.event(&Event::Warning(format!("{}: {w}", e.job.id)));
        }
    }
    observer.event(&Event::Planned { to_run: to_run.len() });
    let interrupted = AtomicBool::new(false);
    let not_run = Mutex::new(Vec::new());
    // Jobs are handed out in order, each once its estimate fits in what the running ones leave of
    // the limit; the pool's threads bound how many run at once. Only start times depend on this.
    // One dispatcher waits for the budget, never a job: methods use rayon inside, and a worker
    // blocked in a nested join may steal another job, which must not then wait for memory that
    // the job beneath it on the same stack holds.
    let budget = Budget::new(opts.max_memory);
    let run_one = |entry: &Entry| {
        if opts.interrupt.as_ref().is_some_and(|f| f.load(Ordering::SeqCst)) {
            interrupted.store(true, Ordering::SeqCst);
            not_run.lock().expect("not run").push(entry.job.id.clone());
            return;
        }
        let job = &entry.job;
        observer.event(&Event::Started { id: &job.id });
        let job_started = Instant::now();
        let mut rec = entry.record.clone();
        let inputs = entry.inputs();
        finish_record(&mut rec, execute(&inputs, &job.metrics, out), job_started, entry.memory);
        observer.event(&Event::Finished { record: &rec, job_file: &job.file, seconds: job_started.elapsed().as_secs_f64() });
        let mut s = state.lock().expect("state");
        if rec.status == Status::Failed {
            s.summary.failed += 1;
        } else {
            s.summary.ran += 1;
        }
        s.rerunning.remove(&rec.id);
        s.records.insert(rec.id.clone(), rec);
        if s.last_write.elapsed() >= Duration::from_millis(250) {
            s.last_write = Instant::now();
            if let Err(e) = write_manifest(out, &manifest_name, &s.records, facts(&s.summary, true, &s.rerunning)) {
                observer.event(&Event::Warning(format!("cannot write the manifest yet: {e}")));
            }
        }
    };
    rayon::scope(|scope| {
        for &entry in &to_run {
            let held = budget.acquire(entry.memory);
            let run_one = &run_one;
            scope.spawn(move |_| {
                run_one(entry);
                drop(held);
            });
        }
    });
    let mut s = state.into_inner().expect("state");
    s.summary.interrupted = interrupted.load(Ordering::SeqCst);
    s.summary.wall_seconds = started.elapsed().as_secs_f64();
    let mut final_facts = facts(&s.summary, false, &BTreeSet::new());
    final_facts.not_run = not_run.into_inner().expect("not run");
    final_facts.not_run.sort();
    write_manifest(out, &manifest_name, &s.records, final_facts)?;
    observer.event(&Event::Done { summary: &s.summary, manifest: &manifest_path });
    Ok(s.summary)
}

/// Completes a job's record with what executing it gave: its outputs, seams, diagnostics, metrics
/// and timing, or its failure.
pub fn finish_record(rec: &mut JobRecord, result: Result<Executed, JobFailure>, started: Instant, estimate: u64) {
    match result {
        Ok(done) => {
            rec.outputs = done.outputs;
            rec.seams = done.synthesis.seams;
            rec.diagnostics = done.synthesis.diagnostics;
            rec.metrics = done.metrics;
            rec.timing = Some(Timing {
                synthesis_seconds: done.synthesis_seconds,
                metrics_seconds: done.metrics_seconds,
                phases: done.synthesis.phases.into_iter().collect(),
                total_seconds: started.elapsed().as_secs_f64(),
                finished_at: now_unix(),
                estimated_peak_bytes: Some(estimate),
            });
        }
        Err(e) => {
            rec.status = Status::Failed;
            rec.error = Some(e.to_string());
        }
    }
}

fn write_manifest(out: &OutDir, name: &str, records: &BTreeMap<String, JobRecord>, facts: RunFacts) -> Result<(), Error> {
    let m = Manifest::new(records.values().cloned().collect(), facts);
    out.write(name, &m.to_bytes()).map(|_| ())
}

pub fn hostname() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .or_else(|_| std::fs::read_to_string("/etc/hostname"))
        .map(|s| s.trim().to_string())
        .unwrap_or_else(|_| "unknown".into())
}
