//! Image quilting speed: 512×512 from a 256×256 bundled sample (block 40, overlap 10, tolerance
//! 0.1) on 1 and 2 threads, plus the same search done by brute force for the ratio. Run with
//! `cargo bench --bench quilting` (`TEXSYN_QUILT_RATIOS_ONLY=1` skips the criterion part).
//!
//! Then issue 13's two ratios, measured in the same run as whole `texsyn run` processes (median
//! of 3, `TEXSYN_QUILT_REPS` to change): the 512² block-40 job on one thread against the IPOL
//! image-quilting C program's 11 s on this protocol (measured at 10.8–12.5 s on the machine issue
//! 13 was filed on; it is not run here, so 11 s is a fixed reference that only holds on that
//! machine: `cargo bench --bench peers` estimates IPOL from Embark's time in the same run, which
//! is the ratio to trust), goal ≥ 100×; and one 2048² job
//! (defaults) on 1 and 2 threads, goal ≥ 1.7× (also shown: the manifest's synthesis seconds).

use criterion::{Criterion, criterion_group};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;
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

/// The IPOL image-quilting program's time on the 512² block-40 protocol, in seconds (a fixed
/// reference: measured at 10.8–12.5 s on the machine issue 13 was filed on, not installed here;
/// on a faster machine the ratio to it is inflated, see the peers bench).
const IPOL_SECONDS: f64 = 11.0;

/// A quilting job file of one output size on pebbles_beige; `params` go under `[params]`.
fn job(dir: &Path, size: u32, params: &str) -> PathBuf {
    let sample = Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/samples/pebbles_beige.png");
    let d = dir.join(format!("q{size}"));
    std::fs::create_dir_all(&d).expect("bench dir");
    let text = format!(
        "sample = \"{}\"\nmethod = \"quilting\"\nseed = 1\n[output]\npath = \"q.png\"\nwidth = {size}\nheight = {size}\n[params]\n{params}",
        sample.display()
    );
    std::fs::write(d.join("job.toml"), text).expect("job file");
    d
}

/// Median wall seconds of the whole process and median synthesis seconds from its manifest.
fn run(dir: &Path, threads: usize, reps: usize) -> (f64, f64) {
    let (mut wall, mut synthesis) = (Vec::new(), Vec::new());
    for _ in 0..reps {
        let out = dir.join("out");
        let t = Instant::now();
        let done = Command::new(env!("CARGO_BIN_EXE_texsyn"))
            .arg("run")
            .arg(dir)
            .arg("-o")
            .arg(&out)
            .args(["-j", &threads.to_string(), "-q", "--force"])
            .output()
            .expect("texsyn runs");
        wall.push(t.elapsed().as_secs_f64());
        assert!(done.status.success(), "texsyn run failed: {}", String::from_utf8_lossy(&done.stderr));
        let manifest: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("manifest.json")).expect("manifest")).expect("manifest is JSON");
        synthesis.push(manifest["jobs"][0]["timing"]["synthesis_seconds"].as_f64().expect("synthesis seconds"));
    }
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    (median(wall), median(synthesis))
}

fn ratios() {
    let reps: usize = std::env::var("TEXSYN_QUILT_REPS").ok().and_then(|s| s.parse().ok()).unwrap_or(3).max(1);
    let work = std::env::temp_dir().join(format!("texsyn-quilt-bench-{}", std::process::id()));
    let small = job(&work, 512, "block = 40\noverlap = 10\ntolerance = 0.1\n");
    let big = job(&work, 2048, "");
    println!("\nwhole processes, median of {reps}");
    let (t, synth) = run(&small, 1, reps);
    println!(
        "512² from 256², block 40, -j 1: {t:.3} s ({synth:.3} s synthesis); IPOL's {IPOL_SECONDS} s on the filing machine / this = {:.0}× (goal ≥ 100×; machine-dependent, the peers bench calibrates it by Embark)",
        IPOL_SECONDS / t
    );
    let (t1, s1) = run(&big, 1, reps);
    let (t2, s2) = run(&big, 2, reps);
    println!(
        "2048² from 256², defaults: -j 1 {t1:.3} s, -j 2 {t2:.3} s: {:.2}× (synthesis {s1:.3} s -> {s2:.3} s: {:.2}×; goal ≥ 1.7×)",
        t1 / t2,
        s1 / s2
    );
    let _ = std::fs::remove_dir_all(&work);
}

fn main() {
    if std::env::var_os("TEXSYN_QUILT_RATIOS_ONLY").is_none() {
        benches();
        Criterion::default().configure_from_args().final_summary();
    }
    ratios();
}
