//! Offset statistics per stage on ~100k-vertex models: the procedural `windmill_100k` and, when
//! the shared data is present (`MOTIF_DATA` or `shared/data` above the crate),
//! `pyb_diff_ring_subdiv.ply` (115k vertices). The target (brief of the offsets issue): the whole
//! analysis under 2 s in release.
//!
//! Stages: `prepare` (normalise, sample both scales, kd-tree, SHOT), `match` (eq. 4.1),
//! `histogram` (binning and peaks), `analyze_features` (matching, histogram, ICP refinement,
//! principal offsets, verdict; the ICP share is this minus `match` and `histogram`), and `full`.

use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use motif_core::mesh::TriMesh;
use motif_core::progress::NoProgress;
use motif_retarget::offsets::{
    OffsetHistogram, OffsetOptions, analyze_features, analyze_offsets, match_features, prepare_features,
};

fn data_dir() -> Option<PathBuf> {
    motif_core::data::shared_data_dir(Path::new(env!("CARGO_MANIFEST_DIR")))
}

fn models() -> Vec<(String, TriMesh)> {
    let mut out = Vec::new();
    if let Ok(ex) = motif_core::procedural::generate("windmill_100k", 0) {
        out.push(("windmill_100k".to_string(), ex.mesh));
    }
    if let Some(dir) = data_dir() {
        if let Ok(m) = motif_core::io::read_mesh(&dir.join("man-made/pyb_diff_ring_subdiv.ply")) {
            out.push(("diff_ring_subdiv".to_string(), m));
        }
    }
    out
}

fn bench(c: &mut Criterion) {
    let options = OffsetOptions::default();
    let mut group = c.benchmark_group("offsets");
    group.sample_size(10).measurement_time(Duration::from_secs(12)).warm_up_time(Duration::from_secs(2));
    for (name, mesh) in models() {
        let features = prepare_features(&mesh, &options, &NoProgress).expect("features");
        let a = analyze_offsets(&mesh, &options, &NoProgress).expect("analysis");
        eprintln!(
            "{name}: {} vertices, {} dense, {} features; one run: {:?}",
            mesh.positions.len(),
            features.dense.len(),
            features.len(),
            a.timings
        );
        let matches = match_features(&features, &[options.tau], &NoProgress).expect("matches");
        group.bench_function(format!("{name}/prepare"), |b| {
            b.iter(|| prepare_features(black_box(&mesh), &options, &NoProgress).expect("features"))
        });
        group.bench_function(format!("{name}/match"), |b| {
            b.iter(|| match_features(black_box(&features), &[options.tau], &NoProgress).expect("matches"))
        });
        group.bench_function(format!("{name}/histogram"), |b| {
            b.iter(|| {
                let h = OffsetHistogram::from_offsets(
                    matches[0].iter().map(|m| m.offset),
                    options.bin_size,
                    options.sign,
                );
                h.peaks(options.nms_radius, options.min_peak_support)
            })
        });
        group.bench_function(format!("{name}/analyze_features"), |b| {
            b.iter(|| analyze_features(black_box(&features), &options, &NoProgress).expect("analysis"))
        });
        group.bench_function(format!("{name}/full"), |b| {
            b.iter(|| analyze_offsets(black_box(&mesh), &options, &NoProgress).expect("analysis"))
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
