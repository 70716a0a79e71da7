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
    /// Detection, ms.
    ms: f64,
    /// The check at the vertices that the printed table compares with (`symmetry check`'s
    /// measure), ms; absent when the report goes to stdout and no table is printed.
    check_ms: Option<f64>,
    report: &'a motif_deform::symmetry_detect::SymmetryReport,
}

pub fn detect(a: SymmetryDetectArgs, g: &GlobalArgs) -> anyhow::Result<()> {
    check_outputs(&[Some(&a.output), a.plot.as_deref(), a.json.json.as_deref()], &[&a.mesh], g.force)?;
    crate::output::check_output_formats(&[(a.plot.as_deref(), crate::output::OutputKind::Png)])?;
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
    let mut check_ms = None;
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
        let t_check = Instant::now();
        let checked = bar
            .spin("checking at the vertices", || {
                motif_deform::residual::check_annotation(&mesh, &det.annotation)
            })
            .ok();
        check_ms = Some(ms_since(t_check));
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
            // A partial group also names its entry in the annotation (`--plot` labels it so):
            // nested groups of one part share the part's number.
            let scope = match gr.scope {
                Scope::Global => "global".to_string(),
                Scope::Part(i) => format!("part {i} #{k}"),
            };
            // Nested partial symmetries of one part (thesis Fig. 3.3: the sails alone, then the
            // rotor) differ in their regions, so each line says how much of the mesh it holds.
            let region = match gr.region_faces {
                Some(n) => format!(" on {n} of {} faces", mesh.num_triangles()),
                None => String::new(),
            };
            println!(
                "{scope:<11} {}{region}; max residual {:.1e} of the diagonal over surface samples{at_vertices}{}",
                gr.name,
                gr.max_residual,
                if gr.possibly_continuous { " (possibly a surface of revolution)" } else { "" }
            );
        }
        if !det.report.approximate.is_empty() {
            let n = crate::output::count(
                det.report.approximate.len(),
                "approximate symmetry",
                "approximate symmetries",
            );
            // With --approximate they are among the groups above, and in the annotation.
            if a.approximate {
                println!(
                    "{n} (residual < {:.0e}) annotated above, as --approximate asks",
                    options.approximate_tolerance
                );
            } else {
                println!(
                    "{n} (residual < {:.0e}) not annotated; --approximate adds them",
                    options.approximate_tolerance
                );
            }
        }
    }
    if !g.quiet {
        eprintln!(
            "wrote {} ({:.0} ms{})",
            a.output.display(),
            ms,
            check_ms.map_or(String::new(), |c| format!(", and {c:.0} ms checking at the vertices"))
        );
    }
    if let Some(png) = &a.plot {
        plot_symmetries(&mesh, &det, &a.mesh, png)?;
        super::note(g, format!("wrote {}", png.display()));
    }
    let report = DetectReport {
        mesh: a.mesh.display().to_string(),
        annotation: a.output.display().to_string(),
        options: &options,
        ms,
        check_ms,
        report: &det.report,
    };
    maybe_json(&a.json.json, &report)
}

/// The `--json` report of `symmetry check`: the check, and the time it took.
#[derive(Serialize)]
struct CheckReport<'a> {
    #[serde(flatten)]
    check: &'a motif_deform::residual::AnnotationReport,
    /// Reading the mesh and the annotation, and checking, ms.
    ms: f64,
}

