//! Image quilting speed: 512×512 from a 256×256 bundled sample (block 40, overlap 10, tolerance
//! 0.1) on 1 and 2 threads, plus the same search done by brute force for the ratio. Run with
//! `cargo bench --bench quilting`; the target is well under one second on one core.

use criterion::{Criterion, criterion_group, criterion_main};
use std::path::Path;
use texsyn::synth::primitives::overlap::Rect;
use texsyn::synth::primitives::overlap_search::OverlapSearch;
use texsyn::{QuiltingConfig, Synthesizer};

fn bench(c: &mut Criterion) {
    let sample = texsyn::load_image(Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/samples/pebbles_beige.png")).expect("bundled sample");
    let config = QuiltingConfig { block: 40, overlap: Some(10), tolerance: 0.1, ..QuiltingConfig::default() };
    let session = Synthesizer::new(config).seed(1).size(512, 512).build(&sample).expect("valid parameters");
    let mut group = c.benchmark_group("quilting 512x512 from 256x256, block 40");
    group.sample_size(10);
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        group.bench_function(format!("{threads} thread(s)"), |b| b.iter(|| pool.install(|| session.run().unwrap())));
    }
    group.finish();

    // One block's search, fast (FFT + exact re-check) vs brute force, single thread.
    let target = sample.crop(0, 0, 60, 60);
    let regions = [Rect::new(0, 0, 10, 40), Rect::new(10, 0, 30, 10)];
    let mut search = OverlapSearch::new(&sample, 40, 40);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let mut group = c.benchmark_group("one L-shaped block search, 1 thread");
    group.sample_size(10);
    group.bench_function("fft + exact recheck", |b| b.iter(|| pool.install(|| search.candidates(&target, (13, 17), &regions, 0.1))));
    group.bench_function("brute force", |b| b.iter(|| pool.install(|| search.candidates_direct(&target, (13, 17), &regions, 0.1))));
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
