//! Filling a hole in an image with blocks of the image itself (`[inpaint]` in a job file), for
//! the block methods: quilting's search and seam, constrained by the pixels around the hole.
//!
//! The output starts as the image, each pixel its own source, and only pixels of the fill
//! region are ever written: everything outside it stays bit for bit (also in companions and at
//! 16-bit or float, which are rendered from the same placement). Blocks are laid over the hole's
//! bounding box at the method's stride and made from the hole's border inwards ([`next_block`]),
//! and only blocks that still hold an empty pixel are made. For each, the search compares the block's content where it must join
//! — what earlier blocks filled within `overlap` of its empty pixels, and the known image in a
//! narrow band along the hole — with each sample position that lies wholly outside the hole
//! (the hole holds what must go) and inside the sample mask. The chosen block then meets what
//! is there along a minimum-error seam (`primitives::graph_cut`): known pixels always stay,
//! empty ones always take the block, pixels filled earlier go to whichever side the cheapest
//! seam leaves them, except on the block's rim, where they meet content outside the block and
//! stay. So the known pixels constrain both the search and the cut, rather than being pasted
//! back over a synthesis.
//!
//! On a torus (`tileable = true`) blocks wrap around the image's edges, so the far side of the
//! image is context for a hole at the border, and the repair wraps like the image does.

use super::{BlockSearch, Engine};
use crate::image::RgbImage;
use crate::synth::constraints::{FillRegion, SampleMask, nth_allowed};
use crate::synth::error::SynthError;
use crate::synth::method::{Request, Synthesis};
use crate::synth::primitives::block_grid::OverlapRule;
use crate::synth::primitives::canvas::Canvas;
use crate::synth::primitives::graph_cut::{Side, min_cut, min_cut_with_keep_costs};
use crate::synth::primitives::overlap::{Rect, pixel_error};
use crate::synth::rng::Stream;

/// How far into the known image (in pixels from the hole) a block's search compares: the band
/// where the block's fixed join with the known pixels shows. Filled pixels are compared within
/// `overlap` (the cut may run anywhere there), but a wider known band weighs the choice towards
/// blocks that resemble known pixels the fixed seam never reaches: on a 1024² pebbles image
/// with a 220×180 hole, the mean step across the hole's border fell from 22.4 (band = overlap,
/// 8) to 19.6 with 2 (the image's own steps: 6.2).
const KNOWN_BAND: u32 = 2;

/// The known band the border polish matches (see [`polish`]).
const POLISH_BAND: u32 = 3;

/// What a pixel of the image holds while the hole is filled.
#[derive(Clone, Copy, PartialEq, Eq)]
enum State {
    /// Outside the fill region: never written.
    Known,
    /// In the fill region, not made yet.
    Empty,
    /// In the fill region, made by an earlier block (a later one may still replace it).
    Filled,
}

/// How the hole is filled: the method's block, stride and pick rule.
pub(crate) struct Fill<'a> {
    pub block: u32,
    pub overlap: u32,
    /// The border polish's tolerance (its patches are picked among those within it).
    pub tolerance: f64,
    /// `Cut`: the minimum-error seam through pixels filled earlier; `Overwrite`: a block replaces
    /// every fill pixel under it; `Feather`: pixels filled earlier are blended towards the block,
    /// its weight rising from the content that stays to the empty pixels (Liang's ramp across an
    /// overlap of any shape). Known pixels are never written, whatever the rule.
    pub rule: OverlapRule,
    /// How the border polish's patches meet the fill: `Cut` (a seam that pays for the present
    /// joints) or `Feather` (blended in from the known border). Ignored with `Overwrite`.
    pub polish_rule: OverlapRule,
    /// The positions a block may be copied from (row-major over the block positions).
    pub allowed: &'a [bool],
    /// The sample pixels that may be copied (outside the hole, inside any sample mask), for the
    /// smaller patches that polish the hole's border.
    pub copyable: &'a SampleMask,
    /// The search engine, for the polishing patches' own search.
    pub engine: Engine,
    /// The stream-label prefix of the method (`quilt`), so that its picks are its own.
    pub label: &'static str,
    /// The border polish's search, made beforehand from the fill's ([`polish_search`]) so that
    /// it shares the sample's spectra; taken by the polish. Empty: the polish makes its own.
    pub polish_search: std::cell::Cell<Option<BlockSearch<'a>>>,
}

/// The border polish's search over `image` (the request's sample, which `search` must search),
/// sharing `search`'s spectra: the same search the polish would make itself, without
/// transforming the sample a second time. `None` where it cannot share (the pyramid) or the
/// polish searches nothing (no patch fits outside the hole).
pub(crate) fn polish_search<'a>(search: &BlockSearch<'a>, block: u32, overlap: u32, copyable: &SampleMask) -> Option<BlockSearch<'a>> {
    let q = polish_side(block, overlap);
    let allowed = copyable.block_positions(q, q);
    if !allowed.contains(&true) {
        return None;
    }
    search.for_block(q, allowed)
}

