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
    let mut flow = Flow::new(free.len() + 2, 2 * free.len() + 2);
    // A pixel's arcs from the source (its known neighbours) and to the sink (its new neighbours,
    // its cost to keep) are summed into one each, and what both can carry goes straight through
    // beforehand: every cut then costs the same less one constant, so the cuts of least cost,
    // and the labels below, are those of the network with every arc apart.
    let (mut from_source, mut to_sink) = (vec![0u64; free.len()], vec![0u64; free.len()]);
    for (i, &p) in free.iter().enumerate() {
        if let Some(&c) = keep_cost.get(p) {
            to_sink[i] += c;
        }
        let (x, y) = (p % width, p / width);
        let neighbours =
            [(x > 0).then(|| p - 1), (x + 1 < width).then(|| p + 1), (y > 0).then(|| p - width), (y + 1 < height).then(|| p + width)];
        for q in neighbours.into_iter().flatten() {
            match sides[q] {
                Side::Free if q > p => flow.add_undirected(i, node[q], error[p] + error[q] + 1),
                Side::Free => {}
                Side::Keep => from_source[i] += error[p] + error[q] + 1,
                Side::New => to_sink[i] += 2 * error[p] + 1,
            }
        }
    }
    for (i, (&a, &b)) in from_source.iter().zip(&to_sink).enumerate() {
        let through = a.min(b);
        if a > through {
            flow.add(source, i, a - through);
        }
        if b > through {
            flow.add(i, sink, b - through);
        }
    }
    flow.max_flow(source, sink);
    let keep = flow.reachable(source);
    for (i, &p) in free.iter().enumerate() {
        label[p] = !keep[i];
    }
    label
}

/// A flow network with integer capacities; arcs are stored in pairs (`e`, `e ^ 1` its reverse),
/// each node's arcs listed contiguously once the network is complete ([`Flow::index`]).
struct Flow {
    nodes: usize,
    to: Vec<u32>,
    capacity: Vec<u64>,
    /// The arcs of node `u` are `arcs[first[u]..first[u + 1]]`, in the order they were added.
    first: Vec<u32>,
    arcs: Vec<u32>,
    /// Breadth-first levels and the queue that finds them, kept between phases.
    level: Vec<u32>,
    queue: Vec<u32>,
}

const UNREACHED: u32 = u32::MAX;

impl Flow {
    fn new(nodes: usize, arcs: usize) -> Flow {
        Flow {
            nodes,
            to: Vec::with_capacity(2 * arcs),
            capacity: Vec::with_capacity(2 * arcs),
            first: Vec::new(),
            arcs: Vec::new(),
            level: Vec::new(),
            queue: Vec::new(),
        }
    }

    fn arc_pair(&mut self, a: usize, b: usize, forward: u64, backward: u64) {
        self.to.push(b as u32);
        self.capacity.push(forward);
        self.to.push(a as u32);
        self.capacity.push(backward);
    }

    fn add(&mut self, a: usize, b: usize, capacity: u64) {
        self.arc_pair(a, b, capacity, 0);
    }

    fn add_undirected(&mut self, a: usize, b: usize, capacity: u64) {
        self.arc_pair(a, b, capacity, capacity);
    }

    /// Lists each node's arcs contiguously (a counting sort by tail: arc `e` leaves `to[e ^ 1]`).
    fn index(&mut self) {
        let mut first = vec![0u32; self.nodes + 1];
        for e in 0..self.to.len() {
            first[self.to[e ^ 1] as usize + 1] += 1;
        }
        for u in 0..self.nodes {
            first[u + 1] += first[u];
        }
        let mut at = first.clone();
        let mut arcs = vec![0u32; self.to.len()];
        for e in 0..self.to.len() {
            let u = self.to[e ^ 1] as usize;
            arcs[at[u] as usize] = e as u32;
            at[u] += 1;
        }
        self.first = first;
        self.arcs = arcs;
    }

    /// Breadth-first levels from `source` over arcs with capacity left (`UNREACHED`), in
    /// `self.level`. With a `sink`, the search stops once the sink's level is done: a node as
    /// deep as the sink or deeper lies on no shortest path to it, so Dinic's phase never enters
    /// it (it would be a dead end), and leaving it unreached changes no augmenting path.
    fn levels(&mut self, source: usize, sink: Option<usize>) {
        self.level.clear();
        self.level.resize(self.nodes, UNREACHED);
        self.level[source] = 0;
        self.queue.clear();
        self.queue.push(source as u32);
        let mut head = 0;
        while head < self.queue.len() {
            let u = self.queue[head] as usize;
            head += 1;
            if sink.is_some_and(|t| self.level[t] <= self.level[u]) {
                break;
            }
            let next = self.level[u] + 1;
            for &e in &self.arcs[self.first[u] as usize..self.first[u + 1] as usize] {
                let v = self.to[e as usize] as usize;
                if self.capacity[e as usize] > 0 && self.level[v] == UNREACHED {
                    self.level[v] = next;
                    self.queue.push(v as u32);
                }
            }
        }
    }

