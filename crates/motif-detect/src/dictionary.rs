//! The feature dictionary (thesis 5.3.1, 5.4): k-means (K = 100, k-means++ seeding) over HOC
//! descriptors, each word's template the member closest to all others, and each word's list of
//! matches found by a sliding-window search of its template over all features, purified by
//! non-maximum suppression at half the descriptor's size.
//!
//! The matching score is the thesis's m(x, y) = exp(−|HOC(x) − HOC(y)|₁ / σ²), σ = 0.1, with one
//! change of units that the thesis needs but does not state: for L1-normalised 1,024-bin
//! histograms of noisy scans, even two views of the same geometry are 0.3–1.0 apart in L1, so the
//! literal formula gives m < e⁻³⁰ for every pair and nothing ever passes the 0.5 cut. Motif
//! measures the L1 distance in units of the data's own typical within-cluster distance d̂ (the
//! median distance of a feature to its k-means template) scaled so that, at the thesis's σ = 0.1,
//! m = 0.5 exactly at d = `tolerance` · d̂: m = exp(−ln 2 · (d / (tolerance · d̂)) · (0.1 / σ)²).
//! Changing σ therefore widens or narrows the kernel exactly as in the thesis's formula.

use motif_core::spatial::{DescriptorNnOptions, descriptor_nn};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::hoc::{DIM, Descriptors, l1};
use crate::preprocess::Feature;

/// Options of [`build`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct DictionaryOptions {
    /// K, the number of k-means clusters (thesis 5.4: 100). Fewer when there are fewer than 4
    /// features per word.
    pub words: usize,
    /// Lloyd iterations after k-means++ seeding. Default 15.
    pub kmeans_iterations: usize,
    /// k-means runs on at most this many features (a seeded random subset); all features are then
    /// assigned to the nearest centre. Default 4,000: enough for 100 centres of 1,024 dimensions.
    pub kmeans_sample: usize,
    /// σ of the matching score m(x, y) (thesis 5.4: 0.1). See the module documentation.
    pub sigma: f64,
    /// Distance, in units of the median within-cluster distance d̂, at which m = 0.5 when σ = 0.1.
    /// Not in the thesis (see the module documentation). Default 1.
    pub tolerance: f64,
    /// Matches scoring below this are dropped (thesis 5.4: 0.5).
    pub min_score: f64,
    /// Minimum distance between two matches of one word, in ε (thesis 5.3.1: half the descriptor
    /// size; the descriptor spans 8 cells of 8ε, so 32ε). Default 32.
    pub purify_radius: f64,
}

impl Default for DictionaryOptions {
    fn default() -> Self {
        DictionaryOptions {
            words: 100,
            kmeans_iterations: 15,
            kmeans_sample: 4000,
            sigma: 0.1,
            tolerance: 1.0,
            min_score: 0.5,
            purify_radius: 32.0,
        }
    }
}

/// One feature in a word's list of matches.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Member {
    /// Feature index.
    pub feature: u32,
    /// Which of the feature's two frames matches the template (see [`Feature::axes`]).
    pub flip: u8,
    /// Matching score or EM confidence, in (0, 1].
    pub score: f32,
}

/// A dictionary word: a template descriptor and its list of matched features Dⁱ.
#[derive(Debug, Clone)]
pub struct Word {
    /// The template tⁱ (`DIM` values).
    pub template: Vec<f32>,
    /// The matches, strongest first.
    pub members: Vec<Member>,
}

/// The matching score m(x, y) with its data-derived distance unit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Matcher {
    /// d̂: median L1 distance of a feature to its k-means template.
    pub unit: f64,
    /// Multiplier of the L1 distance in the exponent.
    rate: f64,
}

impl Matcher {
    /// The matcher for a distance unit `unit` (d̂) and the options' σ and tolerance.
    pub fn new(unit: f64, o: &DictionaryOptions) -> Matcher {
        let unit = if unit > 0.0 && unit.is_finite() { unit } else { 1.0 };
        let s = 0.1 / o.sigma.max(1e-12);
        Matcher { unit, rate: std::f64::consts::LN_2 / (o.tolerance.max(1e-12) * unit) * s * s }
    }

