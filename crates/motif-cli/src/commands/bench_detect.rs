//! `motif bench detect`: the thesis's evaluation (5.5) on generated scenes with ground truth —
//! easy / medium / hard × EM + SC, SC (no EM) and the supervised rigid-ICP baseline — as a table
//! of mean precision, recall and F at τ = 0.125 and median seconds, plus per-stage times of the
//! detector.
//!
//! Each mean F comes with its standard error over the scenes (sample standard deviation / √n), and
//! EM + SC's lead over SC with the standard error of the per-scene differences: the two methods
//! run on the same scenes, so the paired difference is what says whether EM's lead is real. The
//! generated scenes differ a lot from seed to seed (street medium F 0.788 on seeds 1–6, 0.826 on
//! 7–12), and a target missed by 0.01 means little when the error is 0.03.

use std::time::Instant;

use motif_detect::pipeline::Method;
use motif_detect::preprocess::Epsilon;
use motif_detect::rigid_icp::{RigidIcpOptions, rigid_icp};
use motif_detect::scenes::{Difficulty, SceneKind, SceneOptions, generate_scene_with_parts, load_scene_part};
use motif_detect::{
    AnnotatedClassTotals, BenchRow, DetectOptions, DetectionResult, EvalOptions, evaluate_many, plot_bench,
    plot_pr_and_stress_titled,
};
use serde::Serialize;

use crate::cli::{
    AlignedGroupingArg, BenchDetectArgs, DifficultyArg, GlobalArgs, RegroupArg, RepeatedSegmentsArg,
};
use crate::output::{bad_input, check_outputs, maybe_json};
use crate::progress::Bar;

#[derive(Debug, Serialize)]
struct Row {
    difficulty: &'static str,
    method: &'static str,
    scenes: usize,
    precision: f64,
    recall: f64,
    f: f64,
    /// Standard error of the mean F over the scenes (`null` for one scene).
    f_se: Option<f64>,
    /// F per scene, in seed order.
    scene_f: Vec<f64>,
    /// Mean F as the overlap threshold τ goes from 0 to 0.5 (the stress curve, thesis Fig. 5.9
    /// c–d): how well the boxes fit, beyond matching at all.
    stress: Vec<(f64, f64)>,
    median_seconds: f64,
    /// Per annotated class, summed over the scenes: instances, located, credited by the recall.
    annotated: Vec<AnnotatedClassTotals>,
    /// Means of the scenes' share of annotated instances some detected box locates and of 2R /
    /// (1 + R) for it: no grouping or pruning of the detected boxes scores a higher R or F
    /// (upper bounds, `motif_detect::eval`).
    located_recall: f64,
    located_f: f64,
}

/// EM + SC's F minus SC's on the same scenes.
#[derive(Debug, Serialize)]
struct Lead {
    difficulty: &'static str,
    scenes: usize,
    mean: f64,
    /// Standard error of the mean of the per-scene differences (`null` for one scene).
    se: Option<f64>,
}

/// The mean of `v` and its standard error (sample standard deviation / √n; `None` below two
/// values).
fn mean_and_se(v: &[f64]) -> (f64, Option<f64>) {
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    if v.len() < 2 {
        return (mean, None);
    }
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, Some((var / n).sqrt()))
}

/// `±0.012`, or `–` without a standard error.
fn pm(se: Option<f64>) -> String {
    se.map_or_else(|| "–".to_string(), |e| format!("±{e:.3}"))
}

