//! Integration tests of motif-deform: exact symmetry preservation on every generated symmetric
//! example (thesis eq. 3.2), the `Ignore` comparison, handle fits, errors, allocation-free solves.

use std::sync::Mutex;

use motif_core::TriMesh;
use motif_core::geometry::{IDENTITY4, Mat4, Point3, dist, mat4_mul, transform_point};
use motif_core::procedural::{
    FanOptions, Region, SymmetryAnnotation, SymmetryKind, fan, generate, reflection, rotation_about,
    translation,
};
use motif_deform::{
    AnnotationValidation, DeformError, DeformOptions, DeformSession, Handle, HandlesFile, LiftEvaluation,
    SampleSpacing, SymmetryMaps, SymmetryMode, check_annotation, deform, symmetry_residual,
};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

// ---------------------------------------------------------------------------------------------
// Helpers.

/// Every generated example with a symmetry annotation worth testing.
const SYMMETRIC: &[&str] = &["fan", "gear", "windmill", "chair", "shelf", "shelf_sheared", "fence", "facade"];

fn sphere(center: Point3, radius: f64) -> Region {
    Region::Sphere { center, radius }
}

/// A seeded random edit: a fixed handle and a handle moved by a large rotation (0.5 to 2.5 rad
/// about a random axis through it) and a translation of up to 0.2 × the diagonal.
fn random_edit(mesh: &TriMesh, seed: u64) -> (Vec<Handle>, Vec<Mat4>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let d = mesh.diagonal();
    let n = mesh.num_vertices();
    let a = mesh.positions[rng.random_range(0..n)];
    let mut b = a;
    for _ in 0..10_000 {
        b = mesh.positions[rng.random_range(0..n)];
        if dist(a, b) > 0.4 * d {
            break;
        }
    }
    let axis = [rng.random::<f64>() - 0.5, rng.random::<f64>() - 0.5, rng.random::<f64>() - 0.5];
    let angle = rng.random_range(0.5..2.5);
    let t = [rng.random::<f64>() - 0.5, rng.random::<f64>() - 0.5, rng.random::<f64>() - 0.5]
        .map(|c| 0.4 * c * d);
    let m = mat4_mul(&translation(t), &rotation_about(axis, b, angle));
    (vec![Handle::fixed(sphere(a, 0.1 * d)), Handle::moved(sphere(b, 0.1 * d), m)], vec![IDENTITY4, m])
}

fn session(name: &str, mode: SymmetryMode) -> (TriMesh, SymmetryAnnotation, DeformSession) {
    let ex = generate(name, 0).unwrap();
    let o = DeformOptions { symmetry: mode, ..Default::default() };
    let s = DeformSession::new(&ex.mesh, &ex.structure.symmetry, &o).unwrap();
    (ex.mesh, ex.structure.symmetry, s)
}

fn mul3(a: &[[f64; 3]; 3], v: Point3) -> Point3 {
    [
        a[0][0] * v[0] + a[0][1] * v[1] + a[0][2] * v[2],
        a[1][0] * v[0] + a[1][1] * v[1] + a[1][2] * v[2],
        a[2][0] * v[0] + a[2][1] * v[1] + a[2][2] * v[2],
    ]
}

fn linear(m: &Mat4) -> [[f64; 3]; 3] {
    [[m[0][0], m[0][1], m[0][2]], [m[1][0], m[1][1], m[1][2]], [m[2][0], m[2][1], m[2][2]]]
}

// ---------------------------------------------------------------------------------------------
// Exactness (the point of the chapter).

#[test]
fn symmetry_is_exact_on_every_symmetric_example() {
    for name in SYMMETRIC {
        let (mesh, ann, mut s) = session(name, SymmetryMode::Preserve);
        let maps = SymmetryMaps::new(&mesh, &ann).unwrap();
        assert!(!maps.elements.is_empty(), "{name}");
        assert_eq!(s.stats().fallback_vertices, 0, "{name}: {:?}", s.warnings());
        for seed in 0..3 {
            let (handles, transforms) = random_edit(&mesh, 100 * seed + name.len() as u64);
            s.set_handles(&handles).unwrap();
            let y = s.solve(&transforms).unwrap().to_vec();
            assert!(y.iter().flatten().all(|c| c.is_finite()));
            let r = maps.residual(&y).unwrap();
            println!("{name} seed {seed}: residual {:.2e} (rest {:.2e})", r.max, r.rest_max);
            assert!(
                r.max <= 1e-9,
                "{name} seed {seed}: residual {:.3e}: {:?}",
                r.max,
                r.elements.iter().find(|e| e.residual > 1e-9)
            );
            // The edit really moved the shape.
            let moved = y.iter().zip(&mesh.positions).map(|(a, b)| dist(*a, *b)).fold(0.0, f64::max);
            assert!(moved > 1e-3 * mesh.diagonal(), "{name}: nothing moved");
        }
    }
}

