//! `motif deform`: symmetry-preserving handle editing (thesis chapter 3), one-shot from files.

use std::time::Instant;

use anyhow::Context;

use motif_core::io::{Model, WriteOptions};
use motif_core::procedural::SymmetryAnnotation;
use motif_deform::annotation::read_annotation;
use motif_deform::residual::{ResidualReport, SymmetryMaps};
use motif_deform::session::{AnnotationValidation, DeformOptions, DeformStats, HandleFit, SymmetryMode};
use motif_deform::symmetric_sampling::SampleSpacing;
use motif_deform::{DeformSession, HandlesFile};
use serde::Serialize;

use crate::cli::{DeformArgs, GlobalArgs};
use crate::output::{bad_input, check_outputs, maybe_json, ms_since};

/// Median and 95th percentile of a list of milliseconds.
#[derive(Debug, Clone, Copy, Serialize, Default)]
pub struct Spread {
    pub median: f64,
    pub p95: f64,
}

pub fn spread(v: &[f64]) -> Spread {
    if v.is_empty() {
        return Spread::default();
    }
    let mut s = v.to_vec();
    s.sort_by(|a, b| a.total_cmp(b));
    let at = |q: f64| s[((s.len() - 1) as f64 * q).round() as usize];
    Spread { median: at(0.5), p95: at(0.95) }
}

#[derive(Debug, Serialize)]
struct DeformReport {
    mesh: String,
    symmetry: Option<String>,
    handles: String,
    output: String,
    options: DeformOptions,
    vertices: usize,
    triangles: usize,
    symmetries: usize,
    samples: usize,
    dof: usize,
    frames: usize,
    prefactor_ms: f64,
    solve_ms: Spread,
    lift_ms: Spread,
    frame_ms: Spread,
    symmetry_residual: Option<ResidualReport>,
    handle_fit: Vec<HandleFit>,
    /// Per handle, the largest distance of its vertices from their target in the last frame,
    /// relative to the diagonal (the handles constrain samples; the vertices follow the lifting).
    handle_vertex_fit: Vec<f64>,
    stats: DeformStats,
    warnings: Vec<String>,
    total_ms: f64,
}

