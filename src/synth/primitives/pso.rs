//! Particle-swarm optimisation with the chaos search of paper 002 (docs/methods.md §4.3), shared by the
//! patch-sampling method (2-D patch positions) and the function-optimisation example (30-D).
//!
//! One function, [`optimise`], runs both algorithms: plain PSO when [`SwarmParams::chaos`] is
//! `None`, CPSO otherwise. Both draw from the same two streams in the same order (the swarm stream
//! for initialisation and every `η`, the chaos stream only inside a chaos search), so a PSO run and
//! a CPSO run with the same streams coincide draw for draw until CPSO's first chaos search.
//!
//! Everything is sequential `f64` arithmetic in a fixed order, no `mul_add`: the same inputs give
//! the same trajectory on every machine. Fitness is minimised.

use crate::synth::rng::Stream;

/// When the swarm's `g` is updated (docs/methods.md §4.3 "Update order", a reconstructed gap).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UpdateOrder {
    /// Every particle moves using `p(t−1)`, `g(t−1)`; `g` is updated once all are evaluated (default).
    Synchronous,
    /// `g` is updated right after each particle's evaluation, so later particles of the same
    /// iteration already follow it.
    Asynchronous,
}

/// What happens to the swarm after a chaos search (docs/methods.md §4.3 step 4, a reconstructed gap).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rediversify {
    /// The worse half of the particles restart at the next chaotic points (default).
    WorseHalf,
    /// Only `g` is replaced; the (collapsed) swarm is left as it is.
    None,
}

/// The chaos part of CPSO.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChaosParams {
    /// `T`: premature when the mean particle distance (relative to the box diagonal) is below this …
    pub distance_threshold: f64,
    /// … and the normalised fitness variance (eqs. 4–5) is below `S`.
    pub variance_threshold: f64,
    /// `μ` of the logistic map `z ← μ·z·(1 − z)`.
    pub mu: f64,
    /// `N_c`: chaotic points evaluated per chaos search.
    pub steps: u32,
    pub rediversify: Rediversify,
}

/// Swarm parameters (docs/methods.md §4.6).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SwarmParams {
    /// `M`.
    pub particles: usize,
    /// `T_max`: iterations after the initial evaluation (iteration 0).
    pub max_iterations: u32,
    pub c1: f64,
    pub c2: f64,
    /// `ω`.
    pub inertia: f64,
    /// `v_max,k = vmax_fraction · (hi_k − lo_k)`.
    pub vmax_fraction: f64,
    /// `δ`: stop as soon as the best fitness is `< δ`. `None`: never stop early.
    pub stop_below: Option<f64>,
    pub update: UpdateOrder,
    /// `None`: plain PSO.
    pub chaos: Option<ChaosParams>,
    /// Record every particle position after every iteration (tests).
    pub trace: bool,
}

/// The result of one optimisation.
#[derive(Clone, Debug, PartialEq)]
pub struct Outcome {
    /// `g`, the best position found (continuous; the caller rounds it the way its fitness does).
    pub best: Vec<f64>,
    pub best_fitness: f64,
    /// The last iteration run (`0..=T_max`).
    pub iterations: u32,
    /// The iteration at which the final best was first reached; a best found by a chaos search
    /// counts as reached at the iteration after which that search ran.
    pub best_iteration: u32,
    /// Chaos searches run.
    pub chaos_searches: u32,
    /// The iteration after which the first chaos search ran.
    pub first_chaos: Option<u32>,
    /// Fitness evaluations (swarm, chaotic points and re-diversified particles).
    pub evaluations: u64,
    /// Stopped because the best fitness fell below `δ`.
    pub stopped_early: bool,
    /// With [`SwarmParams::trace`]: `(iteration, all positions flattened particle by particle)`
    /// after each iteration's moves (and after each re-diversification, under the same iteration).
    pub trace: Vec<(u32, Vec<f64>)>,
}

/// The values of `z` the logistic map `μ·z·(1 − z)` sends onto a fixed point within one or two
/// steps: the fixed points `0` and `1 − 1/μ`, their pre-images `1` and `1/μ`, and, for `μ ≥ 4`,
/// the points mapped onto `1`. A chaotic sequence must not start there (§4.3 step 1). For `μ = 4`
/// this is `{0, 0.25, 0.5, 0.75, 1}`.
pub fn logistic_traps(mu: f64) -> Vec<f64> {
    let mut t = vec![0.0, 1.0, 1.0 - 1.0 / mu, 1.0 / mu];
    if mu >= 4.0 {
        let r = (1.0 - 4.0 / mu).sqrt();
        t.push((1.0 - r) / 2.0);
        t.push((1.0 + r) / 2.0);
    }
    t
}

