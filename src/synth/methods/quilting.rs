//! Efros–Freeman image quilting with the minimum-error boundary cut (methods.md §6): the
//! baseline every paper we follow compares against.
//!
//! Blocks are laid in raster order at stride `block − overlap`. Each new block is chosen at random
//! among the sample positions whose overlap error is within `(1 + tolerance)` of the best, found by
//! an exhaustive exact search (`primitives::overlap_search`), and pasted along the minimum-error
//! cut through the overlap (B3). The output is the top-left `width × height` of the quilt, so the
//! last row and column of blocks are cropped.

use crate::synth::error::SynthError;
use crate::synth::method::{Method, Request, Synthesis};
use crate::synth::params::{Default, ParamError, ParamKind, ParamSpec, ParamValue, Params};
use crate::synth::primitives::block_grid::{BlockGrid, OverlapRule, paste_block};
use crate::synth::primitives::overlap_search::OverlapSearch;
use crate::synth::rng::Stream;
use crate::image::RgbImage;

pub struct Quilting;

const PARAMS: &[ParamSpec] = &[
    ParamSpec {
        name: "block",
        kind: ParamKind::Int { min: 3, max: 4096 },
        default: Default::Int(50),
        doc: "side of the square blocks, in pixels (at most the sample's smaller side)",
    },
    ParamSpec {
        name: "overlap",
        kind: ParamKind::Int { min: 1, max: 2048 },
        default: Default::Derived {
            rule: "round(block / 6)",
            compute: |p| Some(ParamValue::Int(((p.int("block").ok()? as f64) / 6.0).round().max(1.0) as i64)),
        },
        doc: "width of the overlap between neighbouring blocks (at most block / 2)",
    },
    ParamSpec {
        name: "tolerance",
        kind: ParamKind::Float { min: 0.0, max: 100.0 },
        default: Default::Float(0.1),
        doc: "candidates within (1 + tolerance) x the best overlap error; one is picked at random",
    },
    ParamSpec {
        name: "search",
        kind: ParamKind::Choice(&["fft", "direct"]),
        default: Default::Str("fft"),
        doc: "how the exact exhaustive search is computed: fft (FFT correlation + exact re-check) or direct sums; same pixels",
    },
    ParamSpec {
        name: "cut",
        kind: ParamKind::Choice(&["dp", "none"]),
        default: Default::Str("dp"),
        doc: "dp: minimum-error boundary cut; none: paste the whole block over the overlap",
    },
    ParamSpec {
        name: "blend",
        kind: ParamKind::Choice(&["none", "feather"]),
        default: Default::Str("none"),
        doc: "feather: linear blend across the overlap (Liang et al.) instead of a cut; needs cut = \"none\"",
    },
];

