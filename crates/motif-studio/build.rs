//! Installs the studio's web dependencies (three.js from npm, pinned by `web/package-lock.json`)
//! before the crate embeds them with `include_bytes!`.
//!
//! Why a build script: the README's single build command (`cargo run --release -- demo`) must be
//! enough for a new user, and the binary must serve three.js itself (offline, no CDN). Running
//! `npm ci` here when `web/node_modules/three` is missing does both; once installed, nothing runs
//! again until the lock file changes. The assets are then compiled into the binary, so `motif
//! studio` works from any directory without the source tree.

use std::path::Path;
use std::process::Command;

fn main() {
    let manifest = std::env::var("CARGO_MANIFEST_DIR").unwrap_or_else(|_| ".".to_string());
    let web = Path::new(&manifest).join("web");
    println!("cargo:rerun-if-changed=web/package.json");
    println!("cargo:rerun-if-changed=web/package-lock.json");
    // Missing files make cargo rerun this script, so deleting node_modules reinstalls it.
    println!("cargo:rerun-if-changed=web/node_modules/three/package.json");
    let three = web.join("node_modules/three/package.json");
    let lock_newer = match (std::fs::metadata(web.join("package-lock.json")), std::fs::metadata(&three)) {
        (Ok(lock), Ok(installed)) => match (lock.modified(), installed.modified()) {
            (Ok(l), Ok(i)) => l > i,
            _ => false,
        },
        _ => false,
    };
    if three.exists() && !lock_newer {
        return;
    }
    let npm = if cfg!(windows) { "npm.cmd" } else { "npm" };
    let status = Command::new(npm)
        .args(["ci", "--ignore-scripts", "--no-audit", "--no-fund"])
        .current_dir(&web)
        .status();
    match status {
        Ok(s) if s.success() && three.exists() => {}
        Ok(s) => fail(&format!(
            "`npm ci` in {} failed ({s}); the studio needs three.js from the npm registry. Run it by hand to see why.",
            web.display()
        )),
        Err(e) => fail(&format!(
            "cannot run npm ({e}). The studio embeds three.js installed from npm: install Node.js and npm \
             (Debian: `apt-get install nodejs npm`) and build again."
        )),
    }
}

fn fail(message: &str) -> ! {
    eprintln!("error: motif-studio web assets: {message}");
    std::process::exit(1);
}
