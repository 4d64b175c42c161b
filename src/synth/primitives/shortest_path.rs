//! Shortest-path cut on the 8-neighbour pixel graph (Dijkstra) and region labelling after a cut
//! (docs/methods.md B4).
//!
//! Paper 001 replaces the quilting DP (B3), which takes one pixel per row, by a true shortest path
//! between two pixels of an overlap: the path may visit several pixels of one row and even turn
//! back. Everything here works on a `w × h` grid addressed by the row-major linear index
//! `y·w + x`; errors are exact integers and the tie rules are fixed, so the path is a pure
//! function of its inputs.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

/// The 8 neighbour offsets in B4's fixed relaxation order.
pub const NEIGHBOURS_8: [(i32, i32); 8] = [(-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1)];

/// The 4 neighbour offsets used by the flood fill.
const NEIGHBOURS_4: [(i32, i32); 4] = [(0, -1), (-1, 0), (1, 0), (0, 1)];

/// A shortest path and its length (sum of the edge weights `E(a) + E(b)` along it).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Path {
    /// Linear indices from the start to the first target reached.
    pub pixels: Vec<usize>,
    pub cost: u64,
}

/// Dijkstra on the 8-neighbour graph of a `w × h` grid (B4).
///
/// Nodes are the pixels of `domain` plus `start`; a node is connected to its 8 neighbours that are
/// in the domain or are targets, with edge weight `E(a) + E(b)` (no √2 for diagonals). The heap is
/// keyed by `(distance, linear index)`, neighbours are relaxed in [`NEIGHBOURS_8`] order and only
/// on strict improvement; the search stops when the first target is popped. `None` when no target
/// can be reached.
pub fn shortest_path(w: usize, h: usize, domain: &[bool], error: &[u32], start: usize, targets: &[bool]) -> Option<Path> {
    let n = w * h;
    assert!(domain.len() == n && error.len() == n && targets.len() == n, "grid sizes");
    assert!(start < n, "start outside the grid");
    let mut dist = vec![u64::MAX; n];
    let mut prev = vec![usize::MAX; n];
    let mut done = vec![false; n];
    let mut heap = BinaryHeap::new();
    dist[start] = 0;
    heap.push(Reverse((0u64, start)));
    while let Some(Reverse((d, v))) = heap.pop() {
        if done[v] {
            continue;
        }
        done[v] = true;
        if targets[v] {
            let mut pixels = vec![v];
            let mut p = v;
            while p != start {
                p = prev[p];
                pixels.push(p);
            }
            pixels.reverse();
            return Some(Path { pixels, cost: d });
        }
        // Targets outside the domain are reachable but are not expanded from (they end the search).
        if v != start && !domain[v] {
            continue;
        }
        let (x, y) = ((v % w) as i32, (v / w) as i32);
        for (dx, dy) in NEIGHBOURS_8 {
            let (nx, ny) = (x + dx, y + dy);
            if nx < 0 || ny < 0 || nx >= w as i32 || ny >= h as i32 {
                continue;
            }
            let u = ny as usize * w + nx as usize;
            if done[u] || !(domain[u] || targets[u]) {
                continue;
            }
            let nd = d + error[v] as u64 + error[u] as u64;
            if nd < dist[u] {
                dist[u] = nd;
                prev[u] = v;
                heap.push(Reverse((nd, u)));
            }
        }
    }
    None
}

/// Sum of the edge weights `E(a) + E(b)` along a path given as linear indices.
pub fn path_cost(error: &[u32], path: &[usize]) -> u64 {
    path.windows(2).map(|p| error[p[0]] as u64 + error[p[1]] as u64).sum()
}

/// Whether consecutive pixels of a path are 8-neighbours.
pub fn is_8_connected(w: usize, path: &[usize]) -> bool {
    path.windows(2).all(|p| {
        let (ax, ay) = ((p[0] % w) as i64, (p[0] / w) as i64);
        let (bx, by) = ((p[1] % w) as i64, (p[1] / w) as i64);
        p[0] != p[1] && (ax - bx).abs() <= 1 && (ay - by).abs() <= 1
    })
}

