//! patch-sampling through the `texsyn` binary: bad parameters are reported as job errors naming
//! the key, like every other job error; the diagnostics reach the manifest; thread count does
//! not change the pixels or the diagnostics.

use super::common::*;

fn sample() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/samples/pebbles_beige.png").display().to_string().replace('\\', "/")
}

fn job(dir: &Path, name: &str, params: &str, size: u32) {
    let text = format!(
        "sample = \"{}\"\nmethod = \"patch-sampling\"\nseed = 4\n[output]\npath = \"{name}.png\"\nwidth = {size}\nheight = {size}\n[params]\n{params}\n",
        sample()
    );
    write(&dir.join("jobs").join(format!("{name}.toml")), &text);
}

#[test]
fn bad_parameters_are_job_errors_naming_the_key() {
    let d = scratch("bad");
    let cases = [
        ("zero_particles", "particles = 0", "particles`: 0 is out of range"),
        ("huge_block", "block = 300", "block`: block 300 is larger than the sample"),
        ("wide_overlap", "block = 30\noverlap = 16", "overlap`"),
        ("first_outside", "first_x = 240\nfirst_y = 3", "first_x`"),
        ("half_first", "first_x = 3", "first_y`"),
        ("frozen_swarm", "vmax = 0", "vmax`"),
        ("bad_search", "search = \"annealing\"", "cpso | pso | exhaustive"),
        ("typo", "particle = 20", "did you mean `particles`"),
    ];
    for (name, params, _) in &cases {
        job(&d, name, params, 64);
    }
    job(&d, "good", "block = 20", 64);
    let out = texsyn().current_dir(&d).args(["run", "jobs", "-o", "out", "-j", "1", "-q"]).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    for (name, _, needle) in &cases {
        let line = stderr.lines().find(|l| l.contains(&format!("{name}.toml"))).unwrap_or_else(|| panic!("no error for {name}: {stderr}"));
        assert!(line.contains(needle), "{name}: {line}");
    }
    let m = manifest(&d.join("out"));
    let jobs = m["jobs"].as_array().unwrap();
    assert_eq!(jobs.iter().filter(|j| j["status"] == "invalid").count(), cases.len());
    assert!(jobs.iter().any(|j| j["id"] == "good.toml" && j["status"] == "ok"));
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn diagnostics_reach_the_manifest_and_do_not_depend_on_threads() {
    let d = scratch("threads");
    job(&d, "cpso", "block = 24\ndiagnostics = true", 100);
    job(&d, "pso", "block = 24\nsearch = \"pso\"\nrecord_optimum = true", 100);
    job(&d, "exhaustive", "block = 24\nsearch = \"exhaustive\"\nblend = \"cut\"\ndiagnostics = true", 100);
    let mut runs = Vec::new();
    for (threads, rayon) in [("1", "1"), ("2", "3")] {
        let out = d.join(format!("out{threads}"));
        let st = texsyn()
            .current_dir(&d)
            .env("RAYON_NUM_THREADS", rayon)
            .arg("run")
            .arg("jobs")
            .arg("-o")
            .arg(&out)
            .args(["-j", threads, "-q"])
            .output()
            .unwrap();
        assert!(st.status.success(), "{}", String::from_utf8_lossy(&st.stderr));
        runs.push(manifest(&out));
    }
    assert_eq!(runs[0]["deterministic_digest"], runs[1]["deterministic_digest"]);
    let cpso = runs[0]["jobs"].as_array().unwrap().iter().find(|j| j["id"] == "cpso.toml").unwrap();
    let blocks = cpso["diagnostics"]["per_block"].as_array().unwrap();
    assert_eq!(blocks.len(), 5 * 5 - 1); // block 24, overlap 4: stride 20, 5 x 5 blocks cover 100
    for key in ["error", "iterations", "best_iteration", "chaos_searches", "evaluations", "stopped_early"] {
        assert!(!blocks[0][key].is_null(), "{key}");
    }
    let pso = runs[0]["jobs"].as_array().unwrap().iter().find(|j| j["id"] == "pso.toml").unwrap();
    assert!(pso["diagnostics"]["per_block"][0]["optimum"].is_u64());
    assert!(pso["timing"]["synthesis_seconds"].is_f64());
    let _ = std::fs::remove_dir_all(&d);
}