    /// m for an L1 distance.
    pub fn score(&self, d: f32) -> f32 {
        (-(d as f64) * self.rate).exp() as f32
    }

    /// The best score of `template` against feature `f` over its two frames, and that frame.
    pub fn best(&self, template: &[f32], desc: &Descriptors, f: usize) -> (f32, u8) {
        let d0 = l1(template, desc.row(f, 0));
        let d1 = l1(template, desc.row(f, 1));
        if d1 < d0 { (self.score(d1), 1) } else { (self.score(d0), 0) }
    }
}

/// The result of [`build`].
#[derive(Debug, Clone)]
pub struct Dictionary {
    /// The words (empty ones removed).
    pub words: Vec<Word>,
    /// The matching score.
    pub matcher: Matcher,
    /// The number of k-means clusters actually used.
    pub k: usize,
}

/// Builds the initial dictionary from the features' descriptors.
pub fn build(
    features: &[Feature],
    desc: &Descriptors,
    epsilon: f64,
    o: &DictionaryOptions,
    seed: u64,
) -> Dictionary {
    let n = features.len();
    let k = o.words.min(n / 4).max(1);
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x9e37_79b9_7f4a_7c15);
    let mut sample: Vec<usize> = (0..n).collect();
    sample.shuffle(&mut rng);
    sample.truncate(o.kmeans_sample.max(k));
    sample.sort_unstable();
    let rows = |idx: &[usize]| -> Vec<f32> {
        let mut v = Vec::with_capacity(idx.len() * DIM);
        for &i in idx {
            v.extend_from_slice(desc.row(i, 0));
        }
        v
    };
    let data = rows(&sample);
    let centres = kmeans(&data, k, o.kmeans_iterations, &mut rng);
    // Assign every feature to its nearest centre (L2, as k-means minimises).
    let all = rows(&(0..n).collect::<Vec<_>>());
    let assign: Vec<usize> = descriptor_nn(&all, &centres, DIM, false, &DescriptorNnOptions::default())
        .map(|v| v.into_iter().map(|m| m.map_or(0, |m| m.target)).collect())
        .unwrap_or_else(|_| vec![0; n]);
    let mut clusters: Vec<Vec<usize>> = vec![Vec::new(); k];
    for (f, &c) in assign.iter().enumerate() {
        clusters[c].push(f);
    }
    // Template: the member with the smallest summed L1 distance to the others (on at most 64
    // members, a seeded subset, to keep this linear in the cluster size).
    let templates: Vec<Option<(usize, Vec<f32>)>> = clusters
        .par_iter()
        .enumerate()
        .map(|(c, members)| {
            if members.is_empty() {
                return None;
            }
            let mut m = members.clone();
            if m.len() > 64 {
                let mut r = ChaCha8Rng::seed_from_u64(seed.wrapping_add(c as u64));
                m.shuffle(&mut r);
                m.truncate(64);
            }
            let best = m
                .iter()
                .map(|&a| {
                    let s: f32 = m.iter().map(|&b| l1(desc.row(a, 0), desc.row(b, 0))).sum();
                    (s, a)
                })
                .min_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)))
                .map(|(_, a)| a)?;
            Some((c, desc.row(best, 0).to_vec()))
        })
        .collect();
    // d̂: median distance of a feature to its own cluster's template.
    let mut dists: Vec<f32> = (0..n)
        .into_par_iter()
        .filter_map(|f| templates[assign[f]].as_ref().map(|(_, t)| l1(t, desc.row(f, 0))))
        .filter(|d| *d > 0.0)
        .collect();
    dists.sort_by(f32::total_cmp);
    let unit = dists.get(dists.len() / 2).copied().unwrap_or(1.0) as f64;
    let matcher = Matcher::new(unit, o);
    let words: Vec<Word> = templates
        .into_par_iter()
        .flatten()
        .map(|(_, template)| {
            let scores: Vec<(f32, u8)> = (0..n).map(|f| matcher.best(&template, desc, f)).collect();
            let members = find_peaks(&scores, o.min_score as f32, o.purify_radius * epsilon, features);
            Word { template, members }
        })
        .filter(|w| w.members.len() >= 2)
        .collect();
    Dictionary { words, matcher, k }
}

