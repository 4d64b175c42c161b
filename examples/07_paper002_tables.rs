//! Paper 002's Table 2 and Figure 4 from a manifest of `jobs/papers/002` (the same numbers
//! `texsyn report` is meant to show; this reads only the manifest, so it works without it).
//!
//! ```sh
//! texsyn run jobs/papers/002 -o out/002 -j 1      # -j 1: clean timings for Figure 4
//! cargo run --release --example 07_paper002_tables -- out/002/manifest.json
//! ```
//!
//! - **Table 2**: every patch-sampling job with `record_optimum = true` and a single searched block
//!   is one run; runs are grouped by job file and search. Success = `error ≤ 1.03 × optimum`;
//!   "mean iterations" = the iteration at which the final best was first reached, averaged over the
//!   successful runs (docs/methods.md §4.8).
//! - **Figure 4**: synthesis time per job file, search (and engine) and particle count.
//! - **Figures 3/5**: the quality metrics of the same jobs, when they were recorded (`metrics = true`).

use serde_json::Value;
use std::collections::BTreeMap;

fn main() {
    let path = std::env::args().nth(1).unwrap_or_else(|| {
        eprintln!("usage: paper002_tables <manifest.json>");
        std::process::exit(2);
    });
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| {
        eprintln!("{path}: {e}");
        std::process::exit(2);
    });
    let manifest: Value = serde_json::from_str(&text).unwrap_or_else(|e| {
        eprintln!("{path}: not JSON: {e}");
        std::process::exit(2);
    });
    let jobs: Vec<&Value> = manifest["jobs"]
        .as_array()
        .map(|a| {
            a.iter().filter(|j| j["method"] == "patch-sampling" && matches!(j["status"].as_str(), Some("ok" | "up-to-date"))).collect()
        })
        .unwrap_or_default();
    if jobs.is_empty() {
        eprintln!("{path}: no successful patch-sampling jobs");
        std::process::exit(1);
    }
    table2(&jobs);
    figure4(&jobs);
}

fn file_of(job: &Value) -> String {
    job["id"].as_str().unwrap_or("").split('#').next().unwrap_or("").to_string()
}

fn table2(jobs: &[&Value]) {
    // (job file, search) → per-run (error, optimum, best_iteration, chaos searches, within 3 %).
    type Run = (u64, u64, u64, u64, u64);
    let mut groups: BTreeMap<(String, String), Vec<Run>> = BTreeMap::new();
    for j in jobs {
        let d = &j["diagnostics"];
        let Some(blocks) = d["per_block"].as_array() else { continue };
        if blocks.len() != 1 || blocks[0]["optimum"].as_u64().is_none() || blocks[0]["best_iteration"].as_u64().is_none() {
            continue;
        }
        let b = &blocks[0];
        let search = j["params"]["search"].as_str().unwrap_or("?").to_string();
        groups.entry((file_of(j), search)).or_default().push((
            b["error"].as_u64().unwrap_or(0),
            b["optimum"].as_u64().unwrap_or(0),
            b["best_iteration"].as_u64().unwrap_or(0),
            b["chaos_searches"].as_u64().unwrap_or(0),
            b["positions_within_3pct"].as_u64().unwrap_or(0),
        ));
    }
    if groups.is_empty() {
        println!("Table 2: no single-block jobs with record_optimum = true in this manifest.\n");
        return;
    }
    println!("## Table 2: search success on one block problem (success: error ≤ 1.03 × exhaustive optimum)\n");
    println!(
        "| problem | algorithm | runs | mean iterations | successes | failures | success rate | runs with chaos | mean error / optimum | optimum (positions within 3 %) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for ((file, search), runs) in &groups {
        let ok: Vec<&Run> = runs.iter().filter(|r| (r.0 as f64) <= 1.03 * r.1 as f64).collect();
        let mean_it =
            if ok.is_empty() { "—".to_string() } else { format!("{:.1}", ok.iter().map(|r| r.2 as f64).sum::<f64>() / ok.len() as f64) };
        let ratio = runs.iter().map(|r| if r.1 == 0 { 1.0 } else { r.0 as f64 / r.1 as f64 }).sum::<f64>() / runs.len() as f64;
        let optima: std::collections::BTreeSet<(u64, u64)> = runs.iter().map(|r| (r.1, r.4)).collect();
        let optima: Vec<String> = optima.iter().map(|(o, n)| format!("{o} ({n})")).collect();
        println!(
            "| {file} | {} | {} | {mean_it} | {} | {} | {:.0} % | {} | {ratio:.3} | {} |",
            search.to_uppercase(),
            runs.len(),
            ok.len(),
            runs.len() - ok.len(),
            100.0 * ok.len() as f64 / runs.len() as f64,
            runs.iter().filter(|r| r.3 > 0).count(),
            optima.join(", ")
        );
    }
    println!("\nPaper: PSO 87 iterations, 44/50 (88 %); CPSO 49 iterations, 50/50 (100 %).\n");
}

