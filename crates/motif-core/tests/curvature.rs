//! Accuracy and invariance tests of normals, jet-fitting curvature and ICP on analytic shapes
//! generated here. Measured errors are printed (`cargo test -p motif-core --test curvature --
//! --nocapture`).

use std::f64::consts::{PI, TAU};

use motif_core::TriMesh;
use motif_core::curvature::{
    CurvatureOptions, CurvatureStatus, FittingFrame, Neighbourhood, PrincipalCurvature, Weighting,
    principal_curvatures_mesh, principal_curvatures_points,
};
use motif_core::geometry::{
    IDENTITY4, Mat4, Point3, add, cross, dot, mat4_from_rt, norm, normalize, rotation_about_axis, scale,
    transform_point, transform_vector,
};
use motif_core::icp::{IcpMetric, IcpMotion, IcpOptions, icp, icp_with_tree};
use motif_core::normals::{GraphWeight, NormalsOptions, Orientation, estimate_normals};
use motif_core::spatial::KdTree;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

// ---------------------------------------------------------------------------------------------
// Shapes with analytic normals (and curvature).

fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

fn unit_sphere_point(r: &mut ChaCha8Rng) -> Point3 {
    // Archimedes: z uniform in [−1, 1] and a uniform longitude give the uniform area measure.
    let z: f64 = r.random_range(-1.0..1.0);
    let phi: f64 = r.random_range(0.0..TAU);
    let s = (1.0 - z * z).max(0.0).sqrt();
    [s * phi.cos(), s * phi.sin(), z]
}

/// `n` points uniform on the sphere of `radius` around `center`, with outward normals.
fn sphere(n: usize, radius: f64, center: Point3, seed: u64) -> (Vec<Point3>, Vec<Point3>) {
    let mut r = rng(seed);
    let normals: Vec<Point3> = (0..n).map(|_| unit_sphere_point(&mut r)).collect();
    let points = normals.iter().map(|u| add(center, scale(*u, radius))).collect();
    (points, normals)
}

/// Torus around z with major radius `big_r` and tube radius `small_r`, area-uniform; returns
/// points, outward normals and the (φ, θ) parameters (θ = 0 on the outer equator).
fn torus(n: usize, big_r: f64, small_r: f64, seed: u64) -> (Vec<Point3>, Vec<Point3>, Vec<(f64, f64)>) {
    let mut r = rng(seed);
    let (mut p, mut nr, mut par) = (Vec::with_capacity(n), Vec::with_capacity(n), Vec::with_capacity(n));
    while p.len() < n {
        let phi: f64 = r.random_range(0.0..TAU);
        let theta: f64 = r.random_range(0.0..TAU);
        // The area element is ∝ R + r cos θ: rejection sampling.
        if r.random::<f64>() * (big_r + small_r) > big_r + small_r * theta.cos() {
            continue;
        }
        let (pt, normal) = torus_point(big_r, small_r, phi, theta);
        p.push(pt);
        nr.push(normal);
        par.push((phi, theta));
    }
    (p, nr, par)
}

fn torus_point(big_r: f64, small_r: f64, phi: f64, theta: f64) -> (Point3, Point3) {
    let normal = [theta.cos() * phi.cos(), theta.cos() * phi.sin(), theta.sin()];
    let centre = [big_r * phi.cos(), big_r * phi.sin(), 0.0];
    (add(centre, scale(normal, small_r)), normal)
}

/// Principal curvatures of the torus w.r.t. the outward normal: 1/r along the tube (θ), and
/// cos θ / (R + r cos θ) along the ring (φ); the first is always the larger.
fn torus_truth(big_r: f64, small_r: f64, theta: f64) -> (f64, f64) {
    (1.0 / small_r, theta.cos() / (big_r + small_r * theta.cos()))
}

fn torus_tube_direction(phi: f64, theta: f64) -> Point3 {
    [-theta.sin() * phi.cos(), -theta.sin() * phi.sin(), theta.cos()]
}

/// Open cylinder around z, radius `radius`, `z ∈ [−half, half]`.
fn cylinder(n: usize, radius: f64, half: f64, seed: u64) -> (Vec<Point3>, Vec<Point3>) {
    let mut r = rng(seed);
    let mut p = Vec::with_capacity(n);
    let mut nr = Vec::with_capacity(n);
    for _ in 0..n {
        let phi: f64 = r.random_range(0.0..TAU);
        let z: f64 = r.random_range(-half..half);
        p.push([radius * phi.cos(), radius * phi.sin(), z]);
        nr.push([phi.cos(), phi.sin(), 0.0]);
    }
    (p, nr)
}

/// The saddle `z = (x² − y²) / 2` over `[−half, half]²`, with upward normals.
fn saddle(n: usize, half: f64, seed: u64) -> (Vec<Point3>, Vec<Point3>) {
    let mut r = rng(seed);
    let mut p = Vec::with_capacity(n);
    let mut nr = Vec::with_capacity(n);
    for _ in 0..n {
        let x: f64 = r.random_range(-half..half);
        let y: f64 = r.random_range(-half..half);
        p.push([x, y, 0.5 * (x * x - y * y)]);
        nr.push(saddle_normal(x, y));
    }
    (p, nr)
}

fn saddle_normal(x: f64, y: f64) -> Point3 {
    normalize([-x, y, 1.0]).unwrap_or([0.0, 0.0, 1.0])
}

