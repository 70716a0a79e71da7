//! `motif eval`: the evaluation protocol of thesis 5.5.2 on detection results.

use std::path::Path;

use motif_detect::{
    AnnotatedClassTotals, DetectionResult, EvalOptions, EvalSummary, evaluate_many, plot_pr_and_stress,
};

use crate::cli::{EvalArgs, GlobalArgs};
use crate::output::{bad_input, check_outputs, maybe_json};

/// The `--json` report: the summary, and the time it took.
#[derive(serde::Serialize)]
struct Report<'a> {
    #[serde(flatten)]
    summary: &'a EvalSummary,
    /// Reading and scoring, ms.
    ms: f64,
}

pub fn run(a: EvalArgs, g: &GlobalArgs) -> anyhow::Result<()> {
    let t0 = std::time::Instant::now();
    if a.files.len() % 2 != 0 {
        return Err(bad_input(format!("give RESULT GT pairs: {} files is an odd number", a.files.len())));
    }
    let inputs: Vec<&std::path::Path> = a.files.iter().map(|f| f.as_path()).collect();
    check_outputs(&[a.plot.as_deref(), a.json.json.as_deref()], &inputs, g.force)?;
    crate::output::check_output_formats(&[(a.plot.as_deref(), crate::output::OutputKind::Png)])?;
    let options = EvalOptions { tau: a.tau, ..Default::default() };
    options.validate()?;
    let mut loaded = Vec::new();
    for pair in a.files.chunks(2) {
        let (d, gt) = (DetectionResult::read(&pair[0])?, DetectionResult::read(&pair[1])?);
        for w in pair_warnings(&d, &gt, &pair[0], &pair[1]) {
            super::warn(w);
        }
        loaded.push((d, gt));
    }
    let summary = evaluate_many(loaded.iter().map(|(d, gt)| (d, gt)), &options)?;
    if let Some(p) = &a.plot {
        plot_pr_and_stress(&summary, p)?;
    }
    // Results print even with --quiet (only notes are hidden), as for info and symmetry check.
    if !crate::output::json_on_stdout(&a.json.json) {
        for (s, pair) in summary.scenes.iter().zip(a.files.chunks(2)) {
            println!(
                "{}: P {:.3}  R {:.3}  F {:.3}  ({} / {} vs {} / {} annotated)",
                pair[0].display(),
                s.precision,
                s.recall,
                s.f,
                crate::output::count(s.detected_classes, "detected class", "detected classes"),
                crate::output::count(s.detected_instances, "instance", "instances"),
                s.ground_truth_classes,
                s.ground_truth_instances
            );
        }
        if summary.scenes.len() > 1 {
            println!(
                "mean over {} scenes: P {:.3}  R {:.3}  F {:.3}",
                summary.scenes.len(),
                summary.precision,
                summary.recall,
                summary.f
            );
        }
        let stress: Vec<String> =
            summary.mean_stress.iter().step_by(4).map(|(t, f)| format!("{t:.2}:{f:.2}")).collect();
        println!("stress (tau:F) {}", stress.join("  "));
        if a.per_class {
            print_per_class(&summary);
        }
        if let Some(p) = &a.plot {
            super::note(g, format!("wrote {}", p.display()));
        }
    }
    maybe_json(&a.json.json, &Report { summary: &summary, ms: crate::output::ms_since(t0) })
}

/// The `--per-class` tables: annotated classes summed by name, then (one scene) detected classes.
fn print_per_class(summary: &EvalSummary) {
    print_annotated(summary.annotated.iter().map(|t| (None, t)));
    if summary.scenes.iter().any(|s| s.ground_truth_instances > 0) {
        println!(
            "located by some box: {:.1}% of the annotated instances{}; no grouping or pruning of these boxes scores R > {:.3} or F > {:.3}",
            100.0 * summary.located_recall,
            if summary.scenes.len() > 1 { " (mean of the scenes' shares)" } else { "" },
            summary.located_recall,
            summary.located_f
        );
    }
    if let [scene] = summary.scenes.as_slice() {
        let width = scene.detected.iter().map(|c| c.name.len()).max().unwrap_or(0).max(14);
        println!("{:<width$}  {:>9}  {:>8}  against", "detected class", "instances", "credited");
        for c in &scene.detected {
            let against = c.best_annotated.map_or("-", |i| scene.annotated[i].name.as_str());
            println!("{:<width$}  {:>9}  {:>8}  {against}", c.name, c.instances, c.credited);
        }
    }
}

