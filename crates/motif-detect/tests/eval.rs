//! Integration tests of the 5.5.2 evaluation. Every expected number is worked out by hand in the
//! comments next to it, from boxes laid out far apart (unit cubes at x = 0, 10, 20, ...) so that
//! only the intended pairs overlap.

use motif_detect::eval::{boxes_match, overlap_ratio};
use motif_detect::{
    DetectError, DetectedClass, DetectedInstance, DetectionResult, EvalOptions, evaluate, evaluate_many,
    plot_pr_and_stress,
};

const EPS: f64 = 1e-12;

fn cube(x: f64) -> DetectedInstance {
    DetectedInstance::from_box([x, 0.0, 0.0], [x + 1.0, 1.0, 1.0])
}

fn class(xs: &[f64]) -> DetectedClass {
    DetectedClass::new(xs.iter().map(|&x| cube(x)).collect())
}

fn scene(classes: Vec<DetectedClass>) -> DetectionResult {
    DetectionResult { scene: "scene_test.ply".into(), classes }
}

fn one_box(min: [f64; 3], max: [f64; 3]) -> DetectionResult {
    scene(vec![DetectedClass::new(vec![DetectedInstance::from_box(min, max)])])
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() < EPS
}

fn assert_prf(d: &DetectionResult, g: &DetectionResult, p: f64, r: f64, f: f64) {
    let rep = evaluate(d, g, &EvalOptions::default()).expect("valid input");
    assert!(close(rep.precision, p), "precision {} != {p}", rep.precision);
    assert!(close(rep.recall, r), "recall {} != {r}", rep.recall);
    assert!(close(rep.f, f), "F {} != {f}", rep.f);
}

#[test]
fn perfect_detection() {
    let gt = scene(vec![class(&[0.0, 10.0, 20.0]), class(&[100.0, 110.0])]);
    // score(D0, G0) = 3, score(D1, G1) = 2, cross scores 0: P = R = 5 / 5.
    assert_prf(&gt.clone(), &gt, 1.0, 1.0, 1.0);
}

#[test]
fn half_the_instances() {
    let gt = scene(vec![class(&[0.0, 10.0, 20.0, 30.0])]);
    let det = scene(vec![class(&[0.0, 10.0])]);
    // score = min(2, 2) = 2; P = 2 / 2, R = 2 / 4, F = 2 · 1 · 0.5 / 1.5 = 2/3.
    assert_prf(&det, &gt, 1.0, 0.5, 2.0 / 3.0);
}

#[test]
fn spurious_class() {
    let gt = scene(vec![class(&[0.0, 10.0])]);
    let det = scene(vec![class(&[0.0, 10.0]), class(&[50.0, 60.0, 70.0])]);
    // P = (2 + 0) / 5 = 0.4, R = 2 / 2 = 1, F = 0.8 / 1.4 = 4/7.
    assert_prf(&det, &gt, 0.4, 1.0, 4.0 / 7.0);
}

#[test]
fn split_classes() {
    let gt = scene(vec![class(&[0.0, 10.0, 20.0, 30.0])]);
    let det = scene(vec![class(&[0.0, 10.0]), class(&[20.0, 30.0])]);
    // Each half scores min(2, 2) = 2: P = (2 + 2) / 4 = 1. The one GT class keeps only its best
    // score, 2: R = 2 / 4 = 0.5. F = 2/3.
    assert_prf(&det, &gt, 1.0, 0.5, 2.0 / 3.0);
    // Merged the other way (two GT classes detected as one) is the mirror image.
    assert_prf(&gt, &det, 0.5, 1.0, 2.0 / 3.0);
}

