//! `texsyn methods`: every method with its parameters, defaults and ranges (from the same
//! tables that validate job files).

use super::{Outcome, say};
use texsyn::Error;

pub fn run() -> Result<Outcome, Error> {
    for m in texsyn::synth::methods::registry() {
        say(format!("{} (algorithm version {})\n  {}", m.name(), m.algorithm_version(), m.summary()));
        for p in m.params() {
            say(format!("  {:<12} {:<28} default {:<18} {}", p.name, p.kind.describe(), p.default.describe(), p.doc));
        }
        say("");
    }
    Ok(Outcome::Success)
}
