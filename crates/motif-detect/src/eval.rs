//! The evaluation protocol of thesis 5.5.2: precision, recall and F of a building-block
//! detection against a ground-truth annotation, the PR curve by successive class removal, and
//! the stress curve over the minimum overlap ratio τ. The exact definitions are those of
//! `../shared/formats/detection.md`.
//!
//! Conventions:
//! - Two boxes A, B *match* when vol(A ∩ B) > 0 and vol(A ∩ B) / max(vol(A), vol(B)) ≥ τ
//!   (see [`overlap_ratio`]). Requiring a positive intersection makes τ = 0 mean "the boxes
//!   overlap" rather than "any two boxes", and means a flat (zero-volume) box never matches
//!   anything: give annotations of planar parts a small thickness.
//! - score(𝐃ʲ, 𝐆ⁱ) = min(#boxes of 𝐃ʲ matching some box of 𝐆ⁱ, #boxes of 𝐆ⁱ matching some box
//!   of 𝐃ʲ) (eq. 5.4).
//! - precision = Σⱼ maxᵢ score(𝐃ʲ, 𝐆ⁱ) / Σⱼ |𝐃ʲ| (eq. 5.5); recall swaps 𝐃 and 𝐆;
//!   F = 2PR / (P + R), and F = 0 when P + R = 0.
//! - Empty sides: when the detection and the ground truth both have no instances, nothing was
//!   missed and nothing is spurious, so P = R = F = 1. Otherwise a ratio whose denominator is 0
//!   is 0: an empty detection scores P = R = F = 0 against a non-empty ground truth, and a
//!   non-empty detection scores P = R = F = 0 against an empty ground truth.
//!
//! Beyond the thesis, each report breaks the two numerators down by class
//! ([`AnnotatedClassReport`], [`DetectedClassReport`]): which annotated instances no detected
//! box locates, which are located but credited to no class, and how much of each detected class
//! the precision credits. The per-class terms add up to exactly the P and R above.
//!
//! Also beyond the thesis, each report bounds what regrouping the detected boxes could reach
//! ([`EvalReport::located_recall`]): the recall counts, per annotated class, at most the
//! instances some detected box matches, so no grouping or pruning of these boxes scores a recall
//! above the share of annotated instances they locate, nor (with P ≤ 1) an F above
//! 2R / (1 + R) for that share. It is an upper bound, not always reached (a box spanning two
//! blocks locates both but can be credited for one), so the gap between the bound and 1 is at
//! least what blocks no box locates cost.

use serde::{Deserialize, Serialize};

use crate::detection::{DetectedInstance, DetectionResult};
use crate::error::{DetectError, Result};

/// Options of the 5.5.2 evaluation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct EvalOptions {
    /// τ, the minimum overlap ratio vol(A ∩ B) / max(vol(A), vol(B)) for two boxes to match
    /// (thesis 5.5.2, threshold in eq. 5.4). Dimensionless, in [0, 1]; default 0.125, about half
    /// overlap along each axis, as used for the PR curves of Fig. 5.9 a-b.
    pub tau: f64,
    /// First τ of the stress curve (thesis 5.5.2, Fig. 5.9 c-d). In [0, 1]; default 0.
    pub stress_min: f64,
    /// Last τ of the stress curve. In [`Self::stress_min`], 1]; default 0.5.
    pub stress_max: f64,
    /// Step between the stress curve's τ values; > 0, default 0.025 (21 points from 0 to 0.5).
    pub stress_step: f64,
}

impl Default for EvalOptions {
    fn default() -> Self {
        Self { tau: 0.125, stress_min: 0.0, stress_max: 0.5, stress_step: 0.025 }
    }
}

