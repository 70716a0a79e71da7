//! SHOT benchmarks: a 100k-point torus and, when `shared/data` is found, CGAL's armadillo
//! (26k vertices, every 10th vertex a keypoint, radius 10 × mean edge length), each on one thread
//! and on all threads. The timings include the kd-tree build, like PCL's `compute()`.
//!
//! When the PCL reference tool is built (`scripts/pcl-shot-setup.sh`), the armadillo case also
//! runs PCL's single-threaded `SHOTEstimation` on the identical input and prints its best-of-10
//! time per keypoint, for comparison with criterion's numbers (`thrpt` is keypoints per second).

use std::path::{Path, PathBuf};
use std::process::Command;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use motif_core::TriMesh;
use motif_core::geometry::Point3;
use motif_core::shot::{ShotOptions, compute_shot};
use rand::{Rng, SeedableRng};

/// `n` points spread uniformly (by area) over a torus with radii 1 and 0.4, with unit normals.
fn torus(n: usize, seed: u64) -> (Vec<Point3>, Vec<Point3>) {
    let (big, small) = (1.0_f64, 0.4_f64);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut points = Vec::with_capacity(n);
    let mut normals = Vec::with_capacity(n);
    while points.len() < n {
        let u: f64 = rng.random_range(0.0..std::f64::consts::TAU);
        let v: f64 = rng.random_range(0.0..std::f64::consts::TAU);
        // Area element ∝ big + small cos v: rejection sampling keeps the density uniform.
        if rng.random_range(0.0..big + small) > big + small * v.cos() {
            continue;
        }
        let normal = [v.cos() * u.cos(), v.cos() * u.sin(), v.sin()];
        let ring = big + small * v.cos();
        points.push([ring * u.cos(), ring * u.sin(), small * v.sin()]);
        normals.push(normal);
    }
    (points, normals)
}

/// A tiny OFF reader (the IO module is separate).
fn read_off(path: &Path) -> Option<TriMesh> {
    let text = std::fs::read_to_string(path).ok()?;
    let mut tokens =
        text.lines().map(|l| l.split('#').next().unwrap_or("")).flat_map(|l| l.split_whitespace());
    if !tokens.next()?.ends_with("OFF") {
        return None;
    }
    let mut num = || tokens.next();
    let nv: usize = num()?.parse().ok()?;
    let nf: usize = num()?.parse().ok()?;
    num()?;
    let mut positions = Vec::with_capacity(nv);
    for _ in 0..nv {
        positions.push([num()?.parse().ok()?, num()?.parse().ok()?, num()?.parse().ok()?]);
    }
    let mut triangles = Vec::with_capacity(nf);
    for _ in 0..nf {
        let k: usize = num()?.parse().ok()?;
        let poly: Vec<u32> = (0..k).map(|_| num().and_then(|t| t.parse().ok())).collect::<Option<_>>()?;
        for j in 1..k.saturating_sub(1) {
            triangles.push([poly[0], poly[j], poly[j + 1]]);
        }
    }
    TriMesh::new(positions, triangles).ok()
}

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn armadillo() -> Option<TriMesh> {
    let data = motif_core::data::shared_data_dir(&repo_root())?;
    read_off(&data.join("natural/cgal_armadillo.off"))
}

fn pcl_tool() -> Option<PathBuf> {
    let path = match std::env::var_os("MOTIF_PCL_SHOT") {
        Some(p) => PathBuf::from(p),
        None => std::env::var_os("CARGO_TARGET_DIR")
            .map(PathBuf::from)
            .unwrap_or_else(|| repo_root().join("target"))
            .join("pcl-shot/pcl_shot"),
    };
    path.is_file().then_some(path)
}

/// Runs PCL's tool on the same input (f32 text, as PCL stores it) and prints its time.
fn report_pcl(points: &[Point3], normals: &[Point3], keys: &[usize], radius: f64) {
    let Some(tool) = pcl_tool() else {
        println!("PCL reference tool not built (run scripts/pcl-shot-setup.sh): no PCL timing");
        return;
    };
    let Ok(dir) = tempfile::tempdir() else { return };
    let input = dir.path().join("points.xyzn");
    let key_file = dir.path().join("keys.txt");
    let mut text = String::new();
    for (p, n) in points.iter().zip(normals) {
        let f = |v: f64| (v as f32).to_string();
        text.push_str(&format!("{} {} {} {} {} {}\n", f(p[0]), f(p[1]), f(p[2]), f(n[0]), f(n[1]), f(n[2])));
    }
    let keys_text: String = keys.iter().map(|k| format!("{k}\n")).collect();
    if std::fs::write(&input, text).is_err() || std::fs::write(&key_file, keys_text).is_err() {
        return;
    }
    let out = Command::new(&tool)
        .arg(&input)
        .arg(&key_file)
        .arg(radius.to_string())
        .arg(dir.path().join("pcl.peershot"))
        .arg("10")
        .output();
    match out {
        Ok(o) if o.status.success() => {
            print!("PCL SHOTEstimation (1 thread, best of 10): {}", String::from_utf8_lossy(&o.stdout))
        }
        Ok(o) => println!("PCL tool failed: {}", String::from_utf8_lossy(&o.stderr)),
        Err(e) => println!("PCL tool failed to start: {e}"),
    }
}

fn bench_case(
    c: &mut Criterion,
    name: &str,
    points: &[Point3],
    normals: &[Point3],
    keys: &[usize],
    radius: f64,
) {
    let options = ShotOptions { radius, ..Default::default() };
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("a one-thread rayon pool");
    let mut group = c.benchmark_group(format!("shot/{name}"));
    group.sample_size(10);
    group.throughput(Throughput::Elements(keys.len() as u64));
    group.bench_function("lrf/1-thread", |b| {
        b.iter(|| one.install(|| compute_shot(points, normals, keys, &options)).expect("valid input"))
    });
    group.bench_function(format!("lrf/{}-threads", rayon::current_num_threads()), |b| {
        b.iter(|| compute_shot(points, normals, keys, &options).expect("valid input"))
    });
    group.finish();
}

fn shot(c: &mut Criterion) {
    let (points, normals) = torus(100_000, 1);
    let keys: Vec<usize> = (0..points.len()).step_by(100).collect();
    // Area 4π² · 0.4 ≈ 15.8, so ~6300 points per unit area: radius 0.12 holds ~290 neighbours.
    bench_case(c, "torus-100k", &points, &normals, &keys, 0.12);

    match armadillo() {
        Some(mesh) => {
            let normals = mesh.vertex_normals();
            let keys: Vec<usize> = (0..mesh.num_vertices()).step_by(10).collect();
            let radius = 10.0 * mesh.mean_edge_length();
            report_pcl(&mesh.positions, &normals, &keys, radius);
            bench_case(c, "armadillo", &mesh.positions, &normals, &keys, radius);
        }
        None => {
            println!("shared/data/natural/cgal_armadillo.off not found (set MOTIF_DATA): armadillo skipped")
        }
    }
}

criterion_group!(benches, shot);
criterion_main!(benches);
