//! End-to-end tests of the `motif` binary: exit codes, refusal to overwrite inputs, atomic
//! outputs, JSON reports, and every subcommand on generated shapes.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn motif(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_motif"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("the motif binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().expect("a temporary directory")
}

fn files_in(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()).collect();
    v.sort();
    v
}

#[test]
fn usage_errors_exit_2_and_help_exits_0() {
    let d = tmp();
    let o = motif(&["--help"], d.path());
    assert_eq!(o.status.code(), Some(0));
    assert!(stdout(&o).contains("Usage"));
    let o = motif(&["no-such-command"], d.path());
    assert_eq!(o.status.code(), Some(2));
    let o = motif(&["sample", "a.obj", "b.ply"], d.path());
    assert_eq!(o.status.code(), Some(2), "sample needs --radius or --count: {}", stderr(&o));
}

#[test]
fn missing_and_malformed_inputs_exit_2_naming_the_file() {
    let d = tmp();
    let o = motif(&["info", "missing.obj"], d.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("missing.obj"), "{}", stderr(&o));

    std::fs::write(
        d.path().join("bad.ply"),
        b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nend_header\n1\n",
    )
    .unwrap();
    let o = motif(&["convert", "bad.ply", "out.obj"], d.path());
    assert_eq!(o.status.code(), Some(2));
    let e = stderr(&o);
    assert!(e.contains("bad.ply"), "{e}");
    assert!(!e.contains("panicked"), "{e}");
    assert!(!d.path().join("out.obj").exists(), "no partial output on failure");

    std::fs::write(d.path().join("weird.xyz"), b"1 2 3\n").unwrap();
    let o = motif(&["info", "weird.xyz"], d.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("weird.xyz"));
}

#[test]
fn refuses_to_overwrite_its_input_unless_forced() {
    let d = tmp();
    assert!(motif(&["example", "chair", "chair.obj"], d.path()).status.success());
    let before = std::fs::read(d.path().join("chair.obj")).unwrap();
    let o = motif(&["convert", "chair.obj", "chair.obj"], d.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("refusing to overwrite"), "{}", stderr(&o));
    assert_eq!(std::fs::read(d.path().join("chair.obj")).unwrap(), before, "input untouched");
    let o = motif(&["convert", "chair.obj", "./chair.obj", "--force"], d.path());
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn example_convert_info_round_trip_every_format() {
    let d = tmp();
    let o = motif(&["example", "shelf", "shelf.ply", "--structure", "shelf.json"], d.path());
    assert!(o.status.success(), "{}", stderr(&o));
    let s: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.path().join("shelf.json")).unwrap()).unwrap();
    assert!(s.get("cell_pitch").is_some(), "structure JSON has the cell pitch: {s}");

    let info = |f: &str| -> serde_json::Value {
        let o = motif(&["info", f, "--json"], d.path());
        assert!(o.status.success(), "info {f}: {}", stderr(&o));
        serde_json::from_slice(&o.stdout).expect("--json prints JSON on stdout")
    };
    let base = info("shelf.ply");
    for ext in ["obj", "off", "stl", "glb", "ply"] {
        let out = format!("copy.{ext}");
        let o = motif(&["convert", "shelf.ply", &out], d.path());
        assert!(o.status.success(), "convert to {ext}: {}", stderr(&o));
        let r = info(&out);
        if ext == "stl" {
            // STL stores bare triangles: corners are welded by position on load, so parts that
            // touch (the shelf's boards and sides) share vertices afterwards.
            assert!(r["vertices"].as_u64() <= base["vertices"].as_u64(), "{ext}");
        } else {
            assert_eq!(r["vertices"], base["vertices"], "{ext}");
        }
        assert_eq!(r["triangles"], base["triangles"], "{ext}");
        let (a, b) = (r["diagonal"].as_f64().unwrap(), base["diagonal"].as_f64().unwrap());
        assert!((a - b).abs() < 1e-5 * b, "{ext}: diagonal {a} vs {b}");
    }
    // No temporary files left behind by the atomic writer.
    for f in files_in(d.path()) {
        let name = f.file_name().unwrap().to_string_lossy().into_owned();
        assert!(!name.contains(".tmp") && !name.starts_with('.'), "stray file {name}");
    }
}

#[test]
fn example_list_names_every_required_shape() {
    let d = tmp();
    let o = motif(&["example", "--list"], d.path());
    assert!(o.status.success());
    let names = stdout(&o);
    for n in ["shelf", "facade", "fan", "gear", "chair", "windmill", "fence"] {
        assert!(names.lines().any(|l| l.trim() == n), "missing example {n} in {names}");
    }
}
