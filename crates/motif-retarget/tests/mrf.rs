//! Integration tests of the MRF machinery: max-flow against petgraph's Dinic as an oracle,
//! alpha-expansion against brute force, and the `mrf_grid_v1` format.

use motif_retarget::alpha_expansion::{
    AlphaExpansion, AlphaExpansionOptions, CycleStrategy, LabelOrder, MrfEnergy, Termination, TieBreak,
    alpha_expansion, dense_unary, energy_of,
};
use motif_retarget::maxflow::{Graph, Segment};
use motif_retarget::mrf_grid::{Connectivity, GridProblem, InitLabels, generate_grid, solve_grid_file};
use motif_retarget::{Error, THESIS_CHAPTER};
use petgraph::algo::dinics;
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The shipped example, found in `shared/` beside the repository (or a parent of it).
fn example_path() -> std::path::PathBuf {
    let rel = "shared/formats/examples/mrf_10x10x10_L8_c6.json";
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .map(|a| a.join(rel))
        .find(|p| p.is_file())
        .unwrap_or_else(|| panic!("{rel} not found beside the repository"))
}

// ---------------------------------------------------------------------------------------------
// Max-flow
// ---------------------------------------------------------------------------------------------

/// A flow network given by its capacities, buildable both for our solver and for petgraph.
#[derive(Debug, Clone)]
struct Network {
    /// (source → v, v → sink) capacities.
    terminals: Vec<(u64, u64)>,
    /// (a, b, cap a → b, cap b → a).
    edges: Vec<(usize, usize, u64, u64)>,
}

impl Network {
    fn random(rng: &mut ChaCha8Rng, n: usize, edge_prob: f64, max_cap: u64, terminal_prob: f64) -> Self {
        let cap =
            |rng: &mut ChaCha8Rng, p: f64| if rng.random_bool(p) { rng.random_range(0..=max_cap) } else { 0 };
        let terminals = (0..n).map(|_| (cap(rng, terminal_prob), cap(rng, terminal_prob))).collect();
        let mut edges = Vec::new();
        for a in 0..n {
            for b in a + 1..n {
                if rng.random_bool(edge_prob) {
                    let c = rng.random_range(0..=max_cap);
                    let r = if rng.random_bool(0.5) { rng.random_range(0..=max_cap) } else { 0 };
                    // Random orientation, occasionally a parallel edge.
                    let (x, y) = if rng.random_bool(0.5) { (a, b) } else { (b, a) };
                    edges.push((x, y, c, r));
                    if rng.random_bool(0.05) {
                        edges.push((x, y, rng.random_range(0..=max_cap), 0));
                    }
                }
            }
        }
        Network { terminals, edges }
    }

    /// An nx × ny 4-connected grid with random capacities.
    fn grid(rng: &mut ChaCha8Rng, nx: usize, ny: usize, max_cap: u64) -> Self {
        let n = nx * ny;
        let terminals =
            (0..n).map(|_| (rng.random_range(0..=max_cap), rng.random_range(0..=max_cap))).collect();
        let mut edges = Vec::new();
        for x in 0..nx {
            for y in 0..ny {
                let p = x * ny + y;
                if x + 1 < nx {
                    edges.push((p, p + ny, rng.random_range(0..=max_cap), rng.random_range(0..=max_cap)));
                }
                if y + 1 < ny {
                    edges.push((p, p + 1, rng.random_range(0..=max_cap), rng.random_range(0..=max_cap)));
                }
            }
        }
        Network { terminals, edges }
    }

    fn ours(&self) -> Graph<i64> {
        let mut g = Graph::new(self.terminals.len(), self.edges.len());
        for (v, &(s, t)) in self.terminals.iter().enumerate() {
            g.add_tweights(v, s as i64, t as i64);
        }
        for &(a, b, c, r) in &self.edges {
            g.add_edge(a, b, c as i64, r as i64);
        }
        g
    }

    fn dinic_flow(&self) -> u64 {
        let mut pg = petgraph::Graph::<(), u64>::new();
        let nodes: Vec<_> = (0..self.terminals.len()).map(|_| pg.add_node(())).collect();
        let s = pg.add_node(());
        let t = pg.add_node(());
        for (v, &(cs, ct)) in self.terminals.iter().enumerate() {
            if cs > 0 {
                pg.add_edge(s, nodes[v], cs);
            }
            if ct > 0 {
                pg.add_edge(nodes[v], t, ct);
            }
        }
        for &(a, b, c, r) in &self.edges {
            pg.add_edge(nodes[a], nodes[b], c);
            pg.add_edge(nodes[b], nodes[a], r);
        }
        dinics(&pg, s, t).0
    }

    /// Capacity of the cut given by our segments, with the original capacities.
    fn cut_capacity(&self, g: &Graph<i64>) -> u64 {
        let side: Vec<Segment> = (0..self.terminals.len()).map(|v| g.what_segment(v)).collect();
        let mut cut = 0;
        for (v, &(cs, ct)) in self.terminals.iter().enumerate() {
            cut += if side[v] == Segment::Sink { cs } else { ct };
        }
        for &(a, b, c, r) in &self.edges {
            if side[a] == Segment::Source && side[b] == Segment::Sink {
                cut += c;
            }
            if side[b] == Segment::Source && side[a] == Segment::Sink {
                cut += r;
            }
        }
        cut
    }

    fn check(&self, what: &str) {
        let mut g = self.ours();
        let flow = g.maxflow();
        let oracle = self.dinic_flow();
        assert_eq!(flow as u64, oracle, "{what}: flow differs from Dinic");
        assert_eq!(self.cut_capacity(&g), oracle, "{what}: the cut is not minimal");
        // The other min cut (free nodes on the sink side) must be minimal too.
        let side_free_sink: Vec<Segment> =
            (0..self.terminals.len()).map(|v| g.what_segment_or(v, Segment::Sink)).collect();
        let mut cut = 0;
        for (v, &(cs, ct)) in self.terminals.iter().enumerate() {
            cut += if side_free_sink[v] == Segment::Sink { cs } else { ct };
        }
        for &(a, b, c, r) in &self.edges {
            if side_free_sink[a] == Segment::Source && side_free_sink[b] == Segment::Sink {
                cut += c;
            }
            if side_free_sink[b] == Segment::Source && side_free_sink[a] == Segment::Sink {
                cut += r;
            }
        }
        assert_eq!(cut, oracle, "{what}: the sink-biased cut is not minimal");
    }
}

#[test]
fn maxflow_matches_dinic_on_random_graphs() {
    let mut checked = 0;
    for seed in 0..600u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let n = rng.random_range(1..=70);
        let density = [0.02, 0.05, 0.1, 0.3, 0.7][seed as usize % 5];
        let max_cap = [1, 3, 10, 100, 10_000][(seed / 5) as usize % 5];
        let terminal_prob = rng.random_range(0.05..0.9);
        let net = Network::random(&mut rng, n, density, max_cap, terminal_prob);
        net.check(&format!("seed {seed} (n {n}, density {density}, max cap {max_cap})"));
        checked += 1;
    }
    assert_eq!(checked, 600);
}

