//! Atomic file replacement: write a temporary file next to the target, fsync it, rename it over
//! the target. Readers see the old file or the new one, never a half-written one.
//!
//! Two kinds of targets are not replaced: a symbolic link is followed (the file it points to is
//! replaced and the link kept, as editors do), and a device, FIFO or socket (`/dev/null`,
//! `/dev/stdout`, a named pipe) is written through like `cat > path` would. Renaming a temporary
//! file over those would replace the link or the device node itself: run as root, `-o /dev/null`
//! once turned the machine's `/dev/null` into a regular file.

use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::{Error, Result};

/// Writes a file atomically: `f` writes into a buffered temporary file in the target's directory
/// (so the final rename stays on one file system), which is flushed, fsynced and renamed over
/// `path`; the directory is then fsynced (best effort) so the rename survives a crash. On any
/// error, and if `f` panics, the temporary file is removed and an existing file at `path` is left
/// untouched. After [`defer_renames`], the complete temporary file waits for
/// [`commit_deferred`] instead of being renamed at once.
///
/// Used by every mesh writer and by other writers of the project (CSV, JSON).
pub fn write_atomic(path: &Path, f: impl FnOnce(&mut dyn Write) -> io::Result<()>) -> Result<()> {
    let Some((resolved, dir)) = file_target(path)? else {
        return write_through(path, f);
    };
    let (path, dir) = (resolved.as_path(), dir.as_path());
    let (file, guard) = create_temp_for(path, dir, path)?;
    // A file that is replaced keeps its permissions (a private 600 output stayed 600 with
    // `cp`, and became 644 here).
    if let Some(meta) = fs::metadata(path).ok().filter(|m| m.is_file()) {
        let _ = fs::set_permissions(&guard.path, meta.permissions());
    }
    let result = (|| {
        let mut w = BufWriter::new(file);
        f(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        drop(file);
        // Under the registry's lock: an interrupt removes the temporary file either before the
        // rename (the target is untouched) or after it (the target is complete), never between.
        let live = LIVE_TEMPS.lock().unwrap_or_else(|e| e.into_inner());
        if !live.contains(&guard.path) {
            return Err(io::Error::new(io::ErrorKind::Interrupted, "interrupted"));
        }
        if DEFERRING.load(Ordering::SeqCst) {
            // Renamed by `commit_deferred` once every output is written.
            return Ok(true);
        }
        let renamed = fs::rename(&guard.path, path);
        drop(live);
        renamed.map(|()| false)
    })();
    match result {
        Ok(true) => {
            let temp = guard.keep();
            DEFERRED.lock().unwrap_or_else(|e| e.into_inner()).push((temp, path.to_path_buf()));
            Ok(())
        }
        Ok(false) => {
            guard.disarm();
            sync_dir(dir);
            Ok(())
        }
        // The guard removes the temporary file.
        Err(e) => Err(Error::io(path, e)),
    }
}

/// The path a chain of symbolic links ends at (the path itself when it is no link; a dangling
/// link gives the missing file it names). At most 40 links are followed, as the kernel does.
fn follow_links(path: &Path) -> PathBuf {
    let mut p = path.to_path_buf();
    for _ in 0..40 {
        let is_link = fs::symlink_metadata(&p).is_ok_and(|m| m.file_type().is_symlink());
        let Some(target) = is_link.then(|| fs::read_link(&p).ok()).flatten() else { break };
        p = match p.parent() {
            Some(dir) if target.is_relative() => dir.join(target),
            _ => target,
        };
    }
    p
}

/// Writes into an existing device, FIFO or socket without replacing it.
fn write_through(path: &Path, f: impl FnOnce(&mut dyn Write) -> io::Result<()>) -> Result<()> {
    let result = (|| {
        let mut w = BufWriter::new(OpenOptions::new().write(true).open(path)?);
        f(&mut w)?;
        w.flush()
    })();
    result.map_err(|e| Error::io(path, e))
}

/// Removes the temporary file when dropped, unless disarmed after the rename.
struct TempGuard {
    path: PathBuf,
    armed: bool,
}

impl TempGuard {
    fn disarm(mut self) {
        self.armed = false;
        forget_temp(&self.path);
    }

    /// Keeps the temporary file, still registered for removal on an interrupt.
    fn keep(mut self) -> PathBuf {
        self.armed = false;
        std::mem::take(&mut self.path)
    }
}

/// Whether [`write_atomic`] defers its renames (see [`defer_renames`]).
static DEFERRING: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// The deferred writes: each complete, fsynced temporary file and the target it replaces.
static DEFERRED: std::sync::Mutex<Vec<(PathBuf, PathBuf)>> = std::sync::Mutex::new(Vec::new());

/// From now on, [`write_atomic`] leaves each complete temporary file in place, and
/// [`commit_deferred`] renames them all over their targets at the end; [`discard_deferred`]
/// removes them instead. For a command with several outputs (a detection result, its labelled
/// points, a picture, a report): when the last one fails (a full disk, a folder that refuses
/// it), no output is left behind, as no output of the run is replaced until all are written.
/// Devices and pipes are written at once, as before. A program that reads back what it
/// wrote must not defer.
pub fn defer_renames() {
    DEFERRING.store(true, Ordering::SeqCst);
}

/// Renames every deferred write over its target, in the order they were written, and stops
/// deferring. On the first failure the remaining temporary files are removed and that error is
/// returned (the targets renamed before it stay replaced: a rename within one folder fails only
/// when the folder itself changed meanwhile).
pub fn commit_deferred() -> Result<()> {
    DEFERRING.store(false, Ordering::SeqCst);
    let pending = std::mem::take(&mut *DEFERRED.lock().unwrap_or_else(|e| e.into_inner()));
    let mut failure = None;
    for (temp, target) in pending {
        if failure.is_some() {
            let _ = fs::remove_file(&temp);
            forget_temp(&temp);
            continue;
        }
        // Under the registry's lock, as in `write_atomic`.
        let live = LIVE_TEMPS.lock().unwrap_or_else(|e| e.into_inner());
        let renamed = if live.contains(&temp) {
            fs::rename(&temp, &target)
        } else {
            Err(io::Error::new(io::ErrorKind::Interrupted, "interrupted"))
        };
        drop(live);
        forget_temp(&temp);
        match renamed {
            Ok(()) => sync_dir(folder_of(&target)),
            Err(e) => {
                let _ = fs::remove_file(&temp);
                failure = Some(Error::io(&target, e));
            }
        }
    }
    failure.map_or(Ok(()), Err)
}

/// Removes every deferred write's temporary file (the targets stay as they were) and stops
/// deferring: for a command that failed after some of its outputs were written.
pub fn discard_deferred() {
    DEFERRING.store(false, Ordering::SeqCst);
    let pending = std::mem::take(&mut *DEFERRED.lock().unwrap_or_else(|e| e.into_inner()));
    for (temp, _) in pending {
        let _ = fs::remove_file(&temp);
        forget_temp(&temp);
    }
}

/// Checks that `path` can be written as [`write_atomic`] writes it, by creating and removing
/// its temporary file: a folder that refuses files, a name too long once the temporary file's
/// `.NAME.PID.N.tmp` is added, a path in `/proc`. Devices, pipes and links to them are not
/// touched. For a command's outputs before it starts its work, so that a long computation does
/// not end in "permission denied".
pub fn check_writable(path: &Path) -> Result<()> {
    let Some((resolved, dir)) = file_target(path)? else { return Ok(()) };
    // Dropping the file and its guard removes it.
    create_temp_for(&resolved, &dir, path).map(drop)
}

/// The regular file a write to `path` replaces, with its folder: `None` for a device, FIFO or
/// socket, which is written through. What the path ends at is asked of the kernel first:
/// `/dev/stdout` on a pipe is a link to `/proc/self/fd/1`, whose link text `pipe:[N]` names no
/// file, so following the links by hand reached nothing (a report given `--json /dev/stdout |
/// cat` failed with "no such file").
fn file_target(path: &Path) -> Result<Option<(PathBuf, PathBuf)>> {
    if fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir()) {
        return Ok(None);
    }
    let resolved = follow_links(path);
    if resolved.file_name().is_none() {
        return Err(Error::io(
            &resolved,
            io::Error::new(io::ErrorKind::InvalidInput, "the path names no file"),
        ));
    }
    let dir = folder_of(&resolved).to_path_buf();
    Ok(Some((resolved, dir)))
}

