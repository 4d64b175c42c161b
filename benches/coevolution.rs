//! Paper 000's Table 2, measured in one run (docs/methods.md §2.10, B13): co-evolution vs the
//! reconstructed TES baseline on `metal_tread_studs` (lattice (27, 0), (0, 26), given as in the
//! `jobs/papers/000` Table 2 jobs, and once more extracted from the sample to show that shared cost) for output lattices of 8×8, 12×12, 20×20 and 32×32 texels, with the parameters of
//! `jobs/papers/000/*.toml` (output 26·N px square, seed 1, defaults otherwise), on 1 and 2
//! threads. For co-evolution the whole synthesis call ("total") is split with the method's
//! `phases`: `lattice` (extraction, or nothing when given), `tables` (`E_I` and the `H`/`V` tables) and `iterations`
//! (initialisation and evolution); rendering and feathering are the rest. The speed-up is TES time /
//! co-evolution total time, as in the paper. Image quilting (block 27 ≈ the texel, its default
//! overlap) at the 20×20 job's output size (520×520) gives the "vs image quilting" ratios.
//! Medians of `TEXSYN_BENCH_RUNS` runs (default 5) after one warm-up; quilting runs
//! `TEXSYN_BENCH_QUILT_RUNS` times (default 1; it takes seconds).
//! `cargo bench --bench coevolution`.

use std::path::Path;
use std::time::Instant;
use texsyn::RgbImage;
use texsyn::image::io::{DecodeLimits, read_rgb8};
use texsyn::synth::lattice::{LatticeOptions, extract};
use texsyn::synth::method::{Request, Synthesis};
use texsyn::synth::methods::find;
use texsyn::synth::params::{ParamValue, resolve};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn phase(s: &Synthesis, name: &str) -> f64 {
    s.phases.iter().find(|(n, _)| n == name).map_or(f64::NAN, |p| p.1)
}

/// One timed synthesis call: (wall seconds, result).
fn call(method: &str, sample: &RgbImage, size: u32, given: &[(&str, ParamValue)]) -> (f64, Synthesis) {
    let m = find(method).unwrap();
    let given: Vec<(String, ParamValue)> = given.iter().map(|(k, v)| (k.to_string(), v.clone())).collect();
    let params = resolve(m.params(), &given).unwrap();
    let req = Request {
        sample,
        width: size,
        height: size,
        params: &params,
        seed: 1,
        placement: false,
        tileable: false,
        constraints: Default::default(),
    };
    let t = Instant::now();
    let s = m.synthesize(&req).unwrap();
    (t.elapsed().as_secs_f64(), s)
}

/// Medians over `runs` calls after one warm-up: (total, phase "lattice", phase "tables", phase
/// "iterations", iterations run).
fn timed(runs: usize, method: &str, sample: &RgbImage, size: u32, given: &[(&str, ParamValue)]) -> (f64, f64, f64, f64, u64) {
    call(method, sample, size, given);
    let results: Vec<(f64, Synthesis)> = (0..runs).map(|_| call(method, sample, size, given)).collect();
    let iterations = results[0].1.diagnostics["iterations"].as_u64().unwrap_or(0);
    (
        median(results.iter().map(|r| r.0).collect()),
        median(results.iter().map(|r| phase(&r.1, "lattice")).collect()),
        median(results.iter().map(|r| phase(&r.1, "tables")).collect()),
        median(results.iter().map(|r| phase(&r.1, "iterations")).collect()),
        iterations,
    )
}

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return; // `cargo test --benches` probes with --list
    }
    let env = |k: &str, d: usize| std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d).max(1);
    let runs = env("TEXSYN_BENCH_RUNS", 5);
    let quilt_runs = env("TEXSYN_BENCH_QUILT_RUNS", 1);
    let (sample, _) =
        read_rgb8(&Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/samples/metal_tread_studs.png"), DecodeLimits::default()).unwrap();
    let found = extract(&sample, &LatticeOptions::default()).unwrap();
    assert_eq!((found.t1, found.t2), ((27, 0), (0, 26)), "the \"lattice given\" rows assume the extracted lattice");
    println!("metal_tread_studs 256x256, seed 1; median of {runs} runs after a warm-up, seconds");
    println!("coevolution total = whole call; lattice = extraction; tables = E_I + H/V; iter = initialisation + evolution");
    println!("\"lattice given\": t1 = (27, 0), t2 = (0, 26) as params (the extracted vectors, same pixels), no extraction");
    println!("speed-up = TES / coevolution total (paper 000 Table 2: 62.9, 131.6, 233.9, 334.2)");
    for threads in [1usize, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let lattice = pool.install(|| {
            extract(&sample, &LatticeOptions::default()).unwrap();
            median(
                (0..runs)
                    .map(|_| {
                        let t = Instant::now();
                        extract(&sample, &LatticeOptions::default()).unwrap();
                        t.elapsed().as_secs_f64()
                    })
                    .collect(),
            )
        });
        println!("{threads} thread(s)  lattice extraction alone (part of both methods' times when extracted) {lattice:>8.4} s");
        let mut at_20 = (0.0, 0.0);
        for n in [8i64, 12, 20, 32] {
            let size = 26 * n as u32;
            let jobs = [("rows", ParamValue::Int(n)), ("cols", ParamValue::Int(n))];
            // The same lattice given explicitly (the vectors the extraction finds), so the table
            // also shows the methods' own cost without the shared extraction.
            let given = [jobs[0].clone(), jobs[1].clone(), ("t1_x", ParamValue::Int(27)), ("t2_y", ParamValue::Int(26))];
            for (label, params) in [("lattice extracted", &jobs[..]), ("lattice given (as the jobs)", &given[..])] {
                let (total, lattice, tables, iter, it_c) = pool.install(|| timed(runs, "coevolution", &sample, size, params));
                let (tes, _, _, tes_iter, it_t) = pool.install(|| timed(runs, "tes", &sample, size, params));
                println!(
                    "{threads} thread(s)  {n:>2}x{n:<2} ({size}x{size})  {label:<31}  coevolution total {total:>8.4} s (lattice {lattice:>7.4}, tables {tables:>7.4}, iter {iter:>7.4}; {it_c:>2} iterations)  TES (reconstructed) {tes:>8.4} s (iter {tes_iter:>7.4}; {it_t:>2} iterations)  speed-up {:>7.2}  iteration speed-up {:>7.1}",
                    tes / total,
                    tes_iter / iter
                );
                if n == 20 && params.len() == 2 {
                    at_20 = (total, tes);
                }
            }
        }
        // Image quilting for a comparable output: the 20×20 job's 520×520, block ≈ the 27×26 texel.
        let q =
            pool.install(|| median((0..quilt_runs).map(|_| call("quilting", &sample, 520, &[("block", ParamValue::Int(27))]).0).collect()));
        let (c, t) = at_20;
        println!(
            "{threads} thread(s)  520x520  image quilting (block 27) {q:>8.4} s  quilting / coevolution {:>7.2}  quilting / TES {:>6.3}",
            q / c,
            q / t
        );
    }
}
