//! `motif convert`: format conversion.

use std::time::Instant;

use serde::Serialize;

use crate::cli::{ConvertArgs, GlobalArgs};
use crate::output::{maybe_json, ms_since};

#[derive(Debug, Serialize)]
struct ConvertReport {
    input: String,
    output: String,
    vertices: usize,
    triangles: usize,
    warnings: Vec<String>,
    ms: f64,
}

pub fn run(a: ConvertArgs, g: &GlobalArgs) -> anyhow::Result<()> {
    crate::output::check_outputs(&[Some(a.output()), a.json.json.as_deref()], &[&a.input], g.force)?;
    crate::output::check_output_formats(&[(Some(a.output()), crate::output::OutputKind::Model)])?;
    let t = Instant::now();
    let model = super::read_model(&a.input)?;
    let mut warnings: Vec<String> =
        model.warnings.iter().map(|w| format!("{}: {w}", a.input.display())).collect();
    let format = motif_core::io::Format::from_path(a.output())?;
    warnings.extend(
        motif_core::io::lost_in(format, &model.vertices)
            .into_iter()
            .map(|l| format!("{}: {l} could not be written", a.output().display())),
    );
    super::write_model(a.output(), &model, &[&a.input], g, &a.encoding)?;
    for w in &warnings {
        super::warn(w);
    }
    let r = ConvertReport {
        input: a.input.display().to_string(),
        output: a.output().display().to_string(),
        vertices: model.vertices.len(),
        triangles: model.triangles.len(),
        warnings,
        ms: ms_since(t),
    };
    if !crate::output::json_on_stdout(&a.json.json) {
        super::written(g, &r.output, format!("{} vertices, {} triangles", r.vertices, r.triangles));
    }
    maybe_json(&a.json.json, &r)
}
