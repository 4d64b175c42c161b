//! How a batch run tells its caller what it is doing.
//!
//! The library never prints: a run reports [`Event`]s to an [`Observer`] the caller supplies. The
//! CLI implements one that draws a progress bar, writes plain lines for logs, or JSON Lines; a
//! program embedding texsyn can collect the events or ignore them ([`Silent`]).

use crate::batch::job::JobError;
use crate::batch::manifest::JobRecord;
use std::path::Path;

/// Something that happened during a run, in the order it happened (events of jobs running in
/// parallel interleave).
#[derive(Debug)]
pub enum Event<'a> {
    /// A job that cannot run, with every reason (reported before anything runs).
    Invalid { id: &'a str, errors: &'a [JobError] },
    /// The plan is made: `to_run` jobs will run, the others are up to date or invalid.
    Planned { to_run: usize },
    /// A job started.
    Started { id: &'a str },
    /// A job finished (its record says whether it failed, and why).
    Finished { record: &'a JobRecord, job_file: &'a Path, seconds: f64 },
    /// Something the user should know that does not stop the run.
    Warning(String),
    /// The run is over and the manifest written.
    Done { summary: &'a Summary, manifest: &'a Path },
}

/// Receives a run's events. Called from worker threads, hence `Sync`.
pub trait Observer: Sync {
    fn event(&self, event: &Event);
}

/// An observer that ignores everything.
pub struct Silent;

impl Observer for Silent {
    fn event(&self, _event: &Event) {}
}

/// What a run did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Summary {
    pub ran: usize,
    pub up_to_date: usize,
    pub failed: usize,
    pub invalid: usize,
    pub wall_seconds: f64,
    pub interrupted: bool,
}

impl Summary {
    pub fn all_good(&self) -> bool {
        self.failed == 0 && self.invalid == 0 && !self.interrupted
    }
}
