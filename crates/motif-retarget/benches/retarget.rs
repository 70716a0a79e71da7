//! Retargeting benchmarks against thesis Fig. 4.8 (offsets vs the dense MRF of 4.5) and the
//! interactive size of 4.4 (~1,000 nodes, 30 labels).
//! Run: `cargo bench -p motif-retarget --bench retarget -- --warm-up-time 1 --measurement-time 5`.
//!
//! - `shelf_2x2/{offsets,dense}_total`: one-shot `retarget` of the generated 4×3 shelf by +2,+2
//!   (sampling, SHOT, distances, graph cut, stitching);
//! - `shelf_2x2/{offsets,dense}_reuse`: session built from the offset detection's features
//!   (`RetargetSession::with_features`, thesis 4.2.2: descriptors "can be reused here") and one
//!   solve: the retargeting step of the thesis's pipeline, without sampling and SHOT;
//! - `shelf_2x2/{offsets,dense}_solve`: a solve of a prepared `RetargetSession` whose distance
//!   cache is warm (graph cut and stitching: what an interactive resize costs);
//! - `interactive/offsets_solve`: a 30 × 20-cell shelf grown by +5,+4 (30 labels, ~900 nodes).
//!
//! Each case's report (nodes, labels, graph-cut and total ms) is printed once before measuring,
//! with the thesis's figures for comparison: with offsets 32–810 nodes, 3–9 labels, 8–72 ms of
//! graph cut; without, 924–7,429 nodes, 5–54 labels, 0.08–5.2 s.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use motif_core::geometry::Point3;
use motif_core::mesh::TriMesh;
use motif_core::procedural::{ShelfOptions, generate, shelf};
use motif_core::progress::NoProgress;
use motif_retarget::offsets::{OffsetOptions, prepare_features};
use motif_retarget::retarget::{RetargetMethod, RetargetOptions, RetargetReport, RetargetSession, retarget};

fn options(method: RetargetMethod) -> RetargetOptions {
    RetargetOptions { method, ..Default::default() }
}

fn print(name: &str, r: &RetargetReport) {
    eprintln!(
        "{name}: {} nodes, {} labels, {} edges, {} cycles, {} moves, energy {:.3}, graph cut {:.2} ms, solve {:.1} ms, total {:.1} ms \
         (voxelize {:.1}, sampling {:.1}, SHOT {:.1}, distances {:.1}, stitch {:.1} ms)",
        r.nodes,
        r.labels,
        r.edges,
        r.cycles,
        r.moves,
        r.energy,
        r.graph_cut_ms,
        r.solve_ms,
        r.total_ms,
        r.stages.voxelize_ms,
        r.stages.sampling_ms,
        r.stages.descriptors_ms,
        r.stages.distances_ms,
        r.stages.stitch_ms
    );
}

fn run_once(
    mesh: &TriMesh,
    pitch: &[Point3],
    steps: [i32; 3],
    method: RetargetMethod,
) -> Option<RetargetReport> {
    match retarget(mesh, pitch, steps, &options(method), &NoProgress) {
        Ok(r) => Some(r.report),
        Err(e) => {
            eprintln!("{method:?}: {e}");
            None
        }
    }
}

fn shelf_2x2(c: &mut Criterion) {
    let Ok(ex) = generate("shelf", 0) else { return };
    let pitch = ex.structure.cell_pitch.clone();
    let steps = [2, 2, 0];
    let reports: Vec<Option<RetargetReport>> = [RetargetMethod::Offsets, RetargetMethod::Dense]
        .iter()
        .map(|&m| run_once(&ex.mesh, &pitch, steps, m))
        .collect();
    if let [Some(o), Some(d)] = &reports[..] {
        print("shelf_2x2/offsets", o);
        print("shelf_2x2/dense", d);
        eprintln!(
            "shelf_2x2: offsets vs dense: graph cut {:.0}x faster, solve {:.1}x, total {:.1}x",
            d.graph_cut_ms / o.graph_cut_ms.max(1e-9),
            d.solve_ms / o.solve_ms.max(1e-9),
            d.total_ms / o.total_ms.max(1e-9)
        );
    }
    let features = prepare_features(&ex.mesh, &OffsetOptions::default(), &NoProgress).ok();
    let reuse = |method| {
        features.as_ref().and_then(|f| {
            RetargetSession::with_features(&ex.mesh, f, &pitch, &options(method), &NoProgress)
                .and_then(|mut s| s.retarget(steps, &NoProgress))
                .ok()
        })
    };
    if let (Some(o), Some(d)) = (reuse(RetargetMethod::Offsets), reuse(RetargetMethod::Dense)) {
        print("shelf_2x2/offsets_reuse", &o.report);
        print("shelf_2x2/dense_reuse", &d.report);
        eprintln!(
            "shelf_2x2 with the detection's features: offsets vs dense total {:.1}x faster",
            d.report.total_ms / o.report.total_ms.max(1e-9)
        );
    }
    let mut g = c.benchmark_group("shelf_2x2");
    g.sample_size(10);
    for (name, method) in [("offsets", RetargetMethod::Offsets), ("dense", RetargetMethod::Dense)] {
        g.bench_function(format!("{name}_total"), |b| {
            b.iter(|| retarget(&ex.mesh, &pitch, black_box(steps), &options(method), &NoProgress))
        });
        if let Some(f) = &features {
            g.bench_function(format!("{name}_reuse"), |b| {
                b.iter(|| {
                    RetargetSession::with_features(&ex.mesh, f, &pitch, &options(method), &NoProgress)
                        .and_then(|mut s| s.retarget(black_box(steps), &NoProgress))
                })
            });
        }
        let Ok(mut session) = RetargetSession::new(&ex.mesh, &pitch, &options(method), &NoProgress) else {
            continue;
        };
        // Warm the distance cache.
        let _ = session.retarget(steps, &NoProgress);
        g.bench_function(format!("{name}_solve"), |b| {
            b.iter(|| session.retarget(black_box(steps), &NoProgress))
        });
    }
    g.finish();
}

fn interactive(c: &mut Criterion) {
    let Ok(ex) = shelf(&ShelfOptions { cells: [30, 20], ..Default::default() }) else { return };
    let pitch = ex.structure.cell_pitch.clone();
    let steps = [5, 4, 0];
    let Ok(mut session) =
        RetargetSession::new(&ex.mesh, &pitch, &options(RetargetMethod::Offsets), &NoProgress)
    else {
        return;
    };
    match session.retarget(steps, &NoProgress) {
        Ok(r) => print("interactive/shelf_30x20_+5+4", &r.report),
        Err(e) => eprintln!("interactive: {e}"),
    }
    let mut g = c.benchmark_group("interactive");
    g.sample_size(10);
    g.bench_function("offsets_solve", |b| b.iter(|| session.retarget(black_box(steps), &NoProgress)));
    g.finish();
}

criterion_group!(benches, shelf_2x2, interactive);
criterion_main!(benches);