#[test]
fn maxflow_matches_dinic_on_grids() {
    for seed in 0..60u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(1000 + seed);
        let (nx, ny) = (rng.random_range(1..=25), rng.random_range(1..=25));
        let max_cap = [5, 50, 1000][seed as usize % 3];
        Network::grid(&mut rng, nx, ny, max_cap).check(&format!("grid seed {seed} {nx}x{ny}"));
    }
}

#[test]
fn maxflow_f64_matches_i64() {
    for seed in 0..100u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(5000 + seed);
        let n = rng.random_range(2..=40);
        let net = Network::random(&mut rng, n, 0.15, 1000, 0.5);
        let exact = net.ours().maxflow();
        // The same capacities scaled by 1/8 (exactly representable) as f64.
        let mut g = Graph::<f64>::new(n, net.edges.len());
        for (v, &(s, t)) in net.terminals.iter().enumerate() {
            g.add_tweights(v, s as f64 / 8.0, t as f64 / 8.0);
        }
        for &(a, b, c, r) in &net.edges {
            g.add_edge(a, b, c as f64 / 8.0, r as f64 / 8.0);
        }
        assert_eq!(g.maxflow(), exact as f64 / 8.0, "seed {seed}");
    }
}

#[test]
fn maxflow_edge_cases() {
    // No nodes.
    let mut g = Graph::<i64>::new(0, 0);
    assert_eq!(g.maxflow(), 0);
    // No edges: each node's flow is min(source, sink).
    let mut g = Graph::<i64>::new(3, 0);
    g.add_tweights(0, 5, 3);
    g.add_tweights(1, 0, 4);
    g.add_tweights(2, 7, 0);
    assert_eq!(g.maxflow(), 3);
    assert_eq!(g.what_segment(0), Segment::Source);
    assert_eq!(g.what_segment(1), Segment::Sink);
    assert_eq!(g.what_segment(2), Segment::Source);
    // Zero capacities everywhere: every node is free (reported on the requested side).
    let mut g = Graph::<i64>::new(4, 3);
    for v in 0..3 {
        g.add_edge(v, v + 1, 0, 0);
    }
    assert_eq!(g.maxflow(), 0);
    assert!((0..4).all(|v| g.what_segment_or(v, Segment::Sink) == Segment::Sink));
    // Disconnected components.
    let net = Network {
        terminals: vec![(10, 0), (0, 0), (0, 10), (4, 0), (0, 0), (0, 9)],
        edges: vec![(0, 1, 3, 0), (1, 2, 7, 0), (3, 4, 8, 0), (4, 5, 2, 1)],
    };
    net.check("two components");
    assert_eq!(net.ours().maxflow(), 5);
    // Source and sink link on the same node only.
    let net = Network { terminals: vec![(6, 6)], edges: vec![] };
    net.check("direct terminals");
    // add_node after construction and add_edge after a max-flow keep the flow.
    let mut g = Graph::<i64>::new(1, 1);
    g.add_tweights(0, 5, 0);
    assert_eq!(g.maxflow(), 0);
    let v = g.add_node();
    g.add_tweights(v, 0, 3);
    g.add_edge(0, v, 2, 0);
    assert_eq!(g.maxflow(), 2);
    g.add_edge(0, v, 4, 0);
    assert_eq!(g.maxflow_reuse(), 3);
    // reset keeps nothing but the allocations.
    g.reset(2);
    assert_eq!((g.num_nodes(), g.num_edges(), g.flow()), (2, 0, 0));
}

/// Changes terminal capacities between runs and compares `maxflow_reuse` with a fresh solve.
#[test]
fn maxflow_reuse_matches_fresh_solves() {
    let mut rounds = 0;
    for seed in 0..150u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(9000 + seed);
        let n = rng.random_range(2..=50);
        let mut net = if seed % 3 == 0 {
            let (nx, ny) = (rng.random_range(1..=10), rng.random_range(2..=10));
            Network::grid(&mut rng, nx, ny, 50)
        } else {
            Network::random(&mut rng, n, 0.15, 50, 0.4)
        };
        let n = net.terminals.len();
        let mut g = net.ours();
        g.maxflow();
        for round in 0..6 {
            let changes = rng.random_range(1..=n.min(8));
            for _ in 0..changes {
                let v = rng.random_range(0..n);
                let (cs, ct) = net.terminals[v];
                // New totals, sometimes lower than before (negative increments).
                let ns = if rng.random_bool(0.3) { 0 } else { rng.random_range(0..=60) };
                let nt = if rng.random_bool(0.3) { 0 } else { rng.random_range(0..=60) };
                g.add_tweights(v, ns as i64 - cs as i64, nt as i64 - ct as i64);
                net.terminals[v] = (ns, nt);
            }
            let flow = g.maxflow_reuse();
            let oracle = net.dinic_flow();
            assert_eq!(flow as u64, oracle, "seed {seed} round {round}: reused flow differs");
            assert_eq!(net.cut_capacity(&g), oracle, "seed {seed} round {round}: reused cut not minimal");
            rounds += 1;
        }
    }
    assert_eq!(rounds, 900);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, .. ProptestConfig::default() })]
    #[test]
    fn maxflow_proptest(
        terminals in prop::collection::vec((0u64..20, 0u64..20), 1..12),
        raw_edges in prop::collection::vec((0usize..12, 0usize..12, 0u64..20, 0u64..20), 0..40),
    ) {
        let n = terminals.len();
        let edges = raw_edges
            .into_iter()
            .map(|(a, b, c, r)| (a % n, b % n, c, r))
            .filter(|&(a, b, _, _)| a != b)
            .collect();
        let net = Network { terminals, edges };
        let mut g = net.ours();
        let flow = g.maxflow();
        prop_assert_eq!(flow as u64, net.dinic_flow());
        prop_assert_eq!(net.cut_capacity(&g), flow as u64);
    }
}

// ---------------------------------------------------------------------------------------------
// Alpha-expansion
// ---------------------------------------------------------------------------------------------

/// A small random energy with explicit tables.
struct Tiny {
    n: usize,
    labels: usize,
    edges: Vec<[u32; 2]>,
    weights: Vec<i64>,
    unary: Vec<i64>,
    /// L×L label cost, scaled per edge by `weights`.
    v: Vec<i64>,
}

#[derive(Debug, Clone, Copy)]
enum PairKind {
    Potts,
    TruncatedLinear,
    RandomMetric,
}