impl EvalOptions {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<()> {
        let bad = |name, message: String| Err(DetectError::InvalidOption { name, message });
        for (name, v) in [("tau", self.tau), ("stress_min", self.stress_min), ("stress_max", self.stress_max)]
        {
            if !(0.0..=1.0).contains(&v) {
                return bad(name, format!("{v} is not an overlap ratio in [0, 1]"));
            }
        }
        if self.stress_min > self.stress_max {
            return bad(
                "stress_min",
                format!("{} is greater than stress_max {}", self.stress_min, self.stress_max),
            );
        }
        if !(self.stress_step.is_finite() && self.stress_step > 0.0) {
            return bad("stress_step", format!("{} is not a positive step", self.stress_step));
        }
        if (self.stress_max - self.stress_min) / self.stress_step > 10_000.0 {
            return bad("stress_step", format!("{} gives more than 10 000 stress points", self.stress_step));
        }
        Ok(())
    }

    /// The τ values of the stress curve: `stress_min + k · stress_step` up to `stress_max`
    /// (a rounding slack of 1e-9 steps keeps the end point, e.g. 0.5 with step 0.025). Values are
    /// rounded to 12 decimals so that 0.425 is written as `0.425`, not `0.42500000000000004`, and
    /// reads back to the same number.
    pub fn stress_taus(&self) -> Vec<f64> {
        let n = ((self.stress_max - self.stress_min) / self.stress_step + 1e-9).floor().max(0.0) as usize;
        (0..=n)
            .map(|k| {
                let tau = (self.stress_min + k as f64 * self.stress_step).min(self.stress_max);
                (tau * 1e12).round() / 1e12
            })
            .collect()
    }
}

/// One scene's figures (thesis 5.5.2).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvalReport {
    /// The detection's scene name.
    pub scene: String,
    /// The τ the precision, recall, F and PR curve were computed with.
    pub tau: f64,
    /// Precision at τ (eq. 5.5), in [0, 1].
    pub precision: f64,
    /// Recall at τ (eq. 5.5 with 𝐃 and 𝐆 swapped), in [0, 1].
    pub recall: f64,
    /// F-measure 2PR / (P + R) at τ.
    pub f: f64,
    /// PR curve at τ: `(detected classes kept, precision, recall)`, starting with all |𝐃|
    /// classes and removing the largest remaining class (most instances; ties: lower index first)
    /// one at a time down to 0 classes; |𝐃| + 1 points.
    pub pr_curve: Vec<(usize, f64, f64)>,
    /// Stress curve: `(τ, F)` for each τ of [`EvalOptions::stress_taus`], with all classes.
    pub stress: Vec<(f64, f64)>,
    /// |𝐃|, the number of detected classes.
    pub detected_classes: usize,
    /// Σⱼ |𝐃ʲ|, the number of detected instances.
    pub detected_instances: usize,
    /// |𝐆|, the number of annotated classes.
    pub ground_truth_classes: usize,
    /// Σᵢ |𝐆ⁱ|, the number of annotated instances.
    pub ground_truth_instances: usize,
    /// Per annotated class at τ: how many of its instances some detected box locates and how
    /// many the recall credits (see [`AnnotatedClassReport`]), in the ground truth's order.
    #[serde(default)]
    pub annotated: Vec<AnnotatedClassReport>,
    /// Per detected class at τ: how many of its instances the precision credits and against
    /// which annotated class (see [`DetectedClassReport`]), in the detection's order.
    #[serde(default)]
    pub detected: Vec<DetectedClassReport>,
    /// Share of the annotated instances that some detected box matches at τ (Σ
    /// [`AnnotatedClassReport::found`] over Σᵢ |𝐆ⁱ|; 1 when nothing is annotated): no grouping
    /// or pruning of the detected boxes scores a higher recall (module documentation). An upper
    /// bound, not always reached: one box over two blocks locates both but is credited once.
    pub located_recall: f64,
    /// 2R / (1 + R) for R = [`Self::located_recall`]: no grouping or pruning of the detected
    /// boxes scores a higher F.
    pub located_f: f64,
}

/// One annotated class's part in the recall (not in the thesis; a diagnosis of where recall is
/// lost). `instances − found` instances were missed by every detected box; `found − recalled`
/// were located but counted against a detected class other than the one credited for this
/// annotated class (a block split over several classes, or mixed into classes of other blocks).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct AnnotatedClassReport {
    /// The class's name, or `class_i` (its index) when it has none.
    pub name: String,
    /// |𝐆ⁱ|.
    pub instances: usize,
    /// Instances whose box matches some detected box of any class at τ.
    pub found: usize,
    /// maxⱼ score(𝐃ʲ, 𝐆ⁱ) (eq. 5.4), this class's term of the recall's numerator.
    pub recalled: usize,
    /// The detected class j attaining that maximum (on ties, the one whose matching boxes overlap
    /// most, then the first); `None` when it is 0.
    pub best_detected: Option<usize>,
}

