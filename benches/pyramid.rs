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

use std::path::Path;
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
    let base = bundled("pebbles_beige.png");
    println!("quilting, defaults (block 50), 2 threads; sample: pebbles_beige enlarged to each size");
    println!(
        "{:>11} {:>6} | {:>9} {:>9} {:>7} | pyramid / exact: {:>8} {:>8} {:>8} {:>8}",
        "sample", "output", "exact s", "pyramid s", "ratio", MEASURES[0], MEASURES[1], MEASURES[2], MEASURES[3]
    );
    for (w, h) in [(256, 256), (1024, 1024), (2048, 2048), (4000, 3000)] {
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

    // Quality over several real samples: each enlarged to 1024², 512² outputs.
    println!("\nquality, 1024² samples (bundled, enlarged 4x), 512² outputs, seeds 1-2: measure means");
    let names = ["pebbles_beige.png", "bricks_gray.png", "cork.png", "grass_gray.png", "wood_weathered.png", "tiles_terracotta.png"];
    let (mut sum_e, mut sum_p, mut runs) = ([0.0f64; 4], [0.0f64; 4], 0.0);
    for name in names {
        let sample = resized(&bundled(name), 1024, 1024);
        for seed in [1, 2] {
            let (e, te) = pool.install(|| quilt(&sample, Engine::Fft, 512, seed));
            let (p, tp) = pool.install(|| quilt(&sample, Engine::Pyramid, 512, seed));
            let (me, mp) = (measures(&sample, &e), measures(&sample, &p));
            println!("{name:>22} seed {seed}: exact {te:.2} s {me:.4?}; pyramid {tp:.2} s {mp:.4?}");
            for k in 0..4 {
                sum_e[k] += me[k];
                sum_p[k] += mp[k];
            }
            runs += 1.0;
        }
    }
    for k in 0..4 {
        println!(
            "{:>16}: exact mean {:.4}, pyramid mean {:.4}, pyramid / exact {:.3}",
            MEASURES[k],
            sum_e[k] / runs,
            sum_p[k] / runs,
            sum_p[k] / sum_e[k]
        );
    }
}
