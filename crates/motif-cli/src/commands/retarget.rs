//! `motif retarget`: structure-aware resizing (thesis chapter 4): principal offsets, then the
//! voxel MRF over the offset label space solved by alpha-expansion, then stitching.

use std::time::Instant;

use anyhow::Context;
use motif_core::TriMesh;
use motif_core::geometry::Point3;
use motif_core::geometry::{dot, normalize};
use motif_core::io::{Model, WriteOptions};
use motif_core::point_cloud::PointCloud;
use motif_retarget::offsets::{
    OffsetAnalysis, OffsetOptions, Repetition, analyze_features, prepare_features,
};
use motif_retarget::retarget::{
    RetargetError, RetargetMethod, RetargetOptions, RetargetReport, RetargetSession, TriangleAssignment,
    carry_vertex_data, orient_offsets,
};
use serde::Serialize;

use crate::cli::{AssignmentArg, GlobalArgs, RetargetArgs, RetargetMethodArg, SizeArg};
use crate::output::{bad_input, check_outputs, count, maybe_json, ms_since};
use crate::progress::Bar;

#[derive(Debug, Serialize)]
struct Report<'a> {
    mesh: String,
    output: String,
    /// What the user asked for, as given on the command line.
    request: Request,
    /// The output's bounding-box size, to compare with `request.target_size`.
    output_size: Option<[f64; 3]>,
    steps: [i32; 3],
    principal_offsets: Vec<[f64; 3]>,
    offsets: &'a OffsetAnalysis,
    retarget: Option<RetargetReport>,
    plain_resize: Option<[f64; 3]>,
    /// When the stitching has seams of infinite cost: the nearby steps that stitch without any
    /// (see [`RetargetSession::clean_alternatives`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    clean_alternatives: Option<Vec<[i32; 3]>>,
    /// Edge counts of the input and the output (boundary, non-manifold, misoriented), as
    /// `motif info` gives them; absent for a plain resize, which keeps the input's.
    #[serde(skip_serializing_if = "Option::is_none")]
    edges: Option<EdgesReport>,
    /// The input's per-vertex data carried onto the output, when it has any.
    #[serde(skip_serializing_if = "Option::is_none")]
    vertex_data: Option<VertexDataReport>,
    analysis_ms: f64,
    total_ms: f64,
}

/// What the output's vertices carry of the input's (`carry_vertex_data`).
#[derive(Debug, Serialize)]
struct VertexDataReport {
    /// What was carried: `normals`, `colours` and attribute names.
    carried: Vec<String>,
    /// Output vertices that lie on the input surface (interpolated there).
    interpolated: usize,
    /// Output vertices capping added, which took their neighbours' data.
    from_neighbours: usize,
}

#[derive(Debug, Serialize)]
struct EdgesReport {
    input: motif_core::mesh::EdgeStats,
    output: motif_core::mesh::EdgeStats,
}

/// The command line's request, for the report.
#[derive(Debug, Serialize)]
struct Request {
    steps: Option<Vec<i32>>,
    target_size: Option<Vec<SizeArg>>,
    method: &'static str,
    offsets: Option<String>,
    assignment: &'static str,
    caps: bool,
    fill: bool,
    plain_resize: bool,
    seed: u64,
}

impl Request {
    fn of(a: &RetargetArgs, g: &GlobalArgs) -> Self {
        Request {
            steps: a.steps.clone(),
            target_size: a.target_size.clone(),
            method: match a.method {
                RetargetMethodArg::Offsets => "offsets",
                RetargetMethodArg::Dense => "dense",
            },
            offsets: a.offsets.clone(),
            assignment: match a.assignment {
                AssignmentArg::Centroid => "centroid",
                AssignmentArg::Cut => "cut",
            },
            caps: !a.no_caps,
            fill: !a.no_fill,
            plain_resize: a.plain_resize,
            seed: g.seed,
        }
    }
}

/// The size of `mesh`'s bounding box.
fn size_of(mesh: &TriMesh) -> Option<[f64; 3]> {
    mesh.aabb().map(|b| b.extent())
}

/// Parses `--offsets`: one to three finite, non-zero, linearly independent vectors X,Y,Z
/// separated by ';'.
fn parse_offsets(text: &str) -> anyhow::Result<Vec<[f64; 3]>> {
    use motif_core::geometry::{cross, norm};
    let mut out: Vec<[f64; 3]> = Vec::new();
    for (k, part) in text.split(';').enumerate() {
        let v: Vec<f64> =
            part.split(',').map(|x| x.trim().parse::<f64>()).collect::<Result<_, _>>().map_err(|_| {
                bad_input(format!("--offsets: vector {} ('{part}') is not three numbers X,Y,Z", k + 1))
            })?;
        let [x, y, z] = v[..] else {
            return Err(bad_input(format!(
                "--offsets: vector {} ('{part}') needs three numbers X,Y,Z",
                k + 1
            )));
        };
        let o = [x, y, z];
        if !o.iter().all(|c| c.is_finite()) || norm(o) == 0.0 {
            return Err(bad_input(format!(
                "--offsets: vector {} ('{part}') must be finite and non-zero",
                k + 1
            )));
        }
        out.push(o);
    }
    if out.len() > 3 {
        return Err(bad_input(format!("--offsets takes one to three vectors, got {}", out.len())));
    }
    // Independence: the vectors span as many dimensions as there are (relative tolerance).
    let unit: Vec<[f64; 3]> = out.iter().map(|v| normalize(*v).unwrap_or([0.0; 3])).collect();
    let independent = match unit[..] {
        [a, b] => norm(cross(a, b)) > 1e-3,
        [a, b, c] => dot(cross(a, b), c).abs() > 1e-3,
        _ => true,
    };
    if !independent {
        return Err(bad_input(
            "--offsets: the vectors must be linearly independent (no two parallel, three not in one plane)",
        ));
    }
    Ok(out)
}