impl Tiny {
    fn random(rng: &mut ChaCha8Rng, kind: PairKind, n: usize, labels: usize) -> Self {
        let mut edges = Vec::new();
        for a in 0..n as u32 {
            for b in a + 1..n as u32 {
                if rng.random_bool(0.5) {
                    edges.push(if rng.random_bool(0.5) { [a, b] } else { [b, a] });
                }
            }
        }
        let weights = edges.iter().map(|_| rng.random_range(1..=6)).collect();
        let unary = (0..n * labels).map(|_| rng.random_range(0..=30)).collect();
        let l = labels;
        let v = match kind {
            PairKind::Potts => (0..l * l).map(|i| if i / l == i % l { 0 } else { 5 }).collect(),
            PairKind::TruncatedLinear => {
                let (k, t) = (rng.random_range(1..=5), rng.random_range(1..=3) as usize);
                (0..l * l).map(|i| k * (i / l).abs_diff(i % l).min(t) as i64).collect()
            }
            PairKind::RandomMetric => {
                let mut m = vec![0i64; l * l];
                for a in 0..l {
                    for b in a + 1..l {
                        let x = rng.random_range(1..=12);
                        m[a * l + b] = x;
                        m[b * l + a] = x;
                    }
                }
                // Shortest-path closure makes it a metric.
                for k in 0..l {
                    for a in 0..l {
                        for b in 0..l {
                            let via = m[a * l + k] + m[k * l + b];
                            if via < m[a * l + b] {
                                m[a * l + b] = via;
                            }
                        }
                    }
                }
                m
            }
        };
        Tiny { n, labels, edges, weights, unary, v }
    }

    fn energy(
        &self,
    ) -> MrfEnergy<'_, i64, impl Fn(usize, usize) -> i64 + '_, impl Fn(usize, usize, usize, usize) -> i64 + '_>
    {
        let l = self.labels;
        MrfEnergy::new(self.n, l, &self.edges, dense_unary(&self.unary, l), move |_, _, a, b| {
            self.v[a * l + b]
        })
        .with_edge_weights(&self.weights)
    }

    fn eval(&self, x: &[u32]) -> i64 {
        energy_of(&self.energy(), x).unwrap()
    }

    /// Global minimum by enumeration.
    fn brute_force(&self) -> i64 {
        let total = self.labels.pow(self.n as u32);
        let mut x = vec![0u32; self.n];
        let mut best = i64::MAX;
        for mut code in 0..total {
            for xi in x.iter_mut() {
                *xi = (code % self.labels) as u32;
                code /= self.labels;
            }
            best = best.min(self.eval(&x));
        }
        best
    }

    /// c = max / min of the off-diagonal label costs (BVZ's bound constant).
    fn metric_ratio(&self) -> f64 {
        let l = self.labels;
        let off: Vec<i64> = (0..l * l).filter(|i| i / l != i % l).map(|i| self.v[i]).collect();
        *off.iter().max().unwrap() as f64 / *off.iter().min().unwrap() as f64
    }
}

/// The lowest energy over all 2^n α-expansions of `x`, for every α.
fn best_expansion(t: &Tiny, x: &[u32], alpha: u32) -> i64 {
    let mut best = i64::MAX;
    let mut y = x.to_vec();
    for mask in 0u32..(1 << t.n) {
        for p in 0..t.n {
            y[p] = if mask & (1 << p) != 0 { alpha } else { x[p] };
        }
        best = best.min(t.eval(&y));
    }
    best
}

#[test]
fn alpha_expansion_brute_force() {
    let mut instances = 0;
    for seed in 0..360u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(20_000 + seed);
        let kind = [PairKind::Potts, PairKind::TruncatedLinear, PairKind::RandomMetric][seed as usize % 3];
        let n = rng.random_range(4..=7);
        let labels = rng.random_range(2..=4);
        let t = Tiny::random(&mut rng, kind, n, labels);
        let init: Vec<u32> = (0..n).map(|_| rng.random_range(0..labels as u32)).collect();
        let order = if seed % 2 == 0 { LabelOrder::Sequential } else { LabelOrder::Random { seed } };
        let cycles =
            [CycleStrategy::Full, CycleStrategy::Adaptive, CycleStrategy::Queue][(seed / 2 % 3) as usize];
        let ties = if seed % 5 == 0 { TieBreak::FewestAlpha } else { TieBreak::MostAlpha };
        let options = AlphaExpansionOptions { label_order: order, cycles, ties, ..Default::default() };
        let r = alpha_expansion(&t.energy(), &init, &options).unwrap();
        let what = format!("seed {seed} {kind:?} n {n} L {labels}");

        assert_eq!(r.termination, Termination::Converged, "{what}");
        assert_eq!(r.truncated_terms, 0, "{what}: metric terms are never truncated");
        assert_eq!(r.energy, t.eval(&r.labels), "{what}: reported energy");
        assert_eq!(r.initial_energy, t.eval(&init), "{what}");
        assert_eq!(*r.cycle_energies.last().unwrap(), r.energy, "{what}");
        let mut prev = r.initial_energy;
        for &e in &r.cycle_energies {
            assert!(e <= prev, "{what}: energy increased over a cycle: {:?}", r.cycle_energies);
            prev = e;
        }
        // Local minimum with respect to every expansion move.
        for alpha in 0..labels as u32 {
            assert!(
                best_expansion(&t, &r.labels, alpha) >= r.energy,
                "{what}: an {alpha}-expansion lowers the energy"
            );
        }
        // BVZ bound 2c (c = 1 for Potts).
        let optimum = t.brute_force();
        let c = t.metric_ratio();
        assert!(r.energy as f64 <= 2.0 * c * optimum as f64 + 1e-9, "{what}: {} > 2c·{optimum}", r.energy);
        if labels == 2 {
            assert_eq!(r.energy, optimum, "{what}: two labels must give the global optimum");
        }
        instances += 1;
    }
    assert_eq!(instances, 360);
}

