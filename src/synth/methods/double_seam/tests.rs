//! Unit tests of double-seam: the scores against a direct computation, the bounds and the
//! FFT search against the exhaustive one, the torus and the parameters. Kept out of `mod.rs`,
//! which they outgrew (over a thousand lines).
use super::*;
use crate::synth::params::resolve;
use crate::synth::primitives::correlation::pearson;

fn params(given: &[(&str, ParamValue)]) -> Params {
    let g: Vec<(String, ParamValue)> = given.iter().map(|(k, v)| (k.to_string(), v.clone())).collect();
    resolve(PARAMS, &g).unwrap()
}

fn structured() -> RgbImage {
    RgbImage::from_fn(96, 96, |x, y| {
        let mortar = x % 24 < 3 || y % 16 < 3;
        let v = if mortar { 200 } else { 90 + ((x * 7 + y * 13) % 23) as u8 };
        [v, (v as u32 * 3 / 4) as u8, (v as u32 / 2) as u8]
    })
}

#[test]
fn output_size_determinism_and_verbatim_pixels() {
    let s = structured();
    let p = params(&[("block", ParamValue::Int(24))]);
    let req = Request {
        sample: &s,
        width: 100,
        height: 70,
        params: &p,
        seed: 2,
        placement: false,
        tileable: false,
        constraints: std::default::Default::default(),
    };
    let a = DoubleSeam.synthesize(&req).unwrap();
    assert_eq!(a.image.dimensions(), (100, 70));
    assert_eq!(a.image, DoubleSeam.synthesize(&req).unwrap().image);
    let colours: std::collections::HashSet<[u8; 3]> = s.as_raw().chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect();
    assert!(a.image.as_raw().chunks_exact(3).all(|p| colours.contains(&[p[0], p[1], p[2]])), "pasted without blending");
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let b = one.install(|| DoubleSeam.synthesize(&req).unwrap());
    assert_eq!(a.image, b.image, "thread count");
}

#[test]
fn scores_equal_a_direct_evaluation_of_the_formula() {
    // Recompute F for a few candidates straight from the definition (B8, eqs. 6–10).
    let sample = structured();
    let p =
        params(&[("block", ParamValue::Int(24)), ("clamp_negative", ParamValue::Bool(false)), ("level_penalty", ParamValue::Float(0.0))]);
    let s = Settings {
        block: 24,
        g: 4,
        a: -1,
        weights: [0.25, 0.25, 0.5],
        mu: 2.0,
        tau: 1.6,
        eps: 0.05,
        circular: false,
        clamp: false,
        level_penalty: 0.0,
    };
    assert_eq!(p.int("overlap").unwrap(), 4);
    assert_eq!(Settings::of(&DoubleSeamConfig::from_params(&p).unwrap()), s);
    let prep = Prepared::of(&sample);
    let mut out = Canvas::new(60, 60, (96, 96), false);
    out.paste(&prep, (10, 5), (0, 0), 0..24, 0..24);
    out.paste(&prep, (40, 30), (20, 0), 4..24, 0..24);
    out.paste(&prep, (3, 50), (0, 20), 0..24, 4..24);
    let case = Case::L;
    let ls = lines(case, 24, 4, -1);
    let stats = [candidate_stats(&prep, &s, case, &ls[0]), candidate_stats(&prep, &s, case, &ls[1])];
    let origin = (20, 20);
    let (positions, scores) = score_all(&prep, &s, case, &stats, &out, origin);
    for k in [0usize, 17, 500, positions.len() - 1] {
        let (x, y) = positions[k];
        let mut f = 0.0;
        for line in &ls {
            let o = |plane: &Vec<f64>| -> Vec<f64> {
                line.iter().map(|&(c, r)| plane[((origin.1 + r) * 60 + origin.0 + c) as usize]).collect()
            };
            let c = |plane: &Vec<f64>| -> Vec<f64> { line.iter().map(|&(cc, r)| plane[((y + r) * 96 + x + cc) as usize]).collect() };
            let d = 0.25 * pearson(&o(&out.h), &c(&prep.planes.h))
                + 0.25 * pearson(&o(&out.s), &c(&prep.planes.s))
                + 0.5 * pearson(&o(&out.i), &c(&prep.planes.i));
            let mism = line
                .iter()
                .filter(|&&(cc, r)| out.e[((origin.1 + r) * 60 + origin.0 + cc) as usize] != prep.edges[((y + r) * 96 + x + cc) as usize])
                .count();
            f += d / (1.0 + 2.0 * mism as f64 / line.len() as f64);
        }
        assert!((f - scores[k]).abs() < 1e-12, "candidate {k}: {f} vs {}", scores[k]);
    }
    // The natural continuation of a block scores F = 2 when its lines vary and edges agree.
    let mut out2 = Canvas::new(60, 60, (96, 96), false);
    out2.paste(&prep, (10, 10), (0, 0), 0..24, 0..24);
    let hz = Case::Horizontal;
    let lh = lines(hz, 24, 4, -1);
    let st = [candidate_stats(&prep, &s, hz, &lh[0]), candidate_stats(&prep, &s, hz, &lh[1])];
    let (pos, sc) = score_all(&prep, &s, hz, &st, &out2, (20, 0));
    let natural = pos.iter().position(|&p| p == (30, 10)).unwrap();
    assert!((sc[natural] - 2.0).abs() < 1e-9, "{}", sc[natural]);
}

