//! The batch pipeline, in the order a run goes through it:
//!
//! 1. [`job`]: job files → validated jobs (sweeps expanded, every problem with file:line:key);
//! 2. [`plan`]: samples decoded, method checks, memory estimates against `--max-memory`
//!    ([`memory`]), content keys, and for each job *run (why)* or *up to date* — data, printed by
//!    `--dry-run`;
//! 3. [`execute`]: one job synthesised, scored and written (shared by `run` and `verify`);
//! 4. [`run`]: the plan executed in parallel under the output directory's lock ([`outdir`]),
//!    the [`manifest`] rewritten as jobs finish, progress sent to an [`observer`];
//! 5. [`verify`] re-executes a manifest's jobs; [`golden`] compares its digests with `golden/`.
//!
//! [`single`] makes one synthesis from a sample in memory as a job would (the Python package's door).

pub mod diff;
pub mod execute;
pub mod golden;
pub mod guide;
pub mod inpaint;
pub mod job;
pub mod manifest;
pub mod memory;
pub mod merge;
pub mod observer;
pub mod outdir;
pub mod plan;
pub mod run;
pub mod samples;
pub mod shard;
pub mod single;
pub mod source_map;
pub mod verify;
