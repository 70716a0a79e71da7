//! Benchmarks of symmetry-preserving deformation (thesis Table 3.1): prefactor (`set_handles`:
//! handle selection, assembly and Cholesky of eq. 3.4), one frame (`solve`: 5 co-rotated
//! iterations + lift), and the lift alone, on generated shapes with 4 handles and about 700
//! samples. `MOTIF_BENCH_SHAPES=fan,windmill` limits the shapes.

use std::hint::black_box;
use std::time::Instant;

use criterion::{Criterion, criterion_group, criterion_main};
use motif_core::TriMesh;
use motif_core::geometry::{IDENTITY4, Mat4, Point3, mat4_mul};
use motif_core::procedural::{
    Example, Region, WindmillOptions, generate, rotation_about, translation, windmill,
};
use motif_deform::{DeformOptions, DeformSession, Handle, SampleSpacing, SymmetryMode};

/// Samples of every benchmark session (the "700 samples").
const SAMPLES: usize = 700;

fn shape(name: &str) -> Example {
    match name {
        // Vertex count grows quadratically with the resolution (about 890 · resolution²):
        // 5 → 22k and 6 → 32k bracket libigl ARAP's 26k-vertex timing, 15 → 200k.
        "windmill_22k" => windmill(&WindmillOptions { resolution: 5, ..Default::default() }).unwrap(),
        "windmill_32k" => windmill(&WindmillOptions { resolution: 6, ..Default::default() }).unwrap(),
        "windmill_200k" => windmill(&WindmillOptions { resolution: 15, ..Default::default() }).unwrap(),
        _ => generate(name, 0).unwrap(),
    }
}

/// Four handles: spheres around the extreme vertices along −y (fixed), +y, −x and +x (moved).
fn four_handles(mesh: &TriMesh) -> (Vec<Handle>, Vec<Mat4>) {
    let d = mesh.diagonal();
    let pick = |key: &dyn Fn(&Point3) -> f64| -> Point3 {
        *mesh.positions.iter().max_by(|a, b| key(a).total_cmp(&key(b))).unwrap()
    };
    let ext = [pick(&|p| -p[1]), pick(&|p| p[1]), pick(&|p| -p[0]), pick(&|p| p[0])];
    let handles =
        ext.iter().map(|&c| Handle::fixed(Region::Sphere { center: c, radius: 0.06 * d })).collect();
    let t = vec![
        IDENTITY4,
        mat4_mul(&translation([0.0, 0.0, 0.1 * d]), &rotation_about([1.0, 0.0, 0.0], ext[1], 0.6)),
        rotation_about([0.0, 1.0, 0.0], ext[2], 0.8),
        mat4_mul(&translation([0.05 * d, 0.05 * d, 0.0]), &rotation_about([0.0, 0.0, 1.0], ext[3], -0.5)),
    ];
    (handles, t)
}

fn bench(c: &mut Criterion) {
    let names = std::env::var("MOTIF_BENCH_SHAPES")
        .unwrap_or_else(|_| "fan,windmill,windmill_22k,windmill_32k,windmill_100k,windmill_200k".into());
    for name in names.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let ex = shape(name);
        for mode in [SymmetryMode::Preserve, SymmetryMode::Ignore] {
            let mut o = DeformOptions { symmetry: mode, ..Default::default() };
            o.sampling.spacing = SampleSpacing::Count(SAMPLES);
            let t0 = Instant::now();
            let mut s = DeformSession::new(&ex.mesh, &ex.structure.symmetry, &o).unwrap();
            let setup = t0.elapsed().as_secs_f64() * 1e3;
            let (handles, transforms) = four_handles(&ex.mesh);
            s.set_handles(&handles).unwrap();
            s.solve(&transforms).unwrap();
            let st = s.stats().clone();
            let tag = match mode {
                SymmetryMode::Preserve => "sym",
                SymmetryMode::Ignore => "nosym",
            };
            eprintln!(
                "{name}/{tag}: {} vertices, {} samples, {} orbits, dof {}, SVDs/iteration {}, W rows {} nnz {}, session setup {setup:.0} ms \
                 (annotation {:.0}, sampling {:.0}, lift setup {:.0}, basis {:.0}), fit {:?}",
                st.vertices,
                st.samples,
                st.orbits,
                st.dof,
                st.rotation_fits,
                st.lift_rows,
                st.lift_nonzeros,
                st.timings.annotation_ms,
                st.timings.sampling_ms,
                st.timings.lift_setup_ms,
                st.timings.basis_ms,
                s.handle_fit().iter().map(|f| format!("{:.1e}", f.max_error)).collect::<Vec<_>>()
            );
            let mut g = c.benchmark_group(format!("deform/{name}/{tag}"));
            g.sample_size(10);
            g.warm_up_time(std::time::Duration::from_millis(500));
            g.measurement_time(std::time::Duration::from_secs(2));
            g.bench_function("prefactor", |b| b.iter(|| s.set_handles(black_box(&handles)).unwrap()));
            g.bench_function("frame (5 iterations + lift)", |b| {
                b.iter(|| {
                    black_box(s.solve(black_box(&transforms)).unwrap());
                })
            });
            let ubar = s.sample_displacements().to_vec();
            let mut out = ex.mesh.positions.clone();
            let mut work = vec![[0.0; 3]; s.lifting().num_rows()];
            g.bench_function("lift", |b| {
                b.iter(|| s.lifting().lift(black_box(&ubar), &ex.mesh.positions, &mut work, &mut out))
            });
            g.finish();
        }
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
