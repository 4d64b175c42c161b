//! Issue 32: the exact search against the coarse-to-fine one (`search = "fft"` vs `"pyramid"`),
//! quilting with its defaults (block 50), side by side in one run, on two threads.
//!
//! Samples are made here from the bundled ones (the repository holds no photo): a bundled 256²
//! sample enlarged (bilinear) to 256², 1024², 2048² and 4000×3000 (a 12 MP "camera photo", 16×
//! cropped), as issue 32 measured, each to 1024² and 2048² outputs. Printed: seconds of each search and
//! their ratio, and paper 003's four measures (`texsyn eval`: gray and orientation histogram KL,
//! gray and orientation ACF distance) of the pyramid's output over the exact one's. Then the
//! quality over several bundled samples (each enlarged to 1024², 512² outputs): the mean of each measure,
//! pyramid over exact (the goal: within 10 %).
//!
//! `cargo bench --bench pyramid`. The exact search of a big sample takes minutes (2048² sample to
//! a 2048² output: about 150 s; 12 MP: several minutes), so by default it runs only where the
//! sample's pixels times the output's are at most 1024²·2048²; `TEXSYN_PYRAMID_ALL=1` runs every
//! exact case. `TEXSYN_PYRAMID_PNG=DIR` writes the 12 MP sample's outputs there, to look at.

use std::path::{Path, PathBuf};
use std::time::Instant;
use texsyn::synth::methods::Engine;
use texsyn::{QuiltingConfig, RgbImage, Synthesizer};

/// `img` enlarged `factor`× by bilinear interpolation (pixel centres aligned).
fn enlarge(img: &RgbImage, factor: u32) -> RgbImage {
    let (w, h) = img.dimensions();
    let at = |v: f64, n: u32| -> (u32, u32, f64) {
        let c = v.clamp(0.0, f64::from(n - 1));
        let i = (c.floor() as u32).min(n - 1);
        (i, (i + 1).min(n - 1), c - f64::from(i))
    };
    RgbImage::from_fn(w * factor, h * factor, |x, y| {
        let (x0, x1, fx) = at((f64::from(x) + 0.5) / f64::from(factor) - 0.5, w);
        let (y0, y1, fy) = at((f64::from(y) + 0.5) / f64::from(factor) - 0.5, h);
        let mut p = [0u8; 3];
        for (c, v) in p.iter_mut().enumerate() {
            let g = |x: u32, y: u32| f64::from(img.get(x, y)[c]);
            let top = g(x0, y0) * (1.0 - fx) + g(x1, y0) * fx;
            let bottom = g(x0, y1) * (1.0 - fx) + g(x1, y1) * fx;
            *v = (top * (1.0 - fy) + bottom * fy).round() as u8;
        }
        p
    })
}

/// `img` enlarged by the smallest whole factor that covers `w × h`, cropped to it: the issue's
/// protocol (one sample "resized to each size"), without the repeats a tiling would add.
fn resized(img: &RgbImage, w: u32, h: u32) -> RgbImage {
    let factor = w.div_ceil(img.width()).max(h.div_ceil(img.height()));
    enlarge(img, factor).crop(0, 0, w, h)
}

