//! Invariants of every procedural example: exact symmetries, closed outward-wound parts, no
//! degenerate triangles, determinism, lattice and instance consistency, JSON format.

use std::collections::HashSet;

use motif_core::geometry::{Mat4, Point3, cross, dot, mat4_mul, transform_point};
use motif_core::procedural::{
    self, ChairOptions, Example, FacadeOptions, FanOptions, FenceOptions, GearOptions, Region, ShelfLattice,
    ShelfOptions, Symmetry, SymmetryKind, WindmillOptions, rigid_inverse,
};
use motif_core::spatial::KdTree;
use motif_core::{Error, TriMesh};

/// Symmetry exactness demanded by the deformation tests: 1e-9 of the diagonal.
const EXACT: f64 = 1e-9;

fn all_examples() -> Vec<Example> {
    procedural::names()
        .iter()
        .filter(|n| **n != "windmill_100k")
        .map(|n| procedural::generate(n, 7).unwrap_or_else(|e| panic!("{n}: {e}")))
        .collect()
}

/// Vertices of a region, computed here independently of the library's helper.
fn region_vertices(mesh: &TriMesh, region: &Region, tol: f64) -> HashSet<usize> {
    match region {
        Region::All => (0..mesh.num_vertices()).collect(),
        Region::Vertices(v) => v.iter().map(|&i| i as usize).collect(),
        Region::Faces(f) => f.iter().flat_map(|&t| mesh.triangles[t as usize]).map(|i| i as usize).collect(),
        Region::Aabb { min, max } => (0..mesh.num_vertices())
            .filter(|&i| {
                let p = mesh.positions[i];
                (0..3).all(|k| p[k] >= min[k] - tol && p[k] <= max[k] + tol)
            })
            .collect(),
        Region::Sphere { center, radius } => (0..mesh.num_vertices())
            .filter(|&i| motif_core::geometry::dist(mesh.positions[i], *center) <= radius + tol)
            .collect(),
        Region::Union(r) => r.iter().flat_map(|r| region_vertices(mesh, r, tol)).collect(),
    }
}

/// Largest distance (relative to the diagonal) from `m(v)`, v in `verts`, to the nearest vertex.
fn map_residual(mesh: &TriMesh, tree: &KdTree, verts: &HashSet<usize>, m: &Mat4) -> f64 {
    let worst = verts
        .iter()
        .map(|&v| tree.nearest(transform_point(m, mesh.positions[v])).distance)
        .fold(0.0, f64::max);
    worst / mesh.diagonal()
}

fn check_orthogonal(m: &Mat4, what: &str) {
    for i in 0..3 {
        for j in 0..3 {
            let d: f64 = (0..3).map(|k| m[k][i] * m[k][j]).sum();
            let e = if i == j { 1.0 } else { 0.0 };
            assert!((d - e).abs() < 1e-12, "{what}: linear part not orthogonal");
        }
    }
    assert_eq!(m[3], [0.0, 0.0, 0.0, 1.0], "{what}: last row");
}

