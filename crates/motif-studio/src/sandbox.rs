//! File access confined to the studio's root folder.
//!
//! Every path a client sends is resolved against the root and checked *after* resolution: `..`
//! components, absolute paths and symbolic links are all followed by `canonicalize`, and the result
//! must still lie under the canonical root. Writes resolve the parent folder the same way, refuse
//! a final component that is a symbolic link (it could point anywhere), and never replace an input
//! the session read.

use std::path::{Component, Path, PathBuf};

use crate::error::{Result, StudioError};

/// The folder a studio may read and write in.
#[derive(Debug, Clone)]
pub struct Sandbox {
    root: PathBuf,
}

/// Folder depth of [`Sandbox::list`] (the root is depth 0).
pub const LIST_DEPTH: usize = 4;
/// Most files [`Sandbox::list`] returns.
pub const LIST_FILES: usize = 5000;

/// Longest path string accepted from a client, bytes.
const MAX_PATH_LEN: usize = 4096;

impl Sandbox {
    /// A sandbox at `root` (canonicalised; must be an existing folder).
    pub fn new(root: &Path) -> Result<Sandbox> {
        let bad = |problem: String| StudioError::BadRoot { path: root.to_path_buf(), problem };
        let canonical = root.canonicalize().map_err(|e| bad(e.to_string()))?;
        if !canonical.is_dir() {
            return Err(bad("not a folder".to_string()));
        }
        Ok(Sandbox { root: canonical })
    }

    /// The canonical root.
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// True when the symbolic link `path` leads to a file under the root (what
    /// [`Sandbox::resolve_read`] accepts).
    fn links_inside(&self, path: &Path) -> bool {
        path.canonicalize().is_ok_and(|c| c.starts_with(&self.root) && c.is_file())
    }

    /// Files under the root, relative paths sorted, for which `keep` is true: folders at most
    /// [`LIST_DEPTH`] deep, without hidden folders, `target` and `node_modules`, and without
    /// following symbolic links to folders (a listing never leaves the root; a link to a file is
    /// listed only when it leads to a file under the root); at most
    /// [`LIST_FILES`] files. The flag is true when a limit cut the listing short.
    pub fn list(&self, keep: impl Fn(&Path) -> bool) -> (Vec<PathBuf>, bool) {
        let mut out = Vec::new();
        let mut truncated = false;
        let mut stack = vec![(self.root.clone(), 0usize)];
        while let Some((dir, depth)) = stack.pop() {
            let Ok(entries) = std::fs::read_dir(&dir) else { continue };
            for entry in entries.flatten() {
                let path = entry.path();
                let name = entry.file_name().to_string_lossy().into_owned();
                let Ok(kind) = entry.file_type() else { continue };
                if kind.is_dir() {
                    if name.starts_with('.') || name == "target" || name == "node_modules" {
                        continue;
                    }
                    if depth + 1 < LIST_DEPTH {
                        stack.push((path, depth + 1));
                    } else {
                        truncated = true;
                    }
                } else if (kind.is_file() || (kind.is_symlink() && self.links_inside(&path))) && keep(&path) {
                    if out.len() == LIST_FILES {
                        truncated = true;
                        break;
                    }
                    out.push(path.strip_prefix(&self.root).unwrap_or(&path).to_path_buf());
                }
            }
        }
        out.sort();
        (out, truncated)
    }

    fn check_text(path: &str) -> Result<()> {
        let bad = |problem: &str| StudioError::BadPath { path: shorten(path), problem: problem.to_string() };
        if path.trim().is_empty() {
            return Err(bad("empty path"));
        }
        if path.len() > MAX_PATH_LEN {
            return Err(bad("path too long"));
        }
        if path.contains('\0') {
            return Err(bad("a path cannot contain NUL bytes"));
        }
        Ok(())
    }

    fn joined(&self, path: &str) -> PathBuf {
        let p = Path::new(path);
        if p.is_absolute() { p.to_path_buf() } else { self.root.join(p) }
    }

    /// Refuses a path that leaves the root with `..` components applied lexically. Used when the
    /// path does not resolve, so that a path outside the root is refused the same way whether
    /// or not it exists (otherwise the message would tell a client which files exist outside).
    fn lexically_inside(&self, path: &str) -> Result<()> {
        let mut out = PathBuf::new();
        for c in self.joined(path).components() {
            match c {
                Component::ParentDir => {
                    out.pop();
                }
                Component::CurDir => {}
                other => out.push(other),
            }
        }
        if out.starts_with(&self.root) {
            Ok(())
        } else {
            Err(StudioError::OutsideRoot { path: shorten(path), root: self.root.clone() })
        }
    }

    fn inside(&self, path: &str, resolved: PathBuf) -> Result<PathBuf> {
        if resolved.starts_with(&self.root) {
            Ok(resolved)
        } else {
            Err(StudioError::OutsideRoot { path: shorten(path), root: self.root.clone() })
        }
    }

