//! `texsyn lattice` on the bundled samples: the four structured samples have a lattice (the
//! vectors docs/methods.md §2.2's prototype found, in canonical form), the eight others do not, and
//! the command says so with its exit code.

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
