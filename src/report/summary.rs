//! The top of the page: what a reader of a nightly run needs first — how many jobs ran and
//! failed (with the error text), how long it took, the slowest jobs and, when compared with an
//! earlier run or the golden digests, what regressed. The tables and pictures come after.

use super::fmt::{self, html as h};
use crate::batch::diff::Diff;
use crate::batch::diff::describe_changes;
use crate::batch::golden::CheckReport;
use crate::batch::manifest::{Manifest, Status};

/// How many of the slowest jobs are listed.
pub const SLOWEST: usize = 10;
/// Failures listed in full before the rest fold away.
const FAILURES_SHOWN: usize = 50;

/// What the run is compared with, if anything.
pub struct Comparison<'a> {
    pub since: Option<(&'a str, &'a Diff)>,
    pub golden: Option<(&'a str, &'a CheckReport)>,
}

fn count_row(key: &str, label: &str, n: usize) -> String {
    format!("<tr><th>{}</th><td data-count=\"{key}\" data-value=\"{n}\">{n}</td></tr>", h(label))
}

fn seconds(x: f64) -> String {
    format!("<span data-seconds=\"{}\">{} s</span>", fmt::full(x), fmt::sig(x))
}

pub fn html(manifest: &Manifest, cmp: &Comparison) -> String {
    let jobs = &manifest.jobs;
    let of = |s: Status| jobs.iter().filter(|j| j.status == s).count();
    let r = &manifest.run;
    let mut out = String::from("<section id=\"summary\">\n<h2>Summary</h2>\n<div class=\"summary\">\n");
    out.push_str("<table class=\"counts\"><tbody>\n");
    out.push_str(&count_row("jobs", "jobs in the manifest", jobs.len()));
    out.push_str(&count_row("ok", "synthesised in this run", of(Status::Ok)));
    out.push_str(&count_row("up-to-date", "up to date (kept from an earlier run)", of(Status::UpToDate)));
    out.push_str(&count_row("failed", "failed", of(Status::Failed)));
    out.push_str(&count_row("invalid", "invalid (refused before running)", of(Status::Invalid)));
    if !r.not_run.is_empty() {
        out.push_str(&count_row("not-run", "not run (the run was stopped)", r.not_run.len()));
    }
    let synthesis: f64 = jobs.iter().filter_map(|j| j.timing.as_ref()).map(|t| t.synthesis_seconds).sum();
    out.push_str(&format!(
        "<tr><th>wall time</th><td>{}</td></tr><tr><th>synthesis time, all jobs</th><td>{}</td></tr>\
         <tr><th>threads · host</th><td>{} · {}</td></tr>\n",
        seconds(r.wall_seconds),
        seconds(synthesis),
        r.threads,
        h(&r.host)
    ));
    if r.in_progress {
        out.push_str("<tr><th>state</th><td class=\"bad\">the run was still in progress when this manifest was written</td></tr>\n");
    }
    out.push_str("</tbody></table>\n");

    // Regressions first among the lists: they are why a nightly reader opens the page.
    if let Some((source, d)) = cmp.since {
        out.push_str(&regressions(source, d));
    }
    if let Some((dir, g)) = cmp.golden {
        out.push_str(&format!(
            "<div class=\"golden\" data-golden-matched=\"{}\" data-golden-mismatched=\"{}\" data-golden-missing=\"{}\">\
             <h3>Against the golden digests in <code>{}</code></h3><p>{} outputs match, {} differ, {} have no golden digest, \
             {} jobs not checked (failed or invalid).</p>",
            g.matched,
            g.mismatched.len(),
            g.missing.len(),
            h(dir),
            g.matched,
            g.mismatched.len(),
            g.missing.len(),
            g.not_checked.len()
        ));
        list(&mut out, "golden-mismatch", g.mismatched.iter().chain(&g.missing).map(|s| h(s)));
        out.push_str("</div>\n");
    }

    let failures: Vec<_> = jobs.iter().filter(|j| !j.status.is_success()).collect();
    if failures.is_empty() {
        out.push_str("<h3>Failures</h3><p>None: every job succeeded.</p>\n");
    } else {
        out.push_str(&format!("<h3>Failures ({})</h3>\n<ol class=\"failures\">\n", failures.len()));
        for (i, j) in failures.iter().enumerate() {
            if i == FAILURES_SHOWN {
                out.push_str(&format!("</ol><details><summary>{} more</summary><ol start=\"{}\">\n", failures.len() - i, i + 1));
            }
            out.push_str(&format!(
                "<li data-job=\"{}\" data-status=\"{}\"><b>{}</b> ({}): <span class=\"error\">{}</span></li>\n",
                h(&j.id),
                j.status.name(),
                h(&j.id),
                j.status.name(),
                h(j.error.as_deref().unwrap_or("no error text recorded"))
            ));
        }
        out.push_str(if failures.len() > FAILURES_SHOWN { "</ol></details>\n" } else { "</ol>\n" });
    }

    let warned: Vec<_> = jobs.iter().filter(|j| !j.warnings.is_empty()).collect();
    if !warned.is_empty() {
        out.push_str(&format!(
            "<h3>Method advice ({} jobs)</h3>\n<details><summary>Jobs whose method and parameters may not look right on their \
             sample (<code>texsyn advise</code>); they ran</summary><ul class=\"warnings\">\n",
            warned.len()
        ));
        for j in warned {
            for w in &j.warnings {
                out.push_str(&format!("<li data-job=\"{}\"><b>{}</b>: {}</li>\n", h(&j.id), h(&j.id), h(w)));
            }
        }
        out.push_str("</ul></details>\n");
    }
    let mut timed: Vec<(&str, f64, String)> = jobs
        .iter()
        .filter_map(|j| {
            let t = j.timing.as_ref()?;
            let size = j.outputs.first().map(|o| format!("{}×{}", o.width, o.height)).unwrap_or_default();
            Some((j.id.as_str(), t.synthesis_seconds, format!("{} {size}", j.method.as_deref().unwrap_or(""))))
        })
        .collect();
    timed.sort_by(|a, b| b.1.total_cmp(&a.1).then_with(|| a.0.cmp(b.0)));
    if !timed.is_empty() {
        out.push_str(
            "<h3>Slowest jobs</h3>\n<table class=\"slowest\"><thead><tr><th>job</th><th>method, output</th><th>synthesis</th></tr></thead><tbody>\n",
        );
        for (id, s, what) in timed.iter().take(SLOWEST) {
            out.push_str(&format!(
                "<tr data-job=\"{}\"><td class=\"text\">{}</td><td class=\"text\">{}</td><td data-value=\"{}\">{}</td></tr>\n",
                h(id),
                h(id),
                h(what),
                fmt::full(*s),
                fmt::sig(*s)
            ));
        }
        out.push_str("</tbody></table>\n");
    }
    out.push_str("</div>\n</section>\n");
    out
}

