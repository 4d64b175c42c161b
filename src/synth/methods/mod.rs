//! The synthesis methods, one file each, behind one interface.
//!
//! A method is a pure function of (sample pixels, resolved parameters, seed, output size): it
//! never sees file names, formats or the clock. That is what lets the runner cache, verify and
//! re-run results from the manifest alone. Adding a method means adding a file here and one line
//! in [`registry`]; the job model, scheduler and manifest do not change.

pub mod double_seam;
pub(crate) mod guide;
pub(crate) mod inpaint;
pub mod near_regular;
pub mod patch_sampling;
pub mod quilting;
pub mod tiles;

use crate::image::RgbImage;
use crate::synth::method::Method;
use crate::synth::params::{Choice, MethodConfig, ParamError, ParamValue, Params};
use crate::synth::primitives::overlap::Rect;
use crate::synth::primitives::overlap_search::{Candidates, OverlapSearch};
use crate::synth::primitives::pyramid_search::{self, PyramidSearch};

crate::choice! {
    /// How a block search scores sample positions (quilting's `search`, patch sampling's
    /// `engine`). `fft` and `direct` are the exact exhaustive search, with the same candidates
    /// hence the same pixels; `pyramid` is the coarse-to-fine search for big samples; `auto` is
    /// resolved per sample before a job is recorded ([`Engine::for_sample`]).
    pub enum Engine {
        /// FFT correlation, then an exact integer re-check of the near-best positions.
        Fft = "fft",
        /// Brute-force SSD sums at every position.
        Direct = "direct",
        /// Coarse-to-fine (`primitives::pyramid_search`): a box pyramid's coarse level searched
        /// exactly, its best positions re-scored exactly at full resolution around them.
        Pyramid = "pyramid",
        /// `fft` for samples of at most [`AUTO_EXACT_PIXELS`], `pyramid` above.
        Auto = "auto",
    }
}

/// The largest sample (in pixels, 512²) that `auto` searches exactly: there the exact search costs
/// about 3 ms a block on two cores; above it its cost grows with every sample pixel.
pub const AUTO_EXACT_PIXELS: u64 = 512 * 512;

impl Engine {
    /// The engine that runs for a sample of this size: `auto` made concrete, the others as given.
    pub fn for_sample(self, sample: (u32, u32)) -> Engine {
        match self {
            Engine::Auto if u64::from(sample.0) * u64::from(sample.1) <= AUTO_EXACT_PIXELS => Engine::Fft,
            Engine::Auto => Engine::Pyramid,
            e => e,
        }
    }
}

/// Replaces `auto` in the [`Engine`] parameter `key` by the engine that runs for this sample, so
/// that a job's recorded parameters say which search made its pixels (and a sample of at most
/// 512² keeps the `fft` its jobs always recorded).
pub(crate) fn resolve_engine(params: &mut Params, key: &str, sample: (u32, u32)) {
    if let Ok(engine) = params.choice::<Engine>(key) {
        params.0.insert(key.to_string(), ParamValue::Str(engine.for_sample(sample).name().to_string()));
    }
}

/// The pyramid search's own version, added to a method's: 1 since its coarse level ranks cells by
/// luma, a yellow-blue mean and the luma's spread and quilting re-scores its neighbours'
/// continuations (#32; it was 0 when the pyramid came). Jobs of the exact search keep the
/// method's version, their pixels unchanged.
pub(crate) const PYRAMID_VERSION: u32 = 1;

/// The algorithm version of patch sampling's syntheses from turned copies, whose pixels changed
/// in issue #28 while plain syntheses kept version 1 (2 is that with the pyramid); see its
/// `algorithm_version_of`.
pub(crate) const COPIES_VERSION: u32 = 3;

/// The algorithm version of quilting's and patch sampling's inpainting: 3 (issue #28) while the
/// hole's blocks were made in raster order, 9 since they are made from the hole's border inwards
/// (`inpaint::next_block`; 10 with the pyramid).
pub(crate) const INPAINT_VERSION: u32 = 9;