/// The same checks with f64 costs (fractional, with forbidden labels as +∞), where moves are
/// scored through the flow or, near large capacities, through the exact energy change.
#[test]
fn alpha_expansion_brute_force_f64() {
    for seed in 0..150u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(25_000 + seed);
        let n = rng.random_range(4..=7);
        let l = rng.random_range(2..=4);
        let mut edges = Vec::new();
        for a in 0..n as u32 {
            for b in a + 1..n as u32 {
                if rng.random_bool(0.5) {
                    edges.push([a, b]);
                }
            }
        }
        // Label 0 is allowed everywhere, so a feasible labelling exists.
        let unary: Vec<f64> =
            (0..n * l)
                .map(|i| {
                    if i % l != 0 && rng.random_bool(0.2) {
                        f64::INFINITY
                    } else {
                        rng.random_range(0.0..3.0)
                    }
                })
                .collect();
        let weights: Vec<f64> = edges.iter().map(|_| rng.random_range(0.1..2.0)).collect();
        let trunc = rng.random_range(0.5..2.5);
        // Odd seeds: labels {0, 1} and {2, 3} form two groups that may not touch (+∞ across), a
        // metric with infinities whose moves carry `infinite_cost` capacities.
        let groups = seed % 2 == 1;
        let energy = MrfEnergy::new(n, l, &edges, dense_unary(&unary, l), |_, _, a: usize, b: usize| {
            if groups && a / 2 != b / 2 { f64::INFINITY } else { (a.abs_diff(b) as f64 * 0.7).min(trunc) }
        })
        .with_edge_weights(&weights);
        let init = vec![0u32; n];
        let r = alpha_expansion(&energy, &init, &AlphaExpansionOptions::default()).unwrap();
        let eval = |x: &[u32]| energy_of(&energy, x).unwrap();
        let what = format!("seed {seed} n {n} L {l}");
        assert!(r.energy.is_finite(), "{what}");
        assert!((r.energy - eval(&r.labels)).abs() < 1e-9, "{what}");
        let mut prev = r.initial_energy;
        for &e in &r.cycle_energies {
            assert!(e <= prev + 1e-9, "{what}: {:?}", r.cycle_energies);
            prev = e;
        }
        // Local minimum over every expansion, and within 2c of the optimum.
        let mut best = f64::INFINITY;
        let mut x = vec![0u32; n];
        for mut code in 0..l.pow(n as u32) {
            for xi in x.iter_mut() {
                *xi = (code % l) as u32;
                code /= l;
            }
            best = best.min(eval(&x));
        }
        for alpha in 0..l as u32 {
            let mut y = r.labels.clone();
            for mask in 0u32..(1 << n) {
                for p in 0..n {
                    y[p] = if mask & (1 << p) != 0 { alpha } else { r.labels[p] };
                }
                assert!(eval(&y) >= r.energy - 1e-9, "{what}: an {alpha}-expansion lowers the energy");
            }
        }
        if !groups || l <= 2 {
            let c = if l == 2 { 1.0 } else { trunc / 0.7f64.min(trunc) };
            assert!(r.energy <= 2.0 * c * best + 1e-9, "{what}: {} vs optimum {best}", r.energy);
        }
        if l == 2 {
            assert!((r.energy - best).abs() < 1e-9, "{what}: two labels must be optimal");
        }
        if groups && l > 2 {
            // From an infeasible start (groups touching) the first 0-expansion already reaches a
            // finite energy; moves here are scored by their exact energy change.
            let bad: Vec<u32> = (0..n).map(|p| if p % 2 == 0 { 0 } else { 2 }).collect();
            let r2 = alpha_expansion(&energy, &bad, &AlphaExpansionOptions::default()).unwrap();
            assert!(r2.energy.is_finite() && (r2.energy - eval(&r2.labels)).abs() < 1e-9, "{what}");
            assert!(r2.energy <= r2.initial_energy);
        }
    }
}

#[test]
fn alpha_expansion_two_labels_is_exact_on_larger_graphs() {
    // 2 labels, up to 12 sites (4096 labellings): exact every time.
    for seed in 0..40u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(30_000 + seed);
        let n = rng.random_range(8..=12);
        let t = Tiny::random(&mut rng, PairKind::RandomMetric, n, 2);
        let init: Vec<u32> = (0..n).map(|_| rng.random_range(0..2)).collect();
        let r = alpha_expansion(&t.energy(), &init, &AlphaExpansionOptions::default()).unwrap();
        assert_eq!(r.energy, t.brute_force(), "seed {seed}");
    }
}

/// The best α-expansion move from `labels` of a grid problem, as the minimum of
/// ΔE(y) = Σ_p c_p y_p + Σ_pq K_pq (1 − y_p) y_q (y_p = 1: site p switches to α), built here
/// from the textbook construction and solved by petgraph's Dinic: independent of the solver's
/// own move graphs and max-flow. Returns min ΔE (≥ 0 at an expansion local minimum).
fn best_move_by_dinic(p: &GridProblem, labels: &[u32], alpha: u32) -> i64 {
    let (n, l) = (p.num_sites(), p.num_labels);
    let a = alpha as usize;
    let v = |x: u32, y: usize| p.edge_weight * p.pairwise[x as usize * l + y];
    let mut c = vec![0i64; n];
    let mut pair: Vec<(usize, usize, u64)> = Vec::new();
    for s in 0..n {
        if labels[s] != alpha {
            c[s] += p.unary[s * l + a] - p.unary[s * l + labels[s] as usize];
        }
    }
    for [s, t] in p.edges() {
        let (s, t) = (s as usize, t as usize);
        let (ls, lt) = (labels[s], labels[t]);
        match (ls == alpha, lt == alpha) {
            (true, true) => {}
            (false, true) => c[s] += v(alpha, a) - v(ls, lt as usize),
            (true, false) => c[t] += v(alpha, a) - v(ls, lt as usize),
            (false, false) => {
                let (ea, eb, ec, ed) = (v(ls, lt as usize), v(ls, a), v(alpha, lt as usize), v(alpha, a));
                c[s] += ec - ea;
                c[t] += ed - ec;
                let k = eb + ec - ea - ed;
                assert!(k >= 0, "the shipped pairwise costs are metric");
                pair.push((s, t, k as u64));
            }
        }
    }
    let mut g = petgraph::Graph::<(), u64>::new();
    let nodes: Vec<_> = (0..n).map(|_| g.add_node(())).collect();
    let (src, sink) = (g.add_node(()), g.add_node(()));
    let mut constant = 0i64;
    for (s, &cs) in c.iter().enumerate() {
        if cs > 0 {
            g.add_edge(src, nodes[s], cs as u64);
        } else if cs < 0 {
            constant += cs;
            g.add_edge(nodes[s], sink, (-cs) as u64);
        }
    }
    for (s, t, k) in pair {
        g.add_edge(nodes[s], nodes[t], k);
    }
    constant + dinics(&g, src, sink).0 as i64
}

/// On grids of a thousand sites and more (whose moves the solver builds in parallel chunks of
/// 256 sites, with edges across every chunk boundary) the result is a local minimum of every
/// expansion move, each move solved independently by Dinic.
#[test]
fn large_grid_result_is_expansion_local_minimum_by_dinic() {
    for (dims, labels, conn, seed, cycles) in [
        ([12, 12, 8], 5, Connectivity::Six, 11, CycleStrategy::Full),
        ([10, 10, 12], 4, Connectivity::TwentySix, 12, CycleStrategy::Queue),
    ] {
        let p = generate_grid(dims, labels, conn, seed);
        let s = p.solve(&AlphaExpansionOptions { cycles, ..Default::default() }).unwrap();
        assert_eq!(s.termination, Termination::Converged);
        assert!(s.energy < s.initial_energy);
        for alpha in 0..labels as u32 {
            let gain = best_move_by_dinic(&p, &s.labels_flat, alpha);
            assert!(gain >= 0, "{dims:?}: the {alpha}-expansion still lowers the energy by {}", -gain);
        }
    }
}

