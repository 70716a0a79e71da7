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
