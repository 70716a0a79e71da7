//! Communities of a small weighted graph by modularity (Louvain; Blondel, Guillaume, Lambiotte
//! and Lefebvre 2008), deterministic.
//!
//! Used by [`crate::aligned`] to group instances by their images, and by
//! [`crate::shape_split`] to group free-standing instances by their shapes. The graphs there have one node
//! per instance (tens to a few hundred) and an edge between almost every pair, so the graph is a
//! dense symmetric matrix and every step is a row scan. No maintained, field-standard Rust crate
//! does this (graph crates with a Louvain are young or unmaintained, and all take sparse edge
//! lists); it is short, and tested here against modularity computed from its definition and
//! against the best partition found by enumeration on small graphs.
//!
//! # Algorithm
//! Modularity with resolution γ (Reichardt and Bornholdt 2006) of a partition into communities
//! C, for weights w_ij (w_ii a self-loop), degrees k_i = Σ_j w_ij + w_ii and total 2W = Σ_i k_i:
//! Q = Σ_C (in_C / 2W − γ (tot_C / 2W)²), where in_C counts each edge inside C twice (a
//! self-loop twice) and tot_C = Σ_{i∈C} k_i.
//! 1. **Local moves.** Each node in turn, in index order, leaves its community and joins the
//!    one with the largest gain k_{i,C} − γ tot_C k_i / 2W (k_{i,C}: its weight to C's
//!    members), among its own and its neighbours', staying unless another is strictly better;
//!    it stands alone (gain 0) when every one of them has a negative gain.
//!    Passes repeat until no node moves.
//! 2. **Aggregation.** Each community becomes one node; weights between communities are
//!    summed, the weight inside one becomes its self-loop. Steps 1–2 repeat until a level
//!    moves no node.
//! 3. **Refinement.** Step 1 once more on the original nodes, from the final partition: moves
//!    at coarse levels carry whole communities, after which a single node may still gain by
//!    leaving its own. The result is then one no single move improves.
//!
//! Index order instead of the usual random order makes the result a function of the input and
//! its order alone, so that a detection reproduces exactly whatever the thread count.

/// Most passes of local moves per level (each pass moves every node at most once; a pass that
/// moves nothing ends the level long before this on graphs of this size).
const MAX_PASSES: usize = 100;

/// Community of each node of the `n × n` symmetric weight matrix `w` (row-major; non-negative,
/// finite; the diagonal holds self-loops), numbered 0, 1, … in order of each community's lowest
/// node. Nodes with no weight at all are communities of their own.
pub fn louvain(w: &[f64], n: usize, resolution: f64) -> Vec<usize> {
    assert_eq!(w.len(), n * n, "louvain: the weight matrix must be n × n");
    let mut membership: Vec<usize> = (0..n).collect();
    let mut graph = w.to_vec();
    let mut size = n;
    loop {
        let level = local_moves(&graph, size, resolution, (0..size).collect());
        let (labels, count) = renumber(&level);
        if count == size {
            break;
        }
        for m in membership.iter_mut() {
            *m = labels[*m];
        }
        graph = aggregate(&graph, size, &labels, count);
        size = count;
    }
    // Moves of single nodes once more: a level's moves carry whole communities, after which a
    // single node may still gain by leaving its own.
    renumber(&local_moves(w, n, resolution, renumber(&membership).0)).0
}

