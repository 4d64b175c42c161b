//! Helpers every test module shares: the binary, scratch directories, running and reading
//! results. The library paths the tests use are imported here once, so a change of the
//! library's public paths touches this file only.

#![allow(dead_code)]

pub use serde_json::Value;
pub use std::collections::BTreeMap;
pub use std::path::{Path, PathBuf};
pub use std::process::{Command, Output, Stdio};
pub use std::time::{Duration, Instant};
pub use texsyn::RgbImage;
pub use texsyn::image::io::{self as imageio, DecodeLimits};

use std::sync::atomic::{AtomicUsize, Ordering};

/// The `texsyn` binary under test.
pub fn texsyn() -> Command {
    Command::new(env!("CARGO_BIN_EXE_texsyn"))
}

/// The repository root (bundled jobs, samples, golden digests, fixtures).
pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A fresh, empty directory of its own for each call (tests run in parallel in one process).
pub fn scratch(tag: &str) -> PathBuf {
    static NEXT: AtomicUsize = AtomicUsize::new(0);
    let n = NEXT.fetch_add(1, Ordering::Relaxed);
    let d = std::env::temp_dir().join(format!("texsyn-it-{tag}-{}-{n}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A command and what it printed, for assertion messages.
pub fn show(cmd: &Command, out: &Output) -> String {
    format!(
        "{cmd:?} exited {:?}\nstdout:\n{}\nstderr:\n{}",
        out.status.code(),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// stdout and stderr together.
pub fn text(out: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr))
}

/// Runs a command, whatever its exit code.
pub fn run(cmd: &mut Command) -> Output {
    cmd.output().expect("texsyn runs")
}

/// Runs a command that must succeed.
pub fn run_ok(cmd: &mut Command) -> Output {
    let out = run(cmd);
    assert!(out.status.success(), "{}", show(cmd, &out));
    out
}

/// Runs a command that must exit with `code`.
pub fn run_expect(cmd: &mut Command, code: i32) -> Output {
    let out = run(cmd);
    assert_eq!(out.status.code(), Some(code), "{}", show(cmd, &out));
    out
}

/// `texsyn ARGS…`, whatever its exit code.
pub fn texsyn_args(args: &[&str]) -> Output {
    run(texsyn().args(args))
}

/// A JSON file.
pub fn json(path: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))).unwrap()
}

/// The manifest of an output directory.
pub fn manifest(out: &Path) -> Value {
    json(&out.join("manifest.json"))
}

/// Writes a file, creating its directory.
pub fn write(path: &Path, text: &str) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, text).unwrap();
}

/// Copies a directory tree.
pub fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let target = to.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            copy_dir(&e.path(), &target);
        } else {
            std::fs::copy(e.path(), &target).unwrap();
        }
    }
}

/// Every file under a directory.
pub fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            out.extend(walk(&p));
        } else {
            out.push(p);
        }
    }
    out
}

/// The pixel digest of an output file as texsyn records it.
pub fn pixels(path: &Path) -> String {
    let bytes = std::fs::read(path).unwrap();
    imageio::decode_output(&bytes, DecodeLimits::default()).unwrap().pixel_digest().sha256
}

/// An image as 8-bit RGB.
pub fn rgb(path: &Path) -> RgbImage {
    imageio::read_rgb8(path, DecodeLimits::default()).unwrap().0
}

/// `img` enlarged `f`× by bilinear interpolation (pixel centres aligned), its top-left `w × h`:
/// a close-up of the same surface, every feature `f`× larger, without the detail a camera would add;
/// and big samples made at test time from bundled ones (no photo of megabytes in the repository).
pub fn enlarged(img: &RgbImage, f: u32, w: u32, h: u32) -> RgbImage {
    let (iw, ih) = img.dimensions();
    let at = |v: f64, n: u32| {
        let c = v.clamp(0.0, f64::from(n - 1));
        let i = c.floor() as u32;
        (i, (i + 1).min(n - 1), c - f64::from(i))
    };
    RgbImage::from_fn(w, h, |x, y| {
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

/// Writes `img` as an 8-bit PNG.
pub fn write_png(path: &Path, img: &RgbImage) {
    let enc = imageio::encode(img, imageio::Encoding { format: imageio::Format::Png, bit_depth: 8 }).unwrap();
    std::fs::write(path, enc.bytes).unwrap();
}