fn list(out: &mut String, class: &str, items: impl Iterator<Item = String>) {
    let items: Vec<String> = items.collect();
    if items.is_empty() {
        return;
    }
    out.push_str(&format!("<ul class=\"{class}\">"));
    for i in items {
        out.push_str(&format!("<li>{i}</li>"));
    }
    out.push_str("</ul>\n");
}

fn regressions(source: &str, d: &Diff) -> String {
    let mut out = format!(
        "<div class=\"since\" data-failed-now=\"{}\" data-pixels-changed=\"{}\" data-slower=\"{}\" data-metrics-moved=\"{}\" \
         data-fixed-now=\"{}\" data-added=\"{}\" data-removed=\"{}\" data-unchanged=\"{}\"><h3>Since <code>{}</code></h3>\n<p>",
        d.failed_now.len(),
        d.pixels_changed.len(),
        d.slower.len(),
        d.metrics_moved.len(),
        d.fixed_now.len(),
        d.added.len(),
        d.removed.len(),
        d.unchanged,
        h(source)
    );
    let mut parts = vec![
        format!("<b>{} fail now</b>", d.failed_now.len()),
        format!("<a href=\"#changes\">{} changed pixels</a>", d.pixels_changed.len()),
        format!("{} slower", d.slower.len()),
        format!("{} with a metric moved", d.metrics_moved.len()),
        format!("{} fixed", d.fixed_now.len()),
        format!("{} unchanged", d.unchanged),
    ];
    if !d.added.is_empty() || !d.removed.is_empty() {
        parts.push(format!("{} added, {} removed", d.added.len(), d.removed.len()));
    }
    if !d.tool.is_empty() {
        parts.push(format!("tool changed: {}", h(&describe_changes(&d.tool))));
    }
    out.push_str(&parts.join(" · "));
    out.push_str("</p>\n");
    list(
        &mut out,
        "failed-now",
        d.failed_now.iter().map(|(id, e)| format!("<span data-job=\"{}\">FAILS NOW <b>{}</b>: {}</span>", h(id), h(id), h(e))),
    );
    list(
        &mut out,
        "pixels-changed",
        d.pixels_changed
            .iter()
            .map(|p| format!("<span data-job=\"{}\">PIXELS <b>{}</b>: {}</span>", h(&p.id), h(&p.id), h(&describe_changes(&p.because)))),
    );
    list(
        &mut out,
        "slower",
        d.slower.iter().map(|m| {
            format!(
                "<span data-job=\"{}\" data-old=\"{}\" data-new=\"{}\">SLOWER <b>{}</b>: {} s → {} s (×{:.2})</span>",
                h(&m.id),
                fmt::full(m.old),
                fmt::full(m.new),
                h(&m.id),
                fmt::sig(m.old),
                fmt::sig(m.new),
                m.new / m.old.max(1e-12)
            )
        }),
    );
    list(
        &mut out,
        "metrics-moved",
        d.metrics_moved.iter().map(|m| {
            format!(
                "<span data-job=\"{}\" data-metric=\"{}\" data-old=\"{}\" data-new=\"{}\">METRIC <b>{}</b> {}: {} → {}</span>",
                h(&m.id),
                h(&m.what),
                fmt::full(m.old),
                fmt::full(m.new),
                h(&m.id),
                h(&m.what),
                fmt::sig(m.old),
                fmt::sig(m.new)
            )
        }),
    );
    list(&mut out, "fixed-now", d.fixed_now.iter().map(|id| format!("FIXED <b>{}</b>", h(id))));
    out.push_str("</div>\n");
    out
}
