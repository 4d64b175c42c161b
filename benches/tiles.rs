//! Paper 001's speed claim, measured in one run (docs/methods.md §3.9, B13): from the 128×128 crops of
//! `jobs/samples/crops/`, build 8 tiles of 64×64 and fill 1280×1280 (the paper: "under 2 s in
//! total") and 8192×8192, for RW-Tiles and for Cohen's Wang tiles (DP and shortest-path cuts),
//! on 1 and 2 threads; tile building and filling are timed separately. Image quilting (block 64,
//! its default overlap) at 1280×1280 from the same crop gives the "each method vs image quilting"
//! ratio. Medians of `TEXSYN_BENCH_RUNS` runs (default 5) after one warm-up; quilting runs
//! `TEXSYN_BENCH_QUILT_RUNS` times (default 1; it takes seconds).
//! Then issue #30's judgement with every method's defaults (`defaults` below): on whole bundled
//! samples, each tile method's fill at 512² and 2048² against image quilting's on the same sample
//! (whole synthesis calls): repetition (`metrics::repetition::max_autocorrelation`) at most twice
//! quilting's, and at 2048² at least 10× faster.
//! `cargo bench --bench tiles` (both); `cargo bench --bench tiles -- defaults` (only the latter).

use std::path::Path;
use std::time::Instant;
use texsyn::RgbImage;
use texsyn::image::io::{DecodeLimits, read_rgb8};
use texsyn::metrics::repetition::max_autocorrelation;
use texsyn::synth::method::Request;
use texsyn::synth::methods::find;
use texsyn::synth::methods::tiles::common::PixelError;
use texsyn::synth::methods::tiles::rw_tiles;
use texsyn::synth::methods::tiles::wang::{TileSet, TilingOrder};
use texsyn::synth::methods::tiles::wang_tiles::{self, Cut};
use texsyn::synth::params::{ParamValue, resolve};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v[v.len() / 2]
}

/// Median (build, fill) seconds over `runs` runs after one warm-up.
fn time_phases(runs: usize, mut once: impl FnMut() -> (f64, f64)) -> (f64, f64) {
    once();
    let (b, f): (Vec<f64>, Vec<f64>) = (0..runs).map(|_| once()).unzip();
    (median(b), median(f))
}

fn rw(sample: &RgbImage, size: u32) -> (f64, f64) {
    let t = Instant::now();
    let set = rw_tiles::build_tile_set(sample, 64, 8, TileSet::Minimal, PixelError::Squared, 1).unwrap();
    let build = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let tiling = set.tile_output(TilingOrder::Keyed, size, size, 1);
    let img = set.render(&tiling, size, size);
    let fill = t.elapsed().as_secs_f64();
    assert_eq!(img.width(), size);
    (build, fill)
}

