//! `motif example`: procedural shapes with known structure.

use std::path::Path;
use std::time::Instant;

use motif_core::io::Model;
use motif_core::procedural;
use motif_detect::scenes::{Difficulty, SceneKind, SceneOptions, generate_scene, scene_names};

use crate::cli::{DifficultyArg, ExampleArgs, GlobalArgs};
use crate::output::{bad_input, check_outputs, write_json};

pub fn run(a: ExampleArgs, g: &GlobalArgs) -> anyhow::Result<()> {
    if a.list {
        // `--list` takes nothing else: `example --list shelf` read as a list request ignored
        // the name without a word.
        if a.name.is_some() || a.output().is_some() {
            return Err(bad_input("--list takes no name or output: `motif example --list`"));
        }
        for name in procedural::names() {
            println!("{name}");
        }
        for name in scene_names() {
            println!("{name}");
        }
        return Ok(());
    }
    let (Some(name), Some(output)) = (a.name.clone(), a.output().map(|p| p.to_path_buf())) else {
        return Err(bad_input("usage: motif example NAME OUT (or motif example --list)"));
    };
    // The shapes are named with '_' (shelf_sheared) and the scenes with '-' (scene-facade); either
    // spelling finds either.
    let name = [name.replace('-', "_"), name.replace('_', "-")]
        .into_iter()
        .find(|n| procedural::names().contains(&n.as_str()) || SceneKind::from_name(n).is_some())
        .unwrap_or(name);
    if let Some(kind) = SceneKind::from_name(&name) {
        return run_scene(kind, &output, &a, g);
    }
    if !procedural::names().contains(&name.as_str()) {
        let all: Vec<&str> =
            procedural::names().iter().copied().chain(scene_names().iter().copied()).collect();
        return Err(bad_input(format!("unknown example {name:?}; valid names: {}", all.join(", "))));
    }
    if a.gt.is_some() || a.difficulty.is_some() || a.points.is_some() || !a.parts.is_empty() {
        return Err(bad_input(format!(
            "--gt, --difficulty, --points and --parts apply to the benchmark scenes ({}), not to {name}",
            scene_names().join(", ")
        )));
    }
    check_outputs(
        &[Some(&output), a.structure.as_deref(), a.annotation.as_deref(), a.handles.as_deref()],
        &[],
        g.force,
    )?;
    crate::output::check_output_formats(&[(Some(&output), crate::output::OutputKind::Model)])?;
    let ex = procedural::generate(&name, g.seed)?;
    let model = Model::from_mesh(&ex.mesh);
    super::write_model(&output, &model, &[], g, &a.encoding)?;
    if let Some(s) = &a.structure {
        write_json(s, &ex.structure)?;
    }
    if let Some(p) = &a.annotation {
        write_json(p, &ex.structure.symmetry)?;
    }
    if let Some(p) = &a.handles {
        let text = sample_drag(&ex.mesh, &ex.structure.symmetry).to_json();
        motif_core::io::write_atomic(p, |w| w.write_all(text.as_bytes()))?;
    }
    super::written(
        g,
        output.display(),
        format!(
            "{}: {} vertices, {} triangles{}",
            ex.name,
            ex.mesh.num_vertices(),
            ex.mesh.num_triangles(),
            a.structure.as_ref().map(|s| format!("; structure in {}", s.display())).unwrap_or_default()
        ),
    );
    for p in [&a.structure, &a.annotation, &a.handles].into_iter().flatten() {
        super::note(g, format!("wrote {}", p.display()));
    }
    Ok(())
}