/// Extent of the vertices along a unit direction.
fn extent_along(mesh: &TriMesh, d: [f64; 3]) -> f64 {
    let (lo, hi) = mesh.positions.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
        let t = dot(*p, d);
        (lo.min(t), hi.max(t))
    });
    hi - lo
}

/// What `--preview` writes above a retargeting: the method and the figures of thesis Fig. 4.8,
/// a warning when seams have infinite cost, and each output triangle's copy (its voxel's step
/// vector, numbered in order of first use with "copied in place" first) to colour it by.
pub(crate) fn preview_text(
    title: String,
    res: &motif_retarget::retarget::Retargeted,
) -> motif_retarget::plot::PreviewText {
    let r = &res.report;
    let mut copies: Vec<[i32; 3]> = vec![[0, 0, 0]];
    let groups: Vec<u32> = res
        .triangle_voxels
        .iter()
        .map(|&v| {
            let k = res.voxel_labels[v as usize];
            match copies.iter().position(|c| *c == k) {
                Some(i) => i as u32,
                None => {
                    copies.push(k);
                    (copies.len() - 1) as u32
                }
            }
        })
        .collect();
    let method = match r.method {
        RetargetMethod::Offsets => "the detected offsets",
        RetargetMethod::Dense => "the dense baseline (regular offsets)",
    };
    let mut notes = vec![(
        format!(
            "with {method}: {} nodes, {} labels, energy {:.4}, graph cut {:.1} ms; colours: the copy each part came from (blue: in place)",
            r.nodes, r.labels, r.energy, r.graph_cut_ms
        ),
        false,
    )];
    if r.infinite_seams > 0 {
        notes.push((
            format!(
                "warning: at {} of {} seams one copy meets empty space in another (energy +inf); {}",
                r.infinite_seams,
                r.seams,
                if r.output_boundary_edges == 0 {
                    "the openings there were capped".to_string()
                } else {
                    format!("{} open boundary edges are left", r.output_boundary_edges)
                }
            ),
            true,
        ));
    }
    motif_retarget::plot::PreviewText { title, notes, output_groups: Some(groups), ..Default::default() }
}

/// The preview camera: a three-quarter view (about 25° off the normal, so that recesses and
/// depth show under the headlight) of the plane of the first two principal offsets, up along the
/// second; with one offset, of the plane holding it and the bounding box's longest other axis.
pub(crate) fn preview_camera(mesh: &TriMesh, principal: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
    use motif_core::geometry::cross;
    let e = mesh.aabb().map_or([1.0; 3], |b| b.extent());
    let (a, b) = match principal {
        [a, b, ..] => (*a, *b),
        [a] => {
            let mut axes = [0usize, 1, 2];
            axes.sort_by(|&i, &j| (e[j] * (1.0 - a[j].abs())).total_cmp(&(e[i] * (1.0 - a[i].abs()))));
            let mut b = [0.0; 3];
            b[axes[0]] = 1.0;
            (*a, b)
        }
        [] => ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
    };
    let (Some(n), Some(ua), Some(ub)) = (normalize(cross(a, b)), normalize(a), normalize(b)) else {
        return ([0.0, 0.0, -1.0], [0.0, 1.0, 0.0]);
    };
    let view = normalize([0, 1, 2].map(|k| -n[k] + 0.35 * ua[k] + 0.3 * ub[k])).unwrap_or(n);
    (view, ub)
}