fn check_symmetries(ex: &Example) {
    let mesh = &ex.mesh;
    let tree = KdTree::new(&mesh.positions).unwrap();
    let tol = 1e-9 * mesh.diagonal();
    assert!(!ex.structure.symmetry.symmetries.is_empty(), "{}: no symmetry", ex.name);
    for s in &ex.structure.symmetry.symmetries {
        let what = format!("{} / {}", ex.name, s.name);
        match &s.kind {
            SymmetryKind::Group { region, generators } => {
                let verts = region_vertices(mesh, region, tol);
                assert!(!verts.is_empty(), "{what}: empty region");
                assert!(!generators.is_empty(), "{what}: no generator");
                for g in generators {
                    check_orthogonal(g, &what);
                    let r = map_residual(mesh, &tree, &verts, g);
                    assert!(r <= EXACT, "{what}: generator residual {r:e}");
                    // The region is invariant: images of region vertices land on region vertices.
                    for &v in &verts {
                        let q = tree.nearest(transform_point(g, mesh.positions[v]));
                        let p = mesh.positions[q.index];
                        let dup = tree.within(p, tol);
                        assert!(
                            dup.iter().any(|n| verts.contains(&n.index)),
                            "{what}: image leaves the region"
                        );
                    }
                }
                check_triangles_map(mesh, &tree, &verts, generators, &what);
            }
            SymmetryKind::Instances { instances } => {
                assert!(instances.len() >= 2, "{what}: fewer than two instances");
                let v0 = region_vertices(mesh, &instances[0].region, tol);
                assert!(!v0.is_empty(), "{what}: empty template region");
                let from0 = rigid_inverse(&instances[0].transform);
                for (i, inst) in instances.iter().enumerate() {
                    check_orthogonal(&inst.transform, &what);
                    let to_i = mat4_mul(&inst.transform, &from0);
                    let r = map_residual(mesh, &tree, &v0, &to_i);
                    assert!(r <= EXACT, "{what}: instance {i} residual {r:e}");
                    let vi = region_vertices(mesh, &inst.region, tol);
                    let back = map_residual(mesh, &tree, &vi, &rigid_inverse(&to_i));
                    assert!(back <= EXACT, "{what}: instance {i} inverse residual {back:e}");
                    // Regions correspond: instance 0's maps into instance i's and back.
                    for (from, to, m) in [(&v0, &vi, to_i), (&vi, &v0, rigid_inverse(&to_i))] {
                        for &v in from {
                            let q = transform_point(&m, mesh.positions[v]);
                            assert!(
                                tree.within(q, tol).iter().any(|n| to.contains(&n.index)),
                                "{what}: instance {i}: regions do not correspond"
                            );
                        }
                    }
                }
            }
        }
        let lib = procedural::symmetry_residual(mesh, s).unwrap();
        assert!(lib <= EXACT, "{what}: library residual {lib:e}");
    }
}

/// Group symmetries map triangles onto triangles (as vertex sets), not only vertices.
fn check_triangles_map(mesh: &TriMesh, tree: &KdTree, verts: &HashSet<usize>, gens: &[Mat4], what: &str) {
    let tol = 1e-9 * mesh.diagonal();
    // Canonical vertex of a position (the lowest index among coincident vertices).
    let canon =
        |p: Point3| -> usize { tree.within(p, tol).iter().map(|n| n.index).min().unwrap_or(usize::MAX) };
    let key = |t: [usize; 3]| {
        let mut k = t;
        k.sort_unstable();
        k
    };
    let tris: HashSet<[usize; 3]> =
        mesh.triangles.iter().map(|t| key(t.map(|v| canon(mesh.positions[v as usize])))).collect();
    for g in gens {
        for t in &mesh.triangles {
            if !t.iter().all(|&v| verts.contains(&(v as usize))) {
                continue;
            }
            let img = key(t.map(|v| canon(transform_point(g, mesh.positions[v as usize]))));
            assert!(tris.contains(&img), "{what}: a triangle's image is not a triangle");
        }
    }
}

fn signed_volume(m: &TriMesh, tris: &[usize]) -> f64 {
    tris.iter()
        .map(|&f| {
            let [a, b, c] = m.corners(f);
            dot(a, cross(b, c)) / 6.0
        })
        .sum()
}

fn check_mesh(ex: &Example) {
    let m = &ex.mesh;
    m.validate().unwrap();
    assert_eq!(m.degenerate_triangles(), 0, "{}: degenerate triangles", ex.name);
    let e = m.edge_stats();
    assert_eq!((e.boundary, e.non_manifold), (0, 0), "{}: not closed / not manifold", ex.name);
    let comps = m.components();
    assert_eq!(comps.isolated_vertices, 0, "{}: unused vertices", ex.name);
    let mut by_comp: Vec<Vec<usize>> = vec![Vec::new(); m.num_vertices()];
    for (f, t) in m.triangles.iter().enumerate() {
        by_comp[comps.vertex_component[t[0] as usize] as usize].push(f);
    }
    for tris in by_comp.iter().filter(|t| !t.is_empty()) {
        // Translate to the component's first vertex so the volume is not lost in rounding.
        let v = signed_volume(m, tris);
        assert!(v > 0.0, "{}: a part is wound inward (volume {v})", ex.name);
    }
}

#[test]
fn every_example_is_closed_outward_and_nondegenerate() {
    for ex in all_examples() {
        check_mesh(&ex);
        assert!(
            ex.mesh.num_triangles() <= 20_000,
            "{}: {} triangles by default",
            ex.name,
            ex.mesh.num_triangles()
        );
        assert!(ex.mesh.num_triangles() >= 100, "{}: too coarse", ex.name);
    }
}

#[test]
fn every_symmetry_is_exact() {
    for ex in all_examples() {
        check_symmetries(&ex);
    }
}

