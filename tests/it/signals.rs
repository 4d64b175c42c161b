//! SIGTERM and SIGHUP stop a run the way Ctrl-C does: running jobs finish, the manifest is
//! complete and says which jobs did not run, the exit code names the signal.

use super::common::*;

fn stop_with(signal: &str, expected: i32) {
    let out = std::env::temp_dir().join(format!("texsyn-signal-{signal}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let jobs = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("jobs");
    let child = Command::new(env!("CARGO_BIN_EXE_texsyn"))
        .args(["run", jobs.to_str().unwrap(), "-o", out.to_str().unwrap(), "-j", "1", "-q"])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Wait until some job has finished (the manifest lists one), then signal.
    let started = Instant::now();
    loop {
        let done = std::fs::read(out.join("manifest.json"))
            .ok()
            .and_then(|b| serde_json::from_slice::<serde_json::Value>(&b).ok())
            .is_some_and(|m| m["run"]["ran"].as_u64() > Some(0));
        if done || started.elapsed() > Duration::from_secs(120) {
            break;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let status = Command::new("kill").args([&format!("-{signal}"), &child.id().to_string()]).status().unwrap();
    assert!(status.success());
    let output = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(expected), "{signal}: {stderr}");
    assert!(stderr.contains("finishing running jobs"), "{stderr}");
    let m = manifest(&out);
    assert_eq!(m["run"]["in_progress"], false, "{signal}");
    let not_run = m["run"]["not_run"].as_array().expect("not_run listed").len();
    let recorded = m["jobs"].as_array().unwrap().len();
    assert!(not_run > 0, "{signal}: the bundled run is far from done after one job");
    assert_eq!(recorded + not_run, bundled_jobs(), "{signal}: every job is recorded or listed as not run");
    // The next run does exactly the jobs that did not run.
    let again = Command::new(env!("CARGO_BIN_EXE_texsyn"))
        .args(["run", jobs.to_str().unwrap(), "-o", out.to_str().unwrap(), "--dry-run"])
        .output()
        .unwrap();
    let plan = String::from_utf8_lossy(&again.stdout);
    assert_eq!(plan.lines().filter(|l| l.contains("will run")).count(), not_run, "{plan}");
    let _ = std::fs::remove_dir_all(&out);
}

/// How many jobs the bundled directory holds: what a dry run into an empty directory would run.
fn bundled_jobs() -> usize {
    let empty = scratch("signal-count");
    let jobs = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("jobs");
    let plan = run_ok(texsyn().args(["run", jobs.to_str().unwrap(), "-o", empty.to_str().unwrap(), "--dry-run"]));
    let n = String::from_utf8_lossy(&plan.stdout).lines().filter(|l| l.contains("will run")).count();
    assert!(n > 400, "the bundled jobs: {n}");
    n
}

#[test]
fn sigterm_stops_like_ctrl_c_with_exit_143() {
    stop_with("TERM", 143);
}

#[test]
fn sighup_stops_like_ctrl_c_with_exit_129() {
    stop_with("HUP", 129);
}
