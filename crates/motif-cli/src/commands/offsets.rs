//! `motif offsets` and `motif sparsity`: offset statistics of thesis chapter 4.

use motif_retarget::offsets::{OffsetOptions, Repetition, analyze_offsets};
use motif_retarget::plot::{plot_offsets, plot_sparsity};
use motif_retarget::sparsity::{SparsityOptions, collect_inputs, sparsity_study};

use crate::cli::{GlobalArgs, OffsetsArgs, SparsityArgs};
use crate::output::{bad_input, check_output, maybe_json};
use crate::progress::Bar;

pub fn offsets(a: OffsetsArgs, g: &GlobalArgs) -> anyhow::Result<()> {
    if !(a.tau >= 0.0 && a.tau < 2.0) {
        return Err(bad_input(format!("--tau {}: in normalised units, between 0 and 2", a.tau)));
    }
    let mesh = motif_core::io::read_mesh(&a.mesh)?;
    if let Some(p) = &a.plot {
        check_output(p, &[&a.mesh], g.force)?;
    }
    let options = OffsetOptions { tau: a.tau, seed: g.seed, ..Default::default() };
    let bar = Bar::new(g.quiet);
    let an = analyze_offsets(&mesh, &options, &bar)?;
    if let Some(p) = &a.plot {
        let title = a.mesh.file_name().and_then(|n| n.to_str()).unwrap_or("model");
        plot_offsets(&an, title, p)?;
    }
    if !crate::output::json_on_stdout(&a.json.json) && !g.quiet {
        println!("{}", a.mesh.display());
        // The verdict's own reasons (the discrete-period test decides, not the peak's share).
        match an.repetition.kind {
            Repetition::Repetitive => {
                println!("  {} principal offsets; {}", an.principal.len(), an.repetition.summary)
            }
            Repetition::NoRepetition => {
                println!("  {}; a plain resize is all that is possible", an.repetition.summary)
            }
        }
        for (i, p) in an.principal.iter().enumerate() {
            println!(
                "  principal {i}: [{:.6}, {:.6}, {:.6}] (length {:.6} model units), support {} ({:.1}% of offsets), overlap {:.1}%",
                p.offset_model[0],
                p.offset_model[1],
                p.offset_model[2],
                p.length_model,
                p.support,
                100.0 * p.support_share,
                100.0 * p.overlap
            );
            if let Some(snap) = &p.vertex_snap {
                println!(
                    "    snapped to the exact vertex translation ({} of {} vertex pairs agree; ICP was {:.2e} model units off)",
                    snap.pairs,
                    snap.probed,
                    snap.shift / an.normalisation.scale
                );
            }
        }
        println!(
            "  {} dominant offsets (histogram peaks); analysis {:.0} ms",
            an.dominant.len(),
            1e3 * an.timings.total
        );
        if let Some(p) = &a.plot {
            eprintln!("wrote {}", p.display());
        }
    }
    maybe_json(&a.json.json, &an)
}

pub fn sparsity(a: SparsityArgs, g: &GlobalArgs) -> anyhow::Result<()> {
    let inputs = collect_inputs(&a.inputs)?;
    if inputs.is_empty() {
        return Err(bad_input("no meshes found in the given inputs"));
    }
    if let Some(p) = &a.plot {
        check_output(p, &[], g.force)?;
    }
    let options = SparsityOptions::default();
    let bar = Bar::new(g.quiet);
    let report = sparsity_study(&inputs, &options, &bar)?;
    if let Some(p) = &a.plot {
        plot_sparsity(&report, p)?;
    }
    if !crate::output::json_on_stdout(&a.json.json) && !g.quiet {
        println!("{}", report.table());
        let failed: Vec<_> = report.models.iter().filter(|m| m.error.is_some()).collect();
        for m in &failed {
            println!("skipped {}: {}", m.path.display(), m.error.as_deref().unwrap_or("?"));
        }
        if let Some(p) = &a.plot {
            eprintln!("wrote {}", p.display());
        }
    }
    maybe_json(&a.json.json, &report)
}