#[test]
fn instance_boxes_and_transforms_are_consistent() {
    for ex in all_examples() {
        assert!(!ex.structure.instances.is_empty(), "{}: no instance class", ex.name);
        let bb = ex.mesh.aabb().unwrap();
        for class in &ex.structure.instances {
            assert!(!class.instances.is_empty());
            let first = &class.instances[0];
            assert_eq!(
                first.transform,
                motif_core::geometry::IDENTITY4,
                "{}: template is not instance 0",
                ex.name
            );
            let e0 = first.aabb().extent();
            for inst in &class.instances {
                check_orthogonal(&inst.transform, &class.name);
                for k in 0..3 {
                    assert!(inst.bbox_min[k] <= inst.bbox_max[k]);
                    assert!(inst.bbox_min[k] >= bb.min[k] - 1e-9 && inst.bbox_max[k] <= bb.max[k] + 1e-9);
                }
                // Boxes of translated instances have the template's size.
                let is_translation =
                    (0..3).all(|i| (0..3).all(|j| inst.transform[i][j] == if i == j { 1.0 } else { 0.0 }));
                if is_translation {
                    let e = inst.aabb().extent();
                    for k in 0..3 {
                        assert!((e[k] - e0[k]).abs() < 1e-9, "{} {}: box size differs", ex.name, class.name);
                    }
                    let c = transform_point(&inst.transform, first.aabb().center());
                    assert!(motif_core::geometry::dist(c, inst.aabb().center()) < 1e-9);
                }
            }
        }
    }
}

#[test]
fn examples_are_deterministic_and_seeds_matter_only_where_random() {
    for name in procedural::names().iter().filter(|n| **n != "windmill_100k") {
        let a = procedural::generate(name, 1).unwrap();
        let b = procedural::generate(name, 1).unwrap();
        assert_eq!(a, b, "{name}: not deterministic");
        let c = procedural::generate(name, 2).unwrap();
        if *name == "facade_irregular" {
            assert_ne!(a.mesh, c.mesh, "{name}: seed has no effect");
        } else {
            assert_eq!(a.mesh, c.mesh, "{name}: depends on the seed");
        }
    }
}

#[test]
fn unknown_names_list_the_valid_ones() {
    match procedural::generate("teapot", 0) {
        Err(Error::InvalidOption { message, .. }) => {
            for n in procedural::names() {
                assert!(message.contains(n), "{message}");
            }
        }
        other => panic!("expected InvalidOption, got {other:?}"),
    }
}

#[test]
fn structure_json_follows_the_formats() {
    for ex in all_examples() {
        let v = serde_json::to_value(&ex.structure).unwrap();
        assert_eq!(v["symmetry"]["format"], "motif_symmetry_v1");
        assert!(v["symmetry"]["tolerance"].as_f64().unwrap() > 0.0);
        for s in v["symmetry"]["symmetries"].as_array().unwrap() {
            assert!(s["name"].is_string());
            let group = s.get("generators").is_some();
            assert_eq!(group, s.get("region").is_some());
            assert_ne!(group, s.get("instances").is_some());
            for g in s.get("generators").and_then(|g| g.as_array()).into_iter().flatten() {
                assert_eq!(g.as_array().unwrap().len(), 4);
                assert_eq!(g[0].as_array().unwrap().len(), 4);
            }
        }
        for c in v["instances"].as_array().unwrap() {
            for i in c["instances"].as_array().unwrap() {
                assert_eq!(i["bbox_min"].as_array().unwrap().len(), 3);
                assert_eq!(i["bbox_max"].as_array().unwrap().len(), 3);
                assert_eq!(i["transform"].as_array().unwrap().len(), 4);
            }
        }
        let back: procedural::Structure = serde_json::from_value(v).unwrap();
        assert_eq!(back, ex.structure);
        let gt = ex.structure.detection_ground_truth("scene.ply");
        assert_eq!(gt["scene"], "scene.ply");
        assert_eq!(gt["classes"].as_array().unwrap().len(), ex.structure.instances.len());
    }
}

