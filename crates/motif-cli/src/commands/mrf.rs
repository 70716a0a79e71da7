//! `motif mrf`: solve and generate grid MRF problems (`mrf_grid_v1`).

use motif_retarget::alpha_expansion::{AlphaExpansionOptions, CycleStrategy, LabelOrder, TieBreak};
use motif_retarget::{Connectivity, generate_grid, solve_grid_file};

use crate::cli::{CyclesArg, GlobalArgs, LabelOrderArg, MrfGenerateArgs, MrfSolveArgs, TiesArg};
use crate::output::{bad_input, check_outputs, maybe_json};

pub fn solve(a: MrfSolveArgs, g: &GlobalArgs) -> anyhow::Result<()> {
    check_outputs(&[a.json.json.as_deref()], &[&a.problem], g.force)?;
    if a.max_cycles == 0 {
        return Err(bad_input("--max-cycles 0: allow at least one cycle"));
    }
    let options = AlphaExpansionOptions {
        max_cycles: a.max_cycles,
        label_order: match a.order {
            LabelOrderArg::Sequential => LabelOrder::Sequential,
            LabelOrderArg::Random => LabelOrder::Random { seed: g.seed },
        },
        cycles: match a.cycles {
            CyclesArg::Full => CycleStrategy::Full,
            CyclesArg::Adaptive => CycleStrategy::Adaptive,
            CyclesArg::Queue => CycleStrategy::Queue,
        },
        ties: match a.ties {
            TiesArg::MostAlpha => TieBreak::MostAlpha,
            TiesArg::FewestAlpha => TieBreak::FewestAlpha,
        },
        recycle_flows: !a.no_recycle,
        ..Default::default()
    };
    let sol = match solve_grid_file(&a.problem, &options) {
        Ok(sol) => sol,
        Err(e) => {
            // Named once: reading errors name the file already ("nope.json: nope.json: No such
            // file" before).
            let name = a.problem.display().to_string();
            let named = e.to_string().starts_with(&name);
            let e = anyhow::Error::from(e);
            return Err(if named { e } else { e.context(name) });
        }
    };
    // A report written to a file leaves the text on stdout; one on stdout replaces it.
    // The solution, with the problem's path and the solver's options beside it.
    let mut report = serde_json::to_value(&sol)?;
    if let Some(m) = report.as_object_mut() {
        m.insert("problem".into(), serde_json::json!(a.problem.display().to_string()));
        m.insert("options".into(), serde_json::to_value(&options)?);
        m.insert("seed".into(), serde_json::json!(g.seed));
    }
    maybe_json(&a.json.json, &report)?;
    // On stderr too, so that a report on stdout (or a reader of the energy alone) is told: the
    // energy of a non-metric problem may lie above the optimum (a negative entry gave 3 where 2
    // was reachable).
    if let Some(first) = sol.pairwise_issues.first() {
        super::warn(format!(
            "{}: the pairwise matrix is not a metric ({first}{}): alpha-expansion is exact in its moves only for a \
             metric, so the energy may lie above the optimum",
            a.problem.display(),
            if sol.pairwise_issues.len() > 1 { ", and more" } else { "" }
        ));
    }
    if crate::output::json_on_stdout(&a.json.json) {
        return Ok(());
    }
    println!("{}", a.problem.display());
    println!(
        "  grid         {}x{}x{}, {} labels, {}-connected ({} edges)",
        sol.dims[0], sol.dims[1], sol.dims[2], sol.num_labels, sol.connectivity, sol.num_edges
    );
    println!("  energy       {} (from {} at the start)", sol.energy, sol.initial_energy);
    println!(
        "  cycles       {} ({}, {} accepted; {})",
        sol.cycles,
        crate::output::count(sol.moves, "move", "moves"),
        sol.accepted_moves,
        sol.termination.as_str()
    );
    let recycled = match sol.recycled_labels {
        0 => String::new(),
        k if k == sol.num_labels => ", flows recycled".to_string(),
        k => format!(", flows recycled for {k} of {} labels", sol.num_labels),
    };
    println!("  solve        {:.1} ms ({}-bit capacities{recycled})", sol.solve_ms, sol.capacity_bits);
    if sol.truncated_terms > 0 {
        println!("  note         {} non-metric pairwise terms truncated", sol.truncated_terms);
    }
    for issue in &sol.pairwise_issues {
        println!("  note         {issue}: expansion moves are exact only for a metric");
    }
    if sol.forbidden_sites > 0 {
        println!(
            "  warning      {} site(s) keep a label of cost invalid_cost or more: no valid labelling was found there",
            sol.forbidden_sites
        );
    }
    Ok(())
}

pub fn generate(a: MrfGenerateArgs, g: &GlobalArgs) -> anyhow::Result<()> {
    check_outputs(&[Some(&a.output)], &[], g.force)?;
    let dims: [usize; 3] = match a.dims.as_slice() {
        [x, y, z] if *x > 0 && *y > 0 && *z > 0 => [*x, *y, *z],
        _ => return Err(bad_input("--dims needs three positive sizes, e.g. --dims 20,20,20")),
    };
    if dims.iter().product::<usize>() > 1_000_000 {
        return Err(bad_input("--dims: more than 10^6 sites; that file would be enormous"));
    }
    if a.labels < 2 || a.labels > 1024 {
        return Err(bad_input(format!("--labels {}: use 2 to 1024 labels", a.labels)));
    }
    let sites: usize = dims.iter().product();
    if sites * a.labels > 50_000_000 {
        return Err(bad_input(format!(
            "--dims {}x{}x{} with --labels {}: {} unary costs (more than 5·10⁷); that file would be enormous",
            dims[0],
            dims[1],
            dims[2],
            a.labels,
            sites * a.labels
        )));
    }
    let connectivity = Connectivity::from_number(u64::from(a.connectivity))
        .ok_or_else(|| bad_input(format!("--connectivity {}: must be 6 or 26", a.connectivity)))?;
    let problem = generate_grid(dims, a.labels, connectivity, g.seed);
    let text = problem.to_json_string();
    // `-` prints the problem, as `detect -o -` prints its result (a file named `-` was made).
    if a.output == std::path::Path::new("-") {
        println!("{text}");
        return Ok(());
    }
    motif_core::io::write_atomic(&a.output, |w| w.write_all(text.as_bytes()))?;
    super::note(
        g,
        format!(
            "wrote {} ({}x{}x{}, {} labels, {}-connected)",
            a.output.display(),
            dims[0],
            dims[1],
            dims[2],
            a.labels,
            a.connectivity
        ),
    );
    Ok(())
}
