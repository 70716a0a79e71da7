//! Times alpha-expansion on grid MRFs too large for criterion and prints a table to compare with
//! GCO's times measured on this machine's kind.
//!
//! Run: `cargo run --release -p motif-retarget --example mrf_timing [-- OPTIONS]`
//! - `--sizes small|all` (default `small`: up to 20³; `all` adds 30³ with 64 labels);
//! - `--repeat N` (default 3): solves per problem, the median is reported;
//! - `--write DIR`: also writes every generated problem as `mrf_grid_v1` JSON into DIR;
//! - `--only TEXT`: only the problems whose name contains TEXT (e.g. `20³ L30 c6`);
//! - `--cycles full|adaptive|queue` (default `queue`): the alpha-expansion cycle strategy.

use std::path::PathBuf;

use motif_retarget::alpha_expansion::{AlphaExpansionOptions, CycleStrategy};
use motif_retarget::mrf_grid::{Connectivity, GridProblem, generate_grid};

struct Case {
    name: String,
    problem: GridProblem,
    /// GCO's time on the same kind of problem (ms), measured by peers on this machine's kind.
    gco_ms: Option<f64>,
}

fn shipped_example() -> Option<GridProblem> {
    let rel = "shared/formats/examples/mrf_10x10x10_L8_c6.json";
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .map(|a| a.join(rel))
        .find(|p| p.is_file())?;
    GridProblem::from_json_bytes(&std::fs::read(path).ok()?).ok()
}

/// CPU time of this thread in ns (Linux), which a busy shared machine disturbs less than
/// wall-clock time.
fn thread_cpu_ns() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    s.split_whitespace().next()?.parse().ok()
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut all = false;
    let mut repeat = 3usize;
    let mut write: Option<PathBuf> = None;
    let mut only: Option<String> = None;
    let mut options = AlphaExpansionOptions::default();
    let mut i = 0;
    while i < args.len() {
        match args[i].as_str() {
            "--sizes" => {
                all = args.get(i + 1).map(String::as_str) == Some("all");
                i += 1;
            }
            "--repeat" => {
                repeat = args.get(i + 1).and_then(|s| s.parse().ok()).unwrap_or(3).max(1);
                i += 1;
            }
            "--write" => {
                write = args.get(i + 1).map(PathBuf::from);
                i += 1;
            }
            "--only" => {
                only = args.get(i + 1).cloned();
                i += 1;
            }
            "--cycles" => {
                options.cycles = match args.get(i + 1).map(String::as_str) {
                    Some("adaptive") => CycleStrategy::Adaptive,
                    Some("full") => CycleStrategy::Full,
                    _ => CycleStrategy::Queue,
                };
                i += 1;
            }
            "--bench" => {}
            other => {
                eprintln!("unknown argument {other}");
                std::process::exit(2);
            }
        }
        i += 1;
    }

    let mut cases = Vec::new();
    if let Some(p) = shipped_example() {
        cases.push(Case { name: "shipped 10³ L8 c6".into(), problem: p, gco_ms: Some(11.7) });
    } else {
        eprintln!("shipped example not found; skipping it");
    }
    let generated: &[([usize; 3], usize, Connectivity, Option<f64>)] = &[
        ([10, 10, 10], 8, Connectivity::Six, Some(11.7)),
        ([10, 10, 10], 8, Connectivity::TwentySix, Some(61.0)),
        ([20, 20, 20], 30, Connectivity::Six, Some(469.0)),
        ([20, 20, 20], 30, Connectivity::TwentySix, Some(4700.0)),
        ([30, 30, 30], 64, Connectivity::Six, Some(3100.0)),
        ([30, 30, 30], 64, Connectivity::TwentySix, Some(51000.0)),
    ];
    for &(dims, labels, conn, gco_ms) in generated {
        if dims[0] == 30 && !all {
            continue;
        }
        let problem = generate_grid(dims, labels, conn, 1);
        let name = format!("gen {}³ L{} c{}", dims[0], labels, conn.number());
        if let Some(dir) = &write {
            let file = dir.join(format!(
                "mrf_{}x{}x{}_L{}_c{}_seed1.json",
                dims[0],
                dims[1],
                dims[2],
                labels,
                conn.number()
            ));
            if let Err(e) = std::fs::write(&file, problem.to_json_string()) {
                eprintln!("{}: {e}", file.display());
            }
        }
        cases.push(Case { name, problem, gco_ms });
    }

    println!(
        "| problem | sites | edges | initial E | final E | cycles | moves | median wall ms | median CPU ms | GCO ms | CPU ratio |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for case in &cases {
        if only.as_ref().is_some_and(|o| !case.name.contains(o.as_str())) {
            continue;
        }
        let mut times = Vec::new();
        let mut cpu = Vec::new();
        let mut last = None;
        for _ in 0..repeat {
            let c0 = thread_cpu_ns();
            let s = case.problem.solve(&options).expect("valid problem");
            if let (Some(a), Some(b)) = (c0, thread_cpu_ns()) {
                cpu.push((b - a) as f64 / 1e6);
            }
            times.push(s.solve_ms);
            last = Some(s);
        }
        times.sort_by(f64::total_cmp);
        cpu.sort_by(f64::total_cmp);
        let median = times[times.len() / 2];
        // Wall time when CPU time is unavailable.
        let median_cpu = cpu.get(cpu.len() / 2).copied().unwrap_or(median);
        let Some(s) = last else { continue };
        let (gco, ratio) = match case.gco_ms {
            Some(g) => (format!("{g}"), format!("{:.2}", median_cpu / g)),
            None => ("-".into(), "-".into()),
        };
        println!(
            "| {} | {} | {} | {} | {} | {} | {} | {:.1} | {:.1} | {} | {} |",
            case.name,
            case.problem.num_sites(),
            s.num_edges,
            s.initial_energy,
            s.energy,
            s.cycles,
            s.moves,
            median,
            median_cpu,
            gco,
            ratio
        );
    }
}