/// Non-maximum suppression over per-feature `(score, flip)`: features scoring at least `min`,
/// strongest first, each kept unless a kept feature lies within `radius` (the thesis's sliding-
/// window purification and EM FindPeak).
pub fn find_peaks(scores: &[(f32, u8)], min: f32, radius: f64, features: &[Feature]) -> Vec<Member> {
    let mut cand: Vec<usize> =
        (0..scores.len()).filter(|&f| scores[f].0 >= min && scores[f].0 > 0.0).collect();
    cand.sort_by(|&a, &b| scores[b].0.total_cmp(&scores[a].0).then(a.cmp(&b)));
    // Only kept features can block a candidate, and they are sparse (at least `radius` apart), so
    // they are hashed as they are kept: a check visits a handful of points, not every feature.
    let cell = radius.max(f64::MIN_POSITIVE);
    let key = |p: motif_core::Point3| {
        [(p[0] / cell).floor() as i64, (p[1] / cell).floor() as i64, (p[2] / cell).floor() as i64]
    };
    let mut kept: std::collections::HashMap<[i64; 3], Vec<u32>> = std::collections::HashMap::new();
    let r2 = radius * radius;
    let mut out = Vec::new();
    for f in cand {
        let p = features[f].position;
        let k = key(p);
        let mut blocked = false;
        'search: for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    if let Some(v) = kept.get(&[k[0] + dx, k[1] + dy, k[2] + dz]) {
                        if v.iter()
                            .any(|&g| motif_core::geometry::dist2(features[g as usize].position, p) <= r2)
                        {
                            blocked = true;
                            break 'search;
                        }
                    }
                }
            }
        }
        if blocked {
            continue;
        }
        kept.entry(k).or_default().push(f as u32);
        out.push(Member { feature: f as u32, flip: scores[f].1, score: scores[f].0 });
    }
    out
}

/// k-means with k-means++ seeding over `dim`-dimensional rows; returns `k × DIM` centres.
fn kmeans(data: &[f32], k: usize, iterations: usize, rng: &mut ChaCha8Rng) -> Vec<f32> {
    let n = data.len() / DIM;
    let row = |i: usize| &data[i * DIM..(i + 1) * DIM];
    let d2 = |a: &[f32], b: &[f32]| a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f32>();
    let mut centres: Vec<f32> = Vec::with_capacity(k * DIM);
    let first = rng.random_range(0..n);
    centres.extend_from_slice(row(first));
    let mut nearest: Vec<f32> = (0..n).into_par_iter().map(|i| d2(row(i), row(first))).collect();
    while centres.len() / DIM < k {
        let total: f64 = nearest.iter().map(|&v| v as f64).sum();
        let pick = if total > 0.0 {
            let mut t = rng.random::<f64>() * total;
            let mut chosen = n - 1;
            for (i, &v) in nearest.iter().enumerate() {
                t -= v as f64;
                if t <= 0.0 {
                    chosen = i;
                    break;
                }
            }
            chosen
        } else {
            rng.random_range(0..n)
        };
        let c = row(pick).to_vec();
        nearest.par_iter_mut().enumerate().for_each(|(i, v)| *v = v.min(d2(row(i), &c)));
        centres.extend_from_slice(&c);
    }
    for _ in 0..iterations {
        let assign: Vec<usize> =
            match descriptor_nn(data, &centres, DIM, false, &DescriptorNnOptions::default()) {
                Ok(m) => m.into_iter().map(|m| m.map_or(0, |m| m.target)).collect(),
                Err(_) => break,
            };
        let mut sums = vec![0.0f64; k * DIM];
        let mut counts = vec![0usize; k];
        for (i, &c) in assign.iter().enumerate() {
            counts[c] += 1;
            for (s, &x) in sums[c * DIM..(c + 1) * DIM].iter_mut().zip(row(i)) {
                *s += x as f64;
            }
        }
        let mut moved = false;
        for c in 0..k {
            if counts[c] == 0 {
                continue;
            }
            for d in 0..DIM {
                let v = (sums[c * DIM + d] / counts[c] as f64) as f32;
                if v != centres[c * DIM + d] {
                    moved = true;
                }
                centres[c * DIM + d] = v;
            }
        }
        if !moved {
            break;
        }
    }
    centres
}
