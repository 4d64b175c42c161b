//! The exact searches of one block: exhaustive search with Liang et al.'s tolerance rule or the
//! near-best rule (paper 002 §4.4), its guided form (Efros–Freeman's weighed error), and the
//! rectangle-by-rectangle zone error they and the tests check against.

use super::config::CandidateRule;
use super::positions::Twins;
use super::{BlockResult, Settings, Zone};
use crate::image::RgbImage;
use crate::synth::methods::BlockSearch;
use crate::synth::methods::guide::GuidedSearch;
use crate::synth::primitives::overlap::{Rect, rect_ssd};
use crate::synth::primitives::overlap_search::Candidates;
use crate::synth::rng::Stream;
use rayon::prelude::*;

/// `SSD(sample block at (x, y), output block, Ω)` (eq. 7), rectangle by rectangle: the reference
/// the swarms' packed evaluation ([`PackedZone::ssd`]) is checked against.
pub(super) fn zone_error(sample: &RgbImage, canvas: &RgbImage, (x, y): (u32, u32), origin: (u32, u32), regions: &[Rect]) -> u64 {
    regions.iter().map(|r| rect_ssd(sample, x + r.x, y + r.y, canvas, origin.0 + r.x, origin.1 + r.y, r.w, r.h)).sum()
}

/// The exhaustive search of one block of a guided synthesis ([`GuidedSearch`], exact
/// over the allowed positions): the best weighted error (row-major first on ties) with `tolerance
/// = 0`, else uniform among the positions within `(1 + tolerance)` of it (Efros–Freeman's rule:
/// Liang's threshold is relative to the zone's intensity, which a guided error does not have).
/// A neighbour's twins ([`Twins`]) are left out.
#[allow(clippy::too_many_arguments)]
pub(super) fn guided_block(
    search: &mut GuidedSearch,
    sample: &RgbImage,
    zone: &Zone,
    bi: u32,
    bj: u32,
    settings: &Settings,
    seed: u64,
    twins: Option<&Twins>,
) -> BlockResult {
    let tolerance = settings.tolerance.max(0.0);
    let mut members = search.candidates(&zone.target, zone.origin, &zone.regions, zone.guide_at, tolerance);
    if let Some(t) = twins {
        // Without the neighbours' twins; when every member is one, a wider set (as quilting).
        let untwinned = |m: &[(u32, u32)]| -> Vec<(u32, u32)> { m.iter().copied().filter(|&p| !t.is_twin(p)).collect() };
        let mut kept = untwinned(&members);
        for wider in [0.25, 1.0, 4.0] {
            if !kept.is_empty() {
                break;
            }
            kept = untwinned(&search.candidates(&zone.target, zone.origin, &zone.regions, zone.guide_at, tolerance + wider));
        }
        if !kept.is_empty() {
            members = kept;
        }
    }
    let pos = if settings.tolerance <= 0.0 || members.len() == 1 {
        members[0]
    } else {
        let mut s = Stream::new(seed, &format!("{}liang/pick/bi={bi}/bj={bj}", settings.label));
        members[s.below_usize(members.len())]
    };
    let zone_pixels: u64 = zone.regions.iter().map(|r| r.area()).sum();
    let error = zone_error(sample, &zone.target, pos, zone.origin, &zone.regions);
    BlockResult { bi, bj, pos, error, zone_pixels, swarm: None, candidates: Some(members.len()), optimum: None, near_optimum: None }
}

