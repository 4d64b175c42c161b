//! Paper 002, Table 1 (docs/methods.md §4.5): PSO vs chaos PSO minimising four 30-dimensional test
//! functions, 30 independent runs each, 600 iterations, 20 particles, c1 = c2 = 1.47, ω = 0.729,
//! chaos search at most 200 steps, T = 0.01, S = 0.001, μ = 4, continuous positions.
//!
//! ```sh
//! cargo run --release --example 06_function_optimisation            # the table
//! cargo run --release --example 06_function_optimisation -- --runs 5 # quicker
//! ```
//!
//! Run `r` of function `f` draws its swarm from the stream `cpso/bench/{f}/run={r}` and its chaos
//! searches from `cpso/bench/{f}/run={r}/chaos` (seed 2010), so PSO and CPSO start from the same
//! swarm and coincide until CPSO's first chaos search. The paper's claim to check: CPSO's spread
//! (worst − best over the runs) is smaller and its mean better than PSO's on all four functions.

use std::f64::consts::{E, PI};
use texsyn::synth::primitives::pso::{self, ChaosParams, Outcome, Rediversify, SwarmParams, UpdateOrder};
use texsyn::synth::rng::Stream;

const DIMS: usize = 30;
const SEED: u64 = 2010;

struct Function {
    name: &'static str,
    range: f64,
    f: fn(&[f64]) -> f64,
}

fn ackley(x: &[f64]) -> f64 {
    let n = x.len() as f64;
    let sq = x.iter().map(|v| v * v).sum::<f64>() / n;
    let cos = x.iter().map(|v| (2.0 * PI * v).cos()).sum::<f64>() / n;
    -20.0 * (-0.2 * sq.sqrt()).exp() - cos.exp() + 20.0 + E
}

fn griewank(x: &[f64]) -> f64 {
    let sum = x.iter().map(|v| v * v).sum::<f64>() / 4000.0;
    let prod = x.iter().enumerate().map(|(i, v)| (v / ((i + 1) as f64).sqrt()).cos()).product::<f64>();
    sum - prod + 1.0
}

fn quadric(x: &[f64]) -> f64 {
    let mut partial = 0.0;
    let mut total = 0.0;
    for v in x {
        partial += v;
        total += partial * partial;
    }
    total
}

fn rosenbrock(x: &[f64]) -> f64 {
    x.windows(2).map(|w| 100.0 * (w[1] - w[0] * w[0]).powi(2) + (w[0] - 1.0).powi(2)).sum()
}

const FUNCTIONS: &[Function] = &[
    Function { name: "Ackley", range: 30.0, f: ackley },
    Function { name: "Griewank", range: 300.0, f: griewank },
    Function { name: "Rosenbrock", range: 50.0, f: rosenbrock },
    Function { name: "Quadric", range: 100.0, f: quadric },
];

fn params(chaos: bool) -> SwarmParams {
    SwarmParams {
        particles: 20,
        max_iterations: 600,
        c1: 1.47,
        c2: 1.47,
        inertia: 0.729,
        vmax_fraction: 0.2,
        stop_below: None,
        update: UpdateOrder::Synchronous,
        chaos: chaos.then_some(ChaosParams {
            distance_threshold: 0.01,
            variance_threshold: 0.001,
            mu: 4.0,
            steps: 200,
            rediversify: Rediversify::WorseHalf,
        }),
        trace: false,
    }
}

fn run(func: &Function, r: u32, chaos: bool) -> Outcome {
    let lo = vec![-func.range; DIMS];
    let hi = vec![func.range; DIMS];
    let label = format!("cpso/bench/{}/run={r}", func.name.to_lowercase());
    let mut swarm = Stream::new(SEED, &label);
    let mut chaos_stream = Stream::new(SEED, &format!("{label}/chaos"));
    pso::optimise(&lo, &hi, &params(chaos), &mut swarm, &mut chaos_stream, func.f)
}

struct Stats {
    max: f64,
    min: f64,
    mean: f64,
    sd: f64,
    chaos_runs: usize,
    chaos_searches: u32,
}

fn stats(outcomes: &[Outcome]) -> Stats {
    let v: Vec<f64> = outcomes.iter().map(|o| o.best_fitness).collect();
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let sd = if v.len() > 1 { (v.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1.0)).sqrt() } else { 0.0 };
    Stats {
        max: v.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        min: v.iter().copied().fold(f64::INFINITY, f64::min),
        mean,
        sd,
        chaos_runs: outcomes.iter().filter(|o| o.chaos_searches > 0).count(),
        chaos_searches: outcomes.iter().map(|o| o.chaos_searches).sum(),
    }
}

fn main() {
    let mut runs = 30u32;
    let args: Vec<String> = std::env::args().collect();
    if let Some(i) = args.iter().position(|a| a == "--runs") {
        runs = args.get(i + 1).and_then(|v| v.parse().ok()).expect("--runs N");
    }
    println!("Paper 002, Table 1: best fitness over {runs} runs, {DIMS} dimensions, 600 iterations, 20 particles");
    println!("(c1 = c2 = 1.47, ω = 0.729, v_max = 0.2·range, T = 0.01, S = 0.001, μ = 4, N_c = 200; seed {SEED})\n");
    println!("| algorithm | value | {} |", FUNCTIONS.iter().map(|f| f.name).collect::<Vec<_>>().join(" | "));
    println!("|---|---|{}", "---|".repeat(FUNCTIONS.len()));
    let mut all: Vec<(Stats, Stats)> = Vec::new();
    for func in FUNCTIONS {
        let pso: Vec<Outcome> = (0..runs).map(|r| run(func, r, false)).collect();
        let cpso: Vec<Outcome> = (0..runs).map(|r| run(func, r, true)).collect();
        all.push((stats(&pso), stats(&cpso)));
    }
    let row = |alg: &str, what: &str, pick: &dyn Fn(&(Stats, Stats)) -> f64| {
        let cells: Vec<String> = all.iter().map(|s| format!("{:.4e}", pick(s))).collect();
        println!("| {alg} | {what} | {} |", cells.join(" | "));
    };
    row("PSO", "max", &|s| s.0.max);
    row("PSO", "min", &|s| s.0.min);
    row("PSO", "mean", &|s| s.0.mean);
    row("PSO", "std", &|s| s.0.sd);
    row("CPSO", "max", &|s| s.1.max);
    row("CPSO", "min", &|s| s.1.min);
    row("CPSO", "mean", &|s| s.1.mean);
    row("CPSO", "std", &|s| s.1.sd);
    println!("| range | | {} |", FUNCTIONS.iter().map(|f| format!("[−{0}, {0}]", f.range)).collect::<Vec<_>>().join(" | "));
    println!();
    println!("| function | CPSO runs with a chaos search | chaos searches | spread PSO | spread CPSO | smaller spread | better mean |");
    println!("|---|---|---|---|---|---|---|");
    let mut claim = true;
    for (func, (p, c)) in FUNCTIONS.iter().zip(&all) {
        let (sp, sc) = (p.max - p.min, c.max - c.min);
        let spread = sc < sp;
        let mean = c.mean < p.mean;
        claim &= spread && mean;
        println!(
            "| {} | {}/{runs} | {} | {:.4e} | {:.4e} | {} | {} |",
            func.name,
            c.chaos_runs,
            c.chaos_searches,
            sp,
            sc,
            if spread { "yes" } else { "no" },
            if mean { "yes" } else { "no" }
        );
    }
    println!(
        "\nPaper's claim (CPSO: smaller spread and better mean on all four functions): {}",
        if claim { "holds" } else { "does NOT hold on every function" }
    );
}