/// One detected class's part in the precision (not in the thesis; a diagnosis of where
/// precision is lost). `instances − credited` instances are spurious or belong to annotated
/// classes other than the one the class is credited for (a class mixing blocks).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct DetectedClassReport {
    /// The class's name, or `class_j` (its index) when it has none.
    pub name: String,
    /// |𝐃ʲ|.
    pub instances: usize,
    /// maxᵢ score(𝐃ʲ, 𝐆ⁱ) (eq. 5.4), this class's term of the precision's numerator.
    pub credited: usize,
    /// The annotated class i attaining that maximum (on ties, the one whose matching boxes overlap
    /// most, then the first); `None` when it is 0.
    pub best_annotated: Option<usize>,
}

/// An annotated class's figures summed over the scenes that annotate a class of that name (see
/// [`AnnotatedClassReport`]).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct AnnotatedClassTotals {
    /// The class name (`class_i` for unnamed classes, so unnamed classes of different scenes
    /// with the same index are summed together).
    pub name: String,
    /// Scenes that annotate the class.
    pub scenes: usize,
    /// Σ |𝐆ⁱ|.
    pub instances: usize,
    /// Σ found.
    pub found: usize,
    /// Σ recalled.
    pub recalled: usize,
}

impl AnnotatedClassTotals {
    /// Instances no detected box locates: `instances − found`.
    pub fn missed(&self) -> usize {
        self.instances - self.found
    }

    /// Instances located, but not by the detected class the recall credits: `found − recalled`
    /// (never negative: a credited instance is a located one).
    pub fn elsewhere(&self) -> usize {
        self.found.saturating_sub(self.recalled)
    }
}

impl From<&AnnotatedClassReport> for AnnotatedClassTotals {
    /// One scene's row as totals over that scene.
    fn from(c: &AnnotatedClassReport) -> Self {
        AnnotatedClassTotals {
            name: c.name.clone(),
            scenes: 1,
            instances: c.instances,
            found: c.found,
            recalled: c.recalled,
        }
    }
}

/// The figures of a set of scenes: per-scene reports and their means ("the final PR curve is the
/// average of all scenes", thesis 5.5.2).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvalSummary {
    /// The options every scene was evaluated with.
    pub options: EvalOptions,
    /// One report per scene, in input order.
    pub scenes: Vec<EvalReport>,
    /// Mean of the per-scene precisions.
    pub precision: f64,
    /// Mean of the per-scene recalls.
    pub recall: f64,
    /// Mean of the per-scene F-measures (not the F of the mean P and R).
    pub f: f64,
    /// Mean PR curve: `(classes removed, mean precision, mean recall)` for 0 .. max |𝐃| removed.
    /// Indexed by the number of removed classes because scenes have different class counts;
    /// each point is the mean over the scenes that still have a class left (a scene's point with
    /// none left has no precision; counting it as 0 once dragged the mean precision at low
    /// recall to 0.43–0.50 where every scene's was 1).
    pub mean_pr_curve: Vec<(usize, f64, f64)>,
    /// Mean stress curve: `(τ, mean F)`.
    pub mean_stress: Vec<(f64, f64)>,
    /// Per annotated class name, summed over the scenes, in order of first appearance.
    #[serde(default)]
    pub annotated: Vec<AnnotatedClassTotals>,
    /// Mean of the per-scene [`EvalReport::located_recall`] (a scene with nothing annotated
    /// counts as 1).
    pub located_recall: f64,
    /// Mean of the per-scene [`EvalReport::located_f`]: like F, a mean of the scenes' values,
    /// not 2R / (1 + R) of the mean R.
    pub located_f: f64,
}

