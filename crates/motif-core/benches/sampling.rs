//! Sampling benchmarks: Poisson-disc sampling of a 100k-point cloud and of a mesh surface at radii
//! giving about 10k samples, plus the surface sampling and resampling around them.
//!
//! Run with `cargo bench -p motif-core --bench sampling`.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use motif_core::PointCloud;
use motif_core::procedural;
use motif_core::sampling::{
    Constraints, PoissonDiscOptions, ResampleMethod, ResampleOptions, Spacing, poisson_disc_points,
    poisson_disc_surface, resample, sample_surface,
};

fn bench(c: &mut Criterion) {
    let mesh = procedural::generate("windmill", 0).expect("windmill").mesh;
    let cloud = sample_surface(&mesh, 100_000, 1).expect("cloud").points;
    let none = Constraints::default();
    // Radii that give about 10k samples, found once with the count mode.
    let count = |n| PoissonDiscOptions { spacing: Spacing::Count(n), ..Default::default() };
    let r_cloud = poisson_disc_points(&cloud, None, &none, &count(10_000)).expect("count").radius;
    let r_mesh = poisson_disc_surface(&mesh, &none, &count(10_000)).expect("count").radius;
    let at = |r| PoissonDiscOptions { spacing: Spacing::Radius(r), ..Default::default() };
    eprintln!(
        "cloud: r = {r_cloud:.5} -> {} samples; surface: r = {r_mesh:.5} -> {} samples ({} candidates)",
        poisson_disc_points(&cloud, None, &none, &at(r_cloud)).expect("run").len(),
        poisson_disc_surface(&mesh, &none, &at(r_mesh)).expect("run").len(),
        poisson_disc_surface(&mesh, &none, &at(r_mesh)).expect("run").num_candidates,
    );

    let mut g = c.benchmark_group("sampling");
    g.sample_size(20);
    g.bench_function("poisson_cloud_100k_to_10k", |b| {
        b.iter(|| poisson_disc_points(black_box(&cloud), None, &none, &at(r_cloud)).expect("run"))
    });
    g.bench_function("poisson_surface_windmill_10k", |b| {
        b.iter(|| poisson_disc_surface(black_box(&mesh), &none, &at(r_mesh)).expect("run"))
    });
    g.bench_function("poisson_cloud_100k_count_10k", |b| {
        b.iter(|| poisson_disc_points(black_box(&cloud), None, &none, &count(10_000)).expect("run"))
    });
    g.bench_function("sample_surface_100k", |b| {
        b.iter(|| sample_surface(black_box(&mesh), 100_000, 1).expect("run"))
    });
    let pc = PointCloud::from_positions(cloud.clone());
    for (name, method) in [
        ("resample_poisson_100k", ResampleMethod::PoissonDisc),
        ("resample_voxel_100k", ResampleMethod::VoxelGrid),
    ] {
        let o = ResampleOptions { spacing: r_cloud, method, seed: 0 };
        g.bench_function(name, |b| b.iter(|| resample(black_box(&pc), &o).expect("run")));
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