/// The algorithm version of quilting's and patch sampling's hole fills led by a luminance guide,
/// compared at a block's scale since issue #28's transfer statistics: 5 in raster order, 11 from
/// the border inwards (12 with the pyramid); a guide with its own `source` keeps the versions
/// above.
pub(crate) const LUMINANCE_GUIDE_VERSION: u32 = 11;

/// The algorithm version of quilting's and patch sampling's syntheses led by a luminance guide
/// (not hole fills) since their later passes follow the previous pass through the target instead
/// of pixel by pixel ([`crate::synth::constraints::Guide::after_pass`]; 8 with the pyramid). A
/// single pass makes the same pixels as version 5, but the passes are not among a method's
/// parameters, so every such synthesis says 7.
pub(crate) const LUMINANCE_TRANSFER_VERSION: u32 = 7;

/// The base version of a quilting or patch sampling output led by a luminance guide.
pub(crate) fn luminance_guide_version(uses: crate::synth::method::Uses) -> u32 {
    if uses.inpaint { LUMINANCE_GUIDE_VERSION } else { LUMINANCE_TRANSFER_VERSION }
}

/// A method's algorithm version for the [`Engine`] parameter `key` (resolved): its own, plus
/// [`PYRAMID_VERSION`] when the pyramid makes the pixels.
pub(crate) fn engine_version(params: &Params, key: &str, base: u32) -> u32 {
    match params.choice::<Engine>(key) {
        Ok(Engine::Pyramid) => base + PYRAMID_VERSION,
        _ => base,
    }
}

/// The peak memory of a square-block method searching with `engine` (resolved): the canvas (3 B
/// per output pixel, a block wider than the output at most), trimmed in place, and the search.
/// Measured (VmHWM of `texsyn run`, quilting, block 50): the exact FFT search holds about 130 B per
/// sample pixel (bricks_gray 256²; 2048² output: 42 MB, 4096²: 116 MB in all); the pyramid its
/// reduced levels (1 B per sample pixel) and the FFT search of a coarse level of at most
/// `COARSE_PIXELS`, whatever the sample (4000×3000 to 2048², measured by hand: 131 MB peak RSS
/// against an estimate of 207 MB). tests/it/memory.rs runs a 12 MP sample to 1024² within the
/// estimate's margin and plans a 24 MP one under a 512 MiB limit that refuses the exact search.
/// A pyramid that would not reduce the sample (`block`'s coarse level 0) is the exact search.
pub(crate) fn search_memory(engine: Engine, sample: (u32, u32), output: (u32, u32), block: u32) -> u64 {
    use crate::synth::method::linear_memory;
    match engine {
        Engine::Pyramid if pyramid_search::coarse_level(sample, block) > 0 => {
            let coarse = pyramid_search::COARSE_PIXELS;
            linear_memory(sample, output, 3.5, 2.0, (4 << 20) + 256 * coarse)
        }
        _ => linear_memory(sample, output, 3.5, 256.0, 4 << 20),
    }
}

/// What each thread adds to [`search_memory`] ([`Method::thread_memory`]): the exact search runs
/// blocks side by side, each with its own work arrays (spectra products, planes, the positions'
/// SSDs: about 40 B per sample pixel), kept per thread; the pyramid's coarse searches less.
/// Measured (peak RSS, `-j 16` against `-j 2`): quilting a 256² sample to 2048², 3.5 MiB a thread
/// (live heap 47 against 20 MB); a 12 MP photo to 1024² by the pyramid, 2.6 to 3.9 MiB.
pub(crate) fn search_thread_memory(engine: Engine, sample: (u32, u32), block: u32) -> u64 {
    match engine {
        Engine::Pyramid if pyramid_search::coarse_level(sample, block) > 0 => 4 << 20,
        _ => crate::synth::method::THREAD_MEMORY + 48 * u64::from(sample.0) * u64::from(sample.1),
    }
}

/// A block search over one sample, as its [`Engine`] says.
pub(crate) enum BlockSearch<'a> {
    /// The exact search, by direct sums (`Direct`) or by FFT (any other engine: `Pyramid` is a
    /// pyramid whose coarse level is the sample itself).
    Exact(OverlapSearch<'a>, Engine),
    /// The coarse-to-fine search, and the positions a sample mask allows (when there is one).
    Pyramid(PyramidSearch<'a>, Option<Allowed<'a>>),
}