/// The self-tuning affinity of Zelnik-Manor and Perona (2004) on the `m × m` distances `d`
/// (row-major): w_ab = exp(−d_ab² / (s_a s_b)) for the pairs `linked(a, b)` (symmetric, never a
/// node with itself), 0 for the others, where a node's scale s is its distance to its
/// `rank`-th nearest linked node (the farthest, when it has fewer). Each node is measured
/// against its own neighbourhood, so that a tight group and a loose one both stand out. When
/// either node of a pair has scale 0 (exact copies among its nearest), the pair's weight is 1 at
/// distance 0 and 0 otherwise.
pub fn self_tuning_weights(
    d: &[f64],
    m: usize,
    linked: impl Fn(usize, usize) -> bool,
    rank: usize,
) -> Vec<f64> {
    let scale: Vec<Option<f64>> = (0..m)
        .map(|a| {
            let mut ds: Vec<f64> = (0..m).filter(|&b| linked(a, b)).map(|b| d[a * m + b]).collect();
            ds.sort_by(f64::total_cmp);
            (!ds.is_empty()).then(|| ds[rank.clamp(1, ds.len()) - 1])
        })
        .collect();
    let mut w = vec![0.0; m * m];
    for a in 0..m {
        for b in (a + 1..m).filter(|&b| linked(a, b)) {
            let (Some(sa), Some(sb)) = (scale[a], scale[b]) else { continue };
            let v = d[a * m + b];
            let weight = if sa * sb > 0.0 {
                (-v * v / (sa * sb)).exp()
            } else if v == 0.0 {
                1.0
            } else {
                0.0
            };
            w[a * m + b] = weight;
            w[b * m + a] = weight;
        }
    }
    w
}

/// Modularity of `membership` on `w` (module documentation), from its definition; 0 for a graph
/// without weight.
pub fn modularity(w: &[f64], n: usize, membership: &[usize], resolution: f64) -> f64 {
    let k: Vec<f64> = (0..n).map(|i| degree(w, n, i)).collect();
    let two_w: f64 = k.iter().sum();
    if two_w <= 0.0 {
        return 0.0;
    }
    let mut q = 0.0;
    for i in 0..n {
        for j in 0..n {
            if membership[i] == membership[j] {
                // A self-loop counts twice, as in the degree.
                let a = if i == j { 2.0 * w[i * n + i] } else { w[i * n + j] };
                q += a - resolution * k[i] * k[j] / two_w;
            }
        }
    }
    q / two_w
}

/// Weighted degree: the row's weights, the self-loop counted twice.
fn degree(w: &[f64], n: usize, i: usize) -> f64 {
    w[i * n..(i + 1) * n].iter().sum::<f64>() + w[i * n + i]
}

/// Local moves (step 1) from the partition `community` (labels below `n`); returns each node's
/// community.
fn local_moves(w: &[f64], n: usize, resolution: f64, mut community: Vec<usize>) -> Vec<usize> {
    let k: Vec<f64> = (0..n).map(|i| degree(w, n, i)).collect();
    let two_w: f64 = k.iter().sum();
    if two_w <= 0.0 {
        return community;
    }
    let mut tot = vec![0.0; n];
    let mut members = vec![0usize; n];
    for (i, &c) in community.iter().enumerate() {
        tot[c] += k[i];
        members[c] += 1;
    }
    // Weight from the current node to each community; reset after each node.
    let mut to = vec![0.0; n];
    let mut touched: Vec<usize> = Vec::with_capacity(n);
    for _ in 0..MAX_PASSES {
        let mut moved = false;
        for i in 0..n {
            let own = community[i];
            touched.clear();
            for j in (0..n).filter(|&j| j != i && w[i * n + j] > 0.0) {
                let c = community[j];
                if to[c] == 0.0 {
                    touched.push(c);
                }
                to[c] += w[i * n + j];
            }
            tot[own] -= k[i];
            members[own] -= 1;
            let gain = |c: usize, to: &[f64]| to[c] - resolution * tot[c] * k[i] / two_w;
            // Another community only when strictly better than staying; among equals, the
            // lowest-numbered.
            let mut best = (gain(own, &to), own);
            let mut other: Option<(f64, usize)> = None;
            for &c in touched.iter().filter(|&&c| c != own) {
                let g = gain(c, &to);
                if other.is_none_or(|b| g > b.0 || (g == b.0 && c < b.1)) {
                    other = Some((g, c));
                }
            }
            if let Some(b) = other
                && b.0 > best.0
            {
                best = b;
            }
            // Alone (gain 0), when every community costs.
            if best.0 < 0.0
                && members[own] > 0
                && let Some(free) = members.iter().position(|&m| m == 0)
            {
                best = (0.0, free);
            }
            tot[best.1] += k[i];
            members[best.1] += 1;
            if best.1 != own {
                community[i] = best.1;
                moved = true;
            }
            for &c in &touched {
                to[c] = 0.0;
            }
        }
        if !moved {
            break;
        }
    }
    community
}

