//! `motif info`: what a file holds.

use motif_core::geometry::format_length;
use std::time::Instant;

use motif_core::TriMesh;
use serde::Serialize;

use crate::cli::{GlobalArgs, InfoArgs};
use crate::output::{maybe_json, ms_since};

#[derive(Debug, Serialize)]
struct InfoReport {
    file: String,
    format: String,
    kind: &'static str,
    vertices: usize,
    faces_in_file: usize,
    triangles: usize,
    bbox_min: Option<[f64; 3]>,
    bbox_max: Option<[f64; 3]>,
    diagonal: f64,
    surface_area: f64,
    components: usize,
    isolated_vertices: usize,
    edges: usize,
    boundary_edges: usize,
    non_manifold_edges: usize,
    misoriented_edges: usize,
    degenerate_triangles: usize,
    has_normals: bool,
    has_colors: bool,
    attributes: Vec<String>,
    warnings: Vec<String>,
    load_ms: f64,
}

pub fn run(a: InfoArgs, _g: &GlobalArgs) -> anyhow::Result<()> {
    crate::output::check_outputs(&[a.json.json.as_deref()], &[&a.input], _g.force)?;
    let t = Instant::now();
    let model = super::read_model(&a.input)?;
    let load_ms = ms_since(t);
    let mesh = TriMesh { positions: model.vertices.positions.clone(), triangles: model.triangles.clone() };
    let bbox = mesh.aabb();
    let comps = mesh.components();
    let edges = mesh.edge_stats();
    let r = InfoReport {
        file: a.input.display().to_string(),
        format: model.format.extension().to_string(),
        kind: if model.is_mesh() { "mesh" } else { "point cloud" },
        vertices: mesh.num_vertices(),
        faces_in_file: model.source_faces,
        triangles: mesh.num_triangles(),
        bbox_min: bbox.map(|b| b.min),
        bbox_max: bbox.map(|b| b.max),
        diagonal: mesh.diagonal(),
        surface_area: mesh.area(),
        components: comps.count,
        isolated_vertices: comps.isolated_vertices,
        edges: edges.edges,
        boundary_edges: edges.boundary,
        non_manifold_edges: edges.non_manifold,
        misoriented_edges: edges.misoriented,
        degenerate_triangles: mesh.degenerate_triangles(),
        has_normals: model.vertices.normals.is_some(),
        has_colors: model.vertices.colors.is_some(),
        attributes: model.vertices.attributes.iter().map(|x| x.name.clone()).collect(),
        warnings: model.warnings.clone(),
        load_ms,
    };
    // A report written to a file leaves the text on stdout; one on stdout replaces it.
    maybe_json(&a.json.json, &r)?;
    if crate::output::json_on_stdout(&a.json.json) {
        return Ok(());
    }
    println!("{}", r.file);
    println!("  format       {} ({})", r.format, r.kind);
    println!("  vertices     {}", r.vertices);
    if model.is_mesh() {
        println!(
            "  faces        {} in file, {}",
            r.faces_in_file,
            crate::output::count(r.triangles, "triangle", "triangles")
        );
    }
    // Lengths at the model's scale (a model 1e-9 across would print as zeros with 6 decimals).
    let len = |x: f64| format_length(x, r.diagonal, 6);
    if let (Some(lo), Some(hi)) = (r.bbox_min, r.bbox_max) {
        println!(
            "  bbox         [{}, {}, {}] .. [{}, {}, {}]",
            len(lo[0]),
            len(lo[1]),
            len(lo[2]),
            len(hi[0]),
            len(hi[1]),
            len(hi[2])
        );
        println!("  diagonal     {}", len(r.diagonal));
    }
    if model.is_mesh() {
        println!("  area         {}", format_length(r.surface_area, r.diagonal * r.diagonal, 6));
        println!(
            "  components   {}{}",
            r.components,
            if r.isolated_vertices > 0 {
                format!(" (+{} isolated vertices)", r.isolated_vertices)
            } else {
                String::new()
            }
        );
        println!(
            "  edges        {} ({} boundary, {} non-manifold, {} misoriented)",
            r.edges, r.boundary_edges, r.non_manifold_edges, r.misoriented_edges
        );
        // Closed means watertight, as trimesh and libigl use it: no boundary edge, and every
        // edge between exactly two triangles.
        let closed = match (r.boundary_edges, r.non_manifold_edges) {
            (0, 0) => "closed",
            (0, _) => "without boundary but not closed (non-manifold edges)",
            _ => "open",
        };
        let winding =
            if r.misoriented_edges == 0 { "consistently oriented" } else { "not consistently oriented" };
        println!("  surface      {closed}, {winding}");
        println!("  degenerate   {}", crate::output::count(r.degenerate_triangles, "triangle", "triangles"));
    }
    let mut extras = Vec::new();
    if r.has_normals {
        extras.push("normals".to_string());
    }
    if r.has_colors {
        extras.push("colours".to_string());
    }
    extras.extend(r.attributes.iter().cloned());
    if !extras.is_empty() {
        println!("  per vertex   {}", extras.join(", "));
    }
    for w in &r.warnings {
        println!("  warning      {w}");
    }
    println!("  loaded in    {:.1} ms", r.load_ms);
    Ok(())
}