/// A chaotic start value: `uniform_f64()`, re-drawn while within `1e−9` of a trap.
fn draw_z(stream: &mut Stream, traps: &[f64]) -> f64 {
    loop {
        let z = stream.uniform_f64();
        if traps.iter().all(|t| (z - t).abs() >= 1e-9) {
            return z;
        }
    }
}

/// One step of the logistic map, re-drawing a value that collapsed onto 0 or 1.
fn logistic_step(z: f64, mu: f64, stream: &mut Stream, traps: &[f64]) -> f64 {
    let next = mu * z * (1.0 - z);
    if !(1e-12..=1.0 - 1e-12).contains(&next) { draw_z(stream, traps) } else { next }
}

/// Minimises `fitness` over the box `[lo, hi]` (docs/methods.md §4.3). `swarm` supplies the
/// initialisation and every `η`; `chaos` is drawn from only inside chaos searches. Ties between
/// particles go to the lowest index; every improvement must be strict.
pub fn optimise(
    lo: &[f64],
    hi: &[f64],
    params: &SwarmParams,
    swarm: &mut Stream,
    chaos: &mut Stream,
    mut fitness: impl FnMut(&[f64]) -> f64,
) -> Outcome {
    let d = lo.len();
    assert_eq!(d, hi.len(), "bounds of different dimensions");
    assert!(params.particles >= 1, "a swarm needs at least one particle");
    let m = params.particles;
    let vmax: Vec<f64> = (0..d).map(|k| params.vmax_fraction * (hi[k] - lo[k])).collect();
    let diagonal = (0..d).map(|k| (hi[k] - lo[k]) * (hi[k] - lo[k])).sum::<f64>().sqrt();
    let below_delta = |f: f64| params.stop_below.is_some_and(|delta| f < delta);

    // Initialisation: for each particle, its position then its velocity, dimension by dimension.
    let mut x = vec![0.0; m * d];
    let mut v = vec![0.0; m * d];
    for i in 0..m {
        for k in 0..d {
            x[i * d + k] = swarm.uniform_range(lo[k], hi[k]);
        }
        for k in 0..d {
            v[i * d + k] = swarm.uniform_range(-vmax[k], vmax[k]);
        }
    }
    let mut evaluations = 0u64;
    let mut f: Vec<f64> = (0..m)
        .map(|i| {
            evaluations += 1;
            fitness(&x[i * d..(i + 1) * d])
        })
        .collect();
    let mut p = x.clone();
    let mut pf = f.clone();
    let first = argmin(&pf);
    let mut g = p[first * d..(first + 1) * d].to_vec();
    let mut gf = pf[first];
    let mut out = Outcome {
        best: Vec::new(),
        best_fitness: 0.0,
        iterations: 0,
        best_iteration: 0,
        chaos_searches: 0,
        first_chaos: None,
        evaluations: 0,
        stopped_early: false,
        trace: Vec::new(),
    };
    if params.trace {
        out.trace.push((0, x.clone()));
    }
    let traps = params.chaos.map(|c| logistic_traps(c.mu)).unwrap_or_default();

    let mut t = 0;
    let mut stopped = below_delta(gf);
    while !stopped && t < params.max_iterations {
        t += 1;
        let g_before = gf;
        for i in 0..m {
            for k in 0..d {
                let j = i * d + k;
                let eta1 = swarm.uniform_f64();
                let eta2 = swarm.uniform_f64();
                let mut vel = params.inertia * v[j] + params.c1 * eta1 * (p[j] - x[j]) + params.c2 * eta2 * (g[k] - x[j]);
                if vel > vmax[k] {
                    vel = vmax[k];
                } else if vel < -vmax[k] {
                    vel = -vmax[k];
                }
                let mut pos = x[j] + vel;
                if pos < lo[k] {
                    pos = lo[k];
                    vel = 0.0;
                } else if pos > hi[k] {
                    pos = hi[k];
                    vel = 0.0;
                }
                x[j] = pos;
                v[j] = vel;
            }
            if params.update == UpdateOrder::Asynchronous {
                evaluations += 1;
                f[i] = fitness(&x[i * d..(i + 1) * d]);
                if f[i] < pf[i] {
                    pf[i] = f[i];
                    p[i * d..(i + 1) * d].copy_from_slice(&x[i * d..(i + 1) * d]);
                }
                if pf[i] < gf {
                    gf = pf[i];
                    g.copy_from_slice(&p[i * d..(i + 1) * d]);
                }
            }
        }
        if params.update == UpdateOrder::Synchronous {
            for i in 0..m {
                evaluations += 1;
                f[i] = fitness(&x[i * d..(i + 1) * d]);
                if f[i] < pf[i] {
                    pf[i] = f[i];
                    p[i * d..(i + 1) * d].copy_from_slice(&x[i * d..(i + 1) * d]);
                }
            }
            let b = argmin(&pf);
            if pf[b] < gf {
                gf = pf[b];
                g.copy_from_slice(&p[b * d..(b + 1) * d]);
            }
        }
        if params.trace {
            out.trace.push((t, x.clone()));
        }
        if gf < g_before {
            out.best_iteration = t;
        }
        if below_delta(gf) {
            stopped = true;
            break;
        }
        let Some(cp) = params.chaos else { continue };
        if !premature(&x, &f, d, diagonal, &cp) {
            continue;
        }
        // Chaos search (§4.3 steps 1–3).
        out.chaos_searches += 1;
        out.first_chaos.get_or_insert(t);
        let mut z: Vec<f64> = (0..d).map(|_| draw_z(chaos, &traps)).collect();
        let mut point = vec![0.0; d];
        let mut best_chaos: Option<(f64, Vec<f64>)> = None;
        for _ in 0..cp.steps {
            for k in 0..d {
                z[k] = logistic_step(z[k], cp.mu, chaos, &traps);
                point[k] = lo[k] + (hi[k] - lo[k]) * z[k];
            }
            evaluations += 1;
            let fc = fitness(&point);
            if best_chaos.as_ref().is_none_or(|(bf, _)| fc < *bf) {
                best_chaos = Some((fc, point.clone()));
            }
            if below_delta(fc) {
                break;
            }
        }
        let g_before = gf;
        if let Some((bf, bp)) = best_chaos
            && bf < gf
        {
            gf = bf;
            g = bp;
        }
        if below_delta(gf) {
            out.best_iteration = t;
            stopped = true;
            break;
        }
        // Re-diversification (step 4): the worse half restarts at the next chaotic points.
        if cp.rediversify == Rediversify::WorseHalf {
            let mut order: Vec<usize> = (0..m).collect();
            order.sort_by(|&a, &b| f[a].total_cmp(&f[b]).then(a.cmp(&b)));
            let count = (m / 2).max(1);
            let mut restart: Vec<usize> = order[m - count..].to_vec();
            restart.sort_unstable();
            for &i in &restart {
                for k in 0..d {
                    z[k] = logistic_step(z[k], cp.mu, chaos, &traps);
                    x[i * d + k] = lo[k] + (hi[k] - lo[k]) * z[k];
                }
                for k in 0..d {
                    v[i * d + k] = chaos.uniform_range(-vmax[k], vmax[k]);
                }
                evaluations += 1;
                f[i] = fitness(&x[i * d..(i + 1) * d]);
                pf[i] = f[i];
                p[i * d..(i + 1) * d].copy_from_slice(&x[i * d..(i + 1) * d]);
            }
            // g from the new positions, by the strict rule (ties: lowest index).
            if let Some(&b) = restart.iter().min_by(|&&a, &&b| f[a].total_cmp(&f[b]).then(a.cmp(&b)))
                && f[b] < gf
            {
                gf = f[b];
                g.copy_from_slice(&x[b * d..(b + 1) * d]);
            }
            if params.trace {
                out.trace.push((t, x.clone()));
            }
        }
        if gf < g_before {
            out.best_iteration = t;
        }
        if below_delta(gf) {
            stopped = true;
        }
    }
    out.best = g;
    out.best_fitness = gf;
    out.iterations = t;
    out.evaluations = evaluations;
    out.stopped_early = stopped;
    out
}

