//! `texsyn lattice` on the bundled samples: the four structured samples have a lattice (the
//! vectors docs/methods.md §2.2's prototype found, in canonical form), the eight others do not, and
//! the command says so with its exit code. Then on real game textures of walls, roofs and floors
//! (tests/fixtures/structured/): each has a lattice of the texel size one measures by eye, and the
//! two irregular stone layouts among them have none; a running bond's lattice is of whole bricks.

use super::common::*;

fn lattice(sample: &str, extra: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_texsyn"))
        .arg("lattice")
        .arg(format!("{}/jobs/samples/{sample}.png", env!("CARGO_MANIFEST_DIR")))
        .args(extra)
        .output()
        .unwrap()
}

#[test]
fn structured_samples_have_the_expected_lattices() {
    for (sample, t1, t2) in [
        ("metal_tread_studs", "(27, 0)", "(0, 26)"),
        ("tiles_terracotta", "(88, 0)", "(1, 84)"),
        ("bricks_gray", "(38, -24)", "(36, 24)"),
        ("weave_gray", "(60, 12)", "(0, 48)"),
    ] {
        let out = lattice(sample, &[]);
        assert_eq!(out.status.code(), Some(0), "{sample}: {}", String::from_utf8_lossy(&out.stderr));
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(text.contains(&format!("t1 = {t1}")) && text.contains(&format!("t2 = {t2}")), "{sample}: {text}");
    }
}

#[test]
fn other_samples_have_none_and_say_why() {
    for sample in
        ["pebbles_beige", "hedge_leaves", "wood_weathered", "flagstone_gray", "grass_gray", "gravel_gray", "cork", "roughcast_plaster"]
    {
        let out = lattice(sample, &[]);
        assert_eq!(out.status.code(), Some(1), "{sample}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(sample) && err.contains("no lattice found; give t1/t2"), "{sample}: {err}");
    }
}

#[test]
fn overlay_png_and_json() {
    let dir = std::env::temp_dir().join(format!("texsyn-lattice-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let png = dir.join("overlay.png");
    let out = lattice("weave_gray", &["--json", "--overlay", png.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(0));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["lattice"]["t1"], serde_json::json!([60, 12]));
    let img = image::open(&png).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (240, 240));
    assert!(img.pixels().any(|p| p.0 == [255, 40, 40]), "lattice lines drawn");
}

fn lattice_json(path: &str) -> (Option<i32>, serde_json::Value) {
    let out = Command::new(env!("CARGO_BIN_EXE_texsyn"))
        .arg("lattice")
        .arg(format!("{}/{path}", env!("CARGO_MANIFEST_DIR")))
        .arg("--json")
        .output()
        .unwrap();
    (out.status.code(), serde_json::from_slice(&out.stdout).unwrap())
}

fn vector_length(v: &serde_json::Value) -> f64 {
    let (x, y) = (v[0].as_f64().unwrap(), v[1].as_f64().unwrap());
    x.hypot(y)
}

/// The ranges are the texel sizes read off each image by eye (the repeat of the mortar or tile
/// joints, in pixels), with a few pixels of slack: a lattice of half or twice the texel fails.
#[test]
fn real_walls_roofs_and_floors_have_a_lattice_of_their_texel_size() {
    for (sample, shorter, longer, view) in [
        // Square-cut beige bricks, the artwork repeating 4 × 4 times.
        ("beige_bricks", 60.0..68.0, 60.0..68.0, None),
        // Running bond, two courses of about 32 px per repeat, bricks about 63 px long.
        ("city_bricks", 60.0..68.0, 66.0..76.0, None),
        // Stone blocks about 53 × 62 px, rows slightly offset.
        ("stktex_generic_stoneWallA", 48.0..58.0, 58.0..68.0, None),
        // Floor tiles, a 32 px square pattern.
        ("tiles", 29.0..35.0, 29.0..35.0, None),
        // Staggered roof shingles, about 57 px wide and 33 px per row: diagonal vectors.
        ("stk_generic_asianRoof_a", 40.0..48.0, 40.0..48.0, None),
        // Running bond of varied bricks (about 68 × 32 px): its joints show only in the edges.
        ("stk_generic_brickRoad_a", 42.0..52.0, 42.0..52.0, Some("edge strength")),
        // Clay roof tiles: rows 31 px apart, two tile columns (about 49 px) per repeat.
        ("roof", 28.0..35.0, 44.0..54.0, Some("band-passed gray")),
    ] {
        check_texel(&format!("tests/fixtures/structured/{sample}.png"), shorter, longer, view);
    }
    // Red bricks in running bond, about 80 × 43 px: whole bricks, (±40, 43) and (80, 0) or their
    // sums. The half-brick lattice (40, 0), (−6, 43) that shifts by half a brick or one course
    // also explains its peaks, but the sample repeats a whole brick 1.4 times as clearly.
    check_texel("tests/fixtures/advice/brick_a_albedo.png", 50.0..60.0, 56.0..66.0, None);
}

/// The lattice of the sample at `path` has vectors of these lengths, found in `view`.
fn check_texel(path: &str, shorter: std::ops::Range<f64>, longer: std::ops::Range<f64>, view: Option<&str>) {
    let (code, v) = lattice_json(path);
    assert_eq!(code, Some(0), "{path}: {v}");
    let l = &v["lattice"];
    let (a, b) = (vector_length(&l["t1"]), vector_length(&l["t2"]));
    let (s, g) = (a.min(b), a.max(b));
    assert!(shorter.contains(&s) && longer.contains(&g), "{path}: |t| = {s:.1}, {g:.1}: {l}");
    assert_eq!(l["found_in"].as_str(), view, "{path}: {l}");
}

/// The fallback views must not promote what the gray plane rightly refused: the rubble and sett
/// layouts here, the material albedos without a lattice, and (in `other_samples_have_none_and_say_why`)
/// the stochastic bundled samples.
#[test]
fn irregular_stone_layouts_and_stochastic_albedos_still_have_none() {
    let refused = ["HortonStone6", "Paving_stones_2"].map(|s| format!("tests/fixtures/structured/{s}.png")).into_iter().chain(
        ["aztek_wall_albedo", "cobblestone_a_albedo", "rock_a_albedo", "wood_b_albedo"].map(|s| format!("tests/fixtures/advice/{s}.png")),
    );
    for path in refused {
        let (code, v) = lattice_json(&path);
        assert_eq!(code, Some(1), "{path}: {v}");
        assert!(v["lattice"].is_null() && v["error"].as_str().unwrap().contains("no lattice found"), "{path}: {v}");
    }
}
