//! Loads every file of the shared test-mesh set and checks its vertex and face counts against
//! `MANIFEST.json` (OBJ: `v` records, polygons counted once; STL: corners welded by exact
//! position). The data lives outside the repository: `$MOTIF_DATA`, else `../shared/data` next to
//! the workspace; without it the test prints one line and passes.

use std::path::Path;
use std::time::Instant;

use motif_core::io;

#[test]
fn every_manifest_file_loads_with_the_listed_counts() {
    let Some(dir) = motif_core::data::shared_data_dir(Path::new(env!("CARGO_MANIFEST_DIR"))) else {
        println!("skipping: no test data at ../shared/data or $MOTIF_DATA (set MOTIF_DATA)");
        return;
    };
    let manifest_path = dir.join("MANIFEST.json");
    let text = std::fs::read_to_string(&manifest_path).expect("MANIFEST.json is readable");
    let manifest: serde_json::Value = serde_json::from_str(&text).expect("MANIFEST.json is JSON");
    let files = manifest["files"].as_array().expect("MANIFEST.json has a files array");
    assert!(!files.is_empty(), "the manifest lists no files");

    let mut failures = Vec::new();
    for entry in files {
        let rel = entry["path"].as_str().expect("every entry has a path");
        let want_v = entry["vertices"].as_u64().expect("every entry has a vertex count") as usize;
        let want_f = entry["faces"].as_u64().expect("every entry has a face count") as usize;
        let t = Instant::now();
        match io::read(&dir.join(rel)) {
            Ok(model) => {
                let ms = t.elapsed().as_secs_f64() * 1e3;
                let (v, f) = (model.vertices.len(), model.source_faces);
                println!("{rel:<45} V {v:>7} F {f:>7} {ms:>8.1} ms");
                if (v, f) != (want_v, want_f) {
                    failures.push(format!("{rel}: read V={v} F={f}, manifest says V={want_v} F={want_f}"));
                }
                if !model.warnings.is_empty() {
                    println!("    warnings: {:?}", model.warnings);
                }
            }
            Err(e) => failures.push(format!("{rel}: {e}")),
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} files failed:\n{}",
        failures.len(),
        files.len(),
        failures.join("\n")
    );
}
