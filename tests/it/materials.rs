//! Materials end to end (issue: companions, native precision, source maps, `texsyn apply`): a job
//! with companions writes them with the main output's placement; 16-bit and float samples keep
//! their values where pixels are copied; RGBA stays RGBA; the source map replays every method's
//! output exactly; bad companions and maps get clear errors without losing the other jobs.

use crate::common::*;
use texsyn::batch::source_map;
use texsyn::image::io::{Encoding, Format, NativeImage, Samples, encode_native};
use texsyn::synth::placement::UNCOVERED;

fn save(path: &Path, img: &NativeImage, format: Format, bit_depth: u8) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, encode_native(img, Encoding { format, bit_depth }).unwrap().bytes).unwrap();
}

fn decode(path: &Path) -> NativeImage {
    imageio::decode_native(&std::fs::read(path).unwrap(), DecodeLimits::default()).unwrap()
}

/// A textured 16-bit RGB sample whose values are (almost all) not multiples of 257.
fn sample16(w: u32, h: u32) -> NativeImage {
    let v: Vec<u16> = (0..h)
        .flat_map(|y| {
            (0..w).flat_map(move |x| {
                (0..3u32).map(move |c| ((x / 6 + y / 9) % 2 * 30_000 + (x * 997 + y * 131 + c * 7919) % 9000 + 1) as u16)
            })
        })
        .collect();
    NativeImage { width: w, height: h, channels: 3, samples: Samples::U16(v) }
}

fn job(dir: &Path, name: &str, body: &str) {
    write(&dir.join(name), body);
}

/// The sample pixel (index) every output pixel of a copy-only placement comes from.
fn sources(map: &Path) -> (texsyn::synth::placement::Placement, Vec<u32>) {
    let p = source_map::decode(&std::fs::read(map).unwrap()).unwrap();
    let s = p.sources().to_vec();
    (p, s)
}

#[test]
fn sixteen_bit_samples_keep_their_exact_values_and_companions_follow_the_placement() {
    let d = scratch("mat16");
    let s = sample16(96, 96);
    save(&d.join("in/height16.png"), &s, Format::Png, 16);
    // A companion: the same pattern shifted in value, 8-bit gray.
    let gray: Vec<u8> = (0..96 * 96).map(|i| (i * 7 % 251) as u8).collect();
    save(&d.join("in/gloss.png"), &NativeImage { width: 96, height: 96, channels: 1, samples: Samples::U8(gray.clone()) }, Format::Png, 8);
    job(
        &d.join("jobs"),
        "h.toml",
        &format!(
            "sample = \"{0}/in/height16.png\"\nmethod = \"quilting\"\nseed = 4\n[output]\npath = \"h/height.png\"\nwidth = 150\nheight = 140\nsource_map = \"h/map.exr\"\n[params]\nblock = 32\n[[companion]]\nsample = \"{0}/in/gloss.png\"\npath = \"h/gloss.png\"\n",
            d.display()
        ),
    );
    let out = d.join("out");
    run_ok(texsyn().args(["run", "-j", "2"]).arg(d.join("jobs")).arg("-o").arg(&out));
    let main = decode(&out.join("h/height.png"));
    let Samples::U16(px) = &main.samples else { panic!("a 16-bit sample gives a 16-bit output by default, got {:?}", main.samples) };
    let Samples::U16(sp) = &s.samples else { unreachable!() };
    let (p, src) = sources(&out.join("h/map.exr"));
    assert!(!p.has_blends(), "quilting with its cut only copies");
    let mut checked = 0;
    for (i, &k) in src.iter().enumerate() {
        assert_ne!(k, UNCOVERED);
        assert_eq!(&px[i * 3..i * 3 + 3], &sp[k as usize * 3..k as usize * 3 + 3], "output pixel {i} is not its sample pixel");
        checked += 1;
    }
    assert_eq!(checked, 150 * 140);
    assert!(px.iter().any(|v| v % 257 != 0), "values between the 8-bit levels survive");
    // The gray companion: gray, 8-bit, the same sample pixels.
    let g = decode(&out.join("h/gloss.png"));
    assert_eq!(g.channels, 1);
    let Samples::U8(gp) = &g.samples else { panic!("8-bit companion") };
    assert!(src.iter().zip(gp).all(|(&k, &v)| gray[k as usize] == v));
    // Recorded, verified, and reproduced by apply.
    let m = manifest(&out);
    let paths: Vec<&str> = m["jobs"][0]["outputs"].as_array().unwrap().iter().map(|o| o["path"].as_str().unwrap()).collect();
    assert_eq!(paths, ["h/height.png", "h/gloss.png", "h/map.exr"]);
    run_ok(texsyn().arg("verify").arg(out.join("manifest.json")));
    run_ok(texsyn().arg("apply").arg(out.join("h/map.exr")).arg(d.join("in/height16.png")).arg("-o").arg(d.join("applied.png")));
    assert_eq!(pixels(&d.join("applied.png")), pixels(&out.join("h/height.png")));
    // Asking for 8 bits quantises (and says so by its depth).
    run_ok(
        texsyn()
            .arg("apply")
            .arg(out.join("h/map.exr"))
            .arg(d.join("in/height16.png"))
            .args(["--bit-depth", "8", "-o"])
            .arg(d.join("applied8.png")),
    );
    assert!(matches!(decode(&d.join("applied8.png")).samples, Samples::U8(_)));
}

