//! What a patch-sampling run records in the manifest's `diagnostics`: the summary every run has,
//! the per-block list with `diagnostics = true`, and paper 002's Table 2 figures with
//! `record_optimum = true` (all deterministic).

use super::config::Search;
use super::{BlockResult, NEAR_OPTIMUM, Settings};
use crate::synth::params::Choice;
use serde_json::{Value, json};

/// The manifest's diagnostics: a summary always, every searched block with `diagnostics = true`.
pub(super) fn diagnostics((cols, rows): (u32, u32), settings: &Settings, results: &[BlockResult]) -> Value {
    let searched: Vec<&BlockResult> = results.iter().filter(|r| (r.bi, r.bj) != (0, 0)).collect();
    let n = searched.len();
    let mean = |f: &dyn Fn(&BlockResult) -> f64| if n == 0 { 0.0 } else { searched.iter().map(|r| f(r)).sum::<f64>() / n as f64 };
    let mut summary = json!({
        "search": settings.search.name(),
        "blocks": { "cols": cols, "rows": rows },
        "searched_blocks": n,
        "mean_rms_error": mean(&|r| rms(r.error, r.zone_pixels)),
    });
    let obj = summary.as_object_mut().expect("object");
    if settings.search == Search::Exhaustive {
        obj.insert("mean_candidates".into(), json!(mean(&|r| r.candidates.unwrap_or(0) as f64)));
    } else {
        let sw = |r: &BlockResult| r.swarm.clone().expect("swarm outcome");
        obj.insert("mean_iterations".into(), json!(mean(&|r| sw(r).iterations as f64)));
        obj.insert("mean_evaluations".into(), json!(mean(&|r| sw(r).evaluations as f64)));
        obj.insert("early_stops".into(), json!(searched.iter().filter(|r| sw(r).stopped_early).count()));
        obj.insert("chaos_blocks".into(), json!(searched.iter().filter(|r| sw(r).chaos_searches > 0).count()));
        obj.insert("chaos_searches".into(), json!(searched.iter().map(|r| sw(r).chaos_searches as u64).sum::<u64>()));
    }
    if settings.optimum {
        obj.insert("mean_rms_optimum".into(), json!(mean(&|r| rms(r.optimum.unwrap_or(0), r.zone_pixels))));
        // Per-run figures of paper 002's Table 2, tabulated by `texsyn report` (mean over seeds =
        // success rate): success = every searched block within 3 % of the exhaustive optimum;
        // iterations to the final best, only for successful runs (null otherwise).
        let success = searched.iter().all(|r| (r.error as f64) <= (1.0 + NEAR_OPTIMUM) * r.optimum.unwrap_or(0) as f64);
        let iterations = if success && settings.search != Search::Exhaustive {
            json!(mean(&|r| r.swarm.as_ref().map_or(0.0, |s| s.best_iteration as f64)))
        } else {
            Value::Null
        };
        obj.insert("summary".into(), json!({ "success": if success { 1.0 } else { 0.0 }, "iterations_when_successful": iterations }));
    }
    if settings.per_block {
        let first = &results[0];
        obj.insert("first".into(), json!({ "x": first.pos.0, "y": first.pos.1 }));
        let list: Vec<Value> = searched
            .iter()
            .map(|r| {
                let mut b = json!({
                    "bi": r.bi, "bj": r.bj, "x": r.pos.0, "y": r.pos.1,
                    "error": r.error, "zone_pixels": r.zone_pixels,
                });
                let o = b.as_object_mut().expect("object");
                if let Some(s) = &r.swarm {
                    o.insert("iterations".into(), json!(s.iterations));
                    o.insert("best_iteration".into(), json!(s.best_iteration));
                    o.insert("chaos_searches".into(), json!(s.chaos_searches));
                    o.insert("first_chaos".into(), json!(s.first_chaos));
                    o.insert("evaluations".into(), json!(s.evaluations));
                    o.insert("stopped_early".into(), json!(s.stopped_early));
                    if settings.polish_radius > 0 {
                        o.insert("swarm_error".into(), json!(s.best_fitness as u64));
                    }
                }
                if let Some(c) = r.candidates {
                    o.insert("candidates".into(), json!(c));
                }
                if settings.optimum {
                    o.insert("optimum".into(), json!(r.optimum));
                    o.insert("positions_within_3pct".into(), json!(r.near_optimum));
                }
                b
            })
            .collect();
        obj.insert("per_block".into(), Value::Array(list));
    }
    summary
}

/// RMS difference per channel over a zone of `pixels` pixels.
fn rms(ssd: u64, pixels: u64) -> f64 {
    if pixels == 0 { 0.0 } else { (ssd as f64 / (3 * pixels) as f64).sqrt() }
}