/// A deformed model saved with its annotation must open with it again: the rest annotation's
/// boxes no longer hold the moved blades of a deformed windmill, its regions as vertices do,
/// and they select the same vertices, on which the symmetries are still exact.
#[test]
fn an_annotation_pinned_to_vertices_fits_the_deformed_model() {
    let (mesh, ann, mut s) = session("windmill", SymmetryMode::Preserve);
    let (handles, transforms) = random_edit(&mesh, 3);
    s.set_handles(&handles).unwrap();
    let deformed =
        TriMesh { positions: s.solve(&transforms).unwrap().to_vec(), triangles: mesh.triangles.clone() };
    let pinned = motif_deform::regions_as_vertices(&ann, &mesh).unwrap();
    assert_eq!(pinned.symmetries.len(), ann.symmetries.len());
    let regions = |a: &SymmetryAnnotation, m: &TriMesh| -> Option<Vec<Vec<u32>>> {
        let r = motif_deform::resolve_annotation(m, a).ok()?;
        Some(
            r.symmetries
                .iter()
                .flat_map(|s| match &s.kind {
                    motif_deform::ResolvedKind::Group { region, .. } => vec![region.vertices.clone()],
                    motif_deform::ResolvedKind::Instances { instances, .. } => {
                        instances.iter().map(|i| i.vertices.clone()).collect()
                    }
                })
                .collect(),
        )
    };
    let on_rest = regions(&ann, &mesh).expect("the annotation fits the rest shape");
    assert_eq!(regions(&pinned, &mesh).as_ref(), Some(&on_rest), "pinned regions select the same vertices");
    assert_eq!(regions(&pinned, &deformed).as_ref(), Some(&on_rest), "... also on the deformed shape");
    // The rest annotation's places no longer select those vertices on the deformed shape.
    assert_ne!(
        regions(&ann, &deformed).as_ref(),
        Some(&on_rest),
        "the edit should move a blade out of its box"
    );
    let r = symmetry_residual(&deformed, &deformed.positions, &pinned).unwrap();
    assert!(r.max <= 1e-9, "residual {:.2e}", r.max);
}

#[test]
fn ignoring_symmetry_breaks_it() {
    for name in ["fan", "windmill", "chair", "shelf", "fence"] {
        let (mesh, ann, mut s) = session(name, SymmetryMode::Ignore);
        assert_eq!(s.stats().symmetries, 0);
        assert_eq!(s.stats().dof, 3 * s.stats().samples, "{name}: every sample has 3 DoF");
        let (handles, transforms) = random_edit(&mesh, 7);
        s.set_handles(&handles).unwrap();
        let y = s.solve(&transforms).unwrap().to_vec();
        let r = symmetry_residual(&mesh, &y, &ann).unwrap();
        println!("{name} ignore: residual {:.2e}", r.max);
        assert!(
            r.max > 1e-3,
            "{name}: an asymmetric edit without symmetry should break it, got {:.2e}",
            r.max
        );
    }
}

#[test]
fn windmill_nested_symmetries_are_all_checked() {
    let ex = generate("windmill", 0).unwrap();
    let maps = SymmetryMaps::new(&ex.mesh, &ex.structure.symmetry).unwrap();
    // mirror (1 element) + rotor C4 (3) + one mirror per blade (4).
    assert_eq!(maps.elements.len(), 8);
    let names: Vec<&str> = maps.elements.iter().map(|e| e.name.as_str()).collect();
    assert!(names.contains(&"rotor") && names.contains(&"blade 3") && names.contains(&"windmill mirror"));
    for m in &maps.maps {
        assert_eq!(m.unmatched, 0);
    }
}

#[test]
fn per_vertex_lifting_is_exact_too() {
    for name in ["windmill", "shelf", "chair"] {
        let ex = generate(name, 0).unwrap();
        let mut o = DeformOptions::default();
        o.lift.evaluation = LiftEvaluation::PerVertex;
        let mut s = DeformSession::new(&ex.mesh, &ex.structure.symmetry, &o).unwrap();
        assert_eq!(s.lifting().num_rows(), ex.mesh.num_vertices());
        let per_orbit =
            DeformSession::new(&ex.mesh, &ex.structure.symmetry, &DeformOptions::default()).unwrap();
        assert!(per_orbit.lifting().num_rows() < ex.mesh.num_vertices() / 2 + 1, "{name}: orbits share rows");
        let (h, t) = random_edit(&ex.mesh, 21);
        s.set_handles(&h).unwrap();
        let y = s.solve(&t).unwrap().to_vec();
        let r = symmetry_residual(&ex.mesh, &y, &ex.structure.symmetry).unwrap();
        assert!(r.max <= 1e-9, "{name}: {:.3e}", r.max);
        // Per orbit and per vertex agree up to rounding.
        let mut p = per_orbit;
        p.set_handles(&h).unwrap();
        let z = p.solve(&t).unwrap();
        let diff = y.iter().zip(z).map(|(a, b)| dist(*a, *b)).fold(0.0, f64::max);
        assert!(diff <= 1e-12 * ex.mesh.diagonal(), "{name}: {diff:.3e}");
    }
}