#[test]
fn pruned_choice_equals_scoring_every_candidate() {
    // The bound-pruned choice against the exhaustive one: same pick, set size and F_max, bit
    // for bit, with hints that are natural continuations (so θ is high and most candidates
    // are pruned), with misleading hints and with none, across settings.
    let sample = structured();
    let prep = Prepared::of(&sample);
    let mut out = Canvas::new(60, 60, (96, 96), false);
    out.paste(&prep, (10, 5), (0, 0), 0..24, 0..24);
    out.paste(&prep, (30, 5), (20, 0), 4..24, 0..24);
    out.paste(&prep, (10, 25), (0, 20), 0..24, 4..24);
    let base = Settings {
        block: 24,
        g: 4,
        a: -1,
        weights: [0.25, 0.25, 0.5],
        mu: 2.0,
        tau: 1.6,
        eps: 0.05,
        circular: false,
        clamp: false,
        level_penalty: 0.0,
    };
    let variants = [
        Settings { ..base },
        Settings { clamp: true, ..base },
        Settings { level_penalty: 10.0, ..base },
        Settings { mu: 0.0, ..base },
        Settings { tau: 1.1, eps: 0.3, ..base },
        Settings { a: 1, mu: 5.0, ..base },
    ];
    for s in &variants {
        for (case, origin, natural) in
            [(Case::Horizontal, (20, 0), (30, 5)), (Case::L, (20, 20), (30, 25)), (Case::Vertical, (0, 20), (10, 25))]
        {
            let ls = lines(case, s.block, s.g, s.a);
            let stats = [candidate_stats(&prep, s, case, &ls[0]), candidate_stats(&prep, s, case, &ls[1])];
            let (positions, scores) = score_all(&prep, s, case, &stats, &out, origin);
            let shape = Shape::new(&prep, ls, admissible(&prep, s, case));
            for seed in [1u64, 2, 3] {
                let want = pick(s, &positions, &scores, seed, 1, 1).unwrap();
                for hints in [vec![natural], vec![(3, 60), natural], vec![(50, 50)], vec![]] {
                    let got = choose(&prep, s, &shape, &out, origin, &hints, (seed, 1, 1), None).unwrap();
                    assert_eq!(got.0, want.0, "{case:?} {s:?} {hints:?}");
                    assert_eq!(got.1, want.1);
                    assert_eq!(got.2.to_bits(), want.2.to_bits());
                }
            }
        }
    }
}

#[test]
fn pruned_choice_on_ring_lines_equals_scoring_every_candidate() {
    // Lines on three and on four sides of the pasted square, as a torus's blocks have them:
    // two columns and one or two rows per line, which the FFT bounds correlate group by group.
    let sample = structured();
    let prep = Prepared::of(&sample);
    let mut out = Canvas::new(60, 60, (96, 96), false);
    for (bi, bj) in [(0u32, 0u32), (0, 1), (0, 2), (1, 0), (1, 1), (1, 2), (2, 0), (2, 1), (2, 2)] {
        out.paste(&prep, (7 + 23 * bj + 5 * bi, 3 + 21 * bi + 7 * bj), (20 * bj, 20 * bi), 0..20, 0..20);
    }
    let base = Settings::of(&DoubleSeamConfig { block: 24, ..DoubleSeamConfig::default() });
    for s in [Settings { ..base }, Settings { clamp: true, ..base }, Settings { level_penalty: 10.0, ..base }] {
        let (b, g) = (s.block, s.g);
        for bottom in [false, true] {
            let ring = |d: i32| -> Vec<(i32, i32)> {
                let (lo, hi) = (g - 1 - d, b + d);
                let top = (lo..=hi).map(|c| (c, lo));
                let left = (lo + 1..hi).map(|r| (lo, r));
                let right = (lo + 1..hi).map(|r| (hi, r));
                let under = (lo..=hi).map(|c| (c, hi)).filter(|_| bottom);
                top.chain(left).chain(right).chain(under).collect()
            };
            let ls = [ring(0), ring(g - 1 - s.a)];
            let ranges = line_ranges(&prep, &s, &ls);
            let stats = [candidate_stats_in(&prep, &s, ranges.clone(), &ls[0]), candidate_stats_in(&prep, &s, ranges.clone(), &ls[1])];
            let origin = (20, 20);
            let (positions, scores) = score_lines(&prep, &s, &ls, ranges.clone(), &stats, &out, origin);
            let best = positions[(0..scores.len()).max_by(|&i, &j| scores[i].total_cmp(&scores[j])).unwrap()];
            let shape = Shape::new(&prep, ls.clone(), ranges);
            for seed in [1u64, 2, 3] {
                let want = pick(&s, &positions, &scores, seed, 1, 1).unwrap();
                for hints in [vec![], vec![(40, 40)], vec![best]] {
                    let got = choose(&prep, &s, &shape, &out, origin, &hints, (seed, 1, 1), None).unwrap();
                    assert_eq!(got.0, want.0, "{s:?} bottom {bottom} {hints:?}");
                    assert_eq!(got.1, want.1);
                    assert_eq!(got.2.to_bits(), want.2.to_bits());
                }
            }
        }
    }
}