pub fn run(a: RetargetArgs, g: &GlobalArgs) -> anyhow::Result<()> {
    let t0 = Instant::now();
    check_outputs(&[Some(&a.output), a.preview.as_deref(), a.json.json.as_deref()], &[&a.mesh], g.force)?;
    crate::output::check_output_formats(&[
        (Some(&a.output), crate::output::OutputKind::Model),
        (a.preview.as_deref(), crate::output::OutputKind::Png),
    ])?;
    let (mesh, vertex_data) = read_mesh_and_vertex_data(&a.mesh, &a.output)?;
    let given = a.offsets.as_deref().map(parse_offsets).transpose()?;
    // A given offset at least as long as the model along it shifts copies clear of each other:
    // nothing overlaps to stitch, and the "copies" come out as separate models.
    if let Some(offsets) = &given {
        for (k, v) in offsets.iter().enumerate() {
            let u = normalize(*v).unwrap_or([1.0, 0.0, 0.0]);
            let (len, extent) = (motif_core::geometry::norm(*v), extent_along(&mesh, u));
            if len >= extent {
                return Err(bad_input(format!(
                    "--offsets: vector {} is {} long, but {} measures only {} along it: shifted copies \
                     would not overlap (give the pitch of the repetition, in model units)",
                    k + 1,
                    motif_core::geometry::format_length(len, extent.max(len), 6),
                    a.mesh.display(),
                    motif_core::geometry::format_length(extent, extent.max(len), 6)
                )));
            }
        }
    }
    // `-` keeps an axis's size: the extent the size checks below measure the model by.
    let model_size = mesh.surface_aabb().or_else(|| mesh.aabb()).map_or([0.0; 3], |b| b.extent());
    let target = match &a.target_size {
        Some(v) if v.len() == 3 && v.iter().all(|x| x.0.is_none_or(|x| x > 0.0 && x.is_finite())) => {
            Some([0, 1, 2].map(|k| v[k].0.unwrap_or(model_size[k])))
        }
        Some(_) => {
            return Err(bad_input(
                "--target-size needs three sizes X,Y,Z, each positive, or - to keep the model's size along that axis",
            ));
        }
        None => None,
    };
    let bar = Bar::new(g.quiet);
    // Offset detection; its SHOT features are reused by the MRF's pairwise term (thesis 4.2.2).
    let offset_options = OffsetOptions { seed: g.seed, ..Default::default() };
    let in_mesh = || a.mesh.display().to_string();
    let features = prepare_features(&mesh, &offset_options, &bar).with_context(in_mesh)?;
    let analysis = analyze_features(&features, &offset_options, &bar).with_context(in_mesh)?;
    let analysis_ms = ms_since(t0);
    // Copies are added at the +v end of each offset: orient them so growth goes along +x/+y/+z.
    // `solver_offsets` are in the analysis's order of selection, the order the session solves
    // with; the user sees and counts steps in `principal`, by model axis (`axis_order`), so that
    // `--steps U,V,W` grows the model the same way in any unit.
    let solver_offsets: Vec<[f64; 3]> = match &given {
        Some(v) => orient_offsets(v),
        None => orient_offsets(&analysis.principal.iter().map(|p| p.offset_model).collect::<Vec<_>>()),
    };
    let order: Vec<usize> = match &given {
        Some(_) => (0..solver_offsets.len()).collect(),
        None => analysis.axis_order.clone(),
    };
    let principal: Vec<[f64; 3]> = order.iter().map(|&i| solver_offsets[i]).collect();
    // Steps counted along `principal` ↔ steps along `solver_offsets`.
    let to_solver = |s: [i32; 3]| {
        let mut out = s;
        for (k, &i) in order.iter().enumerate() {
            out[i] = s[k];
        }
        out
    };
    let to_user = |s: [i32; 3]| {
        let mut out = s;
        for (k, &i) in order.iter().enumerate() {
            out[k] = s[i];
        }
        out
    };

    if given.is_none() && (analysis.repetition.kind == Repetition::NoRepetition || principal.is_empty()) {
        let evidence = format!(
            "{}: {} (see `motif offsets {} --plot PNG`)",
            a.mesh.display(),
            analysis.repetition.summary,
            a.mesh.display()
        );
        let (true, Some(size)) = (a.plain_resize, target) else {
            if a.plain_resize {
                return Err(bad_input(format!(
                    "{evidence}; --plain-resize scales to a size: give it with --target-size X,Y,Z (steps count cells, which a plain resize has none of)"
                )));
            }
            return Err(bad_input(format!(
                "{evidence}; pass --plain-resize with --target-size to scale it instead, or --offsets X,Y,Z to retarget along a pitch you know"
            )));
        };
        let bb = mesh.aabb().ok_or_else(|| bad_input("empty mesh"))?;
        let e = bb.extent();
        let s = [0, 1, 2].map(|k| if e[k] > 0.0 { size[k] / e[k] } else { 1.0 });
        let out = TriMesh {
            positions: mesh
                .positions
                .iter()
                .map(|p| [0, 1, 2].map(|k| bb.min[k] + (p[k] - bb.min[k]) * s[k]))
                .collect(),
            triangles: mesh.triangles.clone(),
        };
        let model = match &vertex_data {
            Some(data) => Model {
                vertices: scaled_vertex_data(data, out.positions.clone(), s),
                ..Model::from_mesh(&out)
            },
            None => Model::from_mesh(&out),
        };
        motif_core::io::write(&a.output, &model, &WriteOptions::default())?;
        if let Some(p) = &a.preview {
            let (view, up) = preview_camera(&mesh, &[]);
            let text = motif_retarget::plot::PreviewText {
                title: format!("{}: plain resize (no repetition to follow)", a.mesh.display()),
                notes: vec![("every part is stretched by the same factor per axis".to_string(), false)],
                ..Default::default()
            };
            motif_retarget::plot::plot_retarget_preview(&mesh, &out, view, up, &text, p)?;
        }
        // A flat model cannot be given a size along its zero extent: say so, not "as asked".
        let flat: Vec<String> = (0..3)
            .filter(|&k| e[k] <= 0.0)
            .map(|k| format!("{} (asked {})", ["x", "y", "z"][k], size[k]))
            .collect();
        // The scale factors are the result (printed under --quiet too, on stdout as every result
        // is); "wrote" is a note.
        let factor = |f: f64| if (1e-3..1e4).contains(&f) { format!("{f:.4}") } else { format!("{f:.4e}") };
        let result = format!(
            "{evidence}; scaled by {} x {} x {} (--plain-resize){}",
            factor(s[0]),
            factor(s[1]),
            factor(s[2]),
            if flat.is_empty() { " as asked".to_string() } else { String::new() }
        );
        // With the JSON report on stdout, stdout is the report alone.
        if crate::output::json_on_stdout(&a.json.json) {
            eprintln!("{result}");
        } else {
            println!("{result}");
        }
        if !g.quiet {
            eprintln!("wrote {}", a.output.display());
            if let Some(p) = &a.preview {
                eprintln!("wrote {}", p.display());
            }
        }
        if !flat.is_empty() {
            eprintln!(
                "warning: {}: the model is flat along {}: a plain resize cannot give it a size there, which stays 0",
                a.mesh.display(),
                flat.join(", ")
            );
        }
        let report = Report {
            mesh: a.mesh.display().to_string(),
            output: a.output.display().to_string(),
            request: Request::of(&a, g),
            output_size: size_of(&out),
            steps: [0; 3],
            principal_offsets: principal,
            offsets: &analysis,
            retarget: None,
            plain_resize: Some(s),
            clean_alternatives: None,
            edges: None,
            vertex_data: vertex_data.as_ref().map(|d| VertexDataReport {
                carried: vertex_data_names(d),
                interpolated: out.positions.len(),
                from_neighbours: 0,
            }),
            analysis_ms,
            total_ms: ms_since(t0),
        };
        return maybe_json(&a.json.json, &report);
    }

    let steps: [i32; 3] = match (&a.steps, target) {
        (Some(v), _) => {
            if v.is_empty() || v.len() > 3 {
                return Err(bad_input("--steps takes one to three integers U,V,W"));
            }
            let mut s = [0; 3];
            s[..v.len()].copy_from_slice(v);
            if let Some(k) = (principal.len()..3).find(|&k| s[k] != 0) {
                return Err(bad_input(format!(
                    "--steps: direction {k} has no principal offset ({} only)",
                    if a.offsets.is_some() {
                        format!("--offsets gives {}", count(principal.len(), "direction", "directions"))
                    } else {
                        format!(
                            "the model repeats along {}",
                            count(principal.len(), "direction", "directions")
                        )
                    }
                )));
            }
            s
        }
        (None, Some(size)) => {
            let mut s = [0; 3];
            // The model is about extent / |o| cells long along each offset.
            let mut cells = Vec::with_capacity(principal.len());
            for (k, o) in principal.iter().enumerate() {
                let len = o.iter().map(|x| x * x).sum::<f64>().sqrt();
                let d = normalize(*o).unwrap_or([1.0, 0.0, 0.0]);
                let want: f64 = (0..3).map(|i| d[i].abs() * size[i]).sum();
                let extent = extent_along(&mesh, d);
                cells.push((extent / len).round() as i32);
                let steps = ((want - extent) / len).round();
                // Beyond any grid the limits allow (10⁶ voxels): said in the user's terms
                // rather than as a step count saturated at 2³¹ − 1.
                if steps.abs() > 1e6 {
                    return Err(bad_input(format!(
                        "--target-size: {want} along principal offset {k} would take {steps:.0} cells of {} model units; \
                         that is not a size a model can be resized to",
                        motif_core::geometry::format_length(len, len, 6)
                    )));
                }
                s[k] = steps as i32;
            }
            // The estimate above treats each offset alone; on a sheared grid a step along one
            // offset also widens the box along another axis (`--target-size 3,-,-` on the sheared
            // shelf chose +2,+1 and made it 1.5 high instead of keeping 1.13). One step along `o`
            // grows the box by |o| per axis, so the whole steps near the estimate are scored by
            // the distance of the size they give to the size asked ('-' asks for the model's own).
            // No shrink below one cell that the estimate did not itself ask for.
            s = nearest_steps(&principal, &cells, model_size, size, s);
            // Offsets across the model's axes: each axis's size mixes cells of several offsets,
            // and the closest box can trade the cells of one for another's (a turned shelf asked
            // wider with its height kept grew +4 columns and lost 2 of its 3 rows). Said, with the
            // way to choose the cells instead.
            let slanted = principal.iter().any(|o| {
                let n = motif_core::geometry::norm(*o);
                n > 0.0 && o.iter().all(|x| x.abs() / n < 8f64.to_radians().cos())
            });
            if slanted {
                super::note(
                    g,
                    format!(
                        "--target-size: {} has principal offsets across its axes, so the size asked per axis is \
                         met by its bounding box, here with steps {}; --steps U,V,W chooses the cells directly",
                        a.mesh.display(),
                        s[..principal.len()].iter().map(|x| format!("{x:+}")).collect::<Vec<_>>().join(",")
                    ),
                );
            }
            // An axis that no offset reaches (no offset has 5% of its length along it) keeps
            // its size: asking for another one there is refused, as --steps along a direction
            // without an offset is, instead of being ignored. Axes an offset reaches come as
            // close as whole steps allow (on a sheared grid, growth along one offset also moves
            // another axis a little, so no tolerance is checked there).
            let bbox = mesh
                .surface_aabb()
                .or_else(|| mesh.aabb())
                .unwrap_or(motif_core::Aabb { min: [0.0; 3], max: [0.0; 3] });
            let diagonal = bbox.diagonal();
            let unreachable: Vec<String> = (0..3)
                .filter_map(|i| {
                    let reached =
                        principal.iter().any(|o| o[i].abs() > 0.05 * motif_core::geometry::norm(*o));
                    let extent = bbox.max[i] - bbox.min[i];
                    let slack = 0.01 * extent + 1e-6 * diagonal;
                    (!reached && (extent - size[i]).abs() > slack).then(|| {
                        let len = |x: f64| motif_core::geometry::format_length(x, diagonal, 4);
                        format!("{} = {} (it stays {})", ["x", "y", "z"][i], size[i], len(extent))
                    })
                })
                .collect();
            if !unreachable.is_empty() {
                return Err(bad_input(format!(
                    "--target-size: {} repeats along {} principal offset(s) only (`motif offsets {}` lists \
                     them), and none of them reaches {}: ask there for the size the model has",
                    a.mesh.display(),
                    principal.len(),
                    a.mesh.display(),
                    unreachable.join(", ")
                )));
            }
            s
        }
        (None, None) => return Err(bad_input("give --steps U,V,W or --target-size X,Y,Z")),
    };
    let options = RetargetOptions {
        method: match a.method {
            RetargetMethodArg::Offsets => RetargetMethod::Offsets,
            RetargetMethodArg::Dense => RetargetMethod::Dense,
        },
        seed: g.seed,
        force: g.force,
        assignment: match a.assignment {
            AssignmentArg::Centroid => TriangleAssignment::Centroid,
            AssignmentArg::Cut => TriangleAssignment::Cut,
        },
        cap_openings: !a.no_caps,
        fill_holes: !a.no_fill,
        ..Default::default()
    };
    let mut session = RetargetSession::with_features(&mesh, &features, &solver_offsets, &options, &bar)
        .with_context(in_mesh)?;
    // The session numbers its directions in the order it solves with; the user counts steps by
    // model axis (`order`), so a shrink error names the entry of `--steps` the user typed.
    let in_user_order = |e: RetargetError| match e {
        RetargetError::ShrinkBelowOneCell {
            direction,
            steps,
            input_voxels,
            output_voxels,
            minimum,
            min_steps,
        } => RetargetError::ShrinkBelowOneCell {
            direction: order.iter().position(|&i| i == direction).unwrap_or(direction),
            steps,
            input_voxels,
            output_voxels,
            minimum,
            min_steps,
        },
        e => e,
    };
    let res = match session.retarget(to_solver(steps), &bar).map_err(in_user_order) {
        Ok(res) => res,
        // A size the user asked for, in the steps it was turned into (the error speaks of
        // steps, which the user never gave).
        Err(e) if a.steps.is_none() => {
            let size = a.target_size.as_deref().unwrap_or_default();
            let show = |v: Vec<String>| v.join(",");
            return Err(anyhow::Error::from(e)
                .context(format!(
                    "--target-size {} means --steps {} along the principal offsets (`motif offsets {}` lists them)",
                    show(size.iter().map(|x| x.0.map_or("-".to_string(), |x| x.to_string())).collect()),
                    show(steps[..principal.len()].iter().map(|x| x.to_string()).collect()),
                    a.mesh.display()
                ))
                .context(in_mesh()));
        }
        Err(e) => return Err(anyhow::Error::from(e).context(in_mesh())),
    };
    let alternatives = (res.report.infinite_seams > 0)
        .then(|| session.clean_alternatives(to_solver(steps)).into_iter().map(to_user).collect::<Vec<_>>());
    // The input's normals, colours and attributes, carried onto the copies (`carry_vertex_data`).
    let carried = vertex_data.as_ref().map(|data| {
        let origins = session.vertex_origins(&res);
        let cloud = carry_vertex_data(data, &mesh.triangles, &res.mesh, &origins);
        let interpolated = origins.iter().filter(|o| o.is_some()).count();
        let report = VertexDataReport {
            carried: vertex_data_names(data),
            interpolated,
            from_neighbours: origins.len() - interpolated,
        };
        (cloud, report)
    });
    let model = match &carried {
        Some((cloud, _)) => Model { vertices: cloud.clone(), ..Model::from_mesh(&res.mesh) },
        None => Model::from_mesh(&res.mesh),
    };
    motif_core::io::write(&a.output, &model, &WriteOptions::default())?;
    if let Some(p) = &a.preview {
        let (view, up) = preview_camera(&mesh, &principal);
        let shown: Vec<String> =
            steps[..principal.len().clamp(1, 3)].iter().map(|s| format!("{s:+}")).collect();
        let title = format!("{}: steps {}", a.mesh.display(), shown.join(" "));
        let mut text = preview_text(title, &res);
        if a.offsets.is_some() && res.report.method == RetargetMethod::Offsets {
            text.notes[0].0 =
                text.notes[0].0.replacen("the detected offsets", "the offsets given (--offsets)", 1);
        }
        motif_retarget::plot::plot_retarget_preview(&mesh, &res.mesh, view, up, &text, p)?;
    }
    let r = &res.report;
    // Results print under --quiet too (only the "wrote" notes are quiet), and the warning
    // always does; a JSON report on stdout replaces the text.
    let input_edges = mesh.edge_stats();
    let input_boundary = input_edges.boundary;
    if !crate::output::json_on_stdout(&a.json.json) {
        for (k, o) in principal.iter().enumerate() {
            let len = |x: f64| motif_core::geometry::format_length(x, motif_core::geometry::norm(*o), 6);
            println!("offset {k}: [{}, {}, {}]  steps {:+}", len(o[0]), len(o[1]), len(o[2]), steps[k]);
        }
        println!(
            "MRF ({}): {} nodes, {}, energy {:.4} ({}), graph cut {:.1} ms, total {:.1} ms",
            r.method.as_str(),
            r.nodes,
            count(r.labels, "label", "labels"),
            r.energy,
            count(r.cycles, "cycle", "cycles"),
            r.graph_cut_ms,
            r.total_ms
        );
        println!(
            "output: {} vertices, {}, {} (input {} / {})",
            r.output_vertices,
            count(r.output_triangles, "triangle", "triangles"),
            count(r.output_components, "component", "components"),
            mesh.num_vertices(),
            mesh.num_triangles()
        );
        // Whole steps come as close to a target size as the pitch allows: say how close.
        if let (Some(want), Some(got)) = (target, size_of(&res.mesh)) {
            let d = mesh.aabb().map_or(1.0, |b| b.diagonal());
            let len = |x: f64| motif_core::geometry::format_length(x, d, 4);
            println!(
                "size: {} (asked {}; whole steps of the offsets)",
                got.map(len).join(" x "),
                want.map(len).join(" x ")
            );
        }
        if r.capped_loops + r.filled_holes + r.output_boundary_edges > 0 {
            let kept = if r.kept_open > 0 {
                format!(
                    "; {} {} along the input's own open boundary kept open",
                    r.kept_open,
                    if r.kept_open == 1 { "opening" } else { "openings" }
                )
            } else {
                String::new()
            };
            println!(
                "closing: {} capped ({}), {} filled ({}), {} left (input {}){kept}",
                count(r.capped_loops, "opening", "openings"),
                count(r.cap_triangles, "triangle", "triangles"),
                count(r.filled_holes, "hole", "holes"),
                count(r.fill_triangles, "triangle", "triangles"),
                count(r.output_boundary_edges, "boundary edge", "boundary edges"),
                input_boundary
            );
        }
        if r.reoriented_triangles > 0 {
            println!(
                "orientation: {} turned to agree with the surface around them",
                count(r.reoriented_triangles, "triangle", "triangles")
            );
        }
    }
    // Edges whose two triangles run the same way: seams where copies meet turned against each
    // other, which repair did not resolve (a viewer shades them inside out). Said, not hidden.
    let output_edges = res.mesh.edge_stats();
    let (in_mis, out_mis) = (input_edges.misoriented, output_edges.misoriented);
    // Edges of more than two triangles: where two copies' sections touch along a voxel edge,
    // the output has an edge of four, as a Boolean union of two solids touching along an edge
    // has (docs/retarget.md). No boundary, but not watertight as trimesh counts it: said.
    if output_edges.non_manifold > input_edges.non_manifold {
        println!(
            "non-manifold: {} (input {}; `motif info` counts them)",
            count(
                output_edges.non_manifold,
                "edge of more than two triangles",
                "edges of more than two triangles"
            ),
            input_edges.non_manifold
        );
    }
    if out_mis > in_mis {
        super::warn(format!(
            "the output has {out_mis} misoriented edges (the input has {in_mis}): at some seams the copies' \
             triangles meet with opposite orientations (`motif info` counts them)"
        ));
    }
    // Open edges a closed input did not have, where no seam of infinite cost explains them (that
    // warning, below, speaks of the openings itself): copying whole triangles by centroid
    // leaves gaps along the seams, which capping and filling do not always close.
    if input_boundary == 0 && r.output_boundary_edges > 0 && r.infinite_seams == 0 {
        super::warn(format!(
            "the output has {} although the input is closed{}",
            count(r.output_boundary_edges, "open boundary edge", "open boundary edges"),
            if matches!(a.assignment, AssignmentArg::Centroid) {
                ": --assignment centroid copies whole triangles, which leave gaps along the seams; \
                 the default, --assignment cut, cuts them at the voxel faces and closes them"
            } else {
                " (`motif info` lists them)"
            }
        ));
    }
    if r.infinite_seams > 0 {
        let dims = principal.len().clamp(1, 3);
        let others = match alternatives.as_deref() {
            Some([]) | None => "Steps along one offset near these do not stitch cleanly either".to_string(),
            Some(list) => {
                let names: Vec<String> = list
                    .iter()
                    .map(|s| {
                        format!(
                            "--steps {}",
                            s[..dims].iter().map(i32::to_string).collect::<Vec<_>>().join(",")
                        )
                    })
                    .collect();
                let verb = if names.len() == 1 { "stitches" } else { "stitch" };
                format!("{} {verb} cleanly", names.join(" and "))
            }
        };
        eprintln!(
            "warning: no seam-consistent stitching was found for these steps (energy +inf): at {} of \
                 {} seams one copy's geometry meets empty space in another copy (an empty voxel of the \
                 input, or beyond its end when the input is only a few cells long along a grown \
                 direction); {}. {others}; --preview PNG shows the result",
            r.infinite_seams,
            r.seams,
            motif_retarget::retarget::open_edges_after(r.output_boundary_edges, input_boundary)
        );
    }
    if !g.quiet {
        eprintln!("wrote {}", a.output.display());
        if let Some(p) = &a.preview {
            eprintln!("wrote {}", p.display());
        }
    }
    let report = Report {
        mesh: a.mesh.display().to_string(),
        output: a.output.display().to_string(),
        request: Request::of(&a, g),
        output_size: size_of(&res.mesh),
        steps,
        principal_offsets: principal.clone(),
        offsets: &analysis,
        retarget: Some(res.report.clone()),
        plain_resize: None,
        clean_alternatives: alternatives,
        edges: Some(EdgesReport { input: input_edges, output: output_edges }),
        vertex_data: carried.map(|(_, r)| r),
        analysis_ms,
        total_ms: ms_since(t0),
    };
    maybe_json(&a.json.json, &report)
}

