//! Tests of the metric layer (the building blocks are tested in their own files).

use super::*;
use crate::image::seam_grid::SeamBand;

fn noise(w: u32, h: u32, seed: u64) -> RgbImage {
    let mut s = seed;
    RgbImage::from_fn(w, h, |_, _| {
        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        let v = (s >> 40) as u32;
        [v as u8, (v >> 8) as u8, (v >> 16) as u8]
    })
}

/// A non-constant, structured test texture: bricks-like stripes plus a little noise.
fn texture(w: u32, h: u32, seed: u64) -> RgbImage {
    let n = noise(w, h, seed);
    RgbImage::from_fn(w, h, |x, y| {
        let base = if (x + 8 * ((y / 10) % 2)) % 16 < 2 || y % 10 == 0 { 60 } else { 170 };
        let jitter = n.get(x, y)[0] / 16;
        [base + jitter, base - 10 + jitter, base - 20 + jitter]
    })
}

fn gray_image(w: u32, h: u32, f: impl Fn(u32, u32) -> u8) -> RgbImage {
    RgbImage::from_fn(w, h, |x, y| {
        let v = f(x, y);
        [v, v, v]
    })
}

fn sinus(t: f64, period: f64) -> u8 {
    (128.0 + 100.0 * (2.0 * std::f64::consts::PI * t / period).sin()).round() as u8
}

fn argmax(v: &[f64]) -> usize {
    let mut best = 0;
    for (i, &x) in v.iter().enumerate() {
        if x > v[best] {
            best = i;
        }
    }
    best
}

const PAPER: [&str; 4] = ["kl_gray", "kl_orientation", "acf_gray", "acf_orientation"];

#[test]
fn identical_images_give_zero_for_the_paper_metrics() {
    let img = texture(70, 50, 1);
    let m = evaluate(&PAPER, &img, &img, None).unwrap();
    assert_eq!(m.len(), 4);
    for name in PAPER {
        assert_eq!(m[name], Some(0.0), "{name}");
    }
    // An independent copy too (no reliance on pointer identity).
    let copy = img.clone();
    assert_eq!(acf_gray(&img, &copy), Some(0.0));
    assert_eq!(acf_orientation(&img, &copy), Some(0.0));
}

#[test]
fn gray_shift_gives_the_analytic_kl() {
    // Sample: gray levels 100..=103 in equal shares; output: the same pattern on a larger canvas,
    // shifted up by one level, so P = ¼ on 100..=103 and Q = ¼ on 101..=104.
    // Only level 100 differs: D = ¼ · ln((¼ + ε)/ε); the three shared levels give ln 1 = 0.
    let sample = gray_image(16, 12, |x, _| 100 + (x % 4) as u8);
    let output = gray_image(40, 30, |x, y| 101 + ((x + y) % 4) as u8);
    let expect = 0.25 * ((0.25 + 1e-10) / 1e-10f64).ln();
    let got = kl_gray(&sample, &output).unwrap();
    assert!((got - expect).abs() < 1e-12, "{got} vs {expect}");
    // And the reverse direction: only level 104 of Q is missing from P, which does not count.
    let back = kl_gray(&output, &sample).unwrap();
    assert!((back - expect).abs() < 1e-12, "{back}");
    // Direction: P = ¼ on 100..=103, Q = ½ on 101..=102.
    // D(P‖Q) = 2·¼·ln((¼ + ε)/ε) + 2·¼·ln((¼ + ε)/(½ + ε)); D(Q‖P) = 2·½·ln((½ + ε)/(¼ + ε)).
    let narrow = gray_image(20, 10, |x, _| 101 + (x % 2) as u8);
    let eps = 1e-10f64;
    let pq = 0.5 * ((0.25 + eps) / eps).ln() + 0.5 * ((0.25 + eps) / (0.5 + eps)).ln();
    let qp = ((0.5 + eps) / (0.25 + eps)).ln();
    assert!((kl_gray(&sample, &narrow).unwrap() - pq).abs() < 1e-12);
    assert!((kl_gray(&narrow, &sample).unwrap() - qp).abs() < 1e-12);
    // Non-gray pixels use the rounded mean: (100, 101, 101) has s = 302 → level 101.
    assert_eq!(gray_level([100, 101, 101]), 101);
    assert_eq!(gray_level([100, 100, 101]), 100);
}

