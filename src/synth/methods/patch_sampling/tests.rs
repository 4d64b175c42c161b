//! Patch sampling's unit tests: the paper's layout and defaults, the waves' order, the searches
//! against each other and against brute force, determinism across threads, the constraints
//! (mask, twins), and the configuration's round trip.

use super::exhaustive::zone_error;
use super::swarm::round_position;
use super::*;
use crate::synth::params::ParamValue;
use crate::synth::params::resolve;
use crate::synth::primitives::pso;

fn params(given: &[(&str, ParamValue)]) -> Params {
    let g: Vec<(String, ParamValue)> = given.iter().map(|(k, v)| (k.to_string(), v.clone())).collect();
    resolve(PARAMS, &g).unwrap()
}

fn noise(w: u32, h: u32, seed: u64) -> RgbImage {
    let mut s = Stream::new(seed, "test/noise");
    RgbImage::from_fn(w, h, |_, _| [s.below(256) as u8, s.below(256) as u8, s.below(256) as u8])
}

/// A smooth-ish texture with structure at several scales (the swarm has something to follow).
fn texture(w: u32, h: u32) -> RgbImage {
    RgbImage::from_fn(w, h, |x, y| {
        let v = ((x / 7 + y / 5) % 3) as u8 * 60 + ((x * 13 + y * 7) % 17) as u8 * 4 + (x % 11) as u8;
        [v, (v / 2).wrapping_add((y % 9) as u8 * 9), 200 - v / 2]
    })
}

fn run(sample: &RgbImage, w: u32, h: u32, p: &Params, seed: u64) -> Synthesis {
    PatchSampling
        .synthesize(&Request {
            sample,
            width: w,
            height: h,
            params: p,
            seed,
            placement: false,
            tileable: false,
            constraints: std::default::Default::default(),
        })
        .unwrap()
}

#[test]
fn continuations_find_the_exact_matches_the_swarm_misses_and_stay_off_by_default() {
    // A periodic sample (period 24 both ways, irregular within): every neighbour's
    // continuation is an exact match as long as it stays inside the sample.
    let mut st = Stream::new(5, "test/period");
    let cell: Vec<[u8; 3]> = (0..24 * 24).map(|_| [st.below(256) as u8, st.below(256) as u8, st.below(256) as u8]).collect();
    let sample = RgbImage::from_fn(120, 120, |x, y| cell[((y % 24) * 24 + x % 24) as usize]);
    let given =
        |c: bool| params(&[("block", ParamValue::Int(30)), ("iterations", ParamValue::Int(10)), ("continuations", ParamValue::Bool(c))]);
    let error = |s: &Synthesis| s.diagnostics["mean_rms_error"].as_f64().unwrap();
    let (off, on) = (run(&sample, 150, 150, &given(false), 3), run(&sample, 150, 150, &given(true), 3));
    // Not zero: a continuation that leaves the sample is not scored, and corner zones also meet
    // the other neighbour.
    assert!(error(&on) < 0.7 * error(&off), "continuations {} vs swarm alone {}", error(&on), error(&off));
    // The default is the paper's search: identical to asking for no continuations.
    assert_eq!(run(&sample, 150, 150, &params(&[("block", ParamValue::Int(30)), ("iterations", ParamValue::Int(10))]), 3).image, off.image);
}