/// Shifting by a lattice vector maps every cell but the last in that direction onto a cell.
#[test]
fn shelf_lattice_matches_the_geometry() {
    for opts in [ShelfOptions::default(), ShelfOptions::sheared()] {
        let ex = procedural::shelf(&opts).unwrap();
        let s = &ex.structure;
        assert_eq!(s.cells, Some([4, 3, 1]));
        assert_eq!(s.cell_pitch.len(), 2);
        let p = [opts.cell_size[0] + opts.board_thickness, opts.cell_size[1] + opts.board_thickness];
        let shift = match opts.lattice {
            ShelfLattice::Orthogonal => 0.0,
            ShelfLattice::Sheared { offset } => offset,
        };
        assert_eq!(s.cell_pitch[0], [p[0], 0.0, 0.0]);
        assert!((s.cell_pitch[1][0] - shift).abs() < 1e-12 && (s.cell_pitch[1][1] - p[1]).abs() < 1e-12);
        let cells = &s.instances[0];
        assert_eq!(cells.name, "cell");
        assert_eq!(cells.instances.len(), 12);
        let tree = KdTree::new(&ex.mesh.positions).unwrap();
        let tol = 1e-9 * ex.mesh.diagonal();
        for (dir, (di, dj)) in [(0, (1, 0)), (1, (0, 1))] {
            let t = motif_core::procedural::translation(s.cell_pitch[dir]);
            for j in 0..3 - dj {
                for i in 0..4 - di {
                    let a = &cells.instances[j * 4 + i];
                    let b = &cells.instances[(j + dj) * 4 + i + di];
                    // Cell (i, j) shifted by one pitch is cell (i + di, j + dj).
                    let expect = mat4_mul(&t, &a.transform);
                    for r in 0..3 {
                        for c in 0..4 {
                            assert!((expect[r][c] - b.transform[r][c]).abs() < 1e-12);
                        }
                    }
                    let verts =
                        region_vertices(&ex.mesh, &Region::Aabb { min: a.bbox_min, max: a.bbox_max }, tol);
                    assert!(map_residual(&ex.mesh, &tree, &verts, &t) <= EXACT);
                }
            }
        }
    }
}

#[test]
fn facade_has_the_requested_windows_and_door() {
    let ex = procedural::generate("facade", 0).unwrap();
    let names: Vec<&str> = ex.structure.instances.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["window_a", "window_b", "door"]);
    let count = |n: &str| ex.structure.instances.iter().find(|c| c.name == n).unwrap().instances.len();
    // 5 bays x 4 floors, alternate floors: floors 0 and 2 are style A, one cell is the door.
    assert_eq!((count("window_a"), count("window_b"), count("door")), (9, 10, 1));
    assert_eq!(ex.structure.cells, Some([5, 4, 1]));
    // Every window sits on the lattice: its offset from the template is a whole number of pitches.
    let [a, b] = [ex.structure.cell_pitch[0], ex.structure.cell_pitch[1]];
    for c in &ex.structure.instances {
        for i in &c.instances {
            let (u, v) = (i.transform[0][3] / a[0], i.transform[1][3] / b[1]);
            assert!((u - u.round()).abs() < 1e-9 && (v - v.round()).abs() < 1e-9 && i.transform[2][3] == 0.0);
        }
    }
    // Windows are recessed geometry: vertices behind the front face inside each window box.
    for c in &ex.structure.instances {
        for i in &c.instances {
            assert!(
                i.bbox_min[2] < -0.1 && i.bbox_max[2] > 0.05,
                "{}: box not around a recess and frame",
                c.name
            );
        }
    }
    let irregular = procedural::generate("facade_irregular", 3).unwrap();
    assert!(irregular.structure.cell_pitch.is_empty() && irregular.structure.cells.is_none());
    let cols = procedural::facade(&FacadeOptions {
        layout: procedural::WindowLayout::AlternateColumns,
        ..Default::default()
    })
    .unwrap();
    check_mesh(&cols);
    check_symmetries(&cols);
}

#[test]
fn fence_posts_follow_the_pitch() {
    let ex = procedural::generate("fence", 0).unwrap();
    assert_eq!(ex.structure.cell_pitch, vec![[1.5, 0.0, 0.0]]);
    assert_eq!(ex.structure.cells, Some([8, 1, 1]));
    let posts = &ex.structure.instances[0];
    assert_eq!(posts.instances.len(), 8);
    for (i, p) in posts.instances.iter().enumerate() {
        assert!((p.transform[0][3] - 1.5 * i as f64).abs() < 1e-12);
    }
}