#[test]
fn lift_weights_commute_with_the_symmetry() {
    let ex = generate("fan", 0).unwrap();
    let mut o = DeformOptions::default();
    o.lift.evaluation = LiftEvaluation::PerVertex;
    let s = DeformSession::new(&ex.mesh, &ex.structure.symmetry, &o).unwrap();
    let (mesh, ann) = (ex.mesh, ex.structure.symmetry);
    let maps = SymmetryMaps::new(&mesh, &ann).unwrap();
    let samples = &s.sampling().positions;
    let w = s.lifting();
    let tol = 1e-9 * mesh.diagonal();
    for (e, m) in maps.elements.iter().zip(&maps.maps).take(4) {
        for &(k, j) in m.pairs.iter().step_by(7) {
            let (_, ck, wk, _) = w.row(k as usize);
            let (_, cj, wj, _) = w.row(j as usize);
            assert_eq!(ck.len(), cj.len());
            for (l, wl) in ck.iter().zip(wk) {
                let g = transform_point(&e.transform, samples[*l as usize]);
                let hit = cj.iter().zip(wj).find(|(c, _)| dist(samples[**c as usize], g) <= tol);
                let (_, wm) =
                    hit.unwrap_or_else(|| panic!("{}: image of sample {l} not in the row of {j}", e.label));
                assert!((wl - wm).abs() <= 1e-12, "{wl} vs {wm}");
            }
        }
    }
}

#[test]
fn co_rotated_laplace_coordinates_are_symmetric() {
    let (mesh, _ann, mut s) = session("fan", SymmetryMode::Preserve);
    let (handles, transforms) = random_edit(&mesh, 3);
    s.set_handles(&handles).unwrap();
    s.solve(&transforms).unwrap();
    let rest = s.sampling().positions.clone();
    let u = s.sample_displacements().to_vec();
    let def: Vec<Point3> =
        rest.iter().zip(&u).map(|(x, u)| [x[0] + u[0], x[1] + u[1], x[2] + u[2]]).collect();
    let g = s.graph();
    let mut delta = vec![[0.0; 3]; rest.len()];
    g.apply_laplacian(&rest, &mut delta);
    let mut rots = vec![[[0.0; 3]; 3]; rest.len()];
    g.fit_rotations(&rest, &def, &mut rots);
    let rotated: Vec<Point3> = (0..rest.len()).map(|i| mul3(&rots[i], delta[i])).collect();
    let el = &s.annotation().symmetries[0];
    let motif_deform::ResolvedKind::Group { elements, .. } = &el.kind else { panic!("fan is a group") };
    let scale = delta.iter().map(|d| d.iter().map(|c| c.abs()).fold(0.0, f64::max)).fold(0.0, f64::max);
    let tol = 1e-9 * mesh.diagonal();
    let mut worst: f64 = 0.0;
    for gm in elements {
        for i in 0..rest.len() {
            let gi = transform_point(gm, rest[i]);
            let Some(j) = (0..rest.len()).find(|&j| dist(rest[j], gi) <= tol) else { continue };
            let expect = mul3(&linear(gm), rotated[i]);
            worst = worst.max(dist(expect, rotated[j]));
            // The displacement itself is symmetric by construction.
            assert!(dist(mul3(&linear(gm), u[i]), u[j]) <= 1e-9 * mesh.diagonal());
        }
    }
    assert!(worst <= 1e-9 * scale, "rotated δ not symmetric: {worst:.3e} (scale {scale:.3e})");
}

