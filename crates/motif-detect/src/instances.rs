//! Instance detection by spectral clustering of co-occurrence (thesis 5.3.3): the co-occurrence
//! matrix of eq. 5.3, classical MDS to 5 dimensions, mean-shift (bandwidth 0.5), the median word of
//! each cluster as the instances' centres, the star model linking each centre to its co-occurring
//! features, instance boxes averaged per class, and the transforms between instances.
//!
//! Choices where the thesis is silent:
//! - eq. 5.3 is not symmetric (Ψ(i, j) counts sources in Dⁱ); Motif averages mᵢⱼ and mⱼᵢ, and
//!   uses dᵢⱼ = 1 − mᵢⱼ as the distance that classical MDS embeds. Words that co-occur with no
//!   other word take no part.
//! - Mean-shift uses the flat kernel (radius = bandwidth), so words that do not co-occur (distance
//!   ≈ 1) never pull on each other; modes closer than half the bandwidth merge. As a guard against
//!   MDS squeezing unrelated groups together in 5 dimensions, each cluster is split into the
//!   connected components of its co-occurrence graph.
//! - An instance is kept when it links at least `min_links` of its class's other words; boxes are
//!   the members' extents in the centre's frame, padded by half a HOC cell (features sit on
//!   creases, the block's surface extends a little beyond them), with the per-class average taken
//!   as the median of each bound. Overlapping instances of one class (a word that fires on two
//!   symmetric corners of one window) are merged, the better-linked one kept.

use motif_core::Point3;
use motif_core::geometry::{Aabb, Mat4, mat4_from_rt};
use serde::{Deserialize, Serialize};

use crate::cooccurrence::PairMatch;
use crate::dictionary::Word;
use crate::grid::SpatialHash;
use crate::preprocess::Feature;

/// Options of [`detect_instances`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct InstanceOptions {
    /// Dimensions of the classical-MDS embedding (thesis 5.4: 5).
    pub embedding_dims: usize,
    /// Mean-shift bandwidth in the embedding (thesis 5.4: 0.5).
    pub bandwidth: f64,
    /// Minimum fraction of the class's other words an instance must link to. Default 0.25.
    pub min_links: f64,
    /// Box padding around the linked features, in ε. Default 4 (half a HOC cell).
    pub box_margin: f64,
    /// Two instances of one class whose boxes overlap by more than this fraction of the smaller
    /// box are merged. Default 0.5.
    pub merge_overlap: f64,
    /// Classes need at least this many instances. Default 2 (a building block repeats).
    pub min_instances: usize,
}

impl Default for InstanceOptions {
    fn default() -> Self {
        InstanceOptions {
            embedding_dims: 5,
            bandwidth: 0.5,
            min_links: 0.25,
            box_margin: 4.0,
            merge_overlap: 0.5,
            min_instances: 2,
        }
    }
}

/// One detected instance.
#[derive(Debug, Clone, PartialEq)]
pub struct Instance {
    /// The centre feature (a member of the class's median word).
    pub centre: usize,
    /// Its frame flip.
    pub flip: u8,
    /// Features linked by the star model, the centre included.
    pub features: Vec<usize>,
    /// World-space frame: local (x, y, z, 1) to world.
    pub frame: Mat4,
    /// Axis-aligned world box of the class box placed at this instance.
    pub aabb: Aabb,
}

/// One building-block class.
#[derive(Debug, Clone, PartialEq)]
pub struct Class {
    /// Indices of the words forming the class.
    pub words: Vec<usize>,
    /// The centre (median) word.
    pub centre_word: usize,
    /// The class box in the centre's local frame (median over instances).
    pub local_min: Point3,
    /// Upper corner of the local box.
    pub local_max: Point3,
    /// The instances.
    pub instances: Vec<Instance>,
}

impl Class {
    /// Whether world point `p` lies inside the class box placed at instance `k`.
    pub fn contains(&self, k: usize, p: Point3) -> bool {
        let inst = &self.instances[k];
        let f = &inst.frame;
        let v = [p[0] - f[0][3], p[1] - f[1][3], p[2] - f[2][3]];
        (0..3).all(|a| {
            let l = f[0][a] * v[0] + f[1][a] * v[1] + f[2][a] * v[2];
            l >= self.local_min[a] && l <= self.local_max[a]
        })
    }
}