#[test]
fn groups_have_the_expected_orders() {
    // Closure of the generators: count distinct group elements.
    fn order(gens: &[Mat4]) -> usize {
        let mut elems: Vec<Mat4> = vec![motif_core::geometry::IDENTITY4];
        let same = |a: &Mat4, b: &Mat4| (0..3).all(|i| (0..4).all(|j| (a[i][j] - b[i][j]).abs() < 1e-9));
        let mut i = 0;
        while i < elems.len() {
            for g in gens {
                let e = mat4_mul(g, &elems[i]);
                if !elems.iter().any(|x| same(x, &e)) {
                    elems.push(e);
                    assert!(elems.len() < 1000);
                }
            }
            i += 1;
        }
        elems.len()
    }
    let group = |ex: &Example, name: &str| -> Vec<Mat4> {
        let s: &Symmetry = ex.structure.symmetry.symmetries.iter().find(|s| s.name == name).unwrap();
        match &s.kind {
            SymmetryKind::Group { generators, .. } => generators.clone(),
            _ => panic!("{name} is not a group"),
        }
    };
    assert_eq!(order(&group(&procedural::generate("fan", 0).unwrap(), "fan")), 12);
    assert_eq!(order(&group(&procedural::generate("gear", 0).unwrap(), "gear")), 68);
    assert_eq!(order(&group(&procedural::generate("chair", 0).unwrap(), "chair mirror")), 2);
    let w = procedural::generate("windmill", 0).unwrap();
    assert_eq!(order(&group(&w, "rotor")), 4);
    for k in 0..4 {
        assert_eq!(order(&group(&w, &format!("blade {k}"))), 2);
    }
}

#[test]
fn windmill_regions_nest() {
    let ex = procedural::generate("windmill", 0).unwrap();
    let tol = 1e-9 * ex.mesh.diagonal();
    let region =
        |name: &str| match &ex.structure.symmetry.symmetries.iter().find(|s| s.name == name).unwrap().kind {
            SymmetryKind::Group { region, .. } => region.clone(),
            _ => panic!(),
        };
    let rotor = region_vertices(&ex.mesh, &region("rotor"), tol);
    // Tower and nacelle lie behind the nacelle's front face (z = 0.6 * nacelle depth).
    let front = 0.6 * WindmillOptions::default().nacelle_size[2];
    assert!(
        rotor.iter().all(|&v| ex.mesh.positions[v][2] > front + 1e-6),
        "the rotor region covers the nacelle"
    );
    let behind = (0..ex.mesh.num_vertices()).filter(|&v| ex.mesh.positions[v][2] <= front).count();
    assert!(behind > 100 && rotor.len() + behind <= ex.mesh.num_vertices());
    for k in 0..4 {
        let r = region(&format!("blade {k}"));
        assert!(matches!(r, Region::Aabb { .. }), "default sails are isolated by boxes");
        let b = region_vertices(&ex.mesh, &r, tol);
        assert!(!b.is_empty() && b.is_subset(&rotor), "blade {k} must lie in the rotor");
    }
}

#[test]
fn variants_and_resolution_keep_exactness() {
    let variants: Vec<Example> = vec![
        procedural::fan(&FanOptions { blades: 5, resolution: 2, ..Default::default() }).unwrap(),
        procedural::gear(&GearOptions { teeth: 8, resolution: 2, ..Default::default() }).unwrap(),
        procedural::chair(&ChairOptions { resolution: 3, ..Default::default() }).unwrap(),
        procedural::windmill(&WindmillOptions { blades: 3, ..Default::default() }).unwrap(),
        procedural::windmill(&WindmillOptions { blades: 6, resolution: 2, ..Default::default() }).unwrap(),
        procedural::fence(&FenceOptions { posts: 3, resolution: 9, ..Default::default() }).unwrap(),
        procedural::shelf(&ShelfOptions { cells: [2, 5], resolution: 2, ..ShelfOptions::sheared() }).unwrap(),
        procedural::shelf(&ShelfOptions { cells: [3, 2], resolution: 3, ..Default::default() }).unwrap(),
        procedural::facade(&FacadeOptions { resolution: 2, ..FacadeOptions::irregular() }).unwrap(),
    ];
    for ex in &variants {
        check_mesh(ex);
        check_symmetries(ex);
    }
    let coarse = procedural::generate("gear", 0).unwrap();
    assert!(variants[1].mesh.num_vertices() > 2 * coarse.mesh.num_vertices() * 8 / 17);
}

