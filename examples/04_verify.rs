//! Verify a manifest: re-run every recorded job from the manifest alone and compare pixels.
//!
//! ```sh
//! cargo run --release --example 03_run_jobs && cargo run --release --example 04_verify
//! cargo run --release --example 04_verify -- out/manifest.json     # any manifest
//! ```

use texsyn::batch::verify::Outcome;

fn main() -> Result<(), texsyn::Error> {
    let manifest = std::env::args().nth(1).unwrap_or_else(|| "03_out/manifest.json".into());
    let report = texsyn::verify(std::path::Path::new(&manifest), None)?;
    for problem in &report.manifest_problems {
        println!("manifest: {problem}");
    }
    for (id, outcome) in &report.jobs {
        match outcome {
            Outcome::Verified => println!("{id}: verified"),
            Outcome::Skipped(why) => println!("{id}: skipped ({why})"),
            Outcome::Mismatch(problems) => println!("{id}: MISMATCH {}", problems.join("; ")),
            Outcome::TooLarge(why) => println!("{id}: not re-run ({why})"),
        }
    }
    println!("{}", if report.ok() { "every job reproduces bit for bit" } else { "mismatches found, or jobs too large to re-run here" });
    Ok(())
}
