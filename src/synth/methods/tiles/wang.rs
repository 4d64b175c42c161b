//! Wang-tile edge colours and stochastic scanline tiling (Cohen et al. 2003; docs/methods.md B12).
//!
//! A tile carries four edge colours `[a, b, c, d]`: `a` and `b` are its *incoming* edges (shared
//! with the tile before it in the row direction and in the column direction), `c` and `d` its
//! *outgoing* edges. On a grid of tiles `(r, col)`, tile `(r, col)`'s `a` equals the `c` of tile
//! `(r − 1, col)` and its `b` equals the `d` of tile `(r, col − 1)`. The Cohen baseline uses
//! `[N, W, S, E]` on rows and columns; RW-Tiles use `[NW, NE, SE, SW]` on the rhombus lattice
//! `(i, j)` (docs/methods.md §3.5–3.6).
//!
//! An output that wraps (`Request::tileable`) is tiled on a torus instead ([`Torus`],
//! [`tile_torus`]): the same colour rule, with the positions a period apart being one tile.

use crate::synth::rng::Stream;

crate::choice! {
    /// Which tiles exist for `K` colours per edge class (the `tile_set` parameter of both tile
    /// methods, and an export's `tile_set`); with `K` itself, an [`EdgeSet`].
    pub enum TileSet {
        /// The `K³` tiles with `a + b ≡ c + d (mod K)`: for each incoming pair `(a, b)` one tile per
        /// outgoing `c`, with `d = a + b − c`. Index `(a·K + b)·K + c`. For `K = 2` this is the
        /// 8-tile parity set `a ⊕ b ⊕ c ⊕ d = 0` (index `a·4 + b·2 + c`).
        Minimal = "minimal",
        /// All `K⁴` colourings; index `((a·K + b)·K + c)·K + d` (for `K = 2`, `a·8 + b·4 + c·2 + d`).
        Complete = "complete",
    }
}

impl TileSet {
    /// This rule with `colors` colours per edge class.
    pub fn with_colors(self, colors: u8) -> EdgeSet {
        assert!(colors >= 2, "at least two colours per edge class");
        EdgeSet { rule: self, colors }
    }
}

/// The tiles of a set: its rule ([`TileSet`]) and the number `K` of colours per edge class (the
/// `colors` parameter). More colours are what keeps a fill from repeating: two tiles a tile
/// apart show the same patch across an edge only when their colours there agree, about once in
/// `K` (with `K = 2`, half the edges of a fill are copies of one patch).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EdgeSet {
    pub rule: TileSet,
    pub colors: u8,
}

/// The set of paper 001: two colours.
impl From<TileSet> for EdgeSet {
    fn from(rule: TileSet) -> EdgeSet {
        rule.with_colors(2)
    }
}

impl EdgeSet {
    pub fn len(&self) -> usize {
        let k = self.colors as usize;
        match self.rule {
            TileSet::Minimal => k * k * k,
            TileSet::Complete => k * k * k * k,
        }
    }

    pub fn is_empty(&self) -> bool {
        false
    }

    /// The colours `[a, b, c, d]` of tile `index`.
    pub fn colours(&self, index: usize) -> [u8; 4] {
        let k = self.colors as usize;
        let digit = |place: u32| (index / k.pow(place) % k) as u8;
        match self.rule {
            TileSet::Minimal => {
                let (a, b, c) = (digit(2), digit(1), digit(0));
                [a, b, c, ((a as usize + b as usize + k - c as usize) % k) as u8]
            }
            TileSet::Complete => [digit(3), digit(2), digit(1), digit(0)],
        }
    }

    /// The index of the tile with colours `[a, b, c, d]` (for the minimal set they must satisfy
    /// its rule).
    pub fn index(&self, [a, b, c, d]: [u8; 4]) -> usize {
        let k = self.colors as usize;
        let (a, b, c, d) = (a as usize, b as usize, c as usize, d as usize);
        match self.rule {
            TileSet::Minimal => {
                assert_eq!((a + b) % k, (c + d) % k, "colours {:?} are not a minimal-set tile", [a, b, c, d]);
                (a * k + b) * k + c
            }
            TileSet::Complete => ((a * k + b) * k + c) * k + d,
        }
    }

