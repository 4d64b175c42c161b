//! Several samples (`samples = [...]`) and transformed copies (`augment = [...]`), issue #28:
//! every output pixel comes from one sample under one transform, inside that sample's mask; the
//! source map (version 2) says which, and `texsyn apply` replays it over one image per sample;
//! the run is reproducible and verifiable; bad lists are refused by key.

use crate::common::*;
use std::path::Path;
use texsyn::batch::source_map;
use texsyn::synth::atlas::Augment;
use texsyn::synth::constraints::SampleMask;

const LEFT: &str = "jobs/samples/guided/gravel_gray_left.png";
const RIGHT: &str = "jobs/samples/guided/gravel_gray_right.png";

fn abs(p: &str) -> String {
    repo().join(p).display().to_string()
}

/// A mask for the 128×256 right half: its top half forbidden.
fn top_forbidden(path: &Path) -> SampleMask {
    let img = texsyn::RgbImage::from_fn(128, 256, |_, y| if y < 128 { [0; 3] } else { [255; 3] });
    texsyn::save_image(&img, path).unwrap();
    SampleMask::from_image(&img)
}

#[test]
fn every_pixel_comes_from_one_sample_and_transform_inside_its_mask() {
    let d = scratch("samples-obeyed");
    let jobs = d.join("jobs");
    std::fs::create_dir_all(&jobs).unwrap();
    let mask = top_forbidden(&d.join("right_mask.png"));
    let body = |name: &str, extra: &str| {
        format!(
            "samples = [\"{}\", \"{}\"]\nsample_mask = [\"\", \"{}\"]\naugment = [\"rot90\", \"flip_v\"]\nmethod = \"quilting\"\nseed = 4\n\
             [output]\npath = \"{name}.png\"\nwidth = 224\nheight = 192\nsource_map = \"{name}.map.exr\"\n{extra}[params]\nblock = 32\n",
            abs(LEFT),
            abs(RIGHT),
            d.join("right_mask.png").display()
        )
    };
    write(&jobs.join("plain.toml"), &body("plain", ""));
    write(&jobs.join("tileable.toml"), &body("tileable", "tileable = true\n"));
    write(&jobs.join("feather.toml"), &body("feather", "").replace("block = 32\n", "block = 32\ncut = \"none\"\nblend = \"feather\"\n"));
    // The other methods that learn from several samples: double-seam pastes blocks verbatim,
    // patch-sampling feathers them (its swarm and its exhaustive search).
    write(&jobs.join("seam.toml"), &body("seam", "").replace("quilting", "double-seam"));
    write(&jobs.join("seam_tileable.toml"), &body("seam_tileable", "tileable = true\n").replace("quilting", "double-seam"));
    write(&jobs.join("ps.toml"), &body("ps", "").replace("quilting", "patch-sampling"));
    write(
        &jobs.join("ps_exhaustive.toml"),
        &body("ps_exhaustive", "").replace("quilting", "patch-sampling").replace("block = 32\n", "block = 32\nsearch = \"exhaustive\"\n"),
    );
    run_ok(texsyn().args(["run", "-q", "-j", "2", "-o"]).arg(d.join("out")).arg(&jobs));
    for name in ["plain", "tileable", "feather", "seam", "seam_tileable", "ps", "ps_exhaustive"] {
        let map = source_map::decode_map(&std::fs::read(d.join(format!("out/{name}.map.exr"))).unwrap()).unwrap();
        let atlas = map.atlas.as_ref().expect("a version 2 map");
        assert_eq!(map.sample_sizes(), vec![(128, 256), (128, 256)]);
        let p = &map.placement;
        let (aw, _) = p.sample_size();
        let (w, h) = p.dimensions();
        let mut used = std::collections::BTreeMap::new();
        for y in 0..h {
            for x in 0..w {
                let blends = p.blends_at(x, y);
                let sources = std::iter::once(p.source(x, y)).chain(blends.iter().map(|b| b.source));
                for s in sources {
                    let (piece, (sx, sy)) = atlas.locate(s % aw, s / aw).unwrap_or_else(|| panic!("{name}: ({x}, {y}) copies a gutter"));
                    if piece.sample == 1 {
                        assert!(mask.allows(sx, sy), "{name}: ({x}, {y}) copies ({sx}, {sy}) of the right photo, which its mask forbids");
                    }
                    *used.entry((piece.sample, piece.transform.map(|t| t.code()))).or_insert(0u32) += 1;
                }
            }
        }
        // Both photos and some transformed copy are used (the test can tell a single-sample run).
        assert!(used.keys().any(|k| k.0 == 0) && used.keys().any(|k| k.0 == 1), "{name}: {used:?}");
        assert!(used.keys().any(|k| k.1.is_some()), "{name}: {used:?}");
    }
    // The map replays over the two photos: the job's own output, pixel for pixel.
    let replay = d.join("replay.png");
    run_ok(texsyn().arg("apply").arg(d.join("out/plain.map.exr")).arg(abs(LEFT)).arg(abs(RIGHT)).arg("-o").arg(&replay));
    assert_eq!(pixels(&replay), pixels(&d.join("out/plain.png")));
    let one = run_expect(texsyn().arg("apply").arg(d.join("out/plain.map.exr")).arg(abs(LEFT)).arg("-o").arg(&replay), 2);
    assert!(text(&one).contains("was made from 2 samples; give one image per sample"), "{}", text(&one));
    // Recorded: both samples and the right one's mask; verify re-runs; one thread gives the same.
    let m = json(&d.join("out/manifest.json"));
    let job = m["jobs"].as_array().unwrap().iter().find(|j| j["id"] == "plain.toml").unwrap();
    assert_eq!(job["samples"].as_array().unwrap().len(), 2, "{job}");
    assert!(job["sample_masks"][0].is_null() && job["sample_masks"][1]["path"].as_str().unwrap().ends_with("right_mask.png"), "{job}");
    assert_eq!(job["output_spec"]["augment"], serde_json::json!(["rot90", "flip_v"]));
    run_ok(texsyn().arg("verify").arg(d.join("out/manifest.json")));
    run_ok(texsyn().args(["run", "-q", "-j", "1", "-o"]).arg(d.join("out1")).arg(&jobs));
    let m1 = json(&d.join("out1/manifest.json"));
    for (a, b) in m["jobs"].as_array().unwrap().iter().zip(m1["jobs"].as_array().unwrap()) {
        assert_eq!(a["outputs"], b["outputs"], "{}", a["id"]);
    }
    // A changed mask of the second sample re-runs the job, and diff says so.
    std::fs::copy(d.join("out/manifest.json"), d.join("before.json")).unwrap();
    texsyn::save_image(&texsyn::RgbImage::from_fn(128, 256, |_, y| if y >= 200 { [0; 3] } else { [255; 3] }), d.join("right_mask.png"))
        .unwrap();
    let again = text(&run_ok(texsyn().args(["run", "-o"]).arg(d.join("out")).arg(jobs.join("plain.toml"))));
    assert!(again.contains("ran 1"), "{again}");
    let said = text(&run(texsyn().arg("diff").arg(d.join("before.json")).arg(d.join("out/manifest.json"))));
    assert!(said.contains("mask changed (samples[2].mask"), "{said}");
}

