//! `motif bench retarget`: thesis Fig. 4.8 (retargeting with the detected offsets against the
//! dense MRF of 4.5) on the generated grid models and the grid-like real models of the shared data
//! (when present), the interactive size of 4.4 (~1,000 nodes and
//! 30 labels), and the alpha-expansion solver on `mrf_grid_v1` problems next to GCO's times.
//!
//! Every figure is a median over `--repeats` runs. The retargeting step is timed as the pipeline
//! runs it: a session built from the offset detection's features (thesis 4.2.2 reuses them for
//! eq. 4.4), then one solve and the stitching. The offset analysis, shared by both methods, is
//! reported in its own column and added for the one-shot ratio. The next-size table times a
//! session that is kept, as the studio keeps it: prepared, used at the slider's previous position,
//! then retargeted to this size.

use std::time::Instant;

use motif_core::TriMesh;
use motif_core::procedural::{ShelfOptions, generate, shelf};
use motif_core::progress::NoProgress;
use motif_retarget::alpha_expansion::AlphaExpansionOptions;
use motif_retarget::offsets::{OffsetOptions, analyze_features, prepare_features};
use motif_retarget::retarget::{RetargetMethod, RetargetOptions, RetargetSession, orient_offsets};
use motif_retarget::{Connectivity, generate_grid};
use serde::Serialize;

use crate::cli::{BenchRetargetArgs, GlobalArgs};
use crate::output::{bad_input, maybe_json};

/// One model of the Fig. 4.8 table.
#[derive(Debug, Serialize)]
struct ModelRow {
    model: String,
    vertices: usize,
    steps: [i32; 3],
    principal_offsets: usize,
    analysis_ms: f64,
    offsets: MethodFigures,
    dense: MethodFigures,
    /// Dense graph cut / offsets graph cut.
    graph_cut_ratio: f64,
    /// Dense retargeting step / offsets retargeting step (features reused).
    retarget_ratio: f64,
    /// (analysis + dense step) / (analysis + offsets step).
    one_shot_ratio: f64,
    /// Dense further size / offsets further size (sessions prepared once, as while a user
    /// drags a size slider).
    resize_ratio: f64,
}

#[derive(Debug, Serialize)]
struct MethodFigures {
    nodes: usize,
    labels: usize,
    energy: f64,
    /// Edges whose voxels copy from different offsets.
    seams: usize,
    /// Seams of infinite cost, where the output may be open (`RetargetReport::infinite_seams`).
    infinite_seams: usize,
    graph_cut_ms: f64,
    retarget_ms: f64,
    /// Retargeting a session already prepared and used at the previous size (one cell fewer
    /// along each growing direction): its voxels, voxel descriptors and the voxel distances that
    /// size needed are kept, so this times the new distances, the graph cut and the stitching,
    /// what each new size costs while a user drags a size slider.
    resize_ms: f64,
    /// Medians of the step's stages (voxelize, descriptors, distances, graph cut, stitch), ms.
    stages_ms: [f64; 5],
}

#[derive(Debug, Serialize)]
struct InteractiveRow {
    model: String,
    steps: [i32; 3],
    nodes: usize,
    labels: usize,
    edges: usize,
    moves: usize,
    graph_cut_ms: f64,
    solve_ms: f64,
}

#[derive(Debug, Serialize)]
struct GridRow {
    problem: String,
    energy: i64,
    cycles: usize,
    solve_ms: f64,
    gco_ms: f64,
    ratio_to_gco: f64,
}