impl Method for Quilting {
    fn name(&self) -> &'static str {
        "quilting"
    }
    fn algorithm_version(&self) -> u32 {
        1
    }
    fn summary(&self) -> &'static str {
        "Efros-Freeman image quilting: exact exhaustive block search, minimum-error boundary cut"
    }
    fn params(&self) -> &'static [ParamSpec] {
        PARAMS
    }

    fn check(&self, p: &Params, sample: (u32, u32), _output: (u32, u32)) -> Vec<ParamError> {
        let mut errors = super::check_block_and_overlap(p.int_unchecked("block"), p.int_unchecked("overlap"), sample);
        if p.str_unchecked("blend") == "feather" && p.str_unchecked("cut") != "none" {
            errors.push(ParamError::new("blend", "blend = \"feather\" replaces the boundary cut; also set cut = \"none\""));
        }
        errors
    }

    fn synthesize(&self, req: &Request) -> Result<Synthesis, SynthError> {
        let block = req.params.int_unchecked("block") as u32;
        let overlap = req.params.int_unchecked("overlap") as u32;
        let tolerance = req.params.float_unchecked("tolerance");
        let rule = if req.params.str_unchecked("blend") == "feather" {
            OverlapRule::Feather
        } else if req.params.str_unchecked("cut") == "dp" {
            OverlapRule::Cut
        } else {
            OverlapRule::Overwrite
        };
        let direct = req.params.str_unchecked("search") == "direct";
        let sample = req.sample;
        if block > sample.width() || block > sample.height() {
            return Err(SynthError::Failed(format!("block {block} does not fit in the {}x{} sample", sample.width(), sample.height())));
        }
        let layout = BlockGrid::new(block, overlap, req.width, req.height);
        let (cw, ch) = layout.canvas();
        let mut canvas = RgbImage::new(cw, ch);
        let mut search = OverlapSearch::new(sample, block, block);
        let mut candidate_counts = Vec::with_capacity((layout.rows * layout.cols) as usize);

        for bi in 0..layout.rows {
            for bj in 0..layout.cols {
                let (ox, oy) = layout.origin(bi, bj);
                let (sx, sy) = if bi == 0 && bj == 0 {
                    let mut s = Stream::new(req.seed, "quilt/first");
                    let x = s.below((sample.width() - block + 1) as u64) as u32;
                    let y = s.below((sample.height() - block + 1) as u64) as u32;
                    (x, y)
                } else {
                    let regions = layout.overlap_regions(bi, bj);
                    let c = if direct {
                        search.candidates_direct(&canvas, (ox, oy), &regions, tolerance)
                    } else {
                        search.candidates(&canvas, (ox, oy), &regions, tolerance)
                    };
                    candidate_counts.push(c.members.len());
                    let mut s = Stream::new(req.seed, &format!("quilt/pick/bi={bi}/bj={bj}"));
                    let pick = c.members[s.below_usize(c.members.len())];
                    (pick.0, pick.1)
                };
                paste_block(&mut canvas, sample, (sx, sy), (ox, oy), block, overlap, bj > 0, bi > 0, rule);
            }
        }
        let image = canvas.crop(0, 0, req.width, req.height);
        let seams = layout.seam_grid(req.width, req.height);
        let diagnostics = serde_json::json!({
            "blocks": { "cols": layout.cols, "rows": layout.rows },
            "mean_candidates": if candidate_counts.is_empty() { 0.0 } else {
                candidate_counts.iter().sum::<usize>() as f64 / candidate_counts.len() as f64
            },
        });
        Ok(Synthesis { image, seams: Some(seams), diagnostics, phases: Vec::new(), extras: Vec::new() })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::params::resolve;

    fn params(given: &[(&str, ParamValue)]) -> Params {
        let g: Vec<(String, ParamValue)> = given.iter().map(|(k, v)| (k.to_string(), v.clone())).collect();
        resolve(PARAMS, &g).unwrap()
    }

    fn sample() -> RgbImage {
        RgbImage::from_fn(64, 64, |x, y| {
            let v = ((x / 8 + y / 8) % 2) as u8 * 120 + ((x * 7 + y * 3) % 13) as u8 * 5;
            [v, v / 2 + 20, 255 - v]
        })
    }

    #[test]
    fn output_has_the_requested_size_and_is_deterministic() {
        let s = sample();
        let p = params(&[("block", ParamValue::Int(16)), ("overlap", ParamValue::Int(4))]);
        let req = Request { sample: &s, width: 70, height: 45, params: &p, seed: 3 };
        let a = Quilting.synthesize(&req).unwrap();
        let b = Quilting.synthesize(&req).unwrap();
        assert_eq!(a.image.dimensions(), (70, 45));
        assert_eq!(a.image, b.image);
        let other = Quilting.synthesize(&Request { seed: 4, ..req }).unwrap();
        assert_ne!(a.image, other.image);
    }

    #[test]
    fn fft_and_direct_search_give_the_same_pixels() {
        let s = sample();
        let fft = params(&[("block", ParamValue::Int(18)), ("tolerance", ParamValue::Float(0.3))]);
        let direct = params(&[("block", ParamValue::Int(18)), ("tolerance", ParamValue::Float(0.3)), ("search", ParamValue::Str("direct".into()))]);
        let a = Quilting.synthesize(&Request { sample: &s, width: 80, height: 80, params: &fft, seed: 9 }).unwrap();
        let b = Quilting.synthesize(&Request { sample: &s, width: 80, height: 80, params: &direct, seed: 9 }).unwrap();
        assert_eq!(a.image, b.image);
    }

    #[test]
    fn every_output_pixel_comes_from_the_sample_without_blending() {
        let s = sample();
        let colours: std::collections::HashSet<[u8; 3]> = (0..64).flat_map(|y| (0..64).map(move |x| (x, y))).map(|(x, y)| s.get(x, y)).collect();
        let p = params(&[("block", ParamValue::Int(20))]);
        let out = Quilting.synthesize(&Request { sample: &s, width: 90, height: 90, params: &p, seed: 1 }).unwrap();
        for y in 0..90 {
            for x in 0..90 {
                assert!(colours.contains(&out.image.get(x, y)), "pixel ({x},{y}) is not a sample colour");
            }
        }
    }

    #[test]
    fn a_periodic_sample_is_continued_seamlessly() {
        // A texture with period 8 in both directions: with tolerance 0 every block must continue
        // the pattern exactly, so the output is itself periodic.
        let s = RgbImage::from_fn(48, 48, |x, y| [(x % 8 * 30) as u8, (y % 8 * 30) as u8, ((x + y) % 8 * 20) as u8]);
        let p = params(&[("block", ParamValue::Int(16)), ("overlap", ParamValue::Int(4)), ("tolerance", ParamValue::Float(0.0))]);
        let out = Quilting.synthesize(&Request { sample: &s, width: 60, height: 60, params: &p, seed: 5 }).unwrap().image;
        for y in 0..52 {
            for x in 0..52 {
                assert_eq!(out.get(x, y), out.get(x + 8, y + 8), "({x},{y})");
            }
        }
    }

    #[test]
    fn rejects_blocks_larger_than_the_sample_and_wide_overlaps() {
        let p = params(&[("block", ParamValue::Int(80)), ("overlap", ParamValue::Int(50))]);
        let errs = Quilting.check(&p, (64, 64), (100, 100));
        let keys: Vec<&str> = errs.iter().map(|e| e.key.as_str()).collect();
        assert_eq!(keys, vec!["block", "overlap"]);
        assert!(errs[0].message.contains("larger than the sample"));
    }

}
