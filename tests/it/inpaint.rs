//! Inpainting (`[inpaint]`, issue #28): every pixel outside the mask stays bit for bit (8-bit,
//! 16-bit, companions, alpha), the hole is filled only from known pixels, runs are reproducible
//! and verifiable, a changed mask reruns the job, and bad input is refused by key.

use crate::common::*;
use std::path::Path;
use texsyn::batch::source_map;

const IMAGE: &str = "jobs/samples/guided/cork_cable.png";
const MASK: &str = "jobs/samples/guided/cork_cable_mask.png";
const HOLES: &str = "jobs/samples/guided/pebbles_beige_holes.png";

fn abs(p: &str) -> String {
    repo().join(p).display().to_string()
}

/// A job file inpainting `image` with `mask_line` (`mask = "…"` or `channel = "…"`).
fn job(dir: &Path, name: &str, image: &str, mask_line: &str, output_extra: &str, params: &str) {
    std::fs::create_dir_all(dir).unwrap();
    let stem = name.trim_end_matches(".toml");
    std::fs::write(
        dir.join(name),
        format!(
            "method = \"quilting\"\nseed = 3\n[inpaint]\nimage = \"{image}\"\n{mask_line}\n[output]\npath = \"{stem}.png\"\n{output_extra}\n[params]\nblock = 32\n{params}"
        ),
    )
    .unwrap();
}

fn mask_flags() -> Vec<bool> {
    let m = rgb(&repo().join(MASK));
    m.as_raw().chunks_exact(3).map(|p| p[0] >= 128).collect()
}

/// Outside the mask the output is the image, and each of its pixels is its own source; inside,
/// every pixel is copied from a known one (never from the cable or the sticker). Also on a torus,
/// on one thread, and through `verify`.
#[test]
fn outside_the_mask_nothing_changes_and_the_hole_is_filled_from_known_pixels() {
    let d = scratch("inpaint-kept");
    let jobs = d.join("jobs");
    let mask_line = format!("mask = \"{}\"", abs(MASK));
    job(&jobs, "plain.toml", &abs(IMAGE), &mask_line, "source_map = \"plain.map.exr\"", "");
    job(&jobs, "torus.toml", &abs(IMAGE), &mask_line, "source_map = \"torus.map.exr\"\ntileable = true", "");
    job(&jobs, "nocut.toml", &abs(IMAGE), &mask_line, "source_map = \"nocut.map.exr\"", "cut = \"none\"\n");
    // Patch sampling: its swarm and its exhaustive search, feathered (the default) or cut, and on a torus.
    for (name, output, params) in [
        ("ps", "", ""),
        ("ps_exhaustive", "", "search = \"exhaustive\"\n"),
        ("ps_cut", "", "blend = \"cut\"\n"),
        ("ps_torus", "tileable = true\n", "search = \"pso\"\n"),
    ] {
        job(&jobs, &format!("{name}.toml"), &abs(IMAGE), &mask_line, &format!("source_map = \"{name}.map.exr\"\n{output}"), params);
        let text = std::fs::read_to_string(jobs.join(format!("{name}.toml"))).unwrap();
        std::fs::write(jobs.join(format!("{name}.toml")), text.replace("method = \"quilting\"", "method = \"patch-sampling\"")).unwrap();
    }
    run_ok(texsyn().args(["run", "-q", "-j", "2", "-o"]).arg(d.join("out")).arg(&jobs));
    let image = rgb(&repo().join(IMAGE));
    let fill = mask_flags();
    let (w, h) = image.dimensions();
    for name in ["plain", "torus", "nocut", "ps", "ps_exhaustive", "ps_cut", "ps_torus"] {
        let out = rgb(&d.join(format!("out/{name}.png")));
        assert_eq!(out.dimensions(), (w, h), "{name}: the image's size");
        let map = source_map::decode(&std::fs::read(d.join(format!("out/{name}.map.exr"))).unwrap()).unwrap();
        let (mut changed, mut blended) = (0, 0);
        for y in 0..h {
            for x in 0..w {
                let i = (y * w + x) as usize;
                let src = map.sources()[i];
                if fill[i] {
                    assert!(!fill[src as usize], "{name}: ({x},{y}) copies ({},{}), inside the hole", src % w, src / w);
                    for b in map.blends_at(x, y) {
                        assert!(!fill[b.source as usize], "{name}: ({x},{y}) blends in a pixel of the hole");
                    }
                    blended += usize::from(!map.blends_at(x, y).is_empty());
                    changed += usize::from(out.get(x, y) != image.get(x, y));
                } else {
                    assert_eq!(out.get(x, y), image.get(x, y), "{name}: known pixel ({x},{y}) changed");
                    assert_eq!(src as usize, i, "{name}: known pixel ({x},{y}) is its own source");
                    assert!(map.blends_at(x, y).is_empty(), "{name}: known pixel ({x},{y}) is blended");
                }
            }
        }
        assert!(changed > 5000, "{name}: the hole was filled ({changed} pixels changed)");
        // Patch sampling feathers into what earlier blocks filled (the test can tell); the cuts never blend.
        let feathered = name == "ps" || name == "ps_exhaustive" || name == "ps_torus";
        assert_eq!(blended > 500, feathered, "{name}: {blended} pixels of the hole blended");
    }
    let m = json(&d.join("out/manifest.json"));
    let plain = m["jobs"].as_array().unwrap().iter().find(|j| j["id"] == "plain.toml").unwrap();
    assert!(plain["inpaint_mask"]["path"].as_str().unwrap().ends_with("cork_cable_mask.png"), "{plain}");
    assert!(plain["output_spec"]["inpaint"]["mask"]["pixels"].is_object(), "{plain}");
    assert!(plain["sample"]["path"].as_str().unwrap().ends_with("cork_cable.png"), "{plain}");
    run_ok(texsyn().arg("verify").arg(d.join("out/manifest.json")));
    run_ok(texsyn().args(["run", "-q", "-j", "1", "-o"]).arg(d.join("one")).arg(&jobs));
    let one = json(&d.join("one/manifest.json"));
    for (a, b) in m["jobs"].as_array().unwrap().iter().zip(one["jobs"].as_array().unwrap()) {
        assert_eq!(a["outputs"][0]["pixel_digest"], b["outputs"][0]["pixel_digest"], "{}: -j 1 = -j 2", a["id"]);
    }
}