/// The overlap ratio vol(A ∩ B) / max(vol(A), vol(B)) of two boxes given by their corners, or
/// `None` when the intersection has zero volume (disjoint, touching, or a flat box).
pub fn overlap_ratio(a_min: &[f64; 3], a_max: &[f64; 3], b_min: &[f64; 3], b_max: &[f64; 3]) -> Option<f64> {
    let mut inter = 1.0;
    let mut va = 1.0;
    let mut vb = 1.0;
    for k in 0..3 {
        inter *= (a_max[k].min(b_max[k]) - a_min[k].max(b_min[k])).max(0.0);
        va *= (a_max[k] - a_min[k]).max(0.0);
        vb *= (b_max[k] - b_min[k]).max(0.0);
    }
    // `inter > 0` implies both volumes are positive, so the division is safe.
    if inter > 0.0 { Some(inter / f64::max(va, vb)) } else { None }
}

/// Whether two instances' boxes match at threshold `tau` (see the module doc).
pub fn boxes_match(a: &DetectedInstance, b: &DetectedInstance, tau: f64) -> bool {
    overlap_ratio(&a.bbox_min, &a.bbox_max, &b.bbox_min, &b.bbox_max).is_some_and(|r| r >= tau)
}

/// Best overlap ratio of each box of one class against any box of another (`None`: no box with
/// positive overlap). "Matches some box at τ" is then `best >= τ`, for every τ at once.
fn best_ratios(from: &[DetectedInstance], to: &[DetectedInstance]) -> Vec<Option<f64>> {
    from.iter()
        .map(|a| {
            to.iter()
                .filter_map(|b| overlap_ratio(&a.bbox_min, &a.bbox_max, &b.bbox_min, &b.bbox_max))
                .reduce(f64::max)
        })
        .collect()
}

/// The pairwise box overlaps of a detection and a ground truth, computed once and thresholded
/// for each τ of the stress curve (precompute / solve split).
struct Pairwise {
    /// |𝐃ʲ| per detected class.
    d_sizes: Vec<usize>,
    /// |𝐆ⁱ| per annotated class.
    g_sizes: Vec<usize>,
    /// `d_best[j][i]`: best ratios of 𝐃ʲ's boxes against 𝐆ⁱ.
    d_best: Vec<Vec<Vec<Option<f64>>>>,
    /// `g_best[j][i]`: best ratios of 𝐆ⁱ's boxes against 𝐃ʲ.
    g_best: Vec<Vec<Vec<Option<f64>>>>,
}

fn count_matching(best: &[Option<f64>], tau: f64) -> usize {
    best.iter().filter(|r| r.is_some_and(|r| r >= tau)).count()
}

fn f_measure(p: f64, r: f64) -> f64 {
    if p + r > 0.0 { 2.0 * p * r / (p + r) } else { 0.0 }
}

impl Pairwise {
    fn new(detection: &DetectionResult, ground_truth: &DetectionResult) -> Self {
        let d_best = detection
            .classes
            .iter()
            .map(|d| ground_truth.classes.iter().map(|g| best_ratios(&d.instances, &g.instances)).collect())
            .collect();
        let g_best = detection
            .classes
            .iter()
            .map(|d| ground_truth.classes.iter().map(|g| best_ratios(&g.instances, &d.instances)).collect())
            .collect();
        Self {
            d_sizes: detection.classes.iter().map(|c| c.instances.len()).collect(),
            g_sizes: ground_truth.classes.iter().map(|c| c.instances.len()).collect(),
            d_best,
            g_best,
        }
    }

    /// score(𝐃ʲ, 𝐆ⁱ) at τ, eq. 5.4.
    fn score(&self, j: usize, i: usize, tau: f64) -> usize {
        count_matching(&self.d_best[j][i], tau).min(count_matching(&self.g_best[j][i], tau))
    }

    /// Sum of the overlap ratios at or above τ between 𝐃ʲ and 𝐆ⁱ, both ways: how well the two
    /// classes' matching boxes fit, to tell apart two classes of equal score.
    fn fit(&self, j: usize, i: usize, tau: f64) -> f64 {
        let sum = |best: &[Option<f64>]| best.iter().flatten().filter(|&&r| r >= tau).sum::<f64>();
        sum(&self.d_best[j][i]) + sum(&self.g_best[j][i])
    }