#[test]
fn per_class_breakdown_names_missed_and_mixed_instances() {
    let mut gt = scene(vec![class(&[0.0, 10.0, 20.0]), class(&[100.0, 110.0, 120.0])]);
    gt.classes[0].name = Some("window".into());
    // Class 0 mixes two windows with one door; class 1 holds the other two doors; the window at
    // x = 20 is missed.
    let det = scene(vec![class(&[0.0, 10.0, 100.0]), class(&[110.0, 120.0])]);
    let rep = evaluate(&det, &gt, &EvalOptions::default()).expect("valid input");
    // Windows: 2 of 3 located, score(D0, window) = min(2, 2) = 2, from class 0.
    let w = &rep.annotated[0];
    assert_eq!(
        (w.name.as_str(), w.instances, w.found, w.recalled, w.best_detected),
        ("window", 3, 2, 2, Some(0))
    );
    // Doors (unnamed, index 1): all 3 located; score(D0, door) = 1, score(D1, door) = 2.
    let d = &rep.annotated[1];
    assert_eq!(
        (d.name.as_str(), d.instances, d.found, d.recalled, d.best_detected),
        ("class_1", 3, 3, 2, Some(1))
    );
    // Class 0 is credited 2 (the windows), class 1 is credited 2 (the doors).
    let c: Vec<_> = rep.detected.iter().map(|c| (c.instances, c.credited, c.best_annotated)).collect();
    assert_eq!(c, vec![(3, 2, Some(0)), (2, 2, Some(1))]);
    // The breakdown adds up to the protocol's figures: P = 4 / 5, R = 4 / 6.
    let credited: usize = rep.detected.iter().map(|c| c.credited).sum();
    let recalled: usize = rep.annotated.iter().map(|c| c.recalled).sum();
    assert!(close(rep.precision, credited as f64 / 5.0) && close(rep.precision, 0.8));
    assert!(close(rep.recall, recalled as f64 / 6.0) && close(rep.recall, 4.0 / 6.0));
    // A detection with nothing in common credits nothing and locates nothing.
    let far = scene(vec![class(&[500.0, 510.0])]);
    let rep = evaluate(&far, &gt, &EvalOptions::default()).expect("valid input");
    assert!(rep.annotated.iter().all(|c| c.found == 0 && c.recalled == 0 && c.best_detected.is_none()));
    assert_eq!(rep.detected[0].best_annotated, None);
    // Over two scenes, classes are summed by name.
    let summary = evaluate_many([(&det, &gt), (&gt.clone(), &gt)], &EvalOptions::default()).expect("valid");
    let t: Vec<_> = summary
        .annotated
        .iter()
        .map(|t| (t.name.as_str(), t.scenes, t.instances, t.found, t.recalled))
        .collect();
    assert_eq!(t, vec![("window", 2, 6, 5, 5), ("class_1", 2, 6, 6, 5)]);
}

/// Balconies in front of windows: each balcony's box also overlaps its window's (ratio 0.25),
/// so a detected class of the balconies scores 2 against both annotated classes. The report
/// names the class its boxes fit best (the balconies, ratio 1), not the first listed.
#[test]
fn ties_are_credited_to_the_class_the_boxes_fit_best() {
    let window = |x: f64| DetectedInstance::from_box([x, 0.0, 0.0], [x + 1.0, 1.0, 1.0]);
    // Half as deep and half as high as the window, in front of it: overlap 0.25 of the window.
    let balcony = |x: f64| DetectedInstance::from_box([x, 0.0, 0.5], [x + 1.0, 0.5, 1.0]);
    let mut gt = scene(vec![
        DetectedClass::new(vec![window(0.0), window(10.0)]),
        DetectedClass::new(vec![balcony(0.0), balcony(10.0)]),
    ]);
    gt.classes[0].name = Some("window".into());
    gt.classes[1].name = Some("balcony".into());
    let det = scene(vec![DetectedClass::new(vec![balcony(0.0), balcony(10.0)])]);
    let rep = evaluate(&det, &gt, &EvalOptions::default()).expect("valid input");
    let (b, w) = (balcony(0.0), window(0.0));
    assert!(close(overlap_ratio(&b.bbox_min, &b.bbox_max, &w.bbox_min, &w.bbox_max).unwrap(), 0.25));
    assert_eq!((rep.detected[0].credited, rep.detected[0].best_annotated), (2, Some(1)));
    // The figures do not depend on the tie-break: P = 2 / 2, and R = 4 / 4, as each annotated
    // class's best detected class is the one class, which scores 2 against both (eq. 5.5).
    assert!(close(rep.precision, 1.0) && close(rep.recall, 1.0), "P {} R {}", rep.precision, rep.recall);
    assert_eq!(rep.annotated[1].best_detected, Some(0));
}