#[test]
fn float_samples_keep_values_above_one_and_below_zero() {
    let d = scratch("matexr");
    let (w, h) = (80u32, 80u32);
    let v: Vec<f32> = (0..h)
        .flat_map(|y| (0..w).flat_map(move |x| (0..3u32).map(move |c| ((x * 37 + y * 11 + c * 5) % 100) as f32 / 25.0 - 0.5)))
        .collect();
    let s = NativeImage { width: w, height: h, channels: 3, samples: Samples::F32(v.clone()) };
    save(&d.join("in/sky.exr"), &s, Format::Exr, 32);
    for (name, method, extra) in [("q", "quilting", "block = 24"), ("p", "patch-sampling", "block = 24")] {
        job(
            &d.join("jobs"),
            &format!("{name}.toml"),
            &format!(
                "sample = \"{}/in/sky.exr\"\nmethod = \"{method}\"\nseed = 2\n[output]\npath = \"{name}.exr\"\nwidth = 100\nheight = 90\nsource_map = \"{name}.map.exr\"\n[params]\n{extra}\n",
                d.display()
            ),
        );
    }
    let out = d.join("out");
    run_ok(texsyn().arg("run").arg(d.join("jobs")).arg("-o").arg(&out));
    for name in ["q", "p"] {
        let o = decode(&out.join(format!("{name}.exr")));
        let Samples::F32(px) = &o.samples else { panic!("float out") };
        assert!(px.iter().any(|&x| x > 1.0) && px.iter().any(|&x| x < 0.0), "{name}: HDR and negative values kept");
        let (p, src) = sources(&out.join(format!("{name}.map.exr")));
        let mut copied = 0;
        for y in 0..90 {
            for x in 0..100 {
                let i = (y * 100 + x) as usize;
                if p.blends_at(x, y).is_empty() {
                    let k = src[i] as usize;
                    assert_eq!(&px[i * 3..i * 3 + 3], &v[k * 3..k * 3 + 3], "{name}: copied pixel ({x}, {y})");
                    copied += 1;
                }
            }
        }
        assert!(copied > 100 * 90 / 2, "{name}: most pixels are copies");
    }
    run_ok(texsyn().arg("verify").arg(out.join("manifest.json")));
}

#[test]
fn rgba_samples_give_rgba_outputs() {
    let d = scratch("matrgba");
    let data: Vec<u8> =
        (0..64u32 * 64).flat_map(|i| [(i % 64 * 4) as u8, (i / 64 * 4) as u8, (i * 13 % 256) as u8, (i * 7 % 256) as u8]).collect();
    save(&d.join("in/leaf.png"), &NativeImage { width: 64, height: 64, channels: 4, samples: Samples::U8(data) }, Format::Png, 8);
    job(
        &d.join("jobs"),
        "a.toml",
        &format!(
            "sample = \"{}/in/leaf.png\"\nmethod = \"quilting\"\nseed = 1\n[output]\npath = \"a.png\"\nwidth = 90\nheight = 70\n[params]\nblock = 20\n",
            d.display()
        ),
    );
    let out = d.join("out");
    run_ok(texsyn().arg("run").arg(d.join("jobs")).arg("-o").arg(&out));
    let o = decode(&out.join("a.png"));
    assert_eq!((o.channels, o.width, o.height), (4, 90, 70));
    let Samples::U8(px) = &o.samples else { panic!() };
    assert!(px.chunks(4).any(|p| p[3] != 255), "alpha carried over");
}