pub fn run(a: DeformArgs, g: &GlobalArgs) -> anyhow::Result<()> {
    let inputs: Vec<&std::path::Path> =
        [Some(a.mesh.as_path()), a.symmetry.as_deref(), Some(a.handles.as_path())]
            .into_iter()
            .flatten()
            .collect();
    check_outputs(&[Some(&a.output), a.preview.as_deref(), a.json.json.as_deref()], &inputs, g.force)?;
    crate::output::check_output_formats(&[
        (Some(&a.output), crate::output::OutputKind::Model),
        (a.preview.as_deref(), crate::output::OutputKind::Png),
    ])?;
    let t0 = Instant::now();
    let model = super::read_model(&a.mesh)?;
    for w in &model.warnings {
        super::warn(format!("{}: {w}", a.mesh.display()));
    }
    // The vertices keep their colours and attributes through the deformation (one to one); normals,
    // when the input has them, are computed anew on the deformed surface.
    let vertex_data = {
        let v = &model.vertices;
        (v.normals.is_some() || v.colors.is_some() || !v.attributes.is_empty())
            .then(|| (v.normals.is_some(), v.colors.clone(), v.attributes.clone()))
    };
    if vertex_data.is_some() {
        if let Ok(format) = motif_core::io::Format::from_path(&a.output) {
            for l in motif_core::io::lost_in(format, &model.vertices) {
                super::warn(format!("{}: {l} could not be written", a.output.display()));
            }
        }
    }
    let mesh = motif_core::io::read_mesh_from(model, &a.mesh)?;
    let annotation = match &a.symmetry {
        Some(p) => read_annotation(p)?,
        None if a.no_symmetry => SymmetryAnnotation {
            format: motif_core::procedural::SYMMETRY_FORMAT.to_string(),
            tolerance: motif_core::procedural::DEFAULT_SYMMETRY_TOLERANCE,
            symmetries: Vec::new(),
        },
        None => return Err(bad_input("give --symmetry ANNOT (or --no-symmetry to deform without one)")),
    };
    let handles = HandlesFile::read(&a.handles)?;
    let mut options = DeformOptions {
        symmetry: if a.no_symmetry { SymmetryMode::Ignore } else { SymmetryMode::Preserve },
        validation: if g.force { AnnotationValidation::Force } else { AnnotationValidation::Strict },
        ..Default::default()
    };
    options.sampling.seed = g.seed;
    match (a.radius, a.samples) {
        (Some(r), _) if !(r > 0.0 && r < 1.0) => {
            return Err(bad_input(format!("--radius {r}: a fraction of the diagonal in (0, 1)")));
        }
        (Some(r), _) => options.sampling.spacing = SampleSpacing::Radius(r),
        (None, Some(0)) => return Err(bad_input("--samples 0: ask for at least one sample")),
        (None, Some(n)) => options.sampling.spacing = SampleSpacing::Count(n),
        (None, None) => {}
    }
    if let Some(alpha) = a.alpha {
        if !(alpha > 0.0 && alpha.is_finite()) {
            return Err(bad_input(format!("--alpha {alpha}: must be positive")));
        }
        options.editing.alpha = alpha;
    }
    if let Some(it) = a.iterations {
        options.editing.iterations = it;
    }

    let bar = crate::progress::Bar::new(g.quiet);
    let mut session = bar
        .spin("precompute", || DeformSession::new(&mesh, &annotation, &options))
        .map_err(with_flag_names)
        .with_context(|| match &a.symmetry {
            Some(s) => format!("{} with {}", a.mesh.display(), s.display()),
            None => a.mesh.display().to_string(),
        })?;
    let alpha = options.editing.alpha;
    session
        .set_handles(&handles.handles)
        .map_err(|e| match e {
            // The library's advice names its own options; say it with this command's flag.
            motif_deform::DeformError::Factorization(m) => anyhow::anyhow!(
                "factorisation of the reduced system (eq. 3.4) failed: {m}; the system is singular or badly \
                 scaled: try a smaller --alpha (this run {alpha:e}, default {:e})",
                motif_deform::EditingOptions::default().alpha
            ),
            e => e.into(),
        })
        .with_context(|| a.handles.display().to_string())?;
    let prefactor_ms = session.stats().timings.prefactor_ms;
    let frames: Vec<Vec<[[f64; 4]; 4]>> =
        if handles.frames.is_empty() { vec![handles.transforms()] } else { handles.frames.clone() };
    let (mut solve, mut lift, mut frame) = (Vec::new(), Vec::new(), Vec::new());
    // The handle sample farthest from its target over all frames: (error, handle, frame).
    let mut worst_fit: Option<(f64, usize, usize)> = None;
    for (i, f) in frames.iter().enumerate() {
        if f.len() != handles.handles.len() {
            return Err(bad_input(format!(
                "{}: frame {i} has {} transforms for {} handles",
                a.handles.display(),
                f.len(),
                handles.handles.len()
            )));
        }
        let t = Instant::now();
        session.solve(f).with_context(|| format!("{}: frame {i}", a.handles.display()))?;
        frame.push(ms_since(t));
        for fit in session.handle_fit() {
            if worst_fit.is_none_or(|(e, _, _)| fit.max_error > e) {
                worst_fit = Some((fit.max_error, fit.handle, i));
            }
        }
        solve.push(session.stats().timings.solve_ms);
        lift.push(session.stats().timings.lift_ms);
    }
    let positions = session.positions().to_vec();
    if positions.iter().any(|p| !motif_core::geometry::is_finite(*p)) {
        anyhow::bail!(
            "{}: the deformation produced non-finite positions; nothing was written",
            a.mesh.display()
        );
    }
    // The residual is measured against the annotation even with --no-symmetry: that contrast is
    // what the symmetric basis buys.
    let residual = if annotation.symmetries.is_empty() {
        None
    } else {
        Some(SymmetryMaps::new(&mesh, &annotation)?.residual(&positions)?)
    };
    let out_mesh = motif_core::TriMesh { positions, triangles: mesh.triangles.clone() };
    let mut out_model = Model::from_mesh(&out_mesh);
    if let Some((normals, colors, attributes)) = &vertex_data {
        let v = &mut out_model.vertices;
        v.normals = normals.then(|| out_mesh.vertex_normals());
        v.colors = colors.clone();
        v.attributes = attributes.clone();
    }
    motif_core::io::write(&a.output, &out_model, &WriteOptions::default())?;
    if let Some(png) = &a.preview {
        let last = frames.last().map(|f| f.as_slice()).unwrap_or_default();
        let mut notes = vec![(
            match &residual {
                Some(r) => {
                    format!("symmetry residual {:.1e} of the diagonal (rest shape {:.1e})", r.max, r.rest_max)
                }
                None => "no symmetry annotation".to_string(),
            },
            false,
        )];
        let worst = session.handle_fit().iter().map(|f| f.max_error).fold(0.0, f64::max);
        notes.push((
            format!("handles within {worst:.1e} of the diagonal of their targets"),
            worst > HANDLE_FIT_WARNING,
        ));
        let title = format!(
            "{}: rest (left) and deformed (right){}",
            a.mesh.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default(),
            if a.no_symmetry {
                ", symmetry ignored"
            } else if annotation.symmetries.is_empty() {
                ", no symmetry annotated"
            } else {
                ", every annotated symmetry kept"
            }
        );
        draw_preview(&mesh, &out_mesh, &handles.handles, last, title, notes, png)?;
        super::note(g, format!("wrote {}", png.display()));
    }

    // The basis keeps the displacement symmetric; the residual is the rest shape's plus what the
    // lifting adds. Over the annotation's tolerance `symmetry check` fails the output: said here,
    // not left for the check to find.
    let over_tolerance =
        residual.as_ref().filter(|r| !a.no_symmetry && r.max > annotation.tolerance).map(|r| {
            format!(
                "the output's symmetry residual ({:.2e} of the diagonal) is above the annotation's \
             tolerance ({:.0e}; the rest shape's is {:.2e}): `motif symmetry check` will fail the \
             output against it",
                r.max, annotation.tolerance, r.rest_max
            )
        });
    let stats = session.stats().clone();
    let report = DeformReport {
        mesh: a.mesh.display().to_string(),
        symmetry: a.symmetry.as_ref().map(|p| p.display().to_string()),
        handles: a.handles.display().to_string(),
        output: a.output.display().to_string(),
        options: options.clone(),
        vertices: mesh.num_vertices(),
        triangles: mesh.num_triangles(),
        symmetries: annotation.symmetries.len(),
        samples: stats.samples,
        dof: stats.dof,
        frames: frames.len(),
        prefactor_ms,
        solve_ms: spread(&solve),
        lift_ms: spread(&lift),
        frame_ms: spread(&frame),
        symmetry_residual: residual,
        handle_fit: session.handle_fit().to_vec(),
        handle_vertex_fit: session.handle_vertex_fit(frames.last().map(|f| f.as_slice()).unwrap_or_default()),
        warnings: {
            let mut w = session.warnings().to_vec();
            if let Some((e, h, i)) = worst_fit.filter(|&(e, _, _)| e > HANDLE_FIT_WARNING) {
                w.push(format!(
                    "handle {h} ended {:.1}% of the diagonal from its target (frame {i}): the handles ask \
                     for a motion the symmetries do not allow, or one the symmetries allow only by \
                     stretching the shape, or pull against each other; the symmetries were kept \
                     (--no-symmetry follows the handles instead)",
                    100.0 * e
                ));
            }
            w.extend(over_tolerance);
            w
        },
        stats,
        total_ms: ms_since(t0),
    };
    // Results print under --quiet too; warnings always; only the "wrote" note is quiet.
    if !crate::output::json_on_stdout(&a.json.json) {
        println!(
            "{} vertices, {}, {} samples, {} DoF{}",
            report.vertices,
            crate::output::count(report.symmetries, "symmetry", "symmetries"),
            report.samples,
            report.dof,
            if a.no_symmetry { " (symmetry ignored)" } else { "" }
        );
        println!(
            "prefactor {:.1} ms; per frame ({}): solve {:.2} ms, lift {:.2} ms, total {:.2} ms median",
            report.prefactor_ms,
            crate::output::count(report.frames, "frame", "frames"),
            report.solve_ms.median,
            report.lift_ms.median,
            report.frame_ms.median
        );
        // Eq. 3.2: each vertex's image against the vertex it maps to, which `symmetry check`
        // (vertex to surface) and `symmetry detect` (samples to surface) do not measure alike.
        if let Some(r) = &report.symmetry_residual {
            println!(
                "symmetry residual {:.2e} of the diagonal (rest shape {:.2e}; eq. 3.2, each vertex's image against its matched vertex)",
                r.max, r.rest_max
            );
        }
        let worst = report.handle_fit.iter().map(|f| f.max_error).fold(0.0, f64::max);
        let worst_vertex = report.handle_vertex_fit.iter().copied().fold(0.0, f64::max);
        println!(
            "handle fit: largest sample error {worst:.2e}, largest vertex error {worst_vertex:.2e} of the diagonal"
        );
    }
    for w in &report.warnings {
        super::warn(w);
    }
    super::note(g, format!("wrote {}", report.output));
    maybe_json(&a.json.json, &report)
}

