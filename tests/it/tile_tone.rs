//! Tone-matched tile interiors (issue #30): on a sample whose colour variance lies largely in
//! features a quarter of a tile and more across (brown rock), both tile methods with their
//! defaults showed their tile grid as steps of shade between each tile's interior and its edge
//! band; `tone = "auto"` now brings the interiors to their bands' tone there, leaves fine-grained
//! samples as they were, and the toned pixels stay a placement (source maps, `apply`, a
//! material's companions, `verify`) and an export (`tiles render`).

use super::common::*;
use texsyn::image::RgbImage;

/// How much the tile grid shows as steps of shade: the gray level blurred over 5×5, its absolute
/// steps between neighbouring columns averaged along the lines of the tile grid (for Wang tiles
/// `x mod period`, rows likewise; for RW tiles the two diagonals `(x ± y) mod period`), the
/// largest of those averages over their median. 1 when the grid does not show at all.
fn grid_steps(img: &RgbImage, period: usize, diagonal: bool) -> f64 {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let gray: Vec<f64> = img.as_raw().chunks_exact(3).map(|p| (f64::from(p[0]) + f64::from(p[1]) + f64::from(p[2])) / 3.0).collect();
    let r = 2usize;
    let blur = |x: usize, y: usize| {
        let (mut s, mut n) = (0.0, 0.0);
        for yy in y.saturating_sub(r)..(y + r + 1).min(h) {
            for xx in x.saturating_sub(r)..(x + r + 1).min(w) {
                s += gray[yy * w + xx];
                n += 1.0;
            }
        }
        s / n
    };
    let b: Vec<f64> = (0..w * h).map(|i| blur(i % w, i / w)).collect();
    let mut profile = vec![(0.0, 0.0); 2 * period];
    for y in 0..h - 1 {
        for x in 0..w - 1 {
            let across = (b[y * w + x + 1] - b[y * w + x]).abs();
            let down = (b[(y + 1) * w + x] - b[y * w + x]).abs();
            let (p, q) =
                if diagonal { ((x + y) % period, period + (x + period * h - y) % period) } else { (x % period, period + y % period) };
            let (step_p, step_q) = if diagonal { (across, across) } else { (across, down) };
            profile[p].0 += step_p;
            profile[p].1 += 1.0;
            profile[q].0 += step_q;
            profile[q].1 += 1.0;
        }
    }
    let mut means: Vec<f64> = profile.iter().map(|(s, n)| s / n).collect();
    let top = means.iter().copied().fold(0.0, f64::max);
    means.sort_by(f64::total_cmp);
    top / means[means.len() / 2]
}

#[test]
fn toned_interiors_hide_the_tile_grid_of_a_sample_with_large_features() {
    let dir = scratch("tiletone");
    let rock = repo().join("tests/fixtures/structured/rock_brown.png");
    let grass = repo().join("jobs/samples/grass_gray.png");
    let job = |name: &str, sample: &std::path::Path, method: &str, params: &str| {
        write(
            &dir.join("jobs").join(format!("{name}.toml")),
            &format!(
                "sample = {:?}\nmethod = \"{method}\"\nseed = 1\n[output]\npath = \"{name}.png\"\nwidth = 512\nheight = 512\n[params]\n{params}\n",
                sample.display().to_string()
            ),
        );
    };
    for m in ["wang-tiles", "rw-tiles"] {
        job(m, &rock, m, "");
        job(&format!("{m}-off"), &rock, m, "tone = \"off\"");
        job(&format!("{m}-grass"), &grass, m, "");
    }
    let out = dir.join("out");
    run_ok(texsyn().arg("run").arg(dir.join("jobs")).arg("-o").arg(&out).arg("-q"));
    let m = manifest(&out);
    let record = |name: &str| m["jobs"].as_array().unwrap().iter().find(|j| j["id"] == format!("{name}.toml").as_str()).unwrap().clone();
    for (method, diagonal) in [("wang-tiles", false), ("rw-tiles", true)] {
        let toned = record(method);
        let tone = &toned["diagnostics"]["tone"];
        assert_eq!(tone["tone"], "on", "{method}: {tone}");
        assert!(tone["large_feature_share"].as_f64().unwrap() > 0.4, "{method}: {tone}");
        assert!(tone["toned_pixels"].as_u64().unwrap() > 0, "{method}: {tone}");
        assert_eq!(record(&format!("{method}-off"))["diagnostics"]["tone"]["tone"], "off");
        let grass_tone = &record(&format!("{method}-grass"))["diagnostics"]["tone"];
        assert_eq!(grass_tone["tone"], "off", "{method} on grass: {grass_tone}");
        let period = toned["diagnostics"]["geometry"]["tile"].as_u64().unwrap() as usize;
        let on = grid_steps(&rgb(&out.join(format!("{method}.png"))), period, diagonal);
        let off = grid_steps(&rgb(&out.join(format!("{method}-off.png"))), period, diagonal);
        eprintln!("{method}: grid steps {off:.3} untoned, {on:.3} toned");
        assert!(off > 1.1, "{method}: the untoned fill shows its grid ({off:.3})");
        assert!(on - 1.0 < 0.6 * (off - 1.0), "{method}: toned {on:.3} against untoned {off:.3}");
    }
    run_ok(texsyn().arg("verify").arg(out.join("manifest.json")));
}