#[test]
fn pruned_choice_on_an_odd_sized_sample_equals_scoring_every_candidate() {
    // Odd transform lengths along both axes: the spectra keep frequencies 0..=n/2 only and
    // the products mirror the others, which must hold without a Nyquist frequency too.
    let sample = RgbImage::from_fn(95, 97, |x, y| {
        let v = ((x * 7 + y * 13) % 23 * 9 + if x % 19 < 3 { 50 } else { 0 }) as u8;
        [v, v / 2 + (y % 5) as u8 * 9, 255 - v]
    });
    let prep = Prepared::of(&sample);
    let mut out = Canvas::new(60, 60, (95, 97), false);
    out.paste(&prep, (10, 5), (0, 0), 0..24, 0..24);
    out.paste(&prep, (30, 5), (20, 0), 4..24, 0..24);
    out.paste(&prep, (10, 25), (0, 20), 0..24, 4..24);
    let s = Settings::of(&DoubleSeamConfig { block: 24, ..DoubleSeamConfig::default() });
    for (case, origin) in [(Case::Horizontal, (20, 0)), (Case::L, (20, 20)), (Case::Vertical, (0, 20))] {
        let ls = lines(case, s.block, s.g, s.a);
        let stats = [candidate_stats(&prep, &s, case, &ls[0]), candidate_stats(&prep, &s, case, &ls[1])];
        let (positions, scores) = score_all(&prep, &s, case, &stats, &out, origin);
        let shape = Shape::new(&prep, ls, admissible(&prep, &s, case));
        for seed in [1u64, 2] {
            let want = pick(&s, &positions, &scores, seed, 1, 1).unwrap();
            for hints in [vec![], vec![(40, 40)]] {
                let got = choose(&prep, &s, &shape, &out, origin, &hints, (seed, 1, 1), None).unwrap();
                assert_eq!((got.0, got.1, got.2.to_bits()), (want.0, want.1, want.2.to_bits()), "{case:?} {hints:?}");
            }
        }
    }
}

#[test]
fn runs_cover_a_line_in_order() {
    for line in [
        lines(Case::L, 24, 4, -1)[0].clone(),
        lines(Case::L, 24, 4, -1)[1].clone(),
        lines(Case::Vertical, 10, 3, 1)[1].clone(),
        vec![(0, 0), (5, 5), (6, 5), (7, 5), (7, 6), (7, 7), (2, 9)],
    ] {
        let runs = runs_of(&line);
        let expanded: Vec<(i32, i32)> =
            runs.iter().flat_map(|r| (0..r.len).map(move |j| if r.horizontal { (r.c + j, r.r) } else { (r.c, r.r + j) })).collect();
        assert_eq!(expanded, line);
    }
    assert_eq!(runs_of(&lines(Case::L, 24, 4, -1)[0]).len(), 2);
}

