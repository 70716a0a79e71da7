//! Repeats the interactive-size solve (30 × 20-cell shelf, +5,+4: 900 nodes, 30 labels) for
//! profiling: `perf record -g target/release/examples/retarget_profile`.

use motif_core::procedural::{ShelfOptions, shelf};
use motif_core::progress::NoProgress;
use motif_retarget::retarget::{RetargetOptions, RetargetSession};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let ex = shelf(&ShelfOptions { cells: [30, 20], ..Default::default() })?;
    let mut o = RetargetOptions::default();
    let args: Vec<String> = std::env::args().collect();
    if let Some(v) = args.get(1).and_then(|a| a.parse::<f64>().ok()) {
        o.graph_cut.infinite_cost = v;
    }
    if args.get(2).is_some_and(|a| a == "adaptive") {
        o.graph_cut.cycles = motif_retarget::alpha_expansion::CycleStrategy::Adaptive;
    }
    let mut s = RetargetSession::new(&ex.mesh, &ex.structure.cell_pitch, &o, &NoProgress)?;
    let mut gc = 0.0;
    let mut last = None;
    for _ in 0..20 {
        let r = s.retarget([5, 4, 0], &NoProgress)?;
        gc += r.report.graph_cut_ms;
        last = Some(r.report);
    }
    if let Some(r) = last {
        println!(
            "mean graph cut {:.2} ms; {} moves, {} cycles, energy {:.4}, initial {:.4}",
            gc / 20.0,
            r.moves,
            r.cycles,
            r.energy,
            r.initial_energy
        );
    }
    Ok(())
}