/// The folder a file is in, `.` for a bare name.
fn folder_of(path: &Path) -> &Path {
    path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."))
}

/// [`create_temp`] for the file `path` in `dir`, its failure said as the folder's and named by
/// `named` (the path as the user gave it, or as resolved).
fn create_temp_for(path: &Path, dir: &Path, named: &Path) -> Result<(File, TempGuard)> {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    create_temp(dir, &name).map_err(|e| Error::io(named, temp_error(dir, e)))
}

impl Drop for TempGuard {
    fn drop(&mut self) {
        if self.armed {
            let _ = fs::remove_file(&self.path);
            forget_temp(&self.path);
        }
    }
}

/// The temporary files being written now, for [`remove_temporary_files`].
static LIVE_TEMPS: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

fn forget_temp(path: &Path) {
    let mut live = LIVE_TEMPS.lock().unwrap_or_else(|e| e.into_inner());
    live.retain(|p| p != path);
}

/// Removes the temporary files of the writes in progress, then runs `then` (which ends the
/// process) before any new write can start or a write in progress can register or rename its
/// file: the registry stays locked meanwhile. For a program's interrupt handler (Ctrl-C,
/// SIGTERM), which ends the process without running the writers' own clean-up: a
/// `.NAME.PID.N.tmp` of a large output was left behind. The targets are untouched.
pub fn remove_temporary_files_and(then: impl FnOnce()) {
    let mut live = LIVE_TEMPS.lock().unwrap_or_else(|e| e.into_inner());
    for p in live.drain(..) {
        let _ = fs::remove_file(p);
    }
    then();
}