#[test]
fn rotations_shared_across_orbits_equal_per_sample_fits() {
    for name in ["fan", "windmill", "shelf"] {
        let (mesh, _ann, mut s) = session(name, SymmetryMode::Preserve);
        let plan = s.rotation_plan().clone();
        assert!(plan.own_fits() <= s.stats().samples);
        if name == "fan" {
            assert_eq!(plan.own_fits(), s.stats().orbits, "a global D6: one fit per orbit");
        }
        let (h, t) = random_edit(&mesh, 4);
        s.set_handles(&h).unwrap();
        s.solve(&t).unwrap();
        let rest = s.sampling().positions.clone();
        let def: Vec<Point3> = rest
            .iter()
            .zip(s.sample_displacements())
            .map(|(x, u)| [x[0] + u[0], x[1] + u[1], x[2] + u[2]])
            .collect();
        let mut each = vec![[[0.0; 3]; 3]; rest.len()];
        s.graph().fit_rotations(&rest, &def, &mut each);
        let mut shared = vec![[[0.0; 3]; 3]; rest.len()];
        plan.fit_rotations(s.graph(), &s.sampling().frames, &rest, &def, &mut shared);
        let worst = each
            .iter()
            .zip(&shared)
            .map(|(a, b)| {
                (0..3).flat_map(|i| (0..3).map(move |j| (a[i][j] - b[i][j]).abs())).fold(0.0, f64::max)
            })
            .fold(0.0, f64::max);
        println!(
            "{name}: {} of {} samples fit their own rotation; largest difference {worst:.1e}",
            plan.own_fits(),
            rest.len()
        );
        assert!(worst < 1e-8, "{name}: {worst:.3e}");
    }
}

#[test]
fn a_sheet_on_its_own_mirror_plane_only_moves_in_plane() {
    // Every point of a flat sheet is fixed by the reflection in its plane: every orbit is
    // degenerate and keeps two in-plane directions (thesis Fig. 3.7b).
    let n = 12;
    let mut pos = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            pos.push([i as f64 / n as f64, j as f64 / n as f64, 0.0]);
        }
    }
    let mut tri = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let a = (j * (n + 1) + i) as u32;
            tri.push([a, a + 1, a + n as u32 + 2]);
            tri.push([a, a + n as u32 + 2, a + n as u32 + 1]);
        }
    }
    let mesh = TriMesh::new(pos, tri).unwrap();
    let ann = SymmetryAnnotation {
        symmetries: vec![motif_core::procedural::Symmetry {
            name: "plane".into(),
            kind: SymmetryKind::Group {
                region: Region::All,
                generators: vec![reflection([0.0, 0.0, 1.0], [0.0; 3])],
            },
        }],
        ..Default::default()
    };
    let o = DeformOptions {
        sampling: motif_deform::SymmetricSamplingOptions {
            spacing: SampleSpacing::Count(60),
            ..Default::default()
        },
        ..Default::default()
    };
    let mut s = DeformSession::new(&mesh, &ann, &o).unwrap();
    assert_eq!(s.stats().degenerate_orbits, s.stats().orbits);
    assert_eq!(s.stats().dof, 2 * s.stats().orbits);
    s.set_handles(&[Handle::fixed(sphere([0.0; 3], 0.2)), Handle::fixed(sphere([1.0, 1.0, 0.0], 0.2))])
        .unwrap();
    let lift =
        mat4_mul(&translation([0.1, 0.0, 0.3]), &rotation_about([1.0, 0.0, 0.0], [1.0, 1.0, 0.0], 0.4));
    let y = s.solve(&[IDENTITY4, lift]).unwrap();
    assert!(y.iter().all(|p| p[2].abs() <= 1e-12), "the sheet left its mirror plane");
    assert!(y.iter().any(|p| dist(*p, [1.0, 1.0, 0.0]) > 1e-3));
}

// ---------------------------------------------------------------------------------------------
// Handles and solves.

#[test]
fn handles_reach_their_targets() {
    let ex = fan(&FanOptions::default()).unwrap();
    let mut s = DeformSession::new(&ex.mesh, &ex.structure.symmetry, &DeformOptions::default()).unwrap();
    s.set_handles(&[Handle::fixed(sphere([0.0; 3], 0.06)), Handle::fixed(sphere([0.29, 0.0, 0.0], 0.03))])
        .unwrap();
    // Lifting the blade tips is compatible with D6: every tip goes up, the fit is tight.
    let up = translation([0.0, 0.0, 0.05]);
    s.solve(&[IDENTITY4, up]).unwrap();
    for f in s.handle_fit() {
        assert!(f.max_error < 1e-4, "{f:?}");
        assert!(f.rms_error <= f.max_error);
    }
    let tip =
        s.positions().iter().zip(&ex.mesh.positions).filter(|(_, x)| dist(**x, [0.29, 0.0, 0.0]) < 0.01);
    for (y, x) in tip {
        assert!((y[2] - x[2] - 0.05).abs() < 5e-3, "tip vertex moved by {}", y[2] - x[2]);
    }
    assert!(s.stats().timings.solve_ms > 0.0 && s.stats().timings.prefactor_ms > 0.0);
}