/// Index of the smallest value, the first one on ties.
fn argmin(values: &[f64]) -> usize {
    let mut best = 0;
    for (i, v) in values.iter().enumerate() {
        if *v < values[best] {
            best = i;
        }
    }
    best
}

/// The premature-convergence test (eqs. 3–5): mean particle distance relative to the box
/// diagonal below `T` and normalised fitness variance below `S`. The variance is decided first:
/// it is cheap and, until the whole swarm has the same fitness, at least 1, so the distance is
/// rarely needed (the conjunction is the same either way).
pub fn premature(x: &[f64], f: &[f64], d: usize, diagonal: f64, cp: &ChaosParams) -> bool {
    variance_below(f, cp.variance_threshold) && mean_distance(x, f.len(), d, diagonal) < cp.distance_threshold
}

/// `σ² < threshold` (eqs. 4–5), deciding without the divisions where it can: with a spread above 1
/// the most distant particle's term is `(±spread / spread)² = 1` exactly and the others are
/// squares, so `σ² ≥ 1` and a threshold of at most 1 is not met. The test runs after every
/// iteration of every block, and this is its usual case.
fn variance_below(f: &[f64], threshold: f64) -> bool {
    let m = f.len();
    let favg = f.iter().sum::<f64>() / m as f64;
    let spread = f.iter().map(|fi| (fi - favg).abs()).fold(0.0, f64::max);
    if spread > 1.0 && threshold <= 1.0 {
        return false;
    }
    normalised_variance(f) < threshold
}

