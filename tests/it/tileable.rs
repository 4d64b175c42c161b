//! Tileable outputs (`Request::tileable`) of the overlapping-block methods must wrap as well as
//! their own interior seams join, on real samples: a texture artist tiles them 2×2 and more, so a
//! wrap seam is a defect in every tile. Also: the placement stays exact on the torus, the result
//! does not depend on the thread count, and sizes that cannot wrap are refused with a sentence
//! saying what would.
//!
//! Set `TEXSYN_TILEABLE_PNG=dir` to also write each output tiled 2×2 into `dir` (to look at).

use crate::common::{repo, rgb};
use texsyn::metrics::seams::{seam_visibility, wrap_visibility};
use texsyn::synth::method::{Method, Request, Synthesis};
use texsyn::synth::methods;
use texsyn::synth::params::resolve;
use texsyn::image::seam_grid::SeamGrid;
use texsyn::{ParamValue, RgbImage};

fn synth(method: &str, sample: &RgbImage, size: (u32, u32), given: &[(&str, ParamValue)], placement: bool) -> Synthesis {
    let m: &dyn Method = methods::find(method).unwrap();
    let given: Vec<(String, ParamValue)> = given.iter().map(|(k, v)| (k.to_string(), v.clone())).collect();
    let params = resolve(m.params(), &given).unwrap();
    m.tileable(&params, sample.dimensions(), size).unwrap_or_else(|e| panic!("{method}: {e}"));
    let req = Request { sample, width: size.0, height: size.1, params: &params, seed: 11, placement, tileable: true };
    let out = m.synthesize(&req).unwrap();
    assert_eq!(out.image.dimensions(), size, "{method}");
    out
}

fn tiled(img: &RgbImage) -> RgbImage {
    let (w, h) = img.dimensions();
    RgbImage::from_fn(2 * w, 2 * h, |x, y| img.get(x % w, y % h))
}

/// The image rolled by half its size: the wrap moves to the middle, where the interior metric
/// looks, and the middle to the border.
fn rolled(img: &RgbImage) -> RgbImage {
    let (w, h) = img.dimensions();
    RgbImage::from_fn(w, h, |x, y| img.get((x + w / 2) % w, (y + h / 2) % h))
}

fn samples() -> Vec<(String, RgbImage)> {
    let mut v: Vec<(String, RgbImage)> =
        ["pebbles_beige.png", "bricks_gray.png"].iter().map(|n| (n.to_string(), rgb(&repo().join("jobs/samples").join(n)))).collect();
    for n in ["aztek_wall_albedo.png", "brick_a_albedo.png", "cobblestone_a_albedo.png", "rock_a_albedo.png", "wood_b_albedo.png"] {
        v.push((n.to_string(), rgb(&repo().join("tests/fixtures/advice").join(n))));
    }
    v
}

/// Wrap vs interior seams for one method and variant on every sample; returns the worst ratio.
/// `wrap_visibility` looks at the wrap itself; the interior metric at every seam band of the
/// torus (the bands where the wrap closes included, which the wrap metric alone would miss: on a
/// torus the wrap boundary lies inside the last blocks, the cuts that close it a few pixels in).
fn check_wraps(method: &str, size: (u32, u32), given: &[(&str, ParamValue)]) -> f64 {
    let mut worst: f64 = 0.0;
    for (name, sample) in samples() {
        let out = synth(method, &sample, size, given, false);
        let seams = out.seams.as_ref().unwrap();
        let interior = seam_visibility(&out.image, seams).unwrap();
        let wrap = wrap_visibility(&out.image).unwrap();
        // The same seams measured with the wrap in the middle of the image: a seam at the wrap
        // the metric cannot see at the border would show here.
        let roll_wrap = wrap_visibility(&rolled(&out.image)).unwrap();
        let split = |keep: &dyn Fn(usize) -> bool| SeamGrid {
            columns: seams.columns.iter().enumerate().filter(|(k, _)| keep(*k)).map(|(_, b)| *b).collect(),
            rows: seams.rows.iter().enumerate().filter(|(k, _)| keep(*k)).map(|(_, b)| *b).collect(),
        };
        let closing = seam_visibility(&out.image, &split(&|k| k == 0)).unwrap();
        let inner = seam_visibility(&out.image, &split(&|k| k > 0)).unwrap();
        println!("{method} {given:?} {name}: wrap {wrap:.3}, rolled {roll_wrap:.3}, interior seams {interior:.3}, closing bands {closing:.3}, inner bands {inner:.3}");
        if let Ok(dir) = std::env::var("TEXSYN_TILEABLE_PNG") {
            let tag: String = given.iter().map(|(k, v)| format!("_{k}-{v:?}")).collect::<String>();
            let tag: String = tag.chars().filter(|c| c.is_ascii_alphanumeric() || *c == '_' || *c == '-').collect();
            let path = std::path::Path::new(&dir).join(format!("{method}{tag}_{}", name.replace(".png", "_2x2.png")));
            texsyn::save_image(&tiled(&out.image), path).unwrap();
        }
        if std::env::var("TEXSYN_NO_ASSERT").is_err() { assert!(wrap <= interior, "{method} {given:?} on {name}: wrap {wrap} is worse than the interior seams {interior}"); }
        worst = worst.max(wrap / interior);
    }
    worst
}

