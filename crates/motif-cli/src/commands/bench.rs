//! `motif bench deform`: a table shaped like thesis Table 3.1 (vertices, triangles, groups,
//! samples, DoF, prefactor, solve for 5 iterations, lift, frames per second), on generated examples
//! and real meshes, with medians over many frames.

use std::path::{Path, PathBuf};
use std::time::Instant;

use motif_core::TriMesh;
use motif_core::geometry::{IDENTITY4, Mat4, mat4_mul, rotation_about_axis};
use motif_core::procedural::{self, Region, SymmetryAnnotation, translation};
use motif_deform::residual::SymmetryMaps;
use motif_deform::session::DeformOptions;
use motif_deform::symmetry_detect::{SymmetryDetectOptions, detect_symmetries};
use motif_deform::{DeformSession, Handle};
use serde::Serialize;

use super::deform::{Spread, spread};
use crate::cli::{BenchDeformArgs, GlobalArgs};
use crate::output::{bad_input, maybe_json, ms_since};

#[derive(Debug, Serialize)]
struct Row {
    model: String,
    annotation: &'static str,
    vertices: usize,
    triangles: usize,
    symmetries: usize,
    group_elements: usize,
    samples: usize,
    dof: usize,
    prefactor_ms: f64,
    solve_ms: Spread,
    lift_ms: Spread,
    frame_ms: Spread,
    fps: f64,
    residual: Option<f64>,
}

#[derive(Debug, Serialize)]
struct BenchReport {
    frames: usize,
    iterations: usize,
    handles: usize,
    threads: usize,
    rows: Vec<Row>,
}

/// The shared data folder for the rows of real models: `--data DIR` (which must be a folder),
/// else `$MOTIF_DATA` or `shared/data` above the current folder, else none.
pub(crate) fn data_dir(given: &Option<PathBuf>) -> anyhow::Result<Option<PathBuf>> {
    match given {
        Some(d) if !d.is_dir() => Err(crate::output::bad_input(format!(
            "--data {}: {}",
            d.display(),
            if d.exists() { "not a folder" } else { "no such folder" }
        ))),
        Some(d) => Ok(Some(d.clone())),
        // A MOTIF_DATA that names no folder is a mistake, as `--data` naming none is (the rows of
        // real models were skipped with a hint to set the variable that was set).
        None => match std::env::var_os("MOTIF_DATA").map(PathBuf::from) {
            Some(d) if !d.as_os_str().is_empty() && !d.is_dir() => Err(crate::output::bad_input(format!(
                "MOTIF_DATA={}: {}",
                d.display(),
                if d.exists() { "not a folder" } else { "no such folder" }
            ))),
            _ => Ok(motif_core::data::shared_data_dir(Path::new("."))),
        },
    }
}

/// Reads one of the shared meshes; a file missing from `--data` is named as such.
pub(crate) fn read_data_mesh(dir: &Path, rel: &str) -> anyhow::Result<TriMesh> {
    let path = dir.join(rel);
    if !path.exists() {
        return Err(crate::output::bad_input(format!(
            "{} has no {rel}: is it the shared data folder (its MANIFEST.json lists the models)?",
            dir.display()
        )));
    }
    Ok(motif_core::io::read_mesh(&path)?)
}

/// Four handles far apart (farthest-point picks among the vertices, starting at the extreme of the
/// longest bounding-box axis), spheres of up to 6% of the diagonal kept disjoint: the first two
/// fixed, the last two dragged (the set-up of the libigl ARAP timings we compare with).
fn four_handles(mesh: &TriMesh) -> Vec<Handle> {
    use motif_core::geometry::dist;
    let bb = mesh.aabb().expect("non-empty mesh");
    let e = bb.extent();
    let ax = (0..3).max_by(|&i, &j| e[i].total_cmp(&e[j])).unwrap_or(0);
    let first = mesh.positions.iter().copied().min_by(|p, q| p[ax].total_cmp(&q[ax])).unwrap_or(bb.min);
    let mut centres = vec![first];
    while centres.len() < 4 {
        let next = mesh
            .positions
            .iter()
            .copied()
            .max_by(|p, q| {
                let dp = centres.iter().map(|c| dist(*c, *p)).fold(f64::INFINITY, f64::min);
                let dq = centres.iter().map(|c| dist(*c, *q)).fold(f64::INFINITY, f64::min);
                dp.total_cmp(&dq)
            })
            .unwrap_or(bb.max);
        centres.push(next);
    }
    let mut min_gap = f64::INFINITY;
    for i in 0..4 {
        for j in i + 1..4 {
            min_gap = min_gap.min(dist(centres[i], centres[j]));
        }
    }
    let r = (0.06 * bb.diagonal()).min(0.45 * min_gap);
    centres.into_iter().map(|c| Handle::fixed(Region::Sphere { center: c, radius: r })).collect()
}

