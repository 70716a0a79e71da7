//! Where the shared test meshes live (`shared/data` with its `MANIFEST.json`), for tests,
//! benchmarks and `motif bench`.

use std::path::{Path, PathBuf};

/// `$MOTIF_DATA` when it is set and holds a `MANIFEST.json`; otherwise the first
/// `shared/data/MANIFEST.json` found walking up from `start` (a crate or repository folder; this
/// also finds the data beside git worktrees). `None` when there is none.
pub fn shared_data_dir(start: &Path) -> Option<PathBuf> {
    if let Some(d) = std::env::var_os("MOTIF_DATA") {
        let d = PathBuf::from(d);
        return d.join("MANIFEST.json").is_file().then_some(d);
    }
    let start = start.canonicalize().unwrap_or_else(|_| start.to_path_buf());
    start.ancestors().map(|a| a.join("shared/data")).find(|p| p.join("MANIFEST.json").is_file())
}
