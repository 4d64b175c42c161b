//! End-to-end tests of the pipeline through the `texsyn` binary: golden digests, determinism
//! across thread counts and job order, incremental runs, verify, and crash safety.

use super::common::*;

/// job id → pixel digest of its first output.
fn pixel_digests(out: &Path) -> BTreeMap<String, String> {
    manifest(out)["jobs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|j| (j["id"].as_str().unwrap().to_string(), j["outputs"][0]["pixel_digest"]["sha256"].as_str().unwrap_or("").to_string()))
        .collect()
}

#[test]
fn bundled_jobs_reproduce_the_golden_digests() {
    let d = scratch("golden-all");
    let out = d.join("out");
    run_ok(texsyn().arg("run").arg(repo().join("jobs")).arg("-o").arg(&out).arg("-q"));
    let digests = pixel_digests(&out);
    assert!(digests.len() >= 12, "every bundled sample has a job: {digests:?}");
    assert!(digests.values().all(|d| d.len() == 64));
    let r = run_ok(texsyn().args(["golden", "check"]).arg(repo().join("golden")).arg(out.join("manifest.json")));
    assert!(String::from_utf8_lossy(&r.stderr).contains("0 mismatched, 0 missing"));
    // The bundle has a seed sweep, an EXR output and a 16-bit PNG output.
    let m = manifest(&out);
    let outputs: Vec<&Value> = m["jobs"].as_array().unwrap().iter().flat_map(|j| j["outputs"].as_array().unwrap()).collect();
    assert!(outputs.iter().any(|o| o["format"] == "exr"));
    assert!(outputs.iter().any(|o| o["format"] == "png" && o["bit_depth"] == 16));
    assert!(m["jobs"].as_array().unwrap().iter().filter(|j| j["id"].as_str().unwrap().contains("#seed=")).count() >= 3);
}

#[test]
fn bundled_method_jobs_do_not_depend_on_threads_or_order() {
    // One directory per method family (the paper directories repeat the same methods at scale):
    // run with 1 and 4 threads, and in reverse order on 2 pool threads with RAYON_NUM_THREADS=3.
    let d = scratch("determinism");
    let jobs = d.join("jobs");
    for sub in ["samples", "quilting", "double_seam", "patch_sampling", "coevolution", "tes", "tiles"] {
        copy_dir(&repo().join("jobs").join(sub), &jobs.join(sub));
    }
    let one = d.join("one");
    let four = d.join("four");
    let rev = d.join("reversed");
    run_ok(texsyn().arg("run").arg(&jobs).arg("-o").arg(&one).args(["-j", "1", "-q"]));
    run_ok(texsyn().arg("run").arg(&jobs).arg("-o").arg(&four).args(["-j", "4", "-q"]));
    run_ok(texsyn().arg("run").arg(&jobs).arg("-o").arg(&rev).args(["-j", "2", "-q", "--reverse"]).env("RAYON_NUM_THREADS", "3"));
    let a = pixel_digests(&one);
    let methods: std::collections::BTreeSet<String> =
        manifest(&one)["jobs"].as_array().unwrap().iter().map(|j| j["method"].as_str().unwrap().to_string()).collect();
    assert!(methods.len() >= 7, "every method is covered: {methods:?}");
    assert_eq!(a, pixel_digests(&four), "1 vs 4 threads");
    assert_eq!(a, pixel_digests(&rev), "forward vs reversed order");
    assert_eq!(manifest(&one)["deterministic_digest"], manifest(&four)["deterministic_digest"]);
    // Same ids as in jobs/, so the single-threaded run is checked against golden/ too.
    run_ok(texsyn().args(["golden", "check"]).arg(repo().join("golden")).arg(one.join("manifest.json")));
}

fn small_job_dir(d: &Path, seeds: u32) -> PathBuf {
    let jobs = d.join("jobs");
    std::fs::create_dir_all(&jobs).unwrap();
    std::fs::copy(repo().join("jobs/samples/bricks_gray.png"), jobs.join("bricks.png")).unwrap();
    std::fs::write(
        jobs.join("sweep.toml"),
        format!(
            "sample = \"bricks.png\"\nmethod = \"quilting\"\n[output]\npath = \"s/{{seed}}.png\"\nwidth = 150\nheight = 150\n\
             [params]\nblock = 40\n[sweep]\nseed = {{ from = 1, to = {seeds} }}\n"
        ),
    )
    .unwrap();
    std::fs::write(
        jobs.join("exr.toml"),
        "sample = \"bricks.png\"\nmethod = \"quilting\"\nseed = 3\n[output]\npath = \"e.exr\"\nwidth = 100\nheight = 90\n[params]\nblock = 30\n",
    )
    .unwrap();
    jobs
}

#[test]
fn incremental_runs_skip_up_to_date_jobs_and_redo_changed_ones() {
    let d = scratch("incremental");
    let jobs = small_job_dir(&d, 3);
    let out = d.join("out");
    let first = run_ok(texsyn().arg("run").arg(&jobs).arg("-o").arg(&out).arg("--json"));
    let summary = |o: &Output| -> Value {
        String::from_utf8_lossy(&o.stdout)
            .lines()
            .map(|l| serde_json::from_str::<Value>(l).unwrap())
            .find(|v| v["event"] == "summary")
            .expect("summary event")
    };
    assert_eq!(summary(&first)["ran"], 4);
    let second = run_ok(texsyn().arg("run").arg(&jobs).arg("-o").arg(&out).arg("--json"));
    assert_eq!(summary(&second)["ran"], 0);
    assert_eq!(summary(&second)["up_to_date"], 4);
    // A deleted output and a changed parameter are both redone; nothing else is.
    std::fs::remove_file(out.join("s/2.png")).unwrap();
    let exr = std::fs::read_to_string(jobs.join("exr.toml")).unwrap().replace("block = 30", "block = 32");
    std::fs::write(jobs.join("exr.toml"), exr).unwrap();
    let dry = run_ok(texsyn().arg("run").arg(&jobs).arg("-o").arg(&out).arg("--dry-run"));
    let plan = String::from_utf8_lossy(&dry.stdout);
    assert!(plan.contains("sweep.toml#seed=2: will run: output `s/2.png` is missing"), "{plan}");
    assert!(plan.contains("exr.toml: will run: inputs changed"), "{plan}");
    assert!(plan.contains("sweep.toml#seed=1: up to date"), "{plan}");
    let third = run_ok(texsyn().arg("run").arg(&jobs).arg("-o").arg(&out).arg("--json"));
    assert_eq!(summary(&third)["ran"], 2);
    assert_eq!(summary(&third)["up_to_date"], 2);
    let forced = run_ok(texsyn().arg("run").arg(&jobs).arg("-o").arg(&out).arg("--json").arg("--force"));
    assert_eq!(summary(&forced)["ran"], 4);
}

#[test]
fn renaming_a_job_file_does_not_change_its_pixels() {
    let d = scratch("rename");
    let jobs = small_job_dir(&d, 1);
    run_ok(texsyn().arg("run").arg(&jobs).arg("-o").arg(d.join("a")).arg("-q"));
    std::fs::create_dir_all(jobs.join("moved")).unwrap();
    let body = std::fs::read_to_string(jobs.join("exr.toml")).unwrap().replace("\"bricks.png\"", "\"../bricks.png\"");
    std::fs::write(jobs.join("moved/renamed.toml"), body).unwrap();
    std::fs::remove_file(jobs.join("exr.toml")).unwrap();
    run_ok(texsyn().arg("run").arg(&jobs).arg("-o").arg(d.join("b")).arg("-q"));
    let a = pixel_digests(&d.join("a"));
    let b = pixel_digests(&d.join("b"));
    assert_eq!(a["exr.toml"], b["moved/renamed.toml"]);
}

#[test]
fn verify_passes_on_a_fresh_run_and_catches_tampering() {
    let d = scratch("verify");
    let jobs = small_job_dir(&d, 2);
    let out = d.join("out");
    run_ok(texsyn().arg("run").arg(&jobs).arg("-o").arg(&out).arg("-q"));
    run_ok(texsyn().arg("verify").arg(out.join("manifest.json")));

    // A tampered output image: one pixel changed, re-encoded as a valid PNG.
    let png = out.join("s/1.png");
    let mut img = image::open(&png).unwrap().to_rgb8();
    let p = img.get_pixel_mut(5, 5);
    p[0] = p[0].wrapping_add(1);
    img.save(&png).unwrap();
    let r = texsyn().arg("verify").arg(out.join("manifest.json")).output().unwrap();
    assert_eq!(r.status.code(), Some(3));
    let text = String::from_utf8_lossy(&r.stdout);
    assert!(text.contains("MISMATCH  sweep.toml#seed=1") && text.contains("s/1.png"), "{text}");
    assert!(!text.contains("seed=2"), "only the tampered job is reported: {text}");

    // Restore it by re-running, then tamper with the manifest instead.
    run_ok(texsyn().arg("run").arg(&jobs).arg("-o").arg(&out).arg("-q"));
    run_ok(texsyn().arg("verify").arg(out.join("manifest.json")));
    let mpath = out.join("manifest.json");
    let mut m: Value = serde_json::from_slice(&std::fs::read(&mpath).unwrap()).unwrap();
    let job = m["jobs"].as_array_mut().unwrap().iter_mut().find(|j| j["id"] == "sweep.toml#seed=2").unwrap();
    job["seed"] = Value::from(99);
    std::fs::write(&mpath, serde_json::to_vec_pretty(&m).unwrap()).unwrap();
    let r = texsyn().arg("verify").arg(&mpath).output().unwrap();
    assert_eq!(r.status.code(), Some(3));
    let text = String::from_utf8_lossy(&r.stdout);
    assert!(text.contains("MISMATCH  sweep.toml#seed=2"), "{text}");
    assert!(text.contains("MANIFEST"), "the digest check notices the edit: {text}");
}

#[test]
fn golden_bless_reports_changes_and_check_catches_them() {
    let d = scratch("golden");
    let jobs = small_job_dir(&d, 2);
    let out = d.join("out");
    run_ok(texsyn().arg("run").arg(&jobs).arg("-o").arg(&out).arg("-q"));
    let golden = d.join("golden");
    let bless = run_ok(texsyn().args(["golden", "bless"]).arg(&golden).arg(out.join("manifest.json")));
    assert_eq!(String::from_utf8_lossy(&bless.stdout).lines().filter(|l| l.starts_with("new")).count(), 3);
    run_ok(texsyn().args(["golden", "check"]).arg(&golden).arg(out.join("manifest.json")));
    // Change the expected digest of one job: check fails with exit 3 and names it.
    let gfile = golden.join("sweep.json");
    let text = std::fs::read_to_string(&gfile).unwrap();
    let first_digest = text.split("\"sha256\": \"").nth(1).unwrap()[..64].to_string();
    std::fs::write(&gfile, text.replacen(&first_digest, &"0".repeat(64), 1)).unwrap();
    let r = texsyn().args(["golden", "check"]).arg(&golden).arg(out.join("manifest.json")).output().unwrap();
    assert_eq!(r.status.code(), Some(3));
    assert!(String::from_utf8_lossy(&r.stdout).contains("MISMATCH  sweep.toml#seed=1"));
    let again = run_ok(texsyn().args(["golden", "bless"]).arg(&golden).arg(out.join("manifest.json")));
    assert!(String::from_utf8_lossy(&again.stdout).contains("changed  sweep.toml#seed=1"));
}

#[test]
fn a_killed_run_resumes_without_redoing_finished_jobs() {
    let d = scratch("crash");
    // Enough jobs that the run outlasts several of the manifest's writes (at most one per 250 ms):
    // 40 finished between two writes once the jobs got faster, and the kill came too late.
    let seeds = 150;
    let jobs = small_job_dir(&d, seeds);
    let out = d.join("out");
    let mut child = texsyn()
        .arg("run")
        .arg(&jobs)
        .arg("-o")
        .arg(&out)
        .args(["-j", "1", "-q"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // Wait until a few jobs are recorded, then kill -9 in the middle of the run.
    let deadline = Instant::now() + Duration::from_secs(120);
    let recorded = loop {
        if let Ok(bytes) = std::fs::read(out.join("manifest.json"))
            && let Ok(m) = serde_json::from_slice::<Value>(&bytes)
        {
            let ok = m["jobs"].as_array().unwrap().iter().filter(|j| j["status"] == "ok").count();
            if ok >= 3 {
                break ok;
            }
        }
        assert!(Instant::now() < deadline, "the run made no progress");
        std::thread::sleep(Duration::from_millis(20));
    };
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    let total = seeds as usize + 1;
    // The manifest on disk is complete JSON (atomic writes) and still marks the run in progress.
    let m = manifest(&out);
    let recorded_now = m["jobs"].as_array().unwrap().iter().filter(|j| j["status"] == "ok").count();
    assert!(recorded_now >= recorded && recorded_now < total, "killed mid-way: {recorded_now}/{total}");
    // Every image present under its final name is complete.
    for entry in std::fs::read_dir(out.join("s")).unwrap() {
        let p = entry.unwrap().path();
        if p.extension().is_some_and(|e| e == "png") {
            image::open(&p).unwrap_or_else(|e| panic!("{} is not a complete image: {e}", p.display()));
        }
    }
    // The lock died with the process: the next run starts and redoes only what is missing.
    let r = run_ok(texsyn().arg("run").arg(&jobs).arg("-o").arg(&out).arg("--json"));
    let summary: Value = String::from_utf8_lossy(&r.stdout)
        .lines()
        .map(|l| serde_json::from_str::<Value>(l).unwrap())
        .find(|v| v["event"] == "summary")
        .unwrap();
    assert_eq!(summary["up_to_date"].as_u64().unwrap() as usize, recorded_now);
    assert_eq!(summary["ran"].as_u64().unwrap() as usize, total - recorded_now);
    // No temporaries are left, and the result equals an uninterrupted run.
    let leftovers: Vec<_> = walk(&out).into_iter().filter(|p| p.to_string_lossy().ends_with(".texsyn-tmp")).collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
    run_ok(texsyn().arg("verify").arg(out.join("manifest.json")));
    let clean = d.join("clean");
    run_ok(texsyn().arg("run").arg(&jobs).arg("-o").arg(&clean).arg("-q"));
    assert_eq!(pixel_digests(&out), pixel_digests(&clean));
}

#[test]
fn a_second_run_on_the_same_output_directory_is_refused() {
    let d = scratch("lock");
    // Enough jobs that the first run is still going when the second one starts.
    let jobs = small_job_dir(&d, 120);
    let out = d.join("out");
    let mut child = texsyn().arg("run").arg(&jobs).arg("-o").arg(&out).args(["-j", "1", "-q"]).spawn().unwrap();
    let deadline = Instant::now() + Duration::from_secs(60);
    while !out.join("manifest.json").exists() {
        assert!(Instant::now() < deadline);
        std::thread::sleep(Duration::from_millis(10));
    }
    let r = texsyn().arg("run").arg(&jobs).arg("-o").arg(&out).output().unwrap();
    child.kill().unwrap();
    child.wait().unwrap();
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("another texsyn run is using the output directory"));
}

#[test]
fn methods_lists_parameters_with_defaults_and_ranges() {
    let out = run_ok(texsyn().arg("methods"));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("quilting"));
    assert!(text.contains("round(block / 6)"));
    assert!(text.contains("tolerance") && text.contains("[0, 100]"));
}

#[test]
fn help_documents_exit_codes() {
    let out = run_ok(texsyn().arg("run").arg("--help"));
    let text = String::from_utf8_lossy(&out.stdout);
    for code in ["0 ", "1 ", "2 ", "3 ", "130"] {
        assert!(text.contains(code), "{text}");
    }
    let usage = texsyn().arg("run").output().unwrap();
    assert_eq!(usage.status.code(), Some(2));
}

#[test]
fn metrics_are_recorded_with_synthesis_time_and_eval_agrees() {
    let d = scratch("metrics");
    let jobs = small_job_dir(&d, 1);
    let body = std::fs::read_to_string(jobs.join("exr.toml")).unwrap().replace("seed = 3", "seed = 3\nmetrics = true");
    std::fs::write(jobs.join("exr.toml"), body).unwrap();
    let out = d.join("out");
    run_ok(texsyn().arg("run").arg(&jobs).arg("-o").arg(&out).arg("-q"));
    let m = manifest(&out);
    let job = m["jobs"].as_array().unwrap().iter().find(|j| j["id"] == "exr.toml").unwrap();
    let metrics = job["metrics"].as_object().expect("metrics recorded");
    for name in ["kl_gray", "kl_orientation", "acf_gray", "acf_orientation", "verbatim", "seam_visibility"] {
        assert!(metrics[name].is_number(), "{name}: {:?}", metrics[name]);
    }
    assert!(job["timing"]["synthesis_seconds"].as_f64().unwrap() > 0.0);
    let sweep = m["jobs"].as_array().unwrap().iter().find(|j| j["id"] == "sweep.toml#seed=1").unwrap();
    assert!(sweep.get("metrics").is_none(), "metrics only when asked");

    // `eval` computes the same numbers for the same pair (seam visibility needs the grid).
    let r = run_ok(texsyn().arg("eval").arg(jobs.join("bricks.png")).arg(out.join("e.exr")).arg("--json"));
    let v: Value = serde_json::from_slice(&r.stdout).unwrap();
    for name in ["kl_gray", "kl_orientation", "acf_gray", "acf_orientation", "verbatim"] {
        assert_eq!(v["metrics"][name], metrics[name], "{name}");
    }
    assert!(v["metrics"]["seam_visibility"].is_null());
    // Identical images score zero on the paper's four measures.
    let same = run_ok(texsyn().arg("eval").arg(jobs.join("bricks.png")).arg(jobs.join("bricks.png")).arg("--json"));
    let v: Value = serde_json::from_slice(&same.stdout).unwrap();
    for name in ["kl_gray", "kl_orientation", "acf_gray", "acf_orientation"] {
        assert_eq!(v["metrics"][name].as_f64(), Some(0.0), "{name}");
    }
    let bad = texsyn().arg("eval").arg(jobs.join("bricks.png")).arg(jobs.join("missing.png")).output().unwrap();
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("missing.png"));
}