    /// The argmax of `score`, or `None` when the best score is 0 (or there is no index); among
    /// equal scores the one of the largest `fit`, then the first. Only which class a report
    /// names depends on the tie-break, never P or R (they count the score). Without it a class
    /// of six balconies was reported as credited against the tall windows behind them: each
    /// balcony's box overlaps a window's, both classes scored 6, and the windows came first.
    fn best(n: usize, score: impl Fn(usize) -> usize, fit: impl Fn(usize) -> f64) -> (usize, Option<usize>) {
        let mut best: (usize, Option<usize>, f64) = (0, None, 0.0);
        for k in 0..n {
            let s = score(k);
            if s > best.0 || (s > 0 && s == best.0 && fit(k) > best.2) {
                best = (s, Some(k), fit(k));
            }
        }
        (best.0, best.1)
    }

    /// (precision, recall) at τ with only the detected classes `kept` (eq. 5.5).
    fn precision_recall(&self, kept: &[bool], tau: f64) -> (f64, f64) {
        let n_d: usize = self.d_sizes.iter().zip(kept).filter(|(_, k)| **k).map(|(n, _)| n).sum();
        let n_g: usize = self.g_sizes.iter().sum();
        if n_d == 0 && n_g == 0 {
            return (1.0, 1.0);
        }
        let kept_j = || (0..self.d_sizes.len()).filter(|&j| kept[j]);
        let matched_d: usize =
            kept_j().map(|j| (0..self.g_sizes.len()).map(|i| self.score(j, i, tau)).max().unwrap_or(0)).sum();
        let matched_g: usize =
            (0..self.g_sizes.len()).map(|i| kept_j().map(|j| self.score(j, i, tau)).max().unwrap_or(0)).sum();
        let p = if n_d > 0 { matched_d as f64 / n_d as f64 } else { 0.0 };
        let r = if n_g > 0 { matched_g as f64 / n_g as f64 } else { 0.0 };
        (p, r)
    }
}

/// Evaluates one scene's `detection` against its `ground_truth` (thesis 5.5.2). Both are
/// validated first; errors name the scene and the bad field.
pub fn evaluate(
    detection: &DetectionResult,
    ground_truth: &DetectionResult,
    options: &EvalOptions,
) -> Result<EvalReport> {
    options.validate()?;
    detection.validate(&format!("detection of scene `{}`", detection.scene))?;
    ground_truth.validate(&format!("ground truth of scene `{}`", ground_truth.scene))?;
    let pw = Pairwise::new(detection, ground_truth);
    let n_classes = detection.classes.len();
    let mut kept = vec![true; n_classes];

    let (precision, recall) = pw.precision_recall(&kept, options.tau);

    // Largest class first; the sort is stable, so ties keep the lower index first.
    let mut order: Vec<usize> = (0..n_classes).collect();
    order.sort_by_key(|&j| std::cmp::Reverse(pw.d_sizes[j]));
    let mut pr_curve = vec![(n_classes, precision, recall)];
    for (removed, &j) in order.iter().enumerate() {
        kept[j] = false;
        let (p, r) = pw.precision_recall(&kept, options.tau);
        pr_curve.push((n_classes - removed - 1, p, r));
    }

    let tau = options.tau;
    let annotated: Vec<AnnotatedClassReport> = ground_truth
        .classes
        .iter()
        .enumerate()
        .map(|(i, g)| {
            let (recalled, best_detected) =
                Pairwise::best(n_classes, |j| pw.score(j, i, tau), |j| pw.fit(j, i, tau));
            let found = (0..g.instances.len())
                .filter(|&k| (0..n_classes).any(|j| pw.g_best[j][i][k].is_some_and(|r| r >= tau)))
                .count();
            AnnotatedClassReport {
                name: g.name.clone().unwrap_or_else(|| format!("class_{i}")),
                instances: g.instances.len(),
                found,
                recalled,
                best_detected,
            }
        })
        .collect();
    let detected = detection
        .classes
        .iter()
        .enumerate()
        .map(|(j, d)| {
            let (credited, best_annotated) =
                Pairwise::best(pw.g_sizes.len(), |i| pw.score(j, i, tau), |i| pw.fit(j, i, tau));
            DetectedClassReport {
                name: d.name.clone().unwrap_or_else(|| format!("class_{j}")),
                instances: d.instances.len(),
                credited,
                best_annotated,
            }
        })
        .collect();

    let ground_truth_instances = ground_truth.instance_count();
    let located: usize = annotated.iter().map(|c| c.found).sum();
    let located_recall =
        if ground_truth_instances > 0 { located as f64 / ground_truth_instances as f64 } else { 1.0 };

    let all = vec![true; n_classes];
    let stress = options
        .stress_taus()
        .into_iter()
        .map(|tau| {
            let (p, r) = pw.precision_recall(&all, tau);
            (tau, f_measure(p, r))
        })
        .collect();

    Ok(EvalReport {
        scene: detection.scene.clone(),
        tau: options.tau,
        precision,
        recall,
        f: f_measure(precision, recall),
        pr_curve,
        stress,
        detected_classes: n_classes,
        detected_instances: detection.instance_count(),
        ground_truth_classes: ground_truth.classes.len(),
        ground_truth_instances,
        annotated,
        detected,
        located_recall,
        located_f: f_measure(1.0, located_recall),
    })
}

