//! Tile-set export (`export_tiles = true`) end to end: the files a job writes, their manifest
//! records, `verify` over them, and `texsyn tiles render` reproducing the job's output from the
//! export alone, rendering other sizes and seeds, and refusing a tampered export.

use super::common::*;

/// Writes one exporting job per tile method and runs them.
fn exported(tag: &str) -> PathBuf {
    let dir = scratch(tag);
    let sample = Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/samples/crops/pebbles_beige_128.png");
    for (method, tile, overlap) in [("wang-tiles", 48, 8), ("rw-tiles", 48, 6)] {
        let job = format!(
            "sample = {sample:?}\nmethod = \"{method}\"\nseed = 5\n[output]\npath = \"{method}.png\"\nwidth = 333\nheight = 201\n\
             [params]\ntile = {tile}\noverlap = {overlap}\nexport_tiles = true\n",
            sample = sample.display().to_string()
        );
        std::fs::write(dir.join(format!("{method}.toml")), job).unwrap();
    }
    run_ok(texsyn().args(["run", "-q"]).arg(&dir).arg("-o").arg(dir.join("out")));
    dir
}

#[test]
fn an_export_is_recorded_verified_and_renders_back_the_jobs_pixels() {
    let dir = exported("roundtrip");
    let out = dir.join("out");
    let manifest: Value = serde_json::from_slice(&std::fs::read(out.join("manifest.json")).unwrap()).unwrap();
    for method in ["wang-tiles", "rw-tiles"] {
        let job = manifest["jobs"].as_array().unwrap().iter().find(|j| j["method"] == method).unwrap();
        let outputs = job["outputs"].as_array().unwrap();
        // The main output first, then the K³ tiles of the minimal set and the index, each hashed
        // (`colors = "auto"`: K = 2 for Wang tiles of 48 on the 128² crop, which has room for no
        // more diamonds of 56; K = 8 for RW tiles of 48, whose sub-blocks of 30 leave room for 8).
        let k: usize = job["diagnostics"]["colors_choice"]["colors"].as_u64().expect("colors = \"auto\" recorded") as usize;
        let n = k * k * k;
        assert_eq!((method, k), (method, if method == "wang-tiles" { 2 } else { 8 }));
        assert_eq!(outputs.len(), n + 2, "{method}: {} outputs", outputs.len());
        assert_eq!(outputs[0]["path"], format!("{method}.png"));
        assert_eq!(outputs[n + 1]["path"], format!("{method}.tiles/index.json"));
        for o in &outputs[1..=n] {
            let path = out.join(o["path"].as_str().unwrap());
            assert_eq!(pixels(&path), o["pixel_digest"]["sha256"].as_str().unwrap(), "{}", path.display());
        }
        let index_path = out.join(format!("{method}.tiles/index.json"));
        let index: Value = serde_json::from_slice(&std::fs::read(&index_path).unwrap()).unwrap();
        assert_eq!(index["format"], "texsyn-tileset/1");
        assert_eq!(index["tiles"].as_array().unwrap().len(), n);
        assert_eq!(index["output"], serde_json::json!([333, 201]));

        // From the export alone, the job's own output, pixel for pixel.
        let again = dir.join(format!("{method}-again.png"));
        run_ok(texsyn().args(["tiles", "render"]).arg(&index_path).arg("-o").arg(&again));
        assert_eq!(pixels(&again), outputs[0]["pixel_digest"]["sha256"].as_str().unwrap(), "{method}");

        // A larger render with the same seed extends it (keyed tiling); another seed differs.
        let big = dir.join(format!("{method}-big.png"));
        run_ok(texsyn().args(["tiles", "render", "--width", "1000", "--height", "700"]).arg(&index_path).arg("-o").arg(&big));
        let (small, large) = (rgb(&again), rgb(&big));
        assert_eq!(large.dimensions(), (1000, 700));
        assert_eq!(large.crop(0, 0, 333, 201), small);
        let other = dir.join(format!("{method}-seed9.png"));
        run_ok(texsyn().args(["tiles", "render", "--seed", "9"]).arg(&index_path).arg("-o").arg(&other));
        assert_ne!(rgb(&other), small);
    }
    // Every extra output is re-checked by verify.
    run_ok(texsyn().arg("verify").arg(out.join("manifest.json")));
    let tile = out.join("rw-tiles.tiles/tile_03.png");
    let mut bytes = std::fs::read(&tile).unwrap();
    let n = bytes.len();
    bytes[n / 2] ^= 0x5a;
    std::fs::write(&tile, bytes).unwrap();
    let v = run(texsyn().arg("verify").arg(out.join("manifest.json")));
    assert_eq!(v.status.code(), Some(3));
    assert!(String::from_utf8_lossy(&v.stdout).contains("tile_03.png") || String::from_utf8_lossy(&v.stderr).contains("tile_03.png"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_tampered_export_is_refused_with_the_reason() {
    let dir = exported("tamper");
    let tiles = dir.join("out/rw-tiles.tiles");
    let index_path = tiles.join("index.json");
    let original = std::fs::read_to_string(&index_path).unwrap();
    let render = |what: &str| -> String {
        let o = run(texsyn().args(["tiles", "render"]).arg(&index_path).arg("-o").arg(dir.join("x.png")));
        assert_eq!(o.status.code(), Some(2), "{what}: {}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stderr).into_owned()
    };

    // Tiles out of order: tile 1's colours are not those of the set's tile 1.
    let mut index: Value = serde_json::from_str(&original).unwrap();
    index["tiles"][1]["colours"] = index["tiles"][2]["colours"].clone();
    std::fs::write(&index_path, serde_json::to_vec(&index).unwrap()).unwrap();
    assert!(render("colours").contains("tile 1"));

    // Another format version.
    let mut index: Value = serde_json::from_str(&original).unwrap();
    index["format"] = "texsyn-tileset/99".into();
    std::fs::write(&index_path, serde_json::to_vec(&index).unwrap()).unwrap();
    assert!(render("format").contains("texsyn-tileset/1"));

    // A rhombus tile that lost its transparency.
    std::fs::write(&index_path, &original).unwrap();
    let tile = tiles.join("tile_00.png");
    let bytes = std::fs::read(&tile).unwrap();
    let (w, h, mut data) = imageio::decode_rgba8(&bytes, DecodeLimits::default()).unwrap();
    data[3] = 255;
    std::fs::write(&tile, imageio::encode_rgba8_png(w, h, &data).unwrap().bytes).unwrap();
    let msg = render("alpha");
    assert!(msg.contains("tile_00.png") && msg.contains("alpha"), "{msg}");

    // A missing tile names the file.
    std::fs::remove_file(&tile).unwrap();
    assert!(render("missing").contains("tile_00.png"));
    let _ = std::fs::remove_dir_all(&dir);
}
