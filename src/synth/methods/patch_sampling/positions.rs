//! Which sample positions a block may be copied from when not every one may: the sample mask
//! (or an inpainted image's hole) rules positions out for every block ([`Allowed`]), the twin rule
//! of several samples' atlas rules out, per block, the turned or mirrored copies of what its
//! neighbours show ([`Twins`]). The swarms move over every position, so both also say which
//! allowed position a ruled-out one stands for.

/// The block positions a search may copy from, when not every one: the flags (row-major over
/// the `nx`-wide grid of positions) and, for the swarms, which move over every position, the
/// allowed position each one stands for: the nearest in 4-connected steps, ties to the one a
/// breadth-first search from the allowed positions (started in row-major order) reaches first.
/// So a swarm is scored and placed only at allowed positions, and its draws stay those of its
/// streams.
pub(super) struct Allowed {
    pub(super) flags: Vec<bool>,
    nearest: Vec<u32>,
    nx: u32,
}

impl Allowed {
    pub(super) fn new(flags: Vec<bool>, nx: u32) -> Allowed {
        let n = flags.len();
        let nxu = nx as usize;
        let mut nearest = vec![u32::MAX; n];
        let mut queue = std::collections::VecDeque::new();
        for (i, _) in flags.iter().enumerate().filter(|(_, a)| **a) {
            nearest[i] = i as u32;
            queue.push_back(i);
        }
        while let Some(p) = queue.pop_front() {
            let (x, y) = (p % nxu, p / nxu);
            for q in [(x > 0).then(|| p - 1), (x + 1 < nxu).then(|| p + 1), (y > 0).then(|| p - nxu), (p + nxu < n).then(|| p + nxu)]
                .into_iter()
                .flatten()
            {
                if nearest[q] == u32::MAX {
                    nearest[q] = nearest[p];
                    queue.push_back(q);
                }
            }
        }
        Allowed { flags, nearest, nx }
    }

    pub(super) fn allows(&self, (x, y): (u32, u32)) -> bool {
        self.flags[(y * self.nx + x) as usize]
    }

    pub(super) fn nearest(&self, (x, y): (u32, u32)) -> (u32, u32) {
        let i = self.nearest[(y * self.nx + x) as usize];
        (i % self.nx, i / self.nx)
    }
}

/// The twin rule of one block (several samples' atlas with `augment`): a block must not show a
/// turned or mirrored copy of the pixels a neighbour already placed shows
/// ([`crate::synth::atlas::Atlas::twins`]). The swarms treat such positions as they treat masked
/// ones (each stands for its nearest position that is allowed and no twin); the exhaustive
/// searches leave them out of their candidates.
pub(super) struct Twins<'a> {
    constraints: &'a crate::synth::constraints::Constraints<'a>,
    /// The sample positions of the blocks placed around this one.
    neighbours: Vec<(u32, u32)>,
    block: u32,
}

impl<'a> Twins<'a> {
    /// The rule for a block whose placed neighbours are at `neighbours`; `None` when no block can
    /// be a twin (no transformed copies, or no neighbour yet).
    pub(super) fn of(
        constraints: &'a crate::synth::constraints::Constraints<'a>,
        neighbours: Vec<(u32, u32)>,
        block: u32,
    ) -> Option<Twins<'a>> {
        let copies = constraints.atlas.is_some_and(|a| a.has_copies());
        (copies && !neighbours.is_empty()).then_some(Twins { constraints, neighbours, block })
    }

    pub(super) fn is_twin(&self, at: (u32, u32)) -> bool {
        self.constraints.is_twin(at, &self.neighbours, self.block)
    }

    /// The position `p` stands for: itself unless it is a twin, else the nearest position (in
    /// 4-connected steps over the `nx × ny` grid of positions) that `allowed` allows and that is
    /// no twin, ring by ring, each ring in a fixed order (up, right, down, left of each step);
    /// `p` itself when there is none.
    pub(super) fn resolve(&self, p: (u32, u32), (nx, ny): (u32, u32), allowed: Option<&Allowed>) -> (u32, u32) {
        if !self.is_twin(p) {
            return p;
        }
        let ok = |q: (u32, u32)| allowed.is_none_or(|a| a.allows(q)) && !self.is_twin(q);
        let (px, py) = (i64::from(p.0), i64::from(p.1));
        for d in 1..=i64::from(nx + ny) {
            // The ring at Manhattan distance d, from the top going clockwise.
            for k in 0..4 * d {
                let (side, t) = (k / d, k % d);
                let (dx, dy) = match side {
                    0 => (t, t - d),
                    1 => (d - t, t),
                    2 => (-t, d - t),
                    _ => (t - d, -t),
                };
                let (x, y) = (px + dx, py + dy);
                if x < 0 || y < 0 || x >= i64::from(nx) || y >= i64::from(ny) {
                    continue;
                }
                if ok((x as u32, y as u32)) {
                    return (x as u32, y as u32);
                }
            }
        }
        p
    }
}