/// `apply` of each method's recorded map over its sample reproduces its output, for every method.
#[test]
fn apply_reproduces_every_methods_output_from_its_source_map() {
    let d = scratch("matapply");
    let samples = repo().join("jobs/samples");
    let cases = [
        ("quilting", "crops/pebbles_beige_128.png", ""),
        ("double-seam", "crops/pebbles_beige_128.png", "block = 32"),
        ("patch-sampling", "crops/hedge_leaves_128.png", ""),
        ("coevolution", "tiles_terracotta.png", ""),
        ("tes", "tiles_terracotta.png", ""),
        ("wang-tiles", "bricks_gray.png", ""),
        ("rw-tiles", "bricks_gray.png", ""),
    ];
    for (method, sample, params) in cases {
        job(
            &d.join("jobs"),
            &format!("{method}.toml"),
            &format!(
                "sample = \"{}\"\nmethod = \"{method}\"\nseed = 6\n[output]\npath = \"{method}.png\"\nwidth = 200\nheight = 180\nsource_map = \"{method}.map.exr\"\n[params]\n{params}\n",
                samples.join(sample).display()
            ),
        );
    }
    let out = d.join("out");
    run_ok(texsyn().arg("run").arg(d.join("jobs")).arg("-o").arg(&out));
    for (method, sample, _) in cases {
        let applied = d.join(format!("{method}.applied.png"));
        run_ok(texsyn().arg("apply").arg(out.join(format!("{method}.map.exr"))).arg(samples.join(sample)).arg("-o").arg(&applied));
        assert_eq!(pixels(&applied), pixels(&out.join(format!("{method}.png"))), "{method}: apply differs from the output");
    }
    // The same job without a source map has the same main output (the placement never changes pixels).
    let plain = d.join("plain");
    for (method, sample, params) in &cases[..3] {
        job(
            &plain,
            &format!("{method}.toml"),
            &format!(
                "sample = \"{}\"\nmethod = \"{method}\"\nseed = 6\n[output]\npath = \"{method}.png\"\nwidth = 200\nheight = 180\n[params]\n{params}\n",
                samples.join(sample).display()
            ),
        );
    }
    run_ok(texsyn().arg("run").arg(&plain).arg("-o").arg(d.join("plain-out")));
    for (method, _, _) in &cases[..3] {
        assert_eq!(pixels(&d.join("plain-out").join(format!("{method}.png"))), pixels(&out.join(format!("{method}.png"))), "{method}");
    }
}

#[test]
fn companions_are_deterministic_across_thread_counts() {
    let d = scratch("matthreads");
    let m = repo().join("jobs/samples/materials");
    for seed in 1..=3 {
        job(
            &d.join("jobs"),
            &format!("b{seed}.toml"),
            &format!(
                "sample = \"{0}/brick_a_albedo.png\"\nmethod = \"patch-sampling\"\nseed = {seed}\n[output]\npath = \"b{seed}/albedo.png\"\nwidth = 160\nheight = 160\n[[companion]]\nsample = \"{0}/brick_a_normal.png\"\npath = \"b{seed}/normal.png\"\nkind = \"normal\"\n",
                m.display()
            ),
        );
    }
    let digests = |threads: &str| {
        let out = d.join(format!("out{threads}"));
        run_ok(texsyn().args(["run", "-j", threads]).arg(d.join("jobs")).arg("-o").arg(&out));
        let man = manifest(&out);
        let mut v: Vec<String> = man["jobs"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|j| j["outputs"].as_array().unwrap().iter().map(|o| format!("{} {}", o["path"], o["pixel_digest"])))
            .collect();
        v.sort();
        v
    };
    let (one, two) = (digests("1"), digests("2"));
    assert_eq!(one.len(), 6);
    assert_eq!(one, two);
}

