//! Benchmarks of normals, jet-fitting curvature and ICP on generated shapes:
//! `cargo bench -p motif-core --bench curvature`.

use std::f64::consts::TAU;
use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use motif_core::curvature::{CurvatureOptions, principal_curvatures_points};
use motif_core::geometry::{IDENTITY4, Point3, mat4_from_rt, rotation_about_axis, scale, transform_point};
use motif_core::icp::{IcpMetric, IcpOptions, icp};
use motif_core::normals::{NormalsOptions, estimate_normals};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Area-uniform torus (R = 1, r = 0.3) with outward normals.
fn torus(n: usize, seed: u64) -> (Vec<Point3>, Vec<Point3>) {
    let (big_r, small_r) = (1.0, 0.3);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (mut p, mut nr) = (Vec::with_capacity(n), Vec::with_capacity(n));
    while p.len() < n {
        let phi: f64 = rng.random_range(0.0..TAU);
        let theta: f64 = rng.random_range(0.0..TAU);
        if rng.random::<f64>() * (big_r + small_r) > big_r + small_r * theta.cos() {
            continue;
        }
        let normal = [theta.cos() * phi.cos(), theta.cos() * phi.sin(), theta.sin()];
        p.push([
            big_r * phi.cos() + small_r * normal[0],
            big_r * phi.sin() + small_r * normal[1],
            small_r * normal[2],
        ]);
        nr.push(normal);
    }
    (p, nr)
}

/// A non-symmetric star-shaped blob (the ICP test shape).
fn blob(n: usize, seed: u64) -> Vec<Point3> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let z: f64 = rng.random_range(-1.0..1.0);
            let phi: f64 = rng.random_range(0.0..TAU);
            let s = (1.0 - z * z).sqrt();
            let u = [s * phi.cos(), s * phi.sin(), z];
            let rad = 1.0 + 0.25 * u[0] * u[1] + 0.2 * u[2].powi(3) + 0.15 * (3.0 * u[0] + 2.0 * u[2]).sin();
            scale(u, rad)
        })
        .collect()
}

fn benches(c: &mut Criterion) {
    let (points, normals) = torus(100_000, 1);
    let mut g = c.benchmark_group("geometry_100k");
    g.sample_size(10);
    g.bench_function("curvature_torus_100k_k15_given_normals", |b| {
        b.iter(|| {
            principal_curvatures_points(black_box(&points), Some(&normals), &CurvatureOptions::default())
        })
    });
    g.bench_function("curvature_torus_100k_k15_estimated_normals", |b| {
        b.iter(|| principal_curvatures_points(black_box(&points), None, &CurvatureOptions::default()))
    });
    g.bench_function("normals_torus_100k_k16_consistent", |b| {
        b.iter(|| estimate_normals(black_box(&points), &NormalsOptions::default()))
    });
    g.finish();

    let target = blob(20_000, 2);
    let target_normals = estimate_normals(&target, &NormalsOptions::default()).unwrap_or_default();
    let motion = mat4_from_rt(rotation_about_axis([0.2, 1.0, -0.4], 10f64.to_radians()), [0.05, -0.08, 0.1]);
    let source: Vec<Point3> = blob(20_000, 3).iter().map(|p| transform_point(&motion, *p)).collect();
    let opts = IcpOptions { metric: IcpMetric::PointToPlane, ..Default::default() };
    let mut g = c.benchmark_group("icp_20k");
    g.sample_size(10);
    g.bench_function("icp_point_to_plane_20k", |b| {
        b.iter(|| icp(black_box(&source), &target, Some(&target_normals), &IDENTITY4, &opts))
    });
    g.finish();
}

criterion_group!(curvature, benches);
criterion_main!(curvature);