    /// Picks uniformly (one `below(n)`) among the `n` tiles, in index order, whose colours agree
    /// with every fixed colour. Both rules always have a match when at most two colours are fixed.
    /// Only the free colours are enumerated (in index order: the index is lexicographic in
    /// `[a, b, c, d]`), so a choice costs `K` or `K²` steps, not one per tile of the set.
    pub fn choose(&self, fixed: [Option<u8>; 4], stream: &mut Stream) -> usize {
        let k = self.colors;
        let range = |e: usize| fixed[e].map_or(0..k, |f| f..f + 1);
        let mut matching = Vec::new();
        for a in range(0) {
            for b in range(1) {
                for c in range(2) {
                    match self.rule {
                        TileSet::Minimal => {
                            let d = ((u32::from(a) + u32::from(b) + u32::from(k) - u32::from(c)) % u32::from(k)) as u8;
                            if fixed[3].is_none_or(|f| f == d) {
                                matching.push(self.index([a, b, c, d]));
                            }
                        }
                        TileSet::Complete => matching.extend(range(3).map(|d| self.index([a, b, c, d]))),
                    }
                }
            }
        }
        assert!(!matching.is_empty(), "no tile matches {fixed:?}");
        matching[stream.below_usize(matching.len())]
    }
}

crate::choice! {
    /// How tile choices are keyed to random streams (the `tiling` parameter of both tile methods,
    /// and an export's `tiling`).
    pub enum TilingOrder {
        /// Keyed by position: row `r` draws from `label/r={r}` for columns `anchor, anchor+1, …` and
        /// from `label/r={r}/back` for `anchor−1, anchor−2, …`, so a tile's choice depends only on
        /// the tiles between it and the anchor column and above it: any range containing it (with the
        /// same first row and containing the anchor column) gives the same tile.
        Keyed = "keyed",
        /// Methods.md as written: one stream `label`, rows outer, columns inner, over the whole
        /// requested range; a tile's choice depends on the range (so on the output size).
        Scanline = "scanline",
    }
}

/// A rectangle of placed tiles: rows `r0 .. r0 + rows`, columns `c0 .. c0 + cols`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Tiling {
    pub r0: i64,
    pub c0: i64,
    pub rows: usize,
    pub cols: usize,
    /// Tile indices, row-major.
    pub tiles: Vec<u16>,
}

impl Tiling {
    /// The tile at `(r, c)`, which must be inside the rectangle.
    #[inline]
    pub fn at(&self, r: i64, c: i64) -> usize {
        let (dr, dc) = ((r - self.r0) as usize, (c - self.c0) as usize);
        debug_assert!(dr < self.rows && dc < self.cols, "({r},{c}) outside the tiling");
        self.tiles[dr * self.cols + dc] as usize
    }

    /// Number of shared edges whose two colours differ (0 for a valid tiling).
    pub fn violations(&self, set: EdgeSet) -> usize {
        let mut bad = 0;
        for dr in 0..self.rows {
            for dc in 0..self.cols {
                let me = set.colours(self.tiles[dr * self.cols + dc] as usize);
                if dr > 0 && set.colours(self.tiles[(dr - 1) * self.cols + dc] as usize)[2] != me[0] {
                    bad += 1;
                }
                if dc > 0 && set.colours(self.tiles[dr * self.cols + dc - 1] as usize)[3] != me[1] {
                    bad += 1;
                }
            }
        }
        bad
    }

    /// How often each tile is used.
    pub fn usage(&self, set: EdgeSet) -> Vec<usize> {
        let mut u = vec![0; set.len()];
        for &t in &self.tiles {
            u[t as usize] += 1;
        }
        u
    }
}

