//! `motif offsets` and `motif sparsity`: offset statistics of thesis chapter 4.

use anyhow::Context;
use motif_retarget::offsets::{OffsetOptions, Repetition, analyze_offsets};
use motif_retarget::plot::{plot_offsets, plot_sparsity};
use motif_retarget::sparsity::{SparsityOptions, collect_inputs_noting, sparsity_study};

use crate::cli::{GlobalArgs, OffsetsArgs, SparsityArgs};
use crate::output::{bad_input, check_outputs, maybe_json};
use crate::progress::Bar;

pub fn offsets(a: OffsetsArgs, g: &GlobalArgs) -> anyhow::Result<()> {
    check_outputs(&[a.plot.as_deref(), a.json.json.as_deref()], &[&a.mesh], g.force)?;
    crate::output::check_output_formats(&[(a.plot.as_deref(), crate::output::OutputKind::Png)])?;
    if !(a.tau >= 0.0 && a.tau < 2.0) {
        return Err(bad_input(format!(
            "--tau {}: in normalised units, at least 0 and below 2 (the model spans [−1, 1])",
            a.tau
        )));
    }
    let mesh = motif_core::io::read_mesh(&a.mesh)?;
    let options = OffsetOptions { tau: a.tau, seed: g.seed, ..Default::default() };
    let bar = Bar::new(g.quiet);
    let an = analyze_offsets(&mesh, &options, &bar).with_context(|| a.mesh.display().to_string())?;
    if let Some(p) = &a.plot {
        let title = a.mesh.file_name().and_then(|n| n.to_str()).unwrap_or("model");
        plot_offsets(&an, title, p)?;
    }
    // The results print under --quiet too (as `info` and `eval` do); only the notes are quiet.
    if !crate::output::json_on_stdout(&a.json.json) {
        println!("{}", a.mesh.display());
        // The verdict's own reasons (the discrete-period test decides, not the peak's share).
        match an.repetition.kind {
            Repetition::Repetitive => {
                println!(
                    "  {}; {}",
                    crate::output::count(an.principal.len(), "principal offset", "principal offsets"),
                    an.repetition.summary
                )
            }
            Repetition::NoRepetition => {
                println!("  {}; a plain resize is all that is possible", an.repetition.summary)
            }
        }
        // Listed by model axis (x, y, z), the order `motif retarget --steps U,V,W` counts them in.
        for (i, p) in an.axis_order.iter().map(|&k| &an.principal[k]).enumerate() {
            let len = |x: f64| motif_core::geometry::format_length(x, p.length_model, 6);
            println!(
                "  principal {i}: [{}, {}, {}] (length {} model units), support {} ({:.1}% of offsets), overlap {:.1}%",
                len(p.offset_model[0]),
                len(p.offset_model[1]),
                len(p.offset_model[2]),
                len(p.length_model),
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
            an.timings.total_ms
        );
    }
    if let Some(p) = &a.plot {
        super::note(g, format!("wrote {}", p.display()));
    }
    let mut report = serde_json::to_value(&an)?;
    if let Some(m) = report.as_object_mut() {
        m.insert("input".into(), serde_json::json!(a.mesh.display().to_string()));
    }
    maybe_json(&a.json.json, &report)
}

pub fn sparsity(a: SparsityArgs, g: &GlobalArgs) -> anyhow::Result<()> {
    let (inputs, repeats) = collect_inputs_noting(&a.inputs)?;
    if !repeats.is_empty() {
        let shown: Vec<String> = repeats.iter().take(3).map(|p| p.display().to_string()).collect();
        let more = if repeats.len() > 3 { format!(" and {} more", repeats.len() - 3) } else { String::new() };
        super::note(
            g,
            format!(
                "note: {} input(s) name a model already included and are counted once: {}{more}",
                repeats.len(),
                shown.join(", ")
            ),
        );
    }
    let named: Vec<&std::path::Path> =
        a.inputs.iter().map(|p| p.as_path()).chain(inputs.iter().map(|m| m.path.as_path())).collect();
    check_outputs(&[a.plot.as_deref(), a.json.json.as_deref()], &named, g.force)?;
    crate::output::check_output_formats(&[(a.plot.as_deref(), crate::output::OutputKind::Png)])?;
    if inputs.is_empty() {
        return Err(bad_input("no meshes found in the given inputs"));
    }
    // The global --seed, as `motif offsets` uses it (the study's offsets used the library's
    // default seed 0 whatever --seed said).
    let options = SparsityOptions {
        offsets: motif_retarget::offsets::OffsetOptions { seed: g.seed, ..Default::default() },
        ..Default::default()
    };
    let bar = Bar::new(g.quiet);
    let report = sparsity_study(&inputs, &options, &bar)?;
    let failed: Vec<_> = report.models.iter().filter(|m| m.error.is_some()).collect();
    let skipped = |m: &&motif_retarget::sparsity::ModelSparsity| {
        let (path, error) = (m.path.display().to_string(), m.error.as_deref().unwrap_or("?"));
        let said = if error.contains(&path) { error.to_string() } else { format!("{path}: {error}") };
        crate::output::plain_os_text(&said)
    };
    if failed.len() == report.models.len() {
        let reasons: Vec<String> = failed.iter().map(skipped).collect();
        return Err(bad_input(format!("no model could be analysed ({})", reasons.join("; "))));
    }
    // A file named on the command line is asked for: its failure fails the study (models found
    // in a folder or listed by a manifest are skipped with a warning, and the report's `error`).
    let named_failed: Vec<String> =
        failed.iter().filter(|m| a.inputs.iter().any(|i| i == &m.path)).map(skipped).collect();
    if !named_failed.is_empty() {
        return Err(bad_input(named_failed.join("; ")));
    }
    // A model left out of the study changes its figures: a warning, shown under --quiet too.
    for m in &failed {
        super::warn(format!("skipped {}", skipped(m)));
    }
    if let Some(p) = &a.plot {
        plot_sparsity(&report, p)?;
    }
    if !crate::output::json_on_stdout(&a.json.json) {
        println!("{}", report.table());
    }
    if let Some(p) = &a.plot {
        super::note(g, format!("wrote {}", p.display()));
    }
    maybe_json(&a.json.json, &report)
}
