//! kd-tree and descriptor nearest-neighbour benchmarks on a 100k-point cloud.
//! Run: `cargo bench -p motif-core --bench kdtree`.

use criterion::{Criterion, criterion_group, criterion_main};
use motif_core::spatial::{DescriptorNnOptions, KdTree, descriptor_nn};
use rand::{Rng, SeedableRng};
use std::hint::black_box;

/// 100k points on a torus (R = 1, r = 0.3): a surface-like cloud, as scans are.
fn torus_cloud(n: usize) -> Vec<[f64; 3]> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(42);
    (0..n)
        .map(|_| {
            let u: f64 = rng.random::<f64>() * std::f64::consts::TAU;
            let v: f64 = rng.random::<f64>() * std::f64::consts::TAU;
            let w = 1.0 + 0.3 * v.cos();
            [w * u.cos(), w * u.sin(), 0.3 * v.sin()]
        })
        .collect()
}

fn kdtree(c: &mut Criterion) {
    let pts = torus_cloud(100_000);
    let tree = KdTree::new(&pts).unwrap();
    let mut g = c.benchmark_group("kdtree_100k");
    g.sample_size(10);
    g.bench_function("build", |b| b.iter(|| KdTree::new(black_box(&pts)).unwrap()));
    g.bench_function("nearest_100k_queries", |b| b.iter(|| tree.nearest_batch(black_box(&pts))));
    g.bench_function("knn16_100k_queries", |b| b.iter(|| tree.knn_batch(black_box(&pts), 16)));
    // ~30 neighbours per query at this density.
    g.bench_function("radius0.02_100k_queries", |b| b.iter(|| tree.within_batch(black_box(&pts), 0.02)));
    g.finish();

    // A scan whose invalid returns all sit at the origin: half the points coincide. Before
    // coincident points were stored once, these queries were quadratic in the heap's size.
    let mut scan = torus_cloud(50_000);
    scan.extend(std::iter::repeat_n([0.0, 0.0, 0.0], 50_000));
    let tree = KdTree::new(&scan).unwrap();
    let mut g = c.benchmark_group("kdtree_100k_half_coincident");
    g.sample_size(10);
    g.bench_function("build", |b| b.iter(|| KdTree::new(black_box(&scan)).unwrap()));
    g.bench_function("knn16_100k_queries", |b| b.iter(|| tree.knn_batch(black_box(&scan), 16)));
    g.finish();
}

fn descriptors(c: &mut Criterion) {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let dim = 352;
    let n = 10_000;
    let d: Vec<f32> = (0..n * dim).map(|_| rng.random()).collect();
    let mut g = c.benchmark_group("descriptor_nn");
    g.sample_size(10);
    g.bench_function("shot352_10k_vs_10k", |b| {
        b.iter(|| {
            descriptor_nn(black_box(&d), black_box(&d), dim, true, &DescriptorNnOptions::default()).unwrap()
        })
    });
    g.finish();
}

criterion_group!(benches, kdtree, descriptors);
criterion_main!(benches);
