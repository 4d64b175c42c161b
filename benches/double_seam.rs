//! Paper 003's speed claim, measured in one run: double-seam splicing vs image quilting at the
//! same block size and grid (block 50 → 386×386 and block 100 → 764×764 from the 256×256
//! `bricks_gray` sample), on 1 and 2 threads. Quilting is measured twice: with its FFT search
//! (ours) and with direct SSD sums (how the paper's baseline searches). Each configuration runs
//! `TEXSYN_BENCH_RUNS` times (default 3); the median and the ratios to double-seam are printed.
//! `cargo bench --bench double_seam`. (No criterion here: the direct quilting runs take seconds
//! each, and ratios within one run are what matter on a noisy machine.)

use std::path::Path;
use std::time::Instant;
use texsyn::image::io::{DecodeLimits, read_rgb8};
use texsyn::synth::method::Request;
use texsyn::synth::methods::find;
use texsyn::synth::params::{ParamValue, resolve};

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return; // `cargo test --benches` probes with --list
    }
    let runs: usize = std::env::var("TEXSYN_BENCH_RUNS").ok().and_then(|v| v.parse().ok()).unwrap_or(3).max(1);
    let (sample, _) =
        read_rgb8(&Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/samples/bricks_gray.png"), DecodeLimits::default()).unwrap();
    println!("median of {runs} runs, seconds; ratio = time / double-seam time in the same configuration");
    for threads in [1usize, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        for (block, overlap, size) in [(50i64, 8i64, 386u32), (100, 17, 764)] {
            let mut rows = Vec::new();
            for (label, method, search) in [
                ("double-seam", "double-seam", None),
                ("quilting, fft search", "quilting", Some("fft")),
                ("quilting, direct search", "quilting", Some("direct")),
            ] {
                let m = find(method).unwrap();
                let mut given = vec![("block".to_string(), ParamValue::Int(block)), ("overlap".to_string(), ParamValue::Int(overlap))];
                if let Some(s) = search {
                    given.push(("search".to_string(), ParamValue::Str(s.into())));
                }
                let params = resolve(m.params(), &given).unwrap();
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
                let mut times: Vec<f64> = (0..runs)
                    .map(|_| {
                        let t = Instant::now();
                        pool.install(|| m.synthesize(&req).unwrap());
                        t.elapsed().as_secs_f64()
                    })
                    .collect();
                times.sort_by(|a, b| a.partial_cmp(b).unwrap());
                rows.push((label, times[times.len() / 2]));
            }
            let ds = rows[0].1;
            for (label, t) in rows {
                println!("{size}x{size} block {block:>3}, {threads} thread(s)  {label:<24} {t:>8.3} s  ratio {:>6.2}", t / ds);
            }
        }
    }
}