/// `sample`/`samples` beside `[inpaint]`: the fill copies from them (and their turned copies),
/// the image's known pixels stay its own, and the image is a source only when listed, never
/// through its hole, not even turned. Checked through the version 2 source map, for quilting
/// and patch-sampling, with `verify`, `-j 1` and the one-off command.
#[test]
fn an_inpainting_job_copies_from_other_samples_never_from_the_hole() {
    let d = scratch("inpaint-samples");
    let jobs = d.join("jobs");
    std::fs::create_dir_all(&jobs).unwrap();
    let (left, right) = (abs("jobs/samples/guided/gravel_gray_left.png"), abs("jobs/samples/guided/gravel_gray_right.png"));
    let (w, h) = (128u32, 256u32);
    let hole = |x: u32, y: u32| {
        let (dx, dy) = ((f64::from(x) - 64.0) / 30.0, (f64::from(y) - 120.0) / 50.0);
        dx * dx + dy * dy <= 1.0 || (x < 30 && (200..240).contains(&y))
    };
    let mask = d.join("hole.png");
    texsyn::save_image(&texsyn::RgbImage::from_fn(w, h, |x, y| if hole(x, y) { [255; 3] } else { [0; 3] }), &mask).unwrap();
    let body = |name: &str, method: &str, samples: &str| {
        format!(
            "{samples}\nmethod = \"{method}\"\nseed = 5\n[inpaint]\nimage = \"{left}\"\nmask = \"{}\"\n[output]\npath = \"{name}.png\"\n\
             source_map = \"{name}.map.exr\"\n[params]\nblock = 24\n",
            mask.display()
        )
    };
    write(&jobs.join("other.toml"), &body("other", "quilting", &format!("sample = \"{right}\"")));
    let both = format!("samples = [\"{right}\", \"{left}\"]\naugment = [\"flip_h\", \"rot90\"]");
    write(&jobs.join("both.toml"), &body("both", "quilting", &both));
    write(&jobs.join("ps_both.toml"), &body("ps_both", "patch-sampling", &both));
    write(&jobs.join("own.toml"), &body("own", "quilting", "augment = [\"rot180\", \"flip_v\"]"));
    run_ok(texsyn().args(["run", "-q", "-j", "2", "-o"]).arg(d.join("out")).arg(&jobs));
    let image = rgb(Path::new(&left));
    for (name, image_used, other_used) in [("other", false, true), ("both", true, true), ("ps_both", true, true), ("own", true, false)] {
        let out = rgb(&d.join(format!("out/{name}.png")));
        let map = source_map::decode_map(&std::fs::read(d.join(format!("out/{name}.map.exr"))).unwrap()).unwrap();
        let atlas = map.atlas.as_ref().expect("a version 2 map");
        let p = &map.placement;
        let (aw, _) = p.sample_size();
        let mut used = std::collections::BTreeMap::new();
        for y in 0..h {
            for x in 0..w {
                let at = |s: u32| atlas.locate(s % aw, s / aw).unwrap_or_else(|| panic!("{name}: ({x}, {y}) copies a gutter"));
                if !hole(x, y) {
                    assert_eq!(out.get(x, y), image.get(x, y), "{name}: known pixel ({x}, {y}) changed");
                    let (piece, src) = at(p.source(x, y));
                    assert_eq!((piece.sample, piece.transform, src), (0, None, (x, y)), "{name}: known ({x}, {y}) is its own source");
                    continue;
                }
                let blends = p.blends_at(x, y);
                for s in std::iter::once(p.source(x, y)).chain(blends.iter().map(|b| b.source)) {
                    let (piece, (sx, sy)) = at(s);
                    if piece.sample == 0 {
                        assert!(!hole(sx, sy), "{name}: ({x}, {y}) copies ({sx}, {sy}) of the image, inside its hole");
                    }
                    *used.entry((piece.sample, piece.transform.is_some())).or_insert(0u32) += 1;
                }
            }
        }
        assert_eq!(used.keys().any(|k| k.0 == 0), image_used, "{name}: {used:?}");
        assert_eq!(used.keys().any(|k| k.0 == 1), other_used, "{name}: {used:?}");
        if name != "other" {
            assert!(used.keys().any(|k| k.1), "{name}: a turned copy is used: {used:?}");
        }
    }
    let m = manifest(&d.join("out"));
    let other = m["jobs"].as_array().unwrap().iter().find(|j| j["id"] == "other.toml").unwrap();
    assert_eq!(other["output_spec"]["inpaint"]["copy_from_image"], false, "{other}");
    assert!(other["samples"][0]["path"].as_str().unwrap().ends_with("gravel_gray_left.png"), "the image is sample 0: {other}");
    run_ok(texsyn().arg("verify").arg(d.join("out/manifest.json")));
    run_ok(texsyn().args(["run", "-q", "-j", "1", "-o"]).arg(d.join("one")).arg(&jobs));
    let one = manifest(&d.join("one"));
    for (a, b) in m["jobs"].as_array().unwrap().iter().zip(one["jobs"].as_array().unwrap()) {
        assert_eq!(a["outputs"][0]["pixel_digest"], b["outputs"][0]["pixel_digest"], "{}: -j 1 = -j 2", a["id"]);
    }
    // The one-off command writes the same job: `synth --inpaint IMAGE --mask M SAMPLE…`.
    let printed = text(&run_ok(texsyn().args(["synth", "--inpaint", &left, "--mask"]).arg(&mask).args([
        &right,
        "--seed",
        "5",
        "--set",
        "block=24",
        "-o",
        "x.png",
        "--print-job",
    ])));
    assert!(printed.contains(&format!("sample = \"{right}\"")) && printed.contains("[inpaint]"), "{printed}");
    let synth_out = d.join("synth/other.png");
    run_ok(
        texsyn()
            .args(["synth", "--inpaint", &left, "--mask"])
            .arg(&mask)
            .args([&right, "--seed", "5", "--set", "block=24", "--source-map", "-o"])
            .arg(&synth_out),
    );
    assert_eq!(pixels(&synth_out), pixels(&d.join("out/other.png")), "synth = the job file");
    // Companions: the image's map first, then one per other sample. With each map its image's
    // channels turned (r, g, b) -> (g, b, r), the companion is the output so turned, pixel for
    // pixel: every filled pixel's map comes from the sample (and copy) its colour came from.
    let turned = |img: &texsyn::RgbImage| {
        texsyn::RgbImage::from_fn(img.width(), img.height(), |x, y| {
            let p = img.get(x, y);
            [p[1], p[2], p[0]]
        })
    };
    let (left_map, right_map) = (d.join("left_map.png"), d.join("right_map.png"));
    texsyn::save_image(&turned(&image), &left_map).unwrap();
    texsyn::save_image(&turned(&rgb(Path::new(&right))), &right_map).unwrap();
    let companion = |name: &str, maps: &str| format!("[[companion]]\nsample = {maps}\npath = \"{name}_map.png\"\n");
    let pair = format!("[\"{}\", \"{}\"]", left_map.display(), right_map.display());
    let cjobs = d.join("companion-jobs");
    std::fs::create_dir_all(&cjobs).unwrap();
    write(&cjobs.join("other.toml"), &(body("other", "quilting", &format!("sample = \"{right}\"")) + &companion("other", &pair)));
    write(&cjobs.join("ps_both.toml"), &(body("ps_both", "patch-sampling", &both) + &companion("ps_both", &pair)));
    run_ok(texsyn().args(["run", "-q", "-o"]).arg(d.join("companions")).arg(&cjobs));
    for name in ["other", "ps_both"] {
        let out = rgb(&d.join(format!("companions/{name}.png")));
        assert_eq!(out, rgb(&d.join(format!("out/{name}.png"))), "{name}: a companion leaves the colours as they were");
        assert!(turned(&out) == rgb(&d.join(format!("companions/{name}_map.png"))), "{name}: the map follows the colours");
    }
    run_ok(texsyn().arg("verify").arg(d.join("companions/manifest.json")));
    // Refused by key: one map for two images to copy from, three for two.
    write(
        &cjobs.join("one.toml"),
        &(body("one", "quilting", &format!("sample = \"{right}\"")) + &companion("one", &format!("\"{}\"", left_map.display()))),
    );
    let three = format!("[\"{}\", \"{}\", \"{}\"]", left_map.display(), right_map.display(), right_map.display());
    write(&cjobs.join("three.toml"), &(body("three", "quilting", &format!("sample = \"{right}\"")) + &companion("three", &three)));
    let said = text(&run(texsyn().args(["run", "-o"]).arg(d.join("bad")).arg(&cjobs)));
    for expected in [
        "one.toml:13:1: `companion[1].sample`: with 2 images to copy from, give this map of each: a list, the [inpaint] image's map first",
        "three.toml:13:10: `companion[1].sample`: lists 3 maps for 2 images to copy from; give the [inpaint] image's map first",
    ] {
        assert!(said.contains(expected), "missing {expected:?} in:\n{said}");
    }
}

