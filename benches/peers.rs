//! texsyn's methods against the peers, side by side, as whole processes (issue 13's protocol):
//! one thread, 512² outputs from 256² samples, block 40 / overlap 10 / tolerance 0.1 where a
//! method has them, defaults otherwise. Each program runs on the same samples in the same run,
//! and the table prints ratios, which is what survives a noisy 2-core machine.
//!
//!     cargo bench --bench peers               # 3 repetitions, median
//!     TEXSYN_PEERS_REPS=5 cargo bench --bench peers
//!
//! Embark's texture-synthesis CLI is the peer; install it with
//!
//!     cargo install --locked --version 0.8.3 texture-synthesis-cli --root <dir>
//!
//! and point `TEXSYN_EMBARK` at `<dir>/bin/texture-synthesis` (or put it on `PATH`). Without it
//! the Embark column is skipped, and the bench says so. Also measured: double-seam against exact
//! quilting at blocks 50 and 100 (paper 003's speed claim). Then camera-sized samples (issue 32,
//! [`big_samples`]): `TEXSYN_PEERS_PART=big` runs those only.
//!
//! The IPOL image-quilting program (Raad & Galerne 2017) is not installed here, so its time is
//! estimated from Embark's, measured in this run: issue 13 timed both on one machine (IPOL
//! 10.8–12.5 s, Embark 24.4–24.8 s on this protocol), and a fixed number of seconds would only
//! hold on that machine (on a faster one it inflates the ratio). `IPOL ≈ Embark × 11.0 / 24.6`.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

#[path = "peers/inpaint.rs"]
mod inpaint;
#[path = "peers/samples.rs"]
mod samples;

const SIZE: u32 = 512;
/// Structured and stochastic samples of 256², plus a near-regular one for the lattice methods.
const SAMPLES: [&str; 3] = ["pebbles_beige", "bricks_gray", "grass_gray"];
const LATTICE_SAMPLE: &str = "metal_tread_studs";
/// IPOL's time over Embark's on issue 13's protocol, both measured there on one machine (midpoints).
const IPOL_PER_EMBARK: f64 = 11.0 / 24.6;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn embark() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("TEXSYN_EMBARK") {
        return Some(PathBuf::from(p)).filter(|p| p.is_file());
    }
    std::env::split_paths(&std::env::var_os("PATH").unwrap_or_default()).map(|d| d.join("texture-synthesis")).find(|p| p.is_file())
}

