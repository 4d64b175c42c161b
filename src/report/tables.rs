//! The paper's tables: one per measure, a row per sample, a column per group, a mean row; as
//! Markdown (to read and paste) and CSV (to compute with).
//!
//! Where several jobs share a sample and a group (a seed sweep), a cell is their mean with the
//! sample standard deviation and count, so run-to-run variation is visible next to the differences
//! between methods. Undefined metric values (`null` in the manifest) are counted, never averaged in.

use super::fmt;
use super::model::{Entry, Model};

/// The measure name the synthesis time is reported under (the manifest's `timing` field).
pub const TIME: &str = "synthesis_seconds";

/// Summary of the values of one cell.
#[derive(Clone, Debug, PartialEq)]
pub struct Stat {
    pub mean: Option<f64>,
    /// Sample standard deviation (n − 1); needs two defined values.
    pub sd: Option<f64>,
    /// Defined values.
    pub n: usize,
    /// Jobs whose value is undefined (`null`: the metric has no value for that pair of images).
    pub undefined: usize,
    /// Jobs that did not record the measure at all (they did not ask for metrics).
    pub missing: usize,
}

impl Stat {
    /// In the order given (the manifest's), so results do not depend on anything else. The outer
    /// `None` is a job that did not record the measure, the inner one an undefined value.
    pub fn of(values: &[Option<Option<f64>>]) -> Stat {
        let defined: Vec<f64> = values.iter().flatten().flatten().copied().collect();
        let n = defined.len();
        let missing = values.iter().filter(|v| v.is_none()).count();
        let undefined = values.len() - n - missing;
        if n == 0 {
            return Stat { mean: None, sd: None, n, undefined, missing };
        }
        let mean = defined.iter().sum::<f64>() / n as f64;
        let sd = (n >= 2).then(|| (defined.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt());
        Stat { mean: Some(mean), sd, n, undefined, missing }
    }

    /// `0.01235 ± 0.0005600 (n=3)`; `—` when nothing is defined.
    pub fn text(&self) -> String {
        let mut s = match (self.mean, self.sd) {
            (None, _) if self.undefined == 0 => return "not recorded".into(),
            (None, _) => "—".to_string(),
            (Some(m), Some(sd)) => format!("{} ± {} (n={})", fmt::sig(m), fmt::sig(sd), self.n),
            (Some(m), None) => fmt::sig(m),
        };
        if self.undefined > 0 {
            s.push_str(&format!(" ({} undefined)", self.undefined));
        }
        if self.missing > 0 {
            s.push_str(&format!(" ({} not recorded)", self.missing));
        }
        s
    }
}

/// The bottom row: the mean over samples of each column's per-sample means.
#[derive(Clone, Debug, PartialEq)]
pub struct MeanCell {
    pub mean: Option<f64>,
    /// Samples that contributed (a defined cell).
    pub samples: usize,
}

#[derive(Clone, Debug)]
pub struct Table {
    /// A metric name or [`TIME`].
    pub measure: String,
    pub title: String,
    /// `cells[sample][group]`; `None` where no job ran for that pair.
    pub cells: Vec<Vec<Option<Stat>>>,
    pub mean: Vec<MeanCell>,
}

/// A one-line description of a measure, for table titles.
pub fn describe(measure: &str) -> String {
    match measure {
        "kl_gray" => "KL divergence of the gray-level histograms, sample ‖ output (lower is better)".into(),
        "kl_orientation" => "KL divergence of the local-orientation histograms (lower is better)".into(),
        "acf_gray" => "Euclidean distance of the gray-level autocorrelations (lower is better)".into(),
        "acf_orientation" => "Euclidean distance of the orientation autocorrelations (lower is better)".into(),
        "verbatim" => "Fraction of output pixels whose 7×7 neighbourhood occurs verbatim in the sample".into(),
        "seam_visibility" => "Seam visibility: mean colour jump at seams over elsewhere (1 = invisible)".into(),
        "repetition" => "Repetition: highest normalised gray autocorrelation at shifts of 16 px or more (lower repeats less)".into(),
        TIME => "Synthesis time in seconds (the synthesis call only)".into(),
        other => format!("{other} (as recorded)"),
    }
}

fn value(e: &Entry, measure: &str) -> Option<Option<f64>> {
    if measure == TIME { Some(e.synthesis_seconds) } else { e.metrics.get(measure).copied() }
}

/// One table per recorded metric, then the time table.
pub fn build(model: &Model) -> Vec<Table> {
    let mut measures: Vec<&str> = model.metric_names.iter().map(String::as_str).collect();
    measures.push(TIME);
    measures
        .iter()
        .enumerate()
        .map(|(i, measure)| {
            let cells: Vec<Vec<Option<Stat>>> = (0..model.samples.len())
                .map(|s| {
                    (0..model.groups.len())
                        .map(|g| {
                            let values: Vec<Option<Option<f64>>> = model.entries_of(s, g).map(|e| value(e, measure)).collect();
                            (!values.is_empty()).then(|| Stat::of(&values))
                        })
                        .collect()
                })
                .collect();
            let mean = (0..model.groups.len())
                .map(|g| {
                    let means: Vec<f64> = cells.iter().filter_map(|row| row[g].as_ref().and_then(|c| c.mean)).collect();
                    MeanCell { mean: (!means.is_empty()).then(|| means.iter().sum::<f64>() / means.len() as f64), samples: means.len() }
                })
                .collect();
            Table { measure: measure.to_string(), title: format!("Table {} — {measure}: {}", i + 1, describe(measure)), cells, mean }
        })
        .collect()
}

/// Speed-up of each group over a baseline method's matching group, for one time measure:
/// `baseline mean / group mean` per sample (above 1: faster than the baseline).
#[derive(Clone, Debug)]
pub struct Speedup {
    pub measure: String,
    pub baseline: String,
    pub title: String,
    /// `(group, baseline group)`, one per column.
    pub pairs: Vec<(usize, usize)>,
    /// `cells[sample][pair]`; `None` where either side has no time for that sample.
    pub cells: Vec<Vec<Option<f64>>>,
    /// Mean over the samples with a ratio (and how many).
    pub mean: Vec<(Option<f64>, usize)>,
}

/// Whether a measure is a time (the synthesis time or a named phase).
pub fn is_time(measure: &str) -> bool {
    measure == TIME || (measure.starts_with("time.") && measure.ends_with("_seconds"))
}

/// The baseline group a group is compared with: the one baseline group whose values agree with
/// the group's on every grouping key both have (paper 000's `rows`/`cols`, paper 003's `block`).
/// `None` when no or several baseline groups agree (the pairing would be a guess).
fn baseline_group(model: &Model, g: usize, baseline: &str) -> Option<usize> {
    let group = &model.groups[g];
    let matches: Vec<usize> = (0..model.groups.len())
        .filter(|&b| model.groups[b].method.as_deref() == Some(baseline))
        .filter(|&b| model.groups[b].key.iter().all(|(name, value)| group.key.iter().all(|(n, v)| n != name || v == value)))
        .collect();
    (matches.len() == 1).then(|| matches[0])
}

/// One speed-up table per time measure with at least one defined ratio.
pub fn speedups(model: &Model, tables: &[Table], baseline: &str) -> Vec<Speedup> {
    let pairs: Vec<(usize, usize)> = (0..model.groups.len())
        .filter(|&g| model.groups[g].method.as_deref() != Some(baseline))
        .filter_map(|g| baseline_group(model, g, baseline).map(|b| (g, b)))
        .collect();
    tables
        .iter()
        .filter(|t| is_time(&t.measure))
        .filter_map(|t| {
            let cells: Vec<Vec<Option<f64>>> = t
                .cells
                .iter()
                .map(|row| {
                    pairs
                        .iter()
                        .map(|&(g, b)| match (row[g].as_ref().and_then(|c| c.mean), row[b].as_ref().and_then(|c| c.mean)) {
                            (Some(x), Some(base)) if x > 0.0 => Some(base / x),
                            _ => None,
                        })
                        .collect()
                })
                .collect();
            let mean: Vec<(Option<f64>, usize)> = (0..pairs.len())
                .map(|i| {
                    let v: Vec<f64> = cells.iter().filter_map(|row| row[i]).collect();
                    ((!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64), v.len())
                })
                .collect();
            mean.iter().any(|m| m.0.is_some()).then(|| Speedup {
                measure: t.measure.clone(),
                baseline: baseline.to_string(),
                title: format!(
                    "Speed-up over {shown} — {}: {shown}'s mean time / the column's (above 1: faster)",
                    t.measure,
                    shown = super::model::method_label(baseline)
                ),
                pairs: pairs.clone(),
                cells,
                mean,
            })
        })
        .collect()
}

/// The speed-up tables as Markdown, to append to the report's tables.
pub fn speedup_markdown(model: &Model, speedups: &[Speedup]) -> String {
    let esc = |s: &str| s.replace('|', "\\|");
    let mut out = String::new();
    for t in speedups {
        out.push_str(&format!("## {}\n\n", t.title));
        let mut header = vec!["sample".to_string()];
        header.extend(t.pairs.iter().map(|&(g, b)| format!("{} (vs {})", esc(&model.groups[g].label), esc(&model.groups[b].label))));
        out.push_str(&format!("| {} |\n|{}\n", header.join(" | "), "---|".repeat(header.len())));
        for (s, row) in t.cells.iter().enumerate() {
            let mut cols = vec![esc(&model.samples[s].key)];
            cols.extend(row.iter().map(|c| c.map_or("—".into(), |r| format!("{}×", fmt::sig(r)))));
            out.push_str(&format!("| {} |\n", cols.join(" | ")));
        }
        let mut cols = vec!["**mean**".to_string()];
        cols.extend(t.mean.iter().map(|(m, n)| match m {
            None => "—".into(),
            Some(m) if *n == model.samples.len() => format!("**{}×**", fmt::sig(*m)),
            Some(m) => format!("**{}×** ({n}/{} samples)", fmt::sig(*m), model.samples.len()),
        }));
        out.push_str(&format!("| {} |\n\n", cols.join(" | ")));
    }
    out
}

/// A speed-up table as CSV: `sample`, then one exact ratio column per pair; a mean row last.
pub fn speedup_csv(model: &Model, t: &Speedup) -> String {
    let mut header = vec!["sample".to_string()];
    header.extend(t.pairs.iter().map(|&(g, b)| fmt::csv(&format!("{} vs {}", model.groups[g].label, model.groups[b].label))));
    let mut out = header.join(",") + "\n";
    for (s, row) in t.cells.iter().enumerate() {
        let mut cols = vec![fmt::csv(&model.samples[s].key)];
        cols.extend(row.iter().map(|c| opt(*c)));
        out.push_str(&(cols.join(",") + "\n"));
    }
    let mut cols = vec!["mean".to_string()];
    cols.extend(t.mean.iter().map(|(m, _)| opt(*m)));
    out.push_str(&(cols.join(",") + "\n"));
    out
}

fn sizes_of_outputs(model: &Model, sample: usize) -> String {
    let mut sizes: Vec<(u64, String)> = model
        .entries
        .iter()
        .filter(|e| e.sample == sample)
        .filter_map(|e| e.output.as_ref().map(|o| (o.width as u64 * o.height as u64, format!("{}×{}", o.width, o.height))))
        .collect();
    sizes.sort();
    sizes.dedup();
    sizes.into_iter().map(|(_, s)| s).collect::<Vec<_>>().join(", ")
}

impl MeanCell {
    pub fn text(&self, of: usize) -> String {
        match self.mean {
            None => "—".into(),
            Some(m) if self.samples == of => fmt::sig(m),
            Some(m) => format!("{} ({}/{of} samples)", fmt::sig(m), self.samples),
        }
    }
}

/// All tables as one Markdown document.
pub fn markdown(model: &Model, tables: &[Table], source: &str) -> String {
    let mut out = format!(
        "# texsyn report\n\nFrom `{source}`; columns: {}. Cells: mean ± sample standard deviation (n) over the jobs \
         sharing a sample and a column.\n\n",
        model.grouping
    );
    let esc = |s: &str| s.replace('|', "\\|");
    for t in tables {
        out.push_str(&format!("## {}\n\n", t.title));
        let time = t.measure == TIME;
        let mut header = vec!["sample".to_string()];
        if time {
            header.extend(["sample size".to_string(), "output size".to_string()]);
        }
        header.extend(model.groups.iter().map(|g| esc(&g.label)));
        out.push_str(&format!("| {} |\n|{}\n", header.join(" | "), "---|".repeat(header.len())));
        for (s, row) in t.cells.iter().enumerate() {
            let info = &model.samples[s];
            let mut cols = vec![esc(&info.key)];
            if time {
                cols.push(format!("{}×{}", info.width, info.height));
                cols.push(sizes_of_outputs(model, s));
            }
            cols.extend(row.iter().map(|c| c.as_ref().map_or("not run".into(), Stat::text)));
            out.push_str(&format!("| {} |\n", cols.join(" | ")));
        }
        let mut cols = vec!["**mean**".to_string()];
        if time {
            cols.extend([String::new(), String::new()]);
        }
        cols.extend(t.mean.iter().map(|m| format!("**{}**", m.text(model.samples.len()))));
        out.push_str(&format!("| {} |\n\n", cols.join(" | ")));
    }
    if !model.excluded.is_empty() {
        out.push_str("## Jobs not counted\n\n| job | status | reason |\n|---|---|---|\n");
        for x in &model.excluded {
            out.push_str(&format!("| {} | {} | {} |\n", esc(&x.job_id), x.status, esc(&x.reason.replace('\n', " "))));
        }
        out.push('\n');
    }
    out
}

fn opt(x: Option<f64>) -> String {
    x.map(fmt::full).unwrap_or_default()
}

fn stat_fields(c: &Option<Stat>) -> [String; 5] {
    match c {
        None => Default::default(),
        Some(s) => [opt(s.mean), opt(s.sd), s.n.to_string(), s.undefined.to_string(), s.missing.to_string()],
    }
}

/// The columns each group gets in the CSV files.
const STAT_FIELDS: [&str; 5] = ["mean", "sd", "n", "undefined", "not_recorded"];

/// One measure's table as CSV: `sample`, then `mean`, `sd`, `n`, `undefined`, `not_recorded` per
/// group; the last row is the mean row (`n` there counts samples). Numbers are exact.
pub fn csv(model: &Model, t: &Table) -> String {
    let mut header = vec!["sample".to_string()];
    let time = t.measure == TIME;
    if time {
        header.extend(["sample_size".into(), "output_size".into()]);
    }
    for g in &model.groups {
        for f in STAT_FIELDS {
            header.push(fmt::csv(&format!("{}:{f}", g.label)));
        }
    }
    let mut out = header.join(",") + "\n";
    for (s, row) in t.cells.iter().enumerate() {
        let info = &model.samples[s];
        let mut cols = vec![fmt::csv(&info.key)];
        if time {
            cols.push(format!("{}x{}", info.width, info.height));
            cols.push(fmt::csv(&sizes_of_outputs(model, s).replace('×', "x")));
        }
        for c in row {
            cols.extend(stat_fields(c).iter().map(|f| fmt::csv(f)));
        }
        out.push_str(&(cols.join(",") + "\n"));
    }
    let mut cols = vec!["mean".to_string()];
    if time {
        cols.extend([String::new(), String::new()]);
    }
    for m in &t.mean {
        cols.extend([opt(m.mean), String::new(), m.samples.to_string(), String::new(), String::new()]);
    }
    out.push_str(&(cols.join(",") + "\n"));
    out
}

/// Every table side by side: one row per sample, one column block per (measure, group).
pub fn csv_all(model: &Model, tables: &[Table]) -> String {
    let mut header = vec!["sample".to_string()];
    for t in tables {
        for g in &model.groups {
            for f in STAT_FIELDS {
                header.push(fmt::csv(&format!("{}:{}:{f}", t.measure, g.label)));
            }
        }
    }
    let mut out = header.join(",") + "\n";
    for (s, info) in model.samples.iter().enumerate() {
        let mut cols = vec![fmt::csv(&info.key)];
        for t in tables {
            for c in &t.cells[s] {
                cols.extend(stat_fields(c).iter().map(|f| fmt::csv(f)));
            }
        }
        out.push_str(&(cols.join(",") + "\n"));
    }
    let mut cols = vec!["mean".to_string()];
    for t in tables {
        for m in &t.mean {
            cols.extend([opt(m.mean), String::new(), m.samples.to_string(), String::new(), String::new()]);
        }
    }
    out.push_str(&(cols.join(",") + "\n"));
    out
}

/// The per-job values the tables summarise, one row per counted job.
pub fn jobs_csv(model: &Model) -> String {
    let mut header: Vec<String> = ["job", "sample", "group", "seed", "output", "output_pixels"].map(String::from).to_vec();
    header.extend(model.metric_names.iter().cloned());
    header.push(TIME.into());
    let mut out = header.iter().map(|h| fmt::csv(h)).collect::<Vec<_>>().join(",") + "\n";
    for e in &model.entries {
        let mut cols = vec![
            fmt::csv(&e.job_id),
            fmt::csv(&model.samples[e.sample].key),
            fmt::csv(&model.groups[e.group].label),
            e.seed.map(|s| s.to_string()).unwrap_or_default(),
            fmt::csv(e.output.as_ref().map_or("", |o| o.recorded_path.as_str())),
            e.output.as_ref().map(|o| (o.width as u64 * o.height as u64).to_string()).unwrap_or_default(),
        ];
        cols.extend(model.metric_names.iter().map(|m| opt(e.metrics.get(m).copied().flatten())));
        cols.push(opt(e.synthesis_seconds));
        out.push_str(&(cols.join(",") + "\n"));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stat_is_mean_sample_sd_and_count_of_defined_values() {
        let s = Stat::of(&[Some(Some(1.0)), Some(None), Some(Some(2.0)), None, Some(Some(3.0))]);
        assert_eq!(s.mean, Some(2.0));
        assert_eq!(s.sd, Some(1.0));
        assert_eq!((s.n, s.undefined, s.missing), (3, 1, 1));
        assert_eq!(s.text(), "2.000 ± 1.000 (n=3) (1 undefined) (1 not recorded)");
        let one = Stat::of(&[Some(Some(0.25))]);
        assert_eq!((one.mean, one.sd), (Some(0.25), None));
        assert_eq!(one.text(), "0.2500");
        let none = Stat::of(&[Some(None), Some(None)]);
        assert_eq!(none.mean, None);
        assert_eq!(none.text(), "— (2 undefined)");
        assert_eq!(Stat::of(&[None, None]).text(), "not recorded");
    }
}
