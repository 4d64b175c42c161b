//! `texsyn run`: plan (and with `--dry-run` only print the plan), or run under the output
//! directory's lock with progress on stderr or JSON Lines on stdout.

use super::progress::Progress;
use super::{Outcome, say};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use texsyn::Error;
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
    let mut opts = RunOptions { out: args.out.clone(), threads: args.jobs, force: args.force, reverse: args.reverse, interrupt: None, shard };
    if args.dry_run {
        return dry_run(&args, &opts);
    }
    let interrupt = Arc::new(AtomicBool::new(false));
    {
        let flag = interrupt.clone();
        let _ = ctrlc::set_handler(move || {
            if flag.swap(true, Ordering::SeqCst) {
                std::process::exit(130);
            }
            eprintln!("texsyn: interrupted; finishing running jobs and writing the manifest (Ctrl-C again to stop now)");
        });
    }
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
        Outcome::Interrupted
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