#[test]
fn grating_orientation_is_one_bin_and_moves_90_bins_when_rotated() {
    let params = MetricParams::default();
    assert_eq!(params.orientation_bins, 180);
    // Vertical stripes (intensity varies along x): gradient along x, O = 0° → bin 90.
    let vertical = gray_image(64, 48, |x, _| sinus(x as f64, 12.0));
    let hv = orientation_histogram(&vertical, &params);
    assert_eq!(hv[90], 1.0, "all pixels in bin 90");
    // Rotated by 90° (the transpose): O = 90° → bin 0 (= −90° wrapped).
    let horizontal = gray_image(48, 64, |x, y| vertical.get(y, x)[0]);
    let hh = orientation_histogram(&horizontal, &params);
    assert_eq!(hh[0], 1.0, "all pixels in bin 0");
    assert_eq!((argmax(&hv) + 90) % 180, argmax(&hh));
    // Diagonal gratings: ±45° → bins 135 and 45 (border pixels may stray).
    let diag = gray_image(64, 64, |x, y| sinus((x + y) as f64, 12.0));
    let anti = gray_image(64, 64, |x, y| sinus((x as f64) - (y as f64), 12.0));
    let hd = orientation_histogram(&diag, &params);
    let ha = orientation_histogram(&anti, &params);
    assert_eq!(argmax(&hd), 135);
    assert_eq!(argmax(&ha), 45);
    assert!(hd[135] > 0.6 && ha[45] > 0.6, "{} {}", hd[135], ha[45]);
    // KL between the two orthogonal gratings: one full bin against an empty one.
    let kl = kl_orientation(&vertical, &horizontal).unwrap();
    assert!((kl - ((1.0 + 1e-10) / 1e-10f64).ln()).abs() < 1e-9, "{kl}");
}

#[test]
fn periodic_image_has_a_periodic_gray_acf() {
    // Period 8 along x and 6 along y.
    let img = gray_image(96, 72, |x, y| {
        let a = sinus(x as f64, 8.0) as f64;
        let b = sinus(y as f64, 6.0) as f64;
        ((a + b) / 2.0).round() as u8
    });
    let c = gray_acf(&img, &MetricParams::default()).unwrap();
    assert_eq!((c.width(), c.height()), (33, 33));
    assert_eq!(c.get(0, 0), 1.0);
    for (dx, dy) in [(8, 0), (16, 0), (0, 6), (0, 12), (8, 6), (-16, 12)] {
        assert!(c.get(dx, dy) > 0.97, "({dx},{dy}) = {}", c.get(dx, dy));
    }
    assert!(c.get(4, 0) < 0.1 && c.get(0, 3) < 0.1);
    // A larger crop of the same periodic texture: the overlap-mean form keeps the two ACFs close
    // (what remains are partial-period edge effects of about 1/(W − |dx|), here ≈ 0.11 over 1089
    // offsets)...
    let sample = img.crop(0, 0, 64, 48);
    let d = acf_gray(&sample, &img).unwrap();
    assert!(d < 0.2, "{d}");
    // ...while the printed eq. 11 (`acf_raw`: un-centred, S/S(0,0)) depends on the image size
    // (≈ 2.7 here).
    let raw = MetricParams { acf_raw: true, ..MetricParams::default() };
    let d_raw = acf_gray_with(&sample, &img, &raw).unwrap();
    assert!(d_raw > 10.0 * d, "raw {d_raw} vs {d}");
}

#[test]
fn constant_image_is_undefined_not_a_panic() {
    let flat = gray_image(40, 40, |_, _| 77);
    let tex = texture(40, 40, 2);
    let all: Vec<&str> = METRIC_NAMES.to_vec();
    for (p, q) in [(&flat, &tex), (&tex, &flat), (&flat, &flat)] {
        let m = evaluate(&all, p, q, None).unwrap();
        assert_eq!(m["acf_gray"], None);
        assert_eq!(m["kl_orientation"], None);
        assert_eq!(m["seam_visibility"], None, "no grid");
        assert!(m["kl_gray"].is_some());
        assert!(m["acf_orientation"].is_some(), "V = 0 everywhere is still a defined ACF");
        assert!(m["verbatim"].is_some());
    }
    assert_eq!(acf_gray(&flat, &tex), None);
    assert_eq!(kl_orientation(&tex, &flat), None);
    // An image no larger than the offset radius has no 33 × 33 ACF.
    let tiny = texture(16, 40, 3);
    assert_eq!(acf_gray(&tiny, &tex), None);
    assert_eq!(acf_orientation(&tex, &tiny), None);
}

#[test]
fn exact_tiling_gives_near_zero_kl() {
    let sample = noise(40, 40, 4);
    let output = RgbImage::from_fn(120, 120, |x, y| sample.get(x % 40, y % 40));
    assert_eq!(kl_gray(&sample, &output), Some(0.0));
    let kl_o = kl_orientation(&sample, &output).unwrap();
    assert!(kl_o < 0.05, "{kl_o}");
    // 7 × 7 windows crossing a tile border are generally not in the sample.
    let v = verbatim(&sample, &output).unwrap();
    assert!(v > 0.1 && v < 0.9, "{v}");
}

#[test]
fn verbatim_and_seams_through_evaluate() {
    let sample = noise(64, 64, 5);
    let crop = sample.crop(7, 9, 40, 40);
    let m = evaluate(&["verbatim"], &sample, &crop, None).unwrap();
    assert_eq!(m["verbatim"], Some(1.0));
    let m = evaluate(&["verbatim"], &sample, &noise(50, 50, 6), None).unwrap();
    assert!(m["verbatim"].unwrap() < 1e-3);
    // A stepped image and a grid along the step.
    let stepped = gray_image(60, 40, |x, y| (x / 3 + y / 5) as u8 + if x >= 30 { 120 } else { 0 });
    let grid = SeamGrid { columns: vec![SeamBand { start: 29, len: 3 }], rows: vec![] };
    let m = evaluate(&["seam_visibility"], &sample, &stepped, Some(&grid)).unwrap();
    assert!(m["seam_visibility"].unwrap() > 10.0);
}

