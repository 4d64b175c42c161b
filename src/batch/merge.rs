//! Joining the manifest fragments of a split run into one manifest.
//!
//! A pure function of the fragments (and, optionally, the job files, to name the jobs of a shard
//! that never wrote anything): the union of their records by job id, with the deterministic
//! digest recomputed, so the result equals a single-machine run's manifest in everything but
//! `run`. Fragments are only read, never changed or removed: a failed merge loses nothing.

use crate::batch::job;
use crate::batch::manifest::{JobRecord, Manifest, RunFacts, ShardFacts, Status};
use crate::batch::plan::is_fragment;
use crate::digest::Digest;
use crate::error::Error;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// What a merge found.
#[derive(Debug)]
pub struct Merged {
    pub manifest: Manifest,
    pub fragments: Vec<PathBuf>,
    /// Shard indices with no fragment.
    pub missing_shards: Vec<usize>,
    /// Shards whose fragment says the run was still going (killed, or still running).
    pub unfinished_shards: Vec<usize>,
    /// Jobs of the job set that no fragment records (known only when the job files are given).
    pub missing_jobs: Vec<String>,
    /// Jobs recorded as failed or invalid, with their error.
    pub failed: Vec<(String, String)>,
}

impl Merged {
    /// Whether every job of the plan is recorded and succeeded.
    pub fn complete(&self) -> bool {
        self.missing_shards.is_empty() && self.unfinished_shards.is_empty() && self.missing_jobs.is_empty() && self.failed.is_empty()
    }
}

/// The fragments (`manifest.shard-I-of-N.json`) in `dir`, sorted by name.
pub fn fragments(dir: &Path) -> Result<Vec<PathBuf>, Error> {
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io(dir, "read directory", e))?;
    let mut found: Vec<PathBuf> = entries.flatten().map(|e| e.path()).filter(|p| is_fragment(p)).collect();
    found.sort();
    Ok(found)
}