/// One block of the hole, as a method's pick sees it.
pub(crate) struct Want<'w> {
    /// The block's window of the image as it stands.
    pub window: &'w RgbImage,
    /// The parts of the window to match (window coordinates, never empty).
    pub regions: &'w [Rect],
    /// The sample positions of the blocks the window's content came from, so that, with turned
    /// copies in an atlas, the block is not their mirror image
    /// ([`crate::synth::constraints::Constraints::is_twin`]).
    pub neighbours: &'w [(u32, u32)],
    /// The block's index (for its random streams).
    pub index: (u32, u32),
    /// The window's top-left pixel in the image (where a guide is read).
    pub place: (u32, u32),
    /// The sample positions of the hole's blocks picked so far, in order ([`Reuse`]).
    pub placed: &'w [(u32, u32)],
}

/// How much a hole's fill repeats itself. A hole copies only from what lies outside it; with a
/// large hole in its own image that is a few strips, and blocks picked for their overlap alone
/// came back to the same few patches: a hole of radius 85 in cork (block 50, 25 blocks) drew its
/// 22 941 pixels from 7 839 sample pixels, a grid of the same dark pore. So among the positions a
/// block may take, those that copy little of what earlier blocks of the hole copied come first:
/// at most what continuing its left and top neighbours shares with them (`2·overlap·block +
/// overlap²`); when none is within the tolerance, a wider one is asked for (as for twins), and
/// failing that the least repeating members are kept.
pub(crate) struct Reuse {
    block: u32,
    allowance: u64,
}

impl Reuse {
    pub(crate) fn new(block: u32, overlap: u32) -> Reuse {
        let (b, o) = (u64::from(block), u64::from(overlap));
        Reuse { block, allowance: 2 * o * b + o * o }
    }

    /// The pixels of the sample block at `p` that the blocks at `placed` copied (each counted
    /// once per block that copied it).
    fn repeats(&self, p: (u32, u32), placed: &[(u32, u32)]) -> u64 {
        let b = i64::from(self.block);
        let shared = |a: u32, c: u32| (b - (i64::from(a) - i64::from(c)).abs()).max(0) as u64;
        placed.iter().map(|&(x, y)| shared(p.0, x) * shared(p.1, y)).sum()
    }

    /// The members to pick from: `set(widening)` is the tolerance set (twins left out) widened
    /// by `widening`; the first of `+0`, `+0.25`, `+1` with members that repeat at most the
    /// allowance gives those, and failing all three, the least repeating of the first set.
    pub(crate) fn members(&self, placed: &[(u32, u32)], mut set: impl FnMut(f64) -> Vec<(u32, u32, u64)>) -> Vec<(u32, u32, u64)> {
        let repeats = |m: &(u32, u32, u64)| self.repeats((m.0, m.1), placed);
        let mut least = Vec::new();
        for widening in [0.0, 0.25, 1.0] {
            let found = set(widening);
            let fresh: Vec<(u32, u32, u64)> = found.iter().copied().filter(|m| repeats(m) <= self.allowance).collect();
            if !fresh.is_empty() {
                return fresh;
            }
            if widening == 0.0 {
                let fewest = found.iter().map(repeats).min().unwrap_or(0);
                least = found.into_iter().filter(|m| repeats(m) == fewest).collect();
            }
        }
        least
    }
}

/// A method's choice of the sample position of one block of the hole: the position (one of
/// `how.allowed` flags) and, for the diagnostics, how many candidates it chose among.
pub(crate) type Pick<'p> = dyn FnMut(&Want) -> ((u32, u32), Option<usize>) + 'p;

/// Guided quilting's choice (`[guide]` with `[inpaint]`): uniform among the positions whose
/// error, the window's match weighed against the guides' ([`super::guide::GuidedSearch`]), is
/// within the tolerance of the best, less its neighbours' twins (stream
/// `{label}/inpaint/guided/…`). `search`'s target guide is read at the window's place.
pub(crate) fn pick_guided<'p>(
    req: &'p Request,
    search: &'p mut super::guide::GuidedSearch<'p>,
    tolerance: f64,
    block: u32,
    reuse: Reuse,
    label: &'static str,
) -> impl FnMut(&Want) -> ((u32, u32), Option<usize>) + 'p {
    move |want| {
        let members = reuse.members(want.placed, |wider| {
            let found: Vec<(u32, u32, u64)> = search
                .candidates(want.window, (0, 0), want.regions, want.place, tolerance + wider)
                .into_iter()
                .map(|(x, y)| (x, y, 0))
                .collect();
            req.constraints.without_twins(&found, want.neighbours, block).unwrap_or(found)
        });
        let (bi, bj) = want.index;
        let mut s = Stream::new(req.seed, &format!("{label}/inpaint/guided/bi={bi}/bj={bj}"));
        let p = members[s.below_usize(members.len())];
        ((p.0, p.1), Some(members.len()))
    }
}