/// The whole steps along each of `principal` whose predicted box size,
/// `model_size + Σₖ sₖ |oₖ|` per axis, is closest to `size` (Euclidean, model units): from
/// `start` (the per-offset estimate), a descent over the steps one away on any offsets (all
/// 3^m − 1 of them) while the size comes closer, then the closest within 3 of where it stopped.
/// The descent finds steps the estimate's neighbourhood does not hold: on a shelf turned 30°
/// about z and 20° about x, `--target-size 3000,-,-` (wider, the rest kept) was estimated
/// +2,+3 along the slanted offsets, and the window of 3 about it held no shrink along the second
/// offset, which the kept height needs. Ties (within 10⁻⁹ of the size asked, squared) go to
/// fewer steps in all, then to the lexicographically smaller step vector, so the choice is
/// deterministic. Along offset k no candidate keeps fewer than one of the model's `cells[k]`
/// cells unless `start` already does (the session refuses it, in the user's terms, for the
/// steps the estimate gave).
fn nearest_steps(
    principal: &[[f64; 3]],
    cells: &[i32],
    model_size: [f64; 3],
    size: [f64; 3],
    start: [i32; 3],
) -> [i32; 3] {
    let m = principal.len().min(3);
    let predicted = |s: [i32; 3]| {
        let mut out = model_size;
        for (k, o) in principal.iter().take(m).enumerate() {
            for i in 0..3 {
                out[i] += s[k] as f64 * o[i].abs();
            }
        }
        out
    };
    let error = |s: [i32; 3]| {
        let p = predicted(s);
        (0..3).map(|i| (p[i] - size[i]).powi(2)).sum::<f64>()
    };
    let floor = |k: usize| start[k].min(1 - cells.get(k).copied().unwrap_or(1));
    let tie = 1e-9 * size.iter().map(|x| x * x).sum::<f64>().max(f64::MIN_POSITIVE);
    let key = |s: [i32; 3]| (error(s), s.iter().map(|x| x.unsigned_abs()).sum::<u32>(), s);
    let better = |a: &(f64, u32, [i32; 3]), b: &(f64, u32, [i32; 3])| {
        a.0 < b.0 - tie || ((a.0 - b.0).abs() <= tie && (a.1, a.2) < (b.1, b.2))
    };
    // Every step vector within `radius` of `centre` on the offsets (none beyond the m offsets),
    // none below a floor.
    let around = |centre: [i32; 3], radius: i32| {
        let range = |k: usize| {
            if k < m {
                centre[k].saturating_sub(radius).max(floor(k))..=centre[k].saturating_add(radius)
            } else {
                0..=0
            }
        };
        let mut out = Vec::new();
        for a in range(0) {
            for b in range(1) {
                for c in range(2) {
                    out.push([a, b, c]);
                }
            }
        }
        out
    };
    let closest = |candidates: Vec<[i32; 3]>, from: [i32; 3]| {
        let mut best = (from, key(from));
        for s in candidates {
            let k = key(s);
            if better(&k, &best.1) {
                best = (s, k);
            }
        }
        best.0
    };
    // The size is a convex quadratic in the steps: the descent ends at a local minimum of the
    // integer grid, a few steps from the continuous one. Bounded, as steps beyond 10⁶ are
    // refused before this.
    let mut at = start;
    for _ in 0..10_000 {
        let next = closest(around(at, 1), at);
        if next == at {
            break;
        }
        at = next;
    }
    closest(around(at, 3), at)
}