/// Merges the fragments found in `dir`. `jobs`, when given, are the job files and directories
/// the shards ran (to name the jobs of missing shards and check the fragments belong to them).
pub fn merge(dir: &Path, jobs: Option<&[PathBuf]>) -> Result<Merged, Error> {
    let paths = fragments(dir)?;
    if paths.is_empty() {
        return Err(Error::Usage(format!(
            "no shard fragments (manifest.shard-I-of-N.json) in {}; run `texsyn run --shard I/N` first",
            dir.display()
        )));
    }
    let mut loaded: Vec<(PathBuf, Manifest, ShardFacts)> = Vec::new();
    for p in &paths {
        let m = Manifest::load(p)?;
        let facts =
            m.run.shard.clone().ok_or_else(|| Error::manifest(p, "has no `run.shard`: not a fragment written by `texsyn run --shard`"))?;
        let expected = format!("manifest.shard-{}-of-{}.json", facts.index, facts.count);
        if p.file_name().and_then(|n| n.to_str()) != Some(expected.as_str()) {
            return Err(Error::manifest(
                p,
                format!("records shard {}/{} but is named for another; was it renamed?", facts.index, facts.count),
            ));
        }
        if m.recompute_digest() != m.deterministic_digest {
            return Err(Error::manifest(p, "its deterministic digest does not match its content: it was edited after texsyn wrote it"));
        }
        loaded.push((p.clone(), m, facts));
    }
    let (first_path, first, first_facts) = &loaded[0];
    for (p, m, f) in &loaded[1..] {
        if f.count != first_facts.count {
            return Err(Error::manifest(
                p,
                format!(
                    "is shard {}/{} but {} is shard {}/{}: fragments of runs split differently; remove the stale ones",
                    f.index,
                    f.count,
                    first_path.display(),
                    first_facts.index,
                    first_facts.count
                ),
            ));
        }
        if f.plan_digest != first_facts.plan_digest {
            return Err(Error::manifest(
                p,
                format!("was planned from another job set than {} (plan digests differ)", first_path.display()),
            ));
        }
        if m.tool != first.tool {
            return Err(Error::manifest(
                p,
                format!(
                    "was written by texsyn {} ({}), {} by {} ({})",
                    m.tool.version,
                    m.tool.commit,
                    first_path.display(),
                    first.tool.version,
                    first.tool.commit
                ),
            ));
        }
    }

    // Union by id; the same id twice must be the same record (timing aside).
    let tool = first.tool.clone();
    let count = first_facts.count;
    let plan_digest = first_facts.plan_digest.clone();
    let plan_jobs = first_facts.plan_jobs;
    let mut runs: Vec<RunFacts> = Vec::with_capacity(loaded.len());
    let mut records: BTreeMap<String, (JobRecord, usize)> = BTreeMap::new();
    for (k, (p, m, _)) in loaded.into_iter().enumerate() {
        // Records are moved, not copied: a merge of 100 000 jobs holds each once.
        let Manifest { jobs, run, .. } = m;
        runs.push(run);
        for rec in jobs {
            match records.get(&rec.id) {
                None => {
                    records.insert(rec.id.clone(), (rec, k));
                }
                Some((other, other_k)) => {
                    let other_path = &paths[*other_k];
                    if comparable(other) != comparable(&rec) {
                        return Err(Error::manifest(
                            &p,
                            format!(
                                "records job `{}` differently from {}; the fragments conflict, refusing to choose",
                                rec.id,
                                other_path.display()
                            ),
                        ));
                    }
                }
            }
        }
    }

    let facts: Vec<ShardFacts> = runs.iter().filter_map(|r| r.shard.clone()).collect();
    let present: std::collections::BTreeSet<usize> = facts.iter().map(|f| f.index).collect();
    let missing_shards: Vec<usize> = (0..count).filter(|i| !present.contains(i)).collect();
    let unfinished_shards: Vec<usize> = runs.iter().filter(|r| r.in_progress).filter_map(|r| r.shard.as_ref().map(|f| f.index)).collect();
    let missing_jobs = match jobs {
        None => Vec::new(),
        Some(inputs) => {
            let set = job::read_all(&job::discover(inputs)?);
            let mut ids: Vec<String> = set.jobs.iter().map(|j| j.id.clone()).chain(set.invalid.iter().map(|i| i.id.clone())).collect();
            ids.sort();
            if Digest::of_json(&serde_json::json!(ids)) != plan_digest {
                return Err(Error::Usage(format!(
                    "the job files given ({} jobs) are not the job set the fragments were planned from ({} jobs); pass the same inputs as to `texsyn run`",
                    ids.len(),
                    plan_jobs
                )));
            }
            ids.into_iter().filter(|id| !records.contains_key(id)).collect()
        }
    };
    let failed: Vec<(String, String)> = records
        .values()
        .filter(|(r, _)| matches!(r.status, Status::Failed | Status::Invalid))
        .map(|(r, _)| (r.id.clone(), format!("{}: {}", r.status.name(), r.error.as_deref().unwrap_or(""))))
        .collect();

    let jobs: Vec<JobRecord> = records.into_values().map(|(r, _)| r).collect();
    let count_status = |s: Status| jobs.iter().filter(|j| j.status == s).count();
    let started_at = runs.iter().map(|r| r.started_at).min().unwrap_or(0);
    let finished_at = runs.iter().map(|r| r.finished_at).max().unwrap_or(0);
    let run = RunFacts {
        started_at,
        finished_at,
        wall_seconds: finished_at.saturating_sub(started_at) as f64,
        host: "merged".into(),
        argv: std::env::args().collect(),
        threads: runs.iter().map(|r| r.threads).sum(),
        ran: count_status(Status::Ok),
        up_to_date: count_status(Status::UpToDate),
        failed: count_status(Status::Failed),
        invalid: count_status(Status::Invalid),
        in_progress: false,
        shard: None,
        not_run: runs.iter().flat_map(|r| r.not_run.iter().cloned()).collect(),
        merged_from: facts,
        max_memory_bytes: runs.iter().filter_map(|r| r.max_memory_bytes).min(),
        peak_rss_bytes: runs.iter().filter_map(|r| r.peak_rss_bytes).max(),
        job_roots: runs.iter().flat_map(|r| r.job_roots.iter().cloned()).collect::<std::collections::BTreeSet<_>>().into_iter().collect(),
        rerunning: Vec::new(),
    };
    let manifest = Manifest::with_tool(tool, jobs, run);
    Ok(Merged { manifest, fragments: paths, missing_shards, unfinished_shards, missing_jobs, failed })
}

