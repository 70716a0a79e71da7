//! Robust co-occurring feature detection (thesis 5.3.2, Algorithm 1): an EM loop that alternates
//! Match (the local transform between two words' constellations), Vote (eq. 5.1), FindPeak and
//! UpdateTemplate until the dictionary stops changing.
//!
//! Interpretation choices, where the thesis is terse:
//! - **Local transform.** Every member carries a frame (x = normal, y = ±t₁); T_{i→j} is a fixed
//!   offset `v` in the source member's frame, so it maps member `a` of Dⁱ to `a + R_a v`. This is
//!   what makes the matching rotation invariant (5.2).
//! - **Match.** The thesis tests every pair ⟨a ∈ Dⁱ, b ∈ Dʲ⟩ (within 64ε) as a hypothesis and keeps
//!   the one with most matches. Motif casts each such pair's local offset into a Hough grid of 8ε
//!   cells (the match tolerance) and checks the three fullest cells exactly — counting, for every
//!   a, whether a member of Dʲ lies within 8ε of `a + R_a v` — which finds the same maximum
//!   without the quadratic re-check of every pair. Ψ(i, j) is the set of matched sources.
//! - **A peak, not chance.** The best hypothesis is kept only when its support is at least
//!   [`EmOptions::peak_share`] of the pair's hypotheses (1/8 by default, the ratio of the 8ε
//!   match radius to the 64ε pair radius). Features are curvature maxima and lie along creases;
//!   for two words whose members are strewn along a crease without a fixed relation, an offset
//!   chosen at random catches about 2·8ε / 2·64ε = 1/8 of the candidates, so a best offset below
//!   that share is what chance alone gives. The thesis's fixed minimum |Ψ(i, j)| cannot tell the
//!   two apart: on noisy, cluttered scans dense words (features on the wall's noise, on long
//!   straight junctions) reach 5 matches at many offsets.
//! - **Vote, eq. 5.1.** Read as a Gaussian in the prediction error times the template score,
//!   exp(−‖y − T·x‖² / σ_s²) · m(tʲ, y): as printed, the score sits inside the exponent and a
//!   better descriptor match would lower the vote, which cannot be meant.
//! - **Maximisation.** Word j's new confidence at feature y sums the votes it receives from all
//!   words i ≠ j whose pair passes the |Ψ(i, j)| threshold; FindPeak normalises it to a maximum of
//!   1, drops < 0.25 and suppresses non-maxima at the purification radius (32ε).
//! - **UpdateTemplate.** The medoid of the members' descriptors (in their matched frames): the
//!   "median feature" of the thesis (a bin-wise median of sparse histograms is mostly zero).

use motif_core::Point3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::dictionary::{Matcher, Member, Word, find_peaks};
use crate::grid::SpatialHash;
use crate::hoc::{Descriptors, l1};
use crate::preprocess::Feature;

/// Options of [`run_em`] and [`match_all`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct EmOptions {
    /// Maximum EM iterations (thesis 5.4: 5).
    pub iterations: usize,
    /// Stop when fewer than this fraction of word memberships change (thesis 5.4: 1%).
    pub min_change: f64,
    /// Match tolerance: a prediction matches a feature of Dʲ within this distance, in ε (thesis
    /// 5.4: 8ε, one HOC cell).
    pub match_radius: f64,
    /// Only feature pairs at most this far apart form hypotheses, in ε (thesis 5.4: 64ε).
    pub pair_radius: f64,
    /// σ_s of eq. 5.1, in ε (thesis 5.4: 16ε).
    pub sigma_s: f64,
    /// Pairs with |Ψ(i, j)| below this are discarded (thesis 5.4: 5 for single shapes, 10 for city
    /// scans). Default 5.
    pub min_support: usize,
    /// Match keeps a pair's best local transform only when its support |Ψ(i, j)| is at least this
    /// fraction of the pair's hypotheses (member pairs ⟨a ∈ Dⁱ, b ∈ Dʲ⟩ within the pair radius);
    /// otherwise the pair does not co-occur. Not in the thesis. Default 0.125 = `match_radius /
    /// pair_radius`, the share a random offset catches when the members lie along a line (see the
    /// module documentation); 0 keeps every best hypothesis, as the thesis does. Measured with
    /// `motif bench detect --no-icp --scenes 6` (seeds 1–6), F of EM + SC easy / medium / hard:
    /// facade 0.922 / 0.812 / 0.468 with 0, 0.914 / 0.851 / 0.478 with 0.125; street 0.725 /
    /// 0.653 / 0.393 with 0, 0.698 / 0.666 / 0.501 with 0.125. Swept on facade seeds 1–3 before
    /// the rigid-motion fixes of `instances::kabsch` and `Aabb::mapped`, medium / hard F was
    /// 0.794 / 0.449 with 0, 0.907 / 0.481 with 0.125, 0.897 / 0.447 with 0.1875 and 0.826 /
    /// 0.293 with 0.25 (0.0625: 0.838 / 0.444): past 1/8 precision rises and recall falls. The SC
    /// baseline (no EM) keeps no pair on hard scenes: its words are too impure for any offset to
    /// stand out.
    pub peak_share: f64,
    /// FindPeak drops features whose normalised confidence is below this (thesis 5.4: 0.25).
    pub min_confidence: f64,
    /// Purification / FindPeak NMS radius, in ε (half the descriptor size, 32ε).
    pub peak_radius: f64,
}

