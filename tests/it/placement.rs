//! Every method's placement is exact: rendered over the 8-bit sample it gives the method's own
//! image, pixel for pixel (so companions and native-precision outputs rendered from it are the
//! same composition, not an approximation). Run on real samples, defaults and the variants that
//! blend (feathering), since blends are where a placement could drift.

use crate::common::{repo, rgb};
use texsyn::ParamValue;
use texsyn::synth::method::{Method, Request};
use texsyn::synth::methods;
use texsyn::synth::params::resolve;

fn check(method: &str, sample: &str, size: (u32, u32), given: &[(&str, ParamValue)]) -> bool {
    check_at(method, sample, size, given, false)
}

/// [`check`], of a tileable output or not; whether the placement blends.
fn check_at(method: &str, sample: &str, size: (u32, u32), given: &[(&str, ParamValue)], tileable: bool) -> bool {
    let m: &dyn Method = methods::find(method).unwrap();
    let s = rgb(&repo().join("jobs/samples").join(sample));
    let given: Vec<(String, ParamValue)> = given.iter().map(|(k, v)| (k.to_string(), v.clone())).collect();
    let params = resolve(m.params(), &given).unwrap();
    let plain = Request {
        sample: &s,
        width: size.0,
        height: size.1,
        params: &params,
        seed: 5,
        placement: false,
        tileable,
        constraints: Default::default(),
    };
    let without = m.synthesize(&plain).unwrap();
    assert!(without.placement.is_none(), "{method}: a placement nobody asked for");
    let with = m.synthesize(&Request { placement: true, ..plain }).unwrap();
    assert_eq!(with.image, without.image, "{method} {given:?}: asking for the placement changed the pixels");
    let p = with.placement.as_ref().unwrap_or_else(|| panic!("{method}: no placement"));
    assert_eq!(p.dimensions(), size);
    assert_eq!(p.sample_size(), s.dimensions());
    let rendered = p.render_rgb8(&s);
    let differing = rendered.as_raw().chunks(3).zip(with.image.as_raw().chunks(3)).filter(|(a, b)| a != b).count();
    assert_eq!(differing, 0, "{method} {given:?} on {sample}: {differing} pixels differ from the placement's rendering");
    p.has_blends()
}

#[test]
fn quilting_placement_renders_its_image() {
    check("quilting", "crops/pebbles_beige_128.png", (150, 130), &[]);
    check(
        "quilting",
        "crops/grass_gray_128.png",
        (150, 130),
        &[("cut", ParamValue::Str("none".into())), ("blend", ParamValue::Str("feather".into()))],
    );
}

#[test]
fn patch_sampling_placement_renders_its_image() {
    check("patch-sampling", "crops/hedge_leaves_128.png", (120, 110), &[]);
    check("patch-sampling", "crops/hedge_leaves_128.png", (120, 110), &[("blend", ParamValue::Str("cut".into()))]);
}

#[test]
fn double_seam_placement_renders_its_image() {
    check("double-seam", "crops/pebbles_beige_128.png", (140, 120), &[("block", ParamValue::Int(32))]);
}

#[test]
fn near_regular_placements_render_their_images() {
    check("coevolution", "tiles_terracotta.png", (300, 260), &[]);
    check("tes", "tiles_terracotta.png", (300, 260), &[]);
}

#[test]
fn tile_placements_render_their_images() {
    check("wang-tiles", "bricks_gray.png", (300, 260), &[]);
    check("rw-tiles", "bricks_gray.png", (300, 260), &[]);
}

/// Toned interiors (`tone`) are blend steps with sample pixels: the placement still renders the
/// method's image exactly, also where a tileable output is fitted from a torus of whole tiles.
#[test]
fn toned_tile_placements_render_their_images() {
    let on = ("tone", ParamValue::Str("on".into()));
    assert!(check("wang-tiles", "wood_weathered.png", (300, 260), std::slice::from_ref(&on)), "toned pixels are blends");
    assert!(check("rw-tiles", "wood_weathered.png", (300, 260), std::slice::from_ref(&on)));
    assert!(check("rw-tiles", "grass_gray.png", (200, 180), &[on.clone(), ("colors", ParamValue::Int(3))]));
    assert!(check_at("wang-tiles", "wood_weathered.png", (300, 260), std::slice::from_ref(&on), true));
    assert!(check_at("rw-tiles", "wood_weathered.png", (300, 260), &[on], true));
}
