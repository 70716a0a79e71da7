//! Max-flow and alpha-expansion benchmarks on grid MRFs (thesis 4.2.2, 4.4).
//! Run: `cargo bench -p motif-retarget --bench mrf -- --warm-up-time 1 --measurement-time 5`.
//!
//! - `grid/*`: `mrf_grid_v1` problems solved from the argmin start: the shipped 10³ example and
//!   generated ones (`generate_grid`, seed 1), with full, adaptive and queue (the default) cycles. Peers' GCO times on this machine's kind, same
//!   generator: 11.7 ms (10³, 8 labels, 6-conn.), 61 ms (26-conn.), 469 ms (20³, 30 labels,
//!   6-conn.), 4.7 s (26-conn.). 30³ × 64 labels is timed by `examples/mrf_timing.rs`.
//! - `retarget_callback/*`: the thesis's interactive size, ~1000 voxels × 30 offset labels on a
//!   26-connected grid, with an f64 pairwise callback shaped like eq. 4.4 and +∞ costs.
//! - `maxflow/*`: one Boykov–Kolmogorov cut of a random 3D grid graph, fresh and with tree reuse.
//!
//! Each problem's energies are printed once before it is measured.

use std::hint::black_box;
use std::path::PathBuf;

use criterion::{Criterion, criterion_group, criterion_main};
use motif_retarget::alpha_expansion::{AlphaExpansion, AlphaExpansionOptions, CycleStrategy, MrfEnergy};
use motif_retarget::maxflow::Graph;
use motif_retarget::mrf_grid::{Connectivity, GridProblem, generate_grid};
use rand::{Rng, SeedableRng};

fn shipped_example() -> Option<GridProblem> {
    let rel = "shared/formats/examples/mrf_10x10x10_L8_c6.json";
    let path: PathBuf = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .map(|a| a.join(rel))
        .find(|p| p.is_file())?;
    GridProblem::from_json_bytes(&std::fs::read(path).ok()?).ok()
}

fn grid(c: &mut Criterion) {
    let mut cases: Vec<(String, GridProblem, usize)> = Vec::new();
    if let Some(p) = shipped_example() {
        cases.push(("shipped_10x10x10_L8_c6".into(), p, 30));
    }
    for (dims, labels, conn, samples) in [
        ([10, 10, 10], 8, Connectivity::Six, 30),
        ([10, 10, 10], 8, Connectivity::TwentySix, 20),
        ([20, 20, 20], 30, Connectivity::Six, 10),
        ([20, 20, 20], 30, Connectivity::TwentySix, 10),
    ] {
        let name = format!("gen_{0}x{0}x{0}_L{1}_c{2}", dims[0], labels, conn.number());
        cases.push((name, generate_grid(dims, labels, conn, 1), samples));
    }
    let full = AlphaExpansionOptions { cycles: CycleStrategy::Full, ..Default::default() };
    let adaptive = AlphaExpansionOptions { cycles: CycleStrategy::Adaptive, ..Default::default() };
    let queue = AlphaExpansionOptions { cycles: CycleStrategy::Queue, ..Default::default() };
    let mut g = c.benchmark_group("grid");
    for (name, problem, samples) in &cases {
        for (strategy, options) in [("full", &full), ("adaptive", &adaptive), ("queue", &queue)] {
            let name = format!("{name}_{strategy}");
            g.sample_size(*samples);
            let printed = std::cell::Cell::new(false);
            g.bench_function(name.as_str(), |b| {
                if !printed.replace(true) {
                    match problem.solve(options) {
                        Ok(s) => eprintln!(
                            "grid/{name}: initial energy {}, final energy {}, {} cycles, {} moves",
                            s.initial_energy, s.energy, s.cycles, s.moves
                        ),
                        Err(e) => eprintln!("grid/{name}: {e}"),
                    }
                }
                b.iter(|| problem.solve(black_box(options)))
            });
        }
    }
    g.finish();
}