/// Reads the mesh to retarget, with the reader's warnings (ignored texture coordinates,
/// materials), and its per-vertex data (normals, colours, named attributes) when it has any: the
/// output carries them ([`carry_vertex_data`]). A warning names what the output's format cannot
/// hold of them (STL holds no vertex colours, only PLY holds named attributes).
fn read_mesh_and_vertex_data(
    path: &std::path::Path,
    output: &std::path::Path,
) -> anyhow::Result<(TriMesh, Option<PointCloud>)> {
    let model = super::read_model(path)?;
    for w in &model.warnings {
        super::warn(format!("{}: {w}", path.display()));
    }
    let v = &model.vertices;
    let has_data = v.normals.is_some() || v.colors.is_some() || !v.attributes.is_empty();
    if model.is_mesh() && has_data {
        if let Ok(format) = motif_core::io::Format::from_path(output) {
            for l in motif_core::io::lost_in(format, v) {
                super::warn(format!("{}: {l} could not be written", output.display()));
            }
        }
    }
    let data = (model.is_mesh() && has_data).then(|| PointCloud {
        positions: Vec::new(),
        normals: v.normals.clone(),
        colors: v.colors.clone(),
        attributes: v.attributes.clone(),
    });
    Ok((motif_core::io::read_mesh_from(model, path)?, data))
}