/// Quilting's choice: uniform among the search's tolerance set less its neighbours' twins
/// ([`super::untwinned`]; stream `{label}/inpaint/pick/…`).
pub(crate) fn pick_among_candidates<'p>(
    req: &'p Request,
    search: &'p mut BlockSearch,
    tolerance: f64,
    block: u32,
    reuse: Reuse,
    label: &'static str,
) -> impl FnMut(&Want) -> ((u32, u32), Option<usize>) + 'p {
    move |want| {
        let (window, regions, (bi, bj)) = (want.window, want.regions, want.index);
        let members = reuse.members(want.placed, |wider| {
            let c = search.candidates(window, (0, 0), regions, tolerance + wider);
            super::untwinned(req, search, window, (0, 0), regions, tolerance + wider, c.members, want.neighbours, block)
        });
        let mut s = Stream::new(req.seed, &format!("{label}/inpaint/pick/bi={bi}/bj={bj}"));
        let p = members[s.below_usize(members.len())];
        ((p.0, p.1), Some(members.len()))
    }
}

/// Fills `region` of the image and returns the whole image. The image is the request's sample
/// or, with other samples or turned copies, the first piece of its atlas (at (0, 0), as it is):
/// either way its pixel (x, y) is sample pixel (x, y), which is where the blocks are copied from.
pub(crate) fn fill(req: &Request, region: &FillRegion, how: &Fill, pick: &mut Pick) -> Result<Synthesis, SynthError> {
    let sample = req.sample;
    let (w, h) = region.dimensions();
    let fits = if req.constraints.atlas.is_some() { sample.width() >= w && sample.height() >= h } else { sample.dimensions() == (w, h) };
    if !fits || (req.width, req.height) != (w, h) {
        return Err(SynthError::Failed(format!(
            "inpainting makes an output of the image's size ({w}x{h}, the mask's); asked for {}x{} from a {}x{} sample",
            req.width,
            req.height,
            sample.width(),
            sample.height()
        )));
    }
    let block = how.block;
    if block > w || block > h {
        return Err(SynthError::param("block", format!("block {block} does not fit in the {w}x{h} image")));
    }
    let mut canvas = Canvas::new(w, h, sample.dimensions(), req.placement);
    for y in 0..h {
        for x in 0..w {
            canvas.copy(x, y, sample, x, y);
        }
    }
    let twins_matter = req.constraints.atlas.is_some_and(|a| a.has_copies());
    // Where each pixel comes from (the image itself until filled), for the border polish.
    let mut source: Vec<(u32, u32)> = (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).collect();
    let mut state: Vec<State> = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| if region.fills(x, y) { State::Empty } else { State::Known })
        .collect();
    let Some((x0, y0, x1, y1)) = region.bounds() else {
        let (image, placement) = canvas.finish();
        let diagnostics = serde_json::json!({ "inpaint": { "filled_pixels": 0, "blocks": 0 } });
        return Ok(Synthesis { image, seams: None, diagnostics, phases: Vec::new(), extras: Vec::new(), placement });
    };
    let stride = block - how.overlap;
    let xs = origins(x0, x1, w, block, how.overlap, stride, req.tileable);
    let ys = origins(y0, y1, h, block, how.overlap, stride, req.tileable);
    let at = |ox: u32, i: u32, size: u32| (ox + i) % size;
    let positions_x = sample.width() - block + 1;
    let mut blocks = 0u32;
    let mut candidate_counts = Vec::new();
    let mut placed: Vec<(u32, u32)> = Vec::new();
    let mut todo: Vec<(usize, usize)> = (0..ys.len()).flat_map(|bi| (0..xs.len()).map(move |bj| (bi, bj))).collect();
    let mut empty = EmptyCounts::new(&xs, &ys, block, (w, h), |x, y| state[(y * w + x) as usize] == State::Empty);
    while let Some((bi, bj)) = next_block(&mut todo, |bi, bj| empty.content(bi, bj)) {
        let (ox, oy) = (xs[bj], ys[bi]);
        let index = |i: u32, j: u32| (at(oy, j, h) * w + at(ox, i, w)) as usize;
        blocks += 1;
        // The block's window of the canvas, and the runs of it that hold content.
        let window = RgbImage::from_fn(block, block, |i, j| canvas.image.get(at(ox, i, w), at(oy, j, h)));
        let near = near_empty(block, how.overlap, |i, j| state[index(i, j)] == State::Empty);
        let near_known = near_empty(block, KNOWN_BAND.min(how.overlap), |i, j| state[index(i, j)] == State::Empty);
        let regions = content_runs(block, |i, j| match state[index(i, j)] {
            State::Empty => false,
            State::Filled => near[(j * block + i) as usize],
            State::Known => near_known[(j * block + i) as usize],
        });
        // Where the window's content was copied from, as block positions (a known pixel is
        // its own source): the blocks a new one must not mirror.
        let mut neighbours = std::collections::BTreeSet::new();
        if twins_matter {
            for r in &regions {
                for i in r.x..r.x + r.w {
                    let (fx, fy) = source[index(i, r.y)];
                    if let (Some(nx), Some(ny)) = (fx.checked_sub(i), fy.checked_sub(r.y)) {
                        neighbours.insert((nx, ny));
                    }
                }
            }
        }
        let neighbours: Vec<(u32, u32)> = neighbours.into_iter().collect();
        let (sx, sy) = if regions.is_empty() {
            // Nothing to match (a hole that swallows a whole block at the image's corner):
            // any allowed position, as quilting's first block.
            let count = how.allowed.iter().filter(|&&a| a).count() as u64;
            let mut s = Stream::new(req.seed, &format!("{}/inpaint/first/bi={bi}/bj={bj}", how.label));
            nth_allowed(how.allowed, positions_x, s.below(count)).expect("an allowed position")
        } else {
            let want = Want {
                window: &window,
                regions: &regions,
                neighbours: &neighbours,
                index: (bi as u32, bj as u32),
                place: (ox, oy),
                placed: &placed,
            };
            let (p, count) = pick(&want);
            candidate_counts.extend(count);
            p
        };
        placed.push((sx, sy));
        if how.rule == OverlapRule::Feather {
            feather_in(&mut canvas, sample, (sx, sy), block, how.overlap, |i, j| state[index(i, j)], |i, j| (at(ox, i, w), at(oy, j, h)));
            for j in 0..block {
                for i in 0..block {
                    let (x, y) = (at(ox, i, w), at(oy, j, h));
                    let k = (y * w + x) as usize;
                    if state[k] == State::Empty {
                        state[k] = State::Filled;
                        source[k] = (sx + i, sy + j);
                        empty.filled(x, y);
                    }
                }
            }
            continue;
        }
        let (bu, n) = (block as usize, (block * block) as usize);
        let mut sides = Vec::with_capacity(n);
        let mut error = Vec::with_capacity(n);
        for j in 0..block {
            for i in 0..block {
                let st = state[index(i, j)];
                let rim = i == 0 || j == 0 || i == block - 1 || j == block - 1;
                sides.push(match (st, how.rule) {
                    (State::Known, _) => Side::Keep,
                    (State::Empty, _) | (State::Filled, OverlapRule::Overwrite) => Side::New,
                    // A filled pixel on the window's rim meets content outside the window,
                    // which the cut cannot see: it stays, so the seam runs inside the
                    // window where its cost is counted (else a block with no known pixel
                    // would take its whole window at no cost, along a straight line).
                    (State::Filled, _) if rim => Side::Keep,
                    (State::Filled, _) => Side::Free,
                });
                error.push(if st == State::Empty { 0 } else { u64::from(pixel_error(window.get(i, j), sample.get(sx + i, sy + j))) });
            }
        }
        let take = min_cut(bu, bu, &sides, &error);
        for j in 0..block {
            for i in 0..block {
                if take[(j * block + i) as usize] {
                    let (x, y) = (at(ox, i, w), at(oy, j, h));
                    canvas.copy(x, y, sample, sx + i, sy + j);
                    if state[(y * w + x) as usize] == State::Empty {
                        empty.filled(x, y);
                    }
                    state[(y * w + x) as usize] = State::Filled;
                    source[(y * w + x) as usize] = (sx + i, sy + j);
                }
            }
        }
    }
    if state.contains(&State::Empty) {
        return Err(SynthError::Failed("inpainting left pixels of the hole empty (a bug: the blocks must cover the hole)".into()));
    }
    let polished = if how.rule == OverlapRule::Overwrite { (0, 0) } else { polish(req, region, how, &mut canvas, &mut source) };
    let (image, placement) = canvas.finish();
    let diagnostics = serde_json::json!({
        "inpaint": {
            "filled_pixels": region.count(),
            "bounds": [x0, y0, x1, y1],
            "blocks": blocks,
            "mean_candidates": candidate_counts.iter().sum::<usize>() as f64 / candidate_counts.len().max(1) as f64,
            "border_patches": polished.0,
            "border_pixels_replaced": polished.1,
        }
    });
    Ok(Synthesis { image, seams: None, diagnostics, phases: Vec::new(), extras: Vec::new(), placement })
}

