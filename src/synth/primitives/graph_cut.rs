//! The minimum-error seam between what a region already holds and a new block, for regions of
//! any shape (Kwatra et al.'s graph cut, the general form of quilting's boundary cut, B3).
//!
//! Quilting's dynamic-programming cut needs the overlap to be a strip with the old content on
//! one side and the new on the other. Filling a hole breaks that: the pixels a block may replace
//! (filled earlier in the hole) form any shape, bounded by pixels that must stay (the known image
//! around the hole) and pixels that must be new (still empty). The cheapest seam through such a
//! region is a minimum s–t cut: the source is "keep", the sink is "new", and cutting between
//! neighbours costs how badly the two contents disagree there. Maximum flow finds it (Dinic's
//! algorithm, iterative so a large block cannot overflow the stack); everything is integer and
//! visited in a fixed order, so the labels are the same on every machine.

/// What a pixel of the region may become.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// Must keep what it holds (a known pixel).
    Keep,
    /// Must take the new block (nothing there yet).
    New,
    /// Either: the cut decides.
    Free,
}

/// For a `width × height` region, row-major: `true` where a pixel takes the new block. `sides`
/// says what each pixel may become; `error[p]` is how much old and new disagree at a `Keep` or
/// `Free` pixel (unused at `New` ones, which hold nothing to compare). Cutting between
/// neighbours `p` and `q` costs `error[p] + error[q] + 1` (a `New` neighbour counts its partner's
/// error twice); the `+ 1` makes the shortest of equally good seams win.
pub fn min_cut(width: usize, height: usize, sides: &[Side], error: &[u64]) -> Vec<bool> {
    min_cut_with_keep_costs(width, height, sides, error, &[])
}

/// [`min_cut`] where keeping a `Free` pixel may cost too: `keep_cost[p]` is paid when `p` keeps
/// what it holds (empty: nothing). That is how a seam already in the region counts: a pixel next
/// to a badly joined neighbour pays for keeping the bad joint, so the cut may replace it.
pub fn min_cut_with_keep_costs(width: usize, height: usize, sides: &[Side], error: &[u64], keep_cost: &[u64]) -> Vec<bool> {
    assert_eq!(sides.len(), width * height, "one side per pixel");
    assert!(keep_cost.is_empty() || keep_cost.len() == sides.len(), "no keep costs, or one per pixel");
    assert_eq!(error.len(), width * height, "one error per pixel");
    let free: Vec<usize> = (0..sides.len()).filter(|&p| sides[p] == Side::Free).collect();
    let mut label: Vec<bool> = sides.iter().map(|s| *s == Side::New).collect();
    if free.is_empty() {
        return label;
    }
    let mut node = vec![usize::MAX; sides.len()];
    for (i, &p) in free.iter().enumerate() {
        node[p] = i;
    }
    let (source, sink) = (free.len(), free.len() + 1);
    let mut flow = Flow::new(free.len() + 2);
    for (i, &p) in free.iter().enumerate() {
        if let Some(&c) = keep_cost.get(p).filter(|&&c| c > 0) {
            flow.add(i, sink, c);
        }
        let (x, y) = (p % width, p / width);
        let neighbours =
            [(x > 0).then(|| p - 1), (x + 1 < width).then(|| p + 1), (y > 0).then(|| p - width), (y + 1 < height).then(|| p + width)];
        for q in neighbours.into_iter().flatten() {
            match sides[q] {
                Side::Free if q > p => flow.add_undirected(i, node[q], error[p] + error[q] + 1),
                Side::Free => {}
                Side::Keep => flow.add(source, i, error[p] + error[q] + 1),
                Side::New => flow.add(i, sink, 2 * error[p] + 1),
            }
        }
    }
    flow.max_flow(source, sink);
    let keep = flow.reachable(source);
    for (i, &p) in free.iter().enumerate() {
        label[p] = !keep[i];
    }
    label
}

/// A flow network with integer capacities; arcs are stored in pairs (`e`, `e ^ 1` its reverse).
struct Flow {
    adjacency: Vec<Vec<usize>>,
    to: Vec<usize>,
    capacity: Vec<u64>,
}

impl Flow {
    fn new(nodes: usize) -> Flow {
        Flow { adjacency: vec![Vec::new(); nodes], to: Vec::new(), capacity: Vec::new() }
    }

    fn arc_pair(&mut self, a: usize, b: usize, forward: u64, backward: u64) {
        self.adjacency[a].push(self.to.len());
        self.to.push(b);
        self.capacity.push(forward);
        self.adjacency[b].push(self.to.len());
        self.to.push(a);
        self.capacity.push(backward);
    }

    fn add(&mut self, a: usize, b: usize, capacity: u64) {
        self.arc_pair(a, b, capacity, 0);
    }

    fn add_undirected(&mut self, a: usize, b: usize, capacity: u64) {
        self.arc_pair(a, b, capacity, capacity);
    }

    /// Breadth-first levels from `source` over arcs with capacity left (`usize::MAX`: unreached).
    fn levels(&self, source: usize) -> Vec<usize> {
        let mut level = vec![usize::MAX; self.adjacency.len()];
        level[source] = 0;
        let mut queue = std::collections::VecDeque::from([source]);
        while let Some(u) = queue.pop_front() {
            for &e in &self.adjacency[u] {
                let v = self.to[e];
                if self.capacity[e] > 0 && level[v] == usize::MAX {
                    level[v] = level[u] + 1;
                    queue.push_back(v);
                }
            }
        }
        level
    }

