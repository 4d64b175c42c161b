//! `texsyn diff`: what changed between two runs, and why.

use super::{Outcome, say};
use std::path::PathBuf;
use texsyn::Error;
use texsyn::batch::diff::{self, Thresholds, describe_changes, short_value};
use texsyn::batch::manifest::Manifest;

pub const HELP: &str = "\
Exit codes:
  0    no job's pixels changed and no job started failing (jobs may have been added or removed)
  4    some job's pixels changed, or a job that succeeded before fails now
  2    usage error, or a manifest that cannot be read";

#[derive(clap::Args)]
pub struct Args {
    /// The earlier run's manifest.
    old: PathBuf,
    /// The later run's manifest.
    new: PathBuf,
    /// The whole difference as one JSON document on stdout.
    #[arg(long)]
    json: bool,
    /// Report a synthesis time that moved by more than this fraction…
    #[arg(long, default_value_t = 0.2, value_name = "FRACTION")]
    time_relative: f64,
    /// …and by at least this many seconds.
    #[arg(long, default_value_t = 0.05, value_name = "SECONDS")]
    time_seconds: f64,
    /// Report a metric that moved by more than this fraction.
    #[arg(long, default_value_t = 0.05, value_name = "FRACTION")]
    metric_relative: f64,
}

pub fn run(args: Args) -> Result<Outcome, Error> {
    let t = Thresholds { time_relative: args.time_relative, time_seconds: args.time_seconds, metric_relative: args.metric_relative };
    if !(t.time_relative >= 0.0 && t.time_seconds >= 0.0 && t.metric_relative >= 0.0) {
        return Err(Error::Usage("thresholds must be non-negative numbers".into()));
    }
    let (old, new) = (Manifest::load(&args.old)?, Manifest::load(&args.new)?);
    let d = diff::diff(&old, &new, &t);
    if args.json {
        say(serde_json::json!({"old": args.old.display().to_string(), "new": args.new.display().to_string(), "thresholds": t, "diff": d}));
    } else {
        for c in &d.tool {
            say(format!("TOOL      {}: {} → {}", c.key, short_value(&c.old), short_value(&c.new)));
        }
        for (id, error) in &d.failed_now {
            say(format!("FAILS NOW {id}: {}", error.lines().next().unwrap_or("")));
        }
        for p in &d.pixels_changed {
            let why = describe_changes(&p.because);
            say(format!("PIXELS    {}: {} ({why})", p.id, p.outputs.join(", ")));
        }
        for id in &d.fixed_now {
            say(format!("FIXED     {id}"));
        }
        for id in &d.added {
            say(format!("ADDED     {id}"));
        }
        for id in &d.removed {
            say(format!("REMOVED   {id}"));
        }
        for m in &d.slower {
            say(format!("SLOWER    {}: {:.3} s → {:.3} s ({:.1}×)", m.id, m.old, m.new, m.new / m.old.max(1e-9)));
        }
        for m in &d.faster {
            say(format!("FASTER    {}: {:.3} s → {:.3} s ({:.1}×)", m.id, m.old, m.new, m.old / m.new.max(1e-9)));
        }
        for m in &d.metrics_moved {
            say(format!("METRIC    {}: {} {:.6} → {:.6}", m.id, m.what, m.old, m.new));
        }
        eprintln!(
            "texsyn diff: {} pixels changed, {} fail now, {} fixed, {} added, {} removed, {} slower, {} faster, {} metrics moved, {} unchanged",
            d.pixels_changed.len(),
            d.failed_now.len(),
            d.fixed_now.len(),
            d.added.len(),
            d.removed.len(),
            d.slower.len(),
            d.faster.len(),
            d.metrics_moved.len(),
            d.unchanged
        );
    }
    Ok(if d.pixels_differ() { Outcome::PixelsChanged } else { Outcome::Success })
}
