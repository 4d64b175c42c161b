//! Shards and merge through the `texsyn` binary: a job directory split N ways and merged gives the
//! single-machine manifest (deterministic digest), for N from 1 to more shards than jobs; a shard
//! that never ran is named job by job; re-running a shard redoes only what is not up to date.

use super::common::*;

fn jobs() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/cluster_jobs")
}

fn run(args: &[&str]) -> Output {
    texsyn().args(args).output().expect("texsyn runs")
}

#[test]
fn merged_shards_equal_one_machine_for_every_split() {
    let jobs = jobs();
    let jobs = jobs.to_str().unwrap();
    let local = scratch("local");
    // One job fails on purpose: exit 1, recorded as failed.
    let o = run(&["run", jobs, "-o", local.to_str().unwrap(), "-q"]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let want = json(&local.join("manifest.json"))["deterministic_digest"].clone();
    let total = json(&local.join("manifest.json"))["jobs"].as_array().unwrap().len();
    assert_eq!(total, 41);
    for n in [1usize, 2, 3, 4, 7, 16, 41, 45] {
        let out = scratch(&format!("n{n}"));
        let out_s = out.to_str().unwrap();
        let mut assigned = 0;
        for i in 0..n {
            let o = run(&["run", jobs, "-o", out_s, "-q", "-j", "1", "--shard", &format!("{i}/{n}")]);
            assert!(matches!(o.status.code(), Some(0 | 1)), "shard {i}/{n}: {}", text(&o));
            let frag = json(&out.join(format!("manifest.shard-{i}-of-{n}.json")));
            let facts = &frag["run"]["shard"];
            assert_eq!(
                (facts["index"].as_u64(), facts["count"].as_u64(), facts["plan_jobs"].as_u64()),
                (Some(i as u64), Some(n as u64), Some(41))
            );
            assigned += frag["jobs"].as_array().unwrap().len();
        }
        assert_eq!(assigned, total, "n={n}: every job in exactly one fragment");
        let o = run(&["merge", out_s, "--jobs", jobs]);
        assert_eq!(o.status.code(), Some(1), "n={n}: the failing job makes merge exit 1\n{}", text(&o));
        assert!(text(&o).contains("FAILED    fails.toml"), "{}", text(&o));
        let merged = json(&out.join("manifest.json"));
        assert_eq!(merged["deterministic_digest"], want, "n={n}");
        assert_eq!(merged["run"]["merged_from"].as_array().unwrap().len(), n);
        let _ = std::fs::remove_dir_all(&out);
    }
    // verify and golden-style checks read the merged manifest like any other.
    let out = scratch("verify");
    let out_s = out.to_str().unwrap();
    for i in 0..3 {
        run(&["run", jobs, "-o", out_s, "-q", "--shard", &format!("{i}/3")]);
    }
    run(&["merge", out_s]);
    let o = run(&["verify", out.join("manifest.json").to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("40 verified, 0 mismatched"), "{}", text(&o));
    // The merged night compares with the single-machine one: nothing changed, one failure named.
    let report = scratch("merged-report").join("r");
    let o = run(&["report", out.join("manifest.json").to_str().unwrap(), "-o", report.to_str().unwrap(), "--since"]
        .into_iter()
        .chain([local.join("manifest.json").to_str().unwrap()])
        .collect::<Vec<_>>());
    assert!(o.status.success(), "{}", text(&o));
    let page = std::fs::read_to_string(report.join("index.html")).unwrap();
    assert!(page.contains("data-pixels-changed=\"0\"") && page.contains("data-failed-now=\"0\""), "since block");
    assert!(page.contains("data-job=\"fails.toml\" data-status=\"failed\""), "the failure is listed");
}

#[test]
fn a_missing_shard_is_named_job_by_job_and_a_rerun_redoes_only_its_part() {
    let jobs = jobs();
    let jobs = jobs.to_str().unwrap();
    let out = scratch("missing");
    let out_s = out.to_str().unwrap();
    for i in [0, 2] {
        run(&["run", jobs, "-o", out_s, "-q", "--shard", &format!("{i}/3")]);
    }
    let o = run(&["merge", out_s, "--jobs", jobs]);
    let t = text(&o);
    assert_eq!(o.status.code(), Some(1), "{t}");
    assert!(t.contains("MISSING   shard 1/3"), "{t}");
    let missing = t.lines().filter(|l| l.starts_with("MISSING   ") && !l.contains("shard")).count();
    assert!(missing > 0, "{t}");
    // The merged manifest is written all the same, with the other shards' jobs kept.
    let merged = json(&out.join("manifest.json"));
    assert_eq!(merged["jobs"].as_array().unwrap().len() + missing, 41);
    // Shard 1 runs now; shards 0 and 2 re-run find everything up to date.
    run(&["run", jobs, "-o", out_s, "-q", "--shard", "1/3"]);
    let again = run(&["run", jobs, "-o", out_s, "--shard", "0/3"]);
    assert!(text(&again).contains("ran 0, up to date"), "{}", text(&again));
    let o = run(&["merge", out_s, "--jobs", jobs]);
    assert!(!text(&o).contains("MISSING"), "{}", text(&o));
    // A merge elsewhere than the directory would break the manifest's relative paths.
    let elsewhere = scratch("elsewhere");
    let o = run(&["merge", out_s, "-o", elsewhere.join("m.json").to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    // Bad shard specifications are usage errors.
    for bad in ["3/3", "x", "1/0"] {
        let o = run(&["run", jobs, "-o", out_s, "--shard", bad]);
        assert_eq!(o.status.code(), Some(2), "{bad}: {}", text(&o));
    }
    let o = texsyn()
        .args(["run", jobs, "-o", out_s, "--shard", "auto"])
        .env_remove("SLURM_ARRAY_TASK_ID")
        .env_remove("JOB_COMPLETION_INDEX")
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("no scheduler index found"), "{}", text(&o));
    let o = texsyn()
        .args(["run", jobs, "-o", out_s, "-q", "--shard", "auto"])
        .env("SLURM_ARRAY_TASK_ID", "2")
        .env("SLURM_ARRAY_TASK_COUNT", "3")
        .output()
        .unwrap();
    assert!(matches!(o.status.code(), Some(0 | 1)), "{}", text(&o));
    assert_eq!(json(&out.join("manifest.shard-2-of-3.json"))["run"]["shard"]["scheduler"]["SLURM_ARRAY_TASK_ID"], "2");
}