#[test]
fn lazy_exact_statistics_and_bound_intervals_hold_the_exact_values() {
    // The per-candidate exact statistics must be candidate_stats' bits; the bounds' run-sum
    // statistics must hold them: the mean within a tiny error, 1/sqrt(sum of squares) inside
    // its interval, and every line that is flat or nearly so marked (the sample's mortar is flat).
    let sample = structured();
    let prep = Prepared::of(&sample);
    let s = Settings::of(&DoubleSeamConfig { block: 24, ..DoubleSeamConfig::default() });
    let mut flat_lines = 0;
    for case in [Case::Horizontal, Case::Vertical, Case::L] {
        let ls = lines(case, s.block, s.g, s.a);
        let ranges = admissible(&prep, &s, case);
        let exact = [candidate_stats(&prep, &s, case, &ls[0]), candidate_stats(&prep, &s, case, &ls[1])];
        let bounds = BoundStats::new(&prep, &ls, ranges.clone());
        let (x0, y0) = (*ranges.0.start(), *ranges.1.start());
        let nx = (ranges.0.end() - x0 + 1) as usize;
        for li in 0..2 {
            let offsets: Vec<isize> = ls[li].iter().map(|&(c, r)| (r * 96 + c) as isize).collect();
            assert_eq!(3 * exact[li].len(), bounds.lines[li].len());
            for (k, e) in exact[li].iter().enumerate() {
                let b: [f64; 3] = std::array::from_fn(|ch| bounds.inv_hi(li, k / nx, ch)[k % nx]);
                let base = ((y0 + (k / nx) as i32) * 96 + x0 + (k % nx) as i32) as isize;
                let [lazy] = exact_line_stats(&prep, &offsets, [base]);
                assert_eq!(lazy.map(f64::to_bits), e.map(f64::to_bits), "{case:?} line {li} candidate {k}");
                for ch in 0..3 {
                    let v = e[2 * ch + 1];
                    if b[ch] == f64::INFINITY {
                        flat_lines += 1;
                    } else {
                        assert!(v >= FLAT, "a flat line not marked");
                        let inv = 1.0 / v.sqrt();
                        assert!(b[ch] * (1.0 - INV_SPREAD) <= inv && inv <= b[ch], "{inv} {}", b[ch]);
                    }
                }
            }
        }
    }
    assert!(flat_lines > 0, "the test should meet flat lines");
}

#[test]
fn rejects_bad_weights_negative_mu_and_big_blocks() {
    let p = params(&[("alpha", ParamValue::Float(0.5)), ("block", ParamValue::Int(200))]);
    let errs = DoubleSeam.check(&p, (128, 128), (100, 100));
    let keys: Vec<&str> = errs.iter().map(|e| e.key.as_str()).collect();
    assert!(keys.contains(&"block") && keys.contains(&"alpha"), "{keys:?}");
    let g: Vec<(String, ParamValue)> = vec![("mu".into(), ParamValue::Float(-1.0))];
    assert!(resolve(PARAMS, &g).unwrap_err()[0].message.contains("out of range"));
}

#[test]
fn default_config_is_the_table_defaults() {
    let cfg = DoubleSeamConfig::default();
    assert_eq!(resolve(PARAMS, &cfg.to_params()).unwrap(), resolve(PARAMS, &[]).unwrap());
    let back = DoubleSeamConfig::from_params(&resolve(PARAMS, &[]).unwrap()).unwrap();
    assert_eq!(back, DoubleSeamConfig { overlap: Some(8), aux_dist: Some(8), ..cfg.clone() });
    assert_eq!(Settings::of(&back), Settings::of(&cfg));
}

#[test]
fn a_non_default_config_round_trips() {
    let cfg = DoubleSeamConfig {
        block: 40,
        overlap: Some(9),
        aux_dist: Some(6),
        alpha: 0.2,
        beta: 0.3,
        gamma: 0.4,
        mu: 1.5,
        tau_f: 1.2,
        eps_f: 0.1,
        hue_mode: HueMode::Circular,
        clamp_negative: true,
        level_penalty: 7.0,
    };
    let d = DoubleSeamConfig::default();
    assert!(cfg.block != d.block && cfg.overlap != d.overlap && cfg.aux_dist != d.aux_dist);
    assert!(cfg.alpha != d.alpha && cfg.beta != d.beta && cfg.gamma != d.gamma && cfg.mu != d.mu);
    assert!(cfg.tau_f != d.tau_f && cfg.eps_f != d.eps_f && cfg.hue_mode != d.hue_mode);
    assert!(cfg.clamp_negative != d.clamp_negative && cfg.level_penalty != d.level_penalty);
    let p = resolve(PARAMS, &cfg.to_params()).unwrap();
    assert_eq!(DoubleSeamConfig::from_params(&p).unwrap(), cfg);
    // aux_dist follows a given overlap when not set itself.
    let derived = DoubleSeamConfig { aux_dist: None, ..cfg };
    assert_eq!(resolve(PARAMS, &derived.to_params()).unwrap().int("aux_dist").unwrap(), 9);
    assert_eq!(derived.aux_dist_or_derived(), 9);
}

#[test]
fn an_unknown_word_is_an_error_naming_its_key() {
    let mut p = params(&[]);
    p.0.insert("hue_mode".into(), ParamValue::Str("polar".into()));
    let errs = DoubleSeam.check(&p, (128, 128), (100, 100));
    assert_eq!(errs.len(), 1);
    assert_eq!(errs[0].key, "hue_mode");
    let s = structured();
    let e = DoubleSeam
        .synthesize(&Request {
            sample: &s,
            width: 20,
            height: 20,
            params: &p,
            seed: 1,
            placement: false,
            tileable: false,
            constraints: std::default::Default::default(),
        })
        .unwrap_err();
    assert!(matches!(&e, SynthError::Param { key, .. } if key == "hue_mode"), "{e}");
}