/// `GridProblem::solve` runs alpha-expansion on 32-bit capacities when the costs allow it: the
/// result is the 64-bit solver's, move for move; costs too large for 32 bits (the same problem
/// scaled by 2³⁰) take 64 bits and give the same labels, with energies scaled.
#[test]
fn grid_solve_on_32_bit_capacities_matches_the_64_bit_solver() {
    for (dims, labels, conn, seed) in
        [([10, 10, 10], 8, Connectivity::Six, 1), ([8, 6, 5], 12, Connectivity::TwentySix, 2)]
    {
        let p = generate_grid(dims, labels, conn, seed);
        let s = p.solve(&AlphaExpansionOptions::default()).unwrap();
        let (edges, l) = (p.edges(), p.num_labels);
        let w: Vec<i64> = p.pairwise.iter().map(|&v| p.edge_weight * v).collect();
        let energy =
            MrfEnergy::new(p.num_sites(), l, &edges, |q, a| p.unary[q * l + a], |_, _, a, b| w[a * l + b]);
        let r = AlphaExpansion::<i64>::new()
            .solve(&energy, &p.initial_labels(), &AlphaExpansionOptions::default())
            .unwrap();
        assert!(r.accepted_moves > 1 && r.energy < r.initial_energy, "{dims:?}: a non-trivial solve");
        assert_eq!(s.capacity_bits, 32, "{dims:?}");
        assert_eq!(s.labels_flat, r.labels, "{dims:?}: labels");
        assert_eq!(
            (s.energy, &s.cycle_energies, s.moves, s.accepted_moves),
            (r.energy, &r.cycle_energies, r.moves, r.accepted_moves),
            "{dims:?}: energy, cycle energies, moves, accepted moves"
        );
    }
    let p = generate_grid([6, 6, 6], 6, Connectivity::Six, 4);
    let scale = 1i64 << 30;
    let mut big = p.clone();
    big.unary.iter_mut().for_each(|u| *u *= scale);
    big.pairwise.iter_mut().for_each(|v| *v *= scale);
    big.invalid_cost *= scale;
    let (s, t) = (
        p.solve(&AlphaExpansionOptions::default()).unwrap(),
        big.solve(&AlphaExpansionOptions::default()).unwrap(),
    );
    assert!(t.initial_energy > i64::from(i32::MAX), "the scaled problem needs 64 bits");
    assert_eq!((s.capacity_bits, t.capacity_bits), (32, 64));
    assert_eq!(t.labels_flat, s.labels_flat);
    assert_eq!((t.energy, t.moves), (s.energy * scale, s.moves));
}

/// Flow recycling (each label's move graph kept, and its next move started from the last one's
/// flow) takes exactly the moves of graphs built anew: the same labels, energies, cycle
/// energies, move counts and truncated terms, on grids (6- and 26-connected, every cycle
/// strategy, both tie rules, 1 and 2 threads) and on random graphs with edge weights, metric and
/// non-metric costs and random label orders.
#[test]
fn recycled_flows_take_the_moves_of_fresh_graphs() {
    for (dims, labels, conn, seed, metric) in [
        ([12, 10, 8], 9, Connectivity::Six, 3, true),
        ([8, 7, 6], 6, Connectivity::TwentySix, 4, true),
        ([12, 10, 8], 7, Connectivity::Six, 5, false),
    ] {
        let mut p = generate_grid(dims, labels, conn, seed);
        if !metric {
            // Truncated quadratic: some move terms are truncated.
            let l = labels;
            p.pairwise = (0..l * l).map(|i| ((i / l).abs_diff(i % l).pow(2) as i64).min(5) * 3).collect();
        }
        for cycles in [CycleStrategy::Full, CycleStrategy::Adaptive, CycleStrategy::Queue] {
            for ties in [TieBreak::MostAlpha, TieBreak::FewestAlpha] {
                for threads in [1, 2] {
                    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                    let run = |recycle_flows| {
                        let options =
                            AlphaExpansionOptions { cycles, ties, recycle_flows, ..Default::default() };
                        pool.install(|| p.solve(&options).unwrap())
                    };
                    let (kept, fresh) = (run(true), run(false));
                    let what = format!("{dims:?} {cycles:?} {ties:?} {threads} threads");
                    assert_eq!((kept.recycled_labels, fresh.recycled_labels), (labels, 0), "{what}");
                    assert_eq!(kept.truncated_terms > 0, !metric, "{what}: truncated terms");
                    assert!(kept.moves > labels && kept.accepted_moves > 1, "{what}: several cycles");
                    assert_eq!(kept.labels_flat, fresh.labels_flat, "{what}: labels");
                    assert_eq!(
                        (
                            kept.energy,
                            &kept.cycle_energies,
                            kept.moves,
                            kept.accepted_moves,
                            kept.truncated_terms
                        ),
                        (
                            fresh.energy,
                            &fresh.cycle_energies,
                            fresh.moves,
                            fresh.accepted_moves,
                            fresh.truncated_terms
                        ),
                        "{what}: energy, cycle energies, moves, accepted moves, truncated terms"
                    );
                }
            }
        }
    }
    let mut truncated = 0;
    for seed in 0..200u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(70_000 + seed);
        let (n, l) = (rng.random_range(6..=48), rng.random_range(3..=6));
        let mut t = Tiny::random(&mut rng, PairKind::TruncatedLinear, n, l);
        if seed % 2 == 1 {
            // Truncated quadratic: not a metric, so some move terms are truncated.
            t.v = (0..l * l).map(|i| ((i / l).abs_diff(i % l).pow(2) as i64).min(5) * 3).collect();
        }
        let init: Vec<u32> = (0..n).map(|_| rng.random_range(0..l as u32)).collect();
        let order = if seed % 3 == 0 { LabelOrder::Random { seed } } else { LabelOrder::Sequential };
        let run = |recycle_flows| {
            let options = AlphaExpansionOptions { label_order: order, recycle_flows, ..Default::default() };
            alpha_expansion(&t.energy(), &init, &options).unwrap()
        };
        let (kept, fresh) = (run(true), run(false));
        truncated += kept.truncated_terms;
        assert_eq!((kept.recycled_labels, fresh.recycled_labels), (l, 0), "seed {seed}");
        assert_eq!(kept.labels, fresh.labels, "seed {seed}: labels");
        assert_eq!(
            (kept.energy, &kept.cycle_energies, kept.moves, kept.accepted_moves, kept.truncated_terms),
            (fresh.energy, &fresh.cycle_energies, fresh.moves, fresh.accepted_moves, fresh.truncated_terms),
            "seed {seed}"
        );
    }
    assert!(truncated > 0, "no non-submodular term was met");
}