impl Default for EmOptions {
    fn default() -> Self {
        EmOptions {
            iterations: 5,
            min_change: 0.01,
            match_radius: 8.0,
            pair_radius: 64.0,
            sigma_s: 16.0,
            min_support: 5,
            peak_share: 0.125,
            min_confidence: 0.25,
            peak_radius: 32.0,
        }
    }
}

/// The best local transform from word i to word j.
#[derive(Debug, Clone, PartialEq)]
pub struct PairMatch {
    /// The offset `v` in the source member's frame.
    pub offset: Point3,
    /// Ψ(i, j): indices into Dⁱ's members whose prediction found a member of Dʲ.
    pub support: Vec<u32>,
}

/// Per-word spatial hashes used by Match.
struct WordGrids {
    fine: SpatialHash,
    coarse: SpatialHash,
}

fn word_grids(word: &Word, features: &[Feature], eps: f64, o: &EmOptions) -> WordGrids {
    let pts: Vec<Point3> = word.members.iter().map(|m| features[m.feature as usize].position).collect();
    WordGrids {
        fine: SpatialHash::new(&pts, o.match_radius * eps),
        coarse: SpatialHash::new(&pts, o.pair_radius * eps),
    }
}

/// Match(Dⁱ, Dʲ): the local offset with the most matches, or `None` when no pair lies within the
/// pair radius or the best offset's support is under [`EmOptions::peak_share`] of the hypotheses.
fn match_pair(
    wi: &Word,
    wj: &Word,
    gj: &WordGrids,
    features: &[Feature],
    eps: f64,
    o: &EmOptions,
    offsets: &mut Vec<([i32; 3], Point3)>,
) -> Option<PairMatch> {
    let cell = o.match_radius * eps;
    let pair_r = o.pair_radius * eps;
    offsets.clear();
    for a in &wi.members {
        let fa = &features[a.feature as usize];
        gj.coarse.for_each_within(fa.position, pair_r, |bj, _| {
            let b = wj.members[bj].feature;
            if b == a.feature {
                return;
            }
            let v =
                fa.to_local(a.flip, motif_core::geometry::sub(features[b as usize].position, fa.position));
            let key =
                [(v[0] / cell).floor() as i32, (v[1] / cell).floor() as i32, (v[2] / cell).floor() as i32];
            offsets.push((key, v));
        });
    }
    if offsets.is_empty() {
        return None;
    }
    offsets.sort_unstable_by_key(|x| x.0);
    // Runs of equal keys, fullest first.
    let mut runs: Vec<(usize, usize)> = Vec::new();
    let mut s = 0;
    for e in 1..=offsets.len() {
        if e == offsets.len() || offsets[e].0 != offsets[s].0 {
            runs.push((s, e));
            s = e;
        }
    }
    runs.sort_by(|x, y| (y.1 - y.0).cmp(&(x.1 - x.0)).then(x.0.cmp(&y.0)));
    let mut best: Option<PairMatch> = None;
    for &(s, e) in runs.iter().take(3) {
        let mut v = [0.0; 3];
        for (_, o) in &offsets[s..e] {
            for d in 0..3 {
                v[d] += o[d] / (e - s) as f64;
            }
        }
        let support: Vec<u32> = wi
            .members
            .iter()
            .enumerate()
            .filter(|(_, a)| {
                let fa = &features[a.feature as usize];
                let pred = fa.to_world(a.flip, v);
                let mut hit = false;
                gj.fine.for_each_within(pred, cell, |bj, _| hit |= wj.members[bj].feature != a.feature);
                hit
            })
            .map(|(k, _)| k as u32)
            .collect();
        if best.as_ref().is_none_or(|b| support.len() > b.support.len()) {
            best = Some(PairMatch { offset: v, support });
        }
    }
    best.filter(|b| b.support.len() as f64 >= o.peak_share * offsets.len() as f64)
}

