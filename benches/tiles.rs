//! Paper 001's speed claim, measured in one run (docs/methods.md §3.9, B13): from the 128×128 crops of
//! `jobs/samples/crops/`, build 8 tiles of 64×64 and fill 1280×1280 (the paper: "under 2 s in
//! total") and 8192×8192, for RW-Tiles and for Cohen's Wang tiles (DP and shortest-path cuts),
//! on 1 and 2 threads; tile building and filling are timed separately. Image quilting (block 64,
//! its default overlap) at 1280×1280 from the same crop gives the "each method vs image quilting"
//! ratio. Medians of `TEXSYN_BENCH_RUNS` runs (default 5) after one warm-up; quilting runs
//! `TEXSYN_BENCH_QUILT_RUNS` times (default 1; it takes seconds).
//! `cargo bench --bench tiles`.

use std::path::Path;
use std::time::Instant;
use texsyn::RgbImage;
use texsyn::image::io::{DecodeLimits, read_rgb8};
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