#[test]
fn a_twin_stands_for_the_nearest_allowed_position_that_is_none() {
    use crate::synth::atlas::{Atlas, Augment};
    use crate::synth::constraints::Constraints;
    let block = 10;
    let atlas = Atlas::layout(&[(40, 30)], &[Augment::FlipH]);
    let (aw, ah) = atlas.dimensions();
    let (nx, ny) = (aw - block + 1, ah - block + 1);
    let mask = crate::synth::constraints::SampleMask::new(aw, ah, atlas.allowed(|_, _, _| true));
    let allowed = Allowed::new(mask.block_positions(block, block), nx);
    let constraints = Constraints { atlas: Some(&atlas), ..Constraints::default() };
    // The neighbour shows sample pixels 5..15 as they are; its mirror image starts at 14.
    let neighbour = atlas.position(0, None, 5, 5).unwrap();
    let twins = Twins::of(&constraints, vec![neighbour], block).expect("copies and a neighbour");
    assert!(Twins::of(&constraints, Vec::new(), block).is_none());
    let mirrored = atlas.position(0, Some(Augment::FlipH), 14, 5).unwrap();
    assert!(twins.is_twin(mirrored) && !twins.is_twin(neighbour));
    let mut resolved = 0;
    for y in 0..ny {
        for x in 0..nx {
            let p = allowed.nearest((x, y));
            let q = twins.resolve(p, (nx, ny), Some(&allowed));
            if !twins.is_twin(p) {
                assert_eq!(q, p);
                continue;
            }
            resolved += 1;
            assert!(allowed.allows(q) && !twins.is_twin(q), "{p:?} -> {q:?}");
            // Nothing nearer is allowed and no twin.
            let d = |a: (u32, u32), b: (u32, u32)| a.0.abs_diff(b.0) + a.1.abs_diff(b.1);
            for yy in 0..ny {
                for xx in 0..nx {
                    if d((xx, yy), p) < d(q, p) {
                        assert!(!allowed.allows((xx, yy)) || twins.is_twin((xx, yy)), "{p:?} -> {q:?}, but ({xx}, {yy}) is nearer");
                    }
                }
            }
        }
    }
    assert!(resolved > 0, "the test reaches twins");
}

#[test]
fn round_position_is_round_then_clamp() {
    let hi = [226.0, 100.0];
    let reference = |v: f64, h: f64| v.round().clamp(0.0, h) as u32;
    let mut values = vec![f64::NAN, f64::INFINITY, f64::NEG_INFINITY, -0.0, 0.0, -0.5, -0.49999999999999994, 0.49999999999999994];
    for k in -4..=240 {
        let v = f64::from(k);
        values.extend([v, v + 0.5, v - 0.5, v + 0.25, v + 0.5 - 1e-13, v + 0.5 + 1e-13, v.next_up(), v.next_down()]);
        values.extend([(v + 0.5).next_down(), (v + 0.5).next_up()]);
    }
    let mut s = Stream::new(1, "test/round");
    values.extend((0..10_000).map(|_| s.uniform_range(-3.0, 230.0)));
    for &a in &values {
        for &b in &values[..40] {
            assert_eq!(round_position(&[a, b], hi), (reference(a, hi[0]), reference(b, hi[1])), "({a}, {b})");
        }
    }
}

#[test]
fn paper_layout_and_defaults() {
    let p = params(&[]);
    let i = |k: &str| p.int(k).unwrap();
    let f = |k: &str| p.float(k).unwrap();
    assert_eq!((i("block"), i("overlap"), i("particles"), i("iterations")), (30, 5, 20, 300));
    assert_eq!((f("c1"), f("c2"), f("inertia"), f("vmax")), (1.47, 1.47, 0.729, 0.2));
    assert_eq!((f("distance_threshold"), f("variance_threshold")), (0.01, 0.001));
    assert_eq!((f("logistic_mu"), i("chaos_steps"), f("delta_rms")), (4.0, 200, 10.0));
    assert_eq!(p.str("search").unwrap(), "cpso");
    // 256 px with B = 30, w_E = 5 needs 11 × 11 blocks (§4.2 step 2).
    let l = BlockGrid::new(30, 5, 256, 256);
    assert_eq!((l.cols, l.rows), (11, 11));
    assert_eq!(l.canvas(), (280, 280));
}