/// Match over every ordered pair of words (i ≠ j); entry `i * K + j`.
pub fn match_all(words: &[Word], features: &[Feature], eps: f64, o: &EmOptions) -> Vec<Option<PairMatch>> {
    let k = words.len();
    let grids: Vec<WordGrids> = words.par_iter().map(|w| word_grids(w, features, eps, o)).collect();
    (0..k * k)
        .into_par_iter()
        .map_init(Vec::new, |buf, ij| {
            let (i, j) = (ij / k, ij % k);
            if i == j {
                return None;
            }
            match_pair(&words[i], &words[j], &grids[j], features, eps, o, buf)
        })
        .collect()
}

/// What one EM run did.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct EmReport {
    /// Iterations run.
    pub iterations: usize,
    /// Fraction of word memberships that changed, per iteration.
    pub changes: Vec<f64>,
    /// Words left after each iteration.
    pub words: Vec<usize>,
    /// Word pairs passing the |Ψ| threshold, per iteration.
    pub strong_pairs: Vec<usize>,
}

/// Algorithm 1: refines the words in place and returns what happened.
pub fn run_em(
    words: &mut Vec<Word>,
    features: &[Feature],
    desc: &Descriptors,
    matcher: &Matcher,
    eps: f64,
    o: &EmOptions,
    mut on_iteration: impl FnMut(usize),
) -> EmReport {
    let mut report = EmReport::default();
    let positions: Vec<Point3> = features.iter().map(|f| f.position).collect();
    let all = SpatialHash::new(&positions, o.sigma_s * eps);
    for it in 0..o.iterations {
        let k = words.len();
        if k < 2 {
            break;
        }
        let matches = match_all(words, features, eps, o);
        let strong = |i: usize, j: usize| {
            matches[i * k + j].as_ref().filter(|m| m.support.len() >= o.min_support.max(1))
        };
        report.strong_pairs.push((0..k * k).filter(|&ij| strong(ij / k, ij % k).is_some()).count());
        let sigma_s = o.sigma_s * eps;
        let new_words: Vec<Word> = (0..k)
            .into_par_iter()
            .map(|j| {
                // Template scores of word j over all features, computed lazily.
                let mut tscore: Vec<Option<(f32, u8)>> = vec![None; features.len()];
                let mut conf = vec![0.0f64; features.len()];
                for i in 0..k {
                    if i == j {
                        continue;
                    }
                    let Some(m) = strong(i, j) else { continue };
                    for a in &words[i].members {
                        let fa = &features[a.feature as usize];
                        let pred = fa.to_world(a.flip, m.offset);
                        all.for_each_within(pred, sigma_s, |y, d2| {
                            let s =
                                *tscore[y].get_or_insert_with(|| matcher.best(&words[j].template, desc, y));
                            conf[y] += (-d2 / (sigma_s * sigma_s)).exp() * s.0 as f64;
                        });
                    }
                }
                let max = conf.iter().cloned().fold(0.0, f64::max);
                if max.is_nan() || max <= 0.0 {
                    return Word { template: words[j].template.clone(), members: Vec::new() };
                }
                let scores: Vec<(f32, u8)> = conf
                    .iter()
                    .zip(&tscore)
                    .map(|(&c, t)| ((c / max) as f32, t.map_or(0, |t| t.1)))
                    .collect();
                let members = find_peaks(&scores, o.min_confidence as f32, o.peak_radius * eps, features);
                let template = median_template(&members, desc).unwrap_or_else(|| words[j].template.clone());
                Word { template, members }
            })
            .collect();
        // Membership change, as a fraction of the old memberships.
        let old_total: usize = words.iter().map(|w| w.members.len()).sum();
        let changed: usize = words
            .iter()
            .zip(&new_words)
            .map(|(a, b)| {
                let mut x: Vec<u32> = a.members.iter().map(|m| m.feature).collect();
                let mut y: Vec<u32> = b.members.iter().map(|m| m.feature).collect();
                x.sort_unstable();
                y.sort_unstable();
                let common = intersection_len(&x, &y);
                x.len() + y.len() - 2 * common
            })
            .sum();
        let change = changed as f64 / old_total.max(1) as f64;
        *words = new_words.into_iter().filter(|w| w.members.len() >= 2).collect();
        report.iterations = it + 1;
        report.changes.push(change);
        report.words.push(words.len());
        on_iteration(it);
        if change < o.min_change {
            break;
        }
    }
    report
}

