//! `motif baseline`: baseline detectors for the comparison of thesis 5.5.3.

use motif_detect::rigid_icp::{RigidIcpOptions, RotationSearch, rigid_icp as run_rigid_icp};
use motif_detect::{DetectionResult, EvalOptions, evaluate};
use serde::Serialize;

use crate::cli::{GlobalArgs, RigidIcpArgs, RotationsArg};
use crate::output::{bad_input, check_outputs, json_on_stdout, maybe_json, write_json};

#[derive(Debug, Serialize)]
struct Report {
    scene: String,
    ground_truth: String,
    output: String,
    /// The baseline's own report (per-class seeds, candidates, detections, times).
    rigid_icp: motif_detect::RigidIcpReport,
    /// The detection scored against the ground truth it was given (τ = 0.125).
    precision: f64,
    recall: f64,
    f: f64,
}

/// `motif baseline rigid-icp SCENE --gt GT -o RESULT [--json REPORT]`.
pub fn rigid_icp(a: RigidIcpArgs, g: &GlobalArgs) -> anyhow::Result<()> {
    let inputs = [a.scene.as_path(), a.gt.as_path()];
    check_outputs(&[Some(&a.output), a.json.json.as_deref()], &inputs, g.force)?;
    let cloud = super::read_model_for_geometry(&a.scene)?.vertices;
    if cloud.is_empty() {
        return Err(bad_input(format!("{}: no points", a.scene.display())));
    }
    let ground_truth = DetectionResult::read(&a.gt)?;
    // The baseline takes each class's first instance as its template: without one there is
    // nothing to search for, and scoring nothing against nothing would print a perfect F.
    if ground_truth.classes.iter().all(|c| c.instances.is_empty()) {
        return Err(bad_input(format!(
            "{}: the ground truth has no instance to take as a template (rigid ICP searches for each \
             class's first instance)",
            a.gt.display()
        )));
    }
    let options = RigidIcpOptions {
        step: a.step,
        min_score: a.min_score,
        inlier_distance: a.inlier_distance,
        rotation_steps: a.rotation_steps,
        rotations: match a.rotations {
            RotationsArg::Auto => RotationSearch::Auto,
            RotationsArg::Never => RotationSearch::Never,
            RotationsArg::Always => RotationSearch::Always,
        },
        seed: g.seed,
        ..Default::default()
    };
    let (mut detection, report) =
        run_rigid_icp(&cloud.positions, cloud.normals.as_deref(), &ground_truth, &options)
            .map_err(|e| anyhow::Error::new(e).context(format!("rigid ICP on {}", a.scene.display())))?;
    detection.scene = a
        .scene
        .file_name()
        .map(|f| f.to_string_lossy().into_owned())
        .unwrap_or_else(|| detection.scene.clone());
    write_json(&a.output, &detection)?;
    let eval = evaluate(&detection, &ground_truth, &EvalOptions::default())?;
    // Results print under --quiet too.
    if !json_on_stdout(&a.json.json) {
        for c in &report.classes {
            match &c.skipped {
                Some(why) => println!("{}: skipped: {why}", c.name),
                None => println!(
                    "{}: {} template points, {} seeds ({} plausible) x {}, {} windows, {} refined, {} accepted, {} detections ({:.2} s)",
                    c.name,
                    c.template_points,
                    c.seeds,
                    c.plausible_seeds,
                    crate::output::count(c.orientations, "yaw", "yaws"),
                    c.windows,
                    c.refined,
                    c.accepted,
                    c.detections,
                    c.seconds
                ),
            }
        }
        println!(
            "{}: P {:.3}  R {:.3}  F {:.3} against {} ({:.2} s); wrote {}",
            a.scene.display(),
            eval.precision,
            eval.recall,
            eval.f,
            a.gt.display(),
            report.seconds,
            a.output.display()
        );
    }
    maybe_json(
        &a.json.json,
        &Report {
            scene: a.scene.display().to_string(),
            ground_truth: a.gt.display().to_string(),
            output: a.output.display().to_string(),
            rigid_icp: report,
            precision: eval.precision,
            recall: eval.recall,
            f: eval.f,
        },
    )
}