/// 4-connected flood fill on a `w × h` grid: every pixel reachable from `seeds` through pixels for
/// which `passable` holds (seeds themselves are included even if not passable). Used for the
/// region labelling after a cut (B4): an 8-connected path blocks a 4-connected fill.
pub fn flood4(w: usize, h: usize, seeds: &[usize], passable: impl Fn(usize) -> bool) -> Vec<bool> {
    let mut reached = vec![false; w * h];
    let mut stack: Vec<usize> = Vec::with_capacity(seeds.len());
    for &s in seeds {
        if !reached[s] {
            reached[s] = true;
            stack.push(s);
        }
    }
    while let Some(v) = stack.pop() {
        let (x, y) = ((v % w) as i32, (v / w) as i32);
        for (dx, dy) in NEIGHBOURS_4 {
            let (nx, ny) = (x + dx, y + dy);
            if nx < 0 || ny < 0 || nx >= w as i32 || ny >= h as i32 {
                continue;
            }
            let u = ny as usize * w + nx as usize;
            if !reached[u] && passable(u) {
                reached[u] = true;
                stack.push(u);
            }
        }
    }
    reached
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::primitives::boundary_cut::vertical_cut;
    use crate::synth::rng::Stream;

    fn all(n: usize) -> Vec<bool> {
        vec![true; n]
    }

    fn bottom_row(w: usize, h: usize) -> Vec<bool> {
        (0..w * h).map(|i| i / w == h - 1).collect()
    }

    #[test]
    fn zero_surface_gives_the_tie_broken_path() {
        // On a zero surface every path costs 0; with heap ties popping the smaller index first and
        // relaxation only on strict improvement, the first target popped is the bottom-row pixel
        // with the smallest index reachable, and each pixel keeps the parent that first reached it.
        let (w, h) = (5, 4);
        let start = 2; // (2, 0)
        let p = shortest_path(w, h, &all(w * h), &vec![0; w * h], start, &bottom_row(w, h)).unwrap();
        assert_eq!(p.cost, 0);
        // Pops go by index among equal distances: (1,0) is popped before (1,1) and becomes the parent
        // of (0,1), which is popped before (1,1) and becomes the parent of (0,2), and so on; the
        // target (0,3) (index 15, the smallest of the bottom row) is the first target popped.
        assert_eq!(p.pixels, vec![2, 1, 5, 10, 15]);
        assert!(is_8_connected(w, &p.pixels));
        // Deterministic.
        assert_eq!(p, shortest_path(w, h, &all(w * h), &vec![0; w * h], start, &bottom_row(w, h)).unwrap());
    }

    #[test]
    fn finds_a_cheap_corridor_that_turns_back_up() {
        // A U-shaped cheap corridor the DP (one pixel per row, no going up) cannot follow.
        let (w, h) = (7, 6);
        let mut e = vec![1000u32; w * h];
        let corridor = [(1, 0), (1, 1), (1, 2), (1, 3), (2, 4), (3, 3), (3, 2), (4, 1), (5, 2), (5, 3), (5, 4), (5, 5)];
        for &(x, y) in &corridor {
            e[y * w + x] = 1;
        }
        let p = shortest_path(w, h, &all(w * h), &e, 1, &bottom_row(w, h)).unwrap();
        let expected: Vec<usize> = corridor.iter().map(|&(x, y)| y * w + x).collect();
        assert_eq!(p.pixels, expected);
        assert_eq!(p.cost, 2 * (corridor.len() as u64 - 1));
        assert_eq!(path_cost(&e, &p.pixels), p.cost);
    }

    #[test]
    fn never_costlier_than_the_dp_cut_from_its_top_pixel() {
        // §8: started at the DP cut's top pixel with the bottom row as targets, Dijkstra's cost is
        // never above the DP cut's cost measured with the same edge weights.
        for trial in 0..200u64 {
            let mut s = Stream::new(trial, "test/b4");
            let w = 2 + s.below_usize(9);
            let h = 2 + s.below_usize(12);
            let e: Vec<u32> = (0..w * h).map(|_| s.below(1000) as u32 * s.below(3) as u32).collect();
            let cut = vertical_cut(&e, h, w);
            let dp_path: Vec<usize> = cut.iter().enumerate().map(|(y, &x)| y * w + x).collect();
            assert!(is_8_connected(w, &dp_path));
            let dp_cost = path_cost(&e, &dp_path);
            let p = shortest_path(w, h, &all(w * h), &e, dp_path[0], &bottom_row(w, h)).unwrap();
            assert!(is_8_connected(w, &p.pixels));
            assert_eq!(path_cost(&e, &p.pixels), p.cost);
            assert!(p.cost <= dp_cost, "trial {trial}: dijkstra {} > dp {dp_cost}", p.cost);
        }
    }

    #[test]
    fn respects_the_domain_and_reports_unreachable_targets() {
        let (w, h) = (5, 5);
        // A wall across row 2 except at x = 4.
        let domain: Vec<bool> = (0..w * h).map(|i| !(i / w == 2 && i % w != 4)).collect();
        let p = shortest_path(w, h, &domain, &vec![1; w * h], 0, &bottom_row(w, h)).unwrap();
        assert!(p.pixels.iter().all(|&i| domain[i]));
        assert!(p.pixels.contains(&14));
        let closed: Vec<bool> = (0..w * h).map(|i| i / w != 2).collect();
        assert_eq!(shortest_path(w, h, &closed, &vec![1; w * h], 0, &bottom_row(w, h)), None);
        // A start that is itself a target is a one-pixel path.
        let t: Vec<bool> = (0..w * h).map(|i| i == 3).collect();
        assert_eq!(shortest_path(w, h, &domain, &vec![5; w * h], 3, &t).unwrap(), Path { pixels: vec![3], cost: 0 });
    }

    #[test]
    fn an_8_connected_path_blocks_the_4_connected_fill() {
        // A diagonal path from (0,0) to (4,4): the fill from (4,0) stays strictly above it.
        let (w, h) = (5, 5);
        let path: Vec<usize> = (0..5).map(|k| k * w + k).collect();
        let on_path = |i: usize| path.contains(&i);
        let reached = flood4(w, h, &[4], |i| !on_path(i));
        for y in 0..h {
            for x in 0..w {
                assert_eq!(reached[y * w + x], x > y, "({x},{y})");
            }
        }
    }
}