/// Solving several moves at once (one per thread) and keeping them up to the first success gives
/// exactly the sequential algorithm's result, move for move, with every cycle strategy.
#[test]
fn parallel_moves_give_the_sequential_result() {
    let p = generate_grid([12, 10, 6], 7, Connectivity::TwentySix, 5);
    for cycles in [CycleStrategy::Full, CycleStrategy::Adaptive, CycleStrategy::Queue] {
        let options = AlphaExpansionOptions { cycles, ..Default::default() };
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| p.solve(&options).unwrap())
        };
        let one = run(1);
        assert!(one.accepted_moves > 1 && one.energy < one.initial_energy, "{cycles:?}: a non-trivial solve");
        for threads in [2, 3, 5] {
            let many = run(threads);
            assert_eq!(many.labels_flat, one.labels_flat, "{cycles:?}, {threads} threads: labels");
            assert_eq!(
                (many.energy, many.cycles, many.moves, many.accepted_moves),
                (one.energy, one.cycles, one.moves, one.accepted_moves),
                "{cycles:?}, {threads} threads: energy, cycles, moves, accepted moves"
            );
        }
    }
}

/// With several optimal cuts, `MostAlpha` switches every site some optimal cut switches and
/// `FewestAlpha` only those every optimal cut switches.
#[test]
fn tie_break_picks_the_largest_or_smallest_optimal_move() {
    // Site 0 gains 5 by switching to label 1; sites 1 and 2 (joined by an edge) are indifferent,
    // and switching one but not the other costs 3.
    let edges = [[1u32, 2]];
    let unary = [5i64, 0, /**/ 0, 0, /**/ 0, 0];
    let energy =
        MrfEnergy::new(3, 2, &edges, dense_unary(&unary, 2), |_, _, a, b| if a == b { 0 } else { 3 });
    let solve = |ties| {
        let options = AlphaExpansionOptions { ties, ..Default::default() };
        alpha_expansion(&energy, &[0, 0, 0], &options).unwrap()
    };
    let most = solve(TieBreak::MostAlpha);
    let fewest = solve(TieBreak::FewestAlpha);
    assert_eq!((most.energy, fewest.energy), (0, 0));
    assert_eq!(most.labels, vec![1, 1, 1]);
    assert_eq!(fewest.labels, vec![1, 0, 0]);
}

#[test]
fn alpha_expansion_callback_sees_sites() {
    // Pairwise cost depends on the edge: on edge [0,1] labels must agree (cost 100 otherwise).
    let edges = [[0u32, 1], [1, 2]];
    let unary = [0i64, 20, 10, 0, 10, 0];
    let e = MrfEnergy::new(3, 2, &edges, dense_unary(&unary, 2), |p, q, a, b| {
        if a == b {
            0
        } else if (p, q) == (0, 1) {
            100
        } else {
            1
        }
    });
    let r = alpha_expansion(&e, &[0, 0, 0], &AlphaExpansionOptions::default()).unwrap();
    assert_eq!(r.labels, vec![0, 0, 1]);
    assert_eq!(r.energy, 10 + 1);
}

#[test]
fn alpha_expansion_non_metric_is_truncated_and_monotone() {
    // Truncated quadratic violates the triangle inequality: moves get truncated, energy still
    // never increases and the result is no worse than the start.
    let mut truncated = 0;
    for seed in 0..60u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(40_000 + seed);
        let n = rng.random_range(4..=7);
        let l = rng.random_range(3..=4);
        let mut t = Tiny::random(&mut rng, PairKind::Potts, n, l);
        t.v = (0..l * l).map(|i| ((i / l).abs_diff(i % l).pow(2) as i64).min(5) * 3).collect();
        let init: Vec<u32> = (0..n).map(|_| rng.random_range(0..l as u32)).collect();
        let r = alpha_expansion(&t.energy(), &init, &AlphaExpansionOptions::default()).unwrap();
        truncated += r.truncated_terms;
        assert_eq!(r.energy, t.eval(&r.labels));
        let mut prev = r.initial_energy;
        for &e in &r.cycle_energies {
            assert!(e <= prev, "seed {seed}: {:?}", r.cycle_energies);
            prev = e;
        }
        assert!(r.energy >= t.brute_force());
    }
    assert!(truncated > 0, "no non-submodular term was met");
}

#[test]
fn alpha_expansion_infinite_costs() {
    // f64 energy: label 0 is forbidden everywhere but site 0; label 2 forbidden next to label 1.
    let n = 6;
    let edges: Vec<[u32; 2]> = (0..n as u32 - 1).map(|p| [p, p + 1]).collect();
    let unary = |p: usize, l: usize| match (p, l) {
        (0, 0) => 0.0,
        (_, 0) => f64::INFINITY,
        (p, l) => (p as f64 * 0.7 + l as f64).sin().abs(),
    };
    let pairwise = |_: usize, _: usize, a: usize, b: usize| {
        if a == b {
            0.0
        } else if a.min(b) == 1 && a.max(b) == 2 {
            f64::INFINITY
        } else {
            0.25
        }
    };
    let e = MrfEnergy::new(n, 3, &edges, unary, pairwise);
    // Start from an infeasible labelling.
    let r = alpha_expansion(&e, &[0, 0, 0, 1, 2, 1], &AlphaExpansionOptions::default()).unwrap();
    assert!(r.initial_energy.is_infinite());
    assert!(r.energy.is_finite(), "{:?}", r);
    assert!(r.labels[1..].iter().all(|&l| l != 0));
    // NaN is an error naming the term.
    let bad = MrfEnergy::new(2, 2, &edges[..1], |_, l| if l == 1 { f64::NAN } else { 0.0 }, |_, _, _, _| 0.0);
    match alpha_expansion(&bad, &[0, 0], &AlphaExpansionOptions::default()) {
        Err(Error::NonFiniteCost { term: "unary", .. }) => {}
        other => panic!("expected a NonFiniteCost error, got {other:?}"),
    }
}

#[test]
fn alpha_expansion_rejects_bad_input() {
    let edges = [[0u32, 3]];
    let e = MrfEnergy::new(3, 2, &edges, |_, _| 0i64, |_, _, _, _| 0);
    assert!(matches!(alpha_expansion(&e, &[0, 0, 0], &Default::default()), Err(Error::InvalidEnergy { .. })));
    let edges = [[0u32, 1]];
    let e = MrfEnergy::new(3, 2, &edges, |_, _| 0i64, |_, _, _, _| 0);
    assert!(matches!(alpha_expansion(&e, &[0, 0], &Default::default()), Err(Error::InvalidEnergy { .. })));
    assert!(matches!(alpha_expansion(&e, &[0, 5, 0], &Default::default()), Err(Error::InvalidEnergy { .. })));
    let w = [-1i64];
    let e = MrfEnergy::new(3, 2, &edges, |_, _| 0i64, |_, _, _, _| 0).with_edge_weights(&w);
    assert!(matches!(alpha_expansion(&e, &[0, 0, 0], &Default::default()), Err(Error::InvalidEnergy { .. })));
}

