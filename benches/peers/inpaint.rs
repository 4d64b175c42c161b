//! Inpainting and texture transfer against Embark's `--inpaint` and `transfer-style` (issue #28),
//! part of the peers bench:
//!
//!     cargo bench --bench peers -- inpaint     # only this part (with the transfer)
//!     cargo bench --bench peers -- transfer    # only the transfer
//!
//! Each bundled sample gets a round hole (radius 40 px, off centre) painted magenta, so that
//! neither program can copy what was there. A second table does the same at 512² (each sample
//! enlarged 2×, bilinear) with a radius-80 hole, where the fill, not the fixed costs of a process
//! (start, plan, the sample's advice, hashing, writing), is most of the time. texsyn runs quilting with its defaults on an
//! `[inpaint]` job (`-j 1`), and patch sampling with its defaults on the same (a second row); Embark runs `--inpaint KEEP --sample-masks KEEP -t 1` (its masks are
//! white = keep), both as whole processes. Quality is paper 003's four measures (lower is better)
//! between the intact sample and the 48 × 48 square at the hole's centre, which both programs
//! filled: how much the filled texture is the sample's. The table prints both and their ratios;
//! the summary counts the samples on which texsyn's measures (summed, each scaled by Embark's)
//! are as good or better.

use std::path::{Path, PathBuf};
use std::process::Command;
use texsyn::RgbImage;

const SAMPLES: [&str; 8] =
    ["pebbles_beige", "cork", "grass_gray", "gravel_gray", "hedge_leaves", "roughcast_plaster", "wood_weathered", "bricks_gray"];
/// (enlargement, hole radius, side of the measured square): the 256² samples, then 512² ones.
const SIZES: [(u32, i64, u32); 2] = [(1, 40, 48), (2, 80, 96)];

fn quality(sample: &RgbImage, filled: &RgbImage, centre: (u32, u32), crop: u32) -> [f64; 4] {
    measures(sample, &filled.crop(centre.0 - crop / 2, centre.1 - crop / 2, crop, crop))
}

/// `img` enlarged `f` times, bilinear (pixel centres aligned, edges clamped).
fn enlarged(img: &RgbImage, f: u32) -> RgbImage {
    if f == 1 {
        return img.clone();
    }
    let (w, h) = img.dimensions();
    RgbImage::from_fn(w * f, h * f, |x, y| {
        let at = |v: u32, n: u32| ((f64::from(v) + 0.5) / f64::from(f) - 0.5).clamp(0.0, f64::from(n - 1));
        let (fx, fy) = (at(x, w), at(y, h));
        let (x0, y0) = (fx as u32, fy as u32);
        let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
        let (ax, ay) = (fx - f64::from(x0), fy - f64::from(y0));
        let (a, b, c, d) = (img.get(x0, y0), img.get(x1, y0), img.get(x0, y1), img.get(x1, y1));
        std::array::from_fn(|k| {
            let top = f64::from(a[k]) * (1.0 - ax) + f64::from(b[k]) * ax;
            let bottom = f64::from(c[k]) * (1.0 - ax) + f64::from(d[k]) * ax;
            (top * (1.0 - ay) + bottom * ay).round() as u8
        })
    })
}

/// Paper 003's four measures of `image` against `sample` (NaN where undefined).
pub fn measures(sample: &RgbImage, image: &RgbImage) -> [f64; 4] {
    [
        texsyn::metrics::kl_gray(sample, image).unwrap_or(f64::NAN),
        texsyn::metrics::kl_orientation(sample, image).unwrap_or(f64::NAN),
        texsyn::metrics::acf_gray(sample, image).unwrap_or(f64::NAN),
        texsyn::metrics::acf_orientation(sample, image).unwrap_or(f64::NAN),
    ]
}

pub fn run(work: &Path, embark: Option<&Path>, reps: usize, time: &dyn Fn(usize, &mut dyn FnMut() -> Command) -> Option<f64>) {
    for (scale, radius, crop) in SIZES {
        table(work, embark, reps, time, scale, radius, crop);
    }
}