/// Frame `f` of `n`: the dragged handles rotate up to 30° about their own centre and rise.
fn frame_transforms(handles: &[Handle], diag: f64, f: usize, n: usize) -> Vec<Mat4> {
    let s = (f + 1) as f64 / n as f64;
    handles
        .iter()
        .enumerate()
        .map(|(i, h)| {
            if i < 2 {
                return IDENTITY4;
            }
            let c = match &h.region {
                Region::Sphere { center, .. } => *center,
                _ => [0.0; 3],
            };
            let sign = if i == 2 { 1.0 } else { -1.0 };
            let rot = motif_core::geometry::mat4_from_rt(
                rotation_about_axis([0.0, 0.0, 1.0], sign * s * 0.52),
                [0.0; 3],
            );
            let about = mat4_mul(&translation(c), &mat4_mul(&rot, &translation([-c[0], -c[1], -c[2]])));
            mat4_mul(&translation([0.0, 0.0, 0.1 * s * diag]), &about)
        })
        .collect()
}

fn bench_one(
    name: &str,
    label: &'static str,
    mesh: &TriMesh,
    annotation: &SymmetryAnnotation,
    frames: usize,
    options: &DeformOptions,
) -> anyhow::Result<Row> {
    let mut session = DeformSession::new(mesh, annotation, options)?;
    let handles = four_handles(mesh);
    session.set_handles(&handles)?;
    let prefactor_ms = session.stats().timings.prefactor_ms;
    let diag = mesh.diagonal();
    let (mut solve, mut lift, mut frame) = (Vec::new(), Vec::new(), Vec::new());
    for f in 0..frames {
        let tr = frame_transforms(&handles, diag, f, frames);
        let t = Instant::now();
        session.solve(&tr)?;
        frame.push(ms_since(t));
        solve.push(session.stats().timings.solve_ms);
        lift.push(session.stats().timings.lift_ms);
    }
    let residual = if annotation.symmetries.is_empty() {
        None
    } else {
        Some(SymmetryMaps::new(mesh, annotation)?.residual(session.positions())?.max)
    };
    let st = session.stats();
    let frame_ms = spread(&frame);
    Ok(Row {
        model: name.to_string(),
        annotation: label,
        vertices: mesh.num_vertices(),
        triangles: mesh.num_triangles(),
        symmetries: annotation.symmetries.len(),
        group_elements: session.annotation().elements().len(),
        samples: st.samples,
        dof: st.dof,
        prefactor_ms,
        solve_ms: spread(&solve),
        lift_ms: spread(&lift),
        fps: if frame_ms.median > 0.0 { 1000.0 / frame_ms.median } else { f64::INFINITY },
        frame_ms,
        residual,
    })
}