#[test]
fn waves_cover_every_block_once_and_respect_dependencies() {
    let l = BlockGrid::new(30, 5, 200, 130);
    let waves = waves(&l);
    let mut seen = std::collections::HashMap::new();
    for (t, wave) in waves.iter().enumerate() {
        for &b in wave {
            assert!(seen.insert(b, t).is_none());
        }
    }
    assert_eq!(seen.len(), (l.rows * l.cols) as usize);
    for (&(bi, bj), &t) in &seen {
        // Every earlier block that overlaps this one is in an earlier wave.
        for (di, dj) in [(-1i64, -1i64), (-1, 0), (-1, 1), (0, -1)] {
            let (i, j) = (bi as i64 + di, bj as i64 + dj);
            if let Some(&u) = (i >= 0 && j >= 0).then(|| seen.get(&(i as u32, j as u32))).flatten() {
                assert!(u < t, "({i},{j}) must precede ({bi},{bj})");
            }
        }
    }
}

#[test]
fn output_size_determinism_and_seed_dependence() {
    let s = texture(80, 70);
    for search in Search::NAMES {
        let p = params(&[("block", ParamValue::Int(16)), ("search", ParamValue::Str(search.to_string()))]);
        let a = run(&s, 75, 50, &p, 3);
        assert_eq!(a.image.dimensions(), (75, 50));
        assert_eq!(a.image, run(&s, 75, 50, &p, 3).image, "{search}");
        assert_eq!(a.diagnostics, run(&s, 75, 50, &p, 3).diagnostics, "{search}");
        assert_ne!(a.image, run(&s, 75, 50, &p, 4).image, "{search}");
    }
}

#[test]
fn pixels_do_not_depend_on_the_thread_count() {
    let s = texture(90, 90);
    for (search, blend) in [("cpso", "feather"), ("pso", "feather"), ("exhaustive", "feather"), ("cpso", "cut"), ("exhaustive", "cut")] {
        let p = params(&[
            ("block", ParamValue::Int(18)),
            ("search", ParamValue::Str(search.to_string())),
            ("blend", ParamValue::Str(blend.to_string())),
            ("diagnostics", ParamValue::Bool(true)),
        ]);
        let runs: Vec<Synthesis> = [1, 2, 5]
            .iter()
            .map(|&n| rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap().install(|| run(&s, 120, 100, &p, 9)))
            .collect();
        for r in &runs[1..] {
            assert_eq!(r.image, runs[0].image, "{search}");
            assert_eq!(r.diagnostics, runs[0].diagnostics, "{search}");
        }
    }
}

/// The wave schedule gives exactly the raster-order result: replay the recorded choices in
/// raster order and compare.
#[test]
fn waves_equal_raster_order() {
    let s = texture(90, 90);
    let p = params(&[("block", ParamValue::Int(20)), ("search", ParamValue::Str("pso".into())), ("diagnostics", ParamValue::Bool(true))]);
    let out = run(&s, 130, 110, &p, 2);
    let l = BlockGrid::new(20, 3, 130, 110);
    let mut canvas = Canvas::new(l.canvas().0, l.canvas().1, s.dimensions(), false);
    let d = &out.diagnostics;
    let first = (d["first"]["x"].as_u64().unwrap() as u32, d["first"]["y"].as_u64().unwrap() as u32);
    paste_block(&mut canvas, &s, first, (0, 0), 20, 3, false, false, OverlapRule::Feather);
    for b in d["per_block"].as_array().unwrap() {
        let g = |k: &str| b[k].as_u64().unwrap() as u32;
        let (bi, bj) = (g("bi"), g("bj"));
        let dst = (bj * l.stride(), bi * l.stride());
        // The recorded error is the zone error against the raster-order canvas.
        assert_eq!(zone_error(&s, &canvas.image, (g("x"), g("y")), dst, &l.overlap_regions(bi, bj)), b["error"].as_u64().unwrap());
        paste_block(&mut canvas, &s, (g("x"), g("y")), dst, 20, 3, bj > 0, bi > 0, OverlapRule::Feather);
    }
    assert_eq!(canvas.image.crop(0, 0, 130, 110), out.image);
}