#[test]
fn quilting_wraps_no_worse_than_its_seams() {
    check_wraps("quilting", (336, 252), &[]);
    check_wraps("quilting", (336, 252), &[("cut", ParamValue::Str("none".into()))]);
    check_wraps("quilting", (336, 252), &[("cut", ParamValue::Str("none".into())), ("blend", ParamValue::Str("feather".into()))]);
}

#[test]
fn patch_sampling_wraps_no_worse_than_its_seams() {
    check_wraps("patch-sampling", (250, 225), &[]);
    check_wraps("patch-sampling", (250, 225), &[("blend", ParamValue::Str("cut".into()))]);
}

#[test]
fn double_seam_wraps_no_worse_than_its_seams() {
    check_wraps("double-seam", (336, 252), &[]);
}

fn check_placement(method: &str, size: (u32, u32), given: &[(&str, ParamValue)]) {
    let s = rgb(&repo().join("jobs/samples/crops/pebbles_beige_128.png"));
    let without = synth(method, &s, size, given, false);
    let with = synth(method, &s, size, given, true);
    assert_eq!(with.image, without.image, "{method} {given:?}: the placement changed the pixels");
    let rendered = with.placement.as_ref().unwrap().render_rgb8(&s);
    assert!(rendered == with.image, "{method} {given:?}: the placement does not render the tileable image");
}

#[test]
fn tileable_placements_render_their_images() {
    let q = |k: &'static str, v: &str| (k, ParamValue::Str(v.into()));
    check_placement("quilting", (128, 96), &[("block", ParamValue::Int(38))]);
    check_placement("quilting", (128, 96), &[("block", ParamValue::Int(38)), q("cut", "none")]);
    check_placement("quilting", (128, 96), &[("block", ParamValue::Int(38)), q("cut", "none"), q("blend", "feather")]);
    check_placement("patch-sampling", (100, 75), &[]);
    check_placement("patch-sampling", (100, 75), &[q("blend", "cut")]);
    check_placement("patch-sampling", (100, 75), &[q("search", "exhaustive")]);
    check_placement("double-seam", (108, 81), &[("block", ParamValue::Int(32))]);
}

#[test]
fn tileable_patch_sampling_does_not_depend_on_the_thread_count() {
    let s = rgb(&repo().join("jobs/samples/crops/pebbles_beige_128.png"));
    let given = [("diagnostics", ParamValue::Bool(true))];
    let runs: Vec<Synthesis> = [1, 3]
        .iter()
        .map(|&n| rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap().install(|| synth("patch-sampling", &s, (125, 100), &given, false)))
        .collect();
    assert!(runs[0].image == runs[1].image);
    assert_eq!(runs[0].diagnostics, runs[1].diagnostics);
}

#[test]
fn sizes_that_cannot_wrap_are_refused_saying_what_would() {
    let refusal = |method: &str, sample: (u32, u32), size: (u32, u32), given: &[(&str, ParamValue)]| -> String {
        let m = methods::find(method).unwrap();
        let given: Vec<(String, ParamValue)> = given.iter().map(|(k, v)| (k.to_string(), v.clone())).collect();
        let params = resolve(m.params(), &given).unwrap();
        m.tileable(&params, sample, size).unwrap_err()
    };
    let e = refusal("quilting", (256, 256), (768, 768), &[]);
    assert_eq!(
        e,
        "tileable quilting needs width and height multiples of block - overlap = 42 (at least 2 blocks each way); 756x756 or 798x798 would work, or block = 56 for 768x768"
    );
    let e = refusal("patch-sampling", (256, 256), (768, 512), &[]);
    assert!(e.contains("block - overlap = 25") && e.contains("750x500 or 775x525"), "{e}");
    let e = refusal("double-seam", (256, 256), (500, 500), &[]);
    assert!(e.contains("block - overlap = 42") && e.contains("504x504"), "{e}");
    let e = refusal("double-seam", (64, 64), (84, 84), &[("block", ParamValue::Int(60)), ("overlap", ParamValue::Int(18))]);
    assert!(e.contains("sample"), "{e}");
    // A synthesis asked anyway fails with the same sentence.
    let s = rgb(&repo().join("jobs/samples/crops/pebbles_beige_128.png"));
    let m = methods::find("quilting").unwrap();
    let params = resolve(m.params(), &[]).unwrap();
    let req = Request { sample: &s, width: 100, height: 100, params: &params, seed: 1, placement: false, tileable: true };
    assert!(m.synthesize(&req).unwrap_err().to_string().contains("multiples of block - overlap = 42"));
}
