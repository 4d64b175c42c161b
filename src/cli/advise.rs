//! `texsyn advise SAMPLE`: what the sample is (lattice, orientation) and, for each method with
//! its defaults, whether it fits, fits with other parameters, or is not for this sample.

use super::{Outcome, say};
use std::path::PathBuf;
use texsyn::Error;
use texsyn::batch::execute::load_sample;
use texsyn::synth::advice::{self, Fit};
use texsyn::synth::methods;
use texsyn::synth::params;

pub const HELP: &str = "\
The analysis is the one a run does at validation: a job whose method and parameters do not fit
its sample still runs, with the same sentence in its manifest entry's `warnings` list.

Exit codes:
  0    the sample was analysed (including \"nothing to analyse\" for a flat or tiny one)
  2    the sample cannot be read or decoded";

#[derive(clap::Args)]
pub struct Args {
    sample: PathBuf,
    /// One JSON document instead of text.
    #[arg(long)]
    json: bool,
}

pub fn run(args: Args) -> Result<Outcome, Error> {
    let loaded = load_sample(&args.sample)?;
    let a = advice::analyse(&loaded.image);
    let mut verdicts = Vec::new();
    for m in methods::registry() {
        let defaults =
            params::resolve(m.params(), &[]).map_err(|e| Error::Usage(format!("{}: default parameters: {}", m.name(), e.len())))?;
        verdicts.push((m.name(), advice::fit(&a, m.name(), &defaults)));
    }
    if args.json {
        let methods: Vec<serde_json::Value> = verdicts.iter().map(|(name, fit)| serde_json::json!({"method": name, "fit": fit})).collect();
        say(serde_json::json!({"sample": args.sample.display().to_string(), "analysis": a, "methods": methods}));
        return Ok(Outcome::Success);
    }
    say(format!("{}: {}", args.sample.display(), a.describe()));
    if a.kind == advice::Kind::Flat {
        return Ok(Outcome::Success);
    }
    for (name, fit) in &verdicts {
        let line = match fit {
            Fit::Fits => "fits with its defaults".to_string(),
            Fit::FitsWith { set, because } => {
                let set: Vec<String> = set.iter().map(|(k, v)| format!("{k} = {v}")).collect();
                format!("fits with {} ({because})", set.join(", "))
            }
            Fit::NotFor { because, instead } => format!("not for this sample: {because}; use {instead}"),
        };
        say(format!("  {name:<15} {line}"));
    }
    Ok(Outcome::Success)
}