#[test]
fn exhaustive_finds_a_unique_perfect_match() {
    // Noise has a unique perfect continuation of the first block: the block one stride to its
    // right in the sample. Exhaustive search must find it with d = 0.
    let s = noise(60, 40, 4);
    let p = params(&[
        ("block", ParamValue::Int(12)),
        ("overlap", ParamValue::Int(3)),
        ("search", ParamValue::Str("exhaustive".into())),
        ("tolerance", ParamValue::Float(0.0)),
        ("first_x", ParamValue::Int(5)),
        ("first_y", ParamValue::Int(7)),
        ("record_optimum", ParamValue::Bool(true)),
    ]);
    let out = run(&s, 21, 12, &p, 1);
    let b = &out.diagnostics["per_block"][0];
    assert_eq!((b["x"].as_u64(), b["y"].as_u64()), (Some(5 + 9), Some(7)));
    assert_eq!(b["error"].as_u64(), Some(0));
    assert_eq!(b["optimum"].as_u64(), Some(0));
    assert_eq!(b["candidates"].as_u64(), Some(1));
    // The output is the sample itself there.
    assert_eq!(out.image, s.crop(5, 7, 21, 12));
}

#[test]
fn liang_candidates_follow_the_relative_rule() {
    let s = texture(64, 64);
    let p = |eps: f64| {
        params(&[
            ("block", ParamValue::Int(16)),
            ("search", ParamValue::Str("exhaustive".into())),
            ("tolerance", ParamValue::Float(eps)),
            ("diagnostics", ParamValue::Bool(true)),
        ])
    };
    let best = run(&s, 60, 60, &p(0.0), 1);
    let liang = run(&s, 60, 60, &p(0.3), 1);
    // Every Liang pick is within the bound, and the bound admits more than one patch somewhere.
    let blocks = liang.diagnostics["per_block"].as_array().unwrap();
    assert!(blocks.iter().any(|b| b["candidates"].as_u64().unwrap() > 1));
    for b in blocks {
        assert!(b["error"].as_u64() >= b["optimum"].as_u64());
    }
    assert_ne!(best.image, liang.image);
}

#[test]
fn direct_engine_equals_fft_engine_for_every_rule() {
    let s = texture(64, 64);
    for (rule, eps) in [("liang", 0.0), ("liang", 0.3), ("liang", 0.05), ("near-best", 0.2)] {
        let p = |engine: &str| {
            params(&[
                ("block", ParamValue::Int(16)),
                ("search", ParamValue::Str("exhaustive".into())),
                ("candidates", ParamValue::Str(rule.into())),
                ("tolerance", ParamValue::Float(eps)),
                ("engine", ParamValue::Str(engine.into())),
                ("diagnostics", ParamValue::Bool(true)),
            ])
        };
        let a = run(&s, 70, 60, &p("fft"), 2);
        let b = run(&s, 70, 60, &p("direct"), 2);
        assert_eq!(a.image, b.image, "{rule} {eps}");
        assert_eq!(a.diagnostics, b.diagnostics, "{rule} {eps}");
    }
}

#[test]
fn near_best_candidates_are_within_the_relative_tolerance() {
    let s = texture(64, 64);
    let p = params(&[
        ("block", ParamValue::Int(16)),
        ("search", ParamValue::Str("exhaustive".into())),
        ("candidates", ParamValue::Str("near-best".into())),
        ("tolerance", ParamValue::Float(0.5)),
        ("record_optimum", ParamValue::Bool(true)),
    ]);
    let out = run(&s, 70, 60, &p, 2);
    for b in out.diagnostics["per_block"].as_array().unwrap() {
        let (e, o) = (b["error"].as_u64().unwrap() as f64, b["optimum"].as_u64().unwrap() as f64);
        assert!(e >= o && e <= 1.5 * o, "{b}");
        assert!(b["candidates"].as_u64().unwrap() >= 1);
    }
}