/// Creates `.<name>.<pid>.<n>.tmp` in `dir`, with a name no other writer (thread or process) uses.
fn create_temp(dir: &Path, name: &str) -> io::Result<(File, TempGuard)> {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let pid = std::process::id();
    loop {
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let path = dir.join(format!(".{name}.{pid}.{n}.tmp"));
        // Registered before it exists, so that no file is made that an interrupt would miss.
        let mut live = LIVE_TEMPS.lock().unwrap_or_else(|e| e.into_inner());
        live.push(path.clone());
        let opened = OpenOptions::new().write(true).create_new(true).open(&path);
        if opened.is_err() {
            live.retain(|p| p != &path);
        }
        drop(live);
        match opened {
            Ok(file) => return Ok((file, TempGuard { path, armed: true })),
            // A leftover of an earlier process with the same pid: try the next number.
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
}

/// The error of creating the temporary file in `dir`, said as such: the OS's own words named the
/// target (`/proc/version: no such file or directory`, of a file that exists).
fn temp_error(dir: &Path, e: io::Error) -> io::Error {
    let why = match e.kind() {
        io::ErrorKind::InvalidFilename => {
            "the name is too long once the temporary file's `.NAME.PID.N.tmp` is added".to_string()
        }
        _ => e.to_string(),
    };
    io::Error::new(e.kind(), format!("cannot create a file in the folder {}: {why}", dir.display()))
}

/// Makes a rename in `dir` durable. Best effort: not every platform can open a directory.
fn sync_dir(dir: &Path) {
    #[cfg(unix)]
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
    #[cfg(not(unix))]
    let _ = dir;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn leftovers(dir: &Path) -> Vec<String> {
        fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".tmp"))
            .collect()
    }

    #[test]
    fn replaces_the_file_and_leaves_no_temp() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.txt");
        fs::write(&p, "old").unwrap();
        write_atomic(&p, |w| w.write_all(b"new")).unwrap();
        assert_eq!(fs::read_to_string(&p).unwrap(), "new");
        assert!(leftovers(dir.path()).is_empty());
    }

    #[test]
    fn error_keeps_the_old_file_and_removes_the_temp() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.txt");
        fs::write(&p, "old").unwrap();
        let e = write_atomic(&p, |w| {
            w.write_all(b"partial")?;
            Err(io::Error::other("disk full"))
        })
        .unwrap_err();
        assert!(matches!(e, Error::Io { .. }) && e.to_string().contains("a.txt"), "{e}");
        assert_eq!(fs::read_to_string(&p).unwrap(), "old");
        assert!(leftovers(dir.path()).is_empty());
    }

    #[test]
    fn panic_removes_the_temp() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("b.txt");
        let r = std::panic::catch_unwind(|| {
            let _ = write_atomic(&p, |_| panic!("writer bug"));
        });
        assert!(r.is_err());
        assert!(!p.exists());
        assert!(leftovers(dir.path()).is_empty());
    }

    /// A symbolic link stays a link; the file it points to gets the new content.
    #[cfg(unix)]
    #[test]
    fn a_symbolic_link_is_followed_and_kept() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("real.txt");
        fs::write(&target, "old").unwrap();
        let link = dir.path().join("link.txt");
        std::os::unix::fs::symlink("real.txt", &link).unwrap();
        write_atomic(&link, |w| w.write_all(b"new")).unwrap();
        assert!(fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
        assert_eq!(fs::read_to_string(&target).unwrap(), "new");
        assert!(leftovers(dir.path()).is_empty());
    }

    /// A named pipe is written through and stays a pipe (a rename would have replaced it by a
    /// regular file, as it once replaced `/dev/null`).
    #[cfg(unix)]
    #[test]
    fn a_named_pipe_is_written_through_and_kept() {
        use std::io::Read;
        use std::os::unix::fs::FileTypeExt;
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("pipe");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        assert!(made.is_ok_and(|s| s.success()), "mkfifo (coreutils) failed");
        let reader_path = fifo.clone();
        let reader = std::thread::spawn(move || {
            let mut text = String::new();
            File::open(&reader_path).and_then(|mut f| f.read_to_string(&mut text)).map(|_| text)
        });
        write_atomic(&fifo, |w| w.write_all(b"through the pipe")).unwrap();
        assert!(fs::symlink_metadata(&fifo).unwrap().file_type().is_fifo(), "the pipe was replaced");
        assert_eq!(reader.join().unwrap().unwrap(), "through the pipe");
        assert!(leftovers(dir.path()).is_empty());
    }

    #[test]
    fn missing_directory_is_an_io_error() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("no/such/dir/c.txt");
        assert!(matches!(write_atomic(&p, |w| w.write_all(b"x")), Err(Error::Io { .. })));
    }
}
