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
/// pair radius.
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
    best
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