/// Stochastic scanline tiling (B12) of rows `r0..=r1` × columns `c0..=c1`. In keyed order,
/// `anchor` is the column each row starts from (it must lie in `c0..=c1`).
pub fn tile_rect(
    set: EdgeSet,
    order: TilingOrder,
    (r0, r1): (i64, i64),
    (c0, c1): (i64, i64),
    anchor: i64,
    seed: u64,
    label: &str,
) -> Tiling {
    assert!(r0 <= r1 && c0 <= c1, "empty tiling range");
    let rows = (r1 - r0 + 1) as usize;
    let cols = (c1 - c0 + 1) as usize;
    let mut tiles = vec![0u16; rows * cols];
    const UNSET: u16 = u16::MAX;
    match order {
        TilingOrder::Scanline => {
            let mut stream = Stream::new(seed, label);
            for dr in 0..rows {
                for dc in 0..cols {
                    let a = (dr > 0).then(|| set.colours(tiles[(dr - 1) * cols + dc] as usize)[2]);
                    let b = (dc > 0).then(|| set.colours(tiles[dr * cols + dc - 1] as usize)[3]);
                    tiles[dr * cols + dc] = set.choose([a, b, None, None], &mut stream) as u16;
                }
            }
        }
        TilingOrder::Keyed => {
            assert!((c0..=c1).contains(&anchor), "anchor column {anchor} outside {c0}..={c1}");
            tiles.fill(UNSET);
            let start = (anchor - c0) as usize;
            for dr in 0..rows {
                let r = r0 + dr as i64;
                let above = |tiles: &[u16], dc: usize| (dr > 0).then(|| set.colours(tiles[(dr - 1) * cols + dc] as usize)[2]);
                let mut fwd = Stream::new(seed, &format!("{label}/r={r}"));
                for dc in start..cols {
                    let b = (dc > start).then(|| set.colours(tiles[dr * cols + dc - 1] as usize)[3]);
                    tiles[dr * cols + dc] = set.choose([above(&tiles, dc), b, None, None], &mut fwd) as u16;
                }
                let mut back = Stream::new(seed, &format!("{label}/r={r}/back"));
                for dc in (0..start).rev() {
                    // The tile to the right is placed: its incoming `b` fixes my outgoing `d`.
                    let d = Some(set.colours(tiles[dr * cols + dc + 1] as usize)[1]);
                    tiles[dr * cols + dc] = set.choose([above(&tiles, dc), None, None, d], &mut back) as u16;
                }
            }
        }
    }
    Tiling { r0, c0, rows, cols, tiles }
}

/// The tile positions `(r, c)` modulo a lattice of periods: the tiles of an output that wraps.
/// Held in Hermite normal form, periods `(a, b)` and `(0, d)`, so that every position has one
/// representative `(r', c')` with `0 ≤ r' < a`, `0 ≤ c' < d` (class `r'·d + c'`). Wang tiles wrap
/// on a rectangle of `rows × cols`; RW tiles on the sheared lattice their output periods map to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Torus {
    a: i64,
    b: i64,
    d: i64,
}

impl Torus {
    /// The positions modulo the lattice spanned by `v1` and `v2` (which must be independent).
    pub fn new(v1: (i64, i64), v2: (i64, i64)) -> Torus {
        // Extended Euclid on the first coordinates: x·v1 + y·v2 = (g, ·) and a combination with
        // first coordinate 0 span the same lattice as v1, v2.
        let (mut r0, mut r1, mut x0, mut x1, mut y0, mut y1) = (v1.0, v2.0, 1i64, 0i64, 0i64, 1i64);
        while r1 != 0 {
            let q = r0.div_euclid(r1);
            (r0, r1) = (r1, r0 - q * r1);
            (x0, x1) = (x1, x0 - q * x1);
            (y0, y1) = (y1, y0 - q * y1);
        }
        let sign = if r0 < 0 { -1 } else { 1 };
        let (g, x, y) = (r0 * sign, x0 * sign, y0 * sign);
        assert!(g > 0, "periods {v1:?}, {v2:?} leave the rows unbounded");
        let d = ((v2.0 / g) * v1.1 - (v1.0 / g) * v2.1).abs();
        assert!(d > 0, "periods {v1:?}, {v2:?} are parallel");
        Torus { a: g, b: (x * v1.1 + y * v2.1).rem_euclid(d), d }
    }

    /// How many distinct tile positions (the lattice's index).
    pub fn len(&self) -> usize {
        (self.a * self.d) as usize
    }

    pub fn is_empty(&self) -> bool {
        false
    }

    /// The class of position `(r, c)`, in `0..len()`.
    #[inline]
    pub fn class(&self, r: i64, c: i64) -> usize {
        let k = r.div_euclid(self.a);
        ((r - k * self.a) * self.d + (c - k * self.b).rem_euclid(self.d)) as usize
    }

    /// The representative position of class `k`.
    fn position(&self, k: usize) -> (i64, i64) {
        (k as i64 / self.d, k as i64 % self.d)
    }
}