pub fn check(a: SymmetryCheckArgs, _g: &GlobalArgs) -> anyhow::Result<()> {
    let t0 = Instant::now();
    check_outputs(&[a.json.json.as_deref()], &[&a.mesh, &a.annotation], _g.force)?;
    let mesh = motif_core::io::read_mesh(&a.mesh)?;
    let annotation = motif_deform::annotation::read_annotation(&a.annotation)?;
    let report = motif_deform::residual::check_annotation(&mesh, &annotation)
        .with_context(|| format!("{} with {}", a.mesh.display(), a.annotation.display()))?;
    maybe_json(&a.json.json, &CheckReport { check: &report, ms: ms_since(t0) })?;
    // The report is the check's result whatever its verdict, and a failed check is when its
    // figures are wanted most: put it in place now, as the error below would discard it with a
    // failed command's outputs (`motif_core::io::defer_renames`).
    motif_core::io::commit_deferred()?;
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

/// A square stick from `p` to `q`, `t` thick (8 vertices, 12 triangles), appended to `m` with
/// `group` for each triangle.
fn stick(m: &mut motif_core::TriMesh, groups: &mut Vec<u32>, p: [f64; 3], q: [f64; 3], t: f64, group: u32) {
    use motif_core::geometry::{add, cross, normalize, scale, sub};
    let Some(d) = normalize(sub(q, p)) else { return };
    let helper = if d[0].abs() < 0.9 { [1.0, 0.0, 0.0] } else { [0.0, 1.0, 0.0] };
    let (Some(u), Some(v)) = (normalize(cross(d, helper)), normalize(cross(d, cross(d, helper)))) else {
        return;
    };
    let base = m.positions.len() as u32;
    for end in [p, q] {
        for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            m.positions.push(add(end, add(scale(u, 0.5 * t * a), scale(v, 0.5 * t * b))));
        }
    }
    for k in 0..4u32 {
        let (a, b) = (k, (k + 1) % 4);
        m.triangles.push([base + a, base + b, base + 4 + b]);
        m.triangles.push([base + a, base + 4 + b, base + 4 + a]);
        groups.extend([group, group]);
    }
    for cap in [[0u32, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7]] {
        m.triangles.push(cap.map(|i| base + i));
        groups.push(group);
    }
}

/// The segment of the line through `p` along `d` inside the box `[lo, hi]`, if any.
fn clip_line(p: [f64; 3], d: [f64; 3], lo: [f64; 3], hi: [f64; 3]) -> Option<([f64; 3], [f64; 3])> {
    let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
    for k in 0..3 {
        if d[k].abs() < 1e-12 {
            if p[k] < lo[k] || p[k] > hi[k] {
                return None;
            }
        } else {
            let (a, b) = ((lo[k] - p[k]) / d[k], (hi[k] - p[k]) / d[k]);
            t0 = t0.max(a.min(b));
            t1 = t1.min(a.max(b));
        }
    }
    (t0 < t1).then(|| ([0, 1, 2].map(|k| p[k] + t0 * d[k]), [0, 1, 2].map(|k| p[k] + t1 * d[k])))
}

/// The polygon where the plane through `p` with normal `n` cuts the box `[lo, hi]`, in order
/// around it.
fn plane_in_box(p: [f64; 3], n: [f64; 3], lo: [f64; 3], hi: [f64; 3]) -> Vec<[f64; 3]> {
    use motif_core::geometry::{cross, dot, normalize, sub};
    let corner = |i: usize| [0, 1, 2].map(|k| if i >> k & 1 == 1 { hi[k] } else { lo[k] });
    let mut pts = Vec::new();
    for i in 0..8usize {
        for k in 0..3 {
            let j = i | (1 << k);
            if j == i {
                continue;
            }
            let (a, b) = (corner(i), corner(j));
            let (da, db) = (dot(sub(a, p), n), dot(sub(b, p), n));
            if (da <= 0.0 && db > 0.0) || (da > 0.0 && db <= 0.0) {
                let t = da / (da - db);
                pts.push([0, 1, 2].map(|c| a[c] + t * (b[c] - a[c])));
            }
        }
    }
    if pts.len() < 3 {
        return Vec::new();
    }
    let c = [0, 1, 2].map(|k| pts.iter().map(|q| q[k]).sum::<f64>() / pts.len() as f64);
    let helper = if n[0].abs() < 0.9 { [1.0, 0.0, 0.0] } else { [0.0, 1.0, 0.0] };
    let (Some(u), Some(v)) = (normalize(cross(n, helper)), normalize(cross(n, cross(n, helper)))) else {
        return Vec::new();
    };
    pts.sort_by(|a, b| {
        let angle = |q: &[f64; 3]| dot(sub(*q, c), v).atan2(dot(sub(*q, c), u));
        angle(a).total_cmp(&angle(b))
    });
    pts
}