/// A retargeting-shaped energy (thesis eq. 4.3, 4.4): a 10×10×10 target grid Ω, 30 offset
/// labels l = (u, v, w), voxel x copies input voxel x − l of a 6×6×6 input. The input is a
/// repetitive structure (periods 1, 2, 4 along the axes, matching the offsets) with noisy scalar
/// "descriptors", a periodic pattern of empty voxels, and 2 % random empty defects.
/// D_x(l) = +∞ when x − l leaves the input, else 0.
/// V(x, x', l, l') = d(x, l, l') + d(x', l, l'), where d compares the descriptors copied from
/// x − l and x − l' (0 if both empty, +∞ if one is): a metric with infinities. As a real caller
/// would, the callbacks read precomputed tables (source voxel per site and label).
struct Retarget {
    edges: Vec<[u32; 2]>,
    num_labels: usize,
    /// Input voxel copied into site p under label l (`p·L + l`), `u32::MAX` outside the input.
    source: Vec<u32>,
    /// Descriptor of each input voxel (NaN = empty).
    input: Vec<f64>,
}

const OMEGA: i64 = 10;
const INPUT: i64 = 6;

impl Retarget {
    fn new(seed: u64) -> Self {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut input = Vec::new();
        for _x in 0..INPUT {
            for y in 0..INPUT {
                for z in 0..INPUT {
                    let empty = (y % 2 == 1 && z % 4 == 3) || rng.random_bool(0.0);
                    let base = [0.1, 0.5][y as usize % 2] + 0.2 * (z % 4) as f64;
                    input.push(if empty { f64::NAN } else { base + rng.random_range(-0.05..0.05) });
                }
            }
        }
        let mut offsets = Vec::new();
        for u in 0..5 {
            for v in [0, 2, 4] {
                for w in [0, 4] {
                    offsets.push([u, v, w]);
                }
            }
        }
        let n = (OMEGA * OMEGA * OMEGA) as usize;
        let mut source = Vec::with_capacity(n * offsets.len());
        for p in 0..n as i64 {
            let x = [p / (OMEGA * OMEGA), (p / OMEGA) % OMEGA, p % OMEGA];
            for o in &offsets {
                let s = [x[0] - o[0], x[1] - o[1], x[2] - o[2]];
                source.push(if s.iter().all(|&c| (0..INPUT).contains(&c)) {
                    ((s[0] * INPUT + s[1]) * INPUT + s[2]) as u32
                } else {
                    u32::MAX
                });
            }
        }
        let p = generate_grid([OMEGA as usize; 3], 1, Connectivity::TwentySix, 0);
        Retarget { edges: p.edges(), num_labels: offsets.len(), source, input }
    }

    #[inline]
    fn descriptor(&self, p: usize, l: usize) -> f64 {
        match self.source[p * self.num_labels + l] {
            u32::MAX => f64::NAN,
            s => self.input[s as usize],
        }
    }

    #[inline]
    fn descriptor_distance(&self, p: usize, a: usize, b: usize) -> f64 {
        let (x, y) = (self.descriptor(p, a), self.descriptor(p, b));
        match (x.is_nan(), y.is_nan()) {
            (false, false) => (x - y).abs(),
            (true, true) => 0.0,
            _ => f64::INFINITY,
        }
    }

    fn solve(
        &self,
        solver: &mut AlphaExpansion<f64>,
        init: &[u32],
    ) -> motif_retarget::AlphaExpansionResult<f64> {
        let l = self.num_labels;
        let energy = MrfEnergy::new(
            (OMEGA * OMEGA * OMEGA) as usize,
            l,
            &self.edges,
            |p, a| if self.source[p * l + a] == u32::MAX { f64::INFINITY } else { 0.0 },
            |p, q, a, b| {
                if a == b {
                    0.0
                } else {
                    self.descriptor_distance(p, a, b) + self.descriptor_distance(q, a, b)
                }
            },
        );
        // Errors are impossible here: the energy is well-formed by construction.
        solver.solve(&energy, init, &AlphaExpansionOptions::default()).unwrap_or_else(|e| panic!("{e}"))
    }