#[test]
fn alpha_expansion_is_deterministic_and_reusable() {
    let mut rng = ChaCha8Rng::seed_from_u64(77);
    let t = Tiny::random(&mut rng, PairKind::TruncatedLinear, 7, 4);
    let init = vec![0; 7];
    let options = AlphaExpansionOptions { label_order: LabelOrder::Random { seed: 3 }, ..Default::default() };
    let mut solver = AlphaExpansion::new();
    let a = solver.solve(&t.energy(), &init, &options).unwrap();
    let b = solver.solve(&t.energy(), &init, &options).unwrap();
    assert_eq!((a.labels, a.energy, a.cycle_energies), (b.labels, b.energy, b.cycle_energies));
    // max_cycles = 0 returns the start.
    let r =
        alpha_expansion(&t.energy(), &init, &AlphaExpansionOptions { max_cycles: 0, ..Default::default() })
            .unwrap();
    assert_eq!((r.labels, r.termination, r.cycles), (init, Termination::MaxCycles, 0));
}

// ---------------------------------------------------------------------------------------------
// mrf_grid_v1
// ---------------------------------------------------------------------------------------------

#[test]
fn shipped_example_loads_and_solves() {
    let bytes = std::fs::read(example_path()).unwrap();
    let p = GridProblem::from_json_bytes(&bytes).unwrap();
    assert_eq!((p.dims, p.num_labels, p.connectivity), ([10, 10, 10], 8, Connectivity::Six));
    assert_eq!((p.edge_weight, p.invalid_cost, &p.init_labels), (1, 1_000_000, &InitLabels::UnaryArgmin));
    assert_eq!(p.edges().len(), 3 * 10 * 10 * 9);
    let s = solve_grid_file(&example_path(), &AlphaExpansionOptions::default()).unwrap();
    assert_eq!(s.termination, Termination::Converged);
    assert_eq!(s.truncated_terms, 0);
    assert_eq!(s.energy, p.energy(&s.labels_flat).unwrap());
    assert_eq!(s.initial_energy, p.energy(&p.initial_labels()).unwrap());
    assert!(s.energy < s.initial_energy);
    // Never a forbidden label when the argmin start has none.
    let l = p.num_labels;
    assert!(s.labels_flat.iter().enumerate().all(|(i, &x)| p.unary[i * l + x as usize] < p.invalid_cost));
    // Same answer with a random label order up to the local-minimum slack; same answer twice.
    let again = p.solve(&AlphaExpansionOptions::default()).unwrap();
    assert_eq!((again.energy, &again.labels_flat), (s.energy, &s.labels_flat));
    let json = serde_json::to_value(&s).unwrap();
    assert!(json.get("labels_flat").is_some() && json.get("energy").is_some());
}

#[test]
fn grid_connectivity_offsets() {
    let offs = Connectivity::TwentySix.offsets();
    assert_eq!(offs.len(), 13);
    let mut all: Vec<[i64; 3]> = offs.iter().copied().chain(offs.iter().map(|o| o.map(|x| -x))).collect();
    all.sort();
    all.dedup();
    assert_eq!(all.len(), 26);
    assert!(offs.iter().all(|o| *o > [0, 0, 0]), "offsets must be lexicographically positive");
    // Edge counts on a 4×5×6 grid: 6-connectivity 3·n − faces; 26 by direct count.
    let p = generate_grid([4, 5, 6], 3, Connectivity::TwentySix, 1);
    let count: usize = offs
        .iter()
        .map(|o| (0..3).map(|i| p.dims[i] - o[i].unsigned_abs() as usize).product::<usize>())
        .sum();
    assert_eq!(p.edges().len(), count);
    assert!(p.edges().iter().all(|&[a, b]| a < b));
    let p6 = generate_grid([4, 5, 6], 3, Connectivity::Six, 1);
    assert_eq!(p6.edges().len(), 3 * 5 * 6 + 4 * 4 * 6 + 4 * 5 * 5);
}

#[test]
fn generated_grid_round_trips_and_solves() {
    let p = generate_grid([6, 5, 4], 8, Connectivity::TwentySix, 11);
    assert_eq!(p, generate_grid([6, 5, 4], 8, Connectivity::TwentySix, 11));
    assert_ne!(p.unary, generate_grid([6, 5, 4], 8, Connectivity::TwentySix, 12).unary);
    let invalid = p.unary.iter().filter(|&&c| c == p.invalid_cost).count() as f64 / p.unary.len() as f64;
    assert!((0.05..0.15).contains(&invalid), "invalid fraction {invalid}");
    let back = GridProblem::from_json_str(&p.to_json_string()).unwrap();
    assert_eq!(back, p);
    let s = back.solve(&AlphaExpansionOptions::default()).unwrap();
    assert_eq!(s.energy, p.energy(&s.labels_flat).unwrap());
    assert!(s.energy <= s.initial_energy);
    // Explicit init labels survive the round trip too.
    let mut q = p.clone();
    q.init_labels = InitLabels::Labels(s.labels_flat.clone());
    let back = GridProblem::from_json_str(&q.to_json_string()).unwrap();
    assert_eq!(back.init_labels, q.init_labels);
    // Starting from a local minimum, nothing changes.
    let s2 = back.solve(&AlphaExpansionOptions::default()).unwrap();
    assert_eq!((s2.energy, s2.accepted_moves, s2.cycles), (s.energy, 0, 1));
}

/// Every local minimum of a grid problem: no single expansion lowers the energy. Checked on a
/// small grid with a fresh solve per label from the result (a move from a local minimum must be
/// rejected).
#[test]
fn grid_result_is_expansion_local_minimum() {
    let p = generate_grid([3, 3, 2], 4, Connectivity::TwentySix, 5);
    let s = p.solve(&AlphaExpansionOptions::default()).unwrap();
    let n = p.num_sites();
    for alpha in 0..4u32 {
        let mut y = s.labels_flat.clone();
        for mask in 0u32..(1 << n) {
            for i in 0..n {
                y[i] = if mask & (1 << i) != 0 { alpha } else { s.labels_flat[i] };
            }
            assert!(p.energy(&y).unwrap() >= s.energy, "alpha {alpha} mask {mask:b}");
        }
    }
}

fn field_error(json: &str) -> String {
    match GridProblem::from_json_str(json) {
        Err(Error::Field { field, .. }) => field,
        other => panic!("expected a field error for {json}, got {other:?}"),
    }
}