#[test]
fn a_cut_paste_copies_sample_pixels_only() {
    let s = texture(64, 64);
    let colours: std::collections::HashSet<[u8; 3]> =
        (0..64).flat_map(|y| (0..64).map(move |x| (x, y))).map(|(x, y)| s.get(x, y)).collect();
    let p = params(&[("block", ParamValue::Int(16)), ("blend", ParamValue::Str("cut".into()))]);
    let out = run(&s, 70, 60, &p, 2).image;
    for y in 0..60 {
        for x in 0..70 {
            assert!(colours.contains(&out.get(x, y)), "({x},{y})");
        }
    }
}

#[test]
fn polish_never_makes_a_block_worse() {
    let s = texture(80, 80);
    let p = params(&[
        ("block", ParamValue::Int(16)),
        ("search", ParamValue::Str("pso".into())),
        ("iterations", ParamValue::Int(5)),
        ("polish_radius", ParamValue::Int(3)),
        ("diagnostics", ParamValue::Bool(true)),
    ]);
    let out = run(&s, 60, 60, &p, 2);
    let blocks = out.diagnostics["per_block"].as_array().unwrap();
    assert!(blocks.iter().all(|b| b["error"].as_u64() <= b["swarm_error"].as_u64()));
    assert!(blocks.iter().any(|b| b["error"].as_u64() < b["swarm_error"].as_u64()));
}

#[test]
fn swarm_diagnostics_are_consistent() {
    let s = texture(100, 100);
    let p = params(&[
        ("block", ParamValue::Int(20)),
        ("search", ParamValue::Str("cpso".into())),
        ("delta_rms", ParamValue::Float(0.0)),
        ("iterations", ParamValue::Int(60)),
        ("record_optimum", ParamValue::Bool(true)),
    ]);
    let out = run(&s, 60, 60, &p, 5);
    let d = &out.diagnostics;
    assert_eq!(d["search"], "cpso");
    for b in d["per_block"].as_array().unwrap() {
        assert_eq!(b["iterations"].as_u64(), Some(60), "no early stop with delta_rms = 0");
        assert!(b["best_iteration"].as_u64().unwrap() <= 60);
        assert!(b["error"].as_u64().unwrap() >= b["optimum"].as_u64().unwrap());
        assert!(!b["stopped_early"].as_bool().unwrap());
    }
}

#[test]
fn pso_and_cpso_blocks_coincide_until_a_chaos_search() {
    // Same streams: with the test unable to fire, CPSO's output is PSO's.
    let s = texture(90, 90);
    let base = [("block", ParamValue::Int(18)), ("diagnostics", ParamValue::Bool(true))];
    let mut pso = base.to_vec();
    pso.push(("search", ParamValue::Str("pso".into())));
    let mut cpso = base.to_vec();
    cpso.push(("search", ParamValue::Str("cpso".into())));
    cpso.push(("distance_threshold", ParamValue::Float(0.0)));
    let a = run(&s, 100, 100, &params(&pso), 8);
    let b = run(&s, 100, 100, &params(&cpso), 8);
    assert_eq!(a.image, b.image);
    assert_eq!(a.diagnostics["per_block"], b.diagnostics["per_block"]);
}