/// One end of the longest bounding-box axis fixed, the other end lifted along the shortest axis by
/// up to 15% of the diagonal over 30 frames (spheres of 5% of the diagonal, or twice the spacing
/// of `motif deform`'s default samples when that is wider, so that each holds samples: on the
/// gear 5% was narrower than the spacing and deform refused the handles).
///
/// When an element of the shape's own symmetry groups maps the lifted end onto the fixed one (the
/// fan's and the gear's opposite blade tips and teeth), the symmetries forbid that drag: the two
/// ends must move alike, and `motif deform` ended 7.5% and 17.5% of the diagonal off target. The
/// fixed handle is then the part nearest the centre (the hub, the bore), and the end is pulled
/// outward from it, so that it takes its copies along, as the symmetries ask.
fn sample_drag(
    mesh: &motif_core::TriMesh,
    annotation: &motif_core::procedural::SymmetryAnnotation,
) -> motif_deform::HandlesFile {
    use motif_core::procedural::{Region, translation};
    use motif_deform::{Handle, HandlesFile};
    let bb = mesh.aabb().unwrap_or(motif_core::Aabb { min: [0.0; 3], max: [1.0; 3] });
    let e = bb.extent();
    let long = (0..3).max_by(|&i, &j| e[i].total_cmp(&e[j])).unwrap_or(0);
    let short = (0..3).min_by(|&i, &j| e[i].total_cmp(&e[j])).unwrap_or(2);
    let end = |sign: f64| {
        mesh.positions
            .iter()
            .copied()
            .max_by(|p, q| (sign * p[long]).total_cmp(&(sign * q[long])))
            .unwrap_or(bb.center())
    };
    use motif_deform::symmetric_sampling::{DEFAULT_SAMPLE_COUNT, radius_for_count};
    let spacing = radius_for_count(mesh.area(), DEFAULT_SAMPLE_COUNT);
    let r = (0.05 * bb.diagonal()).max(2.0 * spacing);
    let (lifted, far) = (end(1.0), end(-1.0));
    let diagonal = bb.diagonal();
    let ends_are_copies = annotation.symmetries.iter().any(|sym| match &sym.kind {
        motif_core::procedural::SymmetryKind::Group { generators, .. } => {
            motif_deform::annotation::group_closure(&sym.name, generators, diagonal, annotation.tolerance)
                .is_ok_and(|group| {
                    group.iter().any(|m| {
                        motif_core::geometry::dist(motif_core::geometry::transform_point(m, lifted), far) < r
                    })
                })
        }
        motif_core::procedural::SymmetryKind::Instances { .. } => false,
    });
    let fixed = if ends_are_copies {
        let c = bb.center();
        mesh.positions
            .iter()
            .copied()
            .min_by(|p, q| motif_core::geometry::dist2(*p, c).total_cmp(&motif_core::geometry::dist2(*q, c)))
            .unwrap_or(c)
    } else {
        far
    };
    let handles = vec![
        Handle::fixed(Region::Sphere { center: fixed, radius: r }),
        Handle::fixed(Region::Sphere { center: lifted, radius: r }),
    ];
    let mut file = HandlesFile::new(handles);
    // Lifted along the shortest axis; or, when the end's copies must follow, pulled outward from
    // the centre, which every rotation about it and every mirror through it carries to the
    // copies' own outward pulls (a lift along the gear's axis is undone by its mirror across its
    // middle plane: the drag ended 20% of the diagonal short).
    let direction = if ends_are_copies {
        motif_core::geometry::normalize(motif_core::geometry::sub(lifted, fixed)).unwrap_or([0.0; 3])
    } else {
        let mut d = [0.0; 3];
        d[short] = 1.0;
        d
    };
    // An outward pull stretches the part between the fixed centre and the pulled end (a gear
    // with mirrors across and along its axis has no motion its symmetries allow that does not):
    // a third of the lift, 5% of the diagonal.
    let reach = if ends_are_copies { 0.05 } else { 0.15 };
    file.frames = (1..=30)
        .map(|f| {
            let t = motif_core::geometry::scale(direction, reach * bb.diagonal() * f as f64 / 30.0);
            vec![motif_core::geometry::IDENTITY4, translation(t)]
        })
        .collect();
    file
}

/// `motif example scene-... OUT.ply [--gt GT.json]`: a benchmark point cloud with normals and its
/// building-block ground truth.
fn run_scene(kind: SceneKind, output: &Path, a: &ExampleArgs, g: &GlobalArgs) -> anyhow::Result<()> {
    if a.structure.is_some() || a.annotation.is_some() || a.handles.is_some() {
        return Err(bad_input(format!(
            "{}: --structure, --annotation and --handles are for the shapes; a scene writes its ground truth with --gt",
            kind.name()
        )));
    }
    let difficulty = match a.difficulty.unwrap_or_default() {
        DifficultyArg::Easy => Difficulty::Easy,
        DifficultyArg::Medium => Difficulty::Medium,
        DifficultyArg::Hard => Difficulty::Hard,
    };
    let options = SceneOptions {
        difficulty,
        points: a.points.unwrap_or(SceneOptions::default().points),
        seed: g.seed,
        parts: a.parts.clone(),
        ..Default::default()
    };
    let parts: Vec<&Path> = a.parts.iter().map(|p| p.as_path()).collect();
    check_outputs(&[Some(output), a.gt.as_deref()], &parts, g.force)?;
    crate::output::check_output_formats(&[(Some(output), crate::output::OutputKind::PointCloud)])?;
    let t = Instant::now();
    let mut scene = generate_scene(kind, &options)?;
    let seconds = t.elapsed().as_secs_f64();
    scene.ground_truth.scene =
        output.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_else(|| kind.name().into());
    let (n, classes, instances) =
        (scene.cloud.len(), scene.ground_truth.classes.len(), scene.ground_truth.instance_count());
    let model = Model::from_point_cloud(scene.cloud);
    super::write_model(output, &model, &parts, g, &a.encoding)?;
    if let Some(gt) = &a.gt {
        write_json(gt, &scene.ground_truth)?;
    }
    let hidden = match scene.stats.hidden_instances {
        0 => String::new(),
        h => format!(" ({h} more hidden from the scanners, not annotated)"),
    };
    super::written(
        g,
        output.display(),
        format!(
            "{}, {}: {n} points, {classes} classes, {instances} instances{hidden}, noise {:.1} mm, {:.0}% of the surface visible; {seconds:.2} s{}",
            kind.name(),
            difficulty.name(),
            1000.0 * scene.stats.noise_sigma,
            100.0 * scene.stats.visible_fraction,
            a.gt.as_ref().map(|p| format!("; ground truth in {}", p.display())).unwrap_or_default()
        ),
    );
    Ok(())
}