#[test]
fn augmented_normals_are_turned_with_their_copy() {
    let d = scratch("samples-normals");
    let albedo = abs("jobs/samples/materials/rock_a_albedo.png");
    let normal = abs("jobs/samples/materials/rock_a_normal.png");
    write(
        &d.join("jobs/rock.toml"),
        &format!(
            "sample = \"{albedo}\"\naugment = [\"rot90\", \"rot180\", \"rot270\", \"flip_h\", \"flip_v\"]\nmethod = \"quilting\"\nseed = 1\n\
             [output]\npath = \"albedo.png\"\nwidth = 160\nheight = 160\nsource_map = \"map.exr\"\n\
             [[companion]]\nsample = \"{normal}\"\npath = \"normal.png\"\nkind = \"normal\"\n[params]\nblock = 40\n"
        ),
    );
    run_ok(texsyn().args(["run", "-q", "-o"]).arg(d.join("out")).arg(d.join("jobs")));
    let map = source_map::decode_map(&std::fs::read(d.join("out/map.exr")).unwrap()).unwrap();
    let atlas = map.atlas.as_ref().unwrap();
    let (aw, _) = map.placement.sample_size();
    let (n_in, n_out) = (rgb(Path::new(&normal)), rgb(&d.join("out/normal.png")));
    let mut turned = 0;
    for y in 0..160 {
        for x in 0..160 {
            let s = map.placement.source(x, y);
            let (piece, (sx, sy)) = atlas.locate(s % aw, s / aw).unwrap();
            let [r, g, b] = n_in.get(sx, sy);
            let want = match piece.transform {
                None => [r, g, b],
                Some(Augment::Rot90) => [g, 255 - r, b],
                Some(Augment::Rot180) => [255 - r, 255 - g, b],
                Some(Augment::Rot270) => [255 - g, r, b],
                Some(Augment::FlipH) => [255 - r, g, b],
                Some(Augment::FlipV) => [r, 255 - g, b],
            };
            turned += usize::from(piece.transform.is_some());
            assert_eq!(n_out.get(x, y), want, "({x}, {y}) from {piece:?}");
        }
    }
    assert!(turned > 1000, "the copies are used: {turned} pixels");
    // `apply --kind normal` over the normal map gives the companion.
    let replay = d.join("replay.png");
    run_ok(texsyn().arg("apply").arg(d.join("out/map.exr")).arg(&normal).args(["--kind", "normal", "-o"]).arg(&replay));
    assert_eq!(pixels(&replay), pixels(&d.join("out/normal.png")));
    run_ok(texsyn().arg("verify").arg(d.join("out/manifest.json")));
}

