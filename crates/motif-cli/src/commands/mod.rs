//! One module per subcommand; each exposes `run(args, &GlobalArgs)`.

mod align;
mod baseline;
mod bench;
mod bench_detect;
mod bench_retarget;
mod convert;
mod curvature;
mod deform;
mod demo;
mod detect;
mod eval;
mod example;
mod features;
mod info;
mod mrf;
mod normals;
mod offsets;
mod retarget;
mod sample;
mod studio;
mod symmetry;

use std::path::Path;

use anyhow::Context;
use motif_core::io::{self, Model, PlyEncoding, StlEncoding, WriteOptions};

use crate::cli::{
    BaselineCommand, BenchCommand, Cli, Command, EncodingArgs, FeaturesCommand, MrfCommand, PlyEncodingArg,
    StlEncodingArg, SymmetryCommand,
};

/// Dispatches a parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    let g = &cli.global;
    match cli.command {
        Command::Info(a) => info::run(a, g),
        Command::Convert(a) => convert::run(a, g),
        Command::Sample(a) => sample::run(a, g),
        Command::Normals(a) => normals::run(a, g),
        Command::Curvature(a) => curvature::run(a, g),
        Command::Features(FeaturesCommand::Shot(a)) => features::run_shot(a, g),
        Command::Align(a) => align::run(a, g),
        Command::Symmetry(SymmetryCommand::Detect(a)) => symmetry::detect(a, g),
        Command::Symmetry(SymmetryCommand::Check(a)) => symmetry::check(a, g),
        Command::Deform(a) => deform::run(a, g),
        Command::Bench(BenchCommand::Deform(a)) => bench::deform(a, g),
        Command::Bench(BenchCommand::Detect(a)) => bench_detect::run(a, g),
        Command::Bench(BenchCommand::Retarget(a)) => bench_retarget::run(a, g),
        Command::Bench(BenchCommand::Studio(a)) => bench::studio(a, g),
        Command::Retarget(a) => retarget::run(a, g),
        Command::Offsets(a) => offsets::offsets(a, g),
        Command::Detect(a) => detect::run(a, g),
        Command::Eval(a) => eval::run(a, g),
        Command::Sparsity(a) => offsets::sparsity(a, g),
        Command::Mrf(MrfCommand::Solve(a)) => mrf::solve(a, g),
        Command::Mrf(MrfCommand::Generate(a)) => mrf::generate(a, g),
        Command::Baseline(BaselineCommand::RigidIcp(a)) => baseline::rigid_icp(a, g),
        Command::Example(a) => example::run(a, g),
        Command::Demo(a) => demo::run(a, g),
        Command::Studio(a) => studio::run(a, g),
    }
}

/// Reads any supported file, with the error naming the file.
pub fn read_model(path: &Path) -> anyhow::Result<Model> {
    Ok(io::read(path)?)
}

/// Reads a model for a command that computes with it: the reader's warnings are shown, and zero normals are estimated from the points around them, or, when more than half
/// are zero, all of them as for a file without normals
/// ([`motif_core::PointCloud::repair_degenerate_normals`]), with a warning.
pub fn read_model_for_geometry(path: &Path) -> anyhow::Result<Model> {
    let mut model = io::read(path)?;
    for w in &model.warnings {
        warn(format!("{}: {w}", path.display()));
    }
    let count = model.vertices.len();
    let repair = model.vertices.repair_degenerate_normals();
    let zero = repair.degenerate;
    if repair.dropped {
        warn(format!(
            "{}: {zero} of {count} normals are zero (or were not finite); the file's normals are ignored",
            path.display()
        ));
    } else if repair.estimated > 0 {
        warn(format!(
            "{}: {zero} of {count} normals are zero (or were not finite); those were estimated \
                 from their {} nearest points and oriented like the file's normals around them",
            path.display(),
            motif_core::point_cloud::REPAIR_NEIGHBOURS
        ));
    }
    Ok(model)
}

/// The write options the user chose for `output`, with a warning when one of them does not apply
/// to its format (`--stl-encoding ascii` for a PLY output used to be ignored without a word).
fn write_options(e: &EncodingArgs, output: &Path) -> WriteOptions {
    let format = motif_core::io::Format::from_path(output).ok();
    let (ply, stl) = (e.ply_encoding.is_some(), e.stl_encoding.is_some());
    for (given, flag, applies, kind) in [
        (ply, "--ply-encoding", format == Some(motif_core::io::Format::Ply), "PLY"),
        (stl, "--stl-encoding", format == Some(motif_core::io::Format::Stl), "STL"),
    ] {
        if given && !applies {
            warn(format!("{flag} applies to {kind} outputs only; {} is not one", output.display()));
        }
    }
    WriteOptions {
        ply: match e.ply_encoding.unwrap_or_default() {
            PlyEncodingArg::Ascii => PlyEncoding::Ascii,
            PlyEncodingArg::BinaryLe => PlyEncoding::BinaryLittleEndian,
            PlyEncodingArg::BinaryBe => PlyEncoding::BinaryBigEndian,
        },
        stl: match e.stl_encoding.unwrap_or_default() {
            StlEncodingArg::Binary => StlEncoding::Binary,
            StlEncodingArg::Ascii => StlEncoding::Ascii,
        },
    }
}

/// Writes a model atomically, in the encodings the user chose, after checking it does not
/// overwrite an input.
pub fn write_model(
    path: &Path,
    model: &Model,
    inputs: &[&Path],
    g: &crate::cli::GlobalArgs,
    encoding: &EncodingArgs,
) -> anyhow::Result<()> {
    crate::output::check_outputs(&[Some(path)], inputs, g.force)?;
    let options = write_options(encoding, path);
    io::write(path, model, &options).with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// Prints a warning on stderr, under --quiet too: a warning says something about the result
/// (an estimated normal, an open seam) that a quiet script should still see.
pub fn warn(msg: impl AsRef<str>) {
    eprintln!("warning: {}", crate::output::tidy_numbers(msg.as_ref()));
}

/// For a command whose result is the file it wrote: what the file holds, on stdout as
/// `OUTPUT: SUMMARY` (a result: printed under --quiet too), then the note `wrote OUTPUT` on
/// stderr (hidden by --quiet). Before, both were one note, so --quiet hid the only result of
/// `curvature`, `sample`, `normals`, `features shot`, `convert` and `example`.
pub fn written(g: &crate::cli::GlobalArgs, output: impl std::fmt::Display, summary: impl AsRef<str>) {
    let line = format!("{output}: {}", crate::output::tidy_numbers(summary.as_ref()));
    // With a document on stdout (`example scene-facade s.ply --gt -`), the summary goes to
    // stderr, where it cannot corrupt the document.
    if crate::output::stdout_is_a_document() {
        eprintln!("{line}");
    } else {
        println!("{line}");
    }
    note(g, format!("wrote {output}"));
}

/// Prints an informational line on stderr unless quiet (stdout is kept for results).
pub fn note(g: &crate::cli::GlobalArgs, msg: impl AsRef<str>) {
    if !g.quiet {
        eprintln!("{}", msg.as_ref());
    }
}
