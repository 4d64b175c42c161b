//! The `texsyn` command line: a thin layer over the library.

use clap::{Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use texsyn::batch::manifest::Manifest;
use texsyn::batch::{golden, run as runner, verify};
use texsyn::synth::methods;

const EXIT_CODES: &str = "\
Exit codes:
  0    all good (including: everything was already up to date)
  1    some job failed or was invalid (the others still ran; see the manifest)
  2    usage error, or the run could not start (no job files, output directory locked)
  3    verify or golden mismatch
  130  interrupted (Ctrl-C); finished jobs are recorded, re-run to continue";

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
    Run {
        /// Job files and/or directories.
        #[arg(required = true)]
        inputs: Vec<PathBuf>,
        /// Output directory (holds the images and manifest.json).
        #[arg(short, long, default_value = "out")]
        out: PathBuf,
        /// Worker threads (default: all cores). Results do not depend on it.
        #[arg(short, long)]
        jobs: Option<usize>,
        /// Print the plan and why each job would (not) run; write nothing.
        #[arg(long)]
        dry_run: bool,
        /// Run every job even if it is up to date.
        #[arg(long)]
        force: bool,
        /// JSON Lines events on stdout instead of progress on stderr.
        #[arg(long)]
        json: bool,
        /// No progress output (errors and the summary are still printed).
        #[arg(short, long)]
        quiet: bool,
        /// Take jobs in reverse order (for testing order independence).
        #[arg(long, hide = true)]
        reverse: bool,
    },
    /// Re-run every recorded job from a manifest alone and compare pixel digests.
    #[command(after_help = EXIT_CODES)]
    Verify {
        manifest: PathBuf,
        #[arg(short, long)]
        jobs: Option<usize>,
    },
    /// Compare a run with the expected digests in a golden directory, or record new ones.
    #[command(subcommand)]
    Golden(GoldenCommand),
    /// List the methods, their parameters, defaults and ranges.
    Methods,
    /// Find the translation vectors t1, t2 of a near-regular sample (exit 0), or say why there
    /// are none (exit 1).
    Lattice {
        sample: PathBuf,
        /// Also write the sample with the lattice drawn over it.
        #[arg(long)]
        overlay: Option<PathBuf>,
        #[arg(long)]
        json: bool,
    },
    /// Score any image against a sample with the metrics texsyn records (paper 003's four
    /// measures, the verbatim-copy fraction; seam visibility needs a method's grid and is undefined here).
    Eval {
        sample: PathBuf,
        output: PathBuf,
        /// Machine-readable output.
        #[arg(long)]
        json: bool,
        /// Comma-separated metric names (default: all).
        #[arg(long, value_delimiter = ',')]
        metrics: Option<Vec<String>>,
    },
    /// Use a tile set exported by a wang-tiles or rw-tiles job (`export_tiles = true`).
    #[command(subcommand)]
    Tiles(TilesCommand),
    /// Tables (Markdown, CSV), contact sheets, a plot and an HTML page from a manifest.
    #[command(after_help = REPORT_HELP)]
    Report {
        manifest: PathBuf,
        /// Report directory (index.html, tables.md, tables/, sheets/, plots/, images/).
        #[arg(short, long)]
        out: PathBuf,
        /// Table columns: `auto` (the method plus the parameters that vary among its jobs), or
        /// comma-separated keys among method, param:NAME, size, seed.
        #[arg(long, default_value = "auto")]
        group_by: texsyn::report::GroupBy,
        /// Add speed-up tables: each group's time against this method's matching group (e.g.
        /// `tes` for paper 000, `quilting` for paper 003).
        #[arg(long)]
        baseline: Option<String>,
    },
}

const REPORT_HELP: &str = "\
Exit codes:
  0    report written
  1    report written, but some images were missing or differ from the manifest (listed)
  2    usage error, unreadable manifest, or the report directory cannot be written";