/// The block positions a sample mask allows, for the pyramid: its full-resolution picks are
/// kept to them, and when none of its re-scored positions is allowed the block falls back to the
/// exact search of the allowed positions (rare: the coarse tracks are the best matches of the
/// whole sample, so a mask must forbid most good ones).
pub(crate) struct Allowed<'a> {
    flags: Vec<bool>,
    sample: &'a RgbImage,
    block: u32,
}

impl Allowed<'_> {
    fn allows(&self, x: u32, y: u32) -> bool {
        self.flags[(y * (self.sample.width() - self.block + 1) + x) as usize]
    }

    /// The tolerance set among the allowed positions of `pool`, or by the exact search of every
    /// allowed position when `pool` has none.
    fn candidates(
        &self,
        pool: Vec<(u32, u32, u64)>,
        canvas: &RgbImage,
        origin: (u32, u32),
        regions: &[Rect],
        tolerance: f64,
    ) -> Candidates {
        let pool: Vec<(u32, u32, u64)> = pool.into_iter().filter(|&(x, y, _)| self.allows(x, y)).collect();
        match pool.iter().map(|c| c.2).min() {
            Some(min) => {
                let members = pool.into_iter().filter(|c| (c.2 as f64) <= (1.0 + tolerance) * (min as f64)).collect();
                Candidates { min_ssd: min, members }
            }
            None => {
                let mut exact = OverlapSearch::new(self.sample, self.block, self.block);
                exact.restrict_to(self.flags.clone());
                exact.candidates(canvas, origin, regions, tolerance)
            }
        }
    }
}