/// A handle sample farther than this from its target (relative to the diagonal) is warned about:
/// handles are soft constraints, but a handle that follows its drag ends within 10⁻⁴ of it (the
/// chair's and the windmill's example drags with their own annotations reach 2·10⁻⁶, the fan's
/// 2·10⁻³), while one the symmetries forbid lags by a large share of the drag. The gear's example
/// drag (D17h: a pull on one tooth is a pull on all, which stretches the ring) ends 2.2% short.
const HANDLE_FIT_WARNING: f64 = 0.01;

/// An invalid option named as the library names it (`editing.iterations`) becomes the flag the
/// user typed (`--iterations`).
fn with_flag_names(e: motif_deform::DeformError) -> anyhow::Error {
    if let motif_deform::DeformError::InvalidOption { name, message } = &e {
        let flag = match *name {
            "editing.alpha" => Some("--alpha"),
            "editing.iterations" => Some("--iterations"),
            "sampling.spacing" => Some("--radius / --samples"),
            _ => None,
        };
        if let Some(flag) = flag {
            return bad_input(format!("{flag}: {message}"));
        }
    }
    if matches!(e, motif_deform::DeformError::SymmetryMismatch { .. }) {
        return bad_input(format!("{e}; or pass --force to deform on the approximate symmetry"));
    }
    e.into()
}