#[test]
fn located_share_bounds_every_regrouping() {
    let gt = scene(vec![class(&[0.0, 10.0, 20.0]), class(&[100.0, 110.0, 120.0])]);
    // Class 0 mixes two windows, a door and a box far from everything; class 1 holds two doors
    // and a second box on the window at x = 0 (overlap ratio 0.9). The window at 20 is missed.
    let det = scene(vec![class(&[0.0, 10.0, 100.0, 500.0]), class(&[110.0, 120.0, 0.1])]);
    let rep = evaluate(&det, &gt, &EvalOptions::default()).expect("valid input");
    // As detected: P = (2 + 2) / 7, R = (2 + 2) / 6.
    assert!(close(rep.precision, 4.0 / 7.0) && close(rep.recall, 4.0 / 6.0));
    // Located: 5 of 6, so R ≤ 5/6 and F ≤ 2 · (5/6) / (1 + 5/6) = 10/11.
    assert!(close(rep.located_recall, 5.0 / 6.0), "{}", rep.located_recall);
    assert!(close(rep.located_f, 10.0 / 11.0), "{}", rep.located_f);
    // The best regrouping of these boxes reaches the bound: windows {0, 10}, doors {100, 110,
    // 120}, the box at 500 and the repeat at 0.1 dropped.
    let best = scene(vec![class(&[0.0, 10.0]), class(&[100.0, 110.0, 120.0])]);
    let b = evaluate(&best, &gt, &EvalOptions::default()).expect("valid input");
    assert!(close(b.recall, rep.located_recall) && close(b.f, rep.located_f));
    // The mean over scenes is the mean of the scenes'.
    let summary = evaluate_many([(&det, &gt), (&gt.clone(), &gt)], &EvalOptions::default()).expect("valid");
    assert!(close(summary.scenes[1].located_f, 1.0));
    assert!(close(summary.located_recall, (5.0 / 6.0 + 1.0) / 2.0));
    assert!(close(summary.located_f, (10.0 / 11.0 + 1.0) / 2.0));
    // Nothing located: no regrouping recalls anything.
    let far = scene(vec![class(&[500.0, 510.0])]);
    let r = evaluate(&far, &gt, &EvalOptions::default()).expect("valid input");
    assert_eq!((r.located_recall, r.located_f), (0.0, 0.0));
}

#[test]
fn multiple_intersections_do_not_over_count() {
    // One big detected box covering two GT cubes: |D ∩ G| = 1 (the big box) but |G ∩ D| = 2; the
    // min keeps 1. The big box [0, 2] × [0, 1] × [0, 1] has volume 2, each cube overlaps with 1:
    // ratio 0.5 ≥ 0.125.
    let gt = scene(vec![class(&[0.0, 1.0])]);
    let det = one_box([0.0, 0.0, 0.0], [2.0, 1.0, 1.0]);
    // P = 1 / 1, R = 1 / 2, F = 2/3.
    assert_prf(&det, &gt, 1.0, 0.5, 2.0 / 3.0);
}

#[test]
fn tau_edge_cases() {
    let unit = one_box([0.0; 3], [1.0; 3]);
    // Shifted by half along every axis: intersection 0.5³ = 0.125 (exact in binary), both
    // volumes 1: ratio exactly 0.125 = τ, which matches (≥).
    let half = one_box([0.5; 3], [1.5; 3]);
    assert_eq!(overlap_ratio(&[0.0; 3], &[1.0; 3], &[0.5; 3], &[1.5; 3]), Some(0.125));
    assert_prf(&half, &unit, 1.0, 1.0, 1.0);
    // Shifted a little more along z: intersection 0.25 · (0.5 − 2⁻¹⁰) < 0.125: no match.
    let dz = 1.0 / 1024.0;
    let less = one_box([0.5, 0.5, 0.5 + dz], [1.5, 1.5, 1.5 + dz]);
    assert_prf(&less, &unit, 0.0, 0.0, 0.0);
    // The larger volume is the denominator: [0, 2]³ contains the unit cube, ratio 1 / 8 = 0.125.
    let big = one_box([0.0; 3], [2.0; 3]);
    assert_prf(&big, &unit, 1.0, 1.0, 1.0);
    // [0, 2] × [0, 2] × [0, 2.5] has volume 10: ratio 0.1 < 0.125.
    let bigger = one_box([0.0; 3], [2.0, 2.0, 2.5]);
    assert_prf(&bigger, &unit, 0.0, 0.0, 0.0);
    let rep = evaluate(&bigger, &unit, &EvalOptions { tau: 0.1, ..Default::default() }).expect("valid");
    assert!(close(rep.f, 1.0));
}