impl<'a> BlockSearch<'a> {
    /// Prepares the search of `block × block` blocks of `sample` (`auto` resolved by its size).
    pub(crate) fn new(engine: Engine, sample: &'a RgbImage, block: u32) -> BlockSearch<'a> {
        match engine.for_sample(sample.dimensions()) {
            Engine::Pyramid if pyramid_search::coarse_level(sample.dimensions(), block) > 0 => {
                BlockSearch::Pyramid(PyramidSearch::new(sample, block), None)
            }
            // A pyramid that would not reduce the sample searches it whole: that is the exact FFT
            // search (same candidates, so the same pixels), kept as such so that a sample mask or
            // a hole's restriction does not turn it into direct sums at every position (a 512²
            // inpainting with `search = "pyramid"` took 7.5 s instead of 0.25 s).
            e => BlockSearch::Exact(OverlapSearch::new(sample, block, block), e),
        }
    }

    /// [`BlockSearch::new`], copying only from the block positions `allowed` flags (row-major; a
    /// sample mask's [`crate::synth::constraints::SampleMask::block_positions`]), when given.
    pub(crate) fn within(engine: Engine, sample: &'a RgbImage, block: u32, allowed: Option<Vec<bool>>) -> BlockSearch<'a> {
        let mut search = BlockSearch::new(engine, sample, block);
        if let Some(flags) = allowed {
            match &mut search {
                BlockSearch::Exact(s, _) => s.restrict_to(flags),
                BlockSearch::Pyramid(_, restriction) => *restriction = Some(Allowed { flags, sample, block }),
            }
        }
        search
    }

    /// The exact search of `block × block` blocks of the same sample, copying only from the
    /// positions `allowed` flags (at least one), sharing this search's spectra of the sample
    /// instead of transforming it again; `None` for the pyramid (which shares nothing).
    pub(crate) fn for_block(&self, block: u32, allowed: Vec<bool>) -> Option<BlockSearch<'a>> {
        match self {
            BlockSearch::Exact(s, e) => {
                let mut search = s.for_block(block, block);
                search.restrict_to(allowed);
                Some(BlockSearch::Exact(search, *e))
            }
            BlockSearch::Pyramid(..) => None,
        }
    }

    /// The tolerance set of the block at `origin` of `canvas`: the positions whose overlap error
    /// is within `(1 + tolerance)` of the best (for the pyramid, of those it re-scored).
    pub(crate) fn candidates(&mut self, canvas: &RgbImage, origin: (u32, u32), regions: &[Rect], tolerance: f64) -> Candidates {
        match self {
            BlockSearch::Exact(s, Engine::Direct) => s.candidates_direct(canvas, origin, regions, tolerance),
            BlockSearch::Exact(s, _) => s.candidates(canvas, origin, regions, tolerance),
            BlockSearch::Pyramid(p, None) => p.candidates(canvas, origin, regions, tolerance),
            BlockSearch::Pyramid(p, Some(a)) => {
                let pool = p.rescored(canvas, origin, regions, &[]);
                a.candidates(pool, canvas, origin, regions, tolerance)
            }
        }
    }

    /// [`BlockSearch::candidates_many`] where the pyramid also re-scores `hints[i]` for block `i`
    /// ([`PyramidSearch::candidates_many_hinted`]); the exact searches score every position anyway.
    pub(crate) fn candidates_many_hinted(
        &mut self,
        canvas: &RgbImage,
        queries: &[((u32, u32), Vec<Rect>)],
        hints: &[Vec<(u32, u32)>],
        tolerance: f64,
    ) -> Vec<Candidates> {
        match self {
            BlockSearch::Pyramid(p, None) => p.candidates_many_hinted(canvas, queries, hints, tolerance),
            BlockSearch::Pyramid(p, Some(a)) => queries
                .iter()
                .zip(hints)
                .map(|((o, r), h)| {
                    let pool = p.rescored(canvas, *o, r, h);
                    a.candidates(pool, canvas, *o, r, tolerance)
                })
                .collect(),
            _ => self.candidates_many(canvas, queries, tolerance),
        }
    }

    /// [`BlockSearch::candidates`] of several blocks against one canvas, in the order given.
    pub(crate) fn candidates_many(&mut self, canvas: &RgbImage, queries: &[((u32, u32), Vec<Rect>)], tolerance: f64) -> Vec<Candidates> {
        match self {
            BlockSearch::Exact(s, Engine::Direct) => queries.iter().map(|(o, r)| s.candidates_direct(canvas, *o, r, tolerance)).collect(),
            BlockSearch::Exact(s, _) => s.candidates_many(canvas, queries, tolerance),
            BlockSearch::Pyramid(p, None) => p.candidates_many(canvas, queries, tolerance),
            BlockSearch::Pyramid(..) => queries.iter().map(|(o, r)| self.candidates(canvas, *o, r, tolerance)).collect(),
        }
    }

    /// The pyramid's coarse level, for diagnostics (`None` for the exact search).
    pub(crate) fn coarse_level(&self) -> Option<u32> {
        match self {
            BlockSearch::Exact(_, Engine::Pyramid) => Some(0),
            BlockSearch::Exact(..) => None,
            BlockSearch::Pyramid(p, _) => Some(p.coarse_level()),
        }
    }
}

/// The square-block methods' default overlap, `round(block / 6)` and at least 1: the derived
/// default of their `overlap` parameter, and what a config's `overlap: None` means.
pub(crate) fn default_overlap(block: i64) -> i64 {
    ((block as f64) / 6.0).round().max(1.0) as i64
}

/// Reads a method's typed config in [`Method::check`]: a parameter that cannot be read becomes
/// the check's only error, naming its key.
pub(crate) fn read_config<C: MethodConfig>(p: &Params) -> Result<C, Vec<ParamError>> {
    C::from_params(p).map_err(|e| vec![e.into()])
}

/// The checks every square-block method shares: the block fits in the sample and the overlap
/// (real or virtual) is at most half the block.
pub(crate) fn check_block_and_overlap(block: u32, overlap: u32, sample: (u32, u32)) -> Vec<ParamError> {
    let mut errors = Vec::new();
    let smaller = sample.0.min(sample.1);
    if block > smaller {
        errors.push(ParamError::new(
            "block",
            format!("block {block} is larger than the sample ({}x{}); use at most {smaller}", sample.0, sample.1),
        ));
    }
    if overlap > block / 2 {
        errors.push(ParamError::new(
            "overlap",
            format!("overlap {overlap} is more than half the block ({block}); use at most {}", block / 2),
        ));
    }
    errors
}

/// Every available method, in listing order.
pub fn registry() -> &'static [&'static dyn Method] {
    &[
        &quilting::Quilting,
        &double_seam::DoubleSeam,
        &patch_sampling::PatchSampling,
        &near_regular::coevolution::Coevolution,
        &near_regular::tes::Tes,
        &tiles::wang_tiles::WangTiles,
        &tiles::rw_tiles::RwTiles,
    ]
}

