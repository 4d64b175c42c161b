//! Paper 003's speed claim, measured in one run: double-seam splicing vs image quilting at the
//! same block size and grid (block 50 → 386×386 and block 100 → 764×764 from a 256×256 structured
//! sample). Quilting is measured twice: with its FFT search (ours) and with direct SSD sums (how
//! the paper's baseline searches). `cargo bench --bench double_seam`; criterion prints the times,
//! and the ratios are printed at the end from medians of the same run.

use criterion::{Criterion, criterion_group, criterion_main};
use std::path::Path;
use std::time::Instant;
use texsyn::imageio::{DecodeLimits, read_rgb8};
use texsyn::methods::{Request, find};
use texsyn::params::{ParamValue, resolve};

fn bench(c: &mut Criterion) {
    let (sample, _) = read_rgb8(&Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/samples/bricks_gray.png"), DecodeLimits::default()).unwrap();
    let mut medians: Vec<(String, f64)> = Vec::new();
    for threads in [1usize, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        for (block, overlap, size) in [(50i64, 8i64, 386u32), (100, 17, 764)] {
            let mut group = c.benchmark_group(format!("{size}x{size} block {block}, {threads} thread(s)"));
            group.sample_size(10);
            for (label, method, extra) in [
                ("double-seam", "double-seam", None),
                ("quilting (fft search)", "quilting", Some("fft")),
                ("quilting (direct search)", "quilting", Some("direct")),
            ] {
                let m = find(method).unwrap();
                let mut given = vec![("block".to_string(), ParamValue::Int(block)), ("overlap".to_string(), ParamValue::Int(overlap))];
                if let Some(s) = extra {
                    given.push(("search".to_string(), ParamValue::Str(s.into())));
                }
                let params = resolve(m.params(), &given).unwrap();
                let req = Request { sample: &sample, width: size, height: size, params: &params, seed: 1 };
                group.bench_function(label, |b| b.iter(|| pool.install(|| m.synthesize(&req).unwrap())));
                let mut times: Vec<f64> = (0..3)
                    .map(|_| {
                        let t = Instant::now();
                        pool.install(|| m.synthesize(&req).unwrap());
                        t.elapsed().as_secs_f64()
                    })
                    .collect();
                times.sort_by(|a, b| a.partial_cmp(b).unwrap());
                medians.push((format!("{size} b{block} {threads}t {label}"), times[1]));
            }
            group.finish();
        }
    }
    println!("\nmedian of 3 (s), and quilting / double-seam ratios:");
    for chunk in medians.chunks(3) {
        let ds = chunk[0].1;
        for (name, t) in chunk {
            println!("  {name:<45} {t:>8.3}  ratio {:>6.2}", t / ds);
        }
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