fn figure4(jobs: &[&Value]) {
    // (job file, search label) → particles → (seconds, metrics).
    type Cell = Vec<(f64, Value)>;
    let mut groups: BTreeMap<(String, String), BTreeMap<i64, Cell>> = BTreeMap::new();
    for j in jobs {
        if j["outputs"][0]["width"].as_u64().unwrap_or(0) < 64 {
            continue; // the tiny single-block jobs of Table 2
        }
        let Some(seconds) = j["timing"]["synthesis_seconds"].as_f64() else { continue };
        let p = &j["params"];
        let search = p["search"].as_str().unwrap_or("?");
        let label =
            if search == "exhaustive" { format!("exhaustive ({})", p["engine"].as_str().unwrap_or("fft")) } else { search.to_string() };
        let particles = if search == "exhaustive" { 0 } else { p["particles"].as_i64().unwrap_or(0) };
        groups.entry((file_of(j), label)).or_default().entry(particles).or_default().push((seconds, j["metrics"].clone()));
    }
    if groups.is_empty() {
        return;
    }
    println!("## Figure 4: synthesis time (s) vs particles (exhaustive search does not use particles)\n");
    let counts: std::collections::BTreeSet<i64> = groups.values().flat_map(|m| m.keys().copied()).filter(|&c| c > 0).collect();
    let header: Vec<String> = counts.iter().map(|c| format!("{c} particles")).collect();
    println!("| job file | search | {} | any |", header.join(" | "));
    println!("|---|---|{}---|", "---|".repeat(counts.len()));
    for ((file, label), by) in &groups {
        let cell = |c: i64| by.get(&c).map(|v| format!("{:.3}", v.iter().map(|x| x.0).sum::<f64>() / v.len() as f64)).unwrap_or_default();
        let cells: Vec<String> = counts.iter().map(|&c| cell(c)).collect();
        println!("| {file} | {label} | {} | {} |", cells.join(" | "), cell(0));
    }
    println!("\n## Figures 3 and 5: quality metrics of the same outputs (lower is better; seam_visibility 1 = invisible)\n");
    let names = ["kl_gray", "kl_orientation", "acf_gray", "acf_orientation", "seam_visibility"];
    println!("| job file | search | particles | {} |", names.join(" | "));
    println!("|---|---|---|{}", "---|".repeat(names.len()));
    for ((file, label), by) in &groups {
        for (c, runs) in by {
            for (_, m) in runs {
                if m.is_null() {
                    continue;
                }
                let cells: Vec<String> =
                    names.iter().map(|n| m[*n].as_f64().map(|v| format!("{v:.4}")).unwrap_or_else(|| "—".into())).collect();
                let c = if *c == 0 { "—".to_string() } else { c.to_string() };
                println!("| {file} | {label} | {c} | {} |", cells.join(" | "));
            }
        }
    }
}