/// How many empty pixels each block's window holds, kept as pixels are filled, so that choosing
/// the next block does not count every remaining window again (on a 900² hole of 484 blocks
/// that recount was an eighth of the fill's time).
struct EmptyCounts {
    /// Row-major over the blocks (`ys.len() × xs.len()`).
    counts: Vec<u32>,
    columns: usize,
    /// The blocks whose windows hold image column `x` (`bj`s) and row `y` (`bi`s), wrapping.
    blocks_at_x: Vec<Vec<usize>>,
    blocks_at_y: Vec<Vec<usize>>,
    area: u32,
}

impl EmptyCounts {
    fn new(xs: &[u32], ys: &[u32], block: u32, (w, h): (u32, u32), is_empty: impl Fn(u32, u32) -> bool) -> EmptyCounts {
        let spans = |origins: &[u32], size: u32| {
            let mut at = vec![Vec::new(); size as usize];
            for (b, &o) in origins.iter().enumerate() {
                for i in 0..block {
                    at[((o + i) % size) as usize].push(b);
                }
            }
            at
        };
        let (blocks_at_x, blocks_at_y) = (spans(xs, w), spans(ys, h));
        let mut counts = vec![0; xs.len() * ys.len()];
        for y in 0..h {
            for x in 0..w {
                if is_empty(x, y) {
                    for &bi in &blocks_at_y[y as usize] {
                        for &bj in &blocks_at_x[x as usize] {
                            counts[bi * xs.len() + bj] += 1;
                        }
                    }
                }
            }
        }
        EmptyCounts { counts, columns: xs.len(), blocks_at_x, blocks_at_y, area: block * block }
    }

