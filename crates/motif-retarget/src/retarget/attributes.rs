//! Per-vertex data of the input (normals, colours, scalar attributes) carried onto a
//! retargeted model.
//!
//! Every vertex of a stitched output is a copy of a vertex of the cut mesh shifted by its copy's
//! step vector (`x + Σ kᵢ vᵢ`, the stitching), except the vertices capping adds inside the
//! model. The cut mesh's vertices are the input's, followed by points on the input's edges and
//! inside its triangles where voxel faces cut them. So each copied vertex has an
//! exact origin on the input surface: an input triangle and barycentric weights, and its data is
//! interpolated there (colours and real attributes linearly, normals linearly and renormalised,
//! integer attributes taken from the corner of largest weight). What capping adds has no origin:
//! those vertices lie on the voxel faces where a cut opened the surface, and take the mean of
//! their neighbours' data (breadth first from the vertices that have some), normals excepted,
//! which are the area-weighted normals of their triangles (the caps are flat).
//!
//! The alternative, the closest point of the input surface to each output vertex moved back by
//! its copy's translation, needs a triangle search structure and guesses where copies meet; the
//! stitch's own arithmetic makes the search exact: the shifted-back position of a copied vertex
//! is its cut-mesh vertex up to rounding (a few ulps), or within the seam-welding tolerance where
//! a weld kept the other copy's position.

use motif_core::geometry::{Point3, cross, dot, norm, scale, sub};
use motif_core::mesh::TriMesh;
use motif_core::point_cloud::{Attribute, AttributeData, PointCloud};
use motif_core::spatial::KdTree;
use rayon::prelude::*;

/// Where an output vertex lies on the input surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VertexOrigin {
    /// The input triangle.
    pub triangle: u32,
    /// Barycentric weights of its three corners (non-negative, summing to 1).
    pub weights: [f64; 3],
}

/// Barycentric weights of `p`'s projection onto triangle `(a, b, c)`, clamped to the triangle
/// (negative weights set to 0 and the rest renormalised); equal thirds for a triangle of no area.
pub(crate) fn barycentric(p: Point3, a: Point3, b: Point3, c: Point3) -> [f64; 3] {
    let (e0, e1, d) = (sub(b, a), sub(c, a), sub(p, a));
    let (d00, d01, d11) = (dot(e0, e0), dot(e0, e1), dot(e1, e1));
    let (d20, d21) = (dot(d, e0), dot(d, e1));
    let den = d00 * d11 - d01 * d01;
    if den.abs() <= 1e-30 * (d00 * d11).max(f64::MIN_POSITIVE) {
        return [1.0 / 3.0; 3];
    }
    let v = (d11 * d20 - d01 * d21) / den;
    let w = (d00 * d21 - d01 * d20) / den;
    let mut weights = [1.0 - v - w, v, w].map(|x| x.max(0.0));
    let sum: f64 = weights.iter().sum();
    if sum > 0.0 {
        weights = weights.map(|x| x / sum);
    } else {
        weights = [1.0 / 3.0; 3];
    }
    weights
}

/// Origins of the output's vertices on the input: `cut` is the session's cut mesh (model units),
/// `parent` the input triangle of each of its triangles, `original` the input's triangles,
/// `translation` the shift of each output triangle's copy, and `tolerance` how far a shifted-back
/// vertex may lie from its cut-mesh vertex (the seam-welding tolerance).
pub(crate) fn vertex_origins(
    cut: &TriMesh,
    parent: &[u32],
    original: &[[u32; 3]],
    out: &TriMesh,
    translation: &(dyn Fn(usize) -> Point3 + Sync),
    tolerance: f64,
) -> Vec<Option<VertexOrigin>> {
    let n_out = out.positions.len();
    let Ok(tree) = KdTree::new(&cut.positions) else {
        return vec![None; n_out];
    };
    // Each corner of each output triangle, moved back by its copy's translation: the cut-mesh
    // vertex it lies on and how far off.
    let corners: Vec<[(u32, f64); 3]> = out
        .triangles
        .par_iter()
        .enumerate()
        .map(|(f, t)| {
            let shift = translation(f);
            t.map(|v| {
                let q = sub(out.positions[v as usize], shift);
                let nb = tree.nearest(q);
                (nb.index as u32, nb.distance)
            })
        })
        .collect();
    let mut best: Vec<(u32, f64)> = vec![(u32::MAX, f64::INFINITY); n_out];
    for (t, c) in out.triangles.iter().zip(&corners) {
        for (&v, &(w, d)) in t.iter().zip(c) {
            if d <= tolerance && d < best[v as usize].1 {
                best[v as usize] = (w, d);
            }
        }
    }
    // The input triangle of each cut-mesh vertex: the parent of its first triangle.
    let mut cut_parent = vec![u32::MAX; cut.positions.len()];
    for (f, t) in cut.triangles.iter().enumerate() {
        for &v in t {
            if cut_parent[v as usize] == u32::MAX {
                cut_parent[v as usize] = parent[f];
            }
        }
    }
    best.par_iter()
        .map(|&(w, _)| {
            if w == u32::MAX {
                return None;
            }
            let triangle = cut_parent[w as usize];
            let tri = *original.get(triangle as usize)?;
            // A vertex of the input itself (the cut keeps their indices): its corner, exactly.
            let weights = match tri.iter().position(|&c| c == w) {
                Some(k) => std::array::from_fn(|i| if i == k { 1.0 } else { 0.0 }),
                None => {
                    let p = |i: usize| cut.positions[tri[i] as usize];
                    barycentric(cut.positions[w as usize], p(0), p(1), p(2))
                }
            };
            Some(VertexOrigin { triangle, weights })
        })
        .collect()
}