#[test]
fn bad_sample_lists_are_refused_by_key() {
    let d = scratch("samples-bad");
    let jobs = d.join("jobs");
    let head = |samples: &str, method: &str, extra: &str, out: &str| {
        format!("{samples}\nmethod = \"{method}\"\nseed = 1\n{extra}\n[output]\npath = \"{out}.png\"\nwidth = 64\nheight = 64\n")
    };
    let two = format!("samples = [\"{}\", \"{}\"]", abs(LEFT), abs(RIGHT));
    let gray = abs("jobs/samples/materials/rock_a_gloss.png");
    write(&jobs.join("channels.toml"), &head(&format!("samples = [\"{}\", \"{gray}\"]", abs(LEFT)), "quilting", "", "a"));
    write(&jobs.join("word.toml"), &head(&two, "quilting", "augment = [\"rot90\", \"flip_x\"]", "b"));
    write(&jobs.join("twice.toml"), &head(&two, "quilting", "augment = [\"rot90\", \"rot90\"]", "c"));
    write(&jobs.join("masks.toml"), &head(&two, "quilting", &format!("sample_mask = [\"{}\"]", abs(RIGHT)), "d"));
    write(&jobs.join("onemask.toml"), &head(&two, "quilting", &format!("sample_mask = \"{}\"", abs(RIGHT)), "e"));
    write(&jobs.join("both.toml"), &head(&format!("sample = \"{}\"\n{two}", abs(LEFT)), "quilting", "", "f"));
    write(&jobs.join("method.toml"), &head(&two, "tes", "augment = [\"flip_h\"]", "g"));
    write(&jobs.join("empty.toml"), &head("samples = []", "quilting", "", "h"));
    write(&jobs.join("missing.toml"), &head(&format!("samples = [\"{}\", \"nowhere.png\"]", abs(LEFT)), "quilting", "", "i"));
    write(&jobs.join("good.toml"), &head(&two, "quilting", "augment = [\"flip_h\"]", "good"));
    let started = std::time::Instant::now();
    let said = text(&run(texsyn().args(["run", "-o"]).arg(d.join("out")).arg(&jobs)));
    assert!(started.elapsed().as_secs() < 30, "refusals are quick");
    for expected in [
        "channels.toml:1:1: `samples`:",
        "rock_a_gloss.png` is 8-bit gray but",
        "is 8-bit RGB; every sample must have the same channels and precision",
        "word.toml:4:21: `augment`: unknown transform `flip_x` (did you mean `flip_h`?); valid: rot90, rot180, rot270, flip_h, flip_v",
        "twice.toml:4:21: `augment`: `rot90` is listed twice",
        "masks.toml:4:15: `sample_mask`: lists 1 masks for 2 samples",
        "onemask.toml:4:15: `sample_mask`: with 2 samples, give `sample_mask` as a list parallel to `samples`",
        "both.toml:2:11: `samples`: both `sample` and `samples` are given",
        "method.toml:1:11: `samples`: tes learns from one sample; methods that take several: quilting, double-seam, patch-sampling",
        "method.toml:4:11: `augment`: tes cannot search transformed copies",
        "empty.toml:1:11: `samples`: samples is empty",
        "missing.toml:1:",
        "nowhere.png` does not exist",
    ] {
        assert!(said.contains(expected), "missing {expected:?} in:\n{said}");
    }
    let m = json(&d.join("out/manifest.json"));
    let good = m["jobs"].as_array().unwrap().iter().find(|j| j["id"] == "good.toml").unwrap();
    assert_eq!(good["status"], "ok", "{good}");
}

