//! Telling the user what a run is doing: a progress bar on a terminal, periodic plain lines in
//! logs (nightly runs), or JSON Lines events on stdout for programs (`--json`). This is the CLI's
//! [`Observer`]; the library only reports events.

use super::say;
use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::sync::Mutex;
use std::time::{Duration, Instant};
use texsyn::batch::manifest::Status;
use texsyn::batch::observer::{Event, Observer};
use texsyn::batch::shard::Shard;

enum Mode {
    /// Created when the plan says how many jobs will run.
    Bar(Mutex<Option<ProgressBar>>),
    Lines {
        last: Mutex<Instant>,
        every: Duration,
    },
    Json,
    Quiet,
}

pub struct Progress {
    mode: Mode,
    /// On a cluster, every line says which shard wrote it (logs of many tasks get mixed).
    shard: Option<Shard>,
    /// Jobs to run, finished, failed.
    counts: Mutex<(usize, usize, usize)>,
    started: Instant,
}

impl Progress {
    /// JSON if asked, nothing if quiet, a bar when stderr is a terminal, else plain lines.
    pub fn new(json: bool, quiet: bool, shard: Option<Shard>) -> Progress {
        let mode = if json {
            Mode::Json
        } else if quiet {
            Mode::Quiet
        } else if std::io::stderr().is_terminal() {
            Mode::Bar(Mutex::new(None))
        } else {
            Mode::Lines { last: Mutex::new(Instant::now()), every: Duration::from_secs(5) }
        };
        Progress { mode, shard, counts: Mutex::new((0, 0, 0)), started: Instant::now() }
    }

    /// A human message on stderr, kept clear of the progress bar (none in JSON mode).
    fn message(&self, text: &str) {
        let text = &match self.shard {
            Some(s) => format!("[shard {s}] {text}"),
            None => text.to_string(),
        };
        match &self.mode {
            Mode::Bar(bar) => match bar.lock().expect("progress lock").as_ref() {
                Some(b) => b.println(text),
                None => eprintln!("{text}"),
            },
            Mode::Json => {}
            _ => eprintln!("{text}"),
        }
    }

    fn json(&self, mut value: serde_json::Value) {
        if let Mode::Json = self.mode {
            if let (Some(s), Some(obj)) = (self.shard, value.as_object_mut()) {
                obj.insert("shard".into(), serde_json::json!({"index": s.index, "count": s.count}));
            }
            say(value);
        }
    }
}

impl Observer for Progress {
    fn event(&self, event: &Event) {
        match event {
            Event::Invalid { id, errors } => {
                for e in *errors {
                    self.message(&format!("error: {e}"));
                }
                self.json(
                    serde_json::json!({"event": "invalid", "id": id, "errors": errors.iter().map(|e| e.to_string()).collect::<Vec<_>>()}),
                );
            }
            Event::Planned { to_run } => {
                self.counts.lock().expect("progress lock").0 = *to_run;
                if let Mode::Bar(bar) = &self.mode
                    && *to_run > 0
                {
                    let b = ProgressBar::new(*to_run as u64);
                    b.set_style(
                        ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} jobs  {msg}")
                            .expect("valid template"),
                    );
                    b.enable_steady_tick(Duration::from_millis(200));
                    *bar.lock().expect("progress lock") = Some(b);
                }
            }
            Event::Started { id } => self.json(serde_json::json!({"event": "start", "id": id})),
            Event::Finished { record, job_file, seconds } => {
                let failed = record.status == Status::Failed;
                if failed {
                    self.message(&format!("error: {}: {}: {}", job_file.display(), record.id, record.error.as_deref().unwrap_or("")));
                }
                self.json(serde_json::json!({
                    "event": "finish", "id": record.id, "status": record.status.name(), "error": record.error,
                    "seconds": seconds, "outputs": record.outputs.iter().map(|o| &o.path).collect::<Vec<_>>(),
                }));
                let (total, done, failures) = {
                    let mut c = self.counts.lock().expect("progress lock");
                    c.1 += 1;
                    c.2 += usize::from(failed);
                    *c
                };
                match &self.mode {
                    Mode::Bar(bar) => {
                        if let Some(b) = bar.lock().expect("progress lock").as_ref() {
                            b.set_message(record.id.clone());
                            b.inc(1);
                        }
                    }
                    Mode::Lines { last, every } => {
                        let mut last = last.lock().expect("progress lock");
                        if last.elapsed() >= *every || done == total {
                            *last = Instant::now();
                            let shard = self.shard.map(|s| format!(" [shard {s}]")).unwrap_or_default();
                            eprintln!(
                                "texsyn{shard}: {done}/{total} jobs done ({failures} failed), {:.1}s",
                                self.started.elapsed().as_secs_f64()
                            );
                        }
                    }
                    _ => {}
                }
            }
            Event::Warning(text) => self.message(&format!("warning: {text}")),
            Event::Done { summary: s, manifest } => {
                if let Mode::Bar(bar) = &self.mode
                    && let Some(b) = bar.lock().expect("progress lock").take()
                {
                    b.finish_and_clear();
                }
                self.json(serde_json::json!({
                    "event": "summary", "ran": s.ran, "up_to_date": s.up_to_date, "failed": s.failed,
                    "invalid": s.invalid, "interrupted": s.interrupted, "wall_seconds": s.wall_seconds,
                    "manifest": manifest.display().to_string(),
                }));
            }
        }
    }
}