pub fn deform(a: BenchDeformArgs, g: &GlobalArgs) -> anyhow::Result<()> {
    crate::output::check_outputs(&[a.json.json.as_deref()], &[], g.force)?;
    if a.frames == 0 {
        return Err(bad_input("--frames 0: time at least one frame"));
    }
    let mut options = DeformOptions::default();
    options.sampling.seed = g.seed;
    let mut cases: Vec<(String, &'static str, TriMesh, SymmetryAnnotation)> = Vec::new();
    for name in ["fan", "gear", "chair", "windmill", "windmill_100k"] {
        let ex = procedural::generate(name, g.seed)?;
        cases.push((name.to_string(), "known", ex.mesh, ex.structure.symmetry));
    }
    if !a.generated_only {
        match data_dir(&a.data)? {
            Some(dir) => {
                for rel in [
                    "man-made/cgal_turbine.off",
                    "man-made/cgal_pinion.off",
                    "natural/cgal_armadillo.off",
                    "natural/cgal_armadillo_subdiv.ply",
                ] {
                    let mesh = read_data_mesh(&dir, rel)?;
                    let det = detect_symmetries(
                        &mesh,
                        &SymmetryDetectOptions { seed: g.seed, ..Default::default() },
                    )?;
                    cases.push((rel.to_string(), "detected", mesh, det.annotation));
                }
            }
            None => eprintln!("note: no ../shared/data (set MOTIF_DATA or --data); generated examples only"),
        }
    }
    let bar = crate::progress::Bar::new(g.quiet);
    motif_core::progress::Progress::start(&bar, "bench deform", cases.len() as u64);
    let mut rows = Vec::new();
    for (name, label, mesh, ann) in &cases {
        rows.push(bench_one(name, label, mesh, ann, a.frames, &options)?);
        motif_core::progress::Progress::inc(&bar, 1);
    }
    motif_core::progress::Progress::finish(&bar);
    let report = BenchReport {
        frames: a.frames,
        iterations: options.editing.iterations,
        handles: 4,
        threads: rayon::current_num_threads(),
        rows,
    };
    if !crate::output::json_on_stdout(&a.json.json) {
        println!(
            "Symmetry-preserving deformation, {} frames per model, {} co-rotated iterations per frame, 4 handles, {} threads",
            report.frames, report.iterations, report.threads
        );
        println!(
            "(thesis Table 3.1, one 2014 Xeon thread: 13-60 fps, prefactor 4 ms-4.2 s, solve < 1 ms per iteration for the fan)\n"
        );
        // The model column is as wide as its longest name (real meshes' names ran past 36).
        let labels: Vec<String> =
            report.rows.iter().map(|r| format!("{} ({})", r.model, r.annotation)).collect();
        let w = labels.iter().map(|l| l.chars().count()).max().unwrap_or(0).max(36);
        println!(
            "{:<w$} {:>7} {:>7} {:>5} {:>7} {:>5} {:>10} {:>10} {:>9} {:>9} {:>7} {:>9}",
            "model",
            "verts",
            "tris",
            "elems",
            "samples",
            "DoF",
            "prefac ms",
            "solve ms",
            "lift ms",
            "frame ms",
            "fps",
            "residual"
        );
        for (r, label) in report.rows.iter().zip(&labels) {
            println!(
                "{:<w$} {:>7} {:>7} {:>5} {:>7} {:>5} {:>10.1} {:>10.3} {:>9.3} {:>9.3} {:>7.0} {:>9}",
                label,
                r.vertices,
                r.triangles,
                r.group_elements,
                r.samples,
                r.dof,
                r.prefactor_ms,
                r.solve_ms.median,
                r.lift_ms.median,
                r.frame_ms.median,
                r.fps,
                r.residual.map_or("-".to_string(), |x| format!("{x:.1e}"))
            );
        }
        println!(
            "\nmedians over frames; elems = symmetry group elements besides the identity; residual = max |g(x+u) - (x+u)∘φ| over group elements, relative to the diagonal"
        );
    }
    maybe_json(&a.json.json, &report)
}

/// `motif bench studio`: runs `crates/motif-studio/e2e/bench.mjs` (playwright-core driving
/// Debian's Chromium) against this binary's `motif studio` and passes its table through. The
/// script lives in the source tree: this benchmark is for developers, like `cargo bench`.
pub fn studio(a: crate::cli::BenchStudioArgs, g: &GlobalArgs) -> anyhow::Result<()> {
    // Checked here, before a browser starts: a wrong example or a window of no size used to
    // hang the page until it was killed.
    if !motif_core::procedural::names().contains(&a.example.as_str()) {
        return Err(crate::output::bad_input(format!(
            "--example {}: no such example (`motif example --list` names them)",
            a.example
        )));
    }
    if a.steps == 0 {
        return Err(crate::output::bad_input("--steps 0: the benchmark needs at least one drag step"));
    }
    // The side panel takes 330 pixels of the width; the 3D view needs the rest.
    if !(480..=8192).contains(&a.width) || !(200..=8192).contains(&a.height) {
        return Err(crate::output::bad_input(format!(
            "--width {} --height {}: the window must be 480 to 8192 pixels wide (the side panel takes \
             330) and 200 to 8192 high",
            a.width, a.height
        )));
    }
    let script = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../motif-studio/e2e/bench.mjs");
    if !script.exists() {
        // A binary installed away from its source tree (the build machine's path is all it knows).
        return Err(crate::output::bad_input(
            "bench studio runs from Motif's source tree (crates/motif-studio/e2e/bench.mjs), which this \
             binary was not built in or which has moved: run it as `cargo run --release -- bench studio` \
             in a clone, after scripts/studio-browser-setup.sh",
        ));
    }
    let modules = script.with_file_name("node_modules").join("playwright-core");
    if !modules.exists() {
        return Err(crate::output::bad_input(format!(
            "{} is missing: run scripts/studio-browser-setup.sh first (installs chromium and playwright-core)",
            modules.display()
        )));
    }
    let exe = std::env::current_exe()?;
    let status = std::process::Command::new("node")
        .arg(&script)
        .arg(&exe)
        .args(["--steps", &a.steps.to_string(), "--example", &a.example, "--seed", &g.seed.to_string()])
        .args(["--width", &a.width.to_string(), "--height", &a.height.to_string()])
        .status()
        .map_err(|e| anyhow::anyhow!("cannot run node ({e}); install Node.js (Debian: nodejs)"))?;
    if !status.success() {
        anyhow::bail!("the studio benchmark failed ({status})");
    }
    Ok(())
}