#[test]
fn grid_rejects_bad_files() {
    let ok = r#"{"format":"mrf_grid_v1","dims":[1,1,2],"num_labels":2,"connectivity":6,
        "unary":[0,1,2,3],"pairwise":[[0,1],[1,0]],"init_labels":[0,1]}"#;
    let p = GridProblem::from_json_str(ok).unwrap();
    assert_eq!(p.edge_weight, 1);
    // unary[0·2 + 0] + unary[1·2 + 1] + V[0][1]
    assert_eq!(p.energy(&[0, 1]).unwrap(), 4);

    let cases: &[(&str, &str)] = &[
        (r#"{"format":"mrf_grid_v2"}"#, "format"),
        (r#"{"format":"mrf_grid_v1","dims":[1,2]}"#, "dims"),
        (r#"{"format":"mrf_grid_v1","dims":[1,0,2]}"#, "dims[1]"),
        (r#"{"format":"mrf_grid_v1","dims":[100000,100000,100000],"num_labels":2}"#, "dims"),
        (r#"{"format":"mrf_grid_v1","dims":[1,1,2],"num_labels":0}"#, "num_labels"),
        (r#"{"format":"mrf_grid_v1","dims":[1,1,2],"num_labels":2,"connectivity":8}"#, "connectivity"),
        (
            r#"{"format":"mrf_grid_v1","dims":[1,1,2],"num_labels":2,"connectivity":6,"unary":[0,1,2]}"#,
            "unary",
        ),
        (
            r#"{"format":"mrf_grid_v1","dims":[1,1,2],"num_labels":2,"connectivity":6,"unary":[0,1,2.5,3]}"#,
            "unary[2]",
        ),
        (
            r#"{"format":"mrf_grid_v1","dims":[1,1,2],"num_labels":2,"connectivity":6,"unary":[0,1,2,3],
               "pairwise":[[0,1]]}"#,
            "pairwise",
        ),
        (
            r#"{"format":"mrf_grid_v1","dims":[1,1,2],"num_labels":2,"connectivity":6,"unary":[0,1,2,3],
               "pairwise":[[0,1],[1]]}"#,
            "pairwise[1]",
        ),
        (
            r#"{"format":"mrf_grid_v1","dims":[1,1,2],"num_labels":2,"connectivity":6,"unary":[0,1,2,3],
               "pairwise":[[0,1],[1,0]],"init_labels":[0,2]}"#,
            "init_labels[1]",
        ),
        (
            r#"{"format":"mrf_grid_v1","dims":[1,1,2],"num_labels":2,"connectivity":6,"unary":[0,1,2,3],
               "pairwise":[[0,1],[1,0]],"init_labels":"random"}"#,
            "init_labels",
        ),
        (
            r#"{"format":"mrf_grid_v1","dims":[1,1,2],"num_labels":2,"connectivity":6,
               "unary":[0,1,2,4611686018427387904],"pairwise":[[0,1],[1,0]]}"#,
            "unary",
        ),
        (r#"{"format":"mrf_grid_v1","dims":[1,1,2],"num_labels":2,"connectivity":6}"#, "unary"),
        (
            r#"{"format":"mrf_grid_v1","dims":[1,1,2],"num_labels":2,"connectivity":6,"unary":[0,1,2,3],
               "pairwise":[[0,9223372036854775807],[1,0]],"edge_weight":9223372036854775807}"#,
            "pairwise",
        ),
        // Only the pairwise costs are too large: the error names them, not the unary.
        (
            r#"{"format":"mrf_grid_v1","dims":[1,1,2],"num_labels":2,"connectivity":6,"unary":[0,1,2,3],
               "pairwise":[[0,9223372036854775807],[9223372036854775807,0]]}"#,
            "pairwise",
        ),
        (
            r#"{"format":"mrf_grid_v1","dims":[1,1,2],"num_labels":2,"connectivity":6,"unary":[0,1,2,3],
               "pairwise":[[0,1],[1,0]],"edge_weight":-1}"#,
            "edge_weight",
        ),
        (
            r#"{"format":"mrf_grid_v1","dims":[1,1,2],"num_labels":2,"connectivity":6,"unary":[0,1,2,3],
               "pairwise":[[0,1],[1,0]],"invalid_cost":-1}"#,
            "invalid_cost",
        ),
        // L² is never allocated before the rows are seen to hold L² numbers.
        (
            r#"{"format":"mrf_grid_v1","dims":[1,1,1],"num_labels":3,"connectivity":6,"unary":[0,1,2],
               "pairwise":[[],[],[]]}"#,
            "pairwise[0]",
        ),
    ];
    for (json, field) in cases {
        assert_eq!(field_error(json), *field, "{json}");
    }
    assert!(matches!(GridProblem::from_json_str("{"), Err(Error::Json { .. })));
    let missing = std::path::Path::new("/nonexistent/problem.json");
    assert!(matches!(solve_grid_file(missing, &Default::default()), Err(Error::Io { .. })));
    // The message names the field.
    let msg = GridProblem::from_json_str(cases[6].0).unwrap_err().to_string();
    assert!(msg.contains("`unary`") && msg.contains("expected"), "{msg}");
}

#[test]
fn grid_solutions_report_forbidden_sites_and_non_metric_costs() {
    // Site 1 has only forbidden labels; V is symmetric but breaks the triangle inequality.
    let json = r#"{"format":"mrf_grid_v1","dims":[1,1,3],"num_labels":3,"connectivity":6,
        "unary":[0,5,5, 1000000,1000000,1000000, 5,5,0],"invalid_cost":1000000,
        "pairwise":[[0,1,10],[1,0,1],[10,1,0]]}"#;
    let p = GridProblem::from_json_str(json).unwrap();
    let s = p.solve(&AlphaExpansionOptions::default()).unwrap();
    assert_eq!(s.forbidden_sites, 1, "{s:?}");
    assert_eq!(s.pairwise_issues.len(), 1, "{:?}", s.pairwise_issues);
    assert!(s.pairwise_issues[0].contains("triangle inequality"), "{:?}", s.pairwise_issues);
    let asymmetric = json.replace("[[0,1,10],[1,0,1],[10,1,0]]", "[[0,1,2],[5,0,1],[2,1,0]]");
    let issues = GridProblem::from_json_str(&asymmetric).unwrap().pairwise_issues();
    assert!(issues.iter().any(|i| i.contains("not symmetric")), "{issues:?}");
    // The shipped generator's truncated-linear costs are a metric, and every site has a label.
    let g = generate_grid([4, 4, 4], 5, Connectivity::Six, 3);
    assert!(g.pairwise_issues().is_empty(), "{:?}", g.pairwise_issues());
    assert_eq!(g.solve(&AlphaExpansionOptions::default()).unwrap().forbidden_sites, 0);
}

#[test]
fn solve_grid_file_reads_a_written_problem() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("p.json");
    let p = generate_grid([5, 5, 5], 6, Connectivity::Six, 2);
    std::fs::write(&path, p.to_json_string()).unwrap();
    let s = solve_grid_file(&path, &AlphaExpansionOptions::default()).unwrap();
    assert_eq!(s.energy, p.energy(&s.labels_flat).unwrap());
    assert!(!THESIS_CHAPTER.is_empty());
}
