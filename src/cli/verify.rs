//! `texsyn verify`: re-run every recorded job from a manifest and compare.

use super::{Outcome, say};
use std::path::PathBuf;
use texsyn::Error;
use texsyn::batch::verify::{self, Outcome as JobOutcome};

#[derive(clap::Args)]
pub struct Args {
    manifest: PathBuf,
    /// Worker threads (default: all cores).
    #[arg(short, long)]
    jobs: Option<usize>,
    /// Memory limit, as for `texsyn run`: a job whose estimated peak memory exceeds it is not
    /// re-run (reported, exit 1), and jobs never run at once beyond it. Default: the memory
    /// available at start; `unlimited` for none.
    #[arg(long, value_name = "SIZE", default_value_t = super::run::MemoryLimit::available())]
    max_memory: super::run::MemoryLimit,
}

pub fn run(args: Args) -> Result<Outcome, Error> {
    let report = verify::verify_within(&args.manifest, args.jobs, args.max_memory.0)?;
    for p in &report.manifest_problems {
        say(format!("MANIFEST  {p}"));
    }
    let mut verified = 0;
    for (id, outcome) in &report.jobs {
        match outcome {
            JobOutcome::Verified => verified += 1,
            JobOutcome::Skipped(why) => say(format!("SKIPPED   {id}: {why}")),
            JobOutcome::TooLarge(why) => say(format!("NOT RUN   {id}: {why}")),
            JobOutcome::Mismatch(problems) => {
                for p in problems {
                    say(format!("MISMATCH  {id}: {p}"));
                }
            }
        }
    }
    let bad = report.jobs.iter().filter(|(_, o)| matches!(o, JobOutcome::Mismatch(_))).count();
    let too_large = report.jobs.iter().filter(|(_, o)| matches!(o, JobOutcome::TooLarge(_))).count();
    // The summary's words are what scripts read: "not run" appears only when a job was not.
    let not_run = if too_large > 0 { format!(", {too_large} not run (over --max-memory)") } else { String::new() };
    eprintln!("texsyn verify: {verified} verified, {bad} mismatched{not_run}, {} manifest problems", report.manifest_problems.len());
    // A mismatch outranks a job left unchecked; a job left unchecked is not a pass.
    Ok(if bad > 0 || !report.manifest_problems.is_empty() {
        Outcome::Mismatch
    } else if too_large > 0 {
        Outcome::Problems
    } else {
        Outcome::Success
    })
}