/// The annotated classes' table (`motif eval --per-class`, `motif bench detect --per-class`):
/// one row per class, led by its difficulty level when the rows have one.
pub(crate) fn print_annotated<'a>(
    rows: impl IntoIterator<Item = (Option<&'a str>, &'a AnnotatedClassTotals)>,
) {
    let rows: Vec<_> = rows.into_iter().collect();
    let width = rows.iter().map(|(_, t)| t.name.len()).max().unwrap_or(0).max(15);
    let level = |l: Option<&str>| {
        if rows.iter().any(|r| r.0.is_some()) { format!("{:<8} ", l.unwrap_or("")) } else { String::new() }
    };
    println!(
        "{}{:<width$}  {:>6}  {:>9}  {:>5}  {:>8}  {:>6}  {:>9}",
        level(Some("level")),
        "annotated class",
        "scenes",
        "instances",
        "found",
        "recalled",
        "missed",
        "elsewhere"
    );
    for (l, t) in &rows {
        println!(
            "{}{:<width$}  {:>6}  {:>9}  {:>5}  {:>8}  {:>6}  {:>9}",
            level(*l),
            t.name,
            t.scenes,
            t.instances,
            t.found,
            t.recalled,
            t.missed(),
            t.elsewhere()
        );
    }
    println!(
        "(missed: located by no detected box; elsewhere: located, but not by the class the recall credits)"
    );
}

/// What makes a pair's scores mean less than they seem: files of different scenes, a ground
/// truth with nothing annotated, boxes that can match nothing (flat, or of a volume that
/// overflows; see `motif_detect::eval`).
fn pair_warnings(d: &DetectionResult, gt: &DetectionResult, dp: &Path, gp: &Path) -> Vec<String> {
    let mut out = Vec::new();
    if std::fs::canonicalize(dp).ok().is_some_and(|a| std::fs::canonicalize(gp).ok() == Some(a)) {
        out.push(format!(
            "{} is given as both the result and the ground truth: it scores 1 against itself",
            dp.display()
        ));
    }
    if !d.scene.is_empty() && !gt.scene.is_empty() && d.scene != gt.scene {
        out.push(format!(
            "{} is a result for scene `{}` but {} annotates scene `{}`",
            dp.display(),
            d.scene,
            gp.display(),
            gt.scene
        ));
    }
    // `motif detect` names its classes class_0, class_1, ...; ground truth names what they are.
    // Both files share one schema, so a swapped pair would score with P and R exchanged.
    let detector_names = |r: &DetectionResult| {
        r.classes.iter().all(|c| {
            c.name
                .as_deref()
                .and_then(|n| n.strip_prefix("class_"))
                .is_some_and(|n| n.parse::<usize>().is_ok())
        })
    };
    let named = |r: &DetectionResult| r.classes.iter().all(|c| c.name.is_some());
    if !d.classes.is_empty() && !gt.classes.is_empty() && named(d) && !detector_names(d) && detector_names(gt)
    {
        out.push(format!(
            "{} names its classes as ground truth does, and {} as `motif detect` does: were they given \
             the wrong way round? (the result comes first, then the ground truth; precision and recall \
             swap otherwise)",
            dp.display(),
            gp.display()
        ));
    }
    if gt.classes.iter().all(|c| c.instances.is_empty()) {
        out.push(format!(
            "{} annotates no instance: the pair scores P = R = F = 1 if the result is empty too, 0 \
             otherwise, and counts in the mean",
            gp.display()
        ));
    }
    for (r, p) in [(d, dp), (gt, gp)] {
        let degenerate = r
            .classes
            .iter()
            .flat_map(|c| &c.instances)
            .filter(|i| {
                let v = motif_core::geometry::Aabb { min: i.bbox_min, max: i.bbox_max }.volume();
                !(v > 0.0 && v.is_finite())
            })
            .count();
        if degenerate > 0 {
            out.push(format!(
                "{}: {degenerate} boxes are flat or so large that their volume overflows; they match \
                 nothing (give planar parts a small thickness)",
                p.display()
            ));
        }
    }
    out
}