#[test]
fn solve_reuses_its_buffers() {
    // The workspace forbids unsafe code, so no counting allocator here: check that the output
    // buffer is the same on every frame (the solve path allocates nothing by construction; see
    // `editing::Workspace`).
    let (mesh, _ann, mut s) = session("windmill", SymmetryMode::Preserve);
    let (handles, transforms) = random_edit(&mesh, 11);
    s.set_handles(&handles).unwrap();
    let p0 = s.solve(&transforms).unwrap().as_ptr();
    for k in 0..3 {
        let mut t = transforms.clone();
        t[1] = mat4_mul(&translation([0.01 * k as f64, 0.0, 0.0]), &t[1]);
        assert_eq!(s.solve(&t).unwrap().as_ptr(), p0);
    }
}

#[test]
fn handles_file_frames_replay_exactly() {
    let ex = generate("chair", 0).unwrap();
    let d = ex.mesh.diagonal();
    let json = format!(
        r#"{{"format":"motif_handles_v1","handles":[
            {{"region":{{"aabb":{{"min":[-1,-0.01,-1],"max":[1,0.02,1]}}}}}},
            {{"region":{{"sphere":{{"center":[0.2,0.95,-0.2],"radius":{r}}}}}}}],
          "frames":[]}}"#,
        r = 0.12 * d
    );
    let mut file = HandlesFile::from_json(&json).unwrap();
    for f in 0..4 {
        let a = 0.2 * f as f64;
        file.frames.push(vec![IDENTITY4, rotation_about([1.0, 0.0, 0.0], [0.0, 0.45, -0.2], -a)]);
    }
    let file = HandlesFile::from_json(&file.to_json()).unwrap();
    let mut s = DeformSession::new(&ex.mesh, &ex.structure.symmetry, &DeformOptions::default()).unwrap();
    s.set_handles(&file.handles).unwrap();
    let maps = SymmetryMaps::new(&ex.mesh, &ex.structure.symmetry).unwrap();
    for frame in &file.frames {
        let y = s.solve(frame).unwrap().to_vec();
        assert!(maps.residual(&y).unwrap().max <= 1e-9);
    }
}

#[test]
fn one_shot_deform_matches_the_session() {
    let ex = generate("fan", 0).unwrap();
    let (mut handles, transforms) = random_edit(&ex.mesh, 5);
    handles[1].transform = Some(transforms[1]);
    let o = DeformOptions::default();
    let r = deform(&ex.mesh, &ex.structure.symmetry, &handles, &[], &o).unwrap();
    let mut s = DeformSession::new(&ex.mesh, &ex.structure.symmetry, &o).unwrap();
    s.set_handles(&handles).unwrap();
    let y = s.solve(&transforms).unwrap();
    assert_eq!(r.positions, y);
    assert_eq!(r.fit.len(), 2);
    assert_eq!(r.stats.dof, s.stats().dof);
}

#[test]
fn sessions_are_deterministic() {
    let (mesh, _a, mut s1) = session("windmill", SymmetryMode::Preserve);
    let (_m, _a2, mut s2) = session("windmill", SymmetryMode::Preserve);
    let (h, t) = random_edit(&mesh, 2);
    s1.set_handles(&h).unwrap();
    s2.set_handles(&h).unwrap();
    assert_eq!(s1.solve(&t).unwrap(), s2.solve(&t).unwrap());
}

// ---------------------------------------------------------------------------------------------
// Errors.

#[test]
fn handle_errors_are_specific() {
    let (mesh, _ann, mut s) = session("fan", SymmetryMode::Preserve);
    assert!(matches!(s.solve(&[IDENTITY4]), Err(DeformError::HandlesNotSet)));
    assert!(matches!(s.set_handles(&[]), Err(DeformError::NoHandles)));
    let far = Handle::fixed(sphere([10.0, 10.0, 10.0], 0.01));
    assert!(matches!(s.set_handles(&[far]), Err(DeformError::EmptyRegion { .. })));
    let v = mesh.positions[17];
    let tiny = Handle::fixed(sphere(v, 1e-7));
    let e = s.set_handles(&[tiny]).unwrap_err();
    assert!(matches!(e, DeformError::HandleSelectsNoSample { handle: 0, .. }), "{e}");
    let h = Handle::fixed(sphere([0.0; 3], 0.06));
    let e = s.set_handles(&[h.clone(), h.clone()]).unwrap_err();
    assert!(matches!(e, DeformError::OverlappingHandles { first: 0, second: 1, .. }), "{e}");
    let bad_index = Handle::fixed(Region::Vertices(vec![1_000_000]));
    assert!(matches!(s.set_handles(&[bad_index]), Err(DeformError::IndexOutOfRange { .. })));
    s.set_handles(&[h]).unwrap();
    assert!(matches!(
        s.solve(&[IDENTITY4, IDENTITY4]),
        Err(DeformError::TransformCount { expected: 1, found: 2 })
    ));
    let mut nan = IDENTITY4;
    nan[0][3] = f64::NAN;
    assert!(matches!(s.solve(&[nan]), Err(DeformError::InvalidTransform { handle: 0 })));
    let mut projective = IDENTITY4;
    projective[3][0] = 1.0;
    assert!(matches!(s.solve(&[projective]), Err(DeformError::InvalidTransform { handle: 0 })));
    // Handles move rigidly: a scale, a flattening or a shear is refused.
    let mut scaled = IDENTITY4;
    scaled[0][0] = 1e10;
    let mut flat = IDENTITY4;
    flat[2][2] = 0.0;
    let mut shear = IDENTITY4;
    shear[0][1] = 0.5;
    for m in [scaled, flat, shear] {
        assert!(matches!(s.solve(&[m]), Err(DeformError::NonRigidTransform { handle: 0, .. })), "{m:?}");
    }
    // Enormous transforms: an error, and the previous positions stay (no NaN ever written).
    let before = s.positions().to_vec();
    let huge = translation([1e300, 1e300, 0.0]);
    assert!(matches!(s.solve(&[huge]), Err(DeformError::NonFinite)));
    assert_eq!(s.positions(), &before[..]);
    assert!(s.positions().iter().flatten().all(|c| c.is_finite()));
}