/// Names of what `data` holds per vertex, for the report.
fn vertex_data_names(data: &PointCloud) -> Vec<String> {
    let mut names = Vec::new();
    if data.normals.is_some() {
        names.push("normals".to_string());
    }
    if data.colors.is_some() {
        names.push("colours".to_string());
    }
    names.extend(data.attributes.iter().map(|a| a.name.clone()));
    names
}

/// The plain resize of per-vertex data: colours and attributes unchanged, normals transformed
/// as normals are under the scaling `s` (by its inverse) and renormalised.
fn scaled_vertex_data(data: &PointCloud, positions: Vec<Point3>, s: [f64; 3]) -> PointCloud {
    let normals = data.normals.as_ref().map(|ns| {
        ns.iter()
            .map(|n| {
                let m = [0, 1, 2].map(|k| if s[k] != 0.0 { n[k] / s[k] } else { n[k] });
                normalize(m).unwrap_or(*n)
            })
            .collect()
    });
    PointCloud { positions, normals, colors: data.colors.clone(), attributes: data.attributes.clone() }
}

#[cfg(test)]
mod tests {
    use super::nearest_steps;

    /// The sheared shelf: a step along the slanted offset also widens the model.
    #[test]
    fn steps_are_chosen_for_the_whole_size() {
        let principal = [[0.42, 0.0, 0.0], [0.15, 0.37, 0.0]];
        let model = [2.158, 1.13, 0.3];
        // Per-offset estimates +2, +1 grow the height the '-' asked to keep.
        assert_eq!(nearest_steps(&principal, &[4, 3], model, [3.0, 1.13, 0.3], [2, 1, 0]), [2, 0, 0]);
        // Both sizes asked: the closest pair.
        assert_eq!(nearest_steps(&principal, &[4, 3], model, [2.5, 1.5, 0.3], [1, 1, 0]), [0, 1, 0]);
    }