/// `--plot`: the model on the left; on the right the model with its symmetry elements drawn as
/// sticks (the preview renderer of `motif retarget`): mirror planes as their outline within the
/// group's box (the model's for the global group, the region's for a partial one), rotation and
/// rotoreflection axes as a line through that box, an inversion centre as a short cross; each
/// labelled. Only generators are drawn, as the text lists them.
fn plot_symmetries(
    mesh: &motif_core::TriMesh,
    det: &motif_deform::symmetry_detect::SymmetryDetection,
    input: &std::path::Path,
    png: &std::path::Path,
) -> anyhow::Result<()> {
    use motif_core::procedural::{Region, SymmetryKind};
    use motif_deform::symmetry_detect::SymmetryElement;
    use motif_retarget::plot::{PreviewMark, PreviewText, plot_retarget_preview};
    let Some(bbox) = mesh.aabb() else { return Ok(()) };
    let diag = bbox.diagonal();
    let mut overlay = mesh.clone();
    let mut groups = vec![0u32; mesh.triangles.len()];
    let mut marks = Vec::new();
    let (orange, green, pink) = ([200, 110, 30], [40, 140, 60], [190, 60, 100]);
    let mut partial = 0;
    // Nested partial groups repeat elements (the windmill's rotor and sails share the C4 axis):
    // each line or plane is drawn once, its label naming every group that has it.
    let mut drawn: Vec<(bool, [f64; 3], [f64; 3], usize)> = Vec::new();
    let same = |plane: bool, d: [f64; 3], p: [f64; 3], e: &(bool, [f64; 3], [f64; 3], usize)| {
        use motif_core::geometry::{cross, dot, norm, sub};
        let parallel = dot(d, e.1).abs() > 1.0 - 1e-9;
        let off = sub(p, e.2);
        let apart = if plane { dot(off, d).abs() } else { norm(cross(off, d)) };
        e.0 == plane && parallel && apart < 1e-6 * diag
    };
    // A label near another's (two boards' axes 1 cm apart) joins it rather than covering it.
    let label = |marks: &mut Vec<PreviewMark>, at, text: String, colour, key: Option<usize>| {
        let key = key.or_else(|| {
            marks
                .iter()
                .position(|m| m.colour == colour && motif_core::geometry::dist(m.at, at) < 0.03 * diag)
        });
        match key {
            Some(i) if marks[i].label.split("; ").any(|l| l == text) => {}
            Some(i) => marks[i].label += &format!("; {text}"),
            None => marks.push(PreviewMark { panel: 1, at, from: None, label: text, colour }),
        }
    };
    for (k, gr) in det.report.groups.iter().enumerate() {
        let global = gr.scope == Scope::Global;
        partial += usize::from(!global);
        // The group's box: the model's, or its region's vertices' for a partial group.
        let region_box = det.annotation.symmetries.get(k).and_then(|s| match &s.kind {
            SymmetryKind::Group { region: region @ Region::Faces(_), .. } => {
                let idx = region.vertex_indices(mesh, 0.0);
                motif_core::geometry::Aabb::from_points(
                    &idx.iter().map(|&i| mesh.positions[i]).collect::<Vec<_>>(),
                )
            }
            _ => None,
        });
        let b = if global { bbox } else { region_box.unwrap_or(bbox) };
        let pad = 0.04 * diag;
        let (lo, hi) = (b.min.map(|x| x - pad), b.max.map(|x| x + pad));
        let t = 0.006 * diag;
        for el in &gr.generators {
            let (group, colour) = match el {
                _ if !global => (3, pink),
                SymmetryElement::Mirror { .. } => (1, orange),
                _ => (2, green),
            };
            // Partial groups are named by their entry in the written annotation.
            let prefix = if global { String::new() } else { format!("#{k}: ") };
            match *el {
                SymmetryElement::Mirror { normal, point } => {
                    let text = format!("{prefix}mirror");
                    if let Some(e) = drawn.iter().find(|e| same(true, normal, point, e)) {
                        label(&mut marks, point, text, colour, Some(e.3));
                        continue;
                    }
                    let poly = plane_in_box(point, normal, lo, hi);
                    for (i, &p) in poly.iter().enumerate() {
                        stick(&mut overlay, &mut groups, p, poly[(i + 1) % poly.len()], t, group);
                    }
                    // Labelled at the outline's corner farthest from the labels placed so far.
                    let free = |q: &[f64; 3]| {
                        marks
                            .iter()
                            .map(|m| motif_core::geometry::dist(*q, m.at))
                            .fold(f64::INFINITY, f64::min)
                    };
                    if let Some(&at) = poly.iter().max_by(|a, b| free(a).total_cmp(&free(b))) {
                        drawn.push((true, normal, point, marks.len()));
                        label(&mut marks, at, text, colour, None);
                    }
                }
                SymmetryElement::Rotation { axis, point, order }
                | SymmetryElement::RotoReflection { axis, point, order } => {
                    let name = if matches!(el, SymmetryElement::Rotation { .. }) { "C" } else { "S" };
                    let text = format!("{prefix}{name}{order} axis");
                    if let Some(e) = drawn.iter().find(|e| same(false, axis, point, e)) {
                        label(&mut marks, point, text, colour, Some(e.3));
                        continue;
                    }
                    if let Some((p, q)) = clip_line(point, axis, lo, hi) {
                        // At least 60% of the diagonal long, about the box's middle, so that an
                        // axis across a flat model shows.
                        let (p, q) = {
                            use motif_core::geometry::{add, dist, scale, sub};
                            let half = 0.5 * dist(p, q).max(0.6 * diag);
                            let mid = add(p, scale(sub(q, p), 0.5));
                            (add(mid, scale(axis, -half)), add(mid, scale(axis, half)))
                        };
                        stick(&mut overlay, &mut groups, p, q, 1.5 * t, group);
                        drawn.push((false, axis, point, marks.len()));
                        label(&mut marks, q, text, colour, None);
                    }
                }
                SymmetryElement::Inversion { center } => {
                    for k in 0..3 {
                        let mut d = [0.0; 3];
                        d[k] = 0.03 * diag;
                        let (p, q) =
                            ([0, 1, 2].map(|c| center[c] - d[c]), [0, 1, 2].map(|c| center[c] + d[c]));
                        stick(&mut overlay, &mut groups, p, q, 1.5 * t, group);
                    }
                    label(&mut marks, center, format!("{prefix}inversion"), colour, None);
                }
            }
        }
    }
    let global = det.report.groups.iter().find(|gr| gr.scope == Scope::Global);
    let title = format!(
        "{}: {}{}",
        input.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default(),
        global.map_or("no global symmetry".to_string(), |gr| format!(
            "global {} (order {})",
            gr.structure.schoenflies, gr.structure.order
        )),
        if partial > 0 {
            format!(", {}", crate::output::count(partial, "partial group", "partial groups"))
        } else {
            String::new()
        }
    );
    let notes = vec![(
        if det.report.groups.is_empty() {
            "nothing to draw".to_string()
        } else {
            "generators of each group, as the text lists them; a plane is drawn as its outline in the \
             group's box (padded by 4% of the diagonal)"
                .to_string()
        },
        false,
    )];
    // More slanted than the deformation's view, so that an axis along the thinnest side (a
    // fan's, a gear's) is seen as a line, not a point.
    let (mut view, up) = super::deform::slanted_camera(mesh);
    for (c, u) in view.iter_mut().zip(up) {
        *c -= 0.5 * u;
    }
    let text = PreviewText {
        title,
        notes,
        output_groups: Some(groups),
        marks,
        panel_names: Some(["model".into(), String::new()]),
        panel_captions: [
            None,
            Some(if det.report.groups.is_empty() {
                "no symmetry found within the tolerance".into()
            } else {
                "global group: mirror planes (orange), axes (green); partial groups (pink, #: annotation entry)"
                    .into()
            }),
        ],
        shared_frame: true,
    };
    plot_retarget_preview(mesh, &overlay, view, up, &text, png)?;
    Ok(())
}
