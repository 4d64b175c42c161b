//! The batch pipeline: job files → plan → execute → manifest, and the checks that read a
//! manifest back (verify, golden).

pub mod golden;
pub mod job;
pub mod manifest;
pub mod outdir;
pub mod progress;
pub mod run;
pub mod verify;