#[test]
fn bad_companions_and_maps_get_clear_errors_and_nothing_else_is_lost() {
    let d = scratch("matbad");
    let m = repo().join("jobs/samples/materials");
    let s = repo().join("jobs/samples");
    let jobs = d.join("jobs");
    let head = |method: &str, path: &str| {
        format!(
            "sample = \"{}/rock_a_albedo.png\"\nmethod = \"{method}\"\nseed = 1\n[output]\npath = \"{path}\"\nwidth = 100\nheight = 100\n",
            m.display()
        )
    };
    job(
        &jobs,
        "good.toml",
        &format!(
            "{}[[companion]]\nsample = \"{}/rock_a_normal.png\"\npath = \"good_n.png\"\nkind = \"normal\"\n",
            head("quilting", "good.png"),
            m.display()
        ),
    );
    job(
        &jobs,
        "size.toml",
        &format!(
            "{}[[companion]]\nsample = \"{}/crops/grass_gray_128.png\"\npath = \"size_n.png\"\n",
            head("quilting", "size.png"),
            s.display()
        ),
    );
    write(&d.join("broken.png"), "this is not a png");
    job(
        &jobs,
        "unreadable.toml",
        &format!("{}[[companion]]\nsample = \"{}/broken.png\"\npath = \"u_n.png\"\n", head("quilting", "u.png"), d.display()),
    );
    job(
        &jobs,
        "twice.toml",
        &format!(
            "{0}[[companion]]\nsample = \"{1}/rock_a_normal.png\"\npath = \"t_n.png\"\n[[companion]]\nsample = \"{1}/rock_a_gloss.png\"\npath = \"t_n.png\"\n",
            head("quilting", "t.png"),
            m.display()
        ),
    );
    job(&jobs, "wrap.toml", &head("coevolution", "w.png").replace("height = 100\n", "height = 100\ntileable = true\n"));
    job(
        &jobs,
        "kind.toml",
        &format!(
            "{}[[companion]]\nsample = \"{}/rock_a_normal.png\"\npath = \"k.png\"\nkind = \"bump\"\n",
            head("quilting", "k0.png"),
            m.display()
        ),
    );
    let out = d.join("out");
    let o = run_expect(texsyn().arg("run").arg(&jobs).arg("-o").arg(&out), 1);
    let t = text(&o);
    for needle in [
        "size.toml",
        "`companion[1].sample`",
        "is 128x128 but the sample",
        "is 256x256",
        "unreadable.toml",
        "broken.png",
        "twice.toml",
        "`companion[2].path`",
        "is also written by `companion[1].path`",
        "wrap.toml",
        "`output.tileable`",
        "coevolution places texels on the sample's lattice, which does not wrap",
        "methods that can wrap a 100x100 output:",
        "kind.toml",
        "unknown kind `bump`",
    ] {
        assert!(t.contains(needle), "missing {needle:?} in:\n{t}");
    }
    assert!(out.join("good.png").is_file() && out.join("good_n.png").is_file(), "the good job still ran");
    let man = manifest(&out);
    let ok = man["jobs"].as_array().unwrap().iter().filter(|j| j["status"] == "ok").count();
    assert_eq!(ok, 1);
    // apply: a map over an image of another size, and a file that is no map.
    run_ok(texsyn().arg("run").arg(jobs.join("good.toml")).arg("-o").arg(d.join("o2")));
    let map_job = format!("{}source_map = \"m.exr\"\n", head("quilting", "m.png"));
    job(&d.join("j3"), "m.toml", &map_job);
    run_ok(texsyn().arg("run").arg(d.join("j3")).arg("-o").arg(d.join("o3")));
    let o =
        run_expect(texsyn().arg("apply").arg(d.join("o3/m.exr")).arg(s.join("crops/grass_gray_128.png")).arg("-o").arg(d.join("x.png")), 2);
    assert!(text(&o).contains("128x128") && text(&o).contains("256x256"), "{}", text(&o));
    assert!(!d.join("x.png").exists());
    let o = run_expect(texsyn().arg("apply").arg(s.join("cork.png")).arg(s.join("cork.png")).arg("-o").arg(d.join("y.png")), 2);
    assert!(text(&o).contains("cork.png"), "{}", text(&o));
}