/// A 16-bit image with a companion map: outside the mask both outputs hold the inputs' exact
/// 16-bit samples; an RGBA image whose holes are its transparent pixels keeps every other pixel,
/// alpha included, and its holes become opaque.
#[test]
fn known_pixels_stay_bit_for_bit_at_16_bit_in_companions_and_with_alpha() {
    let d = scratch("inpaint-16");
    std::fs::create_dir_all(&d).unwrap();
    let image = rgb(&repo().join(IMAGE));
    let (w, h) = image.dimensions();
    // Genuinely 16-bit: the low byte is not a copy of the high one.
    let deep = |img: &texsyn::RgbImage, salt: u32| {
        image::ImageBuffer::<image::Rgb<u16>, Vec<u16>>::from_fn(w, h, |x, y| {
            let p = img.get(x, y);
            image::Rgb([0, 1, 2].map(|c| u16::from(p[c]) * 256 + ((x * 7 + y * 13 + c as u32 * 5 + salt) % 256) as u16))
        })
    };
    deep(&image, 0).save(d.join("deep.png")).unwrap();
    let companion = texsyn::RgbImage::from_fn(w, h, |x, y| [(x % 256) as u8, (y % 256) as u8, ((x + y) % 256) as u8]);
    deep(&companion, 99).save(d.join("deep_normal.png")).unwrap();
    let jobs = d.join("jobs");
    job(&jobs, "deep.toml", &d.join("deep.png").display().to_string(), &format!("mask = \"{}\"", abs(MASK)), "", "");
    let text = std::fs::read_to_string(jobs.join("deep.toml")).unwrap();
    std::fs::write(
        jobs.join("deep.toml"),
        format!("{text}\n[[companion]]\nsample = \"{}\"\npath = \"deep_normal.png\"\n", d.join("deep_normal.png").display()),
    )
    .unwrap();
    job(&jobs, "alpha.toml", &abs(HOLES), "channel = \"a\"", "", "");
    // The same with patch sampling (feathered: its blends come from known pixels too).
    let ps = text.replace("method = \"quilting\"", "method = \"patch-sampling\"").replace("path = \"deep.png\"", "path = \"deep_ps.png\"");
    std::fs::write(
        jobs.join("deep_ps.toml"),
        format!("{ps}\n[[companion]]\nsample = \"{}\"\npath = \"deep_ps_normal.png\"\n", d.join("deep_normal.png").display()),
    )
    .unwrap();
    let alpha = std::fs::read_to_string(jobs.join("alpha.toml")).unwrap();
    std::fs::write(
        jobs.join("alpha_ps.toml"),
        alpha.replace("method = \"quilting\"", "method = \"patch-sampling\"").replace("path = \"alpha.png\"", "path = \"alpha_ps.png\""),
    )
    .unwrap();
    run_ok(texsyn().args(["run", "-q", "-o"]).arg(d.join("out")).arg(&jobs));
    let fill = mask_flags();
    let decode = |p: &Path| texsyn::image::io::decode_output(&std::fs::read(p).unwrap(), Default::default()).unwrap();
    for (input, output) in [
        ("deep.png", "out/deep.png"),
        ("deep_normal.png", "out/deep_normal.png"),
        ("deep.png", "out/deep_ps.png"),
        ("deep_normal.png", "out/deep_ps_normal.png"),
    ] {
        let (a, b) = (decode(&d.join(input)), decode(&d.join(output)));
        let (texsyn::image::io::Samples::U16(a), texsyn::image::io::Samples::U16(b)) = (&a.samples, &b.samples) else {
            panic!("{output} is 16-bit like its input")
        };
        let (mut same, mut differ) = (0, 0);
        for (i, (pa, pb)) in a.chunks_exact(3).zip(b.chunks_exact(3)).enumerate() {
            if fill[i] {
                differ += usize::from(pa != pb);
            } else {
                assert_eq!(pa, pb, "{output}: known pixel {i} changed");
                same += 1;
            }
        }
        assert!(same > 50_000 && differ > 5000, "{output}: {same} kept, {differ} filled");
    }
    for output in ["out/alpha.png", "out/alpha_ps.png"] {
        let (a, b) = (decode(&repo().join(HOLES)), decode(&d.join(output)));
        assert_eq!((a.channels, b.channels), (4, 4));
        let (texsyn::image::io::Samples::U8(a), texsyn::image::io::Samples::U8(b)) = (&a.samples, &b.samples) else { panic!("8-bit RGBA") };
        let mut holes = 0;
        for (pa, pb) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
            if pa[3] < 128 {
                holes += 1;
                assert_eq!(pb[3], 255, "{output}: a filled pixel is opaque");
                assert_ne!(&pb[..3], &[255, 0, 255], "{output}: no hole colour is copied");
            } else {
                assert_eq!(pa, pb, "{output}: a known pixel keeps its colour and alpha");
            }
        }
        assert!(holes > 3000, "{output}: {holes}");
    }
    run_ok(texsyn().arg("verify").arg(d.join("out/manifest.json")));
}