    /// The known and filled pixels of block `(bi, bj)`'s window; `None` once none is empty.
    fn content(&self, bi: usize, bj: usize) -> Option<u32> {
        let empty = self.counts[bi * self.columns + bj];
        (empty > 0).then_some(self.area - empty)
    }

    /// The empty pixel `(x, y)` was filled.
    fn filled(&mut self, x: u32, y: u32) {
        for &bi in &self.blocks_at_y[y as usize] {
            for &bj in &self.blocks_at_x[x as usize] {
                self.counts[bi * self.columns + bj] -= 1;
            }
        }
    }
}

/// The next block of the hole to make: among the grid positions left in `todo`, the one whose
/// window already holds the most content (`content(bi, bj)`: its known and filled pixels, `None`
/// once it holds no empty pixel, which drops it), the first in raster order among equals; `None`
/// when every block is made. Why not raster order: a block made early along the hole's far side
/// must then meet blocks that were made without knowing it, and on a wall whose mortar line runs
/// through the hole the line ended mid-hole in a block of another stone. Filling from the
/// border inwards (the onion peel of exemplar-based inpainting) lets each block continue the
/// known image wherever it touches it, and leaves the hole's middle for last, where blocks meet
/// what was made around them on every side.
fn next_block(todo: &mut Vec<(usize, usize)>, mut content: impl FnMut(usize, usize) -> Option<u32>) -> Option<(usize, usize)> {
    let mut best: Option<(u32, usize)> = None;
    let mut k = 0;
    while k < todo.len() {
        let (bi, bj) = todo[k];
        match content(bi, bj) {
            None => {
                todo.remove(k);
                continue;
            }
            Some(c) if best.is_none_or(|(b, _)| c > b) => best = Some((c, k)),
            Some(_) => {}
        }
        k += 1;
    }
    best.map(|(_, k)| todo.remove(k))
}

/// Feathers the block at sample position `src` into its window: empty pixels take it, pixels
/// filled earlier are blended towards it with weight `(k + 1) / (k + 1 + d)`, where `k + 1` is
/// how far (4-connected steps) the pixel lies from content that stays (a known pixel, or the
/// window's outside) and `d` how far from an empty pixel: across a straight overlap strip of
/// width `w` that is Liang's ramp `(k + 1) / (w + 1)`. Filled pixels farther than `reach` from
/// an empty one keep what they hold; known pixels are never written.
fn feather_in(
    canvas: &mut Canvas,
    image: &RgbImage,
    src: (u32, u32),
    block: u32,
    reach: u32,
    state: impl Fn(u32, u32) -> State,
    pos: impl Fn(u32, u32) -> (u32, u32),
) {
    let b = block as usize;
    let st: Vec<State> = (0..block).flat_map(|j| (0..block).map(move |i| (i, j))).map(|(i, j)| state(i, j)).collect();
    // Breadth-first distances over the filled pixels, from the given seeds (row-major order).
    let distances = |seed: &dyn Fn(usize) -> Option<u32>| {
        let mut d = vec![u32::MAX; b * b];
        let mut queue = std::collections::VecDeque::new();
        for p in 0..b * b {
            if st[p] == State::Filled
                && let Some(v) = seed(p)
            {
                d[p] = v;
                queue.push_back(p);
            }
        }
        while let Some(p) = queue.pop_front() {
            let (i, j) = (p % b, p / b);
            for q in [(i > 0).then(|| p - 1), (i + 1 < b).then(|| p + 1), (j > 0).then(|| p - b), (j + 1 < b).then(|| p + b)]
                .into_iter()
                .flatten()
            {
                if st[q] == State::Filled && d[q] == u32::MAX {
                    d[q] = d[p] + 1;
                    queue.push_back(q);
                }
            }
        }
        d
    };
    let neighbours = |p: usize| {
        let (i, j) = (p % b, p / b);
        [(i > 0).then(|| p - 1), (i + 1 < b).then(|| p + 1), (j > 0).then(|| p - b), (j + 1 < b).then(|| p + b)]
    };
    // k + 1: 1 next to a known pixel or on the rim.
    let stay = distances(&|p| {
        let (i, j) = (p % b, p / b);
        let rim = i == 0 || j == 0 || i + 1 == b || j + 1 == b;
        (rim || neighbours(p).into_iter().flatten().any(|q| st[q] == State::Known)).then_some(1)
    });
    let new = distances(&|p| neighbours(p).into_iter().flatten().any(|q| st[q] == State::Empty).then_some(1));
    for p in 0..b * b {
        let (i, j) = ((p % b) as u32, (p / b) as u32);
        let (x, y) = pos(i, j);
        match st[p] {
            State::Known => {}
            State::Empty => canvas.copy(x, y, image, src.0 + i, src.1 + j),
            State::Filled if new[p] > reach => {}
            // An island of filled pixels among empty ones: nothing around it stays.
            State::Filled if stay[p] == u32::MAX => canvas.copy(x, y, image, src.0 + i, src.1 + j),
            State::Filled => canvas.blend(x, y, image, src.0 + i, src.1 + j, stay[p], stay[p] + new[p]),
        }
    }
}