fn bundled(name: &str) -> RgbImage {
    texsyn::load_image(Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/samples").join(name)).expect("bundled sample")
}

/// One quilting run with `search`, on the current pool: (output, seconds).
fn quilt(sample: &RgbImage, search: Engine, size: u32, seed: u64) -> (RgbImage, f64) {
    let config = QuiltingConfig { search, ..QuiltingConfig::default() };
    let session = Synthesizer::new(config).seed(seed).size(size, size).build(sample).expect("valid parameters");
    let t = Instant::now();
    let out = session.run().expect("synthesis");
    (out.image, t.elapsed().as_secs_f64())
}

const MEASURES: [&str; 4] = ["kl_gray", "kl_orientation", "acf_gray", "acf_orientation"];

/// Paper 003's four measures of `output` against `sample`.
fn measures(sample: &RgbImage, output: &RgbImage) -> [f64; 4] {
    let m = texsyn::metrics::evaluate(&MEASURES, sample, output, None).expect("known metrics");
    MEASURES.map(|k| m[k].unwrap_or(f64::NAN))
}

fn main() {
    let all = std::env::var_os("TEXSYN_PYRAMID_ALL").is_some();
    let png = std::env::var_os("TEXSYN_PYRAMID_PNG").map(std::path::PathBuf::from);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().expect("pool");
    // `TEXSYN_PYRAMID_PART=timing` or `quality` runs one part only.
    let part = std::env::var("TEXSYN_PYRAMID_PART").ok();
    let base = bundled("pebbles_beige.png");
    println!("quilting, defaults (block 50), 2 threads; sample: pebbles_beige enlarged to each size");
    println!(
        "{:>11} {:>6} | {:>9} {:>9} {:>7} | pyramid / exact: {:>8} {:>8} {:>8} {:>8}",
        "sample", "output", "exact s", "pyramid s", "ratio", MEASURES[0], MEASURES[1], MEASURES[2], MEASURES[3]
    );
    let timing = if part.as_deref() == Some("quality") { vec![] } else { vec![(256, 256), (1024, 1024), (2048, 2048), (4000, 3000)] };
    for (w, h) in timing {
        let sample = resized(&base, w, h);
        for size in [1024u32, 2048] {
            let (pyr, tp) = pool.install(|| quilt(&sample, Engine::Pyramid, size, 1));
            let run_exact = all || u64::from(w) * u64::from(h) * u64::from(size) * u64::from(size) <= (1024 * 1024) * (2048 * 2048);
            let exact = run_exact.then(|| pool.install(|| quilt(&sample, Engine::Fft, size, 1)));
            if let Some(dir) = png.as_ref().filter(|_| w == 4000) {
                std::fs::create_dir_all(dir).expect("png dir");
                texsyn::save_image(&pyr, dir.join(format!("pyramid_{size}.png"))).expect("png");
                if let Some((e, _)) = &exact {
                    texsyn::save_image(e, dir.join(format!("exact_{size}.png"))).expect("png");
                }
            }
            let mp = measures(&sample, &pyr);
            match exact {
                Some((e, te)) => {
                    let me = measures(&sample, &e);
                    let r: Vec<String> = mp.iter().zip(&me).map(|(p, e)| format!("{:>8.3}", p / e)).collect();
                    println!("{:>11} {:>6} | {te:>9.2} {tp:>9.2} {:>6.1}x | {}", format!("{w}x{h}"), size, te / tp, r.join(" "));
                }
                None => println!(
                    "{:>11} {:>6} | {:>9} {tp:>9.2} {:>7} | (exact not run: TEXSYN_PYRAMID_ALL=1)",
                    format!("{w}x{h}"),
                    size,
                    "-",
                    "-"
                ),
            }
        }
    }

    if let Some(dir) = std::env::var_os("TEXSYN_PYRAMID_PHOTOS").filter(|_| part.is_none() || part.as_deref() == Some("photos")) {
        photos(Path::new(&dir), &pool, all, png.as_deref());
    }
    if part.as_deref().is_some_and(|p| p != "quality") {
        return;
    }
    // Quality over the real samples: every bundled one (jobs/samples/*.png and the materials'
    // albedos) and those in `TEXSYN_PYRAMID_SAMPLES=DIR` (optional, *.png), each enlarged to the
    // sample size; per sample the four measures' ratios pyramid / exact, then their mean over the
    // samples (the goal: within 10 %, i.e. at most 1.10).
    let mut files: Vec<PathBuf> = Vec::new();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/samples");
    let dirs = [Some(root.clone()), Some(root.join("materials")), std::env::var_os("TEXSYN_PYRAMID_SAMPLES").map(PathBuf::from)];
    for dir in dirs.into_iter().flatten() {
        let mut here: Vec<PathBuf> = std::fs::read_dir(&dir)
            .expect("samples dir")
            .map(|e| e.expect("dir entry").path())
            .filter(|p| p.extension().is_some_and(|e| e == "png"))
            .filter(|p| !p.to_string_lossy().contains("_normal") && !p.to_string_lossy().contains("_gloss"))
            .collect();
        here.sort();
        if let Ok(only) = std::env::var("TEXSYN_PYRAMID_ONLY") {
            here.retain(|p| only.split(',').any(|n| p.file_stem().is_some_and(|s| s.to_string_lossy() == n)));
        }
        files.extend(here);
    }
    // (sample side, output side, how many samples): 2048² samples cost ~40 s per exact run.
    let seeds: Vec<u64> =
        std::env::var("TEXSYN_PYRAMID_SEEDS").map_or(vec![1], |v| v.split(',').map(|s| s.parse().expect("seed")).collect());
    let big: usize = std::env::var("TEXSYN_PYRAMID_BIG").ok().and_then(|v| v.parse().ok()).unwrap_or(4);
    for (side, size, count) in [(1024u32, 512u32, files.len()), (2048, 1024, big.min(files.len()))] {
        if count == 0 {
            continue;
        }
        println!("\nquality, samples enlarged to {side}², {size}² outputs, seeds {seeds:?}: measures pyramid / exact");
        let (mut sum_r, mut sum_e, mut sum_p, mut runs) = ([0.0f64; 4], [0.0f64; 4], [0.0f64; 4], 0.0);
        let (mut te_all, mut tp_all) = (0.0, 0.0);
        // For the 2048² row, samples spread over the list (every k-th).
        let step = files.len() / count;
        for file in files.iter().step_by(step.max(1)).take(count) {
            let name = file.file_name().expect("file name").to_string_lossy().to_string();
            let sample = resized(&texsyn::load_image(file).expect("sample"), side, side);
            for &seed in &seeds {
                let (e, te) = pool.install(|| quilt(&sample, Engine::Fft, size, seed));
                let (p, tp) = pool.install(|| quilt(&sample, Engine::Pyramid, size, seed));
                if let Some(dir) = &png {
                    std::fs::create_dir_all(dir).expect("png dir");
                    let stem = name.trim_end_matches(".png");
                    texsyn::save_image(&e, dir.join(format!("{stem}_{side}_{seed}_exact.png"))).expect("png");
                    texsyn::save_image(&p, dir.join(format!("{stem}_{side}_{seed}_pyramid.png"))).expect("png");
                }
                let (me, mp) = (measures(&sample, &e), measures(&sample, &p));
                let r: [f64; 4] = std::array::from_fn(|k| mp[k] / me[k]);
                println!(
                    "{name:>26} {seed}: exact {te:>6.2} s, pyramid {tp:>5.2} s | {} | exact {me:.4?} pyramid {mp:.4?}",
                    r.map(|v| format!("{v:>6.3}")).join(" ")
                );
                for k in 0..4 {
                    sum_r[k] += r[k];
                    sum_e[k] += me[k];
                    sum_p[k] += mp[k];
                }
                runs += 1.0;
                te_all += te;
                tp_all += tp;
            }
        }
        let means = sum_r.map(|s| s / runs);
        println!(
            "{:>26}: exact {te_all:>6.1} s, pyramid {tp_all:>5.1} s | {} | mean of the four {:.3}",
            format!("mean over {runs} runs"),
            means.map(|v| format!("{v:>6.3}")).join(" "),
            means.iter().sum::<f64>() / 4.0
        );
        let sums: [f64; 4] = std::array::from_fn(|k| sum_p[k] / sum_e[k]);
        println!(
            "{:>26}: {} | mean of the four {:.3}",
            "ratio of the sums",
            sums.map(|v| format!("{v:>6.3}")).join(" "),
            sums.iter().sum::<f64>() / 4.0
        );
    }
}

/// Real photos at their own scale (`TEXSYN_PYRAMID_PHOTOS=DIR`, *.png; the repository holds none,
/// and enlarged bundled samples have no detail finer than their 256² originals): each photo whole
/// (cropped to at most 4000×3000) and its centre 1024² crop, exact and pyramid side by side.
/// Outputs: 1024² (`TEXSYN_PYRAMID_PHOTO_SIZES=1024,2048` adds others; the exact search of a
/// multi-megapixel sample to a 2048² output takes minutes, so there it runs only with
/// `TEXSYN_PYRAMID_ALL=1`). Per row: seconds, their ratio, the four measures pyramid / exact; per
/// group, the mean ratio of each measure and their mean (the goal: at most 1.10).
fn photos(dir: &Path, pool: &rayon::ThreadPool, all: bool, png: Option<&Path>) {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .expect("photos dir")
        .map(|e| e.expect("dir entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    files.sort();
    let sizes: Vec<u32> =
        std::env::var("TEXSYN_PYRAMID_PHOTO_SIZES").map_or(vec![1024], |v| v.split(',').map(|s| s.parse().expect("output size")).collect());
    let seed = 1;
    println!("\nreal photos at their own scale, quilting defaults, seed {seed}: measures pyramid / exact");
    for whole in [true, false] {
        let (mut sum_r, mut runs, mut te_all, mut tp_all) = ([0.0f64; 4], 0.0, 0.0, 0.0);
        for file in &files {
            let name = file.file_stem().expect("file name").to_string_lossy().to_string();
            let photo = texsyn::load_image(file).expect("photo");
            let (w, h) = photo.dimensions();
            let sample = if whole {
                photo.crop(0, 0, w.min(4000), h.min(3000))
            } else if w >= 1024 && h >= 1024 {
                photo.crop((w - 1024) / 2, (h - 1024) / 2, 1024, 1024)
            } else {
                continue;
            };
            let (sw, sh) = sample.dimensions();
            for &size in &sizes {
                let (p, tp) = pool.install(|| quilt(&sample, Engine::Pyramid, size, seed));
                let run_exact = all || size <= 1024;
                let exact = run_exact.then(|| pool.install(|| quilt(&sample, Engine::Fft, size, seed)));
                if let Some(dir) = png {
                    std::fs::create_dir_all(dir).expect("png dir");
                    texsyn::save_image(&p, dir.join(format!("{name}_{sw}x{sh}_{size}_pyramid.png"))).expect("png");
                    if let Some((e, _)) = &exact {
                        texsyn::save_image(e, dir.join(format!("{name}_{sw}x{sh}_{size}_exact.png"))).expect("png");
                    }
                }
                let mp = measures(&sample, &p);
                let Some((e, te)) = exact else {
                    println!(
                        "{name:>22} {:>9} {size:>5}: exact -, pyramid {tp:>6.2} s (exact not run: TEXSYN_PYRAMID_ALL=1)",
                        format!("{sw}x{sh}")
                    );
                    continue;
                };
                let me = measures(&sample, &e);
                let r: [f64; 4] = std::array::from_fn(|k| mp[k] / me[k]);
                println!(
                    "{name:>22} {:>9} {size:>5}: exact {te:>7.2} s, pyramid {tp:>6.2} s, {:>5.1}x | {} | exact {me:.4?} pyramid {mp:.4?}",
                    format!("{sw}x{sh}"),
                    te / tp,
                    r.map(|v| format!("{v:>6.3}")).join(" ")
                );
                for k in 0..4 {
                    sum_r[k] += r[k];
                }
                runs += 1.0;
                te_all += te;
                tp_all += tp;
            }
        }
        if runs > 0.0 {
            let means = sum_r.map(|s| s / runs);
            println!(
                "{:>38}: exact {te_all:>7.1} s, pyramid {tp_all:>6.1} s | {} | mean of the four {:.3}",
                format!("{} mean over {runs} runs", if whole { "whole photos" } else { "1024² crops" }),
                means.map(|v| format!("{v:>6.3}")).join(" "),
                means.iter().sum::<f64>() / 4.0
            );
        }
    }
}