    fn reachable(&self, source: usize) -> Vec<bool> {
        self.levels(source).into_iter().map(|l| l != usize::MAX).collect()
    }

    /// Dinic: blocking flows along shortest paths until the sink is cut off.
    fn max_flow(&mut self, source: usize, sink: usize) -> u64 {
        let mut total = 0;
        loop {
            let mut level = self.levels(source);
            if level[sink] == usize::MAX {
                return total;
            }
            let mut next = vec![0usize; self.adjacency.len()];
            let mut path: Vec<usize> = Vec::new();
            let mut u = source;
            loop {
                if u == sink {
                    let bottleneck = path.iter().map(|&e| self.capacity[e]).min().expect("a path to the sink has arcs");
                    for &e in &path {
                        self.capacity[e] -= bottleneck;
                        self.capacity[e ^ 1] += bottleneck;
                    }
                    total += bottleneck;
                    // Back to the tail of the first arc the push saturated.
                    let first_full = path.iter().position(|&e| self.capacity[e] == 0).expect("the bottleneck arc is full");
                    path.truncate(first_full);
                    u = path.last().map_or(source, |&e| self.to[e]);
                    continue;
                }
                let mut advanced = false;
                while next[u] < self.adjacency[u].len() {
                    let e = self.adjacency[u][next[u]];
                    let v = self.to[e];
                    if self.capacity[e] > 0 && level[v] == level[u] + 1 {
                        path.push(e);
                        u = v;
                        advanced = true;
                        break;
                    }
                    next[u] += 1;
                }
                if advanced {
                    continue;
                }
                // A dead end: no shortest path goes through `u` any more.
                level[u] = usize::MAX;
                match path.pop() {
                    None => break,
                    Some(e) => {
                        u = self.to[e ^ 1];
                        next[u] += 1;
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(rows: &[&str]) -> (usize, usize, Vec<Side>) {
        let sides = rows
            .iter()
            .flat_map(|r| {
                r.chars().map(|c| match c {
                    'K' => Side::Keep,
                    'N' => Side::New,
                    _ => Side::Free,
                })
            })
            .collect();
        (rows[0].len(), rows.len(), sides)
    }

    #[test]
    fn the_seam_runs_where_old_and_new_agree() {
        // Keep on the left, new on the right, free between; old and new agree only in columns 3 and 4.
        let (w, h, sides) = parse(&["K.....N", "K.....N", "K.....N", "K.....N"]);
        let error: Vec<u64> = (0..w * h).map(|p| if p % w == 3 || p % w == 4 { 0 } else { 1000 }).collect();
        let label = min_cut(w, h, &sides, &error);
        for y in 0..h {
            let row: String = (0..w).map(|x| if label[y * w + x] { 'n' } else { 'k' }).collect();
            assert_eq!(row, "kkkknnn", "row {y}");
        }
    }

    #[test]
    fn fixed_pixels_keep_their_side_and_an_enclosed_region_follows_its_cheapest_border() {
        // A free ring around new pixels, inside known ones: cheap to keep, so only the new core is new.
        let (w, h, sides) = parse(&["KKKKK", "K...K", "K.N.K", "K...K", "KKKKK"]);
        let cheap_keep: Vec<u64> = sides.iter().map(|s| if *s == Side::Keep { 0 } else { 5 }).collect();
        let label = min_cut(w, h, &sides, &cheap_keep);
        for (p, s) in sides.iter().enumerate() {
            // Around the core the seam costs 4 × 11, along the known border 12 × 6.
            assert_eq!(label[p], *s == Side::New, "pixel {p}");
        }
        // Nothing free at all: the labels are the sides.
        let (w, h, sides) = parse(&["KN", "NK"]);
        assert_eq!(min_cut(w, h, &sides, &[0; 4]), vec![false, true, true, false]);
    }

    #[test]
    fn a_costly_existing_joint_is_replaced_when_the_new_block_joins_better() {
        // One free pixel between a known one and the rest: keeping it costs its bad joint (50),
        // taking the new block costs the joint the new block makes (errors 1 + 1 + 1).
        let (w, h, sides) = parse(&["K.K"]);
        assert_eq!(min_cut_with_keep_costs(w, h, &sides, &[1, 1, 1], &[0, 50, 0]), vec![false, true, false]);
        // Without a cost to keep it, it stays.
        assert_eq!(min_cut(w, h, &sides, &[1, 1, 1]), vec![false, false, false]);
    }

    #[test]
    fn a_large_free_region_is_cut_without_deep_recursion() {
        let (w, h) = (300, 300);
        let sides: Vec<Side> = (0..w * h)
            .map(|p| match p % w {
                0 => Side::Keep,
                x if x == w - 1 => Side::New,
                _ => Side::Free,
            })
            .collect();
        let error: Vec<u64> = (0..w * h).map(|p| ((p * 7919) % 97) as u64).collect();
        let a = min_cut(w, h, &sides, &error);
        assert_eq!(a, min_cut(w, h, &sides, &error));
        assert!(!a[0] && a[w - 1]);
    }
}
