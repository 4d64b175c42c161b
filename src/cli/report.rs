//! `texsyn report`: tables, contact sheets, a plot and an HTML page from a manifest.

use super::Outcome;
use std::path::PathBuf;
use texsyn::Error;
use texsyn::report::{GroupBy, ReportOptions};

pub const HELP: &str = "\
Exit codes:
  0    report written
  1    report written, but some images were missing or differ from the manifest (listed)
  2    usage error, unreadable manifest, or the report directory cannot be written";

#[derive(clap::Args)]
pub struct Args {
    manifest: PathBuf,
    /// Report directory (index.html, tables.md, tables/, sheets/, plots/, images/).
    #[arg(short, long)]
    out: PathBuf,
    /// Table columns: `auto` (the method plus the parameters that vary among its jobs), or
    /// comma-separated keys among method, param:NAME, size, seed.
    #[arg(long, default_value = "auto")]
    group_by: GroupBy,
    /// Add speed-up tables: each group's time against this method's matching group (e.g.
    /// `tes` for paper 000, `quilting` for paper 003).
    #[arg(long)]
    baseline: Option<String>,
}

pub fn run(args: Args) -> Result<Outcome, Error> {
    let s = texsyn::report::report(&ReportOptions {
        manifest: args.manifest,
        out: args.out,
        group_by: args.group_by,
        baseline: args.baseline,
    })?;
    for p in &s.problems {
        eprintln!("warning: {p}");
    }
    eprintln!("texsyn report: {} jobs counted, {} not counted, {} files; open {}", s.counted, s.excluded, s.files.len(), s.index.display());
    Ok(if s.problems.is_empty() { Outcome::Success } else { Outcome::Problems })
}