/// Analytic principal curvatures of the graph `z = (x² − y²)/2` w.r.t. the upward normal:
/// `κ = −eig(I⁻¹ II)`, `I = [[1+x², −xy], [−xy, 1+y²]]`, `II = diag(1, −1)/w`.
fn saddle_truth(x: f64, y: f64) -> (f64, f64) {
    let w = (1.0 + x * x + y * y).sqrt();
    let (e, f, g) = (1.0 + x * x, -x * y, 1.0 + y * y);
    let det_i = e * g - f * f;
    // I⁻¹ = [[g, −f], [−f, e]] / det; W = I⁻¹ II with II = diag(1/w, −1/w).
    let w11 = g / (w * det_i);
    let w22 = -e / (w * det_i);
    let w12 = f / (w * det_i);
    let w21 = -f / (w * det_i);
    let tr = w11 + w22;
    let det = w11 * w22 - w12 * w21;
    let disc = (0.25 * tr * tr - det).max(0.0).sqrt();
    let (l1, l2) = (0.5 * tr - disc, 0.5 * tr + disc);
    (-l1, -l2)
}

/// Closed box `[−a, a] × [−b, b] × [−c, c]`, area-uniform, with the outward face normals.
fn box_surface(n: usize, half: Point3, seed: u64) -> (Vec<Point3>, Vec<Point3>) {
    let mut r = rng(seed);
    let [a, b, c] = half;
    let areas = [b * c, a * c, a * b];
    let total: f64 = 2.0 * areas.iter().sum::<f64>();
    let mut p = Vec::with_capacity(n);
    let mut nr = Vec::with_capacity(n);
    for _ in 0..n {
        let mut pick = r.random::<f64>() * total;
        let mut axis = 0;
        let mut sign = 1.0;
        'outer: for (k, ar) in areas.iter().enumerate() {
            for s in [1.0, -1.0] {
                if pick < *ar {
                    axis = k;
                    sign = s;
                    break 'outer;
                }
                pick -= ar;
            }
        }
        let mut q = [r.random_range(-a..a), r.random_range(-b..b), r.random_range(-c..c)];
        q[axis] = sign * half[axis];
        let mut normal = [0.0; 3];
        normal[axis] = sign;
        p.push(q);
        nr.push(normal);
    }
    (p, nr)
}

/// A non-symmetric star-shaped blob: `r(u) = 1 + 0.25 uₓu_y + 0.2 u_z³ + 0.15 sin(3uₓ + 2u_z)`.
fn blob(n: usize, seed: u64) -> Vec<Point3> {
    let mut r = rng(seed);
    (0..n)
        .map(|_| {
            let u = unit_sphere_point(&mut r);
            let rad = 1.0 + 0.25 * u[0] * u[1] + 0.2 * u[2].powi(3) + 0.15 * (3.0 * u[0] + 2.0 * u[2]).sin();
            scale(u, rad)
        })
        .collect()
}

// ---------------------------------------------------------------------------------------------
// Meshes.

fn icosphere(subdivisions: usize) -> TriMesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v: Vec<Point3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|p| normalize(*p).unwrap())
    .collect();
    let mut f: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut mid = std::collections::HashMap::new();
        let mut nf = Vec::with_capacity(f.len() * 4);
        let mut midpoint = |a: u32, b: u32, v: &mut Vec<Point3>| -> u32 {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let m = normalize(add(v[a as usize], v[b as usize])).unwrap();
                v.push(m);
                (v.len() - 1) as u32
            })
        };
        for [a, b, c] in f {
            let ab = midpoint(a, b, &mut v);
            let bc = midpoint(b, c, &mut v);
            let ca = midpoint(c, a, &mut v);
            nf.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        f = nf;
    }
    TriMesh::new(v, f).unwrap()
}

/// A grid mesh of a parametric surface over `[0, nu) × [0, nv)`, periodic in the flagged
/// directions, counter-clockwise seen from the side of `∂u × ∂v`.
fn grid_mesh(nu: usize, nv: usize, wrap: (bool, bool), f: impl Fn(usize, usize) -> Point3) -> TriMesh {
    let mut v = Vec::with_capacity(nu * nv);
    for j in 0..nv {
        for i in 0..nu {
            v.push(f(i, j));
        }
    }
    let id = |i: usize, j: usize| ((j % nv) * nu + (i % nu)) as u32;
    let (iu, iv) = (if wrap.0 { nu } else { nu - 1 }, if wrap.1 { nv } else { nv - 1 });
    let mut t = Vec::new();
    for j in 0..iv {
        for i in 0..iu {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            t.push([a, b, c]);
            t.push([a, c, d]);
        }
    }
    TriMesh::new(v, t).unwrap()
}

// ---------------------------------------------------------------------------------------------
// Error statistics.

#[derive(Default)]
struct Stat {
    sum: f64,
    max: f64,
    n: usize,
}

impl Stat {
    fn add(&mut self, e: f64) {
        assert!(e.is_finite(), "non-finite error");
        self.sum += e;
        self.max = self.max.max(e);
        self.n += 1;
    }
    fn mean(&self) -> f64 {
        self.sum / self.n.max(1) as f64
    }
}

fn line_angle_deg(a: Point3, b: Point3) -> f64 {
    // angle between the lines: atan2(|a × b|, |a·b|), accurate near 0
    norm(cross(a, b)).atan2(dot(a, b).abs()).to_degrees()
}