#[derive(Subcommand)]
enum TilesCommand {
    /// Render a texture of any size by copying tiles from an exported tile set. With no options
    /// it reproduces the job's own output exactly; --seed, --width, --height give others.
    Render {
        /// The export's index.json (in `{output}.tiles/`).
        index: PathBuf,
        /// The image to write (.png or .exr).
        #[arg(short, long)]
        out: PathBuf,
        /// Output width (default: the job's).
        #[arg(long)]
        width: Option<u32>,
        /// Output height (default: the job's).
        #[arg(long)]
        height: Option<u32>,
        /// Seed of the tile arrangement (default: the job's).
        #[arg(long)]
        seed: Option<u64>,
        /// `keyed` or `scanline` (default: the job's).
        #[arg(long)]
        tiling: Option<String>,
    },
}

#[derive(Subcommand)]
enum GoldenCommand {
    /// Compare a manifest's pixel digests with the golden files (exit 3 on any difference).
    Check { golden: PathBuf, manifest: PathBuf },
    /// Record the manifest's pixel digests as the expected ones, printing what changed.
    Bless { golden: PathBuf, manifest: PathBuf },
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let _ = e.print();
            return ExitCode::from(if e.use_stderr() { 2 } else { 0 });
        }
    };
    runner::install_panic_hook();
    match cli.command {
        Command::Run { inputs, out, jobs, dry_run, force, json, quiet, reverse } => {
            if jobs == Some(0) {
                eprintln!("error: --jobs must be at least 1");
                return ExitCode::from(2);
            }
            let interrupt = Arc::new(AtomicBool::new(false));
            {
                let flag = interrupt.clone();
                let _ = ctrlc::set_handler(move || {
                    if flag.swap(true, Ordering::SeqCst) {
                        std::process::exit(130);
                    }
                    eprintln!("texsyn: interrupted; finishing running jobs and writing the manifest (Ctrl-C again to stop now)");
                });
            }
            let opts = runner::RunOptions { out: out.clone(), threads: jobs, dry_run, force, json, quiet, reverse, interrupt: Some(interrupt) };
            match runner::run(&inputs, &opts) {
                Err(e) => {
                    eprintln!("error: {e}");
                    ExitCode::from(2)
                }
                Ok(s) => {
                    if !json {
                        let verb = if dry_run { "planned" } else { "ran" };
                        eprintln!(
                            "texsyn: {verb} {}, up to date {}, failed {}, invalid {}{} in {:.1}s{}",
                            s.ran,
                            s.up_to_date,
                            s.failed,
                            s.invalid,
                            if s.interrupted { " (interrupted)" } else { "" },
                            s.wall_seconds,
                            if dry_run { String::new() } else { format!("; manifest: {}", out.join("manifest.json").display()) }
                        );
                    }
                    if s.interrupted {
                        ExitCode::from(130)
                    } else if s.all_good() {
                        ExitCode::SUCCESS
                    } else {
                        ExitCode::from(1)
                    }
                }
            }
        }
        Command::Verify { manifest, jobs } => match verify::verify(&manifest, jobs) {
            Err(e) => {
                eprintln!("error: {e}");
                ExitCode::from(2)
            }
            Ok(report) => {
                for p in &report.manifest_problems {
                    println!("MANIFEST  {p}");
                }
                let mut verified = 0;
                for (id, outcome) in &report.jobs {
                    match outcome {
                        verify::Outcome::Verified => verified += 1,
                        verify::Outcome::Skipped(why) => println!("SKIPPED   {id}: {why}"),
                        verify::Outcome::Mismatch(problems) => {
                            for p in problems {
                                println!("MISMATCH  {id}: {p}");
                            }
                        }
                    }
                }
                let bad = report.jobs.iter().filter(|(_, o)| matches!(o, verify::Outcome::Mismatch(_))).count();
                eprintln!("texsyn verify: {verified} verified, {bad} mismatched, {} manifest problems", report.manifest_problems.len());
                if report.ok() { ExitCode::SUCCESS } else { ExitCode::from(3) }
            }
        },
        Command::Golden(g) => {
            let (dir, manifest_path, bless) = match g {
                GoldenCommand::Check { golden, manifest } => (golden, manifest, false),
                GoldenCommand::Bless { golden, manifest } => (golden, manifest, true),
            };
            let manifest = match Manifest::load(&manifest_path) {
                Ok(m) => m,
                Err(e) => {
                    eprintln!("error: {e}");
                    return ExitCode::from(2);
                }
            };
            if bless {
                match golden::bless(&dir, &manifest) {
                    Ok(changes) => {
                        for c in &changes {
                            println!("{c}");
                        }
                        eprintln!("texsyn golden bless: {} change(s) written to {}", changes.len(), dir.display());
                        ExitCode::SUCCESS
                    }
                    Err(e) => {
                        eprintln!("error: {e}");
                        ExitCode::from(2)
                    }
                }
            } else {
                match golden::check(&dir, &manifest) {
                    Ok(r) => {
                        for m in &r.mismatched {
                            println!("MISMATCH  {m}");
                        }
                        for m in &r.missing {
                            println!("MISSING   {m}");
                        }
                        for m in &r.not_checked {
                            println!("UNCHECKED {m}");
                        }
                        eprintln!(
                            "texsyn golden check: {} matched, {} mismatched, {} missing, {} not checked",
                            r.matched,
                            r.mismatched.len(),
                            r.missing.len(),
                            r.not_checked.len()
                        );
                        if r.ok() { ExitCode::SUCCESS } else { ExitCode::from(3) }
                    }
                    Err(e) => {
                        eprintln!("error: {e}");
                        ExitCode::from(2)
                    }
                }
            }
        }
        Command::Eval { sample, output, json, metrics } => {
            let names: Vec<String> = metrics.unwrap_or_else(|| texsyn::metrics::METRIC_NAMES.iter().map(|s| s.to_string()).collect());
            let names: Vec<&str> = names.iter().map(String::as_str).collect();
            let (s, o) = match (runner::load_sample(&sample), runner::load_sample(&output)) {
                (Ok(s), Ok(o)) => (s, o),
                (Err(e), _) | (_, Err(e)) => {
                    eprintln!("error: {e}");
                    return ExitCode::from(2);
                }
            };
            match texsyn::metrics::evaluate(&names, &s.image, &o.image, None) {
                Err(e) => {
                    eprintln!("error: {e}");
                    ExitCode::from(2)
                }
                Ok(values) => {
                    if json {
                        let v = serde_json::json!({
                            "sample": sample.display().to_string(),
                            "output": output.display().to_string(),
                            "metrics": values,
                        });
                        println!("{v}");
                    } else {
                        for (k, v) in &values {
                            match v {
                                Some(x) => println!("{k:<16} {x:.6}"),
                                None => println!("{k:<16} undefined"),
                            }
                        }
                    }
                    ExitCode::SUCCESS
                }
            }
        }
        Command::Lattice { sample, overlay, json } => {
            let loaded = match runner::load_sample(&sample) {
                Ok(l) => l,
                Err(e) => {
                    eprintln!("error: {e}");
                    return ExitCode::from(2);
                }
            };
            match texsyn::synth::lattice::extract(&loaded.image, &texsyn::synth::lattice::LatticeOptions::default()) {
                Err(e) => {
                    if json {
                        println!("{}", serde_json::json!({"sample": sample.display().to_string(), "lattice": null, "error": e.to_string()}));
                    }
                    eprintln!("{}: {e}", sample.display());
                    ExitCode::from(1)
                }
                Ok(l) => {
                    if let Some(path) = overlay {
                        let img = texsyn::synth::lattice::overlay(&loaded.image, &l);
                        let enc = texsyn::image::io::encode(&img, texsyn::image::io::Encoding { format: texsyn::image::io::Format::Png, bit_depth: 8 });
                        if let Err(e) = enc.and_then(|e| texsyn::batch::outdir::write_atomic(&path, &e.bytes)) {
                            eprintln!("error: {e}");
                            return ExitCode::from(2);
                        }
                    }
                    if json {
                        println!("{}", serde_json::json!({"sample": sample.display().to_string(), "lattice": l}));
                    } else {
                        println!("t1 = ({}, {})\nt2 = ({}, {})", l.t1.0, l.t1.1, l.t2.0, l.t2.1);
                        println!("texel area {} px, peaks A(t1) = {:.3}, A(t2) = {:.3}, {}/{} dominant peaks explained", l.determinant(), l.peak1, l.peak2, l.explained, l.candidates);
                    }
                    ExitCode::SUCCESS
                }
            }
        }
        Command::Tiles(TilesCommand::Render { index, out, width, height, seed, tiling }) => {
            match render_tiles(&index, &out, width, height, seed, tiling.as_deref()) {
                Ok(msg) => {
                    eprintln!("{msg}");
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    eprintln!("error: {e}");
                    ExitCode::from(2)
                }
            }
        }
        Command::Report { manifest, out, group_by, baseline } => {
            match texsyn::report::report(&texsyn::report::ReportOptions { manifest, out, group_by, baseline }) {
                Err(e) => {
                    eprintln!("error: {e}");
                    ExitCode::from(2)
                }
                Ok(s) => {
                    for p in &s.problems {
                        eprintln!("warning: {p}");
                    }
                    eprintln!(
                        "texsyn report: {} jobs counted, {} not counted, {} files; open {}",
                        s.counted,
                        s.excluded,
                        s.files.len(),
                        s.index.display()
                    );
                    if s.problems.is_empty() { ExitCode::SUCCESS } else { ExitCode::from(1) }
                }
            }
        }
        Command::Methods => {
            for m in methods::registry() {
                println!("{} (algorithm version {})\n  {}", m.name(), m.algorithm_version(), m.summary());
                for p in m.params() {
                    println!("  {:<12} {:<28} default {:<18} {}", p.name, p.kind.describe(), p.default.describe(), p.doc);
                }
                println!();
            }
            ExitCode::SUCCESS
        }
    }
}