#[test]
fn unconstrained_parts_fail_without_regularisation() {
    let a = motif_core::procedural::box_mesh([0.0; 3], [1.0; 3], [2, 2, 2]).unwrap();
    let b = motif_core::procedural::box_mesh([5.0, 0.0, 0.0], [6.0, 1.0, 1.0], [2, 2, 2]).unwrap();
    let mut pos = a.positions.clone();
    let off = pos.len() as u32;
    pos.extend(&b.positions);
    let mut tri = a.triangles.clone();
    tri.extend(b.triangles.iter().map(|t| t.map(|i| i + off)));
    let mesh = TriMesh::new(pos, tri).unwrap();
    let ann = SymmetryAnnotation::default();
    let handles = [Handle::fixed(Region::Aabb { min: [-0.1; 3], max: [1.1, 0.3, 1.1] })];
    let mut o = DeformOptions::default();
    o.sampling.spacing = SampleSpacing::Count(120);
    o.editing.regularization = 0.0;
    let mut s = DeformSession::new(&mesh, &ann, &o).unwrap();
    assert!(s.stats().dof < 400, "dense path");
    let e = s.set_handles(&handles).unwrap_err();
    assert!(matches!(e, DeformError::Unconstrained { .. }), "{e}");
    // The sparse path (more unknowns) detects it too.
    o.sampling.spacing = SampleSpacing::Count(300);
    let mut s = DeformSession::new(&mesh, &ann, &o).unwrap();
    assert!(s.stats().dof >= 400, "sparse path");
    let e = s.set_handles(&handles).unwrap_err();
    assert!(matches!(e, DeformError::Unconstrained { .. }), "{e}");
    if let DeformError::Unconstrained { position, .. } = e {
        assert!(position[0] > 4.0, "the unconstrained part is the far box, got {position:?}");
    }
    // Well-posed systems pass the check without regularisation.
    for name in ["fan", "windmill", "shelf", "gear"] {
        let ex = generate(name, 0).unwrap();
        let mut o = DeformOptions::default();
        o.editing.regularization = 0.0;
        for mode in [SymmetryMode::Preserve, SymmetryMode::Ignore] {
            o.symmetry = mode;
            let mut s = DeformSession::new(&ex.mesh, &ex.structure.symmetry, &o).unwrap();
            let (h, t) = random_edit(&ex.mesh, 31);
            s.set_handles(&h).unwrap_or_else(|e| panic!("{name} {mode:?}: {e}"));
            s.solve(&t).unwrap();
        }
    }
    // With the default regularisation the free box simply stays.
    o.editing.regularization = 1e-8;
    let mut s = DeformSession::new(&mesh, &ann, &o).unwrap();
    s.set_handles(&handles).unwrap();
    let y = s.solve(&[translation([0.0, 0.5, 0.0])]).unwrap();
    for (p, x) in y.iter().zip(&mesh.positions).skip(off as usize) {
        assert!(dist(*p, *x) < 1e-6, "the unconstrained box moved");
    }
}