/// The side of the patches that polish the hole's border: small enough that the known pixels
/// in one are few and closely matched, large enough to hold a seam around them.
fn polish_side(block: u32, overlap: u32) -> u32 {
    (2 * overlap + 3).max(block / 2).min(block)
}

/// Polishes the join between the known image and the fill. A block matches the known pixels
/// near the hole only on the whole; along the hole's border, where the known image is fixed and
/// no cut can move, what remains of the mismatch shows as a faint line. So, around border pixels
/// (spaced half a patch apart, raster order), a smaller patch is searched against the known
/// pixels of its window next to the hole and cut in where it joins better: a filled pixel next to the known image pays for
/// keeping its present joint (how far its source, continued one pixel on, is from the known
/// pixel), so the cut replaces badly joined border pixels and keeps well joined ones; the
/// window's rim and the known pixels always stay. With feathering (patch sampling's join) there
/// is no cut: the patch takes the border pixels of its window when its own joints with the known
/// pixels cost less than the present ones, and blends away from them towards the window's rim
/// (`feather_in`). Returns (patches, pixels replaced).
fn polish(req: &Request, region: &FillRegion, how: &Fill, canvas: &mut Canvas, source: &mut [(u32, u32)]) -> (u32, u64) {
    // The image is the sample's top-left corner (see [`fill`]): image pixels are sample pixels.
    let image = req.sample;
    let (w, h) = region.dimensions();
    let (sw, sh) = image.dimensions();
    let q = polish_side(how.block, how.overlap);
    let mut search = match how.polish_search.take() {
        Some(search) => search,
        None => {
            let allowed = how.copyable.block_positions(q, q);
            if !allowed.contains(&true) {
                return (0, 0);
            }
            BlockSearch::within(how.engine, image, q, Some(allowed))
        }
    };
    let neighbours = |x: u32, y: u32| -> [Option<(u32, u32)>; 4] {
        if req.tileable {
            [((x + w - 1) % w, y), ((x + 1) % w, y), (x, (y + h - 1) % h), (x, (y + 1) % h)].map(Some)
        } else {
            [(x > 0).then(|| (x - 1, y)), (x + 1 < w).then(|| (x + 1, y)), (y > 0).then(|| (x, y - 1)), (y + 1 < h).then(|| (x, y + 1))]
        }
    };
    // Border pixels as centres, at least half a patch apart (a coarse grid finds near ones).
    let spacing = (q / 2).max(1);
    let mut taken: std::collections::BTreeMap<(u32, u32), Vec<(u32, u32)>> = Default::default();
    let mut centres = Vec::new();
    for y in 0..h {
        for x in 0..w {
            if !region.fills(x, y) || !neighbours(x, y).into_iter().flatten().any(|(nx, ny)| !region.fills(nx, ny)) {
                continue;
            }
            let cell = (x / spacing, y / spacing);
            let near = (cell.1.saturating_sub(1)..=cell.1 + 1)
                .flat_map(|cy| (cell.0.saturating_sub(1)..=cell.0 + 1).map(move |cx| (cx, cy)))
                .filter_map(|c| taken.get(&c))
                .flatten()
                .any(|&(px, py)| px.abs_diff(x) < spacing && py.abs_diff(y) < spacing);
            if !near {
                taken.entry(cell).or_default().push((x, y));
                centres.push((x, y));
            }
        }
    }
    let at = |o: u32, i: u32, size: u32| (o + i) % size;
    let origin = |c: u32, size: u32| {
        if req.tileable {
            (i64::from(c) - i64::from(q / 2)).rem_euclid(i64::from(size)) as u32
        } else {
            c.saturating_sub(q / 2).min(size - q)
        }
    };
    let (n, qu) = ((q * q) as usize, q as usize);
    let window_at = |canvas: &Canvas, (ox, oy): (u32, u32)| RgbImage::from_fn(q, q, |i, j| canvas.image.get(at(ox, i, w), at(oy, j, h)));
    // Only the known pixels next to the hole are matched: the patch's join with them is all the
    // cut can change here (matching the whole known part of the window spreads the error over
    // pixels that stay anyway; on a 1024² pebbles hole the border step was 19.6 against 15.8
    // with a 3-px band). Known pixels are never written, so no patch changes what a later one
    // matches, and each pick draws from its own stream: all the searches and picks are made up
    // front, one after another, from the canvas as it stands, while the sample's spectra stay
    // in cache (interleaved with the cuts, a 512² inpainting took 5 % longer). Only the picks
    // are kept, so that one candidate set at a time is held, as before.
    let picks: Vec<((u32, u32), (u32, u32))> = centres
        .iter()
        .enumerate()
        .map(|(k, &(cx, cy))| {
            let (ox, oy) = (origin(cx, w), origin(cy, h));
            let hole = |i: u32, j: u32| region.fills(at(ox, i, w), at(oy, j, h));
            let band = near_empty(q, POLISH_BAND, hole);
            let known = content_runs(q, |i, j| !hole(i, j) && band[(j * q + i) as usize]);
            let c = search.candidates(&window_at(canvas, (ox, oy)), (0, 0), &known, how.tolerance);
            let mut s = Stream::new(req.seed, &format!("{}/inpaint/polish/k={k}", how.label));
            let (sx, sy, _) = c.members[s.below_usize(c.members.len())];
            ((ox, oy), (sx, sy))
        })
        .collect();
    let mut replaced = 0u64;
    for ((ox, oy), (sx, sy)) in picks {
        let pos = |i: u32, j: u32| (at(ox, i, w), at(oy, j, h));
        // The window as earlier patches left it (the cut weighs its filled pixels too).
        let window = window_at(canvas, (ox, oy));
        let mut sides = Vec::with_capacity(n);
        let mut error = Vec::with_capacity(n);
        let mut keep_cost = vec![0u64; n];
        // The patch's own joints with the known pixels (its pixel continued onto each known neighbour).
        let mut joint_new = 0u64;
        for j in 0..q {
            for i in 0..q {
                let (x, y) = pos(i, j);
                let rim = i == 0 || j == 0 || i == q - 1 || j == q - 1;
                sides.push(if rim || !region.fills(x, y) { Side::Keep } else { Side::Free });
                error.push(u64::from(pixel_error(window.get(i, j), image.get(sx + i, sy + j))));
                if rim || !region.fills(x, y) {
                    continue;
                }
                // The present joint with each known neighbour: this pixel's source continued onto it.
                let (fx, fy) = source[(y * w + x) as usize];
                for (di, dj) in [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)] {
                    let (ni, nj) = ((i64::from(i) + di) as u32, (i64::from(j) + dj) as u32);
                    let (nx, ny) = pos(ni, nj);
                    if region.fills(nx, ny) {
                        continue;
                    }
                    let (ax, ay) = (i64::from(fx) + di, i64::from(fy) + dj);
                    if (0..i64::from(sw)).contains(&ax) && (0..i64::from(sh)).contains(&ay) {
                        keep_cost[(j * q + i) as usize] += 2 * u64::from(pixel_error(image.get(nx, ny), image.get(ax as u32, ay as u32)));
                    }
                    joint_new += 2 * u64::from(pixel_error(image.get(nx, ny), image.get(sx + ni, sy + nj)));
                }
            }
        }
        if how.polish_rule == OverlapRule::Feather {
            // Feathered: the patch replaces the border pixels of its window only if it joins the
            // known ones better than what is there, and blends away from them towards the rim.
            if joint_new >= keep_cost.iter().sum::<u64>() {
                continue;
            }
            let ring = |i: u32, j: u32| {
                let (x, y) = pos(i, j);
                let rim = i == 0 || j == 0 || i == q - 1 || j == q - 1;
                !rim && region.fills(x, y) && neighbours(x, y).into_iter().flatten().any(|(nx, ny)| !region.fills(nx, ny))
            };
            let state = |i: u32, j: u32| {
                let (x, y) = pos(i, j);
                if !region.fills(x, y) {
                    State::Known
                } else if ring(i, j) {
                    State::Empty
                } else {
                    State::Filled
                }
            };
            feather_in(canvas, image, (sx, sy), q, q, state, pos);
            for j in 0..q {
                for i in 0..q {
                    if ring(i, j) {
                        let (x, y) = pos(i, j);
                        source[(y * w + x) as usize] = (sx + i, sy + j);
                        replaced += 1;
                    }
                }
            }
            continue;
        }
        let take = min_cut_with_keep_costs(qu, qu, &sides, &error, &keep_cost);
        for j in 0..q {
            for i in 0..q {
                if take[(j * q + i) as usize] {
                    let (x, y) = pos(i, j);
                    canvas.copy(x, y, image, sx + i, sy + j);
                    source[(y * w + x) as usize] = (sx + i, sy + j);
                    replaced += 1;
                }
            }
        }
    }
    (centres.len() as u32, replaced)
}