    /// A feasible start, as an application would use: for every site the first label valid on
    /// the site and all its neighbours (so that seams never compare a voxel with the outside).
    fn init(&self) -> Vec<u32> {
        let n = (OMEGA * OMEGA * OMEGA) as usize;
        let mut neighbours = vec![Vec::new(); n];
        for &[p, q] in &self.edges {
            neighbours[p as usize].push(q as usize);
            neighbours[q as usize].push(p as usize);
        }
        let valid = |p: usize, a: usize| self.source[p * self.num_labels + a] != u32::MAX;
        (0..n)
            .map(|p| {
                (0..self.num_labels)
                    .find(|&a| valid(p, a) && neighbours[p].iter().all(|&q| valid(q, a)))
                    .or_else(|| (0..self.num_labels).find(|&a| valid(p, a)))
                    .unwrap_or(0) as u32
            })
            .collect()
    }
}

fn retarget_callback(c: &mut Criterion) {
    let r = Retarget::new(4);
    let init = r.init();
    let mut solver = AlphaExpansion::new();
    let s = r.solve(&mut solver, &init);
    eprintln!(
        "retarget_callback/10x10x10_L30_c26: {} edges, initial energy {:e}, final energy {:.4}, {} cycles, {} moves",
        r.edges.len(),
        s.initial_energy,
        s.energy,
        s.cycles,
        s.moves
    );
    let mut g = c.benchmark_group("retarget_callback");
    g.sample_size(20);
    g.bench_function("10x10x10_L30_c26", |b| b.iter(|| r.solve(&mut solver, black_box(&init))));
    g.finish();
}

/// A 3D grid graph of 60×60×30 nodes (6-connected) with random terminal and edge capacities.
fn random_grid_graph(seed: u64) -> (Graph<i64>, Vec<(i64, i64)>) {
    let (nx, ny, nz) = (60usize, 60usize, 30usize);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let n = nx * ny * nz;
    let mut g = Graph::new(n, 3 * n);
    let mut tw = Vec::with_capacity(n);
    for v in 0..n {
        let t = (rng.random_range(0..100), rng.random_range(0..100));
        g.add_tweights(v, t.0, t.1);
        tw.push(t);
    }
    for x in 0..nx {
        for y in 0..ny {
            for z in 0..nz {
                let p = (x * ny + y) * nz + z;
                for (ok, q) in [(x + 1 < nx, p + ny * nz), (y + 1 < ny, p + nz), (z + 1 < nz, p + 1)] {
                    if ok {
                        g.add_edge(p, q, rng.random_range(0..50), rng.random_range(0..50));
                    }
                }
            }
        }
    }
    (g, tw)
}

fn maxflow(c: &mut Criterion) {
    let (base, _) = random_grid_graph(9);
    let mut g = c.benchmark_group("maxflow");
    g.sample_size(20);
    g.bench_function("grid_60x60x30_fresh", |b| {
        b.iter_batched(|| base.clone(), |mut graph| graph.maxflow(), criterion::BatchSize::LargeInput)
    });
    // Tree reuse: change 1 % of the terminal capacities of a solved graph and solve again.
    let mut solved = base.clone();
    solved.maxflow();
    let n = solved.num_nodes();
    g.bench_function("grid_60x60x30_reuse_1pct", |b| {
        b.iter_batched(
            || {
                let mut graph = solved.clone();
                let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
                for _ in 0..n / 100 {
                    graph.add_tweights(
                        rng.random_range(0..n),
                        rng.random_range(0..30),
                        rng.random_range(0..30),
                    );
                }
                graph
            },
            |mut graph| graph.maxflow_reuse(),
            criterion::BatchSize::LargeInput,
        )
    });
    g.bench_function("grid_60x60x30_no_reuse_1pct", |b| {
        b.iter_batched(
            || {
                let mut graph = solved.clone();
                let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
                for _ in 0..n / 100 {
                    graph.add_tweights(
                        rng.random_range(0..n),
                        rng.random_range(0..30),
                        rng.random_range(0..30),
                    );
                }
                graph
            },
            |mut graph| graph.maxflow(),
            criterion::BatchSize::LargeInput,
        )
    });
    g.finish();
}

criterion_group!(benches, grid, retarget_callback, maxflow);
criterion_main!(benches);
