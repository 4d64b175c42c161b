//! The swarm search of one block (paper 002 §4.2 step 5, §4.3): chaos PSO or plain PSO over the
//! sample positions, the zone error as fitness (weighed against a guide's when guided), with
//! the optional polish and continuations after it, and the per-thread memo of zone errors that
//! makes revisited positions free.

use super::positions::Twins;
use super::{BlockResult, GuideTerm, Settings, Zone};
use crate::image::RgbImage;
use crate::synth::primitives::overlap::Rect;
use crate::synth::primitives::pso;
use crate::synth::primitives::zone_ssd::{PackedZone, SampleLines};
use crate::synth::rng::Stream;

/// The swarm search of one block (§4.2 step 5, §4.3).
#[allow(clippy::too_many_arguments)]
pub(super) fn swarm_block(
    sample: &RgbImage,
    lines: &SampleLines,
    zone: &Zone,
    bi: u32,
    bj: u32,
    settings: &Settings,
    seed: u64,
    hints: &[(u32, u32)],
    guide: Option<&GuideTerm>,
    twins: Option<&Twins>,
) -> BlockResult {
    // A thread searches one block at a time and the search starts no parallel work, so the
    // thread's memo is never borrowed twice; should that change, a fresh memo is still correct.
    MEMO.with(|m| match m.try_borrow_mut() {
        Ok(mut memo) => swarm_search(sample, lines, zone, (bi, bj), settings, seed, hints, guide, twins, &mut memo),
        Err(_) => swarm_search(sample, lines, zone, (bi, bj), settings, seed, hints, guide, twins, &mut Memo::default()),
    })
}

#[allow(clippy::too_many_arguments)]
fn swarm_search(
    sample: &RgbImage,
    lines: &SampleLines,
    zone: &Zone,
    (bi, bj): (u32, u32),
    settings: &Settings,
    seed: u64,
    hints: &[(u32, u32)],
    guide: Option<&GuideTerm>,
    twins: Option<&Twins>,
    memo: &mut Memo,
) -> BlockResult {
    let packed = PackedZone::new(&zone.target, zone.origin, &zone.regions);
    let zone_pixels: u64 = zone.regions.iter().map(|r| r.area()).sum();
    let (nx, ny) = (sample.width() - zone.block + 1, sample.height() - zone.block + 1);
    let hi = [(nx - 1) as f64, (ny - 1) as f64];
    let mut params = settings.swarm;
    if settings.delta_rms > 0.0 && guide.is_none() {
        params.stop_below = Some(zone_pixels as f64 * 3.0 * settings.delta_rms * settings.delta_rms);
    }
    // Guided: the guide's SSD over the whole block where it goes, weighed against the zone's.
    let guide_zone = guide.map(|g| (g, PackedZone::new(&g.target, zone.guide_at, &[Rect::new(0, 0, zone.block, zone.block)])));
    let (k_texture, k_guide) = guide.map_or((1.0, 0.0), |g| g.weights(zone_pixels, zone.block));
    // A position stands for its nearest allowed one when a mask rules some out, and a twin of a
    // neighbour for the nearest allowed position that is none.
    let at = |pos: (u32, u32)| {
        let pos = settings.allowed.as_ref().map_or(pos, |a| a.nearest(pos));
        twins.map_or(pos, |t| t.resolve(pos, (nx, ny), settings.allowed.as_ref()))
    };
    let value = |pos: (u32, u32)| {
        let pos = at(pos);
        match &guide_zone {
            None => packed.ssd(lines, pos) as f64,
            Some((g, gz)) => k_texture * packed.ssd(lines, pos) as f64 + k_guide * gz.ssd(&g.lines, pos) as f64,
        }
    };
    // The fitness at a position is a pure function of the rounded position: memoise it. This
    // changes nothing but the time (the swarm often revisits positions once it has converged).
    // (An SSD is an integer below 2^53: exact as an f64, so plain searches order as before.)
    memo.start(nx as usize * ny as usize);
    let mut fitness_at =
        |pos: (u32, u32)| f64::from_bits(memo.get_or_insert(pos.1 as usize * nx as usize + pos.0 as usize, || value(pos).to_bits()));
    let label = &settings.label;
    let mut swarm = Stream::new(seed, &format!("{label}cpso/swarm/bi={bi}/bj={bj}"));
    let mut chaos = Stream::new(seed, &format!("{label}cpso/chaos/bi={bi}/bj={bj}"));
    let outcome = pso::optimise(&[0.0, 0.0], &hi, &params, &mut swarm, &mut chaos, |x| fitness_at(round_position(x, hi)));
    let mut pos = round_position(&outcome.best, hi);
    let mut best = outcome.best_fitness;
    let r = settings.polish_radius;
    if r > 0 {
        // Row-major over the window; strictly better only, so ties keep the swarm's choice.
        let (x0, y0) = (pos.0.saturating_sub(r), pos.1.saturating_sub(r));
        let (x1, y1) = ((pos.0 + r).min(nx - 1), (pos.1 + r).min(ny - 1));
        for y in y0..=y1 {
            for x in x0..=x1 {
                let e = fitness_at((x, y));
                if e < best {
                    best = e;
                    pos = (x, y);
                }
            }
        }
    }
    // In the given order, strictly better only, so ties keep the swarm's (or polish's) choice.
    for &h in hints {
        let e = fitness_at(h);
        if e < best {
            best = e;
            pos = h;
        }
    }
    let pos = at(pos);
    let error = if guide.is_none() { best as u64 } else { packed.ssd(lines, pos) };
    BlockResult { bi, bj, pos, error, zone_pixels, swarm: Some(outcome), candidates: None, optimum: None, near_optimum: None }
}

