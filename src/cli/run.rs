//! `texsyn run`: plan (and with `--dry-run` only print the plan), or run under the output
//! directory's lock with progress on stderr or JSON Lines on stdout.

use super::progress::Progress;
use super::{Outcome, say};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};
use texsyn::Error;
use texsyn::batch::memory;
use texsyn::batch::run::{self as batch_run, RunOptions};
use texsyn::batch::shard::Shard;

#[derive(clap::Args)]
pub struct Args {
    /// Job files and/or directories.
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// Output directory (holds the images and manifest.json).
    #[arg(short, long, default_value = "out")]
    out: PathBuf,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(short, long)]
    jobs: Option<usize>,
    /// Print the plan and why each job would (not) run; write nothing.
    #[arg(long)]
    dry_run: bool,
    /// Run every job even if it is up to date.
    #[arg(long)]
    force: bool,
    /// Run even though the output directory records the jobs of another job root (job ids are
    /// paths relative to their root, so by default a run from another root is refused, exit 2):
    /// both roots' records are kept, and this run's replace those with the same ids.
    #[arg(long)]
    allow_other_root: bool,
    /// JSON Lines events on stdout instead of progress on stderr.
    #[arg(long)]
    json: bool,
    /// No progress output (errors and the summary are still printed).
    #[arg(short, long)]
    quiet: bool,
    /// Run only part I (0-based) of N of the job set and write the fragment
    /// manifest.shard-I-of-N.json (join fragments with `texsyn merge`). `auto` reads the index from
    /// SLURM_ARRAY_TASK_ID/SLURM_ARRAY_TASK_COUNT, or JOB_COMPLETION_INDEX with TEXSYN_SHARD_COUNT.
    #[arg(long, value_name = "I/N|auto")]
    shard: Option<String>,
    /// After SIGINT, SIGTERM or SIGHUP, seconds the running jobs get to finish before texsyn stops
    /// anyway (a second signal stops at once). Below Slurm's and Kubernetes' default 30 s.
    #[arg(long, default_value_t = 20, value_name = "SECONDS")]
    grace: u64,
    /// Memory limit: a job whose estimated peak memory exceeds it is refused (invalid, with its
    /// estimate), and jobs whose estimates together exceed it never run at once. SIZE is bytes or
    /// a number with K, M, G or T (powers of 1024): 2G, 512M, 1.5GiB; `unlimited` for none.
    /// Default: the memory available when the run starts (MemAvailable), or none where unknown.
    /// Results do not depend on it.
    #[arg(long, value_name = "SIZE", default_value_t = MemoryLimit::available())]
    max_memory: MemoryLimit,
    /// Take jobs in reverse order (for testing order independence).
    #[arg(long, hide = true)]
    reverse: bool,
}

pub fn run(args: Args) -> Result<Outcome, Error> {
    if args.jobs == Some(0) {
        return Err(Error::Usage("--jobs must be at least 1".into()));
    }
    let shard = match args.shard.as_deref() {
        None => None,
        Some("auto") => Some(Shard::from_env(|k| std::env::var(k).ok())?),
        Some(s) => Some(Shard::parse(s)?),
    };
    let mut opts = RunOptions {
        out: args.out.clone(),
        threads: args.jobs,
        force: args.force,
        reverse: args.reverse,
        interrupt: None,
        shard,
        max_memory: args.max_memory.0,
        allow_other_root: args.allow_other_root,
    };
    if args.dry_run {
        return dry_run(&args, &opts);
    }
    let interrupt = Arc::new(AtomicBool::new(false));
    let signal = Arc::new(AtomicI32::new(0));
    install_stop_signals(interrupt.clone(), signal.clone(), args.grace)?;
    opts.interrupt = Some(interrupt);
    let progress = Progress::new(args.json, args.quiet, shard);
    let s = batch_run::run(&args.inputs, &opts, &progress)?;
    let manifest = shard.map_or_else(|| texsyn::batch::manifest::FILE_NAME.to_string(), |s| s.fragment_name());
    if !args.json {
        eprintln!(
            "texsyn{}: ran {}, up to date {}, failed {}, invalid {}{} in {:.1}s; manifest: {}",
            shard.map(|s| format!(" [shard {s}]")).unwrap_or_default(),
            s.ran,
            s.up_to_date,
            s.failed,
            s.invalid,
            if s.interrupted { " (interrupted)" } else { "" },
            s.wall_seconds,
            args.out.join(manifest).display()
        );
    }
    Ok(if s.interrupted {
        Outcome::Interrupted(signal.load(Ordering::SeqCst))
    } else if s.all_good() {
        Outcome::Success
    } else {
        Outcome::Problems
    })
}

