//! Command-line parsing, one file per subcommand, and the exit-code policy.
//!
//! `main` parses, hands the arguments to one subcommand's `run`, and turns what it returns into
//! an exit code here and nowhere else: a subcommand returns an [`Outcome`] (what happened) or a
//! [`texsyn::Error`] (it could not do its work), never a number. The codes are a contract for
//! scripts and schedulers (see `EXIT_CODES`).
//!
//! Output to a closed pipe (`texsyn methods | head`) is not an error: [`say`] stops quietly with
//! exit 0 instead of the panic `println!` would give, because the reader has what it wanted.

mod advise;
mod apply;
mod diff;
mod eval;
mod golden;
mod lattice;
mod merge;
mod methods;
mod progress;
mod report;
mod run;
mod slurm;
mod synth;
mod tiles;
mod verify;

use clap::{Parser, Subcommand};
use std::io::Write;
use std::process::ExitCode;

pub const EXIT_CODES: &str = "\
Exit codes:
  0    all good (including: everything was already up to date)
  1    some job failed or was invalid (the others still ran; see the manifest)
  2    usage error, or the run could not start (no job files, output directory locked)
  3    verify or golden mismatch
  4    diff: pixels changed
  130  interrupted (Ctrl-C); finished jobs are recorded, re-run to continue
  143  stopped by SIGTERM (Slurm/Kubernetes time limit or preemption), likewise
  129  stopped by SIGHUP, likewise";

#[derive(Parser)]
#[command(name = "texsyn", version, about = "Reproducible texture synthesis from TOML job files", after_help = EXIT_CODES)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run job files and directories (searched recursively for *.toml).
    #[command(after_help = EXIT_CODES)]
    Run(run::Args),
    /// One texture from one sample, no job file: the flags become a job file (--print-job shows
    /// it) that is validated and run like any other; writes OUT and OUT's manifest beside it.
    #[command(after_help = synth::HELP)]
    Synth(synth::Args),
    /// Join the manifest fragments of a run split with `--shard` into one manifest (exit 1, listing
    /// them, when jobs failed or are missing; the merged manifest is written all the same).
    Merge(merge::Args),
    /// Print (or with --submit, submit) a Slurm job array running a job directory in N shards,
    /// plus a merge job that depends on it with afterany.
    Slurm(slurm::Args),
    /// Re-run every recorded job from a manifest alone and compare pixel digests.
    #[command(after_help = EXIT_CODES)]
    Verify(verify::Args),
    /// What changed between two runs: jobs added, removed, failing now or fixed, pixels changed
    /// (with the inputs that changed, key by key), times and metrics that moved.
    #[command(after_help = diff::HELP)]
    Diff(diff::Args),
    /// Compare a run with the expected digests in a golden directory, or record new ones.
    #[command(subcommand)]
    Golden(golden::Command),
    /// List the methods, their parameters, defaults and ranges.
    Methods,
    /// Find the translation vectors t1, t2 of a near-regular sample (exit 0), or say why there
    /// are none (exit 1).
    Lattice(lattice::Args),
    /// Describe a sample (lattice, orientation, stochastic) and say which methods fit it with
    /// their defaults, which need other parameters, and which are not for it.
    #[command(after_help = advise::HELP)]
    Advise(advise::Args),
    /// Score any image against a sample with the metrics texsyn records (paper 003's four
    /// measures, the verbatim-copy fraction; seam visibility needs a method's grid and is undefined here).
    Eval(eval::Args),
    /// Render a job's source map (its placement) over any image of the sample's size: a map the
    /// job did not list as a companion, a repainted albedo; over the sample it gives the output.
    #[command(after_help = apply::HELP)]
    Apply(apply::Args),
    /// Use a tile set exported by a wang-tiles or rw-tiles job (`export_tiles = true`).
    #[command(subcommand)]
    Tiles(tiles::Command),
    /// Tables (Markdown, CSV), contact sheets, a plot and an HTML page from a manifest.
    #[command(after_help = report::HELP)]
    Report(report::Args),
}

/// What a subcommand that did its work found. Each maps to one exit code.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// 0: everything as hoped.
    Success,
    /// 1: done, but something is missing or failed (failed/invalid jobs, report images that could
    /// not be shown, no lattice in the sample); the details were printed.
    Problems,
    /// 3: `verify` or `golden check` found a difference.
    Mismatch,
    /// 4: `diff` found jobs whose pixels changed (or that fail now).
    PixelsChanged,
    /// 128 + the signal (130 SIGINT, 143 SIGTERM, 129 SIGHUP): stopped after recording what finished.
    Interrupted(i32),
}

pub fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let _ = e.print();
            // --help and --version are not errors.
            return ExitCode::from(if e.use_stderr() { 2 } else { 0 });
        }
    };
    texsyn::batch::execute::install_panic_hook();
    let result = match cli.command {
        Command::Run(args) => run::run(args),
        Command::Diff(args) => diff::run(args),
        Command::Synth(args) => synth::run(args),
        Command::Merge(args) => merge::run(args),
        Command::Slurm(args) => slurm::run(args),
        Command::Verify(args) => verify::run(args),
        Command::Golden(cmd) => golden::run(cmd),
        Command::Methods => methods::run(),
        Command::Lattice(args) => lattice::run(args),
        Command::Advise(args) => advise::run(args),
        Command::Eval(args) => eval::run(args),
        Command::Apply(args) => apply::run(args),
        Command::Tiles(cmd) => tiles::run(cmd),
        Command::Report(args) => report::run(args),
    };
    match result {
        Ok(Outcome::Success) => ExitCode::SUCCESS,
        Ok(Outcome::Problems) => ExitCode::from(1),
        Ok(Outcome::Mismatch) => ExitCode::from(3),
        Ok(Outcome::PixelsChanged) => ExitCode::from(4),
        Ok(Outcome::Interrupted(signal)) => ExitCode::from(u8::try_from(128 + signal).unwrap_or(130)),
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}

/// Prints one line on stdout; a closed pipe ends the program quietly (see the module comment).
pub fn say(line: impl std::fmt::Display) {
    let mut out = std::io::stdout().lock();
    if let Err(e) = writeln!(out, "{line}").and_then(|()| out.flush()) {
        if e.kind() == std::io::ErrorKind::BrokenPipe {
            std::process::exit(0);
        }
        eprintln!("error: cannot write to stdout: {e}");
        std::process::exit(2);
    }
}