/// Block origins along one axis covering `[lo, hi)` with `overlap` of context on both sides, at
/// most `stride` apart and spread evenly, so that the last block also reaches into the known
/// pixels after the hole and is matched against them. Without wrapping each origin is kept
/// inside the image (a block never leaves it); with wrapping, origins are taken modulo the side.
fn origins(lo: u32, hi: u32, side: u32, block: u32, overlap: u32, stride: u32, wrap: bool) -> Vec<u32> {
    let (block, side) = (i64::from(block), i64::from(side));
    let span = i64::from(hi - lo) + 2 * i64::from(overlap);
    let first = i64::from(lo) - i64::from(overlap);
    let raw: Vec<i64> = if span <= block {
        vec![first - (block - span) / 2]
    } else {
        let gaps = (span - block + i64::from(stride) - 1) / i64::from(stride);
        (0..=gaps).map(|k| first + (k * (span - block) + gaps / 2) / gaps).collect()
    };
    let mut v: Vec<u32> = Vec::new();
    for o in raw {
        let placed = if wrap { o.rem_euclid(side) } else { o.clamp(0, side - block) } as u32;
        if !v.contains(&placed) {
            v.push(placed);
        }
    }
    v
}

/// For a `block × block` window, row-major: whether a pixel lies within `reach` pixels (in both
/// directions) of an empty one. Only content that close is compared in the search: it is where the
/// new block must join what is there, as quilting compares only its overlap strips. Content
/// farther off would weigh the choice towards blocks that resemble it, which the seam never sees.
fn near_empty(block: u32, reach: u32, empty: impl Fn(u32, u32) -> bool) -> Vec<bool> {
    let b = block as usize;
    let r = reach as usize;
    // A box dilation, rows then columns, through running counts.
    let mut rows = vec![false; b * b];
    for j in 0..b {
        let line: Vec<bool> = (0..b).map(|i| empty(i as u32, j as u32)).collect();
        let mut prefix = vec![0u32; b + 1];
        for i in 0..b {
            prefix[i + 1] = prefix[i] + u32::from(line[i]);
        }
        for i in 0..b {
            rows[j * b + i] = prefix[(i + r + 1).min(b)] > prefix[i.saturating_sub(r)];
        }
    }
    let mut out = vec![false; b * b];
    for i in 0..b {
        let mut prefix = vec![0u32; b + 1];
        for j in 0..b {
            prefix[j + 1] = prefix[j] + u32::from(rows[j * b + i]);
        }
        for j in 0..b {
            out[j * b + i] = prefix[(j + r + 1).min(b)] > prefix[j.saturating_sub(r)];
        }
    }
    out
}

