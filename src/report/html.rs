//! The report page: one static `index.html` that shows the tables, plot and images and keeps the
//! provenance one click away, readable offline and from any copy of the report directory.
//!
//! It references only files written beside it (no network, no CDN). Every number carries its
//! exact value in `data-*` attributes, and a small script records on `<body>` whether every image
//! decoded, so a headless browser can check the page as a reader would see it.

use super::fmt::{self, html as h};
use super::model::Model;
use super::tables::{Stat, TIME, Table};
use crate::batch::manifest::Manifest;

/// Where an image of the report lives (relative to the page), or why it could not be shown.
pub type ImageRef = Result<(String, u32, u32), String>;

/// One group's output shown for a sample.
pub struct Shown {
    pub group: usize,
    /// The entry (job) whose output is shown.
    pub entry: usize,
    pub image: ImageRef,
    /// The job's companion maps (label, image), shown beside its output.
    pub companions: Vec<(String, ImageRef)>,
    /// What the job followed besides the sample (what it is, its recorded path, image): masks
    /// and guides, shown before its output.
    pub inputs: Vec<(String, String, ImageRef)>,
}

/// Everything the page links to, already written or about to be.
pub struct Assets {
    pub samples: Vec<ImageRef>,
    /// Per sample, the shown output of each group that ran on it.
    pub shown: Vec<Vec<Shown>>,
    pub sheets: Vec<String>,
    /// The overview's pages: every counted job's output as a thumbnail.
    pub overview: Vec<String>,
    /// Prefix of this section's element ids (empty when the report has one section).
    pub anchor: String,
    pub plot: String,
    /// Width and height of the plot in CSS pixels.
    pub plot_size: (f64, f64),
    pub markdown: String,
    pub csvs: Vec<(String, String)>,
    pub csv_all: String,
    pub jobs_csv: String,
}