/// The per-vertex data of `input` (the input model's vertices, with `input_triangles`) carried
/// onto `out` by `origins` (one per output vertex, from
/// [`super::RetargetSession::vertex_origins`]); positions are `out`'s. Vertices without an origin
/// take their neighbours' mean (normals: their triangles' area-weighted normal).
pub fn carry_vertex_data(
    input: &PointCloud,
    input_triangles: &[[u32; 3]],
    out: &TriMesh,
    origins: &[Option<VertexOrigin>],
) -> PointCloud {
    let n = out.positions.len();
    let corner = |o: &VertexOrigin, k: usize| input_triangles[o.triangle as usize][k] as usize;
    // Interpolates `dim` reals per vertex; `None` where there is no origin.
    let lerp = |dim: usize, value: &dyn Fn(usize, usize) -> f64| -> Vec<Option<Vec<f64>>> {
        origins
            .iter()
            .map(|o| {
                o.as_ref().map(|o| {
                    (0..dim).map(|d| (0..3).map(|k| o.weights[k] * value(corner(o, k), d)).sum()).collect()
                })
            })
            .collect()
    };
    let neighbours = vertex_neighbours(out);
    let mut result = PointCloud::from_positions(out.positions.clone());
    if let Some(colors) = &input.colors {
        let known = lerp(3, &|v, d| colors[v][d] as f64);
        let filled = fill_from_neighbours(known, &neighbours, 3);
        result.colors = Some(
            filled.iter().map(|c| std::array::from_fn(|d| c[d].round().clamp(0.0, 255.0) as u8)).collect(),
        );
    }
    if let Some(normals) = &input.normals {
        let known = lerp(3, &|v, d| normals[v][d]);
        let face = area_weighted_normals(out);
        result.normals = Some(
            known
                .into_iter()
                .enumerate()
                .map(|(v, k)| {
                    let m = k.map(|k| [k[0], k[1], k[2]]).unwrap_or(face[v]);
                    let l = norm(m);
                    if l > 0.0 { scale(m, 1.0 / l) } else { face[v] }
                })
                .collect(),
        );
    }
    for a in &input.attributes {
        let data = match &a.data {
            AttributeData::Float(values) => {
                let known = lerp(1, &|v, _| values[v]);
                AttributeData::Float(
                    fill_from_neighbours(known, &neighbours, 1).into_iter().map(|x| x[0]).collect(),
                )
            }
            AttributeData::Int(values) => {
                // Labels are not averaged: the corner of largest weight, and a neighbour's.
                let known: Vec<Option<Vec<f64>>> = origins
                    .iter()
                    .map(|o| {
                        o.as_ref().map(|o| {
                            let k =
                                (0..3).max_by(|&i, &j| o.weights[i].total_cmp(&o.weights[j])).unwrap_or(0);
                            vec![values[corner(o, k)] as f64]
                        })
                    })
                    .collect();
                AttributeData::Int(
                    first_neighbour(known, &neighbours).into_iter().map(|x| x as i64).collect(),
                )
            }
        };
        result.attributes.push(Attribute { name: a.name.clone(), data });
    }
    debug_assert!(result.positions.len() == n);
    result
}

/// Neighbouring vertices of each vertex (CSR rows, with repeats).
fn vertex_neighbours(mesh: &TriMesh) -> (Vec<u32>, Vec<u32>) {
    let n = mesh.positions.len();
    let mut start = vec![0u32; n + 1];
    for t in &mesh.triangles {
        for &v in t {
            start[v as usize + 1] += 2;
        }
    }
    for v in 0..n {
        start[v + 1] += start[v];
    }
    let mut fill = start.clone();
    let mut list = vec![0u32; start[n] as usize];
    for t in &mesh.triangles {
        for k in 0..3 {
            let v = t[k] as usize;
            for other in [t[(k + 1) % 3], t[(k + 2) % 3]] {
                list[fill[v] as usize] = other;
                fill[v] += 1;
            }
        }
    }
    (start, list)
}