#[test]
fn annotation_errors_name_the_symmetry() {
    let ex = fan(&FanOptions::default()).unwrap();
    let o = DeformOptions::default();
    let with = |kind: SymmetryKind, name: &str| SymmetryAnnotation {
        symmetries: vec![motif_core::procedural::Symmetry { name: name.into(), kind }],
        ..Default::default()
    };
    let mut skew = IDENTITY4;
    skew[0][1] = 0.3;
    let e = DeformSession::new(
        &ex.mesh,
        &with(SymmetryKind::Group { region: Region::All, generators: vec![skew] }, "skewed"),
        &o,
    )
    .unwrap_err();
    assert!(matches!(e, DeformError::NonOrthogonal { .. }) && e.to_string().contains("skewed"), "{e}");
    let irrational = rotation_about([0.0, 0.0, 1.0], [0.0; 3], 1.0);
    let e = DeformSession::new(
        &ex.mesh,
        &with(SymmetryKind::Group { region: Region::All, generators: vec![irrational] }, "spin"),
        &o,
    )
    .unwrap_err();
    // A 1 rad rotation never closes, or closes within the tolerance only after 710 steps (113
    // turns), which is refused as no finite turn. Either way the symmetry is named.
    assert!(
        matches!(e, DeformError::GroupTooLarge { .. } | DeformError::NotAFiniteTurn { .. })
            && e.to_string().contains("spin"),
        "{e}"
    );
    let empty = Region::Sphere { center: [9.0; 3], radius: 0.1 };
    let e = DeformSession::new(
        &ex.mesh,
        &with(SymmetryKind::Group { region: empty, generators: vec![IDENTITY4] }, "nowhere"),
        &o,
    )
    .unwrap_err();
    assert!(matches!(e, DeformError::EmptyRegion { .. }) && e.to_string().contains("nowhere"), "{e}");
    // A wrong angle: 5 blades' rotation on a 6-blade fan.
    let wrong = rotation_about([0.0, 0.0, 1.0], [0.0; 3], std::f64::consts::TAU / 5.0);
    let ann = with(SymmetryKind::Group { region: Region::All, generators: vec![wrong] }, "five");
    let e = DeformSession::new(&ex.mesh, &ann, &o).unwrap_err();
    match &e {
        DeformError::SymmetryMismatch { symmetry, residual, .. } => {
            assert_eq!(symmetry, "five");
            assert!(*residual > 1e-3);
        }
        other => panic!("{other}"),
    }
    assert!(e.is_bad_input());
}

#[test]
fn forced_approximate_symmetry_is_exact_on_the_samples() {
    let ex = fan(&FanOptions::default()).unwrap();
    let near = rotation_about([0.0, 0.0, 1.0], [0.0; 3], std::f64::consts::TAU / 6.0 + 2e-3);
    // Tolerance large enough for the group to close, too small for the shape to pass.
    let ann = SymmetryAnnotation {
        tolerance: 2e-2,
        symmetries: vec![motif_core::procedural::Symmetry {
            name: "nearly".into(),
            kind: SymmetryKind::Group { region: Region::All, generators: vec![near] },
        }],
        ..Default::default()
    };
    let strict = DeformOptions::default();
    assert!(check_annotation(&ex.mesh, &ann).unwrap().symmetries[0].max_residual > 1e-4);
    let o = DeformOptions { validation: AnnotationValidation::Force, ..strict };
    let mut s = DeformSession::new(&ex.mesh, &ann, &o).unwrap();
    let (h, t) = random_edit(&ex.mesh, 9);
    s.set_handles(&h).unwrap();
    s.solve(&t).unwrap();
    let u = s.sample_displacements();
    let sm = s.sampling();
    for o in &sm.orbits {
        if o.basis.len() < 3 {
            continue;
        }
        let seed = u[o.start];
        for l in o.start..o.start + o.len {
            assert!(dist(mul3(&sm.frames[l], seed), u[l]) <= 1e-9 * ex.mesh.diagonal());
        }
    }
}

/// The windmill's mirror moved 0.3 off its plane (1.7% of the diagonal) and forced: with the
/// rotor's rotation it generates thousands of transforms, so the sample count cannot come near
/// the 400 asked at any radius. The radius search stops at twice the guess, where the handles
/// still hold samples (it grew the radius to a third of the diagonal, and a handle then held
/// none), and a warning says why the samples are many.
#[test]
fn a_forced_symmetry_with_a_huge_orbit_keeps_the_samples_dense() {
    let ex = generate("windmill", 0).unwrap();
    let mut ann = ex.structure.symmetry.clone();
    let SymmetryKind::Group { generators, .. } = &mut ann.symmetries[0].kind else { panic!("the mirror") };
    assert_eq!(generators[0][0][0], -1.0, "a mirror across x = 0");
    generators[0][0][3] += 0.3;
    let o = DeformOptions { validation: AnnotationValidation::Force, ..DeformOptions::default() };
    let mut s = DeformSession::new(&ex.mesh, &ann, &o).unwrap();
    let SampleSpacing::Count(asked) = o.sampling.spacing else { panic!("a count by default") };
    let guess = motif_deform::symmetric_sampling::radius_for_count(ex.mesh.area(), asked);
    assert!(s.sampling().radius <= 2.0 * guess * (1.0 + 1e-12), "{} vs {guess}", s.sampling().radius);
    assert!(s.warnings().iter().any(|w| w.contains("samples instead of about 400")), "{:?}", s.warnings());
    let (h, t) = random_edit(&ex.mesh, 4);
    s.set_handles(&h).unwrap();
    s.solve(&t).unwrap();
}

