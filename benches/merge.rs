//! How `texsyn merge` scales: a synthetic run of 100 000 jobs split into 1 000 shards (100 jobs
//! per fragment, records shaped like real quilting records), merged once. Prints the fragment
//! bytes, the merge time, and the process's peak resident memory.
//!
//! ```sh
//! cargo bench --bench merge                       # 100 000 jobs, 1 000 fragments
//! TEXSYN_MERGE_JOBS=20000 TEXSYN_MERGE_SHARDS=200 cargo bench --bench merge
//! ```

use std::time::Instant;
use texsyn::batch::manifest::{FileRef, JobRecord, Manifest, OutputRecord, RunFacts, SampleRecord, ShardFacts, Status, Timing};
use texsyn::batch::shard;
use texsyn::digest::Digest;

fn env(name: &str, default: usize) -> usize {
    std::env::var(name).ok().and_then(|v| v.parse().ok()).unwrap_or(default)
}

fn record(k: usize) -> JobRecord {
    let id = format!("nightly/quilting_{:03}.toml#block={},seed={}", k % 997, 24 + k % 5 * 8, k);
    let d = |s: &str| Digest::of_bytes(format!("{s}{k}").as_bytes());
    JobRecord {
        id: id.clone(),
        job_file: FileRef { path: format!("../jobs/nightly/quilting_{:03}.toml", k % 997), digest: d("file") },
        status: Status::Ok,
        error: None,
        method: Some("quilting".into()),
        algorithm_version: Some(1),
        params: Some(
            serde_json::json!({"block": 24 + k % 5 * 8, "overlap": 4, "tolerance": 0.1, "search": "fft", "cut": "dp", "blend": "none"}),
        ),
        params_digest: Some(d("params")),
        seed: Some(k as u64),
        sample: Some(SampleRecord {
            path: "../jobs/samples/bricks_gray.png".into(),
            file_digest: d("sf"),
            pixel_digest: d("sp"),
            width: 256,
            height: 256,
        }),
        output_spec: Some(serde_json::json!({"path": format!("q/{k}.png"), "width": 512, "height": 512, "format": "png", "bit_depth": 8})),
        content_key: Some(d("key")),
        outputs: vec![OutputRecord {
            path: format!("q/{k}.png"),
            format: "png".into(),
            bit_depth: 8,
            width: 512,
            height: 512,
            file_digest: d("of"),
            pixel_digest: d("op"),
        }],
        seams: None,
        warnings: Vec::new(),
        companions: Vec::new(),
        more_companions: Vec::new(),
        sample_mask: None,
        inpaint_mask: None,
        guide_target: None,
        guide_source: None,
        samples: Vec::new(),
        sample_masks: Vec::new(),
        diagnostics: serde_json::json!({"blocks": {"cols": 13, "rows": 13}, "mean_candidates": 1.5}),
        metrics: None,
        timing: Some(Timing {
            synthesis_seconds: 0.4,
            metrics_seconds: 0.0,
            phases: Default::default(),
            total_seconds: 0.45,
            finished_at: 1_700_000_000 + k as u64,
            estimated_peak_bytes: None,
        }),
    }
}

fn peak_rss_mb() -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let kb: f64 = status
        .lines()
        .find(|l| l.starts_with("VmHWM:"))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(0.0);
    kb / 1024.0
}

/// The merge alone, in a fresh process, so that its peak memory is its own.
fn merge_only(dir: &std::path::Path) {
    let started = Instant::now();
    let merged = texsyn::batch::merge::merge(dir, None).unwrap();
    let merge_seconds = started.elapsed().as_secs_f64();
    let out = merged.manifest.to_bytes();
    println!(
        "merge (read, check, union, digest, serialise): {:.2} s; merged manifest {:.1} MB; complete: {}; peak RSS of the merging process: {:.0} MB",
        merge_seconds,
        out.len() as f64 / 1e6,
        merged.complete(),
        peak_rss_mb()
    );
}

fn main() {
    if let Ok(dir) = std::env::var("TEXSYN_MERGE_ONLY") {
        return merge_only(std::path::Path::new(&dir));
    }
    let jobs = env("TEXSYN_MERGE_JOBS", 100_000);
    let shards = env("TEXSYN_MERGE_SHARDS", 1_000);
    let dir = std::env::temp_dir().join(format!("texsyn-merge-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let records: Vec<JobRecord> = (0..jobs).map(record).collect();
    let mut ids: Vec<&str> = records.iter().map(|r| r.id.as_str()).collect();
    ids.sort();
    let plan_digest = Digest::of_json(&serde_json::json!(ids));
    let costs: Vec<(&str, u64)> = records.iter().map(|r| (r.id.as_str(), 512 * 512)).collect();
    let started = Instant::now();
    let owner = shard::assign(&costs, shards);
    let assign_seconds = started.elapsed().as_secs_f64();
    let mut per: Vec<Vec<JobRecord>> = vec![Vec::new(); shards];
    for (r, s) in records.into_iter().zip(owner) {
        per[s].push(r);
    }
    let mut bytes = 0u64;
    for (index, jobs_of) in per.into_iter().enumerate() {
        let facts = ShardFacts {
            index,
            count: shards,
            plan_jobs: jobs,
            plan_digest: plan_digest.clone(),
            assigned: jobs_of.len(),
            host: format!("node{index}"),
            scheduler: Default::default(),
        };
        let m = Manifest::new(jobs_of, RunFacts { shard: Some(facts), ..RunFacts::default() });
        let b = m.to_bytes();
        bytes += b.len() as u64;
        std::fs::write(dir.join(format!("manifest.shard-{index}-of-{shards}.json")), b).unwrap();
    }
    println!("jobs {jobs}, shards {shards}: assignment {assign_seconds:.3} s; fragments {:.1} MB", bytes as f64 / 1e6);
    let status = std::process::Command::new(std::env::current_exe().unwrap()).env("TEXSYN_MERGE_ONLY", &dir).status().unwrap();
    assert!(status.success());
    let _ = std::fs::remove_dir_all(&dir);
}
