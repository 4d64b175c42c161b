//! `texsyn report`: the morning-after page (summary, what changed, failures) and a paper's
//! tables, contact sheets and plot, from a manifest.

use super::Outcome;
use std::path::PathBuf;
use texsyn::Error;
use texsyn::report::{GroupBy, ReportOptions, Sections};

pub const HELP: &str = "\
The page leads with a summary (counts, wall time, failures with their errors, the slowest jobs and,
with --since or --golden, what regressed), then old | new | difference pictures of every job whose
pixels changed, then one section per job directory with its tables, plot and pictures.

The report lists its files in DIR/.texsyn-report; a later report into the same DIR removes the
files it no longer writes. A DIR holding an index.html without that list is refused.

Exit codes:
  0    report written
  1    report written, but some images were missing or differ from the manifest (listed)
  2    usage error, unreadable manifest (or --since manifest), or the report directory cannot be written";

#[derive(clap::Args)]
pub struct Args {
    manifest: PathBuf,
    /// Report directory (index.html, tables.md, tables/, sheets/, plots/, images/, changes/, sections/).
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
    /// An earlier run's manifest: lead with what changed since (as `texsyn diff`), with old |
    /// new | difference pictures of every job whose pixels changed.
    #[arg(long, value_name = "OLD_MANIFEST")]
    since: Option<PathBuf>,
    /// A golden directory: say which outputs differ from its digests.
    #[arg(long, value_name = "DIR")]
    golden: Option<PathBuf>,
    /// Sections of the page: `auto` (a job directory each, kept whole where its subdirectories
    /// only split a sweep of the same methods), `dir` (every job directory) or `one`.
    #[arg(long, default_value = "auto")]
    sections: Sections,
}

pub fn run(args: Args) -> Result<Outcome, Error> {
    let s = texsyn::report::report(&ReportOptions {
        manifest: args.manifest,
        out: args.out,
        group_by: args.group_by,
        baseline: args.baseline,
        since: args.since,
        golden: args.golden,
        sections: args.sections,
    })?;
    for p in &s.problems {
        eprintln!("warning: {p}");
    }
    let changed = s.pixels_changed.map(|n| format!(", {n} jobs changed pixels")).unwrap_or_default();
    let removed =
        if s.removed.is_empty() { String::new() } else { format!(", {} stale files of the previous report removed", s.removed.len()) };
    eprintln!(
        "texsyn report: {} jobs counted, {} not counted, {} sections{changed}, {} files{removed}; open {}",
        s.counted,
        s.excluded,
        s.sections,
        s.files.len(),
        s.index.display()
    );
    Ok(if s.problems.is_empty() { Outcome::Success } else { Outcome::Problems })
}
