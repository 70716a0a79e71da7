//! Output discipline shared by every subcommand: exit codes, refusing to overwrite inputs,
//! atomic writes, and JSON reports.

use std::path::{Path, PathBuf};

use anyhow::Context;
use serde::Serialize;

/// An error in how the command was called or in what it was given (exit code 2).
#[derive(Debug)]
pub struct BadInput(pub String);

impl std::fmt::Display for BadInput {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for BadInput {}

/// `n` and the noun in the number it needs: `count(1, "class", "classes")` is "1 class".
pub fn count(n: usize, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

/// Shorthand: `return Err(bad_input(...))`.
pub fn bad_input(msg: impl Into<String>) -> anyhow::Error {
    anyhow::Error::new(BadInput(msg.into()))
}

/// Exit code for an error: 2 when the input or the usage is at fault, 1 otherwise.
pub fn exit_code(err: &anyhow::Error) -> u8 {
    for cause in err.chain() {
        if cause.downcast_ref::<BadInput>().is_some() {
            return 2;
        }
        if let Some(e) = cause.downcast_ref::<motif_core::Error>() {
            return if e.is_bad_input() { 2 } else { 1 };
        }
        if let Some(e) = cause.downcast_ref::<motif_deform::DeformError>() {
            return if e.is_bad_input() { 2 } else { 1 };
        }
        if let Some(e) = cause.downcast_ref::<motif_deform::symmetry_detect::SymmetryDetectError>() {
            return match e {
                motif_deform::symmetry_detect::SymmetryDetectError::Core(c) => {
                    if c.is_bad_input() {
                        2
                    } else {
                        1
                    }
                }
                _ => 2,
            };
        }
        if let Some(e) = cause.downcast_ref::<motif_detect::DetectError>() {
            return match e {
                motif_detect::DetectError::Plot { .. } => 1,
                motif_detect::DetectError::Core(c) => {
                    if c.is_bad_input() {
                        2
                    } else {
                        1
                    }
                }
                _ => 2,
            };
        }
        if let Some(e) = cause.downcast_ref::<motif_retarget::retarget::RetargetError>() {
            use motif_retarget::retarget::RetargetError as E;
            return match e {
                E::Core(c) => {
                    if c.is_bad_input() {
                        2
                    } else {
                        1
                    }
                }
                E::GraphCut(_) => 1,
                _ => 2,
            };
        }
        if let Some(e) = cause.downcast_ref::<motif_retarget::offsets::OffsetsError>() {
            use motif_retarget::offsets::OffsetsError as E;
            return match e {
                E::Core(c) => {
                    if c.is_bad_input() {
                        2
                    } else {
                        1
                    }
                }
                E::Plot { .. } => 1,
                _ => 2,
            };
        }
        if let Some(e) = cause.downcast_ref::<motif_retarget::Error>() {
            return match e {
                motif_retarget::Error::Io { source, .. } => io_exit_code(source),
                _ => 2,
            };
        }
    }
    1
}

/// The error and its causes on one line, skipping causes whose text the message already shows
/// (library errors often print their source inline).
pub fn describe(err: &anyhow::Error) -> String {
    let mut msg = String::new();
    for cause in err.chain() {
        let text = cause.to_string();
        if msg.contains(&text) {
            continue;
        }
        if !msg.is_empty() {
            msg.push_str(": ");
        }
        msg.push_str(&text);
    }
    plain_os_text(&tidy_numbers(&flag_names(&msg)))
}

/// An option named as a library names it (``invalid option `preprocess.kappa_threshold` ``)
/// becomes the flag a user types (`--kappa`), when the command being run has that flag: the
/// field's last part, in kebab case, or a flag named otherwise (`kappa_threshold` is `--kappa`).
/// `epsilon` is left as it is: two flags (`--epsilon`, `--epsilon-abs`) set it.
fn flag_names(text: &str) -> String {
    const PREFIX: &str = "invalid option `";
    let mut out = String::new();
    let mut rest = text;
    while let Some(at) = rest.find(PREFIX) {
        let after = &rest[at + PREFIX.len()..];
        let Some(end) = after.find('`') else { break };
        let name = &after[..end];
        out.push_str(&rest[..at]);
        match flag_for(name) {
            Some(flag) => out.push_str(&flag),
            None => out.push_str(&rest[at..at + PREFIX.len() + end + 1]),
        }
        rest = &after[end + 1..];
    }
    out.push_str(rest);
    out
}

/// The command-line flag for a library option name, if the command being run has it (with no
/// command known, if any command has it).
fn flag_for(name: &str) -> Option<String> {
    fn has(c: &clap::Command, long: &str) -> bool {
        c.get_arguments().any(|a| a.get_long() == Some(long)) || c.get_subcommands().any(|s| has(s, long))
    }
    let last = name.rsplit('.').next()?;
    let long = match last {
        "kappa_threshold" => "kappa".to_string(),
        "epsilon" => return None,
        other => other.replace('_', "-"),
    };
    let mut cmd = <crate::cli::Cli as clap::CommandFactory>::command();
    for sub in COMMAND_PATH.get().into_iter().flatten() {
        match cmd.find_subcommand(sub) {
            Some(s) => cmd = s.clone(),
            None => break,
        }
    }
    has(&cmd, &long).then(|| format!("--{long}"))
}

/// Writes numbers of more than 20 digits in scientific notation: `{}` prints an f64 in full, so
/// `--radius 1e-300` came back in messages as a 300-digit decimal.
pub fn tidy_numbers(text: &str) -> String {
    let b = text.as_bytes();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    while i < b.len() {
        let start = i;
        // A run of digits inside a name (`scan_20240101120000123456789.ply`) is not a number.
        let before = text[..start].chars().next_back();
        let before_minus =
            before == Some('-') && !text[..start - 1].chars().next_back().is_some_and(is_name_char);
        if b[i].is_ascii_digit() && (before.is_none_or(|c| !is_name_char(c) && c != '-') || before_minus) {
            while i < b.len()
                && (b[i].is_ascii_digit() || (b[i] == b'.' && b.get(i + 1).is_some_and(u8::is_ascii_digit)))
            {
                i += 1;
            }
            let run = &text[start..i];
            let digits = run.bytes().filter(u8::is_ascii_digit).count();
            let after = text[i..].chars().next();
            let in_name = after.is_some_and(|c| is_name_char(c) || c == '/')
                || (after == Some('.') && text[i + 1..].chars().next().is_some_and(|c| c.is_alphabetic()));
            match run.parse::<f64>() {
                Ok(v) if digits > 20 && v.is_finite() && !in_name => {
                    let e = format!("{v:.3e}");
                    // 1.000e-300 → 1e-300, 1.500e300 → 1.5e300.
                    let (mantissa, exp) = e.split_once('e').unwrap_or((&e, "0"));
                    let mantissa = if mantissa.contains('.') {
                        mantissa.trim_end_matches('0').trim_end_matches('.')
                    } else {
                        mantissa
                    };
                    out.push_str(&format!("{mantissa}e{exp}"));
                }
                _ => out.push_str(run),
            }
        } else {
            // Copy up to the next character that could start a number (a digit run inside a
            // name is copied whole).
            let c = text[i..].chars().next().unwrap_or(' ');
            out.push(c);
            i += c.len_utf8();
            if is_name_char(c) {
                while i < b.len() && b[i].is_ascii_digit() {
                    out.push(b[i] as char);
                    i += 1;
                }
            }
        }
    }
    out
}

/// A character that makes a digit run next to it part of a name or word.
fn is_name_char(c: char) -> bool {
    c.is_alphanumeric() || c == '_'
}

static COMMAND_PATH: std::sync::OnceLock<Vec<String>> = std::sync::OnceLock::new();

/// The subcommand path being run (`["baseline", "rigid-icp"]`), for errors that name its flags.
pub fn set_command_path(path: Vec<String>) {
    let _ = COMMAND_PATH.set(path);
}

/// The operating system's messages in the style of Motif's own: lower case, without the
/// "(os error N)" suffix (`nope.json: no such file or directory`, as `sparsity` and the file
/// checks already said, rather than `No such file or directory (os error 2)`).
pub fn plain_os_text(msg: &str) -> String {
    let mut out = String::with_capacity(msg.len());
    let mut rest = msg;
    while let Some(i) = rest.find(" (os error ") {
        let tail = &rest[i + " (os error ".len()..];
        let digits = tail.bytes().take_while(u8::is_ascii_digit).count();
        if digits > 0 && tail[digits..].starts_with(')') {
            out.push_str(&rest[..i]);
            rest = &tail[digits + 1..];
        } else {
            out.push_str(&rest[..i + 1]);
            rest = &rest[i + 1..];
        }
    }
    out.push_str(rest);
    for (os, plain) in [
        ("No such file or directory", "no such file or directory"),
        ("Permission denied", "permission denied"),
        ("Is a directory", "is a directory"),
        ("Not a directory", "not a directory"),
        ("File exists", "file exists"),
        ("No space left on device", "no space left on device"),
        ("Read-only file system", "read-only file system"),
    ] {
        out = out.replace(os, plain);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::{flag_names, plain_os_text, tidy_numbers};

    #[test]
    fn library_option_names_become_the_flags_users_type() {
        assert_eq!(
            flag_names("invalid option `preprocess.kappa_threshold`: must be > 0"),
            "--kappa: must be > 0"
        );
        assert_eq!(flag_names("invalid option `em.peak_share`: at most 1"), "--peak-share: at most 1");
        assert_eq!(flag_names("a: invalid option `tau`: x"), "a: --tau: x");
        // A name no command has as a flag is kept.
        assert_eq!(
            flag_names("invalid option `extent.no_such_thing`: x"),
            "invalid option `extent.no_such_thing`: x"
        );
    }

    #[test]
    fn huge_and_tiny_numbers_are_written_in_scientific_notation() {
        let tiny = format!("radius {} (the model is 1.5061 across)", 1e-300);
        assert_eq!(tidy_numbers(&tiny), "radius 1e-300 (the model is 1.5061 across)");
        assert_eq!(tidy_numbers(&format!("--tau {}: too long", 1.5e300)), "--tau 1.5e300: too long");
        assert_eq!(tidy_numbers(&format!("x -{}", 1e-300)), "x -1e-300");
        // Ordinary numbers, names with digits and non-ASCII text are kept as they are.
        let plain = "scene_12.ply: 300000 points, 0.000125 apart, τ ≤ 0.5, seed 18446744073709551615";
        assert_eq!(tidy_numbers(plain), plain);
        // So are long digit runs in file names and identifiers.
        for name in [
            "error: scan_20240101120000123456789.ply: no such file",
            "error: 1234567890123456789012.obj: no such file",
            "a/123456789012345678901234/b.ply",
            "id-1234567890123456789012345",
            "run1234567890123456789012345",
        ] {
            assert_eq!(tidy_numbers(name), name);
        }
    }

    #[test]
    fn os_messages_are_written_like_motif_s_own() {
        assert_eq!(
            plain_os_text("a.json: No such file or directory (os error 2)"),
            "a.json: no such file or directory"
        );
        assert_eq!(plain_os_text("x: Is a directory (os error 21): y"), "x: is a directory: y");
        // Text that merely looks similar is kept.
        assert_eq!(plain_os_text("a (os error x) b"), "a (os error x) b");
    }
}

/// 2 when a file could not be read because of what the user named (missing, a directory), 1 for
/// other system failures.
fn io_exit_code(e: &std::io::Error) -> u8 {
    use std::io::ErrorKind::*;
    if matches!(e.kind(), NotFound | InvalidData | UnexpectedEof | IsADirectory | PermissionDenied) {
        2
    } else {
        1
    }
}

/// Checks every output of a command before any work is done, so that a bad path costs nothing
/// and leaves nothing behind: each output's directory must exist and the output must not be a
/// directory; no output may be one of the `inputs` (the same file after resolving links) unless
/// `force`; and no two outputs may be the same file, even with `force` (one would silently
/// replace the other). Outputs that merely exist are replaced, as `cp` does. `None` (an output
/// not asked for) and `-` (a report on stdout) are skipped.
///
/// Also refused before the work: two outputs on stdout (`-o - --json`: two JSON documents back
/// to back, which no reader can parse), and an output whose folder refuses a file (permissions,
/// a name too long once the temporary file's suffix is added, `/proc`): this was found only
/// when the result was written, after the whole computation.
pub fn check_outputs(outputs: &[Option<&Path>], inputs: &[&Path], force: bool) -> anyhow::Result<()> {
    let on_stdout = outputs.iter().flatten().filter(|o| **o == Path::new("-")).count();
    if on_stdout == 1 {
        STDOUT_DOCUMENT.store(true, std::sync::atomic::Ordering::Relaxed);
    }
    if on_stdout > 1 {
        return Err(bad_input(format!(
            "{on_stdout} outputs are given as - (standard output), which would print them one after \
             the other as one stream no reader can split: give all but one of them a file"
        )));
    }
    let mut seen: Vec<(PathBuf, &Path)> = Vec::new();
    for output in outputs.iter().flatten().copied() {
        if output == Path::new("-") {
            continue;
        }
        let resolved = resolve_output(output)?;
        if let Some((_, first)) = seen.iter().find(|(r, _)| *r == resolved) {
            return Err(bad_input(if *first == output {
                format!("{}: given for two outputs (each output needs its own file)", output.display())
            } else {
                format!(
                    "{} and {}: the same file given for two outputs (each output needs its own file)",
                    first.display(),
                    output.display()
                )
            }));
        }
        if !force && inputs.iter().any(|i| std::fs::canonicalize(i).is_ok_and(|i| i == resolved)) {
            return Err(bad_input(format!(
                "{}: refusing to overwrite an input file (choose another output or pass --force)",
                output.display()
            )));
        }
        seen.push((resolved, output));
    }
    for output in outputs.iter().flatten().copied().filter(|o| *o != Path::new("-")) {
        motif_core::io::check_writable(output)?;
    }
    Ok(())
}

/// What an output file holds, for [`check_output_formats`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutputKind {
    /// A mesh or point cloud in any format Motif writes (by extension).
    Model,
    /// A point cloud: any model format but STL, which holds only triangles.
    PointCloud,
    /// A picture, written as PNG.
    Png,
}

/// Checks before any work that each output's extension names a format Motif writes for what it
/// will hold, so that a typo in an extension does not surface only after a long computation.
/// `None` (an output not asked for) is skipped.
pub fn check_output_formats(outputs: &[(Option<&Path>, OutputKind)]) -> anyhow::Result<()> {
    for &(path, kind) in outputs {
        let Some(path) = path else { continue };
        match kind {
            OutputKind::Model | OutputKind::PointCloud => {
                let format = motif_core::io::Format::from_path(path).map_err(|e| bad_input(e.to_string()))?;
                if kind == OutputKind::PointCloud && format == motif_core::io::Format::Stl {
                    return Err(bad_input(format!(
                        "{}: STL holds only triangles, not a point cloud (use .ply, .obj, .off, .gltf or .glb)",
                        path.display()
                    )));
                }
            }
            OutputKind::Png => {
                if !path.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")) {
                    return Err(bad_input(format!(
                        "{}: pictures are written as PNG; give the file a .png extension",
                        path.display()
                    )));
                }
            }
        }
    }
    Ok(())
}

/// Where `output` will be written: its resolved directory joined with its file name (the file
/// itself need not exist). Errors when the directory does not exist or the path is a directory.
fn resolve_output(output: &Path) -> anyhow::Result<PathBuf> {
    if output.is_dir() {
        return Err(bad_input(format!("{}: is a directory, not an output file", output.display())));
    }
    if let Ok(existing) = std::fs::canonicalize(output) {
        return Ok(existing);
    }
    let Some(name) = output.file_name() else {
        return Err(bad_input(format!("{}: not a file name", output.display())));
    };
    let dir = match output.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    match std::fs::canonicalize(dir) {
        Ok(d) if d.is_dir() => Ok(d.join(name)),
        Ok(_) => Err(bad_input(format!("{}: {} is not a directory", output.display(), dir.display()))),
        Err(_) => Err(bad_input(format!(
            "{}: the directory {} does not exist (create it first)",
            output.display(),
            dir.display()
        ))),
    }
}

/// Writes a JSON report: to stdout when `dest` is `-`, else atomically to the file.
pub fn write_json<T: Serialize>(dest: &Path, value: &T) -> anyhow::Result<()> {
    let text = serde_json::to_string_pretty(value).context("serialising the JSON report")?;
    if dest == Path::new("-") {
        println!("{text}");
        return Ok(());
    }
    motif_core::io::write_atomic(dest, |w| {
        w.write_all(text.as_bytes())?;
        w.write_all(b"\n")
    })?;
    Ok(())
}

/// Whether `--quiet` was given ([`set_quiet`]): [`maybe_json`] then says nothing.
static QUIET: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Records `--quiet` for the messages of this module that have no `GlobalArgs` at hand.
pub fn set_quiet(quiet: bool) {
    QUIET.store(quiet, std::sync::atomic::Ordering::Relaxed);
}

/// Writes the report when `--json` was given, and says where (`wrote FILE (report)`, on stderr,
/// unless `--quiet`), as every command says where its other outputs went.
pub fn maybe_json<T: Serialize>(dest: &Option<PathBuf>, value: &T) -> anyhow::Result<()> {
    let Some(d) = dest else { return Ok(()) };
    write_json(d, value)?;
    if !json_on_stdout(dest) && !QUIET.load(std::sync::atomic::Ordering::Relaxed) {
        eprintln!("wrote {} (report)", d.display());
    }
    Ok(())
}

/// Set by [`check_outputs`] when one of the command's outputs (`-o -`, `--gt -`, `--json` with no
/// file) is written to stdout: stdout then carries that document alone.
static STDOUT_DOCUMENT: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// True when the JSON report, or another output checked by [`check_outputs`] (`detect -o -`,
/// `example --gt -`), goes to stdout, so human-readable text must not: `detect -o - | jq` read
/// the result followed by the summary lines, which no JSON reader accepts.
pub fn json_on_stdout(dest: &Option<PathBuf>) -> bool {
    dest.as_deref() == Some(Path::new("-")) || STDOUT_DOCUMENT.load(std::sync::atomic::Ordering::Relaxed)
}

/// Whether some output of the command goes to stdout ([`check_outputs`]).
pub fn stdout_is_a_document() -> bool {
    STDOUT_DOCUMENT.load(std::sync::atomic::Ordering::Relaxed)
}

/// Milliseconds since `t`, rounded to microseconds for reports.
pub fn ms_since(t: std::time::Instant) -> f64 {
    (t.elapsed().as_secs_f64() * 1e6).round() / 1e3
}