fn wang(sample: &RgbImage, size: u32, cut: Cut) -> (f64, f64) {
    let t = Instant::now();
    let set = wang_tiles::build_tile_set(sample, 64, 8, TileSet::Minimal, cut, PixelError::Squared, 1).unwrap();
    let build = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let tiling = set.tile_output(TilingOrder::Keyed, size, size, 1);
    let img = set.render(&tiling, size, size);
    let fill = t.elapsed().as_secs_f64();
    assert_eq!(img.width(), size);
    (build, fill)
}

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return; // `cargo test --benches` probes with --list
    }
    let env = |k: &str, d: usize| std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d).max(1);
    let runs = env("TEXSYN_BENCH_RUNS", 5);
    let quilt_runs = env("TEXSYN_BENCH_QUILT_RUNS", 1);
    defaults(runs, quilt_runs);
    if std::env::args().any(|a| a == "defaults") {
        return;
    }
    let crops = Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/samples/crops");
    println!("median of {runs} runs after a warm-up, seconds; ratios are to RW-Tiles in the same configuration");
    for name in ["pebbles_beige", "hedge_leaves", "tiles_terracotta"] {
        let (sample, _) = read_rgb8(&crops.join(format!("{name}_128.png")), DecodeLimits::default()).unwrap();
        for threads in [1usize, 2] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            for size in [1280u32, 8192] {
                let r = pool.install(|| time_phases(runs, || rw(&sample, size)));
                let w = pool.install(|| time_phases(runs, || wang(&sample, size, Cut::Dp)));
                let ws = pool.install(|| time_phases(runs, || wang(&sample, size, Cut::ShortestPath)));
                for (label, (b, f)) in [("rw-tiles", r), ("wang-tiles, dp cut", w), ("wang-tiles, shortest-path cut", ws)] {
                    println!(
                        "{name:<16} {size:>4}x{size:<4} {threads} thread(s)  {label:<30} build {b:>8.4} s (ratio {:>5.2})  fill {f:>8.4} s (ratio {:>5.2})  total {:>8.4} s",
                        b / r.0,
                        f / r.1,
                        b + f
                    );
                }
            }
            if name == "pebbles_beige" {
                // Image quilting for a comparable output (block 64 = the tile size) vs the whole
                // synthesis call of each tile method.
                let call = |method: &str, extra: &[(&str, ParamValue)]| -> f64 {
                    let m = find(method).unwrap();
                    let mut given: Vec<(String, ParamValue)> = extra.iter().map(|(k, v)| (k.to_string(), v.clone())).collect();
                    if method != "quilting" {
                        given.push(("tile".into(), ParamValue::Int(64)));
                    }
                    let params = resolve(m.params(), &given).unwrap();
                    let req = Request {
                        sample: &sample,
                        width: 1280,
                        height: 1280,
                        params: &params,
                        seed: 1,
                        placement: false,
                        tileable: false,
                        constraints: Default::default(),
                    };
                    let n = if method == "quilting" { quilt_runs } else { runs };
                    if method != "quilting" {
                        pool.install(|| m.synthesize(&req).unwrap());
                    }
                    median(
                        (0..n)
                            .map(|_| {
                                let t = Instant::now();
                                pool.install(|| m.synthesize(&req).unwrap());
                                t.elapsed().as_secs_f64()
                            })
                            .collect(),
                    )
                };
                let q = call("quilting", &[("block", ParamValue::Int(64))]);
                let r = call("rw-tiles", &[]);
                let w = call("wang-tiles", &[]);
                println!("{name:<16} 1280x1280 {threads} thread(s)  image quilting (block 64)      {q:>8.4} s");
                println!(
                    "{name:<16} 1280x1280 {threads} thread(s)  rw-tiles, whole call           {r:>8.4} s  quilting / rw-tiles {:>8.1}",
                    q / r
                );
                println!(
                    "{name:<16} 1280x1280 {threads} thread(s)  wang-tiles, whole call         {w:>8.4} s  quilting / wang-tiles {:>6.1}",
                    q / w
                );
            }
        }
    }
}

/// Issue #30's judgement: each tile method with its defaults against image quilting with its
/// defaults, whole synthesis calls on all cores (medians of `runs`, quilting of `quilt_runs`),
/// on whole 256² samples at 512² and 2048²: time, the ratio quilting / method, repetition and
/// the ratio method / quilting, and whether both criteria hold (repetition ≤ 2× quilting's;
/// at 2048² at least 10× faster). weathered wood's features are large: its tiles are toned
/// (`tone = "auto"`), which the time includes.
fn defaults(runs: usize, quilt_runs: usize) {
    let samples = Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/samples");
    println!("issue #30: defaults, whole synthesis calls (median of {runs}; quilting of {quilt_runs}), all cores");
    for name in ["grass_gray", "gravel_gray", "pebbles_beige", "wood_weathered"] {
        let (sample, _) = read_rgb8(&samples.join(format!("{name}.png")), DecodeLimits::default()).unwrap();
        println!("{name:<14} sample itself: repetition {:.3}", max_autocorrelation(&sample).unwrap());
        for size in [512u32, 2048] {
            let call = |method: &str, n: usize| -> (f64, f64) {
                let m = find(method).unwrap();
                let params = resolve(m.params(), &[]).unwrap();
                let req = Request {
                    sample: &sample,
                    width: size,
                    height: size,
                    params: &params,
                    seed: 1,
                    placement: false,
                    tileable: false,
                    constraints: Default::default(),
                };
                let image = m.synthesize(&req).unwrap().image;
                let secs = median(
                    (0..n)
                        .map(|_| {
                            let t = Instant::now();
                            m.synthesize(&req).unwrap();
                            t.elapsed().as_secs_f64()
                        })
                        .collect(),
                );
                (secs, max_autocorrelation(&image).unwrap())
            };
            let (q, qr) = call("quilting", quilt_runs);
            println!("{name:<14} {size:>4}x{size:<4} quilting    {q:>8.4} s  repetition {qr:.3}");
            for method in ["rw-tiles", "wang-tiles"] {
                let (t, r) = call(method, runs);
                let (speed, rep) = (q / t, r / qr);
                let ok = rep <= 2.0 && (size < 2048 || speed >= 10.0);
                println!(
                    "{name:<14} {size:>4}x{size:<4} {method:<11} {t:>8.4} s  repetition {r:.3}  quilting/method time {speed:>6.1}x  repetition/quilting's {rep:>5.2}  {}",
                    if ok { "ok" } else { "FAILS" }
                );
            }
        }
    }
}