/// One table: every sample enlarged `scale` times, a hole of `radius`, quality over the central `crop`².
fn table(
    work: &Path,
    embark: Option<&Path>,
    reps: usize,
    time: &dyn Fn(usize, &mut dyn FnMut() -> Command) -> Option<f64>,
    scale: u32,
    radius: i64,
    crop: u32,
) {
    let side = 256 * scale;
    let enlarged_how = if scale == 1 { String::new() } else { format!(" (the sample enlarged {scale}×, bilinear)") };
    println!(
        "\ninpainting a round hole (radius {radius}) in each {side}² sample{enlarged_how}, one thread; quality: paper 003's measures of the hole's"
    );
    println!("central {crop}² against the intact sample (lower is better); ratios texsyn / Embark (< 1: texsyn closer)\n");
    println!(
        "{:<20} {:>9} {:>9} {:>8}   {:>22} {:>22} {:>22} {:>22}",
        "sample", "texsyn s", "Embark s", "speed", "kl_gray t/E", "kl_orient t/E", "acf_gray t/E", "acf_orient t/E"
    );
    let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let (mut better, mut compared) = ([0; 2], 0);
    for s in SAMPLES {
        let dir = work.join(format!("inpaint{side}-{s}"));
        std::fs::create_dir_all(&dir).expect("bench dir");
        let sample = enlarged(&texsyn::load_image(repo.join(format!("jobs/samples/{s}.png"))).expect("bundled sample"), scale);
        let (w, h) = sample.dimensions();
        let centre = (w / 2 + 17 * scale, h / 2 - 11 * scale);
        let inside =
            |x: u32, y: u32| (i64::from(x) - i64::from(centre.0)).pow(2) + (i64::from(y) - i64::from(centre.1)).pow(2) <= radius * radius;
        let damaged = RgbImage::from_fn(w, h, |x, y| if inside(x, y) { [255, 0, 255] } else { sample.get(x, y) });
        texsyn::save_image(&damaged, dir.join("damaged.png")).expect("write");
        texsyn::save_image(&RgbImage::from_fn(w, h, |x, y| if inside(x, y) { [255; 3] } else { [0; 3] }), dir.join("fill.png"))
            .expect("write");
        texsyn::save_image(&RgbImage::from_fn(w, h, |x, y| if inside(x, y) { [0; 3] } else { [255; 3] }), dir.join("keep.png"))
            .expect("write");
        let mut texsyn_t = Vec::new();
        for method in ["quilting", "patch-sampling"] {
            let jobs = dir.join(format!("jobs-{method}"));
            std::fs::create_dir_all(&jobs).expect("jobs dir");
            std::fs::write(
                jobs.join("h.toml"),
                format!(
                    "method = \"{method}\"\nseed = 1\n[inpaint]\nimage = \"{}\"\nmask = \"{}\"\n[output]\npath = \"h.png\"\n",
                    dir.join("damaged.png").display(),
                    dir.join("fill.png").display()
                ),
            )
            .expect("job file");
            texsyn_t.push(time(reps, &mut || {
                let mut c = Command::new(env!("CARGO_BIN_EXE_texsyn"));
                c.arg("run").arg(&jobs).arg("-o").arg(dir.join(format!("out-{method}"))).args(["-j", "1", "-q", "--force"]);
                c
            }));
        }
        let embark_out = dir.join("embark.png");
        let embark_t = embark.and_then(|e| {
            time(reps, &mut || {
                let mut c = Command::new(e);
                c.args(["--no-progress", "--threads", "1", "--seed", "1", "--out-size", &format!("{w}x{h}")])
                    .arg("--inpaint")
                    .arg(dir.join("keep.png"))
                    .arg("--sample-masks")
                    .arg(dir.join("keep.png"))
                    .arg("-o")
                    .arg(&embark_out)
                    .arg("generate")
                    .arg(dir.join("damaged.png"));
                c
            })
        });
        let theirs = embark_t.and_then(|_| texsyn::load_image(&embark_out).ok()).map(|img| quality(&sample, &img, centre, crop));
        compared += usize::from(theirs.is_some());
        for (k, (method, tt)) in ["quilting", "patch-sampling"].into_iter().zip(texsyn_t).enumerate() {
            let row = if k == 0 { s.to_string() } else { "  patch-sampling".to_string() };
            let Some(tt) = tt else {
                println!("{row:<20} texsyn failed");
                continue;
            };
            let ours = quality(&sample, &texsyn::load_image(dir.join(format!("out-{method}/h.png"))).expect("texsyn output"), centre, crop);
            let cell = |i: usize| match theirs {
                Some(t) => format!("{:.3}/{:.3} {:>5.2}", ours[i], t[i], ours[i] / t[i]),
                None => format!("{:.3}/—", ours[i]),
            };
            let speed = embark_t.map(|e| format!("{:.1}×", e / tt)).unwrap_or_else(|| "—".into());
            let et = embark_t.map(|e| format!("{e:.3}")).unwrap_or_else(|| "—".into());
            println!("{row:<20} {tt:>9.3} {et:>9} {speed:>8}   {:>22} {:>22} {:>22} {:>22}", cell(0), cell(1), cell(2), cell(3));
            if let Some(t) = theirs {
                let score: f64 = (0..4).map(|i| ours[i] / t[i]).sum();
                if score <= 4.0 {
                    better[k] += 1;
                }
            }
        }
    }
    if compared > 0 {
        println!(
            "\ntexsyn's hole is as close to the sample as Embark's or closer (summed measure ratios ≤ 4) on {} of {compared} samples with quilting, {} with patch-sampling",
            better[0], better[1]
        );
    }
}

