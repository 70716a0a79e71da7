//! `motif features shot`: SHOT descriptors as CSV or the binary PEERSHOT layout.

use std::time::Instant;

use motif_core::TriMesh;
use motif_core::shot::{ShotFrame, ShotOptions, compute_shot_with_tree, write_peershot, write_shot_csv};
use motif_core::spatial::KdTree;
use serde::Serialize;

use crate::cli::{FrameArg, GlobalArgs, ShotArgs};
use crate::output::{bad_input, maybe_json, ms_since};
use crate::progress::Bar;

#[derive(Debug, Serialize)]
struct ShotReport {
    input: String,
    output: String,
    points: usize,
    normals: &'static str,
    options: ShotOptions,
    keypoints: usize,
    valid: usize,
    ms: f64,
    ms_per_keypoint: f64,
}

pub fn run_shot(a: ShotArgs, g: &GlobalArgs) -> anyhow::Result<()> {
    let inputs: Vec<&std::path::Path> =
        std::iter::once(a.input.as_path()).chain(a.keypoints.as_deref()).collect();
    crate::output::check_outputs(&[Some(&a.output), a.json.json.as_deref()], &inputs, g.force)?;
    // `.csv` is text, anything else the binary PEERSHOT layout; a name that says another kind of
    // file (a model, a picture, JSON) would hold bytes no reader of that kind takes.
    let name = a.output.to_string_lossy();
    let ext = a.output.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    if crate::cli::model_extension(&name).is_some() || ext == "json" {
        return Err(bad_input(format!(
            "{}: descriptors are written as CSV (.csv) or in the binary PEERSHOT layout (.bin, .shot, ...), \
             not as .{ext}",
            a.output.display()
        )));
    }
    if let Some(0) = a.every {
        return Err(bad_input("--every 0: use a positive step"));
    }
    let model = super::read_model_for_geometry(&a.input)?;
    let n = model.vertices.len();
    let (normals, source) = match (&model.vertices.normals, model.is_mesh()) {
        (Some(nr), _) => (nr.clone(), "from the input"),
        (None, true) => (
            TriMesh { positions: model.vertices.positions.clone(), triangles: model.triangles.clone() }
                .vertex_normals(),
            "area-weighted vertex normals",
        ),
        (None, false) => {
            return Err(bad_input(format!(
                "{}: a point cloud without normals (run `motif normals` first)",
                a.input.display()
            )));
        }
    };
    let keypoints: Vec<usize> = match (&a.keypoints, a.every) {
        (Some(path), _) => read_keypoints(path, n)?,
        (None, Some(k)) => (0..n).step_by(k).collect(),
        (None, None) => return Err(bad_input("give --keypoints FILE or --every K")),
    };
    if !(a.radius > 0.0 && a.radius.is_finite()) {
        return Err(bad_input(format!(
            "--radius {}: the SHOT support radius must be a positive number (model units; {} is {:.4} across)",
            a.radius,
            a.input.display(),
            model.vertices.diagonal()
        )));
    }
    let options = ShotOptions {
        radius: a.radius,
        frame: match a.frame {
            FrameArg::Lrf => ShotFrame::Lrf,
            FrameArg::World => ShotFrame::World,
        },
        ..Default::default()
    };
    options.validate()?;
    let t = Instant::now();
    let tree = KdTree::new(&model.vertices.positions)?;
    let bar = Bar::new(g.quiet);
    let shots =
        compute_shot_with_tree(&tree, &model.vertices.positions, &normals, &keypoints, &options, &bar)?;
    let ms = ms_since(t);
    // No valid descriptor is a failure, not a file of invalid ones (it used to exit 0 with one).
    if shots.num_valid() == 0 && !shots.is_empty() {
        return Err(crate::output::bad_input(format!(
            "{}: none of the {} descriptors is valid: no keypoint has a neighbour within the support \
             radius {} (the model is {:.4} across); use a larger --radius",
            a.input.display(),
            shots.len(),
            a.radius,
            model.vertices.diagonal()
        )));
    }
    let csv = a.output.extension().is_some_and(|e| e.eq_ignore_ascii_case("csv"));
    motif_core::io::write_atomic(&a.output, |w| {
        let mut w = std::io::BufWriter::new(w);
        if csv { write_shot_csv(&mut w, &shots) } else { write_peershot(&mut w, &shots) }?;
        std::io::Write::flush(&mut w)
    })?;
    let r = ShotReport {
        input: a.input.display().to_string(),
        output: a.output.display().to_string(),
        points: n,
        normals: source,
        options,
        keypoints: shots.len(),
        valid: shots.num_valid(),
        ms,
        ms_per_keypoint: if shots.is_empty() { 0.0 } else { ms / shots.len() as f64 },
    };
    if !crate::output::json_on_stdout(&a.json.json) {
        super::written(
            g,
            &r.output,
            format!(
                "{} keypoints, {} valid, {} layout, {:.1} ms",
                r.keypoints,
                r.valid,
                if csv { "CSV" } else { "PEERSHOT" },
                r.ms
            ),
        );
    }
    maybe_json(&a.json.json, &r)
}

fn read_keypoints(path: &std::path::Path, n: usize) -> anyhow::Result<Vec<usize>> {
    let text = std::fs::read(path).map_err(|e| motif_core::Error::io(path, e))?;
    let text = String::from_utf8(text)
        .map_err(|_| bad_input(format!("{}: keypoint file is not UTF-8 text", path.display())))?;
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let s = line.trim();
        if s.is_empty() || s.starts_with('#') {
            continue;
        }
        let k: usize = s.parse().map_err(|_| {
            bad_input(format!("{}: line {}: {s:?} is not a point index", path.display(), i + 1))
        })?;
        if k >= n {
            return Err(bad_input(format!(
                "{}: line {}: index {k} is out of range (the input has {n} points)",
                path.display(),
                i + 1
            )));
        }
        out.push(k);
    }
    if out.is_empty() {
        return Err(bad_input(format!("{}: no keypoint indices", path.display())));
    }
    Ok(out)
}