/// `(dis, σ²)` of eqs. 3–5 for the positions `x` (`M × D`, particle-major) and fitness values `f`.
/// A box of zero diagonal (a single point) has `dis = 0`.
pub fn convergence_measures(x: &[f64], f: &[f64], d: usize, diagonal: f64) -> (f64, f64) {
    (mean_distance(x, f.len(), d, diagonal), normalised_variance(f))
}

/// `dis` of eq. 3: the mean distance of the `m` particles from their centroid over the diagonal.
fn mean_distance(x: &[f64], m: usize, d: usize, diagonal: f64) -> f64 {
    let mut mean = vec![0.0; d];
    for i in 0..m {
        for k in 0..d {
            mean[k] += x[i * d + k];
        }
    }
    for mk in &mut mean {
        *mk /= m as f64;
    }
    let mut total = 0.0;
    for i in 0..m {
        let mut s = 0.0;
        for k in 0..d {
            let e = x[i * d + k] - mean[k];
            s += e * e;
        }
        total += s.sqrt();
    }
    if diagonal > 0.0 { total / (m as f64 * diagonal) } else { 0.0 }
}

/// `σ²` of eqs. 4–5: the fitness variance normalised by the largest deviation (at least 1).
fn normalised_variance(f: &[f64]) -> f64 {
    let m = f.len();
    let favg = f.iter().sum::<f64>() / m as f64;
    let spread = f.iter().map(|fi| (fi - favg).abs()).fold(0.0, f64::max);
    let fs = if spread > 1.0 { spread } else { 1.0 };
    f.iter().map(|fi| ((fi - favg) / fs) * ((fi - favg) / fs)).sum::<f64>()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params(chaos: Option<ChaosParams>) -> SwarmParams {
        SwarmParams {
            particles: 20,
            max_iterations: 300,
            c1: 1.47,
            c2: 1.47,
            inertia: 0.729,
            vmax_fraction: 0.2,
            stop_below: None,
            update: UpdateOrder::Synchronous,
            chaos,
            trace: true,
        }
    }

    fn chaos() -> ChaosParams {
        ChaosParams { distance_threshold: 0.01, variance_threshold: 0.001, mu: 4.0, steps: 200, rediversify: Rediversify::WorseHalf }
    }

    /// A rugged 2-D integer landscape like the texture objective: the value at the rounded position.
    fn rugged(x: &[f64]) -> f64 {
        let (a, b) = (x[0].round() as i64, x[1].round() as i64);
        ((a * 37 + b * 101) % 97 + (a - 60).abs() + (b - 20).abs()) as f64
    }

    fn run(p: &SwarmParams, seed: u64) -> Outcome {
        optimise(&[0.0, 0.0], &[226.0, 226.0], p, &mut Stream::new(seed, "swarm"), &mut Stream::new(seed, "chaos"), rugged)
    }

    #[test]
    fn logistic_traps_for_mu_4() {
        let mut t = logistic_traps(4.0);
        t.sort_by(f64::total_cmp);
        t.dedup();
        assert_eq!(t, vec![0.0, 0.25, 0.5, 0.75, 1.0]);
    }

    #[test]
    fn cpso_with_chaos_disabled_is_pso_draw_for_draw() {
        for seed in 1..6 {
            let pso = run(&params(None), seed);
            // Thresholds of zero: the test can never fire.
            let never = ChaosParams { distance_threshold: 0.0, variance_threshold: 0.0, ..chaos() };
            let cpso = run(&params(Some(never)), seed);
            assert_eq!(cpso.chaos_searches, 0);
            assert_eq!(pso, cpso, "seed {seed}");
        }
    }

    #[test]
    fn cpso_coincides_with_pso_until_the_first_chaos_search() {
        let mut fired = 0;
        for seed in 1..20 {
            let pso = run(&params(None), seed);
            let cpso = run(&params(Some(chaos())), seed);
            let Some(t0) = cpso.first_chaos else { continue };
            fired += 1;
            // Identical trajectories up to and including iteration t0 (the chaos search runs after it).
            for t in 0..=t0 as usize {
                assert_eq!(pso.trace[t], cpso.trace[t], "seed {seed}, iteration {t}");
            }
            assert_ne!(pso.trace[t0 as usize + 1], cpso.trace[t0 as usize + 1], "seed {seed}: the chaos search changes the swarm");
        }
        assert!(fired > 0, "the test fired on no seed; the comparison is empty");
    }

    #[test]
    fn early_stop_and_iteration_accounting() {
        let mut p = params(None);
        p.stop_below = Some(1e9);
        let o = run(&p, 3);
        assert_eq!(o.iterations, 0);
        assert!(o.stopped_early);
        assert_eq!(o.evaluations, 20);
        p.stop_below = None;
        p.max_iterations = 7;
        let o = run(&p, 3);
        assert_eq!(o.iterations, 7);
        assert_eq!(o.evaluations, 20 * 8);
        assert!(o.best_iteration <= 7);
        assert_eq!(o.best_fitness, rugged(&o.best));
    }

    #[test]
    fn positions_stay_in_the_box_and_asynchronous_differs() {
        let mut p = params(Some(chaos()));
        let sync = run(&p, 5);
        for (_, xs) in &sync.trace {
            assert!(xs.iter().all(|v| (0.0..=226.0).contains(v)));
        }
        p.update = UpdateOrder::Asynchronous;
        let asy = run(&p, 5);
        assert_eq!(sync.trace[0], asy.trace[0]);
        assert_ne!(sync.trace, asy.trace);
    }

    #[test]
    fn the_variance_shortcut_decides_as_the_full_sum() {
        let mut s = Stream::new(4, "test/variance");
        let mut cases: Vec<Vec<f64>> = vec![vec![7.0; 20], vec![0.25, 0.75], vec![3.0, 4.0, 3.0], vec![1e7, 1e7 + 1.0, 1e7 + 3.0]];
        for _ in 0..500 {
            let (m, range) = (1 + s.below(30) as usize, [1, 2, 3, 1000][s.below(4) as usize]);
            let fraction = s.below(2) as f64;
            cases.push((0..m).map(|_| s.below(range) as f64 + fraction * s.uniform_f64()).collect());
        }
        for f in &cases {
            for t in [0.0, 0.001, 0.5, 1.0, 1.5, 2.0, 1e12] {
                assert_eq!(variance_below(f, t), normalised_variance(f) < t, "{f:?}, threshold {t}");
            }
        }
    }

    #[test]
    fn convergence_measures_follow_eqs_3_to_5() {
        // All particles at one point with equal fitness: dis = 0, σ² = 0.
        let (dis, var) = convergence_measures(&[3.0, 4.0, 3.0, 4.0], &[5.0, 5.0], 2, 10.0);
        assert_eq!((dis, var), (0.0, 0.0));
        // Two particles 2 apart on a box of diagonal 10: each is 1 from the mean → dis = 2/(2·10).
        // Fitness 0 and 4: f_avg = 2, f_s = 2, σ² = 1 + 1.
        let (dis, var) = convergence_measures(&[0.0, 0.0, 2.0, 0.0], &[0.0, 4.0], 2, 10.0);
        assert_eq!(dis, 0.1);
        assert_eq!(var, 2.0);
        // Spread ≤ 1: f_s = 1, σ² is the plain sum of squares.
        let (_, var) = convergence_measures(&[0.0, 0.0], &[0.25, 0.75], 1, 1.0);
        assert_eq!(var, 0.125);
    }
}
