//! Tile interiors of their own on lattice-aligned tile sets (issue #30): with their defaults on a
//! brick wall, `wang-tiles` and `rw-tiles` align to the lattice and used to fill with a handful
//! of large tiles repeated (repetition 2–2.7 times quilting's); their interiors now come from
//! in-phase patches of their own.

use super::common::*;

fn repetition(sample: &Path, out: &Path) -> f64 {
    let o = run_ok(texsyn().arg("eval").arg(sample).arg(out).args(["--metrics", "repetition"]));
    let t = text(&o);
    let line = t.lines().find(|l| l.starts_with("repetition")).unwrap_or_else(|| panic!("no repetition in {t}"));
    line.split_whitespace().nth(1).unwrap().parse().unwrap()
}

/// Runs quilting and both tile methods with their defaults on `sample` at 512², seed 1: the tile
/// jobs' records and repetition, and quilting's repetition.
fn fills(tag: &str, sample: &Path, tile_params: &str) -> (Value, f64, Vec<(String, f64)>) {
    let dir = scratch(tag);
    for m in ["quilting", "wang-tiles", "rw-tiles"] {
        let params = if m == "quilting" { "" } else { tile_params };
        write(
            &dir.join("jobs").join(format!("{m}.toml")),
            &format!(
                "sample = {:?}\nmethod = \"{m}\"\nseed = 1\n[output]\npath = \"{m}.png\"\nwidth = 512\nheight = 512\n{params}",
                sample.display().to_string()
            ),
        );
    }
    let out = dir.join("out");
    run_ok(texsyn().arg("run").arg(dir.join("jobs")).arg("-o").arg(&out).arg("-q"));
    let q = repetition(sample, &out.join("quilting.png"));
    let tiles = ["wang-tiles", "rw-tiles"].iter().map(|m| (m.to_string(), repetition(sample, &out.join(format!("{m}.png"))))).collect();
    (manifest(&out), q, tiles)
}

/// An aligned RW set's patches of each class are distinct places of the sample.
fn distinct_patches(rw: &Value, what: &str) {
    let p = &rw["diagnostics"]["patches"];
    for class in ["a", "b"] {
        let c = p[class].as_array().unwrap();
        for i in 0..c.len() {
            for j in i + 1..c.len() {
                assert_ne!(c[i], c[j], "{what} rw-tiles: patches {class}[{i}] and {class}[{j}] are one ({p})");
            }
        }
    }
}

fn job<'a>(m: &'a Value, method: &str) -> &'a Value {
    m["jobs"].as_array().unwrap().iter().find(|j| j["method"] == method).unwrap()
}

/// On city_bricks the Wang tiles (128 px, two colours) now take in-phase interiors (repetition
/// was 1.96 times quilting's, now about 1.6); on stk_generic_brickRoad_a too (1.84 -> about
/// 0.95). RW tiles keep their edge patches with `interior = "auto"` on aligned sets (their
/// in-phase interiors chopped bricks, see `RwTiles::fill`), and with their defaults repeat at most
/// twice as much as quilting since their two "\" patches are two (version 5,
/// `Alignment::place_apart`; they were one patch drawn twice: city 2.23 -> 1.71 times quilting's,
/// brickRoad 2.67 -> 1.91); asked for with `interior = "own"`, brickRoad's are in phase and repeat
/// at most twice as much as quilting too.
#[test]
fn aligned_tiles_take_in_phase_interiors_and_repeat_at_most_twice_as_much_as_quilting() {
    let city = repo().join("tests/fixtures/structured/city_bricks.png");
    let (m, q, tiles) = fills("tile_interiors_city", &city, "");
    let wang = job(&m, "wang-tiles");
    assert!(wang["diagnostics"]["align_choice"].as_str().unwrap().starts_with("auto: lattice"), "{}", wang["diagnostics"]["align_choice"]);
    assert_eq!(wang["diagnostics"]["interior"]["interior"], "own", "{}", wang["diagnostics"]);
    assert!(
        wang["diagnostics"]["interior"]["how"].as_str().unwrap().contains("aligned to a lattice"),
        "{}",
        wang["diagnostics"]["interior"]
    );
    // Version 4 brought in-phase interiors; 5 (`tone = "auto"` may tone them) is every default's.
    assert_eq!(wang["algorithm_version"], 5);
    let w = tiles[0].1;
    eprintln!("city_bricks: wang-tiles {w:.3}, rw-tiles {:.3}, quilting {q:.3}", tiles[1].1);
    assert!(w <= 1.75 * q, "city_bricks wang-tiles: repetition {w:.3} against quilting's {q:.3}");
    let rw = job(&m, "rw-tiles");
    assert!(rw["diagnostics"].get("interior").is_none(), "city_bricks rw-tiles: edges under interior = auto");
    // Version 5 placed aligned patches apart; 6 (`tone = "auto"`) is every default's.
    assert_eq!(rw["algorithm_version"], 6);
    distinct_patches(rw, "city_bricks");
    let r = tiles[1].1;
    assert!(r <= 2.0 * q, "city_bricks rw-tiles: repetition {r:.3} against quilting's {q:.3}");

    let road = repo().join("tests/fixtures/structured/stk_generic_brickRoad_a.png");
    let (m, q, tiles) = fills("tile_interiors_road", &road, "");
    let d = &job(&m, "wang-tiles")["diagnostics"];
    assert_eq!(d["interior"]["interior"], "own", "{d}");
    let r = tiles[0].1;
    eprintln!("brickRoad wang-tiles: repetition {r:.3}, quilting {q:.3} ({:.2}x)", r / q);
    assert!(r <= 2.0 * q, "brickRoad wang-tiles: repetition {r:.3} against quilting's {q:.3}");
    let rw = job(&m, "rw-tiles");
    assert!(rw["diagnostics"].get("interior").is_none(), "brickRoad rw-tiles: edges under interior = auto");
    distinct_patches(rw, "brickRoad");
    let r = tiles[1].1;
    eprintln!("brickRoad rw-tiles: repetition {r:.3}, quilting {q:.3} ({:.2}x)", r / q);
    assert!(r <= 2.0 * q, "brickRoad rw-tiles: repetition {r:.3} against quilting's {q:.3}");
    let (m, q, tiles) = fills("tile_interiors_road_own", &road, "[params]\ninterior = \"own\"\n");
    let d = &job(&m, "rw-tiles")["diagnostics"];
    assert_eq!(d["interior"]["interior"], "own", "{d}");
    let r = tiles[1].1;
    eprintln!("brickRoad rw-tiles, interior = own: repetition {r:.3}, quilting {q:.3} ({:.2}x)", r / q);
    assert!(r <= 2.0 * q, "brickRoad rw-tiles with in-phase interiors: repetition {r:.3} against quilting's {q:.3}");
}
