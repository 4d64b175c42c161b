//! `texsyn diff` between two runs of one job directory in which one parameter, one sample and one
//! algorithm version change, one job starts failing and one gets slower (a larger output): each
//! is named with its reason, the exit code says pixels changed, and bad manifests exit 2.

use super::common::*;

fn job(dir: &Path, name: &str, body: &str) {
    write(&dir.join(format!("{name}.toml")), body);
}

fn quilt(sample: &str, block: u32, size: u32, out: &str) -> String {
    format!(
        "sample = \"{sample}\"\nmethod = \"quilting\"\nseed = 2\n[output]\npath = \"{out}\"\nwidth = {size}\nheight = {size}\n[params]\nblock = {block}\n"
    )
}

#[test]
fn diff_names_each_change_with_its_reason() {
    let d = scratch("diff");
    let crops = repo().join("jobs/samples/crops");
    let (pebbles, hedge, grass) =
        (crops.join("pebbles_beige_128.png"), crops.join("hedge_leaves_128.png"), crops.join("grass_gray_128.png"));
    let (pebbles, hedge, grass) = (pebbles.to_str().unwrap(), hedge.to_str().unwrap(), grass.to_str().unwrap());
    let jobs = d.join("jobs");
    std::fs::create_dir_all(&jobs).unwrap();
    std::fs::copy(pebbles, jobs.join("varying.png")).unwrap();
    job(&jobs, "param", &quilt(pebbles, 24, 96, "param.png"));
    job(&jobs, "sample", &quilt("varying.png", 24, 96, "sample.png"));
    job(&jobs, "algo", &quilt(pebbles, 32, 96, "algo.png"));
    job(&jobs, "same", &quilt(hedge, 24, 96, "same.png"));
    job(&jobs, "slow", &quilt(hedge, 24, 128, "slow.png"));
    let fails = |lattice: &str| {
        format!(
            "sample = \"{grass}\"\nmethod = \"coevolution\"\nseed = 1\n[output]\npath = \"fails.png\"\nwidth = 64\nheight = 64\n[params]\n{lattice}"
        )
    };
    job(&jobs, "fails", &fails("t1_x = 20\nt2_y = 20\n"));
    let (old, new) = (d.join("old"), d.join("new"));
    run_ok(texsyn().arg("run").arg(&jobs).arg("-o").arg(&old).arg("-q"));

    // The second night: a parameter, a sample and a size change, a job loses its lattice.
    job(&jobs, "param", &quilt(pebbles, 40, 96, "param.png"));
    std::fs::copy(hedge, jobs.join("varying.png")).unwrap();
    job(&jobs, "slow", &quilt(hedge, 24, 512, "slow.png"));
    job(&jobs, "fails", &fails(""));
    run_expect(texsyn().arg("run").arg(&jobs).arg("-o").arg(&new).arg("-q"), 1);
    // The algorithm version moved between the nights (as a method change would): edit the old
    // record the way an older texsyn would have written it.
    let old_manifest = old.join("manifest.json");
    let mut m = json(&old_manifest);
    for j in m["jobs"].as_array_mut().unwrap() {
        if j["id"] == "algo.toml" {
            j["algorithm_version"] = 0.into();
            j["outputs"][0]["pixel_digest"]["sha256"] = "0".repeat(64).into();
        }
    }
    let edited = d.join("old-edited.json");
    write(&edited, &serde_json::to_string_pretty(&m).unwrap());
    // Paths in the old manifest are relative to its own directory: keep it there.
    let edited_in_place = old.join("edited.json");
    std::fs::rename(&edited, &edited_in_place).unwrap();

    let out = run_expect(
        texsyn().arg("diff").arg(&edited_in_place).arg(new.join("manifest.json")).args(["--time-seconds", "0", "--time-relative", "0.5"]),
        4,
    );
    let t = text(&out);
    let line = |prefix: &str, id: &str| {
        t.lines().find(|l| l.starts_with(prefix) && l.contains(id)).unwrap_or_else(|| panic!("no {prefix} line for {id}:\n{t}")).to_string()
    };
    assert!(line("PIXELS", "param.toml").contains("params.block 24 → 40"), "{t}");
    assert!(line("PIXELS", "sample.toml").contains("sample.pixels"), "{t}");
    assert!(line("PIXELS", "algo.toml").contains("algorithm_version 0 → 1"), "{t}");
    let slow = line("PIXELS", "slow.toml");
    assert!(slow.contains("output_spec.width 128 → 512") && slow.contains("output_spec.height 128 → 512"), "{t}");
    assert!(line("SLOWER", "slow.toml").contains("×"), "16 times the pixels is well over 1.5 times slower:\n{t}");
    assert!(line("FAILS NOW", "fails.toml").contains("no lattice found"), "{t}");
    assert!(!t.contains("same.toml"), "an unchanged job is not listed:\n{t}");

    // The same as JSON, for programs.
    let out = run_expect(texsyn().arg("diff").arg(&edited_in_place).arg(new.join("manifest.json")).arg("--json"), 4);
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    let changed: Vec<&str> = v["diff"]["pixels_changed"].as_array().unwrap().iter().map(|p| p["id"].as_str().unwrap()).collect();
    assert_eq!(changed, ["algo.toml", "param.toml", "sample.toml", "slow.toml"]);
    assert_eq!(v["diff"]["unchanged"], 1);
    assert_eq!(v["thresholds"]["time_relative"], 0.2);

    // No pixel change: exit 0.
    run_expect(texsyn().arg("diff").arg(new.join("manifest.json")).arg(new.join("manifest.json")), 0);
    // A truncated or foreign manifest: exit 2, naming the file.
    let truncated = d.join("truncated.json");
    let bytes = std::fs::read(new.join("manifest.json")).unwrap();
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
    let out = run_expect(texsyn().arg("diff").arg(&truncated).arg(new.join("manifest.json")), 2);
    assert!(text(&out).contains("truncated.json") && text(&out).contains("not a texsyn manifest"), "{}", text(&out));
    run_expect(texsyn().arg("diff").arg(d.join("missing.json")).arg(new.join("manifest.json")), 2);
}
