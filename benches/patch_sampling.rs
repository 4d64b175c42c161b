//! Patch-sampling speed (paper 002, docs/methods.md §4): 386×386 from the 256×256 bundled sample
//! `pebbles_beige`, paper defaults (block 30, 20 particles, 300 iterations, delta_rms 10), for each
//! search (chaos PSO, PSO, exhaustive FFT + exact re-check with tolerance 0 and with Liang's 0.2) on 1
//! and 2 threads. Run with `cargo bench --bench patch_sampling`.
//!
//! Swarm searches use the second thread through the wave schedule (blocks with equal 2·bi + bj are
//! searched in parallel); exhaustive search through the FFT and the re-check. The pixels are the
//! same on any number of threads.

use criterion::{Criterion, criterion_group, criterion_main};
use std::path::Path;
use texsyn::image::io::{DecodeLimits, read_rgb8};
use texsyn::synth::method::Request;
use texsyn::synth::methods::find;
use texsyn::synth::params::{ParamValue, resolve};

fn bench(c: &mut Criterion) {
    let sample_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/samples/pebbles_beige.png");
    let (sample, _) = read_rgb8(&sample_path, DecodeLimits::default()).expect("bundled sample");
    let method = find("patch-sampling").unwrap();
    let configs: [(&str, Vec<(&str, ParamValue)>); 4] = [
        ("cpso", vec![("search", ParamValue::Str("cpso".into()))]),
        ("pso", vec![("search", ParamValue::Str("pso".into()))]),
        ("exhaustive best", vec![("search", ParamValue::Str("exhaustive".into())), ("tolerance", ParamValue::Float(0.0))]),
        ("exhaustive liang 0.2", vec![("search", ParamValue::Str("exhaustive".into()))]),
    ];
    let mut group = c.benchmark_group("patch-sampling 386x386 from 256x256, block 30");
    group.sample_size(10);
    for (name, given) in &configs {
        let given: Vec<(String, ParamValue)> = given.iter().map(|(k, v)| (k.to_string(), v.clone())).collect();
        let params = resolve(method.params(), &given).unwrap();
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            group.bench_function(format!("{name}, {threads} thread(s)"), |b| {
                b.iter(|| {
                    pool.install(|| {
                        method
                            .synthesize(&Request {
                                sample: &sample,
                                width: 386,
                                height: 386,
                                params: &params,
                                seed: 1,
                                placement: false,
                                tileable: false,
                                constraints: Default::default(),
                            })
                            .unwrap()
                    })
                })
            });
        }
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