#[test]
fn touching_and_flat_boxes_never_match() {
    let a = DetectedInstance::from_box([0.0; 3], [1.0; 3]);
    let touching = DetectedInstance::from_box([1.0, 0.0, 0.0], [2.0, 1.0, 1.0]);
    assert_eq!(overlap_ratio(&a.bbox_min, &a.bbox_max, &touching.bbox_min, &touching.bbox_max), None);
    assert!(!boxes_match(&a, &touching, 0.0));
    // A flat box has zero volume, so even an identical flat box does not match it, at any τ.
    let flat = DetectedInstance::from_box([0.0; 3], [1.0, 1.0, 0.0]);
    assert!(!boxes_match(&flat, &flat, 0.0));
    assert!(!boxes_match(&flat, &a, 0.0));
    // But flat boxes are valid input.
    let det = scene(vec![DetectedClass::new(vec![flat.clone()])]);
    assert_prf(&det, &det.clone(), 0.0, 0.0, 0.0);
    // Disjoint boxes do not match at τ = 0.
    assert!(!boxes_match(&a, &cube(5.0), 0.0));
    assert!(boxes_match(&a, &a, 1.0));
}

#[test]
fn empty_detection_and_empty_ground_truth() {
    let gt = scene(vec![class(&[0.0])]);
    let empty = scene(vec![]);
    assert_prf(&empty, &gt, 0.0, 0.0, 0.0);
    let rep = evaluate(&empty, &gt, &EvalOptions::default()).expect("valid");
    assert_eq!(rep.pr_curve, vec![(0, 0.0, 0.0)]);
    assert!(rep.stress.iter().all(|&(_, f)| f == 0.0));
    // Spurious detections against an empty ground truth: P = 0 / 1, R = 0 (0 / 0 counts as 0
    // when the other side is non-empty).
    assert_prf(&gt, &empty, 0.0, 0.0, 0.0);
    // Nothing to find and nothing found: perfect.
    assert_prf(&empty, &empty.clone(), 1.0, 1.0, 1.0);
}

#[test]
fn pr_curve_removes_largest_class_first() {
    let gt = scene(vec![class(&[0.0, 10.0, 20.0]), class(&[100.0, 110.0]), class(&[200.0])]);
    let det = scene(vec![
        class(&[200.0]),           // d0: 1 instance, matches G2
        class(&[100.0, 110.0]),    // d1: 2, matches G1
        class(&[0.0, 10.0, 20.0]), // d2: 3, matches G0
        class(&[500.0, 510.0]),    // d3: 2, spurious
    ]);
    let rep = evaluate(&det, &gt, &EvalOptions::default()).expect("valid");
    // Removal order: d2 (3), then the tie d1 / d3 (2 each) by index: d1, d3, then d0 (1).
    // All:        P = (1 + 2 + 3 + 0) / 8 = 0.75, R = (3 + 2 + 1) / 6 = 1.
    // − d2:       P = (1 + 2 + 0) / 5 = 0.6,      R = (0 + 2 + 1) / 6 = 0.5.
    // − d1:       P = (1 + 0) / 3,                R = 1 / 6.
    // − d3:       P = 1 / 1,                      R = 1 / 6.
    // − d0:       P = R = 0 (empty detection).
    let expected =
        [(4, 0.75, 1.0), (3, 0.6, 0.5), (2, 1.0 / 3.0, 1.0 / 6.0), (1, 1.0, 1.0 / 6.0), (0, 0.0, 0.0)];
    assert_eq!(rep.pr_curve.len(), expected.len());
    for (got, want) in rep.pr_curve.iter().zip(expected.iter()) {
        assert_eq!(got.0, want.0);
        assert!(close(got.1, want.1) && close(got.2, want.2), "{got:?} != {want:?}");
    }
    // Removing detected classes never raises recall.
    for w in rep.pr_curve.windows(2) {
        assert!(w[1].2 <= w[0].2 + EPS);
    }
    assert!(close(rep.precision, 0.75) && close(rep.recall, 1.0));
}

