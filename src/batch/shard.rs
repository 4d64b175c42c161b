//! Splitting a job set across N workers (a Slurm array, a Kubernetes Indexed Job, any "N
//! workers, each told its index" engine).
//!
//! The assignment is a pure function of the job set and (I, N): every worker computes the same
//! split from the same job files, so a re-submitted shard redoes exactly its own jobs, whatever
//! the timing, host or file order. The rule: jobs are taken by decreasing expected cost (ties by
//! id), each going to the shard with the least cost so far (ties to the lower index) — the
//! longest-processing-time rule, within 4/3 of the best possible balance. A job's cost is its
//! output pixels times its method's relative speed ([`method_cost`]), from the job file alone, so
//! an unreadable sample on one node cannot move jobs between shards.

use crate::error::Error;
use std::fmt;

/// This worker's part: `index` in `0..count`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

/// The most shards a job set may be split into (Slurm's default `MaxArraySize` is 1001).
pub const MAX_SHARDS: usize = 100_000;

impl Shard {
    /// `I/N` with `I` 0-based, e.g. `3/16`.
    pub fn parse(s: &str) -> Result<Shard, Error> {
        let bad = || Error::Usage(format!("--shard `{s}`: expected I/N with 0 <= I < N (e.g. 3/16), or `auto`"));
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let (index, count) = (i.trim().parse::<usize>().map_err(|_| bad())?, n.trim().parse::<usize>().map_err(|_| bad())?);
        Shard::new(index, count).ok_or_else(bad)
    }

    pub fn new(index: usize, count: usize) -> Option<Shard> {
        ((1..=MAX_SHARDS).contains(&count) && index < count).then_some(Shard { index, count })
    }

    /// The shard the scheduler gave this process: Slurm's `SLURM_ARRAY_TASK_ID` and
    /// `SLURM_ARRAY_TASK_COUNT` (relative to `SLURM_ARRAY_TASK_MIN`), or a Kubernetes Indexed
    /// Job's `JOB_COMPLETION_INDEX` with the count in `TEXSYN_SHARD_COUNT` (Kubernetes does not
    /// export the Job's `completions`).
    pub fn from_env(get: impl Fn(&str) -> Option<String>) -> Result<Shard, Error> {
        let num = |name: &str| -> Result<Option<usize>, Error> {
            match get(name) {
                None => Ok(None),
                Some(v) => v.trim().parse().map(Some).map_err(|_| Error::Usage(format!("--shard auto: {name}={v:?} is not a number"))),
            }
        };
        if let Some(id) = num("SLURM_ARRAY_TASK_ID")? {
            let min = num("SLURM_ARRAY_TASK_MIN")?.unwrap_or(0);
            let count = match num("SLURM_ARRAY_TASK_COUNT")? {
                Some(c) => c,
                None => num("SLURM_ARRAY_TASK_MAX")?.map(|max| max + 1 - min).ok_or_else(|| {
                    Error::Usage(
                        "--shard auto: SLURM_ARRAY_TASK_ID is set but neither SLURM_ARRAY_TASK_COUNT nor SLURM_ARRAY_TASK_MAX".into(),
                    )
                })?,
            };
            let index = id
                .checked_sub(min)
                .ok_or_else(|| Error::Usage(format!("--shard auto: SLURM_ARRAY_TASK_ID {id} is below SLURM_ARRAY_TASK_MIN {min}")))?;
            return Shard::new(index, count).ok_or_else(|| {
                Error::Usage(format!(
                    "--shard auto: array task {index} of {count} is not a valid shard (the array must be 0..N-1 or contiguous)"
                ))
            });
        }
        if let Some(index) = num("JOB_COMPLETION_INDEX")? {
            let count = num("TEXSYN_SHARD_COUNT")?.ok_or_else(|| {
                Error::Usage("--shard auto: JOB_COMPLETION_INDEX is set; also set TEXSYN_SHARD_COUNT to the Job's completions".into())
            })?;
            return Shard::new(index, count)
                .ok_or_else(|| Error::Usage(format!("--shard auto: index {index} is not below TEXSYN_SHARD_COUNT {count}")));
        }
        Err(Error::Usage(
            "--shard auto: no scheduler index found (SLURM_ARRAY_TASK_ID, or JOB_COMPLETION_INDEX with TEXSYN_SHARD_COUNT); use --shard I/N".into(),
        ))
    }