/// `--dry-run`: the plan, one line per job (or a JSON `plan` event), and nothing written.
fn dry_run(args: &Args, opts: &RunOptions) -> Result<Outcome, Error> {
    let started = std::time::Instant::now();
    let plan = batch_run::plan_only(&args.inputs, opts)?;
    let progress = Progress::new(args.json, args.quiet, opts.shard);
    for inv in &plan.invalid {
        texsyn::batch::observer::Observer::event(&progress, &texsyn::batch::observer::Event::Invalid { id: &inv.id, errors: &inv.errors });
    }
    for (id, what) in plan.lines() {
        if args.json {
            say(serde_json::json!({"event": "plan", "id": id, "action": what}));
        } else {
            say(format!("{id}: {what}"));
        }
    }
    if !args.json {
        eprintln!(
            "texsyn: planned 0, up to date {}, failed 0, invalid {} in {:.1}s",
            plan.up_to_date(),
            plan.invalid.len(),
            started.elapsed().as_secs_f64()
        );
    }
    Ok(if plan.invalid.is_empty() { Outcome::Success } else { Outcome::Problems })
}

/// `--max-memory`: bytes, or no limit.
#[derive(Clone, Copy, Debug)]
pub(super) struct MemoryLimit(pub(super) Option<u64>);

impl MemoryLimit {
    /// The memory available now, the default limit (none where the platform does not say).
    pub(super) fn available() -> MemoryLimit {
        MemoryLimit(memory::available())
    }
}

impl std::fmt::Display for MemoryLimit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.0 {
            // Whole MiB, so that the default reads back as (almost exactly) what it was.
            Some(bytes) => write!(f, "{}M", bytes / memory::MIB),
            None => f.write_str("unlimited"),
        }
    }
}

impl std::str::FromStr for MemoryLimit {
    type Err = String;
    fn from_str(s: &str) -> Result<MemoryLimit, String> {
        if s.trim().eq_ignore_ascii_case("unlimited") {
            return Ok(MemoryLimit(None));
        }
        memory::parse_size(s).map(|b| MemoryLimit(Some(b)))
    }
}

/// SIGINT (Ctrl-C), SIGTERM (what Slurm, Kubernetes and systemd send before a kill at a time limit
/// or on preemption) and SIGHUP (a closed terminal) all stop a run the same way: no new job starts,
/// running ones get `grace` seconds to finish, the manifest is written with the jobs that did not
/// run listed, and the exit code is 128 + the signal (130, 143, 129). A second signal, or the end
/// of the grace period, stops at once; the manifest then holds every job finished so far.
fn install_stop_signals(interrupt: Arc<AtomicBool>, signal: Arc<AtomicI32>, grace: u64) -> Result<(), Error> {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP])
        .map_err(|e| Error::Usage(format!("cannot install signal handlers: {e}")))?;
    std::thread::spawn(move || {
        for sig in signals.forever() {
            let name = match sig {
                SIGTERM => "SIGTERM",
                SIGHUP => "SIGHUP",
                _ => "interrupt",
            };
            if interrupt.swap(true, Ordering::SeqCst) {
                eprintln!("texsyn: {name} again; stopping now");
                std::process::exit(128 + sig);
            }
            signal.store(sig, Ordering::SeqCst);
            eprintln!("texsyn: {name}; finishing running jobs (at most {grace} s) and writing the manifest (signal again to stop now)");
            std::thread::spawn(move || {
                std::thread::sleep(std::time::Duration::from_secs(grace));
                eprintln!("texsyn: the {grace} s grace period is over; stopping now (finished jobs are in the manifest)");
                std::process::exit(128 + sig);
            });
        }
    });
    Ok(())
}