#[test]
fn stress_curve_from_zero_to_half() {
    let options = EvalOptions::default();
    let taus = options.stress_taus();
    assert_eq!(taus.len(), 21);
    assert_eq!(taus[0], 0.0);
    assert!(close(taus[20], 0.5));
    // Overlap ratio 0.125: matches at τ = 0 (F = 1), not at τ = 0.5 (F = 0).
    let unit = one_box([0.0; 3], [1.0; 3]);
    let half = one_box([0.5; 3], [1.5; 3]);
    let rep = evaluate(&half, &unit, &options).expect("valid");
    assert_eq!(rep.stress.len(), 21);
    assert_eq!(rep.stress[0], (0.0, 1.0));
    assert!(close(rep.stress[20].0, 0.5) && rep.stress[20].1 == 0.0);
    // F never increases with τ.
    for w in rep.stress.windows(2) {
        assert!(w[0].0 < w[1].0 && w[1].1 <= w[0].1);
    }
    // At τ = 0.25 (index 10) the 0.125 overlap fails.
    assert_eq!(rep.stress[10].1, 0.0);
}

#[test]
fn mean_over_two_scenes() {
    let gt1 = scene(vec![class(&[0.0, 10.0, 20.0]), class(&[100.0, 110.0])]);
    let det1 = gt1.clone();
    let gt2 = scene(vec![class(&[0.0, 10.0, 20.0, 30.0])]);
    let det2 = scene(vec![class(&[0.0, 10.0])]);
    let options = EvalOptions::default();
    let summary = evaluate_many([(&det1, &gt1), (&det2, &gt2)], &options).expect("valid");
    // Scene 1: P = R = F = 1. Scene 2: P = 1, R = 0.5, F = 2/3.
    assert_eq!(summary.scenes.len(), 2);
    assert!(close(summary.precision, 1.0));
    assert!(close(summary.recall, 0.75));
    assert!(close(summary.f, (1.0 + 2.0 / 3.0) / 2.0));
    // PR curves. Scene 1: (2, 1, 1), remove the 3-class: (1, 2/2, 2/5), then (0, 0, 0).
    // Scene 2: (1, 1, 0.5), (0, 0, 0). The mean at k removed is over the scenes with a class
    // left: both at 0 removed, scene 1 alone at 1; no point once no scene has one.
    let expected = [(0, 1.0, 0.75), (1, 1.0, 0.4)];
    assert_eq!(summary.mean_pr_curve.len(), 2);
    for (got, want) in summary.mean_pr_curve.iter().zip(expected.iter()) {
        assert_eq!(got.0, want.0);
        assert!(close(got.1, want.1) && close(got.2, want.2), "{got:?} != {want:?}");
    }
    // Identical boxes overlap with ratio 1, so both scenes' F is constant over τ: mean 5/6.
    assert_eq!(summary.mean_stress.len(), 21);
    assert!(summary.mean_stress.iter().all(|&(_, f)| close(f, 5.0 / 6.0)));
    assert!(matches!(evaluate_many([], &options), Err(DetectError::NoScenes)));
}