    /// The name of this shard's manifest fragment in the output directory.
    pub fn fragment_name(&self) -> String {
        format!("manifest.shard-{}-of-{}.json", self.index, self.count)
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// Relative cost per output pixel, from the single-thread timings of the bundled jobs (quilting
/// = 1). Only the balance depends on these; a wrong factor never changes a result.
pub fn method_cost(method: &str) -> u64 {
    match method {
        "double-seam" => 8,
        "patch-sampling" | "tes" => 2,
        "quilting" => 1,
        // Tile fills and lattice texels copy rows; their cost is mostly per job.
        _ => 1,
    }
}

/// Which shard each job goes to. `jobs` are `(id, cost)`; the result is in the same order.
/// Costs are clamped to at least 1 so that free jobs still spread.
pub fn assign(jobs: &[(&str, u64)], count: usize) -> Vec<usize> {
    let mut order: Vec<usize> = (0..jobs.len()).collect();
    order.sort_by(|&a, &b| jobs[b].1.max(1).cmp(&jobs[a].1.max(1)).then_with(|| jobs[a].0.cmp(jobs[b].0)));
    let mut load = vec![0u64; count.max(1)];
    let mut shard_of = vec![0; jobs.len()];
    for k in order {
        // Least loaded, lowest index on ties: deterministic.
        let (s, _) = load.iter().enumerate().min_by_key(|&(i, l)| (*l, i)).expect("at least one shard");
        shard_of[k] = s;
        load[s] += jobs[k].1.max(1);
    }
    shard_of
}

#[cfg(test)]
mod tests {
    use super::*;

    fn jobs(n: usize) -> Vec<(String, u64)> {
        // Costs of very different sizes, like a real job set (64² tiles to 2048² quilts).
        (0..n)
            .map(|k| {
                (format!("dir/job_{k:04}.toml#seed={}", k % 7), [4096u64, 65_536, 262_144, 4_194_304][k * 7 % 4] * (1 + (k % 3) as u64))
            })
            .collect()
    }

    #[test]
    fn every_job_exactly_once_balanced_and_stable_for_1_to_64_shards() {
        let owned = jobs(300);
        let js: Vec<(&str, u64)> = owned.iter().map(|(i, c)| (i.as_str(), *c)).collect();
        let total: u64 = js.iter().map(|j| j.1).sum();
        let biggest = js.iter().map(|j| j.1).max().unwrap();
        for n in 1..=64 {
            let a = assign(&js, n);
            assert_eq!(a.len(), js.len());
            assert!(a.iter().all(|&s| s < n));
            let mut load = vec![0u64; n];
            for (k, &s) in a.iter().enumerate() {
                load[s] += js[k].1;
            }
            // LPT: no shard exceeds the mean by more than the largest job.
            let max = *load.iter().max().unwrap();
            assert!(max <= total / n as u64 + biggest, "n={n}: max load {max}, mean {}", total / n as u64);
            // Stable: the same split whatever order the jobs are listed in.
            let mut shuffled: Vec<(&str, u64)> = js.clone();
            shuffled.reverse();
            shuffled.rotate_left(n % js.len());
            let b = assign(&shuffled, n);
            for (k, (id, _)) in shuffled.iter().enumerate() {
                let orig = js.iter().position(|j| j.0 == *id).unwrap();
                assert_eq!(b[k], a[orig], "n={n}: {id} moved");
            }
        }
    }

    #[test]
    fn more_shards_than_jobs_leaves_some_empty() {
        let js = [("a", 5), ("b", 5), ("c", 1)];
        let a = assign(&js, 8);
        let mut seen: Vec<usize> = a.clone();
        seen.sort();
        seen.dedup();
        assert_eq!(seen.len(), 3, "{a:?}");
    }

    #[test]
    fn parses_shards_and_reads_scheduler_environments() {
        assert_eq!(Shard::parse("3/16").unwrap(), Shard { index: 3, count: 16 });
        for bad in ["16/16", "1/0", "x/2", "3", "-1/4", "1/2/3"] {
            assert!(Shard::parse(bad).is_err(), "{bad}");
        }
        let env = |pairs: &'static [(&'static str, &'static str)]| move |k: &str| pairs.iter().find(|p| p.0 == k).map(|p| p.1.to_string());
        assert_eq!(
            Shard::from_env(env(&[("SLURM_ARRAY_TASK_ID", "2"), ("SLURM_ARRAY_TASK_COUNT", "4")])).unwrap(),
            Shard { index: 2, count: 4 }
        );
        assert_eq!(
            Shard::from_env(env(&[("SLURM_ARRAY_TASK_ID", "5"), ("SLURM_ARRAY_TASK_MIN", "1"), ("SLURM_ARRAY_TASK_MAX", "8")])).unwrap(),
            Shard { index: 4, count: 8 }
        );
        assert_eq!(
            Shard::from_env(env(&[("JOB_COMPLETION_INDEX", "0"), ("TEXSYN_SHARD_COUNT", "3")])).unwrap(),
            Shard { index: 0, count: 3 }
        );
        let e = Shard::from_env(env(&[("JOB_COMPLETION_INDEX", "0")])).unwrap_err();
        assert!(e.to_string().contains("TEXSYN_SHARD_COUNT"), "{e}");
        assert!(Shard::from_env(env(&[])).unwrap_err().to_string().contains("no scheduler index"));
        assert_eq!(Shard { index: 3, count: 16 }.fragment_name(), "manifest.shard-3-of-16.json");
    }
}