fn intersection_len(a: &[u32], b: &[u32]) -> usize {
    let (mut i, mut j, mut n) = (0, 0, 0);
    while i < a.len() && j < b.len() {
        match a[i].cmp(&b[j]) {
            std::cmp::Ordering::Less => i += 1,
            std::cmp::Ordering::Greater => j += 1,
            std::cmp::Ordering::Equal => {
                n += 1;
                i += 1;
                j += 1;
            }
        }
    }
    n
}

/// The "median feature" of a word: the member whose descriptor has the smallest summed L1
/// distance to the other members' (a medoid, computed over the 64 most confident members).
/// A bin-wise median would be the literal reading, but HOC histograms are sparse and the median of
/// each bin is mostly zero, which leaves a template that matches nothing.
fn median_template(members: &[Member], desc: &Descriptors) -> Option<Vec<f32>> {
    let top = &members[..members.len().min(64)];
    let best = top
        .iter()
        .map(|a| {
            let ra = desc.row(a.feature as usize, a.flip);
            let s: f32 = top.iter().map(|b| l1(ra, desc.row(b.feature as usize, b.flip))).sum();
            (s, a)
        })
        .min_by(|x, y| x.0.total_cmp(&y.0).then(x.1.feature.cmp(&y.1.feature)))?;
    Some(desc.row(best.1.feature as usize, best.1.flip).to_vec())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Features on the plane z = 0, all with the same frame (normal +z, t₁ along x).
    fn plane_feature(x: f64, y: f64) -> Feature {
        Feature { point: 0, position: [x, y, 0.0], x: [0.0, 0.0, 1.0], y: [1.0, 0.0, 0.0], kappa: 1.0 }
    }

    fn word(members: std::ops::Range<usize>) -> Word {
        Word {
            template: Vec::new(),
            members: members.map(|f| Member { feature: f as u32, flip: 0, score: 1.0 }).collect(),
        }
    }

    /// Two words whose members are strewn over a plane with no relation between them: the best
    /// hypothesis still gathers the thesis's five matches, but only a small share of the pair's
    /// hypotheses, so the peak test rejects it.
    #[test]
    fn chance_coincidences_on_a_surface_are_not_a_peak() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let features: Vec<Feature> = (0..300)
            .map(|_| plane_feature(rng.random_range(0.0..600.0), rng.random_range(0.0..600.0)))
            .collect();
        let words = vec![word(0..150), word(150..300)];
        let thesis = EmOptions { peak_share: 0.0, ..Default::default() };
        let m = match_all(&words, &features, 1.0, &thesis);
        let best = m[1].as_ref().expect("hypotheses within 64ε");
        assert!(best.support.len() >= thesis.min_support, "support {}", best.support.len());
        assert!(match_all(&words, &features, 1.0, &EmOptions::default())[1].is_none());
    }

    /// A fixed constellation (every member of word 0 has a member of word 1 at the same local
    /// offset) among as many unrelated members of word 1 is a peak.
    #[test]
    fn a_repeated_constellation_is_a_peak() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut features = Vec::new();
        for i in 0..8 {
            for j in 0..5 {
                let (x, y) = (150.0 * i as f64 + rng.random_range(-20.0..20.0), 150.0 * j as f64);
                features.push(plane_feature(x, y));
            }
        }
        let partners: Vec<Feature> =
            features.iter().map(|f| plane_feature(f.position[0] + 20.0, f.position[1] + 10.0)).collect();
        features.extend(partners);
        for _ in 0..40 {
            features.push(plane_feature(rng.random_range(0.0..1200.0), rng.random_range(0.0..750.0)));
        }
        let words = vec![word(0..40), word(40..120)];
        let m = match_all(&words, &features, 1.0, &EmOptions::default());
        let best = m[1].as_ref().expect("the constellation is a peak");
        assert_eq!(best.support.len(), 40);
        // Local axes: x = the normal (world z), y = t₁ (world x), z = x × y (world y).
        let expected = [0.0, 20.0, 10.0];
        assert!((0..3).all(|d| (best.offset[d] - expected[d]).abs() < 1.0), "offset {:?}", best.offset);
    }
}