#[test]
fn json_round_trip() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("det.json");
    let mut det = scene(vec![class(&[0.0, 10.0]), class(&[20.0])]);
    det.classes[0].name = Some("window".into());
    det.classes[0].instances[1].transform =
        Some([[1.0, 0.0, 0.0, 10.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]);
    det.classes[0].instances[1].points = Some(vec![3, 4, 5]);
    det.write(&path).expect("write");
    let back = DetectionResult::read(&path).expect("read");
    assert_eq!(back, det);
    // Optional fields are omitted when absent, and may be absent on reading.
    let text = std::fs::read_to_string(&path).expect("read text");
    assert_eq!(text.matches("\"transform\"").count(), 1);
    assert_eq!(text.matches("\"name\"").count(), 1);
    let minimal =
        r#"{"scene": "s.ply", "classes": [{"instances": [{"bbox_min": [0, 0, 0], "bbox_max": [1, 1, 1]}]}]}"#;
    let parsed =
        DetectionResult::from_json_str(minimal, std::path::Path::new("minimal.json")).expect("parse");
    assert_eq!(parsed, one_box([0.0; 3], [1.0; 3]).with_scene("s.ply"));
    // Values of the wrong shape or type are named by their field, in words rather than Rust's.
    let at = std::path::Path::new("bad.json");
    let err = |text: &str| DetectionResult::from_json_str(text, at).expect_err("refused").to_string();
    let e = err(&minimal.replace("\"bbox_min\": [0, 0, 0]", "\"bbox_min\": [0, 0]"));
    assert!(e.contains("bad.json: field `classes[0].instances[0].bbox_min`: invalid length 2"), "{e}");
    let e = err(&minimal.replace("\"bbox_min\"", "\"points\": [1, -2], \"bbox_min\""));
    assert!(e.contains("field `classes[0].instances[0].points[1]`") && e.contains("a whole number"), "{e}");
    assert!(!e.contains("u32"), "{e}");
    // A cut file is a syntax error of the file, not of the field it stops in.
    let e = err(&minimal[..minimal.len() / 2]);
    assert!(e.contains("bad.json: not a detection/ground-truth JSON file") && !e.contains("field `"), "{e}");
    let e = err("[1, 2]");
    assert!(e.contains("bad.json: not a detection/ground-truth JSON file: it holds no object"), "{e}");
    let e = err(r#"{"classes": 2, "input": "s.ply", "options": {}, "report": {}, "seconds": 1}"#);
    assert!(e.contains("field `classes`") && e.contains("report of `motif detect --json`"), "{e}");
    // Report and summary serialise too.
    let rep = evaluate(&det, &det, &EvalOptions::default()).expect("valid");
    let json = serde_json::to_string(&rep).expect("serialise");
    assert_eq!(serde_json::from_str::<motif_detect::EvalReport>(&json).expect("parse"), rep);
    let opts: EvalOptions = serde_json::from_str(r#"{"tau": 0.25}"#).expect("options");
    assert_eq!(opts, EvalOptions { tau: 0.25, ..Default::default() });
}

trait WithScene {
    fn with_scene(self, name: &str) -> Self;
}
impl WithScene for DetectionResult {
    fn with_scene(mut self, name: &str) -> Self {
        self.scene = name.into();
        self
    }
}

fn read_err(dir: &tempfile::TempDir, name: &str, text: &str) -> String {
    let path = dir.path().join(name);
    std::fs::write(&path, text).expect("write");
    let err = DetectionResult::read(&path).expect_err("malformed file must fail");
    let msg = err.to_string();
    assert!(msg.contains(name), "error does not name the file: {msg}");
    msg
}

#[test]
fn malformed_files_name_the_file_and_field() {
    let dir = tempfile::tempdir().expect("temp dir");
    let msg = read_err(
        &dir,
        "min_gt_max.json",
        r#"{"scene": "s", "classes": [{"instances": [
            {"bbox_min": [0, 0, 0], "bbox_max": [1, 1, 1]},
            {"bbox_min": [0, 0, 2], "bbox_max": [1, 1, 1]}]}]}"#,
    );
    assert!(msg.contains("classes[0].instances[1].bbox_min[2]"), "{msg}");
    let msg = read_err(&dir, "empty_class.json", r#"{"scene": "s", "classes": [{"instances": []}]}"#);
    assert!(msg.contains("classes[0].instances") && msg.contains("no instances"), "{msg}");
    let msg = read_err(
        &dir,
        "missing.json",
        r#"{"scene": "s", "classes": [{"instances": [{"bbox_min": [0, 0, 0]}]}]}"#,
    );
    assert!(msg.contains("bbox_max"), "{msg}");
    let msg = read_err(&dir, "not_json.json", "bbox, min, max\n");
    assert!(msg.contains("not a detection"), "{msg}");
    let msg = read_err(
        &dir,
        "short.json",
        r#"{"scene": "s", "classes": [{"instances": [{"bbox_min": [0, 0], "bbox_max": [1, 1, 1]}]}]}"#,
    );
    assert!(msg.contains("line"), "{msg}");
    let absent = dir.path().join("absent.json");
    let err = DetectionResult::read(&absent).expect_err("missing file");
    assert!(matches!(err, DetectError::Io { .. }) && err.to_string().contains("absent.json"));

    // NaN built in code is caught before scoring, naming the field.
    let nan = one_box([0.0, f64::NAN, 0.0], [1.0; 3]);
    let err = evaluate(&nan, &nan, &EvalOptions::default()).expect_err("NaN");
    assert!(err.to_string().contains("classes[0].instances[0].bbox_min[1]"), "{err}");
    // Bad options.
    let err = evaluate(&nan, &nan, &EvalOptions { tau: 1.5, ..Default::default() }).expect_err("tau");
    assert!(matches!(err, DetectError::InvalidOption { name: "tau", .. }));
    let bad_step = EvalOptions { stress_step: 0.0, ..Default::default() };
    assert!(matches!(bad_step.validate(), Err(DetectError::InvalidOption { name: "stress_step", .. })));
}

