//! Telling the user what a run is doing: a progress bar on a terminal, periodic plain lines in
//! logs (nightly runs), or JSON Lines events on stdout for programs (`--json`).

use indicatif::{ProgressBar, ProgressStyle};
use serde_json::Value;
use std::io::{IsTerminal, Write};
use std::sync::Mutex;
use std::time::{Duration, Instant};

pub enum Mode {
    Bar(ProgressBar),
    Lines { last: Mutex<Instant>, every: Duration },
    Json,
    Quiet,
}

pub struct Progress {
    mode: Mode,
    total: usize,
    done: Mutex<(usize, usize)>,
    started: Instant,
}

impl Progress {
    /// Picks the mode: JSON if asked, a bar when stderr is a terminal, else plain lines.
    pub fn new(total: usize, json: bool, quiet: bool) -> Progress {
        let mode = if json {
            Mode::Json
        } else if quiet || total == 0 {
            Mode::Quiet
        } else if std::io::stderr().is_terminal() {
            let bar = ProgressBar::new(total as u64);
            bar.set_style(
                ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} jobs  {msg}")
                    .expect("valid template"),
            );
            bar.enable_steady_tick(Duration::from_millis(200));
            Mode::Bar(bar)
        } else {
            Mode::Lines { last: Mutex::new(Instant::now()), every: Duration::from_secs(5) }
        };
        Progress { mode, total, done: Mutex::new((0, 0)), started: Instant::now() }
    }

    /// Emits a JSON event (only in JSON mode).
    pub fn event(&self, event: Value) {
        if let Mode::Json = self.mode {
            let mut out = std::io::stdout().lock();
            let _ = writeln!(out, "{event}");
            let _ = out.flush();
        }
    }

    /// A human message (stderr), kept clear of the progress bar.
    pub fn message(&self, text: &str) {
        match &self.mode {
            Mode::Bar(bar) => bar.println(text),
            Mode::Json => {}
            _ => eprintln!("{text}"),
        }
    }

    /// One job finished (any status).
    pub fn job_done(&self, id: &str, failed: bool) {
        let (done, failures) = {
            let mut d = self.done.lock().expect("progress lock");
            d.0 += 1;
            if failed {
                d.1 += 1;
            }
            *d
        };
        match &self.mode {
            Mode::Bar(bar) => {
                bar.set_message(id.to_string());
                bar.inc(1);
            }
            Mode::Lines { last, every } => {
                let mut last = last.lock().expect("progress lock");
                if last.elapsed() >= *every || done == self.total {
                    *last = Instant::now();
                    eprintln!(
                        "texsyn: {done}/{} jobs done ({failures} failed), {:.1}s",
                        self.total,
                        self.started.elapsed().as_secs_f64()
                    );
                }
            }
            _ => {}
        }
    }

    pub fn finish(&self) {
        if let Mode::Bar(bar) = &self.mode {
            bar.finish_and_clear();
        }
    }
}