/// Evaluates each `(detection, ground truth)` pair and averages the per-scene figures and curves
/// (see [`EvalSummary`]). Fails on an empty set of scenes or on the first invalid scene.
pub fn evaluate_many<'a>(
    pairs: impl IntoIterator<Item = (&'a DetectionResult, &'a DetectionResult)>,
    options: &EvalOptions,
) -> Result<EvalSummary> {
    let scenes = pairs.into_iter().map(|(d, g)| evaluate(d, g, options)).collect::<Result<Vec<_>>>()?;
    if scenes.is_empty() {
        return Err(DetectError::NoScenes);
    }
    let n = scenes.len() as f64;
    let mean = |f: &dyn Fn(&EvalReport) -> f64| scenes.iter().map(f).sum::<f64>() / n;

    let max_classes = scenes.iter().map(|s| s.detected_classes).max().unwrap_or(0);
    let mean_pr_curve = (0..max_classes)
        .map(|removed| {
            let left: Vec<(usize, f64, f64)> =
                scenes.iter().filter(|s| removed < s.detected_classes).map(|s| s.pr_curve[removed]).collect();
            let k = left.len() as f64;
            (removed, left.iter().map(|p| p.1).sum::<f64>() / k, left.iter().map(|p| p.2).sum::<f64>() / k)
        })
        .collect();
    let taus = options.stress_taus();
    let mean_stress = taus.iter().enumerate().map(|(k, &tau)| (tau, mean(&|s| s.stress[k].1))).collect();

    let mut annotated: Vec<AnnotatedClassTotals> = Vec::new();
    // The last scene that added to each row: two classes of one name in one scene (a ground
    // truth may repeat a name) count that scene once.
    let mut last_scene: Vec<usize> = Vec::new();
    for (k, c) in scenes.iter().enumerate().flat_map(|(k, s)| s.annotated.iter().map(move |c| (k, c))) {
        match annotated.iter_mut().position(|t| t.name == c.name) {
            Some(row) => {
                let t = &mut annotated[row];
                if last_scene[row] != k {
                    t.scenes += 1;
                    last_scene[row] = k;
                }
                t.instances += c.instances;
                t.found += c.found;
                t.recalled += c.recalled;
            }
            None => {
                annotated.push(c.into());
                last_scene.push(k);
            }
        }
    }

    Ok(EvalSummary {
        options: options.clone(),
        annotated,
        located_recall: mean(&|s| s.located_recall),
        located_f: mean(&|s| s.located_f),
        precision: mean(&|s| s.precision),
        recall: mean(&|s| s.recall),
        f: mean(&|s| s.f),
        mean_pr_curve,
        mean_stress,
        scenes,
    })
}