/// A record as the deterministic digest sees it: without timing, up-to-date as ok.
fn comparable(r: &JobRecord) -> serde_json::Value {
    let mut r = r.clone();
    r.timing = None;
    if r.status == Status::UpToDate {
        r.status = Status::Ok;
    }
    serde_json::to_value(r).expect("record serialises")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::batch::manifest::{FileRef, Timing};

    fn record(id: &str, status: Status, pixels: &str) -> JobRecord {
        JobRecord {
            id: id.into(),
            job_file: FileRef { path: format!("jobs/{id}"), digest: Digest::of_bytes(id.as_bytes()) },
            status,
            error: (status == Status::Failed).then(|| "quilting failed: boom".to_string()),
            method: Some("quilting".into()),
            algorithm_version: Some(1),
            params: None,
            params_digest: None,
            seed: Some(1),
            sample: None,
            output_spec: None,
            content_key: Some(Digest::of_bytes(pixels.as_bytes())),
            outputs: Vec::new(),
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
            diagnostics: serde_json::Value::Null,
            metrics: None,
            timing: Some(Timing {
                synthesis_seconds: 0.5,
                metrics_seconds: 0.0,
                phases: Default::default(),
                total_seconds: 0.6,
                finished_at: 9,
                estimated_peak_bytes: None,
            }),
        }
    }

    fn fragment(dir: &Path, index: usize, count: usize, jobs: Vec<JobRecord>, plan: &str) -> PathBuf {
        let facts = ShardFacts {
            index,
            count,
            plan_jobs: 4,
            plan_digest: Digest::of_bytes(plan.as_bytes()),
            assigned: jobs.len(),
            host: "node".into(),
            scheduler: [("SLURM_ARRAY_TASK_ID".to_string(), index.to_string())].into(),
        };
        let run = RunFacts { shard: Some(facts), ..RunFacts::default() };
        let m = Manifest::new(jobs, run);
        let p = dir.join(format!("manifest.shard-{index}-of-{count}.json"));
        std::fs::write(&p, m.to_bytes()).unwrap();
        p
    }

    fn tmp(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("texsyn-merge-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn union_by_id_with_the_digest_of_one_manifest() {
        let d = tmp("union");
        fragment(&d, 0, 2, vec![record("a", Status::Ok, "1"), record("c", Status::UpToDate, "3")], "p");
        fragment(&d, 1, 2, vec![record("b", Status::Ok, "2"), record("d", Status::Ok, "4")], "p");
        let m = merge(&d, None).unwrap();
        assert!(m.complete(), "{m:?}");
        let ids: Vec<&str> = m.manifest.jobs.iter().map(|j| j.id.as_str()).collect();
        assert_eq!(ids, ["a", "b", "c", "d"]);
        let whole = Manifest::new(
            vec![record("a", Status::Ok, "1"), record("b", Status::Ok, "2"), record("c", Status::Ok, "3"), record("d", Status::Ok, "4")],
            RunFacts::default(),
        );
        assert_eq!(m.manifest.deterministic_digest, whole.deterministic_digest);
        assert_eq!(m.manifest.run.merged_from.len(), 2);
        assert_eq!(m.manifest.run.merged_from[1].scheduler["SLURM_ARRAY_TASK_ID"], "1");
    }

    #[test]
    fn missing_shards_and_failed_jobs_are_reported_and_the_rest_kept() {
        let d = tmp("missing");
        fragment(&d, 0, 3, vec![record("a", Status::Ok, "1"), record("b", Status::Failed, "2")], "p");
        fragment(&d, 2, 3, vec![record("c", Status::Ok, "3")], "p");
        let m = merge(&d, None).unwrap();
        assert!(!m.complete());
        assert_eq!(m.missing_shards, vec![1]);
        assert_eq!(m.failed, vec![("b".to_string(), "failed: quilting failed: boom".to_string())]);
        assert_eq!(m.manifest.jobs.len(), 3, "the other jobs are kept");
        assert_eq!(m.manifest.run.failed, 1);
    }

    #[test]
    fn identical_duplicates_are_one_job_and_conflicting_ones_are_refused() {
        let d = tmp("dup");
        fragment(&d, 0, 2, vec![record("a", Status::Ok, "1")], "p");
        fragment(&d, 1, 2, vec![record("a", Status::UpToDate, "1")], "p");
        assert_eq!(merge(&d, None).unwrap().manifest.jobs.len(), 1);
        fragment(&d, 1, 2, vec![record("a", Status::Ok, "other pixels")], "p");
        let e = merge(&d, None).unwrap_err().to_string();
        assert!(e.contains("records job `a` differently") && e.contains("manifest.shard-1-of-2.json"), "{e}");
    }

    #[test]
    fn corrupt_foreign_or_mixed_fragments_are_clear_errors() {
        let d = tmp("corrupt");
        assert!(merge(&d, None).unwrap_err().to_string().contains("no shard fragments"));
        fragment(&d, 0, 2, vec![record("a", Status::Ok, "1")], "p");
        std::fs::write(d.join("manifest.shard-1-of-2.json"), b"{\"format\": \"texsyn-manifest/1\", \"jobs\": [").unwrap();
        let e = merge(&d, None).unwrap_err().to_string();
        assert!(e.contains("manifest.shard-1-of-2.json") && e.contains("not a texsyn manifest"), "{e}");
        fragment(&d, 1, 2, vec![record("b", Status::Ok, "2")], "another job set");
        assert!(merge(&d, None).unwrap_err().to_string().contains("another job set than"));
        fragment(&d, 1, 2, vec![record("b", Status::Ok, "2")], "p");
        fragment(&d, 0, 3, vec![record("c", Status::Ok, "3")], "p");
        assert!(merge(&d, None).unwrap_err().to_string().contains("split differently"));
        std::fs::remove_file(d.join("manifest.shard-0-of-3.json")).unwrap();
        // An edited fragment.
        let p = d.join("manifest.shard-1-of-2.json");
        let text = std::fs::read_to_string(&p).unwrap().replace("\"seed\": 1", "\"seed\": 2");
        std::fs::write(&p, text).unwrap();
        assert!(merge(&d, None).unwrap_err().to_string().contains("edited after texsyn wrote it"));
    }
}