/// Labels 0, 1, … in order of first appearance, and their count.
fn renumber(labels: &[usize]) -> (Vec<usize>, usize) {
    let mut map = std::collections::HashMap::new();
    let out = labels
        .iter()
        .map(|&l| {
            let next = map.len();
            *map.entry(l).or_insert(next)
        })
        .collect();
    (out, map.len())
}

/// The graph of communities (step 2): weights summed; inside a community, each edge once (its
/// two entries halved) plus the members' self-loops, as the community's self-loop.
fn aggregate(w: &[f64], n: usize, labels: &[usize], count: usize) -> Vec<f64> {
    let mut g = vec![0.0; count * count];
    for i in 0..n {
        for j in 0..n {
            let (a, b) = (labels[i], labels[j]);
            if a != b {
                g[a * count + b] += w[i * n + j];
            } else if i == j {
                g[a * count + a] += w[i * n + i];
            } else {
                g[a * count + a] += 0.5 * w[i * n + j];
            }
        }
    }
    g
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// The best modularity over all partitions of `n` nodes (restricted growth strings).
    fn best_by_enumeration(w: &[f64], n: usize, resolution: f64) -> f64 {
        let mut best = f64::NEG_INFINITY;
        let mut labels = vec![0usize; n];
        loop {
            best = best.max(modularity(w, n, &labels, resolution));
            // Next restricted growth string: labels[i] ≤ 1 + max(labels[..i]).
            let mut i = n - 1;
            loop {
                if i == 0 {
                    return best;
                }
                let cap = labels[..i].iter().max().unwrap() + 1;
                if labels[i] < cap {
                    labels[i] += 1;
                    labels[i + 1..].iter_mut().for_each(|l| *l = 0);
                    break;
                }
                i -= 1;
            }
        }
    }

    /// `groups` cliques of `size` nodes with weight `inside`, every other pair `across`; the
    /// node order interleaves the groups so that index order does not give the answer away.
    fn planted(groups: usize, size: usize, inside: f64, across: f64) -> (Vec<f64>, usize) {
        let n = groups * size;
        let mut w = vec![across; n * n];
        for i in 0..n {
            for j in 0..n {
                if i % groups == j % groups {
                    w[i * n + j] = inside;
                }
            }
            w[i * n + i] = 0.0;
        }
        (w, n)
    }

    #[test]
    fn planted_groups_are_found_whatever_their_order() {
        let (w, n) = planted(3, 5, 1.0, 0.1);
        let m = louvain(&w, n, 1.0);
        for i in 0..n {
            for j in 0..n {
                assert_eq!(m[i] == m[j], i % 3 == j % 3, "nodes {i} and {j}: {m:?}");
            }
        }
        assert_eq!(m[..3], [0, 1, 2]);
    }

    #[test]
    fn modularity_matches_its_definition_on_a_hand_worked_graph() {
        // Two triangles joined by one edge (7 edges, 2W = 14): each triangle has in = 6 and
        // tot = 7, so Q = 2 (6/14 − (7/14)²) = 5/14.
        let n = 6;
        let mut w = vec![0.0; 36];
        for &(a, b) in &[(0, 1), (0, 2), (1, 2), (3, 4), (3, 5), (4, 5), (2, 3)] {
            w[a * n + b] = 1.0;
            w[b * n + a] = 1.0;
        }
        let m = louvain(&w, n, 1.0);
        assert_eq!(m, vec![0, 0, 0, 1, 1, 1]);
        assert!((modularity(&w, n, &m, 1.0) - 5.0 / 14.0).abs() < 1e-12);
        // All in one community: Q = 0.
        assert!(modularity(&w, n, &[0; 6], 1.0).abs() < 1e-12);
    }

    #[test]
    fn on_small_random_graphs_the_result_is_near_the_best_partition_and_locally_optimal() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut ratios = Vec::new();
        for case in 0..40 {
            let n = 5 + case % 4;
            let mut w = vec![0.0; n * n];
            for i in 0..n {
                for j in i + 1..n {
                    let v: f64 = if rng.random::<f64>() < 0.5 { rng.random() } else { 0.0 };
                    w[i * n + j] = v;
                    w[j * n + i] = v;
                }
            }
            let resolution = [0.8, 1.0, 1.2][case % 3];
            let m = louvain(&w, n, resolution);
            let q = modularity(&w, n, &m, resolution);
            let best = best_by_enumeration(&w, n, resolution);
            // No single node can improve the result by changing community.
            for i in 0..n {
                for c in 0..n {
                    let mut moved = m.clone();
                    moved[i] = c + n;
                    if let Some(j) = (0..n).find(|&j| m[j] == c) {
                        moved[i] = m[j];
                    }
                    let dq = modularity(&w, n, &moved, resolution) - q;
                    assert!(dq < 1e-9, "case {case}: moving node {i} gains {dq}");
                }
            }
            if best > 0.0 {
                ratios.push(q / best);
            }
        }
        let mean = ratios.iter().sum::<f64>() / ratios.len() as f64;
        let worst = ratios.iter().cloned().fold(f64::INFINITY, f64::min);
        assert!(mean > 0.98 && worst > 0.85, "mean {mean}, worst {worst}");
    }

    #[test]
    fn nodes_without_weight_stay_alone_and_a_weightless_graph_is_all_singletons() {
        let (mut w, n) = planted(2, 3, 1.0, 0.0);
        // Cut node 5 off.
        for j in 0..n {
            w[5 * n + j] = 0.0;
            w[j * n + 5] = 0.0;
        }
        let m = louvain(&w, n, 1.0);
        assert_eq!(m, vec![0, 1, 0, 1, 0, 2]);
        assert_eq!(louvain(&[0.0; 9], 3, 1.0), vec![0, 1, 2]);
        assert_eq!(modularity(&[0.0; 9], 3, &[0, 1, 2], 1.0), 0.0);
    }

    #[test]
    fn aggregation_keeps_the_modularity_of_every_partition_of_the_communities() {
        // A random graph with self-loops, its nodes grouped in three; any partition of the
        // groups has the same modularity on the aggregated graph as on the original.
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let n = 9;
        let mut w = vec![0.0; n * n];
        for i in 0..n {
            for j in i..n {
                let v: f64 = rng.random();
                w[i * n + j] = v;
                w[j * n + i] = v;
            }
        }
        let labels = [0, 1, 2, 0, 1, 2, 0, 1, 2];
        let g = aggregate(&w, n, &labels, 3);
        for coarse in [[0, 1, 2], [0, 0, 1], [0, 1, 0], [0, 0, 0]] {
            let fine: Vec<usize> = labels.iter().map(|&l| coarse[l]).collect();
            for resolution in [0.5, 1.0, 2.0] {
                let (a, b) = (modularity(&w, n, &fine, resolution), modularity(&g, 3, &coarse, resolution));
                assert!((a - b).abs() < 1e-12, "{coarse:?} at {resolution}: {a} vs {b}");
            }
        }
    }

    #[test]
    fn a_higher_resolution_splits_and_a_lower_one_joins() {
        // Two groups of three joined more weakly than within, but not weakly: at γ = 1 two
        // communities; at γ = 0.2 one.
        let (w, n) = planted(2, 3, 1.0, 0.3);
        let two = louvain(&w, n, 1.0);
        assert_eq!(two, vec![0, 1, 0, 1, 0, 1]);
        assert_eq!(louvain(&w, n, 0.2), vec![0; 6]);
    }
}
