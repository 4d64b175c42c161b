//! `texsyn eval`: the recorded metrics for any sample/output pair.

use super::{Outcome, say};
use std::path::PathBuf;
use texsyn::Error;
use texsyn::batch::execute::load_sample;

#[derive(clap::Args)]
pub struct Args {
    sample: PathBuf,
    output: PathBuf,
    /// Machine-readable output.
    #[arg(long)]
    json: bool,
    /// Comma-separated metric names (default: all).
    #[arg(long, value_delimiter = ',')]
    metrics: Option<Vec<String>>,
}

pub fn run(args: Args) -> Result<Outcome, Error> {
    let names: Vec<String> = args.metrics.unwrap_or_else(|| texsyn::metrics::METRIC_NAMES.iter().map(|s| s.to_string()).collect());
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    let (s, o) = (load_sample(&args.sample)?, load_sample(&args.output)?);
    let values = texsyn::metrics::evaluate(&names, &s.image, &o.image, None).map_err(Error::Metrics)?;
    if args.json {
        say(serde_json::json!({
            "sample": args.sample.display().to_string(),
            "output": args.output.display().to_string(),
            "metrics": values,
        }));
    } else {
        for (k, v) in &values {
            match v {
                Some(x) => say(format!("{k:<16} {x:.6}")),
                None => say(format!("{k:<16} undefined")),
            }
        }
    }
    Ok(Outcome::Success)
}