/// The method called `name`.
pub fn find(name: &str) -> Option<&'static dyn Method> {
    registry().iter().copied().find(|m| m.name() == name)
}

/// The names of all methods, for error messages.
pub fn names() -> Vec<&'static str> {
    registry().iter().map(|m| m.name()).collect()
}

/// A block's tolerance set without the turned or mirrored copies of its neighbours' pixels
/// (several samples' atlas with `augment`: [`crate::synth::atlas::Atlas::twins`]); when every
/// member is one, the search is asked again with the tolerance widened by 0.25, 1 and 4, and
/// only when that finds no other position does the block keep its set.
#[allow(clippy::too_many_arguments)]
pub(crate) fn untwinned(
    req: &crate::synth::method::Request,
    search: &mut BlockSearch,
    target: &crate::image::RgbImage,
    origin: (u32, u32),
    regions: &[crate::synth::primitives::overlap::Rect],
    tolerance: f64,
    members: Vec<(u32, u32, u64)>,
    neighbours: &[(u32, u32)],
    block: u32,
) -> Vec<(u32, u32, u64)> {
    if let Some(kept) = req.constraints.without_twins(&members, neighbours, block) {
        return kept;
    }
    for wider in [0.25, 1.0, 4.0] {
        let c = search.candidates(target, origin, regions, tolerance + wider);
        if let Some(kept) = req.constraints.without_twins(&c.members, neighbours, block) {
            return kept;
        }
    }
    members
}

#[cfg(test)]
mod tests {
    use super::*;

    fn texture(w: u32, h: u32) -> RgbImage {
        RgbImage::from_fn(w, h, |x, y| {
            let v = (x * 37 + y * 91 + (x * y) % 53) as u8;
            [v, v.wrapping_mul(3), v ^ 0x5a]
        })
    }

    #[test]
    fn a_pyramid_that_would_not_reduce_the_sample_is_the_exact_fft_search() {
        // Also when positions are restricted (a hole, a sample mask): the pyramid's restricted
        // path scores every position by direct sums, 25× slower than the FFT on a 512² inpainting.
        let sample = texture(200, 160);
        let allowed = vec![true; (200 - 30 + 1) * (160 - 30 + 1)];
        for flags in [None, Some(allowed)] {
            let search = BlockSearch::within(Engine::Pyramid, &sample, 30, flags);
            assert!(matches!(search, BlockSearch::Exact(_, Engine::Pyramid)));
            assert_eq!(search.coarse_level(), Some(0), "recorded as the pyramid's level 0");
        }
        let big = texture(1200, 900);
        assert!(matches!(BlockSearch::new(Engine::Pyramid, &big, 40), BlockSearch::Pyramid(..)));
        assert!(matches!(BlockSearch::new(Engine::Auto, &big, 40), BlockSearch::Pyramid(..)));
        assert!(matches!(BlockSearch::new(Engine::Auto, &sample, 30), BlockSearch::Exact(_, Engine::Fft)));
    }

    #[test]
    fn the_memory_of_a_pyramid_at_full_resolution_is_the_exact_searchs() {
        let (small, out) = ((400, 300), (512, 512));
        assert_eq!(search_memory(Engine::Pyramid, small, out, 50), search_memory(Engine::Fft, small, out, 50));
        assert_eq!(search_thread_memory(Engine::Pyramid, small, 50), search_thread_memory(Engine::Fft, small, 50));
        let big = (4000, 3000);
        assert!(search_memory(Engine::Pyramid, big, out, 50) < search_memory(Engine::Fft, big, out, 50) / 10);
    }
}
