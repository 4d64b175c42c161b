//! Any bytes as a job file: reading, validation and sweep expansion must answer with jobs or
//! errors, never panic or hang.
#![no_main]

use libfuzzer_sys::fuzz_target;
use texsyn::batch::job::{JobFile, parse_job_file};

fuzz_target!(|data: &[u8]| {
    // Relative sample paths resolve against the job file's directory: the bundled samples.
    let file = JobFile { path: concat!(env!("CARGO_MANIFEST_DIR"), "/../jobs/fuzz.toml").into(), rel: "fuzz.toml".into() };
    if let Ok(jobs) = parse_job_file(&file, data.to_vec()) {
        for job in &jobs {
            // What the run does next with a valid job, short of decoding the sample.
            let _ = job.method.check(&job.params, (256, 256), (job.output.width, job.output.height));
        }
    }
});