/// The vertices without a value (`None`) take the mean of their neighbours', breadth first from
/// those with one; vertices no path reaches take zeros.
fn fill_from_neighbours(
    mut known: Vec<Option<Vec<f64>>>,
    (start, list): &(Vec<u32>, Vec<u32>),
    dim: usize,
) -> Vec<Vec<f64>> {
    let mut frontier: Vec<usize> = (0..known.len()).filter(|&v| known[v].is_none()).collect();
    loop {
        let next: Vec<(usize, Vec<f64>)> = frontier
            .iter()
            .filter_map(|&v| {
                let mut sum = vec![0.0; dim];
                let mut count = 0usize;
                for &w in &list[start[v] as usize..start[v + 1] as usize] {
                    if let Some(x) = &known[w as usize] {
                        for d in 0..dim {
                            sum[d] += x[d];
                        }
                        count += 1;
                    }
                }
                (count > 0).then(|| (v, sum.into_iter().map(|s| s / count as f64).collect()))
            })
            .collect();
        if next.is_empty() {
            break;
        }
        for (v, x) in next {
            known[v] = Some(x);
        }
        frontier.retain(|&v| known[v].is_none());
    }
    known.into_iter().map(|k| k.unwrap_or_else(|| vec![0.0; dim])).collect()
}

/// Like [`fill_from_neighbours`] for one value that is not averaged: the first neighbour's.
fn first_neighbour(mut known: Vec<Option<Vec<f64>>>, (start, list): &(Vec<u32>, Vec<u32>)) -> Vec<f64> {
    let mut frontier: Vec<usize> = (0..known.len()).filter(|&v| known[v].is_none()).collect();
    loop {
        let next: Vec<(usize, f64)> = frontier
            .iter()
            .filter_map(|&v| {
                list[start[v] as usize..start[v + 1] as usize]
                    .iter()
                    .find_map(|&w| known[w as usize].as_ref().map(|x| (v, x[0])))
            })
            .collect();
        if next.is_empty() {
            break;
        }
        for (v, x) in next {
            known[v] = Some(vec![x]);
        }
        frontier.retain(|&v| known[v].is_none());
    }
    known.into_iter().map(|k| k.map_or(0.0, |x| x[0])).collect()
}

/// Area-weighted vertex normals (unit; zero where a vertex has no triangle of any area).
fn area_weighted_normals(mesh: &TriMesh) -> Vec<Point3> {
    let mut normals = vec![[0.0; 3]; mesh.positions.len()];
    for t in &mesh.triangles {
        let p = t.map(|v| mesh.positions[v as usize]);
        let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
        for &v in t {
            let m = &mut normals[v as usize];
            for d in 0..3 {
                m[d] += n[d];
            }
        }
    }
    for m in &mut normals {
        let l = norm(*m);
        if l > 0.0 {
            *m = scale(*m, 1.0 / l);
        }
    }
    normals
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn barycentric_weights_recover_the_point_and_clamp_outside() {
        let (a, b, c) = ([0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 1.0, 1.0]);
        let w = barycentric([0.5, 0.25, 0.25], a, b, c);
        let p: Vec<f64> = (0..3).map(|d| w[0] * a[d] + w[1] * b[d] + w[2] * c[d]).collect();
        assert!(
            (p[0] - 0.5).abs() < 1e-12 && (p[1] - 0.25).abs() < 1e-12 && (p[2] - 0.25).abs() < 1e-12,
            "{w:?}"
        );
        let w = barycentric([-1.0, 0.0, 0.0], a, b, c);
        assert!(w.iter().all(|&x| x >= 0.0) && (w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        assert_eq!(barycentric([1.0, 0.0, 0.0], a, a, a), [1.0 / 3.0; 3]);
    }

    #[test]
    fn vertices_without_an_origin_take_their_neighbours_mean() {
        // A fan around vertex 0 (no origin) whose rim vertices have values 0, 10, 20, 30.
        let mesh = TriMesh {
            positions: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [-1.0, 0.0, 0.0],
                [0.0, -1.0, 0.0],
            ],
            triangles: vec![[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 1]],
        };
        let known = vec![None, Some(vec![0.0]), Some(vec![10.0]), Some(vec![20.0]), Some(vec![30.0])];
        let filled = fill_from_neighbours(known, &vertex_neighbours(&mesh), 1);
        assert!((filled[0][0] - 15.0).abs() < 1e-12, "{filled:?}");
        assert_eq!(filled[3][0], 20.0);
    }
}
