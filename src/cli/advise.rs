//! `texsyn advise SAMPLE`: what the sample is (lattice, orientation) and, for each method with
//! its defaults, whether it fits, fits with other parameters, or is not for this sample.

use super::{Outcome, say};
use std::path::PathBuf;
use texsyn::Error;
use texsyn::batch::execute::load_sample;
use texsyn::synth::advice::{self, Fit};
use texsyn::synth::methods;
use texsyn::synth::params;
use texsyn::synth::wrap;

pub const HELP: &str = "\
The analysis is the one a run does at validation: a job whose method and parameters do not fit
its sample still runs, with the same sentence in its manifest entry's `warnings` list.

Exit codes:
  0    the sample was analysed (including \"nothing to analyse\" for a flat or tiny one)
  2    the sample cannot be read or decoded";

#[derive(clap::Args)]
pub struct Args {
    sample: PathBuf,
    /// Also say whether a tileable output of this size keeps the sample's lattice whole across
    /// its wrap, and if not, the nearest sizes that do (what a tileable job's manifest entry warns).
    #[arg(long, value_name = "WxH")]
    tileable: Option<String>,
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
    let wrap_size = args.tileable.as_deref().map(super::synth::parse_size).transpose()?;
    let wrap = wrap_size.map(|size| (size, a.lattice.as_ref().map(|l| wrap::wrap_fit(l, size))));
    if args.json {
        let methods: Vec<serde_json::Value> = verdicts.iter().map(|(name, fit)| serde_json::json!({"method": name, "fit": fit})).collect();
        let mut doc = serde_json::json!({"sample": args.sample.display().to_string(), "analysis": a, "methods": methods});
        if let Some((size, fit)) = &wrap {
            doc["tileable"] = serde_json::json!({"size": [size.0, size.1], "lattice": fit});
        }
        say(doc);
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
    if let Some(((w, h), fit)) = &wrap {
        match (fit, a.lattice.as_ref()) {
            (Some(f), Some(l)) if !f.continuous => say(format!("  tileable {w}x{h}: {}", wrap::warning(l, (*w, *h)).unwrap_or_default())),
            (Some(_), _) => say(format!("  tileable {w}x{h}: keeps the lattice whole across the wrap (texels meet in phase)")),
            _ => say(format!("  tileable {w}x{h}: no lattice, nothing to keep in phase across the wrap")),
        }
    }
    Ok(Outcome::Success)
}
