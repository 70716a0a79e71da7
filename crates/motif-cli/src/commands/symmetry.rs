//! `motif symmetry`: automatic detection of global symmetries (and, with the deformation engine,
//! checking annotations).

use std::time::Instant;

use anyhow::Context;
use motif_deform::symmetry_detect::{
    AnnotationContents, Scope, SymmetryDetectOptions, detect_symmetries_with_progress,
};
use serde::Serialize;

use crate::cli::{GlobalArgs, SymmetryCheckArgs, SymmetryDetectArgs};
use crate::output::{bad_input, check_outputs, maybe_json, ms_since, write_json};
use crate::progress::Bar;

#[derive(Debug, Serialize)]
struct DetectReport<'a> {
    mesh: String,
    annotation: String,
    options: &'a SymmetryDetectOptions,
    ms: f64,
    report: &'a motif_deform::symmetry_detect::SymmetryReport,
}

pub fn detect(a: SymmetryDetectArgs, g: &GlobalArgs) -> anyhow::Result<()> {
    check_outputs(&[Some(&a.output), a.json.json.as_deref()], &[&a.mesh], g.force)?;
    if !(a.tolerance > 0.0 && a.tolerance < 0.1) {
        return Err(bad_input(format!(
            "--tolerance {}: use a small positive fraction such as 1e-3",
            a.tolerance
        )));
    }
    if !(2..=360).contains(&a.max_order) {
        return Err(bad_input(format!("--max-order {}: use 2 to 360", a.max_order)));
    }
    let mesh = motif_core::io::read_mesh(&a.mesh)?;
    let options = SymmetryDetectOptions {
        tolerance: a.tolerance,
        approximate_tolerance: (10.0 * a.tolerance).max(1e-2),
        max_rotation_order: a.max_order,
        annotation: if a.approximate {
            AnnotationContents::VerifiedAndApproximate
        } else {
            AnnotationContents::Verified
        },
        seed: g.seed,
        ..Default::default()
    };
    let t = Instant::now();
    let bar = Bar::new(g.quiet);
    let det = detect_symmetries_with_progress(&mesh, &options, &bar)
        .with_context(|| a.mesh.display().to_string())?;
    let ms = ms_since(t);
    write_json(&a.output, &det.annotation)?;
    let stdout_json = crate::output::json_on_stdout(&a.json.json);
    // Results print under --quiet too; only the "wrote" note is quiet.
    if !stdout_json {
        let global = det.report.groups.iter().filter(|gr| gr.scope == Scope::Global).count();
        if global == 0 {
            println!("no global symmetry within {:.0e} of the diagonal", a.tolerance);
        }
        // Detection validates each group on surface samples; `motif symmetry check` maps the
        // vertices. On a mesh whose copies are tessellated alike the two agree; where they are
        // not (the CGAL pinion: 9.6e-4 on samples, 3.6e-5 at the vertices) both are printed, so
        // the figure a later check prints is not a surprise. The annotation lists the groups in
        // the report's order.
        let checked = motif_deform::residual::check_annotation(&mesh, &det.annotation).ok();
        for (k, gr) in det.report.groups.iter().enumerate() {
            let at_vertices = checked
                .as_ref()
                .and_then(|c| c.symmetries.get(k))
                .filter(|c| {
                    // Both at rounding level (1e-16 against 2e-16) is agreement, not news.
                    let larger = c.max_residual.max(gr.max_residual);
                    c.ok && larger > 1e-9 && (c.max_residual - gr.max_residual).abs() > 0.5 * larger
                })
                .map(|c| format!(" ({:.1e} at the vertices, as `symmetry check` measures)", c.max_residual))
                .unwrap_or_default();
            let scope = match gr.scope {
                Scope::Global => "global".to_string(),
                Scope::Part(i) => format!("part {i}"),
            };
            // Nested partial symmetries of one part (thesis Fig. 3.3: the sails alone, then the
            // rotor) differ in their regions, so each line says how much of the mesh it holds.
            let region = match gr.region_faces {
                Some(n) => format!(" on {n} of {} faces", mesh.num_triangles()),
                None => String::new(),
            };
            println!(
                "{scope:<8} {}{region}; max residual {:.1e} of the diagonal over surface samples{at_vertices}{}",
                gr.name,
                gr.max_residual,
                if gr.possibly_continuous { " (possibly a surface of revolution)" } else { "" }
            );
        }
        if !det.report.approximate.is_empty() {
            println!(
                "{} (residual < {:.0e}) not annotated{}",
                crate::output::count(
                    det.report.approximate.len(),
                    "approximate symmetry",
                    "approximate symmetries"
                ),
                options.approximate_tolerance,
                if a.approximate { "" } else { "; --approximate adds them" }
            );
        }
    }
    if !g.quiet {
        eprintln!("wrote {} ({:.0} ms)", a.output.display(), ms);
    }
    let report = DetectReport {
        mesh: a.mesh.display().to_string(),
        annotation: a.output.display().to_string(),
        options: &options,
        ms,
        report: &det.report,
    };
    maybe_json(&a.json.json, &report)
}

pub fn check(a: SymmetryCheckArgs, _g: &GlobalArgs) -> anyhow::Result<()> {
    check_outputs(&[a.json.json.as_deref()], &[&a.mesh, &a.annotation], _g.force)?;
    let mesh = motif_core::io::read_mesh(&a.mesh)?;
    let annotation = motif_deform::annotation::read_annotation(&a.annotation)?;
    let report = motif_deform::residual::check_annotation(&mesh, &annotation)
        .with_context(|| format!("{} with {}", a.mesh.display(), a.annotation.display()))?;
    maybe_json(&a.json.json, &report)?;
    if !crate::output::json_on_stdout(&a.json.json) {
        println!(
            "{} against {} (tolerance {:.0e} of the diagonal)",
            a.annotation.display(),
            a.mesh.display(),
            report.tolerance
        );
        for s in &report.symmetries {
            println!(
                "  {:<4} {:<10} order {:>4}  max residual {:.2e}  {}",
                if s.ok { "ok" } else { "FAIL" },
                s.kind,
                s.order,
                s.max_residual,
                s.name
            );
            if let Some(p) = &s.problem {
                println!("       {p}");
            }
        }
    }
    // A symmetry that could not even be resolved (not a rigid motion, a region out of range, an
    // infinite group) is bad input, as `deform` treats it: exit 2, naming what is wrong.
    let malformed: Vec<(&str, &str)> = report
        .symmetries
        .iter()
        .filter(|s| !s.ok)
        .filter_map(|s| s.problem.as_deref().map(|p| (s.name.as_str(), p)))
        .collect();
    if !malformed.is_empty() {
        // The table above gives each problem; the error names the symmetries once. With the
        // JSON on stdout no table is printed, so the problems themselves are the message.
        let what = if crate::output::json_on_stdout(&a.json.json) {
            malformed.iter().map(|(n, p)| format!("symmetry \"{n}\": {p}")).collect::<Vec<_>>().join("; ")
        } else {
            format!(
                "{} cannot be resolved on {} ({}; the problems are listed above)",
                crate::output::count(malformed.len(), "symmetry", "symmetries"),
                a.mesh.display(),
                malformed.iter().map(|(n, _)| format!("\"{n}\"")).collect::<Vec<_>>().join(", ")
            )
        };
        return Err(crate::output::bad_input(format!("{}: {what}", a.annotation.display())));
    }
    if !report.ok {
        anyhow::bail!(
            "{}: the annotation does not fit {} within its tolerance",
            a.annotation.display(),
            a.mesh.display()
        );
    }
    Ok(())
}