/// The row runs of a `block × block` window where `has_content` holds, as rectangles.
fn content_runs(block: u32, has_content: impl Fn(u32, u32) -> bool) -> Vec<Rect> {
    let mut runs = Vec::new();
    for j in 0..block {
        let mut i = 0;
        while i < block {
            if !has_content(i, j) {
                i += 1;
                continue;
            }
            let start = i;
            while i < block && has_content(i, j) {
                i += 1;
            }
            runs.push(Rect::new(start, j, i - start, 1));
        }
    }
    runs
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn origins_cover_the_hole_with_context_and_stay_inside() {
        // Hole [40, 90) in a 200-wide image, block 30, overlap 5: from 35 to 65 (the last block
        // ends 5 pixels past the hole), at most 25 apart.
        assert_eq!(origins(40, 90, 200, 30, 5, 25, false), vec![35, 50, 65]);
        // At the image's start and end the origins are clamped, and the last one reaches the end.
        assert_eq!(origins(0, 20, 100, 30, 5, 25, false), vec![0]);
        assert_eq!(origins(80, 100, 100, 30, 5, 25, false), vec![70]);
        // Wrapping: a hole at the start takes context from the far end.
        assert_eq!(origins(0, 20, 100, 30, 5, 25, true), vec![95]);
        for (lo, hi) in [(3, 97), (50, 51), (0, 100)] {
            let o = origins(lo, hi, 100, 30, 5, 25, false);
            assert!((lo..hi).all(|x| o.iter().any(|&s| s <= x && x < s + 30)), "{lo}..{hi}: {o:?}");
        }
    }

    #[test]
    fn only_content_near_the_empty_pixels_is_compared() {
        let near = near_empty(7, 2, |i, j| i == 3 && j == 3);
        for j in 0..7 {
            for i in 0..7 {
                assert_eq!(near[j * 7 + i], i.abs_diff(3) <= 2 && j.abs_diff(3) <= 2, "({i},{j})");
            }
        }
    }

    #[test]
    fn content_runs_are_the_rows_pieces() {
        let runs = content_runs(4, |i, j| (i + j) % 3 != 0);
        assert_eq!(runs.iter().map(|r| r.area()).sum::<u64>(), (0..16).filter(|p| (p % 4 + p / 4) % 3 != 0).count() as u64);
        assert!(runs.iter().all(|r| r.h == 1));
    }
}