#[test]
fn unknown_name_is_an_error_listing_the_valid_names() {
    let img = texture(40, 40, 7);
    let err = evaluate(&["kl_gray", "psnr"], &img, &img, None).unwrap_err().to_string();
    assert!(err.contains("psnr"), "{err}");
    for name in METRIC_NAMES {
        assert!(err.contains(name), "{err} lacks {name}");
    }
    let bad = MetricParams { sigma: 0.0, ..MetricParams::default() };
    assert_eq!(
        evaluate_with(&["kl_gray"], &img, &img, None, &bad).unwrap_err(),
        MetricError::Parameter("sigma must be positive and finite, got 0".into())
    );
}

#[test]
fn results_do_not_depend_on_the_thread_count() {
    let sample = texture(64, 64, 8);
    let output = texture(90, 80, 9);
    let grid = SeamGrid { columns: vec![SeamBand { start: 30, len: 2 }], rows: vec![SeamBand { start: 40, len: 2 }] };
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| evaluate(METRIC_NAMES, &sample, &output, Some(&grid)).unwrap())
    };
    let one = run(1);
    let four = run(4);
    assert_eq!(one.len(), METRIC_NAMES.len());
    for name in METRIC_NAMES {
        let (a, b) = (one[*name], four[*name]);
        assert!(a.is_some(), "{name}");
        assert_eq!(a.map(f64::to_bits), b.map(f64::to_bits), "{name}");
    }
}

#[test]
fn params_round_trip_through_json() {
    let p = MetricParams::default();
    let json = serde_json::to_string(&p).unwrap();
    assert_eq!(serde_json::from_str::<MetricParams>(&json).unwrap(), p);
    let partial: MetricParams = serde_json::from_str(r#"{"acf_raw": true}"#).unwrap();
    assert!(partial.acf_raw && partial.acf_radius == 16);
    assert!(serde_json::from_str::<MetricParams>(r#"{"acf_radiuss": 3}"#).is_err());
}

#[test]
fn degenerate_sizes_do_not_panic() {
    let tex = texture(40, 40, 10);
    let grid = SeamGrid { columns: vec![SeamBand { start: 1, len: 4 }], rows: vec![SeamBand { start: 0, len: 9 }] };
    for (w, h) in [(0, 0), (1, 1), (3, 1), (1, 5), (7, 7)] {
        let small = texture(w, h, 11);
        for (p, q) in [(&small, &tex), (&tex, &small), (&small, &small)] {
            let m = evaluate(METRIC_NAMES, p, q, Some(&grid)).unwrap();
            assert_eq!(m.len(), METRIC_NAMES.len());
            assert_eq!(m["acf_gray"], None, "{w}x{h}");
            assert_eq!(m["acf_orientation"], None, "{w}x{h}");
        }
    }
    // Duplicate names give one entry.
    let m = evaluate(&["kl_gray", "kl_gray"], &tex, &tex, None).unwrap();
    assert_eq!(m.len(), 1);
}

#[test]
fn a_reference_reused_across_outputs_gives_what_the_standalone_metrics_give() {
    let sample = texture(64, 48, 3);
    // Outputs that share windows with the sample (a crop), and ones that do not; one is constant
    // (undefined gray ACF), one is too small for the verbatim window.
    let crop = RgbImage::from_fn(40, 30, |x, y| sample.get(x + 5, y + 7));
    let flat = gray_image(50, 50, |_, _| 90);
    let outputs = [texture(80, 80, 4), crop, flat, noise(70, 60, 9), noise(5, 5, 1)];
    let standalone: [(&str, fn(&RgbImage, &RgbImage) -> Option<f64>); 5] = [
        ("kl_gray", kl_gray),
        ("kl_orientation", kl_orientation),
        ("acf_gray", acf_gray),
        ("acf_orientation", acf_orientation),
        ("verbatim", verbatim),
    ];
    let reference = SampleReference::new(MetricParams::default());
    // Twice over the outputs, asking for the metrics in different orders, so later jobs read what
    // earlier ones left in the reference.
    for round in 0..2 {
        for (i, out) in outputs.iter().enumerate() {
            let mut names: Vec<&str> = standalone.iter().map(|s| s.0).collect();
            if (round + i) % 2 == 1 {
                names.reverse();
            }
            let got = evaluate_against(&names, &sample, &reference, out, None).unwrap();
            for (name, f) in standalone {
                assert_eq!(got[name].map(f64::to_bits), f(&sample, out).map(f64::to_bits), "{name}, output {i}, round {round}");
            }
        }
    }
    assert!(got_none_for_unknown(&reference, &sample));
}

fn got_none_for_unknown(reference: &SampleReference, sample: &RgbImage) -> bool {
    evaluate_against(&["nope"], sample, reference, sample, None).is_err()
}
