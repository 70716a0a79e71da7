//! `motif studio`: starts the web app (crates/motif-studio) and prints its URL.

use std::io::Write;

use motif_studio::StudioOptions;

use crate::cli::{GlobalArgs, StudioArgs};
use crate::output::bad_input;

pub fn run(a: StudioArgs, g: &GlobalArgs) -> anyhow::Result<()> {
    if !a.host.is_loopback() {
        eprintln!(
            "warning: listening on {} makes the studio reachable from the network: anyone who can connect can read and write files under {}",
            a.host,
            a.root.display()
        );
    }
    let root = a.root.canonicalize().map_err(|e| bad_input(format!("--root {}: {e}", a.root.display())))?;
    let model = match &a.model {
        Some(given) => {
            // A path from the current folder, or else from the root (`--root data shelf.obj`).
            let m = if !given.exists() && given.is_relative() && root.join(given).exists() {
                root.join(given)
            } else {
                given.clone()
            };
            let m = m.canonicalize().map_err(|e| bad_input(format!("{}: {e}", given.display())))?;
            if !m.is_file() {
                return Err(bad_input(format!("{}: not a file", given.display())));
            }
            motif_core::io::Format::from_path(&m).map_err(|e| bad_input(format!("{e}")))?;
            let rel = m.strip_prefix(&root).map_err(|_| {
                bad_input(format!(
                    "{}: outside the studio's root {} (start it with --root set to a folder that holds the model)",
                    m.display(),
                    root.display()
                ))
            })?;
            Some(rel.display().to_string())
        }
        None => None,
    };
    let options =
        StudioOptions { host: a.host, port: a.port, root, model, seed: g.seed, ..Default::default() };
    let quiet = g.quiet;
    motif_studio::run(options, |studio| {
        // The URL goes to stdout (scripts read it); notes to stderr.
        println!("{}", studio.url());
        let _ = std::io::stdout().flush();
        if !quiet {
            eprintln!("motif studio: serving files under {} (Ctrl-C stops it)", studio.root().display());
        }
    })
    .map_err(|e| match e {
        motif_studio::StudioError::BadRoot { .. }
        | motif_studio::StudioError::BadPath { .. }
        | motif_studio::StudioError::OutsideRoot { .. } => bad_input(e.to_string()),
        e => e.into(),
    })
}
