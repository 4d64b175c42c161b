//! Wang-tile edge colours and stochastic scanline tiling (Cohen et al. 2003; docs/methods.md B12).
//!
//! A tile carries four edge colours `[a, b, c, d]`: `a` and `b` are its *incoming* edges (shared
//! with the tile before it in the row direction and in the column direction), `c` and `d` its
//! *outgoing* edges. On a grid of tiles `(r, col)`, tile `(r, col)`'s `a` equals the `c` of tile
//! `(r − 1, col)` and its `b` equals the `d` of tile `(r, col − 1)`. The Cohen baseline uses
//! `[N, W, S, E]` on rows and columns; RW-Tiles use `[NW, NE, SE, SW]` on the rhombus lattice
//! `(i, j)` (docs/methods.md §3.5–3.6).

use crate::synth::rng::Stream;

crate::choice! {
    /// Which tiles exist (the `tile_set` parameter of both tile methods, and an export's
    /// `tile_set`).
    pub enum TileSet {
        /// The 8 tiles with `a ⊕ b ⊕ c ⊕ d = 0`; index `a·4 + b·2 + c`, `d = a ⊕ b ⊕ c`.
        Minimal = "minimal",
        /// All 16 colourings; index `a·8 + b·4 + c·2 + d`.
        Complete = "complete",
    }
}

impl TileSet {
    pub fn len(&self) -> usize {
        match self {
            TileSet::Minimal => 8,
            TileSet::Complete => 16,
        }
    }

    pub fn is_empty(&self) -> bool {
        false
    }

    /// The colours `[a, b, c, d]` of tile `index`.
    pub fn colours(&self, index: usize) -> [u8; 4] {
        let k = index as u8;
        match self {
            TileSet::Minimal => {
                let (a, b, c) = (k >> 2 & 1, k >> 1 & 1, k & 1);
                [a, b, c, a ^ b ^ c]
            }
            TileSet::Complete => [k >> 3 & 1, k >> 2 & 1, k >> 1 & 1, k & 1],
        }
    }

    /// Picks uniformly (one `below(k)`) among the tiles, in index order, whose colours agree with
    /// every fixed colour. Both sets always have a match (`k ≥ 1`).
    pub fn choose(&self, fixed: [Option<u8>; 4], stream: &mut Stream) -> usize {
        let mut matching = [0usize; 16];
        let mut k = 0;
        for t in 0..self.len() {
            let c = self.colours(t);
            if (0..4).all(|e| fixed[e].is_none_or(|f| f == c[e])) {
                matching[k] = t;
                k += 1;
            }
        }
        assert!(k > 0, "no tile matches {fixed:?}");
        matching[stream.below_usize(k)]
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
    pub tiles: Vec<u8>,
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
    pub fn violations(&self, set: TileSet) -> usize {
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
    pub fn usage(&self, set: TileSet) -> Vec<usize> {
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
    set: TileSet,
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
    let mut tiles = vec![0u8; rows * cols];
    const UNSET: u8 = u8::MAX;
    match order {
        TilingOrder::Scanline => {
            let mut stream = Stream::new(seed, label);
            for dr in 0..rows {
                for dc in 0..cols {
                    let a = (dr > 0).then(|| set.colours(tiles[(dr - 1) * cols + dc] as usize)[2]);
                    let b = (dc > 0).then(|| set.colours(tiles[dr * cols + dc - 1] as usize)[3]);
                    tiles[dr * cols + dc] = set.choose([a, b, None, None], &mut stream) as u8;
                }
            }
        }
        TilingOrder::Keyed => {
            assert!((c0..=c1).contains(&anchor), "anchor column {anchor} outside {c0}..={c1}");
            tiles.fill(UNSET);
            let start = (anchor - c0) as usize;
            for dr in 0..rows {
                let r = r0 + dr as i64;
                let above = |tiles: &[u8], dc: usize| (dr > 0).then(|| set.colours(tiles[(dr - 1) * cols + dc] as usize)[2]);
                let mut fwd = Stream::new(seed, &format!("{label}/r={r}"));
                for dc in start..cols {
                    let b = (dc > start).then(|| set.colours(tiles[dr * cols + dc - 1] as usize)[3]);
                    tiles[dr * cols + dc] = set.choose([above(&tiles, dc), b, None, None], &mut fwd) as u8;
                }
                let mut back = Stream::new(seed, &format!("{label}/r={r}/back"));
                for dc in (0..start).rev() {
                    // The tile to the right is placed: its incoming `b` fixes my outgoing `d`.
                    let d = Some(set.colours(tiles[dr * cols + dc + 1] as usize)[1]);
                    tiles[dr * cols + dc] = set.choose([above(&tiles, dc), None, None, d], &mut back) as u8;
                }
            }
        }
    }
    Tiling { r0, c0, rows, cols, tiles }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tile_sets_follow_the_parity_rule_and_index_order() {
        let m = TileSet::Minimal;
        for t in 0..8 {
            let [a, b, c, d] = m.colours(t);
            assert_eq!(a ^ b ^ c ^ d, 0);
            assert_eq!(t, (a * 4 + b * 2 + c) as usize);
        }
        // For each incoming pair exactly two tiles, with outgoing (0, a⊕b) and (1, 1⊕a⊕b).
        assert_eq!(m.colours(0b110), [1, 1, 0, 0]);
        assert_eq!(m.colours(0b111), [1, 1, 1, 1]);
        let c = TileSet::Complete;
        let all: std::collections::HashSet<[u8; 4]> = (0..16).map(|t| c.colours(t)).collect();
        assert_eq!(all.len(), 16);
        assert_eq!(c.colours(0b1011), [1, 0, 1, 1]);
    }

    #[test]
    fn choose_counts_match_b12() {
        // k = 2, 4, 8 (minimal) and 4, 8, 16 (complete) with 2, 1, 0 incoming colours fixed:
        // check through the distribution of choices over many streams.
        for (set, fixed, k) in [
            (TileSet::Minimal, [Some(1), Some(0), None, None], 2),
            (TileSet::Minimal, [None, Some(1), None, None], 4),
            (TileSet::Minimal, [None, None, None, None], 8),
            (TileSet::Complete, [Some(0), Some(1), None, None], 4),
            (TileSet::Complete, [Some(0), None, None, None], 8),
            (TileSet::Complete, [None, None, None, None], 16),
            (TileSet::Minimal, [Some(1), None, None, Some(0)], 2),
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
        for set in [TileSet::Minimal, TileSet::Complete] {
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
        let set = TileSet::Minimal;
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
}