fn assert_no_nan(out: &[PrincipalCurvature]) {
    for pc in out {
        assert!(pc.k1.is_finite() && pc.k2.is_finite() && pc.k1 >= pc.k2);
        for v in [pc.d1, pc.d2, pc.normal] {
            assert!((norm(v) - 1.0).abs() < 1e-9);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Normals.

fn outward_count(est: &[Point3], truth: &[Point3]) -> usize {
    est.iter().zip(truth).filter(|(a, b)| dot(**a, **b) > 0.0).count()
}

fn check_outward(name: &str, points: &[Point3], truth: &[Point3]) -> Vec<Point3> {
    let est = estimate_normals(points, &NormalsOptions::default()).unwrap();
    let good = outward_count(&est, truth);
    let mut angle = Stat::default();
    for (a, b) in est.iter().zip(truth) {
        angle.add(line_angle_deg(*a, *b));
    }
    println!(
        "normals {name}: {good}/{} outward ({:.3}%), mean angle error {:.3}°, max {:.2}°",
        points.len(),
        100.0 * good as f64 / points.len() as f64,
        angle.mean(),
        angle.max
    );
    assert!(good as f64 >= 0.999 * points.len() as f64, "{name}: only {good}/{} outward", points.len());
    est
}

#[test]
fn normals_outward_on_closed_shapes() {
    let (p, n) = sphere(20_000, 1.0, [0.3, -0.2, 0.5], 1);
    let est = check_outward("sphere", &p, &n);
    let mut angle = Stat::default();
    for (a, b) in est.iter().zip(&n) {
        angle.add(line_angle_deg(*a, *b));
    }
    assert!(angle.mean() < 0.5, "sphere mean angle error {}°", angle.mean());

    let (p, n, _) = torus(40_000, 1.0, 0.3, 2);
    check_outward("torus", &p, &n);

    let (p, n) = box_surface(30_000, [1.0, 0.6, 0.4], 3);
    check_outward("box (sharp edges)", &p, &n);

    let (mut p, mut n) = sphere(10_000, 1.0, [0.0; 3], 4);
    let (p2, n2) = sphere(5_000, 0.5, [3.0, 0.5, 0.0], 5);
    p.extend(p2);
    n.extend(n2);
    check_outward("two spheres", &p, &n);
}

#[test]
fn normals_thin_plate() {
    // A plate 0.04 thick sampled at ≈ 0.013 spacing: the kNN graph links its two sides, whose
    // normals are parallel; the tangent-penalised tree weight goes round the rim instead.
    let (p, n) = box_surface(30_000, [1.0, 0.6, 0.02], 9);
    let est = estimate_normals(&p, &NormalsOptions::default()).unwrap();
    let good = outward_count(&est, &n);
    let hoppe = NormalsOptions { graph_weight: GraphWeight::Hoppe, ..Default::default() };
    let plain = outward_count(&estimate_normals(&p, &hoppe).unwrap(), &n);
    println!(
        "normals thin plate (0.04 thick): {good}/{} outward with the tangent-penalised weight, {plain} with Hoppe's 1 − |nᵢ·nⱼ|",
        p.len()
    );
    assert!(good as f64 >= 0.999 * p.len() as f64);
}

#[test]
fn normals_noisy_sphere_accuracy() {
    let (p, n) = sphere(20_000, 1.0, [0.0; 3], 6);
    let mut r = rng(7);
    let sigma = 0.002;
    let noisy: Vec<Point3> = p
        .iter()
        .map(|q| {
            let g = [r.random::<f64>() - 0.5, r.random::<f64>() - 0.5, r.random::<f64>() - 0.5];
            add(*q, scale(g, sigma * 12f64.sqrt()))
        })
        .collect();
    check_outward("sphere, noise σ = 0.2% of R", &noisy, &n);
}

#[test]
fn normals_viewpoint_and_unoriented() {
    let (p, n) = sphere(5_000, 1.0, [0.0; 3], 8);
    let opts = NormalsOptions { orientation: Orientation::TowardsViewpoint([0.0; 3]), ..Default::default() };
    let est = estimate_normals(&p, &opts).unwrap();
    assert_eq!(outward_count(&est, &n), 0, "towards the centre = all inward");
    let opts = NormalsOptions { orientation: Orientation::Unoriented, ..Default::default() };
    let est = estimate_normals(&p, &opts).unwrap();
    for (a, b) in est.iter().zip(&n) {
        assert!(dot(*a, *b).abs() > 0.99);
    }
}

// ---------------------------------------------------------------------------------------------
// Curvature on point clouds.

fn sphere_errors(out: &[PrincipalCurvature], radius: f64) -> (f64, f64) {
    let (mut e1, mut e2) = (Stat::default(), Stat::default());
    for pc in out {
        assert_eq!(pc.status, CurvatureStatus::Fitted);
        e1.add((pc.k1 * radius - 1.0).abs());
        e2.add((pc.k2 * radius - 1.0).abs());
    }
    (e1.mean(), e2.mean())
}

#[test]
fn curvature_sphere_points() {
    let radius = 2.0;
    let (p, n) = sphere(20_000, radius, [1.0, 2.0, -3.0], 11);
    let opts = CurvatureOptions::default();
    let out = principal_curvatures_points(&p, Some(&n), &opts).unwrap();
    assert_no_nan(&out);
    let (e1, e2) = sphere_errors(&out, radius);
    println!(
        "curvature sphere (20k pts, k=15, given normals, PCA frame): κ₁ {:.4}%, κ₂ {:.4}%",
        100.0 * e1,
        100.0 * e2
    );
    assert!(e1 < 0.005 && e2 < 0.005);

    // Without normals: estimated and oriented outward, so the sign is still +1/R.
    let out = principal_curvatures_points(&p, None, &opts).unwrap();
    let (e1, e2) = sphere_errors(&out, radius);
    println!("curvature sphere (estimated normals): κ₁ {:.4}%, κ₂ {:.4}%", 100.0 * e1, 100.0 * e2);
    assert!(e1 < 0.005 && e2 < 0.005);

    // Frame from the exact normals, Gaussian weights, radius neighbourhoods: all accurate.
    for (label, o) in [
        ("reference-normal frame", CurvatureOptions { frame: FittingFrame::ReferenceNormal, ..opts.clone() }),
        (
            "gaussian σ=0.5h",
            CurvatureOptions { weighting: Weighting::Gaussian { sigma: 0.5 }, ..opts.clone() },
        ),
        ("radius 0.2", CurvatureOptions { neighbourhood: Neighbourhood::Radius(0.2), ..opts.clone() }),
    ] {
        let out = principal_curvatures_points(&p, Some(&n), &o).unwrap();
        let (e1, e2) = sphere_errors(&out, radius);
        println!("curvature sphere ({label}): κ₁ {:.4}%, κ₂ {:.4}%", 100.0 * e1, 100.0 * e2);
        assert!(e1 < 0.01 && e2 < 0.01);
    }

    // A fitting frame tilted 15° away from the tangent plane: the first-order jet terms absorb
    // the tilt, curvature and the output normal stay accurate.
    let tilted: Vec<Point3> = n
        .iter()
        .map(|v| {
            let axis = cross(*v, [0.3, 0.5, 0.8]);
            let r = rotation_about_axis(axis, 15f64.to_radians());
            [dot(r[0], *v), dot(r[1], *v), dot(r[2], *v)]
        })
        .collect();
    let o = CurvatureOptions { frame: FittingFrame::ReferenceNormal, ..opts.clone() };
    let out = principal_curvatures_points(&p, Some(&tilted), &o).unwrap();
    let (e1, e2) = sphere_errors(&out, radius);
    let worst_normal = out.iter().zip(&n).map(|(pc, v)| line_angle_deg(pc.normal, *v)).fold(0.0, f64::max);
    println!(
        "curvature sphere (frame tilted 15°): κ₁ {:.4}%, κ₂ {:.4}%, output normal max error {worst_normal:.3}°",
        100.0 * e1,
        100.0 * e2
    );
    assert!(e1 < 0.01 && e2 < 0.01 && worst_normal < 0.5);

    // The sign follows the reference normal: inward normals give −1/R.
    let inward: Vec<Point3> = n.iter().map(|v| scale(*v, -1.0)).collect();
    let out = principal_curvatures_points(&p, Some(&inward), &opts).unwrap();
    for pc in &out {
        assert!((pc.k1 * radius + 1.0).abs() < 0.02 && (pc.k2 * radius + 1.0).abs() < 0.02);
    }
    for (pc, v) in out.iter().zip(&inward) {
        assert!(dot(pc.normal, *v) > 0.99, "output normal on the reference side");
    }
}

#[test]
fn curvature_unit_sphere_cgal_setting() {
    // CGAL's example setting: unit sphere, 15 neighbours; CGAL reports ≈0.1% error.
    for n_pts in [10_000, 40_000] {
        let (p, n) = sphere(n_pts, 1.0, [0.0; 3], 12);
        let out = principal_curvatures_points(&p, Some(&n), &CurvatureOptions::default()).unwrap();
        let (e1, e2) = sphere_errors(&out, 1.0);
        println!("curvature unit sphere ({n_pts} pts, k=15): κ₁ {:.4}%, κ₂ {:.4}%", 100.0 * e1, 100.0 * e2);
        assert!(e1 < 0.003 && e2 < 0.003);
    }
}

#[test]
fn curvature_cylinder_points() {
    let radius = 0.5;
    let (p, n) = cylinder(20_000, radius, 2.0, 13);
    let out = principal_curvatures_points(&p, Some(&n), &CurvatureOptions::default()).unwrap();
    assert_no_nan(&out);
    let (mut e1, mut e2, mut a1, mut a2) =
        (Stat::default(), Stat::default(), Stat::default(), Stat::default());
    for ((q, pc), nr) in p.iter().zip(&out).zip(&n) {
        if q[2].abs() > 1.5 {
            continue; // one-sided neighbourhoods at the open ends
        }
        let k = 1.0 / radius;
        e1.add((pc.k1 - k).abs() / k);
        e2.add(pc.k2.abs() / k);
        let around = [-nr[1], nr[0], 0.0];
        a1.add(line_angle_deg(pc.d1, around));
        a2.add(line_angle_deg(pc.d2, [0.0, 0.0, 1.0]));
    }
    println!(
        "curvature cylinder (20k pts, k=15): κ₁ rel {:.4}%, |κ₂|/κ₁ {:.4}%, d₁ {:.3}° (max {:.2}°), d₂ {:.3}°",
        100.0 * e1.mean(),
        100.0 * e2.mean(),
        a1.mean(),
        a1.max,
        a2.mean()
    );
    assert!(e1.mean() < 0.02 && e2.mean() < 0.02 && a1.mean() < 2.0);
}

fn torus_errors(
    out: &[PrincipalCurvature],
    params: &[(f64, f64)],
    big_r: f64,
    small_r: f64,
) -> (f64, f64, f64) {
    let (mut e1, mut e2, mut a1) = (Stat::default(), Stat::default(), Stat::default());
    for (pc, &(phi, theta)) in out.iter().zip(params) {
        let (k1, k2) = torus_truth(big_r, small_r, theta);
        let scale_k = k1.abs().max(k2.abs());
        e1.add((pc.k1 - k1).abs() / scale_k);
        e2.add((pc.k2 - k2).abs() / scale_k);
        a1.add(line_angle_deg(pc.d1, torus_tube_direction(phi, theta)));
    }
    (e1.mean(), e2.mean(), a1.mean())
}

#[test]
fn curvature_torus_points() {
    let (big_r, small_r) = (1.0, 0.3);
    let (p, n, par) = torus(40_000, big_r, small_r, 14);
    let out = principal_curvatures_points(&p, Some(&n), &CurvatureOptions::default()).unwrap();
    assert_no_nan(&out);
    let (e1, e2, a1) = torus_errors(&out, &par, big_r, small_r);
    println!(
        "curvature torus (40k pts, k=15): κ₁ {:.4}%, κ₂ {:.4}% (of max |κ|), d₁ {:.3}°",
        100.0 * e1,
        100.0 * e2,
        a1
    );
    assert!(e1 < 0.02 && e2 < 0.02 && a1 < 2.0);
    // Inner equator is saddle-shaped: κ₂ < 0 there, > 0 outside.
    for (pc, &(_, theta)) in out.iter().zip(&par) {
        if theta.cos() < -0.5 {
            assert!(pc.k2 < 0.0);
        } else if theta.cos() > 0.5 {
            assert!(pc.k2 > 0.0);
        }
    }
}

#[test]
fn curvature_saddle_points() {
    let (mut p, mut n) = saddle(20_000, 1.0, 15);
    p[0] = [0.0; 3];
    n[0] = [0.0, 0.0, 1.0];
    let out = principal_curvatures_points(&p, Some(&n), &CurvatureOptions::default()).unwrap();
    assert_no_nan(&out);
    let (mut e1, mut e2) = (Stat::default(), Stat::default());
    for (q, pc) in p.iter().zip(&out) {
        if q[0].abs() > 0.5 || q[1].abs() > 0.5 {
            continue;
        }
        let (k1, k2) = saddle_truth(q[0], q[1]);
        let s = k1.abs().max(k2.abs());
        e1.add((pc.k1 - k1).abs() / s);
        e2.add((pc.k2 - k2).abs() / s);
    }
    println!(
        "curvature saddle (20k pts, |x|,|y| ≤ 0.5): κ₁ {:.4}%, κ₂ {:.4}% (of max |κ|)",
        100.0 * e1.mean(),
        100.0 * e2.mean()
    );
    assert!(e1.mean() < 0.02 && e2.mean() < 0.02);
    // At the origin κ = ±1 and κ₁ runs along y, where z = −y²/2 bends away from the upward
    // normal (convex seen from the normal's side ⇒ positive).
    let o = out[0];
    println!("  at the origin: κ₁ {:.5}, κ₂ {:.5}, d₁ {:?}", o.k1, o.k2, o.d1);
    assert!((o.k1 - 1.0).abs() < 0.01 && (o.k2 + 1.0).abs() < 0.01);
    assert!(line_angle_deg(o.d1, [0.0, 1.0, 0.0]) < 1.0);
}

#[test]
fn curvature_rigid_motion_invariance() {
    let (big_r, small_r) = (1.0, 0.3);
    let (p, n, _) = torus(8_000, big_r, small_r, 16);
    let m: Mat4 = mat4_from_rt(rotation_about_axis([0.3, -0.5, 0.8], 1.1), [5.0, -3.0, 12.0]);
    let p2: Vec<Point3> = p.iter().map(|q| transform_point(&m, *q)).collect();
    let n2: Vec<Point3> = n.iter().map(|v| transform_vector(&m, *v)).collect();
    for normals in [true, false] {
        let opts = CurvatureOptions::default();
        let a = principal_curvatures_points(&p, normals.then_some(&n[..]), &opts).unwrap();
        let b = principal_curvatures_points(&p2, normals.then_some(&n2[..]), &opts).unwrap();
        let mut worst: f64 = 0.0;
        let mut worst_dir: f64 = 0.0;
        for (x, y) in a.iter().zip(&b) {
            worst = worst.max((x.k1 - y.k1).abs()).max((x.k2 - y.k2).abs());
            worst_dir = worst_dir.max(line_angle_deg(transform_vector(&m, x.d1), y.d1));
            assert!(dot(transform_vector(&m, x.normal), y.normal) > 1.0 - 1e-9);
        }
        println!(
            "curvature rigid-motion invariance (normals given: {normals}): max |Δκ| {worst:.2e}, max Δd₁ {worst_dir:.2e}°"
        );
        assert!(worst < 1e-8 && worst_dir < 1e-4);
    }
}

// ---------------------------------------------------------------------------------------------
// Curvature on meshes.

#[test]
fn curvature_icosphere_mesh() {
    let mut mesh = icosphere(5);
    let radius = 1.5;
    for v in &mut mesh.positions {
        *v = scale(*v, radius);
    }
    let out = principal_curvatures_mesh(&mesh, &CurvatureOptions::default()).unwrap();
    assert_no_nan(&out);
    let (e1, e2) = sphere_errors(&out, radius);
    println!(
        "curvature icosphere mesh ({} verts), Knn(15): κ₁ {:.4}%, κ₂ {:.4}%",
        mesh.num_vertices(),
        100.0 * e1,
        100.0 * e2
    );
    assert!(e1 < 0.02 && e2 < 0.02);
    let rings = CurvatureOptions { neighbourhood: Neighbourhood::Rings(15), ..Default::default() };
    let out = principal_curvatures_mesh(&mesh, &rings).unwrap();
    let (e1, e2) = sphere_errors(&out, radius);
    println!("curvature icosphere mesh, Rings(15): κ₁ {:.4}%, κ₂ {:.4}%", 100.0 * e1, 100.0 * e2);
    assert!(e1 < 0.02 && e2 < 0.02);
    assert!(principal_curvatures_points(&mesh.positions, None, &rings).is_err());
}

#[test]
fn curvature_uv_sphere_mesh() {
    // A UV sphere crowds vertices along the rings near the poles; the jet still fits.
    let (nu, nv) = (128, 64);
    let mesh = {
        let mut v = vec![[0.0, 0.0, -1.0]];
        for j in 1..nv {
            let th = PI * j as f64 / nv as f64 - PI / 2.0;
            for i in 0..nu {
                let ph = TAU * i as f64 / nu as f64;
                v.push([th.cos() * ph.cos(), th.cos() * ph.sin(), th.sin()]);
            }
        }
        v.push([0.0, 0.0, 1.0]);
        let id = |i: usize, j: usize| (1 + (j - 1) * nu + i % nu) as u32;
        let top = (v.len() - 1) as u32;
        let mut t = Vec::new();
        for i in 0..nu {
            t.push([0, id(i + 1, 1), id(i, 1)]);
            t.push([top, id(i, nv - 1), id(i + 1, nv - 1)]);
        }
        for j in 1..nv - 1 {
            for i in 0..nu {
                t.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                t.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        TriMesh::new(v, t).unwrap()
    };
    // k nearest vertices: near the poles they all lie on one ring (a planar curve), which does
    // not determine a quadric; those vertices are flagged, never NaN.
    let out = principal_curvatures_mesh(&mesh, &CurvatureOptions::default()).unwrap();
    assert_no_nan(&out);
    let flagged = out.iter().filter(|pc| pc.status != CurvatureStatus::Fitted).count();
    let (mut e1, mut e2) = (Stat::default(), Stat::default());
    for pc in out.iter().filter(|pc| pc.status == CurvatureStatus::Fitted) {
        e1.add((pc.k1 - 1.0).abs());
        e2.add((pc.k2 - 1.0).abs());
    }
    println!(
        "curvature UV-sphere mesh ({} verts), Knn(15): {flagged} degenerate vertices flagged; on the rest κ₁ {:.4}%, κ₂ {:.4}%",
        mesh.num_vertices(),
        100.0 * e1.mean(),
        100.0 * e2.mean()
    );
    assert!(flagged < nu * 6);
    // Edge rings grown to ≥ 15 vertices spread in both directions everywhere.
    let rings = CurvatureOptions { neighbourhood: Neighbourhood::Rings(15), ..Default::default() };
    let out = principal_curvatures_mesh(&mesh, &rings).unwrap();
    assert_no_nan(&out);
    let (e1, e2) = sphere_errors(&out, 1.0);
    println!("curvature UV-sphere mesh, Rings(15): κ₁ {:.4}%, κ₂ {:.4}%", 100.0 * e1, 100.0 * e2);
    assert!(e1 < 0.02 && e2 < 0.02);
}

#[test]
fn curvature_torus_mesh() {
    let (big_r, small_r) = (1.0, 0.3);
    let (nu, nv) = (240, 72);
    let par = |i: usize, j: usize| (TAU * i as f64 / nu as f64, TAU * j as f64 / nv as f64);
    let mesh = grid_mesh(nu, nv, (true, true), |i, j| {
        let (phi, theta) = par(i, j);
        torus_point(big_r, small_r, phi, theta).0
    });
    let params: Vec<(f64, f64)> =
        (0..nv).flat_map(|j| (0..nu).map(move |i| (i, j))).map(|(i, j)| par(i, j)).collect();
    let out = principal_curvatures_mesh(&mesh, &CurvatureOptions::default()).unwrap();
    assert_no_nan(&out);
    let (e1, e2, a1) = torus_errors(&out, &params, big_r, small_r);
    println!(
        "curvature torus mesh ({} verts): κ₁ {:.4}%, κ₂ {:.4}% (of max |κ|), d₁ {:.3}°",
        mesh.num_vertices(),
        100.0 * e1,
        100.0 * e2,
        a1
    );
    assert!(e1 < 0.02 && e2 < 0.02 && a1 < 2.0);
}

#[test]
fn curvature_cylinder_mesh() {
    let (radius, nu, nv) = (0.5, 160, 161);
    let z = |j: usize| -2.0 + 4.0 * j as f64 / (nv - 1) as f64;
    let phi = |i: usize| TAU * i as f64 / nu as f64;
    let mesh = grid_mesh(nu, nv, (true, false), |i, j| [radius * phi(i).cos(), radius * phi(i).sin(), z(j)]);
    let out = principal_curvatures_mesh(&mesh, &CurvatureOptions::default()).unwrap();
    assert_no_nan(&out);
    let (mut e1, mut e2, mut a1) = (Stat::default(), Stat::default(), Stat::default());
    for (v, pc) in mesh.positions.iter().zip(&out) {
        if v[2].abs() > 1.5 {
            continue;
        }
        let k = 1.0 / radius;
        e1.add((pc.k1 - k).abs() / k);
        e2.add(pc.k2.abs() / k);
        let around = normalize([-v[1], v[0], 0.0]).unwrap();
        a1.add(line_angle_deg(pc.d1, around));
    }
    println!(
        "curvature cylinder mesh ({} verts): κ₁ rel {:.4}%, |κ₂|/κ₁ {:.4}%, d₁ {:.4}°",
        mesh.num_vertices(),
        100.0 * e1.mean(),
        100.0 * e2.mean(),
        a1.mean()
    );
    assert!(e1.mean() < 0.02 && e2.mean() < 0.02 && a1.mean() < 2.0);
}

#[test]
fn curvature_saddle_mesh() {
    let n = 101;
    let xy = |i: usize| -1.0 + 2.0 * i as f64 / (n - 1) as f64;
    let mesh = grid_mesh(n, n, (false, false), |i, j| {
        let (x, y) = (xy(i), xy(j));
        [x, y, 0.5 * (x * x - y * y)]
    });
    let out = principal_curvatures_mesh(&mesh, &CurvatureOptions::default()).unwrap();
    assert_no_nan(&out);
    let (mut e1, mut e2) = (Stat::default(), Stat::default());
    for (v, pc) in mesh.positions.iter().zip(&out) {
        if v[0].abs() > 0.5 || v[1].abs() > 0.5 {
            continue;
        }
        let (k1, k2) = saddle_truth(v[0], v[1]);
        let s = k1.abs().max(k2.abs());
        e1.add((pc.k1 - k1).abs() / s);
        e2.add((pc.k2 - k2).abs() / s);
        assert!(dot(pc.normal, saddle_normal(v[0], v[1])) > 0.999);
    }
    println!(
        "curvature saddle mesh (101² grid, |x|,|y| ≤ 0.5): κ₁ {:.4}%, κ₂ {:.4}%",
        100.0 * e1.mean(),
        100.0 * e2.mean()
    );
    assert!(e1.mean() < 0.02 && e2.mean() < 0.02);
}

// ---------------------------------------------------------------------------------------------
// ICP.

fn rotation_error_deg(a: &Mat4, b: &Mat4) -> f64 {
    // ‖R_a − R_b‖_F = 2√2 sin(θ/2), θ the angle of R_a R_bᵀ (accurate near 0, unlike acos).
    let mut f2 = 0.0;
    for i in 0..3 {
        for k in 0..3 {
            f2 += (a[i][k] - b[i][k]).powi(2);
        }
    }
    (2.0 * (f2.sqrt() / 8f64.sqrt()).min(1.0).asin()).to_degrees()
}

fn translation_error(a: &Mat4, b: &Mat4) -> f64 {
    norm([a[0][3] - b[0][3], a[1][3] - b[1][3], a[2][3] - b[2][3]])
}

fn inverse_rigid(m: &Mat4) -> Mat4 {
    let r: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|k| m[k][i]));
    let t = [m[0][3], m[1][3], m[2][3]];
    let rt = [-dot(r[0], t), -dot(r[1], t), -dot(r[2], t)];
    mat4_from_rt(r, rt)
}

fn random_motion(r: &mut ChaCha8Rng, degrees: f64, shift: f64) -> Mat4 {
    let axis = unit_sphere_point(r);
    let dir = unit_sphere_point(r);
    mat4_from_rt(rotation_about_axis(axis, degrees.to_radians()), scale(dir, shift))
}

struct IcpScene {
    target: Vec<Point3>,
    normals: Vec<Point3>,
}

fn icp_scene() -> IcpScene {
    let target = blob(20_000, 21);
    let normals = estimate_normals(&target, &NormalsOptions::default()).unwrap();
    IcpScene { target, normals }
}

/// A random subset of the target moved by `truth⁻¹`, so `target_from_source = truth`.
fn subset_source(scene: &IcpScene, n: usize, truth: &Mat4, seed: u64) -> Vec<Point3> {
    let mut r = rng(seed);
    let inv = inverse_rigid(truth);
    (0..n).map(|_| transform_point(&inv, scene.target[r.random_range(0..scene.target.len())])).collect()
}

#[test]
fn icp_recovers_rigid_motions() {
    let scene = icp_scene();
    let mut r = rng(22);
    for (degrees, shift) in [(3.0, 0.05), (20.0, 0.15)] {
        for trial in 0..3 {
            let truth = random_motion(&mut r, degrees, shift);
            let source = subset_source(&scene, 3_000, &truth, 100 + trial);
            for metric in [IcpMetric::PointToPoint, IcpMetric::PointToPlane] {
                let opts = IcpOptions { metric, max_iterations: 200, ..Default::default() };
                let res = icp(&source, &scene.target, Some(&scene.normals), &IDENTITY4, &opts).unwrap();
                let (er, et) =
                    (rotation_error_deg(&res.transform, &truth), translation_error(&res.transform, &truth));
                println!(
                    "icp {metric:?} {degrees}°/{shift}: rot err {er:.2e}°, trans err {et:.2e}, rmse {:.2e}, {} iters, converged {}",
                    res.rmse, res.iterations, res.converged
                );
                assert!(er < 1e-3 && et < 1e-4, "{metric:?} trial {trial}: {er}° {et}");
                assert!(res.converged);
                assert!((res.inlier_fraction - 0.9).abs() < 1e-3);
            }
        }
    }
}

#[test]
fn icp_translation_only() {
    let scene = icp_scene();
    let tree = KdTree::new(&scene.target).unwrap();
    let mut r = rng(23);
    for metric in [IcpMetric::PointToPoint, IcpMetric::PointToPlane] {
        for _ in 0..3 {
            let shift = scale(unit_sphere_point(&mut r), 0.1);
            let truth = mat4_from_rt([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], shift);
            let source = subset_source(&scene, 2_000, &truth, 200);
            let opts = IcpOptions {
                metric,
                motion: IcpMotion::TranslationOnly,
                max_iterations: 200,
                ..Default::default()
            };
            let res = icp_with_tree(&source, &scene.target, &tree, Some(&scene.normals), &IDENTITY4, &opts)
                .unwrap();
            let et = translation_error(&res.transform, &truth);
            println!("icp translation-only {metric:?}: trans err {et:.2e}, {} iters", res.iterations);
            assert!(et < 1e-4 && rotation_error_deg(&res.transform, &truth) == 0.0);
            // Same as the one-shot function.
            let one = icp(&source, &scene.target, Some(&scene.normals), &IDENTITY4, &opts).unwrap();
            assert_eq!(one, res);
        }
    }
}

#[test]
fn icp_trimming_rejects_outliers() {
    let scene = icp_scene();
    let mut r = rng(24);
    let truth = random_motion(&mut r, 10.0, 0.1);
    let mut source = subset_source(&scene, 2_400, &truth, 300);
    // 20% outliers spread over the (moved) bounding box.
    for _ in 0..600 {
        source.push([r.random_range(-1.5..1.5), r.random_range(-1.5..1.5), r.random_range(-1.5..1.5)]);
    }
    for metric in [IcpMetric::PointToPoint, IcpMetric::PointToPlane] {
        let trimmed = IcpOptions { metric, trim_fraction: 0.75, max_iterations: 200, ..Default::default() };
        let res = icp(&source, &scene.target, Some(&scene.normals), &IDENTITY4, &trimmed).unwrap();
        let (er, et) =
            (rotation_error_deg(&res.transform, &truth), translation_error(&res.transform, &truth));
        let untrimmed = IcpOptions { trim_fraction: 1.0, ..trimmed.clone() };
        let raw = icp(&source, &scene.target, Some(&scene.normals), &IDENTITY4, &untrimmed).unwrap();
        println!(
            "icp {metric:?} with 20% outliers: trimmed 0.75 → rot {er:.2e}°, trans {et:.2e}; untrimmed → rot {:.2}°, trans {:.2e}",
            rotation_error_deg(&raw.transform, &truth),
            translation_error(&raw.transform, &truth)
        );
        assert!(er < 1e-3 && et < 1e-4);
    }
}

#[test]
fn icp_residual_matches_noise() {
    // Independent samples of the same surface with Gaussian-like noise on the source: the
    // point-to-plane residual at the solution is the noise's normal component.
    let scene = IcpScene { target: blob(60_000, 31), normals: Vec::new() };
    let normals = estimate_normals(&scene.target, &NormalsOptions::default()).unwrap();
    let mut r = rng(32);
    let truth = random_motion(&mut r, 8.0, 0.1);
    let inv = inverse_rigid(&truth);
    let sigma = 0.004;
    let source: Vec<Point3> = blob(5_000, 33)
        .into_iter()
        .map(|p| {
            // Sum of 12 uniforms − 6 ≈ N(0, 1).
            let mut g = [0.0; 3];
            for c in &mut g {
                *c = (0..12).map(|_| r.random::<f64>()).sum::<f64>() - 6.0;
            }
            transform_point(&inv, add(p, scale(g, sigma)))
        })
        .collect();
    let opts = IcpOptions {
        metric: IcpMetric::PointToPlane,
        trim_fraction: 1.0,
        max_iterations: 100,
        ..Default::default()
    };
    let res = icp(&source, &scene.target, Some(&normals), &IDENTITY4, &opts).unwrap();
    let (er, et) = (rotation_error_deg(&res.transform, &truth), translation_error(&res.transform, &truth));
    println!(
        "icp point-to-plane on noisy independent samples (σ = {sigma}): rmse {:.5} ({:.2}σ), rot {er:.3}°, trans {et:.2e}",
        res.rmse,
        res.rmse / sigma
    );
    assert!(res.rmse > 0.85 * sigma && res.rmse < 1.25 * sigma);
    assert!(er < 0.1 && et < 2e-3);
    let trimmed =
        icp(&source, &scene.target, Some(&normals), &IDENTITY4, &IcpOptions { trim_fraction: 0.9, ..opts })
            .unwrap();
    println!("  with trim 0.9: rmse {:.5} ({:.2}σ)", trimmed.rmse, trimmed.rmse / sigma);
    assert!(trimmed.rmse < res.rmse);
}

// ---------------------------------------------------------------------------------------------
// Options round-trip through JSON (the CLI and studio read them from files).

#[test]
fn options_serde_round_trip() {
    let c = CurvatureOptions {
        neighbourhood: Neighbourhood::Radius(0.25),
        weighting: Weighting::Gaussian { sigma: 0.5 },
        frame: FittingFrame::ReferenceNormal,
        normals: NormalsOptions {
            orientation: Orientation::TowardsViewpoint([1.0, 2.0, 3.0]),
            ..Default::default()
        },
    };
    let back: CurvatureOptions = serde_json::from_str(&serde_json::to_string(&c).unwrap()).unwrap();
    assert_eq!(back, c);
    let i = IcpOptions {
        max_correspondence_distance: Some(0.1),
        motion: IcpMotion::TranslationOnly,
        ..Default::default()
    };
    let back: IcpOptions = serde_json::from_str(&serde_json::to_string(&i).unwrap()).unwrap();
    assert_eq!(back, i);
}
