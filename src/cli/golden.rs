//! `texsyn golden check | bless`: compare a run's pixel digests with `golden/`, or record them.

use super::{Outcome, say};
use std::path::PathBuf;
use texsyn::Error;
use texsyn::batch::golden;
use texsyn::batch::manifest::Manifest;

#[derive(clap::Subcommand)]
pub enum Command {
    /// Compare a manifest's pixel digests with the golden files (exit 3 on any difference).
    Check { golden: PathBuf, manifest: PathBuf },
    /// Record the manifest's pixel digests as the expected ones, printing what changed.
    Bless { golden: PathBuf, manifest: PathBuf },
}

pub fn run(cmd: Command) -> Result<Outcome, Error> {
    match cmd {
        Command::Check { golden: dir, manifest } => {
            let r = golden::check(&dir, &Manifest::load(&manifest)?)?;
            for m in &r.mismatched {
                say(format!("MISMATCH  {m}"));
            }
            for m in &r.missing {
                say(format!("MISSING   {m}"));
            }
            for m in &r.not_checked {
                say(format!("UNCHECKED {m}"));
            }
            eprintln!(
                "texsyn golden check: {} matched, {} mismatched, {} missing, {} not checked",
                r.matched,
                r.mismatched.len(),
                r.missing.len(),
                r.not_checked.len()
            );
            Ok(if r.ok() { Outcome::Success } else { Outcome::Mismatch })
        }
        Command::Bless { golden: dir, manifest } => {
            let changes = golden::bless(&dir, &Manifest::load(&manifest)?)?;
            for c in &changes {
                say(c);
            }
            eprintln!("texsyn golden bless: {} change(s) written to {}", changes.len(), dir.display());
            Ok(Outcome::Success)
        }
    }
}