#[derive(Debug, Serialize)]
struct Report {
    repeats: usize,
    threads: usize,
    models: Vec<ModelRow>,
    interactive: Vec<InteractiveRow>,
    grids: Vec<GridRow>,
    thesis: &'static str,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Grid-like real models of the shared data (`MANIFEST.json` notes): the OpenSCAD gridbeam shelf
/// (one more cell in width and in height), the OpenSCAD fence (three more posts) and the Jetson
/// Xavier heat sink (two more fins). The cells to add are given per model axis (x, y, z), not per
/// principal offset: the analysis orders its offsets by support, so an index would silently grow
/// other cells when that order changes (the heat sink's first offset is the 12.5 mm spacing of its
/// screw holes, along which it has no clean seam; its fins are the 3.8 mm offset along x).
const REAL_MODELS: [(&str, &str, [i32; 3]); 3] = [
    ("gridbeam*", "man-made/mcad_gridbeam_shelf.stl", [1, 0, 1]),
    ("oscad fence*", "man-made/oscad_example019_fence.stl", [3, 0, 0]),
    ("heat sink*", "man-made/pyb_xavier_heatsink.stl", [2, 0, 0]),
];

/// Steps per principal offset for `axis_steps` given per model axis: each non-zero entry goes to
/// the principal offset within 8° of that axis.
fn steps_along_axes(name: &str, principal: &[[f64; 3]], axis_steps: [i32; 3]) -> anyhow::Result<[i32; 3]> {
    let mut steps = [0; 3];
    for (axis, &k) in axis_steps.iter().enumerate() {
        if k == 0 {
            continue;
        }
        let along = principal.iter().position(|v| {
            let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            n > 0.0 && v[axis].abs() / n > 8f64.to_radians().cos()
        });
        let Some(i) = along else {
            anyhow::bail!(
                "{name}: no principal offset along the {} axis (offsets {principal:?})",
                ["x", "y", "z"][axis]
            );
        };
        steps[i] = k;
    }
    Ok(steps)
}

/// GCO's times on this machine's kind for the same generator (the figures).
const GCO_MS: [([usize; 3], usize, Connectivity, f64); 6] = [
    ([10, 10, 10], 8, Connectivity::Six, 11.7),
    ([10, 10, 10], 8, Connectivity::TwentySix, 61.0),
    ([20, 20, 20], 30, Connectivity::Six, 469.0),
    ([20, 20, 20], 30, Connectivity::TwentySix, 4_700.0),
    ([30, 30, 30], 64, Connectivity::Six, 3_100.0),
    ([30, 30, 30], 64, Connectivity::TwentySix, 51_000.0),
];

pub fn run(a: BenchRetargetArgs, g: &GlobalArgs) -> anyhow::Result<()> {
    crate::output::check_outputs(&[a.json.json.as_deref()], &[], g.force)?;
    if a.repeats == 0 {
        return Err(bad_input("--repeats must be at least 1"));
    }
    let say = |s: String| {
        if !g.quiet {
            eprintln!("{s}");
        }
    };
    let mut report = Report {
        repeats: a.repeats,
        threads: rayon::current_num_threads(),
        models: Vec::new(),
        interactive: Vec::new(),
        grids: Vec::new(),
        thesis: "Fig. 4.8: with offsets 32-810 nodes, 3-9 labels, 8-72 ms of graph cut; dense 924-7,429 nodes, 5-54 labels, 0.08-5.2 s",
    };

    // Fig. 4.8 on the generated models, then on the grid-like real models of the shared data.
    let offset_options = OffsetOptions { seed: g.seed, ..Default::default() };
    // (name, mesh, steps, whether the steps are per model axis rather than per principal offset)
    let mut models: Vec<(String, TriMesh, [i32; 3], bool)> = Vec::new();
    for (name, steps) in
        [("shelf", [2, 2, 0]), ("shelf_sheared", [1, 1, 0]), ("facade", [1, 1, 0]), ("fence", [2, 0, 0])]
    {
        models.push((name.to_string(), generate(name, g.seed)?.mesh, steps, false));
    }
    let data = super::bench::data_dir(&a.data)?;
    match &data {
        Some(dir) => {
            for (label, file, steps) in REAL_MODELS {
                let mesh = super::bench::read_data_mesh(dir, file)?;
                models.push((label.to_string(), mesh, steps, true));
            }
        }
        None => {
            say("shared data not found (set MOTIF_DATA or pass --data): rows of real models skipped".into())
        }
    }
    for (name, mesh, steps, per_axis) in models {
        let mut analysis_ms = Vec::new();
        let mut analysed = None;
        say(format!("analysing {name} ..."));
        for _ in 0..a.repeats {
            let t = Instant::now();
            let features = prepare_features(&mesh, &offset_options, &NoProgress)?;
            let analysis = analyze_features(&features, &offset_options, &NoProgress)?;
            analysis_ms.push(ms(t));
            analysed = Some((features, analysis));
        }
        let Some((features, analysis)) = analysed else { unreachable!("repeats >= 1") };
        let principal =
            orient_offsets(&analysis.principal.iter().map(|p| p.offset_model).collect::<Vec<_>>());
        let steps = if per_axis { steps_along_axes(&name, &principal, steps)? } else { steps };
        say(format!("retargeting {name} by {steps:?} (steps along its principal offsets p0, p1, p2) ..."));
        let figures = |method| -> anyhow::Result<MethodFigures> {
            let options = RetargetOptions { method, seed: g.seed, ..Default::default() };
            let (mut cut, mut step, mut last) = (Vec::new(), Vec::new(), None);
            let mut stages: [Vec<f64>; 5] = Default::default();
            for _ in 0..a.repeats {
                let t = Instant::now();
                let r = RetargetSession::with_features(&mesh, &features, &principal, &options, &NoProgress)?
                    .retarget(steps, &NoProgress)?;
                step.push(ms(t));
                cut.push(r.report.graph_cut_ms);
                let st = &r.report.stages;
                for (k, v) in
                    [st.voxelize_ms, st.descriptors_ms, st.distances_ms, st.graph_cut_ms, st.stitch_ms]
                        .into_iter()
                        .enumerate()
                {
                    stages[k].push(v);
                }
                last = Some(r.report);
            }
            let Some(r) = last else { unreachable!("repeats >= 1") };
            // A further size: the session is prepared and used at the slider's previous position
            // (one cell fewer along each direction that grows), then timed at this size.
            let previous = steps.map(|s| s - s.signum());
            let mut resize = Vec::new();
            for _ in 0..a.repeats {
                let mut session =
                    RetargetSession::with_features(&mesh, &features, &principal, &options, &NoProgress)?;
                let _ = session.retarget(previous, &NoProgress)?;
                let t = Instant::now();
                let _ = session.retarget(steps, &NoProgress)?;
                resize.push(ms(t));
            }
            Ok(MethodFigures {
                nodes: r.nodes,
                labels: r.labels,
                energy: r.energy,
                seams: r.seams,
                infinite_seams: r.infinite_seams,
                graph_cut_ms: median(cut),
                retarget_ms: median(step),
                resize_ms: median(resize),
                stages_ms: stages.map(median),
            })
        };
        let offsets = figures(RetargetMethod::Offsets)?;
        let dense = figures(RetargetMethod::Dense)?;
        let analysis_ms = median(analysis_ms);
        report.models.push(ModelRow {
            model: name.to_string(),
            vertices: mesh.num_vertices(),
            steps,
            principal_offsets: principal.len(),
            analysis_ms,
            graph_cut_ratio: dense.graph_cut_ms / offsets.graph_cut_ms.max(1e-6),
            retarget_ratio: dense.retarget_ms / offsets.retarget_ms.max(1e-6),
            one_shot_ratio: (analysis_ms + dense.retarget_ms) / (analysis_ms + offsets.retarget_ms),
            resize_ratio: dense.resize_ms / offsets.resize_ms.max(1e-6),
            offsets,
            dense,
        });
    }

    // The interactive size of 4.4: a 30 × 20-cell shelf grown by +5, +4 (≈ 900 nodes, 30 labels);
    // the session is prepared once, as while a user drags a size slider.
    {
        let steps = [5, 4, 0];
        say(format!("interactive: shelf 30x20 by {steps:?} ..."));
        let ex = shelf(&ShelfOptions { cells: [30, 20], ..Default::default() })?;
        let mut session = interactive_session(&ex.mesh, &ex.structure.cell_pitch, g.seed)?;
        let _ = session.retarget(steps, &NoProgress)?; // warm the distance cache
        let (mut cut, mut solve, mut last) = (Vec::new(), Vec::new(), None);
        for _ in 0..a.repeats.max(5) {
            let r = session.retarget(steps, &NoProgress)?;
            cut.push(r.report.graph_cut_ms);
            solve.push(r.report.solve_ms);
            last = Some(r.report);
        }
        let Some(r) = last else { unreachable!("at least 5 repeats") };
        report.interactive.push(InteractiveRow {
            model: "shelf 30x20 cells".into(),
            steps,
            nodes: r.nodes,
            labels: r.labels,
            edges: r.edges,
            moves: r.moves,
            graph_cut_ms: median(cut),
            solve_ms: median(solve),
        });
    }

    // The solver on mrf_grid_v1 problems (generator seed 1, argmin start, as GCO was run).
    for (dims, labels, conn, gco_ms) in GCO_MS {
        if a.no_grids || (dims[0] == 30 && !a.large) {
            continue;
        }
        let name = format!("{}^3, {} labels, {}-conn.", dims[0], labels, conn.number());
        say(format!("grid {name} ..."));
        let problem = generate_grid(dims, labels, conn, 1);
        let repeats = if dims[0] >= 20 { a.repeats.min(3) } else { a.repeats.max(5) };
        let (mut times, mut last) = (Vec::new(), None);
        for _ in 0..repeats {
            let s = problem.solve(&AlphaExpansionOptions::default())?;
            times.push(s.solve_ms);
            last = Some(s);
        }
        let Some(s) = last else { unreachable!("at least one repeat") };
        let solve_ms = median(times);
        report.grids.push(GridRow {
            problem: name,
            energy: s.energy,
            cycles: s.cycles,
            solve_ms,
            gco_ms,
            ratio_to_gco: solve_ms / gco_ms,
        });
    }

    if !crate::output::json_on_stdout(&a.json.json) {
        print_tables(&report);
    }
    maybe_json(&a.json.json, &report)
}

fn interactive_session(mesh: &TriMesh, pitch: &[[f64; 3]], seed: u64) -> anyhow::Result<RetargetSession> {
    let options = RetargetOptions { method: RetargetMethod::Offsets, seed, ..Default::default() };
    Ok(RetargetSession::new(mesh, pitch, &options, &NoProgress)?)
}

fn print_tables(r: &Report) {
    println!(
        "Retargeting, offsets vs dense (thesis Fig. 4.8; {}, {} threads)",
        if r.repeats == 1 { "one run".to_string() } else { format!("medians of {} runs", r.repeats) },
        r.threads
    );
    println!(
        "{:<14} {:>7} {:>9} | {:>5} {:>6} {:>9} {:>9} | {:>5} {:>6} {:>9} {:>9} | {:>8} {:>8} {:>8}",
        "model",
        "verts",
        "analysis",
        "nodes",
        "labels",
        "cut ms",
        "step ms",
        "nodes",
        "labels",
        "cut ms",
        "step ms",
        "cut x",
        "step x",
        "1-shot x"
    );
    println!("{:<32} | {:^33} | {:^33} |", "", "offsets", "dense (0.1)");
    for m in &r.models {
        println!(
            "{:<14} {:>7} {:>9.1} | {:>5} {:>6} {:>9.2} {:>9.1} | {:>5} {:>6} {:>9.1} {:>9.1} | {:>8.0} {:>8.1} {:>8.1}",
            m.model,
            m.vertices,
            m.analysis_ms,
            m.offsets.nodes,
            m.offsets.labels,
            m.offsets.graph_cut_ms,
            m.offsets.retarget_ms,
            m.dense.nodes,
            m.dense.labels,
            m.dense.graph_cut_ms,
            m.dense.retarget_ms,
            m.graph_cut_ratio,
            m.retarget_ratio,
            m.one_shot_ratio
        );
    }
    if r.models.iter().any(|m| m.model.ends_with('*')) {
        println!("* real model from the shared data");
    }
    for m in &r.models {
        for (method, f) in [("offsets", &m.offsets), ("dense", &m.dense)] {
            if f.infinite_seams > 0 {
                println!(
                    "{}: {method} stitching has {} of {} seams of infinite cost (the output may be open there)",
                    m.model, f.infinite_seams, f.seams
                );
            }
        }
    }
    println!("thesis {}", r.thesis);
    println!();
    println!(
        "Where the step's time goes (medians, ms): voxelize / descriptors / distances / graph cut / stitch"
    );
    for m in &r.models {
        let row = |s: &[f64; 5]| s.iter().map(|v| format!("{v:>6.2}")).collect::<Vec<_>>().join(" ");
        println!("{:<14} offsets {} | dense {}", m.model, row(&m.offsets.stages_ms), row(&m.dense.stages_ms));
    }
    println!();
    println!(
        "Next size (a session prepared and used at one cell fewer per growing direction, as while a user drags a size slider; medians, ms)"
    );
    println!("{:<14} {:>9} {:>9} {:>8}", "model", "offsets", "dense", "size x");
    for m in &r.models {
        println!(
            "{:<14} {:>9.2} {:>9.2} {:>8.1}",
            m.model, m.offsets.resize_ms, m.dense.resize_ms, m.resize_ratio
        );
    }
    println!();
    println!("Interactive size (thesis 4.4: ~1,000 nodes, 30 labels; target: graph cut < 20 ms)");
    for i in &r.interactive {
        println!(
            "{} {:?}: {} nodes, {} labels, {} edges, {} moves: graph cut {:.1} ms, solve {:.1} ms",
            i.model, i.steps, i.nodes, i.labels, i.edges, i.moves, i.graph_cut_ms, i.solve_ms
        );
    }
    if !r.grids.is_empty() {
        println!();
        println!("Alpha-expansion on mrf_grid_v1 (seed 1, argmin start) next to GCO's times");
        println!(
            "{:<26} {:>10} {:>7} {:>10} {:>10} {:>8}",
            "problem", "energy", "cycles", "ms", "GCO ms", "ratio"
        );
        for gr in &r.grids {
            println!(
                "{:<26} {:>10} {:>7} {:>10.1} {:>10.1} {:>8.2}",
                gr.problem, gr.energy, gr.cycles, gr.solve_ms, gr.gco_ms, gr.ratio_to_gco
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::steps_along_axes;

    #[test]
    fn steps_per_axis_go_to_the_offset_along_that_axis() {
        // The gridbeam shelf's principal offsets: z first, then x, then y (orders by support).
        let principal = [[0.0, 0.0, 76.2], [114.3, 0.0, 0.0], [0.0, 76.2, 0.0]];
        assert_eq!(steps_along_axes("m", &principal, [1, 0, 2]).unwrap(), [2, 1, 0]);
        assert_eq!(steps_along_axes("m", &principal, [0, -1, 0]).unwrap(), [0, 0, -1]);
        // A sheared offset 20° off the x axis is not "along x".
        let sheared = [[1.0, 20f64.to_radians().tan(), 0.0], [0.0, 1.0, 0.0]];
        let e = steps_along_axes("m", &sheared, [1, 0, 0]).unwrap_err().to_string();
        assert!(e.contains("no principal offset along the x axis"), "{e}");
        assert_eq!(steps_along_axes("m", &sheared, [0, 1, 0]).unwrap(), [0, 1, 0]);
    }
}