/// Luminance averaged over 16-pixel cells.
fn cells(img: &RgbImage) -> Vec<f64> {
    let (w, h) = img.dimensions();
    let mut v = Vec::new();
    for cy in 0..h / 16 {
        for cx in 0..w / 16 {
            let mut sum = 0.0;
            for y in cy * 16..cy * 16 + 16 {
                for x in cx * 16..cx * 16 + 16 {
                    let p = img.get(x, y);
                    sum += 0.299 * f64::from(p[0]) + 0.587 * f64::from(p[1]) + 0.114 * f64::from(p[2]);
                }
            }
            v.push(sum / 256.0);
        }
    }
    v
}

fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let cov: f64 = a.iter().zip(b).map(|(x, y)| (x - ma) * (y - mb)).sum();
    let va: f64 = a.iter().map(|x| (x - ma).powi(2)).sum();
    let vb: f64 = b.iter().map(|y| (y - mb).powi(2)).sum();
    cov / (va * vb).sqrt()
}

/// Texture transfer against Embark's `transfer-style`: the bundled rings target with three
/// samples, one thread; how closely the output's light and dark follow the target (correlation of
/// 16-pixel cell means) and, as a texture check, paper 003's gray and orientation KL divergences
/// of the output against the sample (lower: more of the sample's texture kept).
pub fn transfer(work: &Path, embark: Option<&Path>, reps: usize, time: &dyn Fn(usize, &mut dyn FnMut() -> Command) -> Option<f64>) {
    let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let target_path = repo.join("jobs/samples/guided/target_rings.png");
    let target = texsyn::load_image(&target_path).expect("bundled target");
    let (w, h) = target.dimensions();
    println!("\ntexture transfer onto jobs/samples/guided/target_rings.png ({w}x{h}), one thread; texsyn: quilting with its defaults");
    println!(
        "(a transfer's blocks 33, 22, 15; weight 0.7); Embark: transfer-style defaults. follow = correlation with the target (16-px cells)\n"
    );
    println!(
        "{:<16} {:>9} {:>9} {:>8}   {:>16} {:>16} {:>16}",
        "sample", "texsyn s", "Embark s", "speed", "follow t / E", "kl_gray t / E", "kl_orient t / E"
    );
    for s in ["pebbles_beige", "grass_gray", "cork"] {
        let dir = work.join(format!("transfer-{s}"));
        let jobs = dir.join("jobs");
        std::fs::create_dir_all(&jobs).expect("bench dir");
        let sample_path = repo.join(format!("jobs/samples/{s}.png"));
        std::fs::write(
            jobs.join("t.toml"),
            format!(
                "sample = \"{}\"\nmethod = \"quilting\"\nseed = 2\n[guide]\ntarget = \"{}\"\n[output]\npath = \"t.png\"\nwidth = {w}\nheight = {h}\n",
                sample_path.display(),
                target_path.display()
            ),
        )
        .expect("job file");
        let tt = time(reps, &mut || {
            let mut c = Command::new(env!("CARGO_BIN_EXE_texsyn"));
            c.arg("run").arg(&jobs).arg("-o").arg(dir.join("out")).args(["-j", "1", "-q", "--force"]);
            c
        });
        let embark_out = dir.join("embark.png");
        let et = embark.and_then(|e| {
            time(reps, &mut || {
                let mut c = Command::new(e);
                c.args(["--no-progress", "--threads", "1", "--seed", "2", "--out-size", &format!("{w}x{h}"), "-o"])
                    .arg(&embark_out)
                    .arg("transfer-style")
                    .arg("--style")
                    .arg(&sample_path)
                    .arg("--guide")
                    .arg(&target_path);
                c
            })
        });
        let Some(tt) = tt else {
            println!("{s:<16} texsyn failed");
            continue;
        };
        let sample = texsyn::load_image(&sample_path).expect("sample");
        let score = |img: &RgbImage| {
            (
                correlation(&cells(img), &cells(&target)),
                texsyn::metrics::kl_gray(&sample, img).unwrap_or(f64::NAN),
                texsyn::metrics::kl_orientation(&sample, img).unwrap_or(f64::NAN),
            )
        };
        let ours = score(&texsyn::load_image(dir.join("out/t.png")).expect("texsyn output"));
        let theirs = et.and_then(|_| texsyn::load_image(&embark_out).ok()).map(|i| score(&i));
        let pair = |a: f64, b: Option<f64>| b.map(|b| format!("{a:.3} / {b:.3}")).unwrap_or_else(|| format!("{a:.3} / —"));
        println!(
            "{s:<16} {tt:>9.3} {:>9} {:>8}   {:>16} {:>16} {:>16}",
            et.map(|e| format!("{e:.3}")).unwrap_or_else(|| "—".into()),
            et.map(|e| format!("{:.1}×", e / tt)).unwrap_or_else(|| "—".into()),
            pair(ours.0, theirs.map(|t| t.0)),
            pair(ours.1, theirs.map(|t| t.1)),
            pair(ours.2, theirs.map(|t| t.2)),
        );
    }
}