#[derive(Debug, Serialize, Default)]
struct Stages {
    preprocess: f64,
    descriptors: f64,
    dictionary: f64,
    em: f64,
    instances: f64,
    total: f64,
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

pub fn run(a: BenchDetectArgs, g: &GlobalArgs) -> anyhow::Result<()> {
    let kind = SceneKind::from_name(&a.kind).ok_or_else(|| {
        bad_input(format!("unknown scene kind `{}` (scene-facade, scene-street, scene-parts)", a.kind))
    })?;
    if a.scenes == 0 {
        return Err(bad_input("--scenes must be at least 1"));
    }
    let options = |method, seed| {
        let mut o = DetectOptions { method, seed, ..Default::default() };
        o.preprocess.epsilon = Epsilon::Relative(a.epsilon);
        o.em.min_support = a.min_support;
        o.em.peak_share = a.peak_share;
        o.extent.regroup = a.regroup.into();
        o.extent.repeated_segments = a.repeated_segments.into();
        o.extent.content.enabled = !a.no_content;
        o.extent.aligned.enabled = !a.no_aligned;
        o.extent.copies.enabled = !a.no_aligned && !a.no_copies;
        o.extent.shapes.enabled = !a.no_shape_split;
        o.extent.shapes.across_classes = !a.shape_split_per_class;
        o.extent.aligned.grouping = a.aligned_grouping.into();
        o.extent.aligned.mask_deep = !a.no_aligned_mask;
        o.extent.segment_support = !a.no_segment_support;
        o
    };
    super::detect::validate_options(&options(Method::EmSc, g.seed))?;
    let parts: Vec<&std::path::Path> = a.parts.iter().map(|p| p.as_path()).collect();
    check_outputs(&[a.plot.as_deref(), a.plot_detail.as_deref(), a.json.json.as_deref()], &parts, g.force)?;
    crate::output::check_output_formats(&[
        (a.plot.as_deref(), crate::output::OutputKind::Png),
        (a.plot_detail.as_deref(), crate::output::OutputKind::Png),
    ])?;
    // The parts are read once, before any scene: a file that is not a usable mesh stops the
    // bench at once, naming it.
    let part_meshes = a.parts.iter().map(|p| load_scene_part(p)).collect::<Result<Vec<_>, _>>()?;
    let bar = Bar::new(g.quiet);
    let eval = EvalOptions::default();
    let mut rows = Vec::new();
    let mut leads = Vec::new();
    let mut stages: Vec<(&'static str, Stages)> = Vec::new();
    let mut curves = Vec::new();
    // The levels asked for, each once, from easy to hard (the table's rows).
    let levels = [
        (DifficultyArg::Easy, Difficulty::Easy, "easy"),
        (DifficultyArg::Medium, Difficulty::Medium, "medium"),
        (DifficultyArg::Hard, Difficulty::Hard, "hard"),
    ];
    let levels: Vec<_> = levels.into_iter().filter(|(l, ..)| a.difficulty.contains(l)).collect();
    for &(_, difficulty, dname) in &levels {
        let mut results: Vec<Vec<(DetectionResult, DetectionResult, f64)>> = vec![Vec::new(); 3];
        let mut st = Stages::default();
        for k in 0..a.scenes {
            let seed = g.seed.wrapping_add(k as u64);
            let so = SceneOptions { difficulty, points: a.points, seed, ..Default::default() };
            let scene = bar.spin(&format!("{dname} scene {}", k + 1), || {
                generate_scene_with_parts(kind, &so, &part_meshes)
            })?;
            let gt = scene.ground_truth.clone();
            for (m, method) in [(0, Method::EmSc), (1, Method::Sc)] {
                let o = options(method, seed);
                let t = Instant::now();
                let d = motif_detect::detect(&scene.cloud, "scene", &o, &bar, false)?;
                let s = t.elapsed().as_secs_f64();
                if method == Method::EmSc {
                    let r = &d.report.seconds;
                    let n = a.scenes as f64;
                    st.preprocess += r.preprocess / n;
                    st.descriptors += r.descriptors / n;
                    st.dictionary += r.dictionary / n;
                    st.em += r.em / n;
                    st.instances += r.instances / n;
                    st.total += r.total / n;
                }
                results[m].push((d.result, gt.clone(), s));
            }
            if !a.no_icp {
                let t = Instant::now();
                let (r, _) = bar.spin(&format!("{dname} scene {}: rigid ICP", k + 1), || {
                    rigid_icp(
                        &scene.cloud.positions,
                        scene.cloud.normals.as_deref(),
                        &gt,
                        &RigidIcpOptions::default(),
                    )
                })?;
                results[2].push((r, gt.clone(), t.elapsed().as_secs_f64()));
            }
        }
        for (m, name) in [(0, "EM + SC"), (1, "SC (no EM)"), (2, "rigid ICP (supervised)")] {
            if results[m].is_empty() {
                continue;
            }
            let summary = evaluate_many(results[m].iter().map(|(d, gt, _)| (d, gt)), &eval)?;
            let scene_f: Vec<f64> = summary.scenes.iter().map(|s| s.f).collect();
            rows.push(Row {
                difficulty: dname,
                method: name,
                scenes: results[m].len(),
                precision: summary.precision,
                recall: summary.recall,
                f: summary.f,
                f_se: mean_and_se(&scene_f).1,
                scene_f,
                stress: summary.mean_stress.clone(),
                median_seconds: median(results[m].iter().map(|x| x.2).collect()),
                annotated: summary.annotated.clone(),
                located_recall: summary.located_recall,
                located_f: summary.located_f,
            });
            if m == 0 {
                curves.push((dname, summary));
            }
        }
        let per_scene =
            |method: &str| rows.iter().rev().find(|r| r.method == method).map(|r| r.scene_f.clone());
        if let (Some(em), Some(sc)) = (per_scene("EM + SC"), per_scene("SC (no EM)")) {
            let d: Vec<f64> = em.iter().zip(&sc).map(|(a, b)| a - b).collect();
            let (mean, se) = mean_and_se(&d);
            leads.push(Lead { difficulty: dname, scenes: d.len(), mean, se });
        }
        stages.push((dname, st));
    }
    let last_seed = g.seed.wrapping_add(a.scenes.saturating_sub(1) as u64);
    let what = if a.scenes == 1 {
        format!("{} × 1 scene of {} points (seed {})", a.kind, a.points, g.seed)
    } else {
        format!("{} × {} scenes of {} points (seeds {}–{last_seed})", a.kind, a.scenes, a.points, g.seed)
    };
    if let Some(p) = &a.plot {
        let bench_rows: Vec<BenchRow> = rows
            .iter()
            .map(|r| BenchRow {
                difficulty: r.difficulty.to_string(),
                method: r.method.to_string(),
                f: r.f,
                f_se: r.f_se,
                stress: r.stress.clone(),
            })
            .collect();
        plot_bench(&bench_rows, &format!("motif bench detect: {what}"), eval.tau, p)?;
    }
    if let Some(p) = &a.plot_detail {
        if let Some((d, s)) = curves.iter().find(|(d, _)| *d == "medium").or(curves.first()) {
            let title = format!(
                "EM + SC, {d} {what}: P {:.3}, R {:.3}, F {:.3} at τ {}",
                s.precision, s.recall, s.f, eval.tau
            );
            plot_pr_and_stress_titled(s, &title, p)?;
        }
    }
    if !crate::output::json_on_stdout(&a.json.json) {
        // The extent stage's steps only when it runs: under `--regroup none` they do nothing.
        let extent = if a.regroup == RegroupArg::Extent {
            format!(
                "regroup by extent, repeated segments {}, content {}, aligned {}",
                match a.repeated_segments {
                    RepeatedSegmentsArg::Classes => "by size and shape",
                    RepeatedSegmentsArg::Sizes => "by size",
                    RepeatedSegmentsArg::None => "off",
                },
                if a.no_content { "off" } else { "on" },
                match (a.no_aligned, a.aligned_grouping) {
                    (true, _) => "off",
                    (false, AlignedGroupingArg::Communities) => "by communities",
                    (false, AlignedGroupingArg::Reassign) => "by reassignment",
                },
            )
        } else {
            "regroup off (the thesis's output)".to_string()
        };
        println!(
            "{} × {} scene{} of {} points, ε = {} × diagonal, minimum support {}, peak share {}, {extent}, τ = {}",
            a.kind,
            a.scenes,
            if a.scenes == 1 { "" } else { "s" },
            a.points,
            a.epsilon,
            a.min_support,
            a.peak_share,
            eval.tau
        );
        if !a.parts.is_empty() {
            let names: Vec<String> = a.parts.iter().map(|p| p.display().to_string()).collect();
            println!("parts: {}", names.join(", "));
        }
        println!(
            "{:<8} {:<24} {:>6} {:>6} {:>6} {:>7} {:>8} {:>9}",
            "level", "method", "P", "R", "F", "F s.e.", "F τ=0.5", "median s"
        );
        for r in &rows {
            println!(
                "{:<8} {:<24} {:>6.3} {:>6.3} {:>6.3} {:>7} {:>8.3} {:>9.2}",
                r.difficulty,
                r.method,
                r.precision,
                r.recall,
                r.f,
                pm(r.f_se),
                r.stress.last().map_or(f64::NAN, |s| s.1),
                r.median_seconds
            );
        }
        for l in &leads {
            println!(
                "{:<8} EM + SC − SC: F {:+.3} {} (paired over {} scenes)",
                l.difficulty,
                l.mean,
                pm(l.se),
                l.scenes
            );
        }
        println!("EM + SC mean seconds per stage:");
        println!(
            "{:<8} {:>10} {:>11} {:>10} {:>6} {:>9} {:>6}",
            "level", "preprocess", "descriptors", "dictionary", "EM", "instances", "total"
        );
        for (d, s) in &stages {
            println!(
                "{:<8} {:>10.2} {:>11.2} {:>10.2} {:>6.2} {:>9.2} {:>6.2}",
                d, s.preprocess, s.descriptors, s.dictionary, s.em, s.instances, s.total
            );
        }
        if a.per_class {
            println!("EM + SC per annotated class (summed over the scenes):");
            super::eval::print_annotated(
                rows.iter()
                    .filter(|r| r.method == "EM + SC")
                    .flat_map(|r| r.annotated.iter().map(|t| (Some(r.difficulty), t))),
            );
            println!(
                "EM + SC: no grouping or pruning of its boxes scores more (from the blocks they locate):"
            );
            println!("{:<8} {:>8} {:>8}   (R, F as detected)", "level", "R bound", "F bound");
            for r in rows.iter().filter(|r| r.method == "EM + SC") {
                println!(
                    "{:<8} {:>8.3} {:>8.3}   ({:.3}, {:.3})",
                    r.difficulty, r.located_recall, r.located_f, r.recall, r.f
                );
            }
        }
        for p in [&a.plot, &a.plot_detail].into_iter().flatten() {
            super::note(g, format!("wrote {}", p.display()));
        }
    }
    maybe_json(
        &a.json.json,
        &serde_json::json!({ "rows": rows, "em_lead": leads, "stages": stages, "epsilon": a.epsilon,
            "min_support": a.min_support, "peak_share": a.peak_share, "points": a.points,
            "kind": a.kind, "parts": a.parts, "levels": levels.iter().map(|l| l.2).collect::<Vec<_>>(),
            "regroup": a.regroup == RegroupArg::Extent,
            "repeated_segments": match a.repeated_segments {
                RepeatedSegmentsArg::Classes => "classes",
                RepeatedSegmentsArg::Sizes => "sizes",
                RepeatedSegmentsArg::None => "none",
            },
            "content": !a.no_content, "aligned": !a.no_aligned,
            "copies": !a.no_aligned && !a.no_copies, "shape_split": !a.no_shape_split, "shape_split_across_classes": !a.no_shape_split && !a.shape_split_per_class, "aligned_mask": !a.no_aligned && !a.no_aligned_mask, "segment_support": !a.no_segment_support,
            "aligned_grouping": if a.aligned_grouping == AlignedGroupingArg::Communities { "communities" } else { "reassign" } }),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn standard_error_is_the_sample_deviation_over_root_n() {
        // 1, 2, 3, 4: mean 2.5, sample variance 5/3, standard error sqrt(5/12).
        let (mean, se) = mean_and_se(&[1.0, 2.0, 3.0, 4.0]);
        assert_eq!(mean, 2.5);
        assert!((se.unwrap() - (5.0f64 / 12.0).sqrt()).abs() < 1e-12);
        assert_eq!(mean_and_se(&[0.7]), (0.7, None));
        assert_eq!(pm(None), "–");
        assert_eq!(pm(Some(0.0123)), "±0.012");
    }
}