/// A tiling of rows `r0..=r1` × columns `c0..=c1` that is periodic on `torus`, so an output cut
/// from it wraps: every tile edge, the ones across the periods included, joins equal colours.
///
/// Instead of placing tiles (a scanline on a torus closes on tiles whose four colours are all
/// fixed, which the minimal set cannot always match), the colours of the torus's edges are drawn
/// from stream `label` and each tile is the one with its four edge colours. `south[k]` is the edge
/// below class `k` (its `c`, the `a` of the tile a row down), `east[k]` the one to its right (its
/// `d`, the next column's `b`). The complete set takes any colours. The minimal set needs
/// `a + b ≡ c + d (mod K)` at every tile: the colours are a circulation of the tile graph with
/// values in `Z_K` (what flows in flows out), so they are a random combination (coefficients
/// drawn in `0..K`) of the 4-cycles around tile corners and of the two loops along rows and
/// columns, which span every circulation. For `K = 2` this is a random sum of those cycles.
pub fn tile_torus(set: EdgeSet, torus: &Torus, (r0, r1): (i64, i64), (c0, c1): (i64, i64), seed: u64, label: &str) -> Tiling {
    assert!(r0 <= r1 && c0 <= c1, "empty tiling range");
    let n = torus.len();
    let k = u64::from(set.colors);
    let add = |edge: &mut u8, m: u64| *edge = ((u64::from(*edge) + m) % k) as u8;
    let mut stream = Stream::new(seed, label);
    let (mut south, mut east) = (vec![0u8; n], vec![0u8; n]);
    match set.rule {
        TileSet::Complete => {
            for i in 0..n {
                south[i] = stream.below(k) as u8;
                east[i] = stream.below(k) as u8;
            }
        }
        TileSet::Minimal => {
            for i in 0..n {
                let m = stream.below(k);
                if m != 0 {
                    // `m` down then right from tile `(r, c)`, and back along right then down.
                    let (r, c) = torus.position(i);
                    add(&mut south[i], m);
                    add(&mut east[torus.class(r + 1, c)], m);
                    add(&mut south[torus.class(r, c + 1)], k - m);
                    add(&mut east[i], k - m);
                }
            }
            for (step, edges) in [((1, 0), &mut south), ((0, 1), &mut east)] {
                let m = stream.below(k);
                if m != 0 {
                    let mut p = (0i64, 0i64);
                    loop {
                        add(&mut edges[torus.class(p.0, p.1)], m);
                        p = (p.0 + step.0, p.1 + step.1);
                        if torus.class(p.0, p.1) == 0 {
                            break;
                        }
                    }
                }
            }
        }
    }
    let (rows, cols) = ((r1 - r0 + 1) as usize, (c1 - c0 + 1) as usize);
    let mut tiles = Vec::with_capacity(rows * cols);
    for r in r0..=r1 {
        for c in c0..=c1 {
            let i = torus.class(r, c);
            tiles.push(set.index([south[torus.class(r - 1, c)], east[torus.class(r, c - 1)], south[i], east[i]]) as u16);
        }
    }
    Tiling { r0, c0, rows, cols, tiles }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tile_sets_follow_the_parity_rule_and_index_order() {
        let m = TileSet::Minimal.with_colors(2);
        for t in 0..8 {
            let [a, b, c, d] = m.colours(t);
            assert_eq!(a ^ b ^ c ^ d, 0);
            assert_eq!(t, (a * 4 + b * 2 + c) as usize);
        }
        // For each incoming pair exactly two tiles, with outgoing (0, a⊕b) and (1, 1⊕a⊕b).
        assert_eq!(m.colours(0b110), [1, 1, 0, 0]);
        assert_eq!(m.colours(0b111), [1, 1, 1, 1]);
        let c = TileSet::Complete.with_colors(2);
        let all: std::collections::HashSet<[u8; 4]> = (0..16).map(|t| c.colours(t)).collect();
        assert_eq!(all.len(), 16);
        assert_eq!(c.colours(0b1011), [1, 0, 1, 1]);
    }

    #[test]
    fn choose_counts_match_b12() {
        // k = 2, 4, 8 (minimal) and 4, 8, 16 (complete) with 2, 1, 0 incoming colours fixed:
        // check through the distribution of choices over many streams.
        for (set, fixed, k) in [
            (TileSet::Minimal.with_colors(2), [Some(1), Some(0), None, None], 2),
            (TileSet::Minimal.with_colors(2), [None, Some(1), None, None], 4),
            (TileSet::Minimal.with_colors(2), [None, None, None, None], 8),
            (TileSet::Complete.with_colors(2), [Some(0), Some(1), None, None], 4),
            (TileSet::Complete.with_colors(2), [Some(0), None, None, None], 8),
            (TileSet::Complete.with_colors(2), [None, None, None, None], 16),
            (TileSet::Minimal.with_colors(2), [Some(1), None, None, Some(0)], 2),
        ] {
            let mut seen = std::collections::HashSet::new();
            let mut s = Stream::new(3, "test/choose");
            for _ in 0..400 {
                let t = set.choose(fixed, &mut s);
                let c = set.colours(t);
                assert!((0..4).all(|e| fixed[e].is_none_or(|f| f == c[e])));
                seen.insert(t);
            }
            assert_eq!(seen.len(), k, "{set:?} {fixed:?}");
        }
    }

    #[test]
    fn tilings_never_violate_an_edge_colour() {
        for set in [TileSet::Minimal.with_colors(2), TileSet::Complete.with_colors(2)] {
            for order in [TilingOrder::Scanline, TilingOrder::Keyed] {
                for seed in 0..5 {
                    let t = tile_rect(set, order, (-3, 17), (-9, 12), 0, seed, "test/tiling");
                    assert_eq!(t.violations(set), 0, "{set:?} {order:?} seed {seed}");
                    assert!(t.usage(set).iter().all(|&u| u > 0), "every tile is used");
                }
            }
        }
    }

    #[test]
    fn keyed_tiling_does_not_depend_on_the_range() {
        let set = TileSet::Minimal.with_colors(2);
        let small = tile_rect(set, TilingOrder::Keyed, (-1, 6), (-4, 5), 0, 11, "t");
        let big = tile_rect(set, TilingOrder::Keyed, (-1, 20), (-15, 30), 0, 11, "t");
        for r in -1..=6 {
            for c in -4..=5 {
                assert_eq!(small.at(r, c), big.at(r, c), "({r},{c})");
            }
        }
        // The literal scanline order is range-dependent (which is why keyed is the default).
        let s1 = tile_rect(set, TilingOrder::Scanline, (0, 6), (0, 5), 0, 11, "t");
        let s2 = tile_rect(set, TilingOrder::Scanline, (0, 6), (0, 9), 0, 11, "t");
        assert!((0..=6).any(|r| (0..=5).any(|c| s1.at(r, c) != s2.at(r, c))));
    }

    #[test]
    fn torus_classes_follow_the_periods() {
        for (v1, v2) in [((3, 0), (0, 5)), ((2, -2), (3, 3)), ((1, -1), (1, 1)), ((4, -4), (1, 1)), ((1, 0), (0, 1))] {
            let t = Torus::new(v1, v2);
            assert_eq!(t.len() as i64, (v1.0 * v2.1 - v1.1 * v2.0).abs(), "{v1:?} {v2:?}");
            let mut seen = std::collections::HashSet::new();
            for r in -7..9 {
                for c in -7..9 {
                    let k = t.class(r, c);
                    seen.insert(k);
                    assert_eq!(t.class(r + v1.0, c + v1.1), k);
                    assert_eq!(t.class(r - v2.0, c - v2.1), k);
                    assert_eq!(t.position(k), t.position(t.class(t.position(k).0, t.position(k).1)));
                }
            }
            assert_eq!(seen.len(), t.len(), "{v1:?} {v2:?}");
        }
    }

    #[test]
    fn torus_tilings_match_every_edge_across_the_periods_too() {
        for set in [TileSet::Minimal.with_colors(2), TileSet::Complete.with_colors(2)] {
            for (v1, v2) in [
                ((1, 0), (0, 1)),
                ((1, 0), (0, 4)),
                ((3, 0), (0, 1)),
                ((4, 0), (0, 6)),
                ((1, -1), (1, 1)),
                ((3, -3), (2, 2)),
                ((5, -5), (1, 1)),
            ] {
                let torus = Torus::new(v1, v2);
                for seed in 0..8 {
                    let t = tile_torus(set, &torus, (-6, 9), (-8, 7), seed, "test/torus");
                    assert_eq!(t.violations(set), 0, "{set:?} {v1:?} {v2:?} seed {seed}");
                    for r in -6..=9 - v1.0.max(v2.0) {
                        for c in -8..=7 {
                            for v in [v1, v2] {
                                if (-8..=7).contains(&(c + v.1)) && r + v.0 <= 9 {
                                    assert_eq!(t.at(r, c), t.at(r + v.0, c + v.1), "({r},{c}) + {v:?}");
                                }
                            }
                        }
                    }
                }
            }
            for (v1, v2) in [((20, 0), (0, 20)), ((12, -12), (10, 10))] {
                let big = tile_torus(set, &Torus::new(v1, v2), (0, 40), (0, 40), 1, "test/torus");
                assert!(big.usage(set).iter().all(|&u| u > 0), "{set:?} {v1:?} {v2:?}: every tile is used");
            }
        }
    }

    #[test]
    fn k_colour_sets_are_their_rules_and_choose_among_k_or_k_squared() {
        for k in 2..=5u8 {
            for (rule, per_pair) in [(TileSet::Minimal, k as usize), (TileSet::Complete, k as usize * k as usize)] {
                let set = rule.with_colors(k);
                let all: std::collections::HashSet<[u8; 4]> = (0..set.len()).map(|t| set.colours(t)).collect();
                assert_eq!(all.len(), set.len(), "{set:?}: distinct colourings");
                for t in 0..set.len() {
                    let c = set.colours(t);
                    assert!(c.iter().all(|&x| x < k));
                    assert_eq!(set.index(c), t, "{set:?}");
                    if rule == TileSet::Minimal {
                        assert_eq!((c[0] + c[1]) % k, (c[2] + c[3]) % k);
                    }
                }
                // Every incoming pair (and the keyed order's `a` with `d`) has K (minimal) or K²
                // (complete) tiles to choose from, all of which get chosen.
                for fixed in [[Some(k - 1), Some(0), None, None], [Some(1), None, None, Some(k - 1)]] {
                    let mut seen = std::collections::HashSet::new();
                    let mut s = Stream::new(u64::from(k), "test/choose");
                    for _ in 0..2000 {
                        seen.insert(set.choose(fixed, &mut s));
                    }
                    assert_eq!(seen.len(), per_pair, "{set:?} {fixed:?}");
                }
            }
        }
    }

    #[test]
    fn k_colour_tilings_are_valid_on_the_plane_and_on_the_torus() {
        for k in 2..=5u8 {
            for set in [TileSet::Minimal.with_colors(k), TileSet::Complete.with_colors(k)] {
                for order in [TilingOrder::Scanline, TilingOrder::Keyed] {
                    for seed in 0..3 {
                        let t = tile_rect(set, order, (-3, 17), (-9, 12), 0, seed, "test/tiling");
                        assert_eq!(t.violations(set), 0, "{set:?} {order:?} seed {seed}");
                    }
                }
                for (v1, v2) in [((1, 0), (0, 1)), ((3, 0), (0, 4)), ((5, 0), (0, 6)), ((3, -3), (2, 2)), ((5, -5), (1, 1))] {
                    let torus = Torus::new(v1, v2);
                    for seed in 0..4 {
                        let t = tile_torus(set, &torus, (-6, 9), (-8, 7), seed, "test/torus");
                        assert_eq!(t.violations(set), 0, "{set:?} {v1:?} {v2:?} seed {seed}");
                        for r in -6..=9 - v1.0.max(v2.0) {
                            for c in -8..=7 {
                                for v in [v1, v2] {
                                    if (-8..=7).contains(&(c + v.1)) && r + v.0 <= 9 {
                                        assert_eq!(t.at(r, c), t.at(r + v.0, c + v.1), "({r},{c}) + {v:?}");
                                    }
                                }
                            }
                        }
                    }
                }
            }
            // A large fill uses every colour on both edge classes.
            let set = TileSet::Minimal.with_colors(k);
            let big = tile_rect(set, TilingOrder::Keyed, (0, 40), (0, 40), 0, 1, "test/tiling");
            let used: std::collections::HashSet<(u8, u8)> =
                big.tiles.iter().map(|&t| set.colours(t as usize)).map(|c| (c[2], c[3])).collect();
            assert_eq!(used.len(), k as usize * k as usize);
        }
    }
}