/// With several samples a companion names each sample's map (`sample = [...]`, parallel to
/// `samples`); the output's map is rendered from the map of the sample and copy each pixel came
/// from. With each sample as its own "map", the companion is the output itself, pixel for pixel
/// (blends and turned copies included); `verify` re-runs it; bad lists are refused by key.
#[test]
fn companions_take_one_map_per_sample() {
    let d = scratch("samples-companions");
    let jobs = d.join("jobs");
    let job = |name: &str, companion_sample: &str, extra: &str| {
        format!(
            "samples = [\"{}\", \"{}\"]\naugment = [\"rot90\", \"flip_h\"]\nmethod = \"quilting\"\nseed = 6\n[output]\npath = \"{name}.png\"\n\
             width = 200\nheight = 160\n[params]\nblock = 32\n{extra}[[companion]]\nsample = {companion_sample}\npath = \"{name}_map.png\"\n",
            abs(LEFT),
            abs(RIGHT)
        )
    };
    let pair = format!("[\"{}\", \"{}\"]", abs(LEFT), abs(RIGHT));
    write(&jobs.join("cut.toml"), &job("cut", &pair, ""));
    write(&jobs.join("feather.toml"), &job("feather", &pair, "cut = \"none\"\nblend = \"feather\"\n"));
    write(&jobs.join("ps.toml"), &job("ps", &pair, "").replace("quilting", "patch-sampling"));
    run_ok(texsyn().args(["run", "-q", "-o"]).arg(d.join("out")).arg(&jobs));
    for name in ["cut", "feather", "ps"] {
        assert_eq!(
            pixels(&d.join(format!("out/{name}_map.png"))),
            pixels(&d.join(format!("out/{name}.png"))),
            "{name}: the companion follows"
        );
    }
    let m = json(&d.join("out/manifest.json"));
    let cut = m["jobs"].as_array().unwrap().iter().find(|j| j["id"] == "cut.toml").unwrap();
    assert!(cut["more_companions"][0][0]["path"].as_str().unwrap().ends_with("gravel_gray_right.png"), "{cut}");
    assert_eq!(cut["output_spec"]["companions"][0]["more_sample_pixels"].as_array().unwrap().len(), 1, "{cut}");
    run_ok(texsyn().arg("verify").arg(d.join("out/manifest.json")));
    // Mistakes: one map for two samples, a list of the wrong length, a map of another size.
    let bad = d.join("bad");
    let small = d.join("small.png");
    texsyn::save_image(&texsyn::RgbImage::from_fn(64, 64, |x, _| [x as u8; 3]), &small).unwrap();
    write(&bad.join("one.toml"), &job("one", &format!("\"{}\"", abs(LEFT)), ""));
    write(&bad.join("three.toml"), &job("three", &format!("[\"{}\", \"{}\", \"{}\"]", abs(LEFT), abs(RIGHT), abs(RIGHT)), ""));
    write(&bad.join("size.toml"), &job("size", &format!("[\"{}\", \"{}\"]", abs(LEFT), small.display()), ""));
    let said = text(&run(texsyn().args(["run", "-o"]).arg(d.join("bad_out")).arg(&bad)));
    for expected in [
        "one.toml:12:1: `companion[1].sample`: with 2 samples, give this map of each sample: a list parallel to `samples`",
        "three.toml:12:10: `companion[1].sample`: lists 3 maps for 2 samples",
        "size.toml:",
        "`companion[1].sample`: companion `",
        "small.png` (entry 2) is 64x64 but its sample",
    ] {
        assert!(said.contains(expected), "missing {expected:?} in:\n{said}");
    }
}