/// The filled hole looks like its surroundings: its gray level and contrast are those of the
/// known image (a hole filled with the cable's black or a flat colour would fail), and the steps
/// across the hole's border are within a small factor of the image's own neighbour steps.
#[test]
fn the_filled_hole_has_the_texture_of_its_surroundings() {
    let d = scratch("inpaint-stats");
    job(&d.join("jobs"), "h.toml", &abs(IMAGE), &format!("mask = \"{}\"", abs(MASK)), "", "");
    run_ok(texsyn().args(["run", "-q", "-o"]).arg(d.join("out")).arg(d.join("jobs")));
    let out = rgb(&d.join("out/h.png"));
    let fill = mask_flags();
    let (w, h) = out.dimensions();
    let gray = |x: u32, y: u32| out.get(x, y).iter().map(|&c| f64::from(c)).sum::<f64>() / 3.0;
    let stats = |inside: bool| {
        let v: Vec<f64> = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .filter(|&(x, y)| fill[(y * w + x) as usize] == inside)
            .map(|(x, y)| gray(x, y))
            .collect();
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        (mean, (v.iter().map(|g| (g - mean).powi(2)).sum::<f64>() / v.len() as f64).sqrt())
    };
    let ((hole_mean, hole_sd), (known_mean, known_sd)) = (stats(true), stats(false));
    assert!((hole_mean - known_mean).abs() < 0.05 * known_mean, "mean {hole_mean:.1} vs {known_mean:.1}");
    assert!((hole_sd / known_sd - 1.0).abs() < 0.25, "contrast {hole_sd:.1} vs {known_sd:.1}");
    // Neighbour steps across the border against those of the known image away from it.
    let step = |a: (u32, u32), b: (u32, u32)| (gray(a.0, a.1) - gray(b.0, b.1)).abs();
    let (mut border, mut known) = (Vec::new(), Vec::new());
    for y in 0..h - 1 {
        for x in 0..w - 1 {
            let i = (y * w + x) as usize;
            for (nx, ny) in [(x + 1, y), (x, y + 1)] {
                let j = (ny * w + nx) as usize;
                match (fill[i], fill[j]) {
                    (true, false) | (false, true) => border.push(step((x, y), (nx, ny))),
                    (false, false) => known.push(step((x, y), (nx, ny))),
                    _ => {}
                }
            }
        }
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let (b, k) = (mean(&border), mean(&known));
    assert!(b < 2.5 * k, "steps across the hole's border {b:.2} against {k:.2} in the known image");
}

/// A changed mask reruns the job and `diff` says the mask changed.
#[test]
fn a_changed_inpaint_mask_reruns_the_job_and_diff_says_so() {
    let d = scratch("inpaint-changed");
    std::fs::create_dir_all(&d).unwrap();
    let mask = d.join("mask.png");
    std::fs::copy(repo().join(MASK), &mask).unwrap();
    job(&d.join("jobs"), "m.toml", &abs(IMAGE), &format!("mask = \"{}\"", mask.display()), "", "");
    run_ok(texsyn().args(["run", "-q", "-o"]).arg(d.join("a")).arg(d.join("jobs")));
    let mut img = rgb(&mask);
    for y in 200..230 {
        for x in 150..200 {
            img.put(x, y, [255, 255, 255]);
        }
    }
    texsyn::save_image(&img, &mask).unwrap();
    std::fs::copy(d.join("a/manifest.json"), d.join("a.json")).unwrap();
    let again = text(&run_ok(texsyn().args(["run", "-o"]).arg(d.join("a")).arg(d.join("jobs"))));
    assert!(again.contains("ran 1"), "{again}");
    let said = text(&run(texsyn().arg("diff").arg(d.join("a.json")).arg(d.join("a/manifest.json"))));
    assert!(said.contains("mask changed (inpaint.mask.pixels"), "{said}");
}

#[test]
fn bad_inpaint_jobs_are_refused_by_key_and_an_empty_mask_only_warns() {
    let d = scratch("inpaint-bad");
    std::fs::create_dir_all(&d).unwrap();
    let jobs = d.join("jobs");
    let save = |name: &str, w: u32, h: u32, f: &dyn Fn(u32, u32) -> bool| {
        let p = d.join(name);
        texsyn::save_image(&texsyn::RgbImage::from_fn(w, h, |x, y| if f(x, y) { [255; 3] } else { [0; 3] }), &p).unwrap();
        format!("mask = \"{}\"", p.display())
    };
    job(&jobs, "size.toml", &abs(IMAGE), &save("small.png", 64, 48, &|_, _| true), "", "");
    job(&jobs, "white.toml", &abs(IMAGE), &save("white.png", 256, 256, &|_, _| true), "", "");
    job(&jobs, "empty.toml", &abs(IMAGE), &save("black.png", 256, 256, &|_, _| false), "", "");
    // Only a 20-pixel band is known: no whole 32-pixel block outside the hole.
    job(&jobs, "block.toml", &abs(IMAGE), &save("band.png", 256, 256, &|_, y| !(100..120).contains(&y)), "", "");
    job(&jobs, "channel.toml", &abs(HOLES), "channel = \"aa\"", "", "");
    job(&jobs, "noalpha.toml", &abs(IMAGE), "channel = \"a\"", "", "");
    job(&jobs, "both.toml", &abs(IMAGE), &format!("mask = \"{}\"\nchannel = \"a\"", abs(MASK)), "", "");
    job(&jobs, "missing.toml", &abs(IMAGE), "mask = \"nowhere/mask.png\"", "", "");
    job(&jobs, "outsize.toml", &abs(IMAGE), &format!("mask = \"{}\"", abs(MASK)), "width = 300\nheight = 256", "");
    let text_of = |p: &Path| std::fs::read_to_string(p).unwrap();
    job(&jobs, "method.toml", &abs(IMAGE), &format!("mask = \"{}\"", abs(MASK)), "", "");
    std::fs::write(
        jobs.join("method.toml"),
        text_of(&jobs.join("method.toml")).replace("quilting", "wang-tiles").replace("block = 32", ""),
    )
    .unwrap();
    job(&jobs, "good.toml", &abs(IMAGE), &format!("mask = \"{}\"", abs(MASK)), "", "");
    let started = std::time::Instant::now();
    let said = text(&run(texsyn().args(["run", "-o"]).arg(d.join("out")).arg(&jobs)));
    assert!(started.elapsed().as_secs() < 30, "refusals are quick");
    for expected in [
        "size.toml:5:1: `inpaint.mask`: inpaint mask",
        "is 64x48 but the image",
        "is 256x256; the mask must have the image's size",
        "white.toml:5:1: `inpaint.mask`: inpaint mask",
        "is white everywhere: the whole image would be filled and nothing is left to copy from",
        "block.toml:5:1: `inpaint.mask`: the image outside the inpaint mask leaves no whole 32x32 block (params.block) to copy from; \
         the largest block it leaves is 20",
        "channel.toml:5:11: `inpaint.channel`: unknown channel `aa` (did you mean `a`?)",
        "noalpha.toml:5:1: `inpaint.channel`: image",
        "has no alpha channel (8-bit RGB)",
        "both.toml:3:1: `inpaint.channel`: give either `mask` (an image) or `channel`",
        "missing.toml:5:8: `inpaint.mask`: mask",
        "outsize.toml:8:1: `output.width`: an inpainting job's output has its image's size",
        "is 256x256 but the output asks for 300x256",
        "method.toml:3:1: `inpaint`: wang-tiles cannot inpaint; methods that can: quilting, patch-sampling",
    ] {
        assert!(said.contains(expected), "missing {expected:?} in:\n{said}");
    }
    let m = json(&d.join("out/manifest.json"));
    let find = |id: &str| m["jobs"].as_array().unwrap().iter().find(|j| j["id"] == id).unwrap().clone();
    assert_eq!(find("good.toml")["status"], "ok");
    let empty = find("empty.toml");
    assert_eq!(empty["status"], "ok", "{empty}");
    assert!(empty["warnings"].to_string().contains("marks no pixel to fill"), "{empty}");
    assert_eq!(empty["outputs"][0]["pixel_digest"]["sha256"], pixels(&repo().join(IMAGE)), "nothing to fill: the image itself");
}

/// The report shows the mask beside the image and the repaired output: on the contact sheet and
/// on the page, as a figure of its own.
#[test]
fn the_report_shows_the_mask_between_the_image_and_the_output() {
    let d = scratch("inpaint-report");
    job(&d.join("jobs"), "h.toml", &abs(IMAGE), &format!("mask = \"{}\"", abs(MASK)), "", "");
    run_ok(texsyn().args(["run", "-q", "-o"]).arg(d.join("out")).arg(d.join("jobs")));
    run_ok(texsyn().arg("report").arg(d.join("out/manifest.json")).arg("--out").arg(d.join("report")));
    let html = std::fs::read_to_string(d.join("report/index.html")).unwrap();
    let input = html.find("data-role=\"input\"").expect("a figure for the mask");
    let figure = &html[input..input + html[input..].find("</figure>").unwrap()];
    assert!(figure.contains("<b>inpaint mask</b>") && figure.contains("cork_cable_mask.png"), "{figure}");
    let src = figure.split("src=\"").nth(1).unwrap().split('"').next().unwrap();
    assert_eq!(rgb(&d.join("report").join(src)), rgb(&repo().join(MASK)), "the mask's own pixels");
    assert!(input < html.find("<figure data-group=").unwrap(), "the mask comes before the output");
}

/// A hole many blocks wide (pebbles enlarged 2×, a 200×150 hole, blocks of 40) shows no block
/// grid: inside the hole, no column or row of neighbour steps stands out from the others, as a
/// straight seam along a block's edge would (the image's own worst line is about 1.6× the
/// median line; blocks whose filled rim pixels were free to change took their whole window,
/// leaving straight seams at 4–10×). And the steps across the hole's border stay near the
/// image's own.
#[test]
fn a_large_hole_shows_no_block_grid_and_no_outline() {
    let d = scratch("inpaint-grid");
    let sample = rgb(&repo().join("jobs/samples/pebbles_beige.png"));
    let image = enlarged(&sample, 2, 512, 512);
    let (x0, y0, x1, y1) = (150u32, 170u32, 350u32, 320u32);
    let hole = |x: u32, y: u32| (x0..x1).contains(&x) && (y0..y1).contains(&y);
    write_png(&d.join("image.png"), &image);
    write_png(&d.join("mask.png"), &texsyn::RgbImage::from_fn(512, 512, |x, y| if hole(x, y) { [255; 3] } else { [0; 3] }));
    let mask_line = format!("mask = \"{}\"", d.join("mask.png").display());
    job(&d.join("jobs"), "h.toml", &d.join("image.png").display().to_string(), &mask_line, "", "block = 40\n");
    let text = std::fs::read_to_string(d.join("jobs/h.toml")).unwrap().replace("block = 32\n", "");
    std::fs::write(d.join("jobs/h.toml"), text).unwrap();
    run_ok(texsyn().args(["run", "-q", "-o"]).arg(d.join("out")).arg(d.join("jobs")));
    let out = rgb(&d.join("out/h.png"));
    let gray = |x: u32, y: u32| out.get(x, y).iter().map(|&c| f64::from(c)).sum::<f64>() / 3.0;
    let step = |a: (u32, u32), b: (u32, u32)| (gray(a.0, a.1) - gray(b.0, b.1)).abs();
    // Mean horizontal step per column pair and vertical step per row pair, 3 px inside the hole.
    let columns: Vec<f64> =
        (x0 + 3..x1 - 4).map(|x| (y0 + 3..y1 - 3).map(|y| step((x, y), (x + 1, y))).sum::<f64>() / f64::from(y1 - y0 - 6)).collect();
    let rows: Vec<f64> =
        (y0 + 3..y1 - 4).map(|y| (x0 + 3..x1 - 3).map(|x| step((x, y), (x, y + 1))).sum::<f64>() / f64::from(x1 - x0 - 6)).collect();
    let worst = |v: &[f64]| {
        let mut s = v.to_vec();
        s.sort_by(f64::total_cmp);
        s[s.len() - 1] / s[s.len() / 2]
    };
    let (c, r) = (worst(&columns), worst(&rows));
    assert!(c < 2.6 && r < 2.6, "the worst column / row of steps inside the hole is {c:.2} / {r:.2} × the median: a straight seam");
    let (mut border, mut known) = (Vec::new(), Vec::new());
    for y in 0..511 {
        for x in 0..511 {
            for (nx, ny) in [(x + 1, y), (x, y + 1)] {
                match (hole(x, y), hole(nx, ny)) {
                    (true, false) | (false, true) => border.push(step((x, y), (nx, ny))),
                    (false, false) => known.push(step((x, y), (nx, ny))),
                    _ => {}
                }
            }
        }
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let (b, k) = (mean(&border), mean(&known));
    assert!(b < 3.0 * k, "steps across the hole's border {b:.2} against {k:.2} in the known image");
}

/// Quilting's and patch sampling's inpainting and patch sampling's syntheses from turned copies
/// changed their pixels (issue #28) while plain syntheses kept theirs: those jobs carry their own
/// algorithm version, so an older record of one is re-made by `run` and reported by `verify`
/// naming both versions, and plain jobs keep version 1.
#[test]
fn inpainting_and_copies_have_their_own_algorithm_version() {
    let d = scratch("inpaint-version");
    let jobs = d.join("jobs");
    let ps = |s: &str| s.replace("method = \"quilting\"", "method = \"patch-sampling\"");
    job(&jobs, "quilting.toml", &abs(IMAGE), &format!("mask = \"{}\"", abs(MASK)), "", "");
    job(&jobs, "ps.toml", &abs(IMAGE), &format!("mask = \"{}\"", abs(MASK)), "", "");
    std::fs::write(jobs.join("ps.toml"), ps(&std::fs::read_to_string(jobs.join("ps.toml")).unwrap())).unwrap();
    let sample = abs("jobs/samples/pebbles_beige.png");
    let plain =
        format!("sample = \"{sample}\"\nmethod = \"patch-sampling\"\nseed = 1\n[output]\npath = \"plain.png\"\nwidth = 96\nheight = 96\n");
    std::fs::write(jobs.join("plain.toml"), &plain).unwrap();
    std::fs::write(
        jobs.join("copies.toml"),
        plain.replace("seed = 1\n", "seed = 1\naugment = [\"flip_h\"]\n").replace("plain.png", "copies.png"),
    )
    .unwrap();
    run_ok(texsyn().args(["run", "-q", "-o"]).arg(d.join("out")).arg(&jobs));
    let m = manifest(&d.join("out"));
    let version = |id: &str| m["jobs"].as_array().unwrap().iter().find(|j| j["id"] == id).unwrap()["algorithm_version"].clone();
    assert_eq!(version("plain.toml"), 1, "a plain synthesis keeps version 1");
    for id in ["quilting.toml", "ps.toml"] {
        assert_eq!(version(id), 9, "{id}: hole fills from the border inwards");
    }
    assert_eq!(version("copies.toml"), 3, "turned copies without a hole keep their version");
    // An older texsyn recorded the inpainting job as version 1.
    let path = d.join("out/manifest.json");
    let mut old: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    for j in old["jobs"].as_array_mut().unwrap().iter_mut().filter(|j| j["id"] == "ps.toml") {
        j["algorithm_version"] = 1.into();
    }
    std::fs::write(&path, serde_json::to_string_pretty(&old).unwrap()).unwrap();
    let said = text(&run(texsyn().arg("verify").arg(&path)));
    assert!(
        said.contains("recorded with patch-sampling algorithm version 1; this texsyn makes these parameters' pixels with version 9"),
        "{said}"
    );
}

/// A large hole in its own image has only a few strips to copy from; picked for their match
/// alone, quilting's blocks came back to the same patches (a radius-85 hole in cork, block 50:
/// 34 % of the filled pixels distinct sample pixels, one pixel copied 15 times, a visible grid of
/// one pore). Blocks that repeat little of what the hole already copied come first: measured
/// through the source map, 52 % distinct and at most 7 copies of a pixel.
#[test]
fn a_large_hole_does_not_repeat_the_same_patches() {
    let d = scratch("inpaint-reuse");
    let jobs = d.join("jobs");
    std::fs::create_dir_all(&jobs).unwrap();
    let image = abs("jobs/samples/cork.png");
    let (w, h) = rgb(Path::new(&image)).dimensions();
    let hole = |x: u32, y: u32| (f64::from(x) - 128.0).powi(2) + (f64::from(y) - 128.0).powi(2) <= 85.0 * 85.0;
    let mask = d.join("hole.png");
    texsyn::save_image(&texsyn::RgbImage::from_fn(w, h, |x, y| if hole(x, y) { [255; 3] } else { [0; 3] }), &mask).unwrap();
    write(
        &jobs.join("h.toml"),
        &format!(
            "method = \"quilting\"\nseed = 1\n[inpaint]\nimage = \"{image}\"\nmask = \"{}\"\n[output]\npath = \"h.png\"\nsource_map = \"h.map.exr\"\n",
            mask.display()
        ),
    );
    run_ok(texsyn().args(["run", "-q", "-o"]).arg(d.join("out")).arg(&jobs));
    let map = source_map::decode_map(&std::fs::read(d.join("out/h.map.exr")).unwrap()).unwrap();
    let mut copies = std::collections::HashMap::new();
    let mut filled = 0usize;
    for y in 0..h {
        for x in 0..w {
            if hole(x, y) {
                *copies.entry(map.placement.source(x, y)).or_insert(0u32) += 1;
                filled += 1;
            }
        }
    }
    let distinct = copies.len() as f64 / filled as f64;
    let most = copies.values().max().copied().unwrap_or(0);
    assert!(distinct > 0.45, "{:.0} % of the filled pixels are distinct sample pixels", 100.0 * distinct);
    assert!(most <= 10, "one sample pixel is copied {most} times");
}

/// The advice of an inpainting job reads the texture around the hole, not the hole's paint: a
/// magenta disc in cork, analysed with the image, reads as flat overlap bands and large features
/// (`advise` of the painted image asks for block = 128, which no longer fits beside the hole);
/// the job's warnings come from the largest rectangle outside the hole, where cork fits quilting.
#[test]
fn an_inpainting_jobs_advice_ignores_the_holes_paint() {
    let d = scratch("inpaint-advice");
    let jobs = d.join("jobs");
    std::fs::create_dir_all(&jobs).unwrap();
    let cork = rgb(&repo().join("jobs/samples/cork.png"));
    let (w, h) = cork.dimensions();
    let hole = |x: u32, y: u32| (f64::from(x) - 128.0).powi(2) + (f64::from(y) - 128.0).powi(2) <= 85.0 * 85.0;
    let (image, mask) = (d.join("painted.png"), d.join("hole.png"));
    texsyn::save_image(&texsyn::RgbImage::from_fn(w, h, |x, y| if hole(x, y) { [255, 0, 255] } else { cork.get(x, y) }), &image).unwrap();
    texsyn::save_image(&texsyn::RgbImage::from_fn(w, h, |x, y| if hole(x, y) { [255; 3] } else { [0; 3] }), &mask).unwrap();
    let whole = text(&run_ok(texsyn().arg("advise").arg(&image)));
    assert!(whole.contains("almost no contrast") && whole.contains("block = 128"), "the painted image read whole: {whole}");
    write(
        &jobs.join("h.toml"),
        &format!(
            "method = \"quilting\"\nseed = 1\n[inpaint]\nimage = \"{}\"\nmask = \"{}\"\n[output]\npath = \"h.png\"\n",
            image.display(),
            mask.display()
        ),
    );
    run_ok(texsyn().args(["run", "-q", "-o"]).arg(d.join("out")).arg(&jobs));
    let rec = &manifest(&d.join("out"))["jobs"][0];
    let warnings = rec["warnings"].to_string();
    assert!(!warnings.contains("no contrast") && !warnings.contains("block = 128"), "{warnings}");
}

/// A hole across a joint of a wall is filled with the joint running through it: the blocks are
/// made from the hole's border inwards, so the block in the middle meets the joint on both sides.
/// In raster order (over a grid that also covers a second hole below) the joint, a dark mortar
/// line 66 px inside an 89-px disc of a stone wall that is not bundled, ran through 55 to 62 of
/// the disc's 85 columns on seeds 1–3 and ended in the middle in a block of another stone.
#[test]
fn a_joint_across_the_hole_runs_through_the_fill() {
    let d = scratch("inpaint-joint");
    let jobs = d.join("jobs");
    std::fs::create_dir_all(&jobs).unwrap();
    let wall = rgb(&repo().join("tests/fixtures/structured/stk_generic_greyWall_a.png"));
    let (w, h) = wall.dimensions();
    // The disc, (77, 77)–(166, 159), where the joint is the darkest row of the wall (y = 143), and
    // a strip below it on the left.
    let hole = |x: u32, y: u32| {
        let disc = (f64::from(x) - 121.5).powi(2) / 44.5f64.powi(2) + (f64::from(y) - 118.0).powi(2) / 41.0f64.powi(2) <= 1.0;
        disc || ((13..=76).contains(&x) && (192..=217).contains(&y))
    };
    let (image, mask) = (d.join("wall.png"), d.join("hole.png"));
    write_png(&image, &texsyn::RgbImage::from_fn(w, h, |x, y| if hole(x, y) { [255, 0, 255] } else { wall.get(x, y) }));
    write_png(&mask, &texsyn::RgbImage::from_fn(w, h, |x, y| if hole(x, y) { [255; 3] } else { [0; 3] }));
    let luma = |img: &texsyn::RgbImage, x: u32, y: u32| img.get(x, y).iter().map(|&c| u32::from(c)).sum::<u32>() / 3;
    let joint = |img: &texsyn::RgbImage, x: u32| (138..150).map(|y| luma(img, x, y)).min().unwrap() < 100;
    assert!((80..165).all(|x| joint(&wall, x)), "the intact wall has the joint across the hole");
    for seed in 1..=3 {
        write(
            &jobs.join(format!("s{seed}.toml")),
            &format!(
                "method = \"quilting\"\nseed = {seed}\n[inpaint]\nimage = \"{}\"\nmask = \"{}\"\n[output]\npath = \"s{seed}.png\"\n",
                image.display(),
                mask.display()
            ),
        );
    }
    run_ok(texsyn().args(["run", "-q", "-o"]).arg(d.join("out")).arg(&jobs));
    for seed in 1..=3 {
        let out = rgb(&d.join(format!("out/s{seed}.png")));
        let across = (80..165).filter(|&x| joint(&out, x)).count();
        assert!(across >= 80, "seed {seed}: the joint runs through {across} of the hole's 85 columns");
    }
}