/// The picture of `--preview`: rest and deformed shapes side by side (the renderer of
/// `motif retarget --preview`), seen along the rest shape's thinnest box axis at a slant, with Y
/// up (Z when Y is the thin axis), each handle marked at the centre of its vertices: grey when
/// fixed, red with an arrow from where it was to where the last frame asks it to go, and blue
/// where it went when that is more than 1% of the diagonal short of its target.
#[allow(clippy::too_many_arguments)]
fn draw_preview(
    rest: &motif_core::TriMesh,
    deformed: &motif_core::TriMesh,
    handles: &[motif_deform::Handle],
    transforms: &[[[f64; 4]; 4]],
    title: String,
    notes: Vec<(String, bool)>,
    png: &std::path::Path,
) -> anyhow::Result<()> {
    use motif_core::geometry::{IDENTITY4, dist, transform_point};
    use motif_retarget::plot::{PreviewMark, PreviewText, plot_retarget_preview};
    let Some(bbox) = rest.aabb() else { return Ok(()) };
    let (view, up) = slanted_camera(rest);
    let diag = bbox.diagonal();
    let centre = |m: &motif_core::TriMesh, idx: &[usize]| {
        let mut c = [0.0; 3];
        for &i in idx {
            for (k, ck) in c.iter_mut().enumerate() {
                *ck += m.positions[i][k] / idx.len() as f64;
            }
        }
        c
    };
    let (grey, red, blue) = ([90, 90, 90], [200, 40, 40], [30, 110, 200]);
    let mut marks = Vec::new();
    for (i, h) in handles.iter().enumerate() {
        let idx = h.region.vertex_indices(rest, 1e-9 * diag);
        if idx.is_empty() {
            continue;
        }
        let at = centre(rest, &idx);
        let m = transforms.get(i).copied().unwrap_or(IDENTITY4);
        let target = transform_point(&m, at);
        let mark = |panel, at, from, label: String, colour| PreviewMark { panel, at, from, label, colour };
        if dist(target, at) <= 1e-9 * diag {
            marks.push(mark(0, at, None, format!("handle {i} (fixed)"), grey));
            // A fixed handle the symmetries pull away (the handles are soft) says so.
            let reached = centre(deformed, &idx);
            if dist(reached, at) > 0.01 * diag {
                marks.push(mark(1, at, None, format!("handle {i} (fixed)"), grey));
                marks.push(mark(1, reached, Some(at), format!("handle {i} moved"), blue));
            } else {
                marks.push(mark(1, at, None, format!("handle {i} (fixed)"), grey));
            }
            continue;
        }
        marks.push(mark(0, at, None, format!("handle {i}"), red));
        let reached = centre(deformed, &idx);
        if dist(reached, target) > 0.01 * diag {
            marks.push(mark(1, target, Some(at), format!("handle {i} target"), red));
            marks.push(mark(1, reached, None, format!("handle {i} reached"), blue));
        } else {
            marks.push(mark(1, target, Some(at), format!("handle {i}, target reached"), red));
        }
    }
    let text = PreviewText {
        title,
        notes,
        marks,
        panel_names: Some(["rest".into(), "deformed".into()]),
        shared_frame: true,
        ..Default::default()
    };
    plot_retarget_preview(rest, deformed, view, up, &text, png)?;
    Ok(())
}

/// The camera of the `--preview` and `symmetry detect --plot` pictures: along the bounding box's
/// thinnest axis at a slant (as the demo shows the windmill), Y up (Z when Y is the thin axis).
pub(crate) fn slanted_camera(mesh: &motif_core::TriMesh) -> ([f64; 3], [f64; 3]) {
    let e = mesh.aabb().map_or([1.0; 3], |b| b.extent());
    let thin = (0..3).min_by(|&i, &j| e[i].total_cmp(&e[j]).then(i.cmp(&j))).unwrap_or(2);
    let up_axis = if thin == 1 { 2 } else { 1 };
    let right_axis = 3 - thin - up_axis;
    let mut view = [0.0; 3];
    view[thin] = -1.0;
    view[up_axis] = -0.25;
    view[right_axis] = -0.4;
    let mut up = [0.0; 3];
    up[up_axis] = 1.0;
    (view, up)
}
