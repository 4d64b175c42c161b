//! `texsyn diff` between two runs of one job directory in which one parameter, one sample and one
//! algorithm version change, one job starts failing and one gets slower (a larger output): each
//! is named with its reason, the exit code says pixels changed, and bad manifests exit 2.

use super::common::*;
use super::report::{Tag, decode, dump_dom, tags};

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
    // 1024² against 128²: about 25 times the synthesis time, well clear of the thresholds below
    // (at 512² quilting became fast enough to land on the 0.05 s one).
    job(&jobs, "slow", &quilt(hedge, 24, 1024, "slow.png"));
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
        texsyn().arg("diff").arg(&edited_in_place).arg(new.join("manifest.json")).args(["--time-seconds", "0.05", "--time-relative", "3"]),
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
    assert!(slow.contains("output_spec.width 128 → 1024") && slow.contains("output_spec.height 128 → 1024"), "{t}");
    assert!(line("SLOWER", "slow.toml").contains("×"), "16 times the pixels is well over 1.5 times slower:\n{t}");
    assert!(line("FAILS NOW", "fails.toml").contains("no lattice found"), "{t}");
    // (Its time may move with the machine's load; its pixels and status may not.)
    assert!(
        !t.lines().any(|l| l.contains("same.toml") && !l.starts_with("SLOWER") && !l.starts_with("FASTER")),
        "an unchanged job is not listed:\n{t}"
    );

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

    // The morning page: the same changes, with old | new | difference pictures.
    let report = d.join("report");
    run_ok(texsyn().arg("report").arg(new.join("manifest.json")).arg("-o").arg(&report).arg("--since").arg(&edited_in_place));
    let page = report.join("index.html");
    let source = std::fs::read_to_string(&page).unwrap();
    let all = tags(&source);
    let change = |id: &str| -> Vec<Tag> {
        let start = source.find(&format!("<div class=\"change\" data-job=\"{id}\"")).unwrap_or_else(|| panic!("no panels for {id}"));
        let end = source[start..].find("</div>\n</div>").map_or(source.len(), |e| start + e);
        tags(&source[start..end])
    };
    let panel = |id: &str, role: &str| -> String {
        let tags = change(id);
        let at = tags.iter().position(|t| t.name == "figure" && t.attrs.get("data-panel").map(String::as_str) == Some(role));
        let next = &tags[at.unwrap_or_else(|| panic!("{id}: no {role} panel")) + 1];
        if next.name == "img" { format!("img {}", next.attrs["src"]) } else { format!("gone {}", next.text) }
    };
    // A parameter and a sample changed: all three panels are pictures, the old read from the old run.
    for id in ["param.toml", "sample.toml"] {
        for role in ["old", "new", "difference"] {
            let p = panel(id, role);
            assert!(p.starts_with("img "), "{id} {role}: {p}");
            let img = decode(&report.join(p.trim_start_matches("img ")));
            assert_eq!(img.dimensions(), (96, 96), "{id} {role}: at 1:1");
        }
        let shown = decode(&report.join(panel(id, "old").trim_start_matches("img ")));
        let old_file = decode(&old.join(id.replace(".toml", ".png")));
        assert_eq!(shown.as_raw(), old_file.as_raw(), "{id}: the old panel is the old run's image");
    }
    // The size changed: no difference map across sizes, and it says so.
    assert!(panel("slow.toml", "difference").contains("sizes differ"), "{}", panel("slow.toml", "difference"));
    // The old record of algo.toml does not match the file on disk: not shown, and said why.
    assert!(panel("algo.toml", "old").contains("gone or was overwritten"), "{}", panel("algo.toml", "old"));
    // The summary names the regressions first.
    let since = all.iter().find(|t| t.name == "div" && t.attrs.get("class").map(String::as_str) == Some("since")).expect("a since block");
    assert_eq!(since.attrs["data-failed-now"], "1");
    assert_eq!(since.attrs["data-pixels-changed"], "4");
    assert!(source.find("id=\"summary\"").unwrap() < source.find("id=\"changes\"").unwrap());
    assert!(source.contains("FAILS NOW <b>fails.toml</b>") && source.contains("no lattice found"));
    // In a real browser: every image decodes, and the timings shown are the manifests'.
    let dom = dump_dom(&page);
    let body = tags(&dom).into_iter().find(|t| t.name == "body").unwrap();
    let n_img = all.iter().filter(|t| t.name == "img").count();
    assert_eq!(body.attrs["data-images-ok"], format!("{n_img}/{n_img}"), "failed: {:?}", body.attrs.get("data-images-failed"));
    let new_m = json(&new.join("manifest.json"));
    let old_m = json(&edited_in_place);
    let seconds = |m: &Value, id: &str| {
        m["jobs"].as_array().unwrap().iter().find(|j| j["id"] == id).unwrap()["timing"]["synthesis_seconds"].as_f64().unwrap()
    };
    for t in tags(&dom).iter().filter(|t| t.attrs.contains_key("data-old") && !t.attrs.contains_key("data-metric")) {
        let id = &t.attrs["data-job"];
        assert_eq!(t.attrs["data-old"].parse::<f64>().unwrap(), seconds(&old_m, id), "{id} old time");
        assert_eq!(t.attrs["data-new"].parse::<f64>().unwrap(), seconds(&new_m, id), "{id} new time");
    }
    // A truncated old manifest is a clear error, not a panic.
    let o = run_expect(texsyn().arg("report").arg(new.join("manifest.json")).arg("-o").arg(d.join("r2")).arg("--since").arg(&truncated), 2);
    assert!(text(&o).contains("truncated.json"), "{}", text(&o));
}
