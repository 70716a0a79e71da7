//! `motif example`: procedural shapes with known structure.

use motif_core::io::Model;
use motif_core::procedural;

use crate::cli::{ExampleArgs, GlobalArgs};
use crate::output::{bad_input, write_json};

pub fn run(a: ExampleArgs, g: &GlobalArgs) -> anyhow::Result<()> {
    if a.list {
        for name in procedural::names() {
            println!("{name}");
        }
        return Ok(());
    }
    let (Some(name), Some(output)) = (a.name, a.output) else {
        return Err(bad_input("usage: motif example NAME OUT (or motif example --list)"));
    };
    let ex = procedural::generate(&name, g.seed)?;
    let model = Model::from_mesh(&ex.mesh);
    super::write_model(&output, &model, &[], g, &super::write_options(&a.encoding))?;
    if let Some(s) = &a.structure {
        crate::output::check_output(s, &[&output], g.force)?;
        write_json(s, &ex.structure)?;
    }
    if let Some(p) = &a.annotation {
        crate::output::check_output(p, &[&output], g.force)?;
        write_json(p, &ex.structure.symmetry)?;
    }
    if let Some(p) = &a.handles {
        crate::output::check_output(p, &[&output], g.force)?;
        let text = sample_drag(&ex.mesh).to_json();
        motif_core::io::write_atomic(p, |w| w.write_all(text.as_bytes()))?;
    }
    super::note(
        g,
        format!(
            "wrote {} ({}: {} vertices, {} triangles{})",
            output.display(),
            ex.name,
            ex.mesh.num_vertices(),
            ex.mesh.num_triangles(),
            a.structure.as_ref().map(|s| format!("; structure in {}", s.display())).unwrap_or_default()
        ),
    );
    Ok(())
}

/// One end of the longest bounding-box axis fixed, the other end lifted along the shortest axis by
/// up to 15% of the diagonal over 30 frames (spheres of 5% of the diagonal).
fn sample_drag(mesh: &motif_core::TriMesh) -> motif_deform::HandlesFile {
    use motif_core::procedural::{Region, translation};
    use motif_deform::{Handle, HandlesFile};
    let bb = mesh.aabb().unwrap_or(motif_core::Aabb { min: [0.0; 3], max: [1.0; 3] });
    let e = bb.extent();
    let long = (0..3).max_by(|&i, &j| e[i].total_cmp(&e[j])).unwrap_or(0);
    let short = (0..3).min_by(|&i, &j| e[i].total_cmp(&e[j])).unwrap_or(2);
    let end = |sign: f64| {
        mesh.positions
            .iter()
            .copied()
            .max_by(|p, q| (sign * p[long]).total_cmp(&(sign * q[long])))
            .unwrap_or(bb.center())
    };
    let r = 0.05 * bb.diagonal();
    let handles = vec![
        Handle::fixed(Region::Sphere { center: end(-1.0), radius: r }),
        Handle::fixed(Region::Sphere { center: end(1.0), radius: r }),
    ];
    let mut file = HandlesFile::new(handles);
    file.frames = (1..=30)
        .map(|f| {
            let mut t = [0.0; 3];
            t[short] = 0.15 * bb.diagonal() * f as f64 / 30.0;
            vec![motif_core::geometry::IDENTITY4, translation(t)]
        })
        .collect();
    file
}