#[test]
fn the_one_off_command_takes_several_samples_and_augment() {
    let d = scratch("samples-synth");
    let out = d.join("remix.png");
    let printed = text(&run_ok(
        texsyn()
            .arg("synth")
            .arg(abs(LEFT))
            .arg(abs(RIGHT))
            .args(["--augment", "rot90,flip_h", "--size", "96x96", "--print-job", "-o"])
            .arg(&out),
    ));
    assert!(printed.contains("samples = [") && printed.contains("augment = [\"rot90\", \"flip_h\"]"), "{printed}");
    run_ok(
        texsyn()
            .arg("synth")
            .arg(abs(LEFT))
            .arg(abs(RIGHT))
            .args(["--augment", "rot90,flip_h", "--size", "96x96", "--seed", "2", "-o"])
            .arg(&out),
    );
    run_ok(texsyn().arg("verify").arg(d.join("remix.manifest.json")));
    let bad = run_expect(texsyn().arg("synth").arg(abs(LEFT)).args(["--augment", "rot45", "-o"]).arg(&out), 2);
    assert!(text(&bad).contains("unknown transform `rot45`"), "{}", text(&bad));
}

/// A block never continues its neighbour with a turned or mirrored copy of the same pixels: such
/// a "twin" shows as a symmetric motif (pairs of nearby output pixels that are one sample pixel
/// under two transforms). Quilting, double-seam and patch-sampling (its swarm and its exhaustive
/// search), plain and tileable.
#[test]
fn augmented_copies_do_not_meet_their_own_mirror_image() {
    let d = scratch("samples-twins");
    let jobs = d.join("jobs");
    for (name, method, extra, params) in [
        ("q", "quilting", "", ""),
        ("q_tileable", "quilting", "tileable = true\n", ""),
        ("seam", "double-seam", "", ""),
        ("seam_tileable", "double-seam", "tileable = true\n", ""),
        ("ps", "patch-sampling", "", ""),
        ("ps_tileable", "patch-sampling", "tileable = true\n", ""),
        ("ps_exhaustive", "patch-sampling", "", "search = \"exhaustive\"\n"),
    ] {
        write(
            &jobs.join(format!("{name}.toml")),
            &format!(
                "samples = [\"{}\", \"{}\"]\naugment = [\"rot90\", \"flip_h\"]\nmethod = \"{method}\"\nseed = 5\n\
                 [output]\npath = \"{name}.png\"\nwidth = 320\nheight = 320\nsource_map = \"{name}.map.exr\"\n{extra}[params]\nblock = 32\n{params}",
                abs(LEFT),
                abs(RIGHT)
            ),
        );
    }
    run_ok(texsyn().args(["run", "-q", "-o"]).arg(d.join("out")).arg(&jobs));
    let mut failed = Vec::new();
    for name in ["q", "q_tileable", "seam", "seam_tileable", "ps", "ps_tileable", "ps_exhaustive"] {
        let map = source_map::decode_map(&std::fs::read(d.join(format!("out/{name}.map.exr"))).unwrap()).unwrap();
        let atlas = map.atlas.as_ref().unwrap();
        let p = &map.placement;
        let (aw, _) = p.sample_size();
        let (w, h) = p.dimensions();
        let at = |x: u32, y: u32| {
            let s = p.source(x, y);
            atlas.locate(s % aw, s / aw).map(|(piece, xy)| (piece.sample, piece.transform, xy))
        };
        let (mut twins, mut pairs) = (0u64, 0u64);
        for y in 0..h {
            for x in 0..w {
                let a = at(x, y);
                for k in 1..=24 {
                    for (qx, qy) in [(x + k, y), (x, y + k)] {
                        if qx >= w || qy >= h {
                            continue;
                        }
                        pairs += 1;
                        let b = at(qx, qy);
                        if let (Some(a), Some(b)) = (a, b)
                            && a.0 == b.0
                            && a.1 != b.1
                            && a.2 == b.2
                        {
                            twins += 1;
                        }
                    }
                }
            }
        }
        eprintln!("{name}: {twins} twin pairs of {pairs}");
        if twins * 20_000 >= pairs {
            failed.push(format!("{name}: {twins} pairs of nearby pixels are one sample pixel under two transforms"));
        }
    }
    assert!(failed.is_empty(), "{}", failed.join("\n"));
}