/// A toned material: the source map replays the albedo exactly, and the normal-map companion is
/// rendered through the same blend steps (its toned pixels are not copies of sample normals).
#[test]
fn toned_tiles_stay_a_placement_for_apply_and_companions() {
    let dir = scratch("tiletoneplace");
    let m = repo().join("jobs/samples/materials");
    write(
        &dir.join("jobs/rock.toml"),
        &format!(
            "sample = \"{0}/rock_a_albedo.png\"\nmethod = \"rw-tiles\"\nseed = 3\n[output]\npath = \"rock/albedo.png\"\nwidth = 300\nheight = 260\nsource_map = \"rock/map.exr\"\n[[companion]]\nsample = \"{0}/rock_a_normal.png\"\npath = \"rock/normal.png\"\nkind = \"normal\"\n",
            m.display()
        ),
    );
    let out = dir.join("out");
    run_ok(texsyn().arg("run").arg(dir.join("jobs")).arg("-o").arg(&out).arg("-q"));
    let record = &manifest(&out)["jobs"][0];
    assert_eq!(record["diagnostics"]["tone"]["tone"], "on", "{}", record["diagnostics"]["tone"]);
    let applied = dir.join("applied.png");
    run_ok(texsyn().arg("apply").arg(out.join("rock/map.exr")).arg(m.join("rock_a_albedo.png")).arg("-o").arg(&applied));
    assert_eq!(pixels(&applied), pixels(&out.join("rock/albedo.png")), "apply differs from the toned output");
    let normals = rgb(&m.join("rock_a_normal.png"));
    let sample_normals: std::collections::HashSet<[u8; 3]> = normals.as_raw().chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    let companion = rgb(&out.join("rock/normal.png"));
    let blended = companion.as_raw().chunks_exact(3).filter(|c| !sample_normals.contains(&[c[0], c[1], c[2]])).count();
    assert!(blended > 1000, "the companion follows the toned pixels' blends: {blended} pixels are not sample normals");
    run_ok(texsyn().arg("verify").arg(out.join("manifest.json")));
}

/// An exported toned set carries its tiles as toned: `tiles render` reproduces the output pixel
/// for pixel from the export alone, for both methods.
#[test]
fn an_exported_toned_set_renders_the_same_fill() {
    let dir = scratch("tiletoneexport");
    let rock = repo().join("tests/fixtures/structured/rock_brown.png");
    for m in ["wang-tiles", "rw-tiles"] {
        write(
            &dir.join("jobs").join(format!("{m}.toml")),
            &format!(
                "sample = {:?}\nmethod = \"{m}\"\nseed = 4\n[output]\npath = \"{m}.png\"\nwidth = 300\nheight = 260\n[params]\nexport_tiles = true\n",
                rock.display().to_string()
            ),
        );
    }
    let out = dir.join("out");
    run_ok(texsyn().arg("run").arg(dir.join("jobs")).arg("-o").arg(&out).arg("-q"));
    let jobs = manifest(&out)["jobs"].as_array().unwrap().clone();
    for m in ["wang-tiles", "rw-tiles"] {
        let record = jobs.iter().find(|j| j["method"] == m).unwrap();
        assert_eq!(record["diagnostics"]["tone"]["tone"], "on", "{m}: {}", record["diagnostics"]["tone"]);
        let again = dir.join(format!("{m}.again.png"));
        run_ok(texsyn().args(["tiles", "render"]).arg(out.join(format!("{m}.tiles/index.json"))).arg("-o").arg(&again));
        assert_eq!(pixels(&again), pixels(&out.join(format!("{m}.png"))), "{m}: the export renders another fill");
    }
}