    /// A shelf turned 30° about z and 20° about x (cells of 420 and 370 model units), asked to be
    /// 3000 wide and keep its height and depth: the per-offset estimate +2,+3 grows every axis;
    /// the closest size shrinks along the second offset. Checked against every step vector in a
    /// wide box.
    #[test]
    fn steps_far_from_the_estimate_are_found() {
        let principal = [[363.73, 197.34, 71.82], [-185.0, 301.11, 109.59]];
        let model = [2037.24, 1820.94, 907.33];
        let size = [3000.0, 1820.94, 907.33];
        let got = nearest_steps(&principal, &[5, 4], model, size, [2, 3, 0]);
        let error = |s: [i32; 3]| {
            (0..3)
                .map(|i| {
                    let p = model[i] + (0..2).map(|k| s[k] as f64 * principal[k][i].abs()).sum::<f64>();
                    (p - size[i]).powi(2)
                })
                .sum::<f64>()
        };
        let best = (-4..=10)
            .flat_map(|a| (-3..=10).map(move |b| [a, b, 0]))
            .min_by(|a, b| error(*a).total_cmp(&error(*b)));
        assert_eq!(Some(got), best);
        assert!(got[1] < 0, "{got:?}");
    }

    /// No candidate shrinks below one cell unless the estimate did: a 3-cell row asked to be half
    /// a cell long stays at the estimate's −2, not −3 (no cell left).
    #[test]
    fn no_shrink_below_one_cell() {
        let principal = [[1.0, 0.0, 0.0]];
        assert_eq!(nearest_steps(&principal, &[3], [3.0, 1.0, 1.0], [0.5, 1.0, 1.0], [-2, 0, 0]), [-2, 0, 0]);
        // An estimate that already leaves no cell is kept, for the session to refuse in its terms.
        assert_eq!(nearest_steps(&principal, &[3], [3.0, 1.0, 1.0], [0.1, 1.0, 1.0], [-3, 0, 0]), [-3, 0, 0]);
    }
}