    /// Resolves a file to read: it must exist, be a regular file and lie under the root.
    pub fn resolve_read(&self, path: &str) -> Result<PathBuf> {
        Self::check_text(path)?;
        let resolved = self.joined(path).canonicalize().map_err(|e| {
            // A path outside the root that does not exist is refused as outside, as one that
            // exists is.
            self.lexically_inside(path).err().unwrap_or_else(|| StudioError::BadPath {
                path: shorten(path),
                problem: format!("cannot open: {e}"),
            })
        })?;
        let resolved = self.inside(path, resolved)?;
        if !resolved.is_file() {
            return Err(StudioError::BadPath {
                path: shorten(path),
                problem: "not a regular file".to_string(),
            });
        }
        Ok(resolved)
    }

    /// Resolves a file to write: its folder must exist under the root, its name must be a plain
    /// file name, it must not be a symbolic link, and it must not be one of `inputs` (canonical
    /// paths of files the session read).
    pub fn resolve_write(&self, path: &str, inputs: &[PathBuf]) -> Result<PathBuf> {
        Self::check_text(path)?;
        let bad = |problem: &str| StudioError::BadPath { path: shorten(path), problem: problem.to_string() };
        let joined = self.joined(path);
        let name = match joined.components().next_back() {
            Some(Component::Normal(n)) => n.to_os_string(),
            _ => return Err(bad("needs a file name")),
        };
        let parent = joined.parent().ok_or_else(|| bad("needs a file name"))?;
        let parent = parent.canonicalize().map_err(|e| {
            self.lexically_inside(path).err().unwrap_or_else(|| bad(&format!("folder not found: {e}")))
        })?;
        let parent = self.inside(path, parent)?;
        let target = parent.join(name);
        match std::fs::symlink_metadata(&target) {
            Ok(m) if m.file_type().is_symlink() => {
                return Err(bad("is a symbolic link; the studio does not write through links"));
            }
            Ok(m) if m.is_dir() => return Err(bad("is a folder")),
            // A FIFO, socket or device: writing through it would block or go elsewhere (an
            // export onto a FIFO hung its session's thread for good).
            Ok(m) if !m.is_file() => {
                return Err(bad(
                    "is not a regular file (a FIFO, socket or device); the studio writes only files",
                ));
            }
            Ok(_) => {
                if inputs.contains(&target) {
                    return Err(bad("refusing to overwrite a file this session read; choose another name"));
                }
            }
            Err(_) => {}
        }
        Ok(target)
    }

    /// `path` relative to the root, for display (the path itself when it is not under the root).
    pub fn display(&self, path: &Path) -> String {
        path.strip_prefix(&self.root).unwrap_or(path).display().to_string()
    }
}

/// At most 200 characters of a client string, for error messages.
pub(crate) fn shorten(s: &str) -> String {
    if s.len() <= 200 {
        return s.to_string();
    }
    let mut end = 200;
    while !s.is_char_boundary(end) {
        end -= 1;
    }
    format!("{}...", &s[..end])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_inside_and_refuses_escapes() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join("root");
        std::fs::create_dir(&root).unwrap();
        std::fs::write(root.join("a.obj"), "v 0 0 0").unwrap();
        std::fs::write(dir.path().join("secret.txt"), "x").unwrap();
        let s = Sandbox::new(&root).unwrap();
        assert!(s.resolve_read("a.obj").is_ok());
        assert!(matches!(s.resolve_read("../secret.txt"), Err(StudioError::OutsideRoot { .. })));
        // Whether a file outside exists or not, the answer is the same.
        assert!(matches!(s.resolve_read("../no-such-file.txt"), Err(StudioError::OutsideRoot { .. })));
        assert!(matches!(s.resolve_write("../no-such-dir/x.obj", &[]), Err(StudioError::OutsideRoot { .. })));
        assert!(matches!(s.resolve_read("no-such-file.obj"), Err(StudioError::BadPath { .. })));
        let abs = dir.path().join("secret.txt").display().to_string();
        assert!(matches!(s.resolve_read(&abs), Err(StudioError::OutsideRoot { .. })));
        assert!(s.resolve_read("").is_err());
        assert!(s.resolve_read("a\0b").is_err());
        assert!(s.resolve_write("../out.obj", &[]).is_err());
        assert!(s.resolve_write("out.obj", &[]).is_ok());
        let input = s.resolve_read("a.obj").unwrap();
        assert!(s.resolve_write("a.obj", &[input]).is_err());
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink(dir.path().join("secret.txt"), root.join("link.txt")).unwrap();
            assert!(matches!(s.resolve_read("link.txt"), Err(StudioError::OutsideRoot { .. })));
            assert!(s.resolve_write("link.txt", &[]).is_err());
            std::os::unix::fs::symlink(dir.path(), root.join("up")).unwrap();
            assert!(s.resolve_write("up/x.obj", &[]).is_err());
        }
    }
}