/// The report shows each companion beside the output it shares a placement with, and in a real
/// browser every image decodes; the shown companion is the companion file, pixel for pixel.
#[test]
fn the_report_shows_companions_next_to_their_output() {
    let d = scratch("matreport");
    let m = repo().join("jobs/samples/materials");
    job(
        &d.join("jobs"),
        "rock.toml",
        &format!(
            "sample = \"{0}/rock_a_albedo.png\"\nmethod = \"quilting\"\nseed = 2\n[output]\npath = \"rock/albedo.png\"\nwidth = 200\nheight = 180\n[[companion]]\nsample = \"{0}/rock_a_normal.png\"\npath = \"rock/normal.png\"\nkind = \"normal\"\n[[companion]]\nsample = \"{0}/rock_a_gloss.png\"\npath = \"rock/gloss.png\"\n",
            m.display()
        ),
    );
    let out = d.join("out");
    run_ok(texsyn().arg("run").arg(d.join("jobs")).arg("-o").arg(&out));
    let rep = d.join("rep");
    run_ok(texsyn().arg("report").arg(out.join("manifest.json")).arg("-o").arg(&rep));
    let dom = crate::report::dump_dom(&rep.join("index.html"));
    let all = crate::report::tags(&dom);
    let body = all.iter().find(|t| t.name == "body").unwrap();
    let ok = body.attrs.get("data-images-ok").cloned().unwrap_or_default();
    let (shown, total) = ok.split_once('/').unwrap();
    assert_eq!(shown, total, "every image decoded: {:?}", body.attrs.get("data-images-failed"));
    let figures: Vec<usize> = all
        .iter()
        .enumerate()
        .filter(|(_, t)| t.name == "figure" && t.attrs.get("data-role").map(String::as_str) == Some("companion"))
        .map(|(i, _)| i)
        .collect();
    assert_eq!(figures.len(), 2, "one figure per companion");
    let main = all
        .iter()
        .position(|t| {
            t.name == "figure" && t.attrs.get("data-job").map(String::as_str) == Some("rock.toml") && t.attrs.contains_key("data-group")
        })
        .unwrap();
    assert!(figures.iter().all(|&f| f > main), "companions follow their output");
    for (f, file) in figures.iter().zip(["rock/normal.png", "rock/gloss.png"]) {
        assert!(all[*f].text.contains(file), "caption names {file}: {}", all[*f].text);
        let src = all[f + 1..].iter().find(|t| t.name == "img").unwrap().attrs["src"].clone();
        assert_eq!(rgb(&rep.join(&src)), rgb(&out.join(file)), "{file} shown 1:1");
    }
}

/// `jobs/materials/`: every bundled material set, tileable, with its companions. A 2×2 tiling of
/// each output shows no seam at the wrap: the jump across the wrap, relative to the image's
/// typical neighbour jump, is no larger than the method's own interior seams' (the
/// `seam_visibility` of its recorded seam grid), for the albedo and every companion, within
/// `WRAP_FACTOR`: the wrap is one line of pixel pairs against all the interior seams, so it is the
/// noisier estimate (rw-tiles' normal map, whose wrap is an ordinary tile join by construction,
/// measures 0.85 against 0.77). Every albedo is within 1.0 today.
const WRAP_FACTOR: f64 = 1.15;

#[test]
fn bundled_materials_wrap_no_worse_than_their_interior_seams() {
    let out = scratch("matwrap");
    run_ok(texsyn().arg("run").arg(repo().join("jobs/materials")).arg("-o").arg(&out));
    let m = manifest(&out);
    let jobs = m["jobs"].as_array().unwrap();
    assert!(jobs.len() >= 5, "every material set has a job");
    let mut checked = Vec::new();
    for j in jobs {
        assert_eq!(j["output_spec"]["tileable"], true, "{}: tileable", j["id"]);
        assert!(!j["companions"].as_array().unwrap().is_empty(), "{}: with companions", j["id"]);
        let seams: texsyn::image::seam_grid::SeamGrid = serde_json::from_value(j["seams"].clone()).unwrap();
        for o in j["outputs"].as_array().unwrap().iter().filter(|o| o["format"] == "png") {
            let img = rgb(&out.join(o["path"].as_str().unwrap()));
            let wrap = texsyn::metrics::wrap_visibility(&img).unwrap();
            let interior = texsyn::metrics::seam_visibility(&img, &seams).unwrap();
            checked.push(format!("{} {}: wrap {wrap:.3}, interior seams {interior:.3}", j["id"], o["path"]));
            assert!(
                wrap <= WRAP_FACTOR * interior,
                "{}: the wrap ({wrap:.3}) shows more than the interior seams ({interior:.3})",
                o["path"]
            );
        }
    }
    eprintln!("{}", checked.join("\n"));
    run_ok(texsyn().arg("verify").arg(out.join("manifest.json")));
}