/// Wall seconds of one whole process (the median of `reps` runs); `None` if it failed.
fn time(reps: usize, mut cmd: impl FnMut() -> Command) -> Option<f64> {
    let mut times = Vec::new();
    for _ in 0..reps {
        let t = Instant::now();
        let out = cmd().output().ok()?;
        if !out.status.success() {
            eprintln!("  failed: {}", String::from_utf8_lossy(&out.stderr).lines().last().unwrap_or(""));
            return None;
        }
        times.push(t.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    Some(times[times.len() / 2])
}

/// A job file for one method on one sample; texsyn runs it with `-j 1 --force` as a whole process.
fn job(dir: &Path, name: &str, sample: &Path, method: &str, params: &str) -> PathBuf {
    let d = dir.join(name);
    std::fs::create_dir_all(&d).expect("bench dir");
    let text = format!(
        "sample = \"{}\"\nmethod = \"{method}\"\nseed = 1\n[output]\npath = \"{name}.png\"\nwidth = {SIZE}\nheight = {SIZE}\n[params]\n{params}",
        sample.display()
    );
    std::fs::write(d.join("job.toml"), text).expect("job file");
    d
}

fn texsyn_run(dir: &Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_texsyn"));
    c.arg("run").arg(dir).arg("-o").arg(dir.join("out")).args(["-j", "1", "-q", "--force"]);
    c
}

fn main() {
    // `cargo bench` passes `--bench`; nothing else to parse.
    let reps: usize = std::env::var("TEXSYN_PEERS_REPS").ok().and_then(|s| s.parse().ok()).unwrap_or(3).max(1);
    let work = std::env::temp_dir().join(format!("texsyn-peers-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&work);
    let embark = embark();
    match &embark {
        Some(p) => println!("Embark texture-synthesis: {}", p.display()),
        None => println!(
            "Embark texture-synthesis not found: its column is skipped. Install it with\n  \
             cargo install --locked --version 0.8.3 texture-synthesis-cli --root <dir>\n\
             and set TEXSYN_EMBARK=<dir>/bin/texture-synthesis"
        ),
    }
    // `cargo bench --bench peers -- inpaint` runs only the inpainting and texture-transfer part.
    if std::env::args().any(|a| a == "inpaint") {
        inpaint::run(&work, embark.as_deref(), reps, &|r, c| time(r, c));
        inpaint::transfer(&work, embark.as_deref(), reps, &|r, c| time(r, c));
        let _ = std::fs::remove_dir_all(&work);
        return;
    }
    // `cargo bench --bench peers -- transfer` runs only the texture-transfer part.
    if std::env::args().any(|a| a == "transfer") {
        inpaint::transfer(&work, embark.as_deref(), reps, &|r, c| time(r, c));
        let _ = std::fs::remove_dir_all(&work);
        return;
    }
    // `cargo bench --bench peers -- samples` runs only the several-samples and augment part.
    if std::env::args().any(|a| a == "samples") {
        samples::run(&work, embark.as_deref(), reps, &|r, c| time(r, c));
        let _ = std::fs::remove_dir_all(&work);
        return;
    }
    // `TEXSYN_PEERS_PART=big`: the camera-sized samples only.
    if std::env::var("TEXSYN_PEERS_PART").is_ok_and(|v| v == "big") {
        big_samples(&work, embark.as_deref(), reps);
        let _ = std::fs::remove_dir_all(&work);
        return;
    }
    println!("{SIZE}² from 256², one thread, whole processes, median of {reps}; ratios = peer time / texsyn time\n");
    let methods: [(&str, &str); 7] = [
        ("quilting", "block = 40\noverlap = 10\ntolerance = 0.1\n"),
        ("double-seam", ""),
        ("patch-sampling", ""),
        ("coevolution", ""),
        ("tes", ""),
        ("wang-tiles", ""),
        ("rw-tiles", ""),
    ];
    println!("{:<22} {:<24} {:>9} {:>11} {:>14}", "sample", "program", "seconds", "vs quilting", "Embark / this");
    let mut ipol_ratios = Vec::new();
    for s in SAMPLES.iter().chain([&LATTICE_SAMPLE]) {
        let sample = repo().join(format!("jobs/samples/{s}.png"));
        let lattice_only = *s == LATTICE_SAMPLE;
        let embark_t = embark.as_ref().and_then(|e| {
            let out = work.join(format!("embark-{s}.png"));
            std::fs::create_dir_all(&work).ok()?;
            time(reps, || {
                let mut c = Command::new(e);
                c.args(["--no-progress", "--out-size", &SIZE.to_string(), "--threads", "1", "--seed", "1", "-o"])
                    .arg(&out)
                    .arg("generate")
                    .arg(&sample);
                c
            })
        });
        if let Some(t) = embark_t {
            println!("{s:<22} {:<24} {t:>9.3} {:>11} {:>14}", "Embark 0.8.3", "", "1");
        }
        let mut quilting = None;
        for (method, params) in methods {
            let near_regular = matches!(method, "coevolution" | "tes");
            if near_regular != lattice_only && method != "quilting" {
                continue;
            }
            let dir = job(&work, &format!("{s}-{method}"), &sample, method, params);
            let Some(t) = time(reps, || texsyn_run(&dir)) else {
                println!("{s:<22} {:<24} {:>9}", format!("texsyn {method}"), "failed");
                continue;
            };
            if method == "quilting" {
                quilting = Some(t);
                if let Some(e) = embark_t {
                    ipol_ratios.push(e * IPOL_PER_EMBARK / t);
                }
            }
            let vs_q = quilting.map(|q| format!("{:.2}×", t / q)).unwrap_or_default();
            let vs_e = embark_t.map(|e| format!("{:.1}×", e / t)).unwrap_or_else(|| "—".into());
            println!("{s:<22} {:<24} {t:>9.3} {vs_q:>11} {vs_e:>14}", format!("texsyn {method}"));
        }
    }
    if !ipol_ratios.is_empty() {
        let shown: Vec<String> = ipol_ratios.iter().map(|r| format!("{r:.0}×")).collect();
        println!(
            "\nexact quilting (block 40 / overlap 10 / tol 0.1) vs IPOL estimated as Embark × {IPOL_PER_EMBARK:.3}: {} (goal ≥ 100×)",
            shown.join(", ")
        );
    }
    // Paper 003's claim: double-seam faster than quilting, more so at larger blocks.
    println!("\ndouble-seam vs exact quilting (same block, overlap = block / 6, 512² from pebbles_beige): goal ≥ 1.5× at 50, ≥ 3× at 100");
    let sample = repo().join("jobs/samples/pebbles_beige.png");
    for block in [50u32, 100] {
        let overlap = block / 6;
        let q = job(&work, &format!("q{block}"), &sample, "quilting", &format!("block = {block}\noverlap = {overlap}\n"));
        let d = job(&work, &format!("d{block}"), &sample, "double-seam", &format!("block = {block}\n"));
        match (time(reps, || texsyn_run(&q)), time(reps, || texsyn_run(&d))) {
            (Some(tq), Some(td)) => {
                println!("block {block:>3}: quilting {tq:.3} s, double-seam {td:.3} s: double-seam is {:.2}× as fast", tq / td)
            }
            _ => println!("block {block:>3}: a run failed"),
        }
    }
    big_samples(&work, embark.as_deref(), reps);
    inpaint::run(&work, embark.as_deref(), reps, &|r, c| time(r, c));
    inpaint::transfer(&work, embark.as_deref(), reps, &|r, c| time(r, c));
    samples::run(&work, embark.as_deref(), reps, &|r, c| time(r, c));
    let _ = std::fs::remove_dir_all(&work);
}

/// Wall seconds of one whole process, ended (by its id) once it has run `limit` seconds: `Err`
/// with the limit then, so a peer that takes an hour on a camera photo costs the bench minutes.
fn time_capped(mut cmd: Command, limit: f64) -> Option<Result<f64, f64>> {
    let t = Instant::now();
    let mut child = cmd.stdout(std::process::Stdio::null()).stderr(std::process::Stdio::piped()).spawn().ok()?;
    loop {
        if let Some(status) = child.try_wait().ok()? {
            if !status.success() {
                eprintln!("  failed: {status}");
                return None;
            }
            return Some(Ok(t.elapsed().as_secs_f64()));
        }
        if t.elapsed().as_secs_f64() > limit {
            let _ = child.kill();
            let _ = child.wait();
            return Some(Err(limit));
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
}

/// Issue 32: camera-sized samples. pebbles_beige enlarged (bilinear) to 2048² and to 4000×3000
/// (12 MP; made here, the repository holds no photo) and the real photos in
/// `TEXSYN_PEERS_PHOTOS=DIR` (*.png, at their own scale), each to a 1024² output on two threads
/// (a photo job on this 2-core machine): texsyn's quilting with its defaults (`search = "auto"`,
/// the pyramid above 512²) against Embark with its defaults (which reads the whole sample). One
/// run each (`reps` for texsyn); Embark is ended after `TEXSYN_PEERS_BIG_LIMIT` seconds (default
/// 600) and its ratio printed as "more than". `TEXSYN_PEERS_BIG=0` skips this part.
fn big_samples(work: &Path, embark: Option<&Path>, reps: usize) {
    if std::env::var("TEXSYN_PEERS_BIG").is_ok_and(|v| v == "0") {
        return;
    }
    let limit: f64 = std::env::var("TEXSYN_PEERS_BIG_LIMIT").ok().and_then(|v| v.parse().ok()).unwrap_or(600.0);
    let out = 1024u32;
    println!("\nbig samples to {out}², two threads, whole processes: texsyn quilting defaults (auto search) vs Embark defaults");
    println!("{:<28} {:>11} {:>9} {:>11} {:>14}", "sample", "size", "texsyn s", "Embark s", "Embark / this");
    let base = texsyn::load_image(repo().join("jobs/samples/pebbles_beige.png")).expect("bundled sample");
    let mut samples: Vec<(String, PathBuf)> = Vec::new();
    std::fs::create_dir_all(work).expect("bench dir");
    for (w, h) in [(2048u32, 2048u32), (4000, 3000)] {
        let path = work.join(format!("pebbles_{w}x{h}.png"));
        texsyn::save_image(&enlarged(&base, w, h), &path).expect("big sample");
        samples.push((format!("pebbles enlarged {w}x{h}"), path));
    }
    if let Some(dir) = std::env::var_os("TEXSYN_PEERS_PHOTOS") {
        let mut photos: Vec<PathBuf> = std::fs::read_dir(&dir)
            .expect("photos dir")
            .map(|e| e.expect("dir entry").path())
            .filter(|p| p.extension().is_some_and(|e| e == "png"))
            .collect();
        photos.sort();
        samples.extend(photos.into_iter().map(|p| (p.file_stem().expect("name").to_string_lossy().into_owned(), p)));
    }
    for (name, path) in samples {
        let (w, h) = texsyn::load_image(&path).expect("sample").dimensions();
        let d = work.join(format!("big-{}", name.replace(' ', "_")));
        std::fs::create_dir_all(&d).expect("bench dir");
        let text = format!(
            "sample = \"{}\"\nmethod = \"quilting\"\nseed = 1\n[output]\npath = \"big.png\"\nwidth = {out}\nheight = {out}\n",
            path.display()
        );
        std::fs::write(d.join("job.toml"), text).expect("job file");
        let ours = time(reps, || {
            let mut c = Command::new(env!("CARGO_BIN_EXE_texsyn"));
            c.arg("run").arg(&d).arg("-o").arg(d.join("out")).args(["-j", "2", "-q", "--force"]);
            c
        });
        let theirs = embark.and_then(|e| {
            let mut c = Command::new(e);
            c.args(["--no-progress", "--out-size", &out.to_string(), "--threads", "2", "--seed", "1", "-o"])
                .arg(d.join("embark.png"))
                .arg("generate")
                .arg(&path);
            time_capped(c, limit)
        });
        let ours_s = ours.map_or("failed".to_string(), |t| format!("{t:.2}"));
        let (theirs_s, ratio) = match (theirs, ours) {
            (Some(Ok(e)), Some(t)) => (format!("{e:.2}"), format!("{:.1}×", e / t)),
            (Some(Err(cap)), Some(t)) => (format!("> {cap:.0}"), format!("> {:.0}×", cap / t)),
            (None, _) if embark.is_none() => ("—".into(), "—".into()),
            _ => ("failed".into(), "—".into()),
        };
        println!("{name:<28} {:>11} {ours_s:>9} {theirs_s:>11} {ratio:>14}", format!("{w}x{h}"));
    }
}

/// `img` enlarged (bilinear, pixel centres aligned) by the smallest whole factor that covers
/// `w × h`, its top-left `w × h`: issue 32's "one sample resized to each size".
fn enlarged(img: &texsyn::RgbImage, w: u32, h: u32) -> texsyn::RgbImage {
    let (iw, ih) = img.dimensions();
    let f = w.div_ceil(iw).max(h.div_ceil(ih));
    let at = |v: f64, n: u32| {
        let c = v.clamp(0.0, f64::from(n - 1));
        let i = c.floor() as u32;
        (i, (i + 1).min(n - 1), c - f64::from(i))
    };
    texsyn::RgbImage::from_fn(w, h, |x, y| {
        let (x0, x1, fx) = at((f64::from(x) + 0.5) / f64::from(f) - 0.5, iw);
        let (y0, y1, fy) = at((f64::from(y) + 0.5) / f64::from(f) - 0.5, ih);
        std::array::from_fn(|c| {
            let g = |x, y| f64::from(img.get(x, y)[c]);
            let top = g(x0, y0) * (1.0 - fx) + g(x1, y0) * fx;
            let bottom = g(x0, y1) * (1.0 - fx) + g(x1, y1) * fx;
            (top * (1.0 - fy) + bottom * fy).round() as u8
        })
    })
}
