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
}

pub fn run(args: Args) -> Result<Outcome, Error> {
    let report = verify::verify(&args.manifest, args.jobs)?;
    for p in &report.manifest_problems {
        say(format!("MANIFEST  {p}"));
    }
    let mut verified = 0;
    for (id, outcome) in &report.jobs {
        match outcome {
            JobOutcome::Verified => verified += 1,
            JobOutcome::Skipped(why) => say(format!("SKIPPED   {id}: {why}")),
            JobOutcome::Mismatch(problems) => {
                for p in problems {
                    say(format!("MISMATCH  {id}: {p}"));
                }
            }
        }
    }
    let bad = report.jobs.iter().filter(|(_, o)| matches!(o, JobOutcome::Mismatch(_))).count();
    eprintln!("texsyn verify: {verified} verified, {bad} mismatched, {} manifest problems", report.manifest_problems.len());
    Ok(if report.ok() { Outcome::Success } else { Outcome::Mismatch })
}
