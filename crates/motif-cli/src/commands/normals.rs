//! `motif normals`: oriented normals for point clouds (and meshes).

use std::time::Instant;

use anyhow::Context;

use motif_core::TriMesh;
use motif_core::normals::{NormalsOptions, Orientation, estimate_normals_detailed};
use serde::Serialize;

use crate::cli::{GlobalArgs, NormalsArgs, OrientationArg};
use crate::output::{bad_input, maybe_json, ms_since};

#[derive(Debug, Serialize)]
struct NormalsReport {
    input: String,
    output: String,
    points: usize,
    method: &'static str,
    neighbours: usize,
    orientation: String,
    /// Points with no determined normal: on a point cloud, those whose neighbours coincide or
    /// lie on one line (their normal is arbitrary); on a mesh, vertices on no face of non-zero
    /// area (written as 0, 0, 0).
    undetermined: usize,
    ms: f64,
}

pub fn run(a: NormalsArgs, g: &GlobalArgs) -> anyhow::Result<()> {
    crate::output::check_outputs(&[Some(a.output()), a.json.json.as_deref()], &[&a.input], g.force)?;
    crate::output::check_output_formats(&[(Some(a.output()), crate::output::OutputKind::PointCloud)])?;
    let mut model = super::read_model(&a.input)?;
    let t = Instant::now();
    let orientation = match a.orientation {
        OrientationArg::Consistent => Orientation::Consistent,
        OrientationArg::None => Orientation::Unoriented,
        OrientationArg::Viewpoint => match a.viewpoint.as_deref() {
            Some([x, y, z]) => Orientation::TowardsViewpoint([*x, *y, *z]),
            _ => return Err(bad_input("--orientation viewpoint needs --viewpoint X,Y,Z")),
        },
    };
    if a.k < 3 {
        return Err(bad_input(format!("-k {}: a plane fit needs at least 3 neighbours", a.k)));
    }
    if a.k > 1000 {
        return Err(bad_input(format!("-k {}: use at most 1000 neighbours (the default is 16)", a.k)));
    }
    if let Some(v) = a.viewpoint.as_deref().filter(|v| v.iter().any(|c| !c.is_finite())) {
        return Err(bad_input(format!("--viewpoint {v:?}: the viewpoint must be finite")));
    }
    if a.viewpoint.is_some() && !matches!(a.orientation, OrientationArg::Viewpoint) {
        super::warn("--viewpoint is used with --orientation viewpoint only; it is ignored here");
    }
    let use_mesh = model.is_mesh() && !a.from_points;
    // Options that only point clouds use are said to be ignored, not silently dropped.
    let point_options: Vec<&str> = [
        (a.k != crate::cli::NORMALS_K, "-k"),
        (!matches!(a.orientation, OrientationArg::Consistent), "--orientation"),
        (a.viewpoint.is_some(), "--viewpoint"),
    ]
    .into_iter()
    .filter_map(|(given, flag)| given.then_some(flag))
    .collect();
    if use_mesh && !point_options.is_empty() {
        super::warn(format!(
            "{}: a mesh's normals come from its faces; {} {} to point clouds and {} ignored \
             (--from-points estimates them from the vertices instead)",
            a.input.display(),
            point_options.join(", "),
            if point_options.len() == 1 { "applies" } else { "apply" },
            if point_options.len() == 1 { "is" } else { "are" },
        ));
    }
    let (normals, undetermined) = if use_mesh {
        let normals =
            TriMesh { positions: model.vertices.positions.clone(), triangles: model.triangles.clone() }
                .vertex_normals();
        // Vertices on no face of any area have no normal (written as 0, 0, 0).
        let zero = normals.iter().filter(|n| n.iter().all(|c| *c == 0.0)).count();
        if zero > 0 {
            super::warn(format!(
                "{}: {zero} of {} vertices lie on no face of non-zero area: their normals are written as \
                 (0, 0, 0)",
                a.input.display(),
                normals.len()
            ));
        }
        (normals, zero)
    } else {
        let opts = NormalsOptions { neighbours: a.k, orientation, ..Default::default() };
        let est = crate::progress::Bar::new(g.quiet)
            .spin("normals", || estimate_normals_detailed(&model.vertices.positions, &opts))
            .with_context(|| a.input.display().to_string())?;
        if est.undetermined > 0 {
            super::warn(format!(
                "{}: {} of {} points have {} nearest neighbours that coincide or lie on one line; \
                 their normals are arbitrary (duplicate points, or a scan line: try a larger -k)",
                a.input.display(),
                est.undetermined,
                model.vertices.len(),
                a.k
            ));
        }
        (est.normals, est.undetermined)
    };
    model.vertices.normals = Some(normals);
    let ms = ms_since(t);
    super::write_model(a.output(), &model, &[&a.input], g, &a.encoding)?;
    let r = NormalsReport {
        input: a.input.display().to_string(),
        output: a.output().display().to_string(),
        points: model.vertices.len(),
        method: if use_mesh { "area-weighted face normals" } else { "PCA over k neighbours" },
        neighbours: a.k,
        orientation: match orientation {
            Orientation::Consistent => "consistent".to_string(),
            Orientation::TowardsViewpoint(p) => format!("towards [{}, {}, {}]", p[0], p[1], p[2]),
            Orientation::Unoriented => "none".to_string(),
        },
        undetermined,
        ms,
    };
    if !crate::output::json_on_stdout(&a.json.json) {
        super::written(g, &r.output, format!("{} normals, {}, {:.1} ms", r.points, r.method, r.ms));
    }
    maybe_json(&a.json.json, &r)
}
