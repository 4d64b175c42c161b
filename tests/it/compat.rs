//! Manifests written by earlier texsyn versions keep verifying: the format is a contract.

use super::common::*;

#[test]
fn a_manifest_written_before_the_layered_refactor_verifies() {
    // tests/fixtures/manifest_v1: written by texsyn 9e78e3d (4 jobs: quilting with metrics,
    // rw-tiles with an exported tile set, a patch-sampling sweep), outputs alongside.
    let m = repo().join("tests/fixtures/manifest_v1/out/manifest.json");
    let out = run_ok(texsyn().arg("verify").arg(&m));
    assert!(text(&out).contains("4 verified, 0 mismatched, 0 manifest problems"), "{}", text(&out));
    // A fresh run of the same job files records the same jobs (tool and paths aside).
    let fresh = scratch("compat");
    run_ok(texsyn().arg("run").arg(repo().join("tests/fixtures/manifest_v1/jobs")).arg("-o").arg(&fresh).arg("-q"));
    let (old, new) = (json(&m), manifest(&fresh));
    let strip = |j: &Value| {
        let mut j = j.clone();
        let o = j.as_object_mut().unwrap();
        for k in ["timing", "job_file", "sample", "warnings"] {
            o.remove(k);
        }
        // Since then the tile methods' `align` defaults to `auto`: the resolved parameters (so the
        // content key) differ and the choice is recorded; on a sample without a lattice, as here,
        // the pixels are the same.
        // And since #30 their `colors` defaults to `auto` (more edge colours, so other tiles and
        // pixels, deliberately): the old manifest still verifies above (a record without
        // `colors` means two), while a fresh run of the old job file makes the new fill, which
        // `diff` below explains. What stays the same is compared. Likewise `interior` (`auto`:
        // tiles of more than two colours take insides of their own; a record without it means
        // `edges`). The new fill is the tile methods' algorithm version 2 (issue #30's spread
        // interiors and balanced bands), while the old record's two colours stay version 1.
        // Likewise `tone` (`auto`: interiors toned on samples with large features; a record
        // without it means `off`).
        if o["method"] == "rw-tiles" || o["method"] == "wang-tiles" {
            for k in ["content_key", "params_digest", "outputs", "diagnostics", "algorithm_version"] {
                o.remove(k);
            }
            for k in ["colors", "align", "interior", "tone"] {
                o["params"].as_object_mut().unwrap().remove(k);
            }
        }
        // 8-bit PNG has since been compressed in chunks as it is written: the same pixels in
        // other file bytes (`verify` above reads the stored files against their recorded bytes).
        for o in o.get_mut("outputs").and_then(|v| v.as_array_mut()).into_iter().flatten() {
            o.as_object_mut().unwrap().remove("file_digest");
        }
        // Patch sampling has since gained `continuations` (default false: the same search and
        // pixels), which enters the resolved parameters and so the content key.
        if o["method"] == "patch-sampling" {
            for k in ["content_key", "params_digest"] {
                o.remove(k);
            }
            o["params"].as_object_mut().unwrap().remove("continuations");
        }
        j
    };
    let old_jobs: Vec<Value> = old["jobs"].as_array().unwrap().iter().map(strip).collect();
    let new_jobs: Vec<Value> = new["jobs"].as_array().unwrap().iter().map(strip).collect();
    assert_eq!(old_jobs, new_jobs);
    // The morning-after tools read it as the older night: the tool named as changed, and only the
    // tile fill changed pixels, for the reason the diff gives (the new `colors` default).
    let o = run_expect(texsyn().arg("diff").arg(&m).arg(fresh.join("manifest.json")), 4);
    let said = text(&o);
    assert_eq!(said.lines().filter(|l| l.starts_with("PIXELS")).count(), 1, "{said}");
    assert!(said.contains("PIXELS    rw_tiles.toml"), "{said}");
    assert!(said.contains("params.colors (none) → \"auto\""), "{said}");
    let report = scratch("compat-report").join("r");
    run_ok(texsyn().arg("report").arg(fresh.join("manifest.json")).arg("-o").arg(&report).arg("--since").arg(&m));
    let page = std::fs::read_to_string(report.join("index.html")).unwrap();
    assert!(page.contains("data-pixels-changed=\"1\"") && page.contains("data-unchanged=\"3\""), "since block");
}