/// `texsyn tiles render`.
fn render_tiles(index: &std::path::Path, out: &std::path::Path, width: Option<u32>, height: Option<u32>, seed: Option<u64>, tiling: Option<&str>) -> Result<String, String> {
    use texsyn::image::io::{Encoding, Format};
    use texsyn::synth::methods::tiles::wang::TilingOrder;
    use texsyn::synth::params::Choice;
    let loaded = texsyn::synth::methods::tiles::export::load(index)?;
    let ix = loaded.index();
    let (w, h) = (width.unwrap_or(ix.output[0]), height.unwrap_or(ix.output[1]));
    const MAX_SIDE: u32 = 65_536;
    if w == 0 || h == 0 || w > MAX_SIDE || h > MAX_SIDE {
        return Err(format!("--width and --height must be 1..={MAX_SIDE} (got {w}x{h})"));
    }
    let tiling = tiling.unwrap_or(&ix.tiling);
    let order = TilingOrder::parse(tiling).ok_or_else(|| format!("tiling `{tiling}` is not keyed or scanline"))?;
    let format = Format::from_path(out).ok_or_else(|| format!("{}: the output must end in .png or .exr", out.display()))?;
    let seed = seed.unwrap_or(ix.seed);
    let started = std::time::Instant::now();
    let img = loaded.render(w, h, seed, order);
    let fill = started.elapsed().as_secs_f64();
    let bit_depth = if format == Format::Exr { 32 } else { 8 };
    let encoded = texsyn::image::io::encode(&img, Encoding { format, bit_depth })?;
    texsyn::batch::outdir::write_atomic(out, &encoded.bytes)?;
    Ok(format!(
        "{}: {w}x{h} from {} {} tiles (seed {seed}), filled in {fill:.3} s; pixels {}",
        out.display(),
        ix.tiles.len(),
        ix.method,
        encoded.pixels.pixel_digest().short()
    ))
}