/// Exhaustive search of one block (§4.4). `tolerance = 0`: the best position (row-major first on
/// ties). `tolerance = ε > 0`, `candidates = "liang"`: Liang et al.'s choice, uniform among
/// `{ d < ε²·Σ_Ω |out(p)|² }` (the same set as `sqrt(d/A) < ε·sqrt(Σ|out|²/A)`, decided on exact
/// integers against one `f64` threshold), the best position if that set is empty.
/// `candidates = "near-best"`: uniform among `{ d ≤ (1 + ε)·d_min }`. A neighbour's twins
/// ([`Twins`]) are never candidates: when the best positions are all twins, the best that is
/// none among a near-best set widened by 0.25, 1 and 4 (as quilting), and a twin only when that
/// finds none.
#[allow(clippy::too_many_arguments)]
pub(super) fn exhaustive_block(
    search: &mut BlockSearch,
    sample: &RgbImage,
    zone: &Zone,
    bi: u32,
    bj: u32,
    settings: &Settings,
    seed: u64,
    twins: Option<&Twins>,
) -> BlockResult {
    let no_twin = |m: &(u32, u32, u64)| twins.is_none_or(|t| !t.is_twin((m.0, m.1)));
    let (canvas, origin, regions) = (&*zone.target, zone.origin, zone.regions.clone());
    let allows = |m: &(u32, u32, u64)| settings.allowed.as_ref().is_none_or(|a| a.allows((m.0, m.1)));
    let zone_pixels: u64 = regions.iter().map(|r| r.area()).sum();
    let mut result =
        BlockResult { bi, bj, pos: (0, 0), error: 0, zone_pixels, swarm: None, candidates: Some(0), optimum: None, near_optimum: None };
    let eps = settings.tolerance;
    let mut best: Option<Candidates> = None;
    let members: Vec<(u32, u32, u64)> = if eps <= 0.0 {
        Vec::new()
    } else if settings.candidates == CandidateRule::NearBest {
        let c = search.candidates(canvas, origin, &regions, eps);
        result.optimum = Some(c.min_ssd);
        c.members
    } else {
        let energy: u64 = regions
            .iter()
            .flat_map(|r| (0..r.h).flat_map(move |dy| (0..r.w).map(move |dx| (r.x + dx, r.y + dy))))
            .map(|(dx, dy)| canvas.get(origin.0 + dx, origin.1 + dy).iter().map(|&c| c as u64 * c as u64).sum::<u64>())
            .sum();
        let threshold = eps * eps * energy as f64;
        // The exact minimum first (one FFT search); the set is a tolerance set around it.
        let c = search.candidates(canvas, origin, &regions, 0.0);
        let min = c.min_ssd;
        result.optimum = Some(min);
        best = Some(c);
        if (min as f64) >= threshold {
            Vec::new()
        } else if min == 0 {
            // A tolerance relative to 0 cannot express the bound: scan every position, pruned (or
            // every position the pyramid re-scored).
            match search {
                BlockSearch::Pyramid(p, _) => {
                    p.rescored(canvas, origin, &regions, &[]).into_iter().filter(|m| (m.2 as f64) < threshold && allows(m)).collect()
                }
                BlockSearch::Exact(..) => {
                    members_below(sample, canvas, origin, &regions, zone.block, threshold).into_iter().filter(allows).collect()
                }
            }
        } else {
            // A superset of the bound (the margin covers rounding of threshold / min), then the exact rule.
            let tol = (threshold / min as f64 - 1.0) * (1.0 + 1e-9) + 1e-9;
            let c = search.candidates(canvas, origin, &regions, tol);
            c.members.into_iter().filter(|m| (m.2 as f64) < threshold && allows(m)).collect()
        }
    };
    let members: Vec<(u32, u32, u64)> = members.into_iter().filter(no_twin).collect();
    if members.is_empty() {
        let best = best.unwrap_or_else(|| search.candidates(canvas, origin, &regions, 0.0));
        // The first (row-major) of the lowest errors that is no twin.
        let untwinned = |c: &Candidates| c.members.iter().copied().filter(no_twin).min_by_key(|m| m.2);
        let (x, y, d) = match twins {
            None => best.members[0],
            Some(_) => untwinned(&best)
                .or_else(|| [0.25, 1.0, 4.0].into_iter().find_map(|wider| untwinned(&search.candidates(canvas, origin, &regions, wider))))
                .unwrap_or(best.members[0]),
        };
        result.pos = (x, y);
        result.error = d;
        result.optimum = Some(d);
        if eps <= 0.0 {
            result.candidates = Some(best.members.len());
        }
        return result;
    }
    let mut s = Stream::new(seed, &format!("{}liang/pick/bi={bi}/bj={bj}", settings.label));
    let pick = members[s.below_usize(members.len())];
    result.pos = (pick.0, pick.1);
    result.error = pick.2;
    result.candidates = Some(members.len());
    result
}

/// Every position whose zone error is `< threshold`, row-major, with its exact error. Each
/// position's sum is abandoned as soon as it reaches the bound, so a tight bound costs little.
fn members_below(
    sample: &RgbImage,
    canvas: &RgbImage,
    origin: (u32, u32),
    regions: &[Rect],
    block: u32,
    threshold: f64,
) -> Vec<(u32, u32, u64)> {
    // For an integer d (exact in f64 below 2^53), d < threshold ⟺ d < ceil(threshold).
    let limit = threshold.ceil() as u64;
    let (nx, ny) = (sample.width() - block + 1, sample.height() - block + 1);
    (0..ny)
        .into_par_iter()
        .flat_map_iter(|y| {
            (0..nx).filter_map(move |x| {
                let mut sum = 0u64;
                for r in regions {
                    for dy in 0..r.h {
                        sum += rect_ssd(sample, x + r.x, y + r.y + dy, canvas, origin.0 + r.x, origin.1 + r.y + dy, r.w, 1);
                        if sum >= limit {
                            return None;
                        }
                    }
                }
                Some((x, y, sum))
            })
        })
        .collect()
}