#[test]
fn windmill_100k_is_large_and_exact() {
    let ex = procedural::generate("windmill_100k", 0).unwrap();
    assert!(ex.mesh.num_vertices() >= 100_000, "{} vertices", ex.mesh.num_vertices());
    assert!(ex.mesh.num_vertices() <= 150_000, "{} vertices", ex.mesh.num_vertices());
    assert_eq!(ex.mesh.degenerate_triangles(), 0);
    let e = ex.mesh.edge_stats();
    assert_eq!((e.boundary, e.non_manifold), (0, 0));
    for s in &ex.structure.symmetry.symmetries {
        let r = procedural::symmetry_residual(&ex.mesh, s).unwrap();
        assert!(r <= EXACT, "{}: {r:e}", s.name);
    }
}

#[test]
fn bad_options_are_refused() {
    assert!(procedural::fan(&FanOptions { blades: 1, ..Default::default() }).is_err());
    assert!(procedural::fan(&FanOptions { blade_root_width: 0.2, ..Default::default() }).is_err());
    assert!(procedural::gear(&GearOptions { bore_radius: 1.0, ..Default::default() }).is_err());
    assert!(procedural::gear(&GearOptions { module: f64::NAN, ..Default::default() }).is_err());
    assert!(procedural::shelf(&ShelfOptions { cells: [0, 3], ..Default::default() }).is_err());
    assert!(procedural::shelf(&ShelfOptions { resolution: 0, ..Default::default() }).is_err());
    assert!(procedural::facade(&FacadeOptions { door_column: 9, ..Default::default() }).is_err());
    assert!(procedural::facade(&FacadeOptions { bay_width: 1.0, ..Default::default() }).is_err());
    assert!(
        procedural::facade(&FacadeOptions {
            spacing: procedural::FacadeSpacing::Jittered { amount: 0.5 },
            ..Default::default()
        })
        .is_err()
    );
    assert!(procedural::windmill(&WindmillOptions { blades: 13, ..Default::default() }).is_err());
    assert!(procedural::fence(&FenceOptions { rail_heights: vec![2.0], ..Default::default() }).is_err());
    assert!(procedural::chair(&ChairOptions { leg_width: 0.3, ..Default::default() }).is_err());
}

#[test]
fn options_round_trip_through_json() {
    let o = ShelfOptions::sheared();
    let s = serde_json::to_string(&o).unwrap();
    assert_eq!(serde_json::from_str::<ShelfOptions>(&s).unwrap(), o);
    // Missing fields take their defaults.
    let f: FanOptions = serde_json::from_str(r#"{"blades": 3}"#).unwrap();
    assert_eq!(f, FanOptions { blades: 3, ..Default::default() });
    let w: FacadeOptions = serde_json::from_str(r#"{"spacing": {"jittered": {"amount": 0.1}}}"#).unwrap();
    assert_eq!(w.spacing, procedural::FacadeSpacing::Jittered { amount: 0.1 });
}

#[test]
fn print_summary() {
    // Not an assertion: the sizes and structure reported in the change description.
    for ex in all_examples() {
        let groups = ex
            .structure
            .symmetry
            .symmetries
            .iter()
            .filter(|s| matches!(s.kind, SymmetryKind::Group { .. }))
            .count();
        let sets = ex.structure.symmetry.symmetries.len() - groups;
        let classes: Vec<String> =
            ex.structure.instances.iter().map(|c| format!("{}×{}", c.name, c.instances.len())).collect();
        let regions: Vec<String> = ex
            .structure
            .symmetry
            .symmetries
            .iter()
            .map(|s| {
                let kind = |r: &Region| match r {
                    Region::All => "all",
                    Region::Aabb { .. } => "aabb",
                    Region::Union(_) => "union",
                    Region::Faces(_) => "faces",
                    _ => "other",
                };
                match &s.kind {
                    SymmetryKind::Group { region, .. } => format!("{}:{}", s.name, kind(region)),
                    SymmetryKind::Instances { instances } => {
                        format!("{}:{}", s.name, kind(&instances[0].region))
                    }
                }
            })
            .collect();
        println!("{:18} regions {}", ex.name, regions.join(", "));
        println!(
            "{:18} V {:6} F {:6} groups {} instance-sets {} classes [{}] pitch {:?} cells {:?}",
            ex.name,
            ex.mesh.num_vertices(),
            ex.mesh.num_triangles(),
            groups,
            sets,
            classes.join(", "),
            ex.structure.cell_pitch,
            ex.structure.cells
        );
    }
}
