//! Times the parts of one deformation frame on a generated shape (a profiling aid):
//! `cargo run --release -p motif-deform --example profile_frame -- fan 700`.

use std::time::Instant;

use motif_core::geometry::{IDENTITY4, mat4_mul};
use motif_core::procedural::{Region, generate, rotation_about, translation};
use motif_deform::{DeformOptions, DeformSession, Handle, SampleSpacing};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let name = args.get(1).map_or("fan", String::as_str);
    let count: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(700);
    let ex = generate(name, 0).expect("known example");
    let mut o = DeformOptions::default();
    o.sampling.spacing = SampleSpacing::Count(count);
    let mut s = DeformSession::new(&ex.mesh, &ex.structure.symmetry, &o).expect("session");
    let d = ex.mesh.diagonal();
    let lo = *ex.mesh.positions.iter().min_by(|a, b| a[1].total_cmp(&b[1])).expect("vertices");
    let hi = *ex.mesh.positions.iter().max_by(|a, b| a[1].total_cmp(&b[1])).expect("vertices");
    s.set_handles(&[
        Handle::fixed(Region::Sphere { center: lo, radius: 0.06 * d }),
        Handle::fixed(Region::Sphere { center: hi, radius: 0.06 * d }),
    ])
    .expect("handles");
    let t =
        [IDENTITY4, mat4_mul(&translation([0.0, 0.0, 0.1 * d]), &rotation_about([1.0, 0.0, 0.0], hi, 0.6))];
    s.solve(&t).expect("solve");
    let n = 50;
    let t0 = Instant::now();
    for _ in 0..n {
        s.solve(&t).expect("solve");
    }
    let frame = t0.elapsed().as_secs_f64() * 1e3 / n as f64;
    let samples = s.sampling().positions.clone();
    let def: Vec<_> = samples
        .iter()
        .zip(s.sample_displacements())
        .map(|(x, u)| [x[0] + u[0], x[1] + u[1], x[2] + u[2]])
        .collect();
    let mut rots = vec![[[0.0; 3]; 3]; samples.len()];
    let t0 = Instant::now();
    for _ in 0..n {
        s.graph().fit_rotations(&samples, &def, &mut rots);
    }
    let rot = t0.elapsed().as_secs_f64() * 1e3 / n as f64;
    let st = s.stats();
    println!(
        "{name}: {} vertices, {} samples, dof {}, edges {}: frame {frame:.3} ms (solve {:.3}, lift {:.3}), \
         rotations {rot:.3} ms per iteration",
        st.vertices, st.samples, st.dof, st.graph_edges, st.timings.solve_ms, st.timings.lift_ms
    );
}