    /// The nodes reached from `source` over arcs with capacity left.
    fn reachable(&mut self, source: usize) -> Vec<bool> {
        if self.first.is_empty() {
            self.index();
        }
        self.levels(source, None);
        self.level.iter().map(|&l| l != UNREACHED).collect()
    }

    /// Dinic: blocking flows along shortest paths until the sink is cut off.
    fn max_flow(&mut self, source: usize, sink: usize) -> u64 {
        self.index();
        let mut total = 0;
        let mut next = vec![0u32; self.nodes];
        let mut path: Vec<u32> = Vec::new();
        loop {
            self.levels(source, Some(sink));
            if self.level[sink] == UNREACHED {
                return total;
            }
            next.copy_from_slice(&self.first[..self.nodes]);
            path.clear();
            let mut u = source;
            loop {
                if u == sink {
                    let bottleneck = path.iter().map(|&e| self.capacity[e as usize]).min().expect("a path to the sink has arcs");
                    for &e in &path {
                        self.capacity[e as usize] -= bottleneck;
                        self.capacity[e as usize ^ 1] += bottleneck;
                    }
                    total += bottleneck;
                    // Back to the tail of the first arc the push saturated.
                    let first_full = path.iter().position(|&e| self.capacity[e as usize] == 0).expect("the bottleneck arc is full");
                    path.truncate(first_full);
                    u = path.last().map_or(source, |&e| self.to[e as usize] as usize);
                    continue;
                }
                let mut advanced = false;
                let end = self.first[u + 1];
                while next[u] < end {
                    let e = self.arcs[next[u] as usize] as usize;
                    let v = self.to[e] as usize;
                    if self.capacity[e] > 0 && self.level[v] == self.level[u].wrapping_add(1) {
                        path.push(e as u32);
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
                self.level[u] = UNREACHED;
                match path.pop() {
                    None => break,
                    Some(e) => {
                        u = self.to[e as usize ^ 1] as usize;
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

    /// The labels by enumeration: of every labelling of the free pixels, those of least cost,
    /// and among them the one keeping fewest (the cuts of least cost are closed under
    /// intersection, so it is the intersection of their kept sets), as max flow leaves it.
    fn brute_force(width: usize, height: usize, sides: &[Side], error: &[u64], keep_cost: &[u64]) -> Vec<bool> {
        let free: Vec<usize> = (0..sides.len()).filter(|&p| sides[p] == Side::Free).collect();
        let takes = |p: usize, mask: u32| match sides[p] {
            Side::Keep => false,
            Side::New => true,
            Side::Free => mask >> free.iter().position(|&f| f == p).unwrap() & 1 == 1,
        };
        let cost = |mask: u32| {
            let mut c = 0u64;
            for p in 0..sides.len() {
                let (x, y) = (p % width, p / width);
                if sides[p] == Side::Free && !takes(p, mask) {
                    c += keep_cost.get(p).copied().unwrap_or(0);
                }
                for q in [(x + 1 < width).then(|| p + 1), (y + 1 < height).then(|| p + width)].into_iter().flatten() {
                    if takes(p, mask) == takes(q, mask) || (sides[p] != Side::Free && sides[q] != Side::Free) {
                        continue;
                    }
                    c += match (sides[p], sides[q]) {
                        (Side::New, _) => 2 * error[q] + 1,
                        (_, Side::New) => 2 * error[p] + 1,
                        _ => error[p] + error[q] + 1,
                    };
                }
            }
            c
        };
        let all = 1u32 << free.len();
        let best = (0..all).map(cost).min().unwrap();
        let mut kept = vec![true; sides.len()];
        for mask in (0..all).filter(|&m| cost(m) == best) {
            for (p, k) in kept.iter_mut().enumerate() {
                *k &= !takes(p, mask);
            }
        }
        (0..sides.len()).map(|p| !kept[p]).collect()
    }

    #[test]
    fn the_cut_is_the_least_costly_labelling_keeping_fewest() {
        // Small random regions with few distinct errors, so that ties between cuts are common.
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = |n: u64| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state % n
        };
        for case in 0..300 {
            let (w, h) = (1 + next(5) as usize, 1 + next(4) as usize);
            let sides: Vec<Side> = (0..w * h)
                .map(|_| match next(5) {
                    0 => Side::Keep,
                    1 => Side::New,
                    _ => Side::Free,
                })
                .collect();
            if sides.iter().filter(|s| **s == Side::Free).count() > 12 {
                continue;
            }
            let error: Vec<u64> = (0..w * h).map(|_| next(4) * 3).collect();
            let keep_cost: Vec<u64> = if case % 2 == 0 { Vec::new() } else { (0..w * h).map(|_| next(3) * 4).collect() };
            assert_eq!(
                min_cut_with_keep_costs(w, h, &sides, &error, &keep_cost),
                brute_force(w, h, &sides, &error, &keep_cost),
                "case {case}: {w}x{h} {sides:?} {error:?} {keep_cost:?}"
            );
        }
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