const STYLE: &str = "
body{font-family:'DejaVu Sans',Verdana,sans-serif;margin:1.5em 2em;color:#222;line-height:1.4}
h1{margin-bottom:0.2em}
code{font-size:0.9em}
table{border-collapse:collapse;margin:0.4em 0 1.4em}
th,td{border:1px solid #ccc;padding:3px 8px;text-align:right;font-variant-numeric:tabular-nums;vertical-align:top}
th{background:#f3f3f3}
th:first-child,td:first-child,td.text{text-align:left}
tr.mean td{font-weight:bold;border-top:2px solid #777}
.sd{color:#666;font-size:0.85em}
figure{display:inline-block;vertical-align:top;margin:0 14px 14px 0}
figcaption{font-size:0.85em;color:#444;max-width:420px;overflow-wrap:anywhere}
figcaption b{color:#111}
.missing{display:inline-block;background:#ddd;color:#900;padding:8px;box-sizing:border-box;max-width:420px}
img.sheet{max-width:100%;height:auto;border:1px solid #ddd}
details{margin:0.6em 0 1.2em}
summary{cursor:pointer}
.problems{background:#fff3f3;border:1px solid #e99;padding:0.5em 1em}
.digest{font-family:monospace;font-size:0.85em;overflow-wrap:anywhere}
.summary table.counts td{text-align:right}
.error{font-family:monospace;font-size:0.9em;white-space:pre-wrap}
.since,.golden{background:#fffbe8;border:1px solid #e8d9a0;padding:0.3em 1em;margin:0.6em 0}
.change{border-top:1px solid #ccc;margin-top:0.8em}
.why{font-size:0.9em;color:#444}
h2.part{border-bottom:2px solid #999;margin-top:2em}
.bad{color:#900}
.warning{color:#8a4b00}
";

const SCRIPT: &str = "
window.addEventListener('load', function () {
  var imgs = Array.prototype.slice.call(document.images);
  var ok = imgs.filter(function (i) { return i.complete && i.naturalWidth > 0; });
  var bad = imgs.filter(function (i) { return !(i.complete && i.naturalWidth > 0); });
  document.body.setAttribute('data-images-ok', ok.length + '/' + imgs.length);
  document.body.setAttribute('data-images-failed', bad.map(function (i) { return i.getAttribute('src'); }).join(' '));
});
";

fn img(r: &ImageRef, alt: &str) -> String {
    match r {
        Ok((src, w, hgt)) => format!("<img src=\"{}\" width=\"{w}\" height=\"{hgt}\" alt=\"{}\">", h(src), h(alt)),
        Err(why) => format!("<span class=\"missing\">image unavailable: {}</span>", h(why)),
    }
}

fn opt_attr(name: &str, v: Option<f64>) -> String {
    v.map(|x| format!(" {name}=\"{}\"", fmt::full(x))).unwrap_or_default()
}

fn stat_cell(model: &Model, t: &Table, s: usize, g: usize, c: &Option<Stat>) -> String {
    let common = format!(
        "data-metric=\"{}\" data-sample=\"{}\" data-group=\"{}\"",
        h(&t.measure),
        h(&model.samples[s].key),
        h(&model.groups[g].label)
    );
    match c {
        None => format!("<td {common} data-n=\"0\">not run</td>"),
        Some(st) => {
            let shown = match (st.mean, st.sd) {
                (None, _) if st.undefined == 0 => "not recorded".to_string(),
                (None, _) => "—".to_string(),
                (Some(m), Some(sd)) => format!("{} <span class=\"sd\">± {} (n={})</span>", fmt::sig(m), fmt::sig(sd), st.n),
                (Some(m), None) => fmt::sig(m),
            };
            let mut notes = String::new();
            if st.undefined > 0 {
                notes.push_str(&format!(" <span class=\"sd\">({} undefined)</span>", st.undefined));
            }
            if st.missing > 0 && st.n + st.undefined > 0 {
                notes.push_str(&format!(" <span class=\"sd\">({} not recorded)</span>", st.missing));
            }
            format!(
                "<td {common}{}{} data-n=\"{}\" data-undefined=\"{}\" data-not-recorded=\"{}\">{shown}{notes}</td>",
                opt_attr("data-value", st.mean),
                opt_attr("data-sd", st.sd),
                st.n,
                st.undefined,
                st.missing
            )
        }
    }
}

fn tables_html(model: &Model, tables: &[Table], assets: &Assets) -> String {
    let a = &assets.anchor;
    let mut out = format!("<section id=\"{a}tables\">\n<h2>Tables</h2>\n");
    out.push_str(&format!(
        "<p>One row per sample; columns: <code>{}</code>. A cell is the mean over the jobs that share its sample and \
         column, with the sample standard deviation and the count where there are several (a seed sweep). The mean row \
         averages the per-sample means. Also as <a href=\"{}\">Markdown</a>, <a href=\"{}\">one CSV</a> and \
         <a href=\"{}\">per-job CSV</a>.</p>\n",
        h(&model.grouping),
        h(&assets.markdown),
        h(&assets.csv_all),
        h(&assets.jobs_csv)
    ));
    for t in tables {
        let csv = assets.csvs.iter().find(|(m, _)| *m == t.measure).map(|(_, p)| p.as_str()).unwrap_or("");
        out.push_str(&format!("<h3>{} <small>(<a href=\"{}\">CSV</a>)</small></h3>\n", h(&t.title), h(csv)));
        let time = t.measure == TIME;
        out.push_str(&format!("<table class=\"measure\" data-measure=\"{}\">\n<thead><tr><th>sample</th>", h(&t.measure)));
        if time {
            out.push_str("<th>sample size</th><th>output size</th>");
        }
        for g in &model.groups {
            out.push_str(&format!("<th data-group=\"{}\">{}</th>", h(&g.label), h(&g.label)));
        }
        out.push_str("</tr></thead>\n<tbody>\n");
        for (s, row) in t.cells.iter().enumerate() {
            let info = &model.samples[s];
            out.push_str(&format!("<tr data-sample=\"{}\"><td><a href=\"#{a}sample-{s}\">{}</a></td>", h(&info.key), h(&info.key)));
            if time {
                let mut sizes: Vec<(u64, String)> = model
                    .entries
                    .iter()
                    .filter(|e| e.sample == s)
                    .filter_map(|e| e.output.as_ref().map(|o| (o.width as u64 * o.height as u64, format!("{}×{}", o.width, o.height))))
                    .collect();
                sizes.sort();
                sizes.dedup();
                let sizes: Vec<String> = sizes.into_iter().map(|x| x.1).collect();
                out.push_str(&format!("<td>{}×{}</td><td>{}</td>", info.width, info.height, h(&sizes.join(", "))));
            }
            for (g, c) in row.iter().enumerate() {
                out.push_str(&stat_cell(model, t, s, g, c));
            }
            out.push_str("</tr>\n");
        }
        out.push_str("<tr class=\"mean\"><td>mean</td>");
        if time {
            out.push_str("<td></td><td></td>");
        }
        for (g, m) in t.mean.iter().enumerate() {
            out.push_str(&format!(
                "<td data-metric=\"{}\" data-group=\"{}\" data-row=\"mean\"{} data-samples=\"{}\">{}</td>",
                h(&t.measure),
                h(&model.groups[g].label),
                opt_attr("data-value", m.mean),
                m.samples,
                h(&m.text(model.samples.len()))
            ));
        }
        out.push_str("</tr>\n</tbody></table>\n");
    }
    out.push_str("</section>\n");
    out
}

fn images_html(model: &Model, assets: &Assets) -> String {
    let a = &assets.anchor;
    let mut out = format!("<section id=\"{a}images\">\n<h2>Images</h2>\n");
    out.push_str("<p>Each sample, then the output of each column at the same scale (the first seed where a column ran several; every seed is on the overview).</p>\n");
    let pages = assets.overview.len();
    for (i, o) in assets.overview.iter().enumerate() {
        out.push_str(&format!(
            "<details{}><summary>Overview, every job{} (<a href=\"{}\">PNG</a>)</summary><img class=\"sheet\" data-role=\"overview\" src=\"{}\" alt=\"overview page {}\"></details>\n",
            if i == 0 { " open" } else { "" },
            if pages > 1 { format!(", page {} of {pages}", i + 1) } else { String::new() },
            h(o),
            h(o),
            i + 1
        ));
    }
    for (s, info) in model.samples.iter().enumerate() {
        out.push_str(&format!("<h3 id=\"{a}sample-{s}\" data-sample=\"{}\">{}</h3>\n<div class=\"row\">", h(&info.key), h(&info.key)));
        out.push_str(&format!(
            "<figure data-role=\"sample\">{}<figcaption><b>sample {}</b><br>{}×{} · <code>{}</code></figcaption></figure>",
            img(&assets.samples[s], &format!("sample {}", info.key)),
            h(&info.key),
            info.width,
            info.height,
            h(&info.recorded_path)
        ));
        for shown in &assets.shown[s] {
            let e = &model.entries[shown.entry];
            let g = &model.groups[shown.group];
            let n = model.entries_of(s, shown.group).count();
            let size = e.output.as_ref().map(|o| format!("{}×{}", o.width, o.height)).unwrap_or_default();
            for (what, path, image) in &shown.inputs {
                out.push_str(&format!(
                    "<figure data-role=\"input\" data-job=\"{}\">{}<figcaption><b>{}</b> of {}<br><code>{}</code></figcaption></figure>",
                    h(&e.job_id),
                    img(image, &format!("{what} of {}", e.job_id)),
                    h(what),
                    h(&g.label),
                    h(path)
                ));
            }
            out.push_str(&format!(
                "<figure data-group=\"{}\" data-job=\"{}\">{}<figcaption><b>{}</b><br>{}<br>{}{} · {}{}</figcaption></figure>",
                h(&g.label),
                h(&e.job_id),
                img(&shown.image, &format!("{} on {}", g.label, info.key)),
                h(&g.label),
                h(&g.params_label),
                e.seed.map(|x| format!("seed {x}")).unwrap_or_default(),
                if n > 1 { format!(" (1 of {n} jobs)") } else { String::new() },
                size,
                e.warnings.iter().map(|w| format!("<br><span class=\"warning\" data-warning=\"1\">⚠ {}</span>", h(w))).collect::<String>()
            ));
            for (label, image) in &shown.companions {
                out.push_str(&format!(
                    "<figure data-role=\"companion\" data-job=\"{}\">{}<figcaption>companion of {}<br><code>{}</code></figcaption></figure>",
                    h(&e.job_id),
                    img(image, &format!("{label} of {}", e.job_id)),
                    h(&g.label),
                    h(label)
                ));
            }
        }
        out.push_str("</div>\n");
        if let Some(sheet) = assets.sheets.get(s) {
            out.push_str(&format!(
                "<details><summary>Contact sheet (<a href=\"{}\">PNG</a>)</summary><img class=\"sheet\" src=\"{}\" alt=\"contact sheet {}\"></details>\n",
                h(sheet),
                h(sheet),
                h(&info.key)
            ));
        }
    }
    out.push_str("</section>\n");
    out
}

fn jobs_html(model: &Model, a: &str) -> String {
    let mut out = format!(
        "<section id=\"{a}jobs\">\n<h2>Per-job values</h2>\n<details><summary>{} counted jobs: every metric and the time of each</summary>\n<table class=\"jobs\"><thead><tr><th>job</th><th>sample</th><th>column</th><th>seed</th>",
        model.entries.len()
    );
    for m in &model.metric_names {
        out.push_str(&format!("<th>{}</th>", h(m)));
    }
    out.push_str(&format!("<th>{TIME}</th></tr></thead>\n<tbody>\n"));
    for e in &model.entries {
        out.push_str(&format!(
            "<tr data-job=\"{}\"><td class=\"text\">{}</td><td class=\"text\">{}</td><td class=\"text\">{}</td><td>{}</td>",
            h(&e.job_id),
            h(&e.job_id),
            h(&model.samples[e.sample].key),
            h(&model.groups[e.group].label),
            e.seed.map(|s| s.to_string()).unwrap_or_default()
        ));
        let cell = |name: &str, v: Option<Option<f64>>| match v {
            Some(Some(x)) => format!(
                "<td data-job=\"{}\" data-metric=\"{}\" data-value=\"{}\">{}</td>",
                h(&e.job_id),
                h(name),
                fmt::full(x),
                fmt::sig(x)
            ),
            Some(None) => format!("<td data-job=\"{}\" data-metric=\"{}\" data-undefined=\"1\">undefined</td>", h(&e.job_id), h(name)),
            None => format!("<td data-job=\"{}\" data-metric=\"{}\" data-absent=\"1\">—</td>", h(&e.job_id), h(name)),
        };
        for m in &model.metric_names {
            out.push_str(&cell(m, e.metrics.get(m).copied()));
        }
        out.push_str(&cell(TIME, e.synthesis_seconds.map(Some)));
        out.push_str("</tr>\n");
    }
    out.push_str("</tbody></table>\n</details>\n</section>\n");
    out
}

fn excluded_html(model: &Model, a: &str) -> String {
    if model.excluded.is_empty() {
        return String::new();
    }
    let mut out = format!(
        "<section id=\"{a}excluded\">\n<h2>Jobs not counted ({})</h2>\n<p>Only jobs with status ok or up-to-date enter the tables.</p>\n\
         <table><thead><tr><th>job</th><th>status</th><th>reason</th></tr></thead><tbody>\n",
        model.excluded.len()
    );
    for x in &model.excluded {
        out.push_str(&format!(
            "<tr data-job=\"{}\" data-status=\"{}\"><td>{}</td><td class=\"text\">{}</td><td class=\"text\">{}</td></tr>\n",
            h(&x.job_id),
            h(&x.status),
            h(&x.job_id),
            h(&x.status),
            h(&x.reason)
        ));
    }
    out.push_str("</tbody></table>\n</section>\n");
    out
}

fn provenance_html(manifest: &Manifest, digest_ok: bool) -> String {
    let r = &manifest.run;
    let mut out = format!(
        "<section id=\"provenance\">\n<h2>Provenance</h2>\n<details data-role=\"provenance\"><summary>{} {} (commit <code>{}</code>), \
         {} jobs, deterministic digest <code>{}</code></summary>\n<table class=\"facts\"><tbody>\n",
        h(&manifest.tool.name),
        h(&manifest.tool.version),
        h(&manifest.tool.commit.chars().take(12).collect::<String>()),
        manifest.jobs.len(),
        h(&manifest.deterministic_digest.sha256.chars().take(16).collect::<String>())
    );
    let mut row = |k: &str, v: String| out.push_str(&format!("<tr><th>{}</th><td class=\"text\">{v}</td></tr>\n", h(k)));
    row("tool", format!("{} {}", h(&manifest.tool.name), h(&manifest.tool.version)));
    row("commit", format!("<span class=\"digest\" data-commit=\"{0}\">{0}</span>", h(&manifest.tool.commit)));
    row("manifest format", h(&manifest.format));
    row(
        "deterministic digest",
        format!(
            "<span class=\"digest\" data-digest=\"{0}\">sha256 {0}</span> — {1}",
            h(&manifest.deterministic_digest.sha256),
            if digest_ok {
                "recomputed from the manifest: matches"
            } else {
                "recomputed from the manifest: DOES NOT MATCH (the manifest was edited after the run)"
            }
        ),
    );
    row("host", h(&r.host));
    row("command", format!("<code>{}</code>", h(&r.argv.join(" "))));
    row("threads", r.threads.to_string());
    row("started / finished (Unix s)", format!("{} / {}", r.started_at, r.finished_at));
    row("wall time (s)", fmt::sig(r.wall_seconds));
    row("jobs ran / up to date / failed / invalid", format!("{} / {} / {} / {}", r.ran, r.up_to_date, r.failed, r.invalid));
    out.push_str(
        "</tbody></table>\n<table class=\"provenance\"><thead><tr><th>job</th><th>status</th><th>method</th><th>params</th>\
        <th>seed</th><th>sample</th><th>sample pixels sha256</th><th>output</th><th>output pixels sha256</th><th>output file sha256</th>\
        <th>content key</th></tr></thead><tbody>\n",
    );
    for j in &manifest.jobs {
        let sample = j.sample.as_ref();
        let output = j.outputs.first();
        out.push_str(&format!(
            "<tr data-job=\"{}\"><td class=\"text\">{}</td><td class=\"text\">{}</td><td class=\"text\">{}</td><td class=\"text\"><code>{}</code></td>\
             <td data-seed=\"{}\">{}</td><td class=\"text\">{}</td><td class=\"digest\">{}</td><td class=\"text\">{}</td>\
             <td class=\"digest\" data-pixel-digest=\"{}\">{}</td><td class=\"digest\">{}</td><td class=\"digest\">{}</td></tr>\n",
            h(&j.id),
            h(&j.id),
            j.status.name(),
            h(j.method.as_deref().unwrap_or("")),
            h(&j.params.as_ref().map(|p| p.to_string()).unwrap_or_default()),
            j.seed.map(|s| s.to_string()).unwrap_or_default(),
            j.seed.map(|s| s.to_string()).unwrap_or_default(),
            h(sample.map_or("", |s| s.path.as_str())),
            h(sample.map_or("", |s| s.pixel_digest.sha256.as_str())),
            h(&output.map(|o| format!("{} ({} {}-bit, {}×{})", o.path, o.format, o.bit_depth, o.width, o.height)).unwrap_or_default()),
            h(output.map_or("", |o| o.pixel_digest.sha256.as_str())),
            h(output.map_or("", |o| o.pixel_digest.sha256.as_str())),
            h(output.map_or("", |o| o.file_digest.sha256.as_str())),
            h(j.content_key.as_ref().map_or("", |d| d.sha256.as_str())),
        ));
    }
    out.push_str("</tbody></table>\n</details>\n</section>\n");
    out
}

/// One section of the page: a job directory's tables, plot and images.
pub struct Part<'a> {
    /// The section's name, shown as a heading when the report has several.
    pub title: Option<String>,
    pub model: &'a Model,
    pub tables: &'a [Table],
    pub assets: &'a Assets,
}

fn part_html(p: &Part) -> String {
    let (model, assets, a) = (p.model, p.assets, &p.assets.anchor);
    let mut out = String::new();
    if let Some(t) = &p.title {
        out.push_str(&format!(
            "<section class=\"part\" id=\"{}\" data-section=\"{}\">\n<h2 class=\"part\">Section {}</h2>\n<p>{} jobs counted, {} not counted; \
             columns: <code>{}</code>. Tables as <a href=\"{}\">Markdown</a> and <a href=\"{}\">CSV</a>.</p>\n",
            h(a.trim_end_matches('-')),
            h(t),
            h(t),
            model.entries.len(),
            model.excluded.len(),
            h(&model.grouping),
            h(&assets.markdown),
            h(&assets.csv_all)
        ));
    } else {
        out.push_str("<section class=\"part\" data-section=\"\">\n");
    }
    if model.metric_names.is_empty() && !model.entries.is_empty() {
        out.push_str(
            "<p>No job here recorded metrics (a job file asks for them with <code>metrics = true</code>); only the time table is shown.</p>\n",
        );
    }
    out.push_str(&excluded_html(model, a));
    if !model.entries.is_empty() {
        out.push_str(&tables_html(model, p.tables, assets));
        out.push_str(&format!(
            "<section id=\"{a}plots\">\n<h2>Plots</h2>\n<figure><img src=\"{0}\" width=\"{1}\" height=\"{2}\" alt=\"synthesis time vs output size\">\
             <figcaption>Synthesis time against output size (pixels), one colour per column; lines join each column's mean time per size. \
             (<a href=\"{0}\">SVG</a>)</figcaption></figure>\n</section>\n",
            h(&assets.plot),
            assets.plot_size.0,
            assets.plot_size.1
        ));
        out.push_str(&images_html(model, assets));
        out.push_str(&jobs_html(model, a));
    }
    out.push_str("</section>\n");
    out
}

/// The whole page: summary, changes, then each section, then the provenance.
#[allow(clippy::too_many_arguments)]
pub fn page(
    parts: &[Part],
    manifest: &Manifest,
    source: &str,
    digest_ok: bool,
    problems: &[String],
    summary: &str,
    changes: &str,
) -> String {
    let counted: usize = parts.iter().map(|p| p.model.entries.len()).sum();
    let excluded: usize = parts.iter().map(|p| p.model.excluded.len()).sum();
    let mut out = format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n\
         <title>texsyn report: {}</title>\n<style>{STYLE}</style>\n</head>\n<body data-images-ok=\"pending\" data-jobs-counted=\"{counted}\" \
         data-jobs-excluded=\"{excluded}\" data-sections=\"{}\">\n<h1>texsyn report</h1>\n<p>Manifest <code>{}</code> — {counted} jobs counted \
         (ok or up-to-date), {excluded} not counted. Written by {} {} (commit <code>{}</code>); details under <a href=\"#provenance\">Provenance</a>.</p>\n",
        h(source),
        parts.len(),
        h(source),
        h(&manifest.tool.name),
        h(&manifest.tool.version),
        h(&manifest.tool.commit.chars().take(12).collect::<String>())
    );
    if !problems.is_empty() {
        out.push_str("<div class=\"problems\" id=\"problems\"><b>Problems while building this report:</b><ul>");
        for p in problems {
            out.push_str(&format!("<li>{}</li>", h(p)));
        }
        out.push_str("</ul></div>\n");
    }
    out.push_str(summary);
    out.push_str(changes);
    if parts.len() > 1 {
        out.push_str("<nav id=\"sections\"><h2>Sections</h2><ul>");
        for p in parts {
            out.push_str(&format!(
                "<li><a href=\"#{}\">{}</a> — {} jobs{}</li>",
                h(p.assets.anchor.trim_end_matches('-')),
                h(p.title.as_deref().unwrap_or("")),
                p.model.entries.len(),
                if p.model.excluded.is_empty() { String::new() } else { format!(", {} not counted", p.model.excluded.len()) }
            ));
        }
        out.push_str("</ul></nav>\n");
    }
    for p in parts {
        out.push_str(&part_html(p));
    }
    out.push_str(&provenance_html(manifest, digest_ok));
    out.push_str(&format!("<script>{SCRIPT}</script>\n</body>\n</html>\n"));
    out
}