#[test]
fn bad_parameters_name_their_key() {
    let p = params(&[("block", ParamValue::Int(80)), ("overlap", ParamValue::Int(50))]);
    let keys: Vec<String> = PatchSampling.check(&p, (64, 64), (100, 100)).into_iter().map(|e| e.key).collect();
    assert_eq!(keys, vec!["block", "overlap"]);
    let p = params(&[("vmax", ParamValue::Float(0.0)), ("first_x", ParamValue::Int(300))]);
    let errs = PatchSampling.check(&p, (256, 256), (100, 100));
    let keys: Vec<&str> = errs.iter().map(|e| e.key.as_str()).collect();
    assert_eq!(keys, vec!["vmax", "first_y", "first_x"]);
    assert!(errs[2].message.contains("0..=226"), "{}", errs[2].message);
    // Particle count 0 is refused by the range with the key named.
    let g = vec![("particles".to_string(), ParamValue::Int(0))];
    let e = resolve(PARAMS, &g).unwrap_err();
    assert_eq!(e[0].key, "particles");
    assert!(e[0].message.contains("1..="), "{}", e[0].message);
    // Exhaustive does not need a moving swarm.
    let p = params(&[("vmax", ParamValue::Float(0.0)), ("search", ParamValue::Str("exhaustive".into()))]);
    assert!(PatchSampling.check(&p, (64, 64), (100, 100)).is_empty());
}

#[test]
fn default_config_is_the_table_defaults() {
    let cfg = PatchSamplingConfig::default();
    assert_eq!(resolve(PARAMS, &cfg.to_params()).unwrap(), resolve(PARAMS, &[]).unwrap());
    let back = PatchSamplingConfig::from_params(&resolve(PARAMS, &[]).unwrap()).unwrap();
    assert_eq!(back, PatchSamplingConfig { overlap: Some(5), ..cfg });
}

#[test]
fn a_non_default_config_round_trips() {
    let cfg = PatchSamplingConfig {
        block: 24,
        overlap: Some(6),
        search: Search::Pso,
        swarm: SwarmConfig {
            particles: 30,
            iterations: 150,
            c1: 2.0,
            c2: 1.2,
            inertia: 0.5,
            vmax: 0.3,
            update: Update::Asynchronous,
            delta_rms: 0.0,
            polish_radius: 2,
            continuations: true,
        },
        chaos: ChaosConfig {
            distance_threshold: 0.02,
            variance_threshold: 0.5,
            logistic_mu: 3.9,
            chaos_steps: 50,
            rediversify: Rediversify::None,
        },
        exhaustive: ExhaustiveConfig { tolerance: 0.0, candidates: CandidateRule::NearBest, engine: Engine::Direct },
        blend: Blend::Cut,
        first_x: Some(3),
        first_y: Some(0),
        diagnostics: true,
        record_optimum: true,
    };
    // Every job-file parameter is given and differs from its default.
    let given = cfg.to_params();
    let defaults = resolve(PARAMS, &[]).unwrap();
    assert_eq!(given.len(), PARAMS.len());
    for (k, v) in &given {
        assert_ne!(defaults.get(k), Some(v), "{k} keeps its default");
    }
    let p = resolve(PARAMS, &given).unwrap();
    assert_eq!(PatchSamplingConfig::from_params(&p).unwrap(), cfg);
    let s = Settings::of(&cfg);
    assert_eq!(s.swarm.update, pso::UpdateOrder::Asynchronous);
    assert!(s.swarm.chaos.is_none(), "pso has no chaos part");
    assert_eq!(
        Settings::of(&PatchSamplingConfig { search: Search::Cpso, ..cfg.clone() }).swarm.chaos.unwrap().rediversify,
        pso::Rediversify::None
    );
    assert_eq!((s.blend, s.first), (OverlapRule::Cut, Some((3, 0))));
}

#[test]
fn an_unknown_word_is_an_error_naming_its_key() {
    let mut p = params(&[]);
    p.0.insert("search".into(), ParamValue::Str("genetic".into()));
    let errs = PatchSampling.check(&p, (64, 64), (100, 100));
    assert_eq!(errs.len(), 1);
    assert_eq!(errs[0].key, "search");
    let s = texture(64, 64);
    let e = PatchSampling
        .synthesize(&Request {
            sample: &s,
            width: 40,
            height: 40,
            params: &p,
            seed: 1,
            placement: false,
            tileable: false,
            constraints: std::default::Default::default(),
        })
        .unwrap_err();
    assert!(matches!(&e, SynthError::Param { key, .. } if key == "search"), "{e}");
}