#[test]
fn check_annotation_reports_orders_and_residuals() {
    let ex = generate("gear", 0).unwrap();
    let r = check_annotation(&ex.mesh, &ex.structure.symmetry).unwrap();
    assert!(r.ok);
    let g = &r.symmetries[0];
    assert_eq!(g.kind, "group");
    assert_eq!(g.order, 68, "D17 × Z2");
    assert_eq!(g.transforms.len(), 67);
    for t in &g.transforms {
        assert!(t.residual <= 1e-12, "{t:?}");
        assert_eq!(t.matched_vertices, t.vertices);
    }
    let shelf = generate("shelf", 0).unwrap();
    let r = check_annotation(&shelf.mesh, &shelf.structure.symmetry).unwrap();
    assert_eq!(r.symmetries[0].kind, "instances");
    assert_eq!(r.symmetries[0].order, 12);
    assert_eq!(r.symmetries[0].transforms.len(), 22);
    // A bad symmetry is reported, not raised.
    let mut ann = ex.structure.symmetry.clone();
    let mut skew = IDENTITY4;
    skew[1][1] = 2.0;
    ann.symmetries.push(motif_core::procedural::Symmetry {
        name: "bad".into(),
        kind: SymmetryKind::Group { region: Region::All, generators: vec![skew] },
    });
    ann.symmetries.push(motif_core::procedural::Symmetry {
        name: "off".into(),
        kind: SymmetryKind::Group { region: Region::All, generators: vec![translation([0.0, 0.0, 0.001])] },
    });
    let r = check_annotation(&ex.mesh, &ann).unwrap();
    assert!(!r.ok);
    assert!(r.symmetries[1].problem.as_deref().unwrap_or("").contains("bad"));
    assert!(r.symmetries[2].problem.is_some(), "a translation generates an infinite group");
    assert!(serde_json::to_string(&r).is_ok());
}

#[test]
fn annotation_files_round_trip() {
    let ex = generate("windmill", 0).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("w.json");
    std::fs::write(&p, serde_json::to_string(&ex.structure.symmetry).unwrap()).unwrap();
    let back = motif_deform::read_annotation(&p).unwrap();
    // serde_json's default float parsing may differ from the written value in the last ulp.
    assert_eq!(back.symmetries.len(), ex.structure.symmetry.symmetries.len());
    let a = serde_json::to_value(&back).unwrap();
    let b = serde_json::to_value(&ex.structure.symmetry).unwrap();
    assert_eq!(a["symmetries"][2]["name"], b["symmetries"][2]["name"]);
    let r = check_annotation(&ex.mesh, &back).unwrap();
    assert!(r.ok);
    assert!(matches!(
        motif_deform::read_annotation(&dir.path().join("missing.json")),
        Err(DeformError::Io { .. })
    ));
}

// ---------------------------------------------------------------------------------------------
// Property: any rigid handle motion keeps the fan exactly symmetric.

static FAN: Mutex<Option<(DeformSession, SymmetryMaps)>> = Mutex::new(None);

proptest! {
    #![proptest_config(ProptestConfig { cases: 12, ..ProptestConfig::default() })]
    #[test]
    fn any_handle_motion_is_exactly_symmetric(
        angle in -3.0f64..3.0, ax in -1.0f64..1.0, ay in -1.0f64..1.0, tz in -0.2f64..0.2,
    ) {
        let mut guard = FAN.lock().unwrap_or_else(|e| e.into_inner());
        let (s, maps) = guard.get_or_insert_with(|| {
            let ex = fan(&FanOptions::default()).unwrap();
            let mut s = DeformSession::new(&ex.mesh, &ex.structure.symmetry, &DeformOptions::default()).unwrap();
            s.set_handles(&[Handle::fixed(sphere([0.0; 3], 0.06)), Handle::fixed(sphere([0.11, 0.19, 0.0], 0.05))]).unwrap();
            let maps = SymmetryMaps::new(&ex.mesh, &ex.structure.symmetry).unwrap();
            (s, maps)
        });
        let m = mat4_mul(&translation([0.0, 0.0, tz]), &rotation_about([ax, ay, 1.0], [0.11, 0.19, 0.0], angle));
        let y = s.solve(&[IDENTITY4, m]).unwrap().to_vec();
        prop_assert!(maps.residual(&y).unwrap().max <= 1e-9);
    }
}