thread_local! {
    /// Each thread's memo of zone errors, reused from block to block.
    static MEMO: std::cell::RefCell<Memo> = std::cell::RefCell::default();
}

/// Zone errors of one block by position index, kept across blocks so that a block neither
/// allocates nor clears a table the size of the search box: only a bit per position, "known in
/// this block", is cleared. The bits are small enough to stay in the nearest cache, so a first
/// visit learns that it must compute without waiting for the value's cache line.
#[derive(Default)]
struct Memo {
    known: Vec<u64>,
    values: Vec<u64>,
}

impl Memo {
    /// Forgets the previous block; `positions` entries.
    fn start(&mut self, positions: usize) {
        self.known.clear();
        self.known.resize(positions.div_ceil(64), 0);
        if self.values.len() < positions {
            self.values.resize(positions, 0);
        }
    }

    #[inline]
    fn get_or_insert(&mut self, index: usize, compute: impl FnOnce() -> u64) -> u64 {
        let (word, bit) = (index / 64, 1u64 << (index % 64));
        if self.known[word] & bit != 0 {
            return self.values[index];
        }
        let value = compute();
        self.known[word] |= bit;
        self.values[index] = value;
        value
    }
}

/// A particle's patch: its position rounded half away from zero, clamped to the box. The same
/// positions as `v.round().clamp(0.0, h)`, without a call to the C library's `round`: clamping
/// first changes nothing (`h` is an integer), and for `0 ≤ c ≤ h`, `t = trunc(c)` and `c − t` are
/// exact, so `c − t ≥ 0.5` is exactly where `round` goes up, and then `t + 1 ≤ h` (NaN gives 0
/// either way).
#[inline]
pub(super) fn round_position(x: &[f64], hi: [f64; 2]) -> (u32, u32) {
    let r = |v: f64, h: f64| {
        let c = v.clamp(0.0, h);
        let t = c as u32;
        if c - f64::from(t) >= 0.5 { t + 1 } else { t }
    };
    (r(x[0], hi[0]), r(x[1], hi[1]))
}
