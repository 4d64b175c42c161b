//! Run a job directory from Rust, receiving the run's events through an `Observer`.
//!
//! ```sh
//! cargo run --release --example 03_run_jobs              # runs jobs/quilting into 03_out/
//! ```

use std::sync::Mutex;
use texsyn::{Event, Observer, RunOptions};

/// Counts finished jobs and keeps the failures; the library itself never prints.
#[derive(Default)]
struct Tally {
    finished: Mutex<Vec<String>>,
}

impl Observer for Tally {
    fn event(&self, event: &Event) {
        match event {
            Event::Planned { to_run } => println!("{to_run} job(s) to run"),
            Event::Finished { record, seconds, .. } => {
                println!("{:<40} {:>8} {seconds:.2}s", record.id, record.status.name());
                self.finished.lock().unwrap().push(record.id.clone());
            }
            Event::Invalid { id, errors } => println!("{id}: invalid ({} problem(s))", errors.len()),
            _ => {}
        }
    }
}

fn main() -> Result<(), texsyn::Error> {
    let jobs = std::path::PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/jobs/quilting"));
    let tally = Tally::default();
    let summary = texsyn::run(&[jobs], &RunOptions::new("03_out"), &tally)?;
    println!(
        "ran {}, up to date {}, failed {}, invalid {}; manifest 03_out/manifest.json",
        summary.ran, summary.up_to_date, summary.failed, summary.invalid
    );
    println!("observer saw {} finished job(s) (a second run finds them up to date)", tally.finished.lock().unwrap().len());
    Ok(())
}