#[test]
fn plots_are_png() {
    let dir = tempfile::tempdir().expect("temp dir");
    let gt = scene(vec![class(&[0.0, 10.0, 20.0]), class(&[100.0, 110.0])]);
    let det = scene(vec![class(&[0.0, 10.0]), class(&[100.0, 500.0])]);
    let options = EvalOptions::default();
    let rep = evaluate(&det, &gt, &options).expect("valid");
    let summary = evaluate_many([(&det, &gt), (&gt, &gt)], &options).expect("valid");
    for (name, result) in [
        ("report.png", plot_pr_and_stress(&rep, &dir.path().join("report.png"))),
        ("summary.png", plot_pr_and_stress(&summary, &dir.path().join("summary.png"))),
    ] {
        result.expect("plot");
        let bytes = std::fs::read(dir.path().join(name)).expect("png written");
        assert!(bytes.starts_with(b"\x89PNG\r\n\x1a\n") && bytes.len() > 1000);
        // Four panels in a 2 × 2 grid: PR curve, stress curve, annotated classes, detected
        // classes or scenes (IHDR width and height, big-endian).
        assert_eq!(u32::from_be_bytes([bytes[16], bytes[17], bytes[18], bytes[19]]), 1800);
        assert_eq!(u32::from_be_bytes([bytes[20], bytes[21], bytes[22], bytes[23]]), 1200);
    }
    let err = plot_pr_and_stress(&rep, &dir.path().join("no_dir/x.png")).expect_err("bad dir");
    assert!(matches!(err, DetectError::Plot { .. }));
}

/// Two annotated classes of one name in one scene are one scene of that name in the per-class
/// totals (they were counted as two scenes).
#[test]
fn a_name_repeated_in_one_scene_counts_that_scene_once() {
    let mut a = class(&[0.0, 10.0]);
    a.name = Some("A".into());
    let mut b = class(&[100.0, 110.0]);
    b.name = Some("A".into());
    let gt = scene(vec![a, b]);
    let det = scene(vec![class(&[0.0, 10.0])]);
    let summary = evaluate_many([(&det, &gt)], &EvalOptions::default()).expect("valid");
    let rows: Vec<(&str, usize, usize)> =
        summary.annotated.iter().map(|t| (t.name.as_str(), t.scenes, t.instances)).collect();
    assert_eq!(rows, [("A", 1, 4)]);
    let two = evaluate_many([(&det, &gt), (&det, &gt)], &EvalOptions::default()).expect("valid");
    assert_eq!((two.annotated[0].scenes, two.annotated[0].instances), (2, 8));
}