/// What the clustering saw, for reports.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ClusteringReport {
    /// Words with at least one strong co-occurrence.
    pub connected_words: usize,
    /// Mean-shift clusters (after the connectivity split).
    pub clusters: usize,
    /// Classes with enough instances.
    pub classes: usize,
}

/// Symmetrised eq. 5.3 over `k` words, zero below the support threshold.
pub fn cooccurrence_matrix(words: &[Word], matches: &[Option<PairMatch>], min_support: usize) -> Vec<f64> {
    let k = words.len();
    let m = |i: usize, j: usize| -> f64 {
        match &matches[i * k + j] {
            Some(p) if p.support.len() >= min_support.max(1) => {
                p.support.len() as f64 / words[i].members.len().max(words[j].members.len()) as f64
            }
            _ => 0.0,
        }
    };
    let mut out = vec![0.0; k * k];
    for i in 0..k {
        out[i * k + i] = 1.0;
        for j in (i + 1)..k {
            let v = (0.5 * (m(i, j) + m(j, i))).min(1.0);
            out[i * k + j] = v;
            out[j * k + i] = v;
        }
    }
    out
}

/// Classical MDS of a distance matrix (`n × n`, row-major) into `dims` dimensions.
pub fn classical_mds(dist: &[f64], n: usize, dims: usize) -> Vec<Vec<f64>> {
    let mut b = nalgebra::DMatrix::<f64>::zeros(n, n);
    for i in 0..n {
        for j in 0..n {
            b[(i, j)] = dist[i * n + j] * dist[i * n + j];
        }
    }
    // Double centring: B = −½ J D² J.
    let row_mean: Vec<f64> = (0..n).map(|i| (0..n).map(|j| b[(i, j)]).sum::<f64>() / n as f64).collect();
    let total = row_mean.iter().sum::<f64>() / n as f64;
    let mut c = nalgebra::DMatrix::<f64>::zeros(n, n);
    for i in 0..n {
        for j in 0..n {
            c[(i, j)] = -0.5 * (b[(i, j)] - row_mean[i] - row_mean[j] + total);
        }
    }
    let eig = nalgebra::SymmetricEigen::new(c);
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]).then(a.cmp(&b)));
    (0..n)
        .map(|i| {
            order
                .iter()
                .take(dims)
                .map(|&k| {
                    let l = eig.eigenvalues[k];
                    if l > 0.0 {
                        // Fix each eigenvector's sign (largest-magnitude entry positive) so the
                        // embedding is deterministic.
                        let col = eig.eigenvectors.column(k);
                        let s =
                            col.iter().cloned().fold(0.0f64, |m, v| if v.abs() > m.abs() { v } else { m });
                        col[i] * l.sqrt() * if s < 0.0 { -1.0 } else { 1.0 }
                    } else {
                        0.0
                    }
                })
                .collect()
        })
        .collect()
}

/// Flat-kernel mean-shift; returns a cluster label per point.
pub fn mean_shift(points: &[Vec<f64>], bandwidth: f64) -> Vec<usize> {
    let d2 = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>();
    let h2 = bandwidth * bandwidth;
    let modes: Vec<Vec<f64>> = points
        .iter()
        .map(|start| {
            let mut x = start.clone();
            for _ in 0..200 {
                let mut sum = vec![0.0; x.len()];
                let mut n = 0usize;
                for p in points {
                    if d2(p, &x) <= h2 {
                        n += 1;
                        for (s, v) in sum.iter_mut().zip(p) {
                            *s += v;
                        }
                    }
                }
                if n == 0 {
                    break;
                }
                let next: Vec<f64> = sum.iter().map(|s| s / n as f64).collect();
                let shift = d2(&next, &x);
                x = next;
                if shift < 1e-14 * h2.max(1e-30) {
                    break;
                }
            }
            x
        })
        .collect();
    let mut centres: Vec<Vec<f64>> = Vec::new();
    modes
        .iter()
        .map(|m| {
            if let Some(c) = centres.iter().position(|c| d2(c, m) <= 0.25 * h2) {
                c
            } else {
                centres.push(m.clone());
                centres.len() - 1
            }
        })
        .collect()
}

