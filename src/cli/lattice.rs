//! `texsyn lattice`: the translation vectors of a near-regular sample, or why there are none.

use super::{Outcome, say};
use std::path::PathBuf;
use texsyn::Error;
use texsyn::batch::execute::load_sample;
use texsyn::image::io::{Encoding, Format};
use texsyn::synth::lattice::{self, LatticeOptions};

#[derive(clap::Args)]
pub struct Args {
    sample: PathBuf,
    /// Also write the sample with the lattice drawn over it.
    #[arg(long)]
    overlay: Option<PathBuf>,
    #[arg(long)]
    json: bool,
}

pub fn run(args: Args) -> Result<Outcome, Error> {
    let loaded = load_sample(&args.sample)?;
    let sample = args.sample.display().to_string();
    let l = match lattice::extract(&loaded.image, &LatticeOptions::default()) {
        Ok(l) => l,
        Err(e) => {
            if args.json {
                say(serde_json::json!({"sample": sample, "lattice": null, "error": e.to_string()}));
            }
            eprintln!("{sample}: {e}");
            return Ok(Outcome::Problems);
        }
    };
    if let Some(path) = &args.overlay {
        let img = lattice::overlay(&loaded.image, &l);
        let enc = texsyn::image::io::encode(&img, Encoding { format: Format::Png, bit_depth: 8 })
            .map_err(|source| Error::Image { path: path.clone(), source })?;
        texsyn::batch::outdir::write_atomic(path, &enc.bytes)?;
    }
    if args.json {
        say(serde_json::json!({"sample": sample, "lattice": l}));
    } else {
        say(format!("t1 = ({}, {})\nt2 = ({}, {})", l.t1.0, l.t1.1, l.t2.0, l.t2.1));
        say(format!(
            "texel area {} px, peaks A(t1) = {:.3}, A(t2) = {:.3}, {}/{} dominant peaks explained",
            l.determinant(),
            l.peak1,
            l.peak2,
            l.explained,
            l.candidates
        ));
        if l.fine.peaks > 0 {
            say(format!(
                "to a fraction of a pixel: t1 = ({:.2}, {:.2}), t2 = ({:.2}, {:.2}) (fitted to {} autocorrelation peaks)",
                l.fine.t1.0, l.fine.t1.1, l.fine.t2.0, l.fine.t2.1, l.fine.peaks
            ));
        } else {
            say("not refined below a pixel (too few clear autocorrelation peaks)".to_string());
        }
        if let Some(view) = l.found_in {
            say(format!("found in the sample's {view} (its plain gray shows no lattice)"));
        }
    }
    Ok(Outcome::Success)
}
