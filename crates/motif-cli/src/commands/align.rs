//! `motif align`: rigid (or translation-only) ICP of one shape onto another.

use std::time::Instant;

use anyhow::Context;
use motif_core::TriMesh;
use motif_core::geometry::IDENTITY4;
use motif_core::icp::{IcpMetric, IcpMotion, IcpOptions, icp};
use motif_core::normals::{NormalsOptions, estimate_normals};
use serde::Serialize;

use crate::cli::{AlignArgs, GlobalArgs, IcpMetricArg, IcpMotionArg};
use crate::output::{bad_input, maybe_json, ms_since};

#[derive(Debug, Serialize)]
struct AlignReport {
    source: String,
    target: String,
    options: IcpOptions,
    target_from_source: [[f64; 4]; 4],
    rmse: f64,
    inlier_fraction: f64,
    iterations: usize,
    converged: bool,
    ms: f64,
}

pub fn run(a: AlignArgs, g: &GlobalArgs) -> anyhow::Result<()> {
    crate::output::check_outputs(
        &[a.output.as_deref(), a.json.json.as_deref()],
        &[&a.source, &a.target],
        g.force,
    )?;
    crate::output::check_output_formats(&[(a.output.as_deref(), crate::output::OutputKind::Model)])?;
    if !(a.trim > 0.0 && a.trim <= 1.0) {
        return Err(bad_input(format!("--trim {}: must be in (0, 1]", a.trim)));
    }
    if a.iterations == 0 || a.iterations > 10_000 {
        return Err(bad_input(format!("--iterations {}: use 1 to 10000", a.iterations)));
    }
    let source = super::read_model_for_geometry(&a.source)?;
    let target = super::read_model_for_geometry(&a.target)?;
    let options = IcpOptions {
        metric: match a.metric {
            IcpMetricArg::PointToPoint => IcpMetric::PointToPoint,
            IcpMetricArg::PointToPlane => IcpMetric::PointToPlane,
        },
        motion: match a.motion {
            IcpMotionArg::Rigid => IcpMotion::Rigid,
            IcpMotionArg::TranslationOnly => IcpMotion::TranslationOnly,
        },
        max_iterations: a.iterations,
        trim_fraction: a.trim,
        ..Default::default()
    };
    let t = Instant::now();
    let target_normals = match (&options.metric, &target.vertices.normals) {
        (IcpMetric::PointToPoint, _) => None,
        (_, Some(n)) => Some(n.clone()),
        (_, None) if target.is_mesh() => Some(
            TriMesh { positions: target.vertices.positions.clone(), triangles: target.triangles.clone() }
                .vertex_normals(),
        ),
        (_, None) => {
            Some(estimate_normals(&target.vertices.positions, &NormalsOptions::default()).with_context(
                || format!("{}: the target's normals (for point-to-plane)", a.target.display()),
            )?)
        }
    };
    // Point-to-plane needs planes: when most target normals are zero (zero-area triangles,
    // collinear or coincident points) every residual along them would read 0 and any rotation
    // would "fit"; align point-to-point instead and say so.
    let mut options = options;
    let mut target_normals = target_normals;
    if let Some(n) = &target_normals {
        let zero = n
            .iter()
            .filter(|v| {
                let l = motif_core::geometry::norm(**v);
                l.is_nan() || l <= 0.0
            })
            .count();
        if 2 * zero > n.len() {
            super::warn(format!(
                "{}: {zero} of {} target normals are undetermined (degenerate triangles, or \
                     collinear or coincident points); aligning point-to-point instead",
                a.target.display(),
                n.len()
            ));
            options.metric = IcpMetric::PointToPoint;
            target_normals = None;
        }
    }
    let r = icp(
        &source.vertices.positions,
        &target.vertices.positions,
        target_normals.as_deref(),
        &IDENTITY4,
        &options,
    )
    .with_context(|| format!("aligning {} to {}", a.source.display(), a.target.display()))?;
    let ms = ms_since(t);
    if let Some(out) = &a.output {
        let mut moved = source.clone();
        for p in &mut moved.vertices.positions {
            *p = motif_core::geometry::transform_point(&r.transform, *p);
        }
        if let Some(n) = &mut moved.vertices.normals {
            for v in n.iter_mut() {
                *v = motif_core::geometry::transform_vector(&r.transform, *v);
            }
        }
        super::write_model(out, &moved, &[&a.source, &a.target], g, &a.encoding)?;
    }
    let trim = options.trim_fraction;
    let report = AlignReport {
        source: a.source.display().to_string(),
        target: a.target.display().to_string(),
        options,
        target_from_source: r.transform,
        rmse: r.rmse,
        inlier_fraction: r.inlier_fraction,
        iterations: r.iterations,
        converged: r.converged,
        ms,
    };
    // A report written to a file leaves the text on stdout; one on stdout replaces it.
    maybe_json(&a.json.json, &report)?;
    if crate::output::json_on_stdout(&a.json.json) {
        return Ok(());
    }
    // Trimmed ICP keeps at most `--trim` of the pairs, so the share is no inlier count: an exact
    // match read "90.0% inliers".
    println!(
        "rmse {:.6e} over {:.1}% of the source points (the closest {:.0}% of the pairs within reach, --trim), {} iterations{}",
        r.rmse,
        100.0 * r.inlier_fraction,
        100.0 * trim,
        r.iterations,
        if r.converged { "" } else { " (not converged)" }
    );
    println!("target_from_source:");
    for row in r.transform {
        println!("  {:>12.6} {:>12.6} {:>12.6} {:>12.6}", row[0], row[1], row[2], row[3]);
    }
    if let Some(out) = &a.output {
        super::note(g, format!("wrote {} (the source moved onto the target)", out.display()));
    }
    Ok(())
}