/// Spectral clustering of the words and the star model (thesis 5.3.3).
pub fn detect_instances(
    words: &[Word],
    matches: &[Option<PairMatch>],
    features: &[Feature],
    eps: f64,
    match_radius: f64,
    min_support: usize,
    o: &InstanceOptions,
) -> (Vec<Class>, ClusteringReport) {
    let k = words.len();
    let mut report = ClusteringReport::default();
    let cm = cooccurrence_matrix(words, matches, min_support);
    let connected: Vec<usize> = (0..k).filter(|&i| (0..k).any(|j| j != i && cm[i * k + j] > 0.0)).collect();
    report.connected_words = connected.len();
    if connected.len() < 2 {
        return (Vec::new(), report);
    }
    let n = connected.len();
    let mut dist = vec![0.0; n * n];
    for a in 0..n {
        for b in 0..n {
            dist[a * n + b] = 1.0 - cm[connected[a] * k + connected[b]];
        }
    }
    let emb = classical_mds(&dist, n, o.embedding_dims.max(1));
    let labels = mean_shift(&emb, o.bandwidth);
    // Split every mean-shift cluster into connected components of the co-occurrence graph.
    let mut clusters: Vec<Vec<usize>> = Vec::new();
    let nlab = labels.iter().max().map_or(0, |m| m + 1);
    for l in 0..nlab {
        let members: Vec<usize> = (0..n).filter(|&a| labels[a] == l).collect();
        let mut seen = vec![false; members.len()];
        for s in 0..members.len() {
            if seen[s] {
                continue;
            }
            let mut comp = vec![members[s]];
            seen[s] = true;
            let mut q = 0;
            while q < comp.len() {
                let a = comp[q];
                for (t, &b) in members.iter().enumerate() {
                    if !seen[t] && cm[connected[a] * k + connected[b]] > 0.0 {
                        seen[t] = true;
                        comp.push(b);
                    }
                }
                q += 1;
            }
            clusters.push(comp);
        }
    }
    report.clusters = clusters.len();
    let fine_r = match_radius * eps;
    let word_hashes: Vec<SpatialHash> = words
        .iter()
        .map(|w| {
            SpatialHash::new(
                &w.members.iter().map(|m| features[m.feature as usize].position).collect::<Vec<_>>(),
                fine_r,
            )
        })
        .collect();
    let mut classes = Vec::new();
    for comp in clusters {
        if comp.len() < 2 {
            continue;
        }
        // Centre word: the member nearest the cluster's coordinate-wise median in the embedding.
        let dims = emb[0].len();
        let median: Vec<f64> = (0..dims)
            .map(|d| {
                let mut v: Vec<f64> = comp.iter().map(|&a| emb[a][d]).collect();
                v.sort_by(f64::total_cmp);
                v[v.len() / 2]
            })
            .collect();
        let centre_local = *comp
            .iter()
            .min_by(|&&a, &&b| {
                let da: f64 = emb[a].iter().zip(&median).map(|(x, y)| (x - y) * (x - y)).sum();
                let db: f64 = emb[b].iter().zip(&median).map(|(x, y)| (x - y) * (x - y)).sum();
                da.total_cmp(&db).then(a.cmp(&b))
            })
            .unwrap_or(&comp[0]);
        let c = connected[centre_local];
        let others: Vec<(usize, &PairMatch)> = comp
            .iter()
            .map(|&a| connected[a])
            .filter(|&j| j != c)
            .filter_map(|j| {
                matches[c * k + j].as_ref().filter(|m| m.support.len() >= min_support.max(1)).map(|m| (j, m))
            })
            .collect();
        if others.is_empty() {
            continue;
        }
        let need = ((o.min_links * others.len() as f64).ceil() as usize).max(1);
        // Star model: link each centre feature to the predicted member of every other word.
        let mut raw: Vec<(usize, u8, Vec<usize>, Point3, Point3)> = Vec::new();
        for m in &words[c].members {
            let f = &features[m.feature as usize];
            let mut linked = vec![m.feature as usize];
            let mut links = 0;
            for &(j, pm) in &others {
                let pred = f.to_world(m.flip, pm.offset);
                if let Some((b, _)) = word_hashes[j].nearest_within(pred, fine_r) {
                    let fb = words[j].members[b].feature as usize;
                    if fb != m.feature as usize {
                        links += 1;
                        linked.push(fb);
                    }
                }
            }
            if links < need {
                continue;
            }
            linked.sort_unstable();
            linked.dedup();
            let mut lo = [0.0f64; 3];
            let mut hi = [0.0f64; 3];
            for &g in &linked {
                let l = f.to_local(m.flip, motif_core::geometry::sub(features[g].position, f.position));
                for d in 0..3 {
                    lo[d] = lo[d].min(l[d]);
                    hi[d] = hi[d].max(l[d]);
                }
            }
            raw.push((m.feature as usize, m.flip, linked, lo, hi));
        }
        if raw.len() < o.min_instances.max(1) {
            continue;
        }
        let pad = o.box_margin * eps;
        let med = |sel: &dyn Fn(&(usize, u8, Vec<usize>, Point3, Point3)) -> f64| {
            let mut v: Vec<f64> = raw.iter().map(sel).collect();
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let local_min = [med(&|r| r.3[0]) - pad, med(&|r| r.3[1]) - pad, med(&|r| r.3[2]) - pad];
        let local_max = [med(&|r| r.4[0]) + pad, med(&|r| r.4[1]) + pad, med(&|r| r.4[2]) + pad];
        let mut instances: Vec<Instance> = raw
            .into_iter()
            .map(|(centre, flip, linked, _, _)| {
                let f = &features[centre];
                let a = f.axes(flip);
                let r =
                    [[a[0][0], a[1][0], a[2][0]], [a[0][1], a[1][1], a[2][1]], [a[0][2], a[1][2], a[2][2]]];
                let frame = mat4_from_rt(r, f.position);
                let mut bb: Option<Aabb> = None;
                for cx in [local_min[0], local_max[0]] {
                    for cy in [local_min[1], local_max[1]] {
                        for cz in [local_min[2], local_max[2]] {
                            let w = f.to_world(flip, [cx, cy, cz]);
                            match &mut bb {
                                Some(b) => b.grow(w),
                                None => bb = Some(Aabb { min: w, max: w }),
                            }
                        }
                    }
                }
                Instance {
                    centre,
                    flip,
                    features: linked,
                    frame,
                    aabb: bb.unwrap_or(Aabb { min: f.position, max: f.position }),
                }
            })
            .collect();
        // Merge overlapping instances, best linked first.
        instances.sort_by(|a, b| b.features.len().cmp(&a.features.len()).then(a.centre.cmp(&b.centre)));
        let mut kept: Vec<Instance> = Vec::new();
        for inst in instances {
            let overlaps = kept.iter().any(|q| {
                inst.aabb.intersection(&q.aabb).is_some_and(|x| {
                    x.volume()
                        > o.merge_overlap * inst.aabb.volume().min(q.aabb.volume()).max(f64::MIN_POSITIVE)
                })
            });
            if !overlaps {
                kept.push(inst);
            }
        }
        if kept.len() < o.min_instances.max(1) {
            continue;
        }
        let mut words_of_class: Vec<usize> = comp.iter().map(|&a| connected[a]).collect();
        words_of_class.sort_unstable();
        classes.push(Class { words: words_of_class, centre_word: c, local_min, local_max, instances: kept });
    }
    // Largest first: most instances, then most linked features.
    classes.sort_by(|a, b| {
        let fa: usize = a.instances.iter().map(|i| i.features.len()).sum();
        let fb: usize = b.instances.iter().map(|i| i.features.len()).sum();
        b.instances.len().cmp(&a.instances.len()).then(fb.cmp(&fa)).then(a.centre_word.cmp(&b.centre_word))
    });
    report.classes = classes.len();
    (classes, report)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mds_recovers_planar_distances() {
        let pts: [[f64; 2]; 5] = [[0.0, 0.0], [1.0, 0.0], [0.0, 2.0], [3.0, 1.0], [-1.0, 0.5]];
        let n = pts.len();
        let mut d = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                d[i * n + j] = ((pts[i][0] - pts[j][0]).powi(2) + (pts[i][1] - pts[j][1]).powi(2)).sqrt();
            }
        }
        let e = classical_mds(&d, n, 5);
        for i in 0..n {
            for j in 0..n {
                let de: f64 = e[i].iter().zip(&e[j]).map(|(a, b)| (a - b) * (a - b)).sum::<f64>().sqrt();
                assert!((de - d[i * n + j]).abs() < 1e-9, "{i} {j}: {de} vs {}", d[i * n + j]);
            }
        }
    }

    #[test]
    fn mean_shift_separates_two_blobs() {
        let mut pts = Vec::new();
        for i in 0..10 {
            pts.push(vec![0.01 * i as f64, 0.0]);
            pts.push(vec![2.0 + 0.01 * i as f64, 1.0]);
        }
        let l = mean_shift(&pts, 0.5);
        for i in 0..10 {
            assert_eq!(l[2 * i], l[0]);
            assert_eq!(l[2 * i + 1], l[1]);
        }
        assert_ne!(l[0], l[1]);
    }
}
