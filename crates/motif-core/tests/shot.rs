//! SHOT descriptor: invariants that stand alone, the PEERSHOT format, and agreement with PCL's
//! `SHOTEstimation` when the reference tool is built (`scripts/pcl-shot-setup.sh`).

use std::path::{Path, PathBuf};
use std::process::Command;

use motif_core::TriMesh;
use motif_core::geometry::{Point3, add, cross, dot, norm, normalize, rotation_about_axis, scale};
use motif_core::shot::{
    CosineInterpolation, SHOT_LEN, ShotDescriptors, ShotFrame, ShotOptions, compute_shot, read_peershot,
    read_peershot_file, write_peershot, write_shot_csv,
};
use rand::{Rng, SeedableRng};

// ---------------------------------------------------------------------------------------------
// Test shapes

/// Radius of the bumpy sphere in direction `u` (unit): a generic shape, no symmetry.
fn bumpy_radius(u: Point3) -> f64 {
    let [x, y, z] = u;
    1.0 + 0.15 * (3.0 * x + 1.0).sin() * (2.0 * y - 0.5).cos()
        + 0.08 * (7.0 * z + 4.0 * x).sin()
        + 0.05 * x * y
}

/// `n` random points on a bumpy sphere with their exact outward unit normals (the gradient of
/// `|p| − r(p/|p|)`, by central differences).
fn bumpy_sphere(n: usize, seed: u64) -> (Vec<Point3>, Vec<Point3>) {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let f = |p: Point3| norm(p) - bumpy_radius(scale(p, 1.0 / norm(p)));
    let mut points = Vec::with_capacity(n);
    let mut normals = Vec::with_capacity(n);
    while points.len() < n {
        let z: f64 = rng.random_range(-1.0..1.0);
        let phi: f64 = rng.random_range(0.0..std::f64::consts::TAU);
        let s = (1.0 - z * z).sqrt();
        let u = [s * phi.cos(), s * phi.sin(), z];
        let p = scale(u, bumpy_radius(u));
        let h = 1e-6;
        let mut g = [0.0; 3];
        for k in 0..3 {
            let mut a = p;
            let mut b = p;
            a[k] += h;
            b[k] -= h;
            g[k] = (f(a) - f(b)) / (2.0 * h);
        }
        if let Some(nrm) = normalize(g) {
            points.push(p);
            normals.push(nrm);
        }
    }
    (points, normals)
}

/// Rounds to f32 and back, so that PCL (which stores f32) and we see identical inputs.
fn to_f32_precision(v: &[Point3]) -> Vec<Point3> {
    v.iter().map(|p| p.map(|c| f64::from(c as f32))).collect()
}

fn rotate_all(v: &[Point3], r: &[[f64; 3]; 3]) -> Vec<Point3> {
    v.iter().map(|p| [dot(r[0], *p), dot(r[1], *p), dot(r[2], *p)]).collect()
}

/// A tiny OFF reader (vertices and polygons, fans for polygons); the IO module is separate.
fn read_off(path: &Path) -> TriMesh {
    let text = std::fs::read_to_string(path).unwrap();
    let mut tokens = text
        .lines()
        .map(|l| l.split('#').next().unwrap_or(""))
        .flat_map(|l| l.split_whitespace())
        .map(str::to_owned);
    let head = tokens.next().unwrap();
    assert!(head.ends_with("OFF"), "{}: not an OFF file", path.display());
    let mut num = || tokens.next().unwrap();
    let nv: usize = num().parse().unwrap();
    let nf: usize = num().parse().unwrap();
    let _ne: usize = num().parse().unwrap();
    let mut positions = Vec::with_capacity(nv);
    for _ in 0..nv {
        positions.push([num().parse().unwrap(), num().parse().unwrap(), num().parse().unwrap()]);
    }
    let mut triangles = Vec::with_capacity(nf);
    for _ in 0..nf {
        let k: usize = num().parse().unwrap();
        let poly: Vec<u32> = (0..k).map(|_| num().parse().unwrap()).collect();
        for j in 1..k.saturating_sub(1) {
            triangles.push([poly[0], poly[j], poly[j + 1]]);
        }
    }
    TriMesh::new(positions, triangles).unwrap()
}

fn cosine(a: &[f32], b: &[f32]) -> f64 {
    let ab: f64 = a.iter().zip(b).map(|(x, y)| f64::from(*x) * f64::from(*y)).sum();
    let aa: f64 = a.iter().map(|x| f64::from(*x).powi(2)).sum();
    let bb: f64 = b.iter().map(|x| f64::from(*x).powi(2)).sum();
    ab / (aa.sqrt() * bb.sqrt())
}

/// Cosine similarities of the descriptors valid in both sets.
fn similarities(a: &ShotDescriptors, b: &ShotDescriptors) -> Vec<f64> {
    (0..a.len())
        .filter(|&i| a.valid[i] && b.valid[i])
        .map(|i| cosine(a.descriptor(i).unwrap(), b.descriptor(i).unwrap()))
        .collect()
}

fn quantile(sorted: &[f64], q: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * q).round() as usize]
}

fn sorted(mut v: Vec<f64>) -> Vec<f64> {
    v.sort_by(f64::total_cmp);
    v
}

// ---------------------------------------------------------------------------------------------
// Invariants

fn sphere_setup() -> (Vec<Point3>, Vec<Point3>, Vec<usize>, ShotOptions) {
    let (p, n) = bumpy_sphere(6000, 7);
    let keys: Vec<usize> = (0..p.len()).step_by(37).collect();
    (p, n, keys, ShotOptions { radius: 0.35, ..Default::default() })
}

#[test]
fn lrf_descriptors_are_rotation_invariant() {
    let (p, n, keys, opts) = sphere_setup();
    let a = compute_shot(&p, &n, &keys, &opts).unwrap();
    let r = rotation_about_axis([0.3, -0.7, 0.5], 1.234);
    let b = compute_shot(&rotate_all(&p, &r), &rotate_all(&n, &r), &keys, &opts).unwrap();
    assert_eq!(a.valid, b.valid);
    assert!(a.num_valid() == keys.len());
    let s = sorted(similarities(&a, &b));
    let exact = s.iter().filter(|&&c| c > 0.99999).count();
    println!("rotation: {exact}/{} keypoints identical, min cosine {:.6}", s.len(), s[0]);
    // Only a vote on a bin boundary (or an axis sign decided by a point on the plane) can move.
    assert!(exact as f64 >= 0.98 * s.len() as f64);
    // Frames rotate with the shape (wherever the descriptor did not move).
    for i in (0..a.len()).filter(|&i| cosine(a.descriptor(i).unwrap(), b.descriptor(i).unwrap()) > 0.99999) {
        for k in 0..3 {
            let fa = a.frames[i][k].map(f64::from);
            let fb = b.frames[i][k].map(f64::from);
            let rotated = [dot(r[0], fa), dot(r[1], fa), dot(r[2], fa)];
            assert!(dot(rotated, fb) > 0.9999, "keypoint {i} axis {k}");
        }
    }
}

#[test]
fn world_descriptors_are_translation_invariant_but_not_rotation_invariant() {
    let (p, n, keys, opts) = sphere_setup();
    let opts = ShotOptions { frame: ShotFrame::World, ..opts };
    let a = compute_shot(&p, &n, &keys, &opts).unwrap();
    let t = [10.0, -3.0, 0.5];
    let moved: Vec<Point3> = p.iter().map(|q| add(*q, t)).collect();
    let b = compute_shot(&moved, &n, &keys, &opts).unwrap();
    let s = sorted(similarities(&a, &b));
    assert_eq!(s.len(), keys.len());
    assert!(quantile(&s, 0.02) > 0.9999, "translation changed descriptors: {s:?}");
    for f in &a.frames {
        assert_eq!(*f, [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
    }

    let r = rotation_about_axis([0.3, -0.7, 0.5], 1.234);
    let c = compute_shot(&rotate_all(&p, &r), &rotate_all(&n, &r), &keys, &opts).unwrap();
    let s = sorted(similarities(&a, &c));
    println!("world frame under rotation: median cosine {:.3}", quantile(&s, 0.5));
    assert!(quantile(&s, 0.5) < 0.9, "world-frame descriptors should change under rotation");
}

#[test]
fn descriptors_are_unit_length_and_frames_orthonormal() {
    let (p, n, keys, opts) = sphere_setup();
    for frame in [ShotFrame::Lrf, ShotFrame::World] {
        for cos in [CosineInterpolation::Pcl, CosineInterpolation::Linear] {
            let o = ShotOptions { frame, cosine_interpolation: cos, ..opts.clone() };
            let d = compute_shot(&p, &n, &keys, &o).unwrap();
            assert_eq!(d.descriptors.len(), keys.len() * SHOT_LEN);
            for i in 0..d.len() {
                let v = d.descriptor(i).unwrap();
                let len: f64 = v.iter().map(|x| f64::from(*x).powi(2)).sum::<f64>().sqrt();
                assert!((len - 1.0).abs() < 1e-5, "{len}");
                assert!(v.iter().all(|x| *x >= -1e-6));
                let [x, y, z] = d.frames[i].map(|a| a.map(f64::from));
                assert!((norm(x) - 1.0).abs() < 1e-5 && (norm(y) - 1.0).abs() < 1e-5);
                assert!(dot(x, y).abs() < 1e-5 && dot(y, z).abs() < 1e-5 && dot(x, z).abs() < 1e-5);
                assert!(dot(cross(x, y), z) > 0.9999, "frames are right-handed");
            }
        }
    }
}

#[test]
fn same_result_on_one_thread() {
    let (p, n, keys, opts) = sphere_setup();
    let a = compute_shot(&p, &n, &keys, &opts).unwrap();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let b = pool.install(|| compute_shot(&p, &n, &keys, &opts)).unwrap();
    assert_eq!(a, b);
}

#[test]
fn fewer_than_five_neighbours_is_invalid() {
    // Keypoint 0 has 4 neighbours within the radius, keypoint 5 has 5 (two clusters far apart);
    // duplicates of the keypoint do not count.
    let mut p = vec![[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.1, 0.0], [0.0, 0.0, 0.1], [0.1, 0.1, 0.02]];
    p.push([0.0, 0.0, 0.0]);
    let c = [5.0, 5.0, 5.0];
    let q = [c, [5.1, 5.0, 5.01], [5.0, 5.1, 5.0], [5.0, 5.0, 5.1], [5.1, 5.1, 5.0], [4.9, 5.05, 5.0]];
    p.extend(q);
    let n = vec![[0.0, 0.0, 1.0]; p.len()];
    let keys = [0, 6];
    let d = compute_shot(&p, &n, &keys, &ShotOptions { radius: 0.5, ..Default::default() }).unwrap();
    assert_eq!(d.valid, [false, true]);
    assert!(d.descriptor(0).unwrap().iter().all(|v| *v == 0.0));
    assert_eq!(d.frames[0], [[0.0; 3]; 3]);
    let d =
        compute_shot(&p, &n, &keys, &ShotOptions { radius: 0.5, min_neighbours: 4, ..Default::default() })
            .unwrap();
    assert_eq!(d.valid, [true, true]);
}

#[test]
fn bad_input_is_an_error() {
    let (p, n, _, opts) = sphere_setup();
    assert!(compute_shot(&p, &n[1..], &[0], &opts).is_err());
    assert!(compute_shot(&p, &n, &[p.len()], &opts).is_err());
    assert!(compute_shot(&p, &n, &[0], &ShotOptions { radius: -1.0, ..opts.clone() }).is_err());
    let mut bad = p.clone();
    bad[3][1] = f64::NAN;
    assert!(compute_shot(&bad, &n, &[0], &opts).is_err());
    // No keypoints is fine.
    assert!(compute_shot(&p, &n, &[], &opts).unwrap().is_empty());
}

// ---------------------------------------------------------------------------------------------
// PEERSHOT

fn sample_descriptors() -> ShotDescriptors {
    let (p, n, _, opts) = sphere_setup();
    let mut p = p[..2000].to_vec();
    let mut n = n[..2000].to_vec();
    p.push([50.0, 50.0, 50.0]); // isolated: invalid
    n.push([0.0, 0.0, 1.0]);
    compute_shot(&p, &n, &[3, 2000, 17], &opts).unwrap()
}

#[test]
fn peershot_round_trips() {
    let d = sample_descriptors();
    assert_eq!(d.valid, [true, false, true]);
    let mut bytes = Vec::new();
    write_peershot(&mut bytes, &d).unwrap();
    assert_eq!(&bytes[..8], b"PEERSHOT");
    assert_eq!(bytes.len(), 16 + 3 * (4 + 36 + 4 * SHOT_LEN));
    assert_eq!(read_peershot(&bytes).unwrap(), d);

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("d.peershot");
    std::fs::write(&path, &bytes).unwrap();
    assert_eq!(read_peershot_file(&path).unwrap(), d);

    let mut csv = Vec::new();
    write_shot_csv(&mut csv, &d).unwrap();
    let csv = String::from_utf8(csv).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 4);
    assert!(lines[0].starts_with("index,xx,xy,xz,yx,yy,yz,zx,zy,zz,f0,f1,") && lines[0].ends_with(",f351"));
    assert_eq!(lines[1].split(',').count(), 1 + 9 + SHOT_LEN);
    assert!(lines[2].starts_with("2000,NaN,"));
    let back: Vec<f32> = lines[1].split(',').skip(1).map(|v| v.parse().unwrap()).collect();
    let frame: Vec<f32> = d.frames[0].iter().flatten().copied().collect();
    assert_eq!(back[..9], frame[..]);
    assert_eq!(back[9..], d.descriptor(0).unwrap()[..]);
}

#[test]
fn peershot_rejects_bad_data() {
    let d = sample_descriptors();
    let mut bytes = Vec::new();
    write_peershot(&mut bytes, &d).unwrap();
    // Truncated anywhere.
    for cut in [0, 7, 15, 16, 100, bytes.len() - 1] {
        let e = read_peershot(&bytes[..cut]).unwrap_err().to_string();
        assert!(e.contains("truncated"), "{cut}: {e}");
    }
    // Trailing garbage.
    let mut long = bytes.clone();
    long.push(0);
    assert!(read_peershot(&long).unwrap_err().to_string().contains("trailing"));
    // Wrong magic.
    let mut bad = bytes.clone();
    bad[0] = b'X';
    assert!(read_peershot(&bad).unwrap_err().to_string().contains("not PEERSHOT"));
    // Wrong descriptor length.
    let mut bad = bytes.clone();
    bad[12..16].copy_from_slice(&351u32.to_le_bytes());
    assert!(read_peershot(&bad).is_err());
    // A huge announced count with little data fails without allocating for it.
    let mut bad = bytes[..16].to_vec();
    bad[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(read_peershot(&bad).unwrap_err().to_string().contains("truncated"));
}

// ---------------------------------------------------------------------------------------------
// Agreement with PCL

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn pcl_tool() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("MOTIF_PCL_SHOT") {
        return Some(PathBuf::from(p)).filter(|p| p.is_file());
    }
    let target =
        std::env::var_os("CARGO_TARGET_DIR").map(PathBuf::from).unwrap_or_else(|| repo_root().join("target"));
    Some(target.join("pcl-shot/pcl_shot")).filter(|p| p.is_file())
}

/// `shared/data`: `MOTIF_DATA`, else `../shared/data` beside the repository (or beside one of its
/// parent folders, for worktrees).
fn data_dir() -> Option<PathBuf> {
    motif_core::data::shared_data_dir(&repo_root())
}

struct Agreement {
    median: f64,
    mean: f64,
    p5: f64,
    frames_agree: f64,
    z_agree: f64,
    valid_agree: usize,
    compared: usize,
}

/// Runs PCL's tool and ours on the same (f32-precision) input and compares.
fn compare_with_pcl(
    tool: &Path,
    name: &str,
    points: &[Point3],
    normals: &[Point3],
    keys: &[usize],
    radius: f64,
) -> Agreement {
    let points = to_f32_precision(points);
    let normals = to_f32_precision(normals);
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("points.xyzn");
    let key_file = dir.path().join("keys.txt");
    let output = dir.path().join("pcl.peershot");
    let mut text = String::new();
    for (p, n) in points.iter().zip(&normals) {
        let f = |v: f64| (v as f32).to_string();
        text.push_str(&format!("{} {} {} {} {} {}\n", f(p[0]), f(p[1]), f(p[2]), f(n[0]), f(n[1]), f(n[2])));
    }
    std::fs::write(&input, text).unwrap();
    std::fs::write(&key_file, keys.iter().map(|k| format!("{k}\n")).collect::<String>()).unwrap();
    let run =
        Command::new(tool).arg(&input).arg(&key_file).arg(radius.to_string()).arg(&output).output().unwrap();
    assert!(run.status.success(), "PCL tool failed: {}", String::from_utf8_lossy(&run.stderr));
    print!("{name}: {}", String::from_utf8_lossy(&run.stdout));
    let pcl = read_peershot_file(&output).unwrap();
    let ours = compute_shot(&points, &normals, keys, &ShotOptions { radius, ..Default::default() }).unwrap();
    assert_eq!(pcl.keypoints, ours.keypoints);

    let valid_agree = (0..keys.len()).filter(|&i| pcl.valid[i] == ours.valid[i]).count();
    let both: Vec<usize> = (0..keys.len()).filter(|&i| pcl.valid[i] && ours.valid[i]).collect();
    assert!(!both.is_empty(), "{name}: no keypoint valid in both");
    let sims = sorted(similarities(&pcl, &ours));
    let axis_dot = |i: usize, k: usize| {
        let a = pcl.frames[i][k].map(f64::from);
        let b = ours.frames[i][k].map(f64::from);
        dot(a, b)
    };
    // The comparison has teeth: the paper's cosine interpolation (without PCL's modulo-10 quirk)
    // agrees measurably worse.
    let linear_opts =
        ShotOptions { radius, cosine_interpolation: CosineInterpolation::Linear, ..Default::default() };
    let linear = compute_shot(&points, &normals, keys, &linear_opts).unwrap();
    let linear = sorted(similarities(&pcl, &linear));
    let linear_mean = linear.iter().sum::<f64>() / linear.len() as f64;
    let linear_p5 = quantile(&linear, 0.05);
    let exact = sims.iter().filter(|&&c| c > 0.99999).count();
    let frames_agree = both.iter().filter(|&&i| (0..3).all(|k| axis_dot(i, k) > 0.999)).count();
    let z_agree = both.iter().filter(|&&i| axis_dot(i, 2) > 0.999).count();
    let a = Agreement {
        median: quantile(&sims, 0.5),
        mean: sims.iter().sum::<f64>() / sims.len() as f64,
        p5: quantile(&sims, 0.05),
        frames_agree: frames_agree as f64 / both.len() as f64,
        z_agree: z_agree as f64 / both.len() as f64,
        valid_agree,
        compared: both.len(),
    };
    println!(
        "{name}: {} keypoints, validity agrees on {}, compared {}: cosine median {:.7} mean {:.7} p5 {:.7} \
         min {:.7}, {exact} above 0.99999; frames agree (all axes within 2.6°) {:.2}%, z axis {:.2}%; \
         paper-style cosine interpolation instead: mean {linear_mean:.6} p5 {linear_p5:.6}",
        keys.len(),
        a.valid_agree,
        a.compared,
        a.median,
        a.mean,
        a.p5,
        sims[0],
        100.0 * a.frames_agree,
        100.0 * a.z_agree
    );
    assert!(linear_mean < a.mean, "the PCL convention should matter");
    a
}

#[test]
fn agrees_with_pcl() {
    let Some(tool) = pcl_tool() else {
        println!("skipping: PCL reference tool not built (run scripts/pcl-shot-setup.sh)");
        return;
    };
    let (p, n) = bumpy_sphere(20_000, 11);
    let keys: Vec<usize> = (0..p.len()).step_by(20).collect();
    let a = compare_with_pcl(&tool, "bumpy sphere", &p, &n, &keys, 0.6);
    assert_eq!(a.valid_agree, keys.len());
    assert!(a.median >= 0.99, "median cosine {} below 0.99", a.median);

    // Noisy positions and normals spread the cosines over every bin and make sign ties likelier.
    let (mut p, mut n) = bumpy_sphere(8000, 12);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(13);
    for (q, m) in p.iter_mut().zip(n.iter_mut()) {
        let jitter = |rng: &mut rand_chacha::ChaCha8Rng, s: f64| -> Point3 {
            [rng.random_range(-s..s), rng.random_range(-s..s), rng.random_range(-s..s)]
        };
        *q = add(*q, jitter(&mut rng, 0.01));
        *m = normalize(add(*m, jitter(&mut rng, 0.6))).unwrap_or(*m);
    }
    let keys: Vec<usize> = (0..p.len()).step_by(10).collect();
    let a = compare_with_pcl(&tool, "noisy sphere", &p, &n, &keys, 0.25);
    assert_eq!(a.valid_agree, keys.len());
    assert!(a.median >= 0.99, "median cosine {} below 0.99", a.median);

    let Some(data) = data_dir() else {
        println!("skipping the armadillo comparison: shared/data not found (set MOTIF_DATA)");
        return;
    };
    let path = data.join("natural/cgal_armadillo.off");
    if !path.is_file() {
        println!("skipping the armadillo comparison: {} not found", path.display());
        return;
    }
    let mesh = read_off(&path);
    let normals = mesh.vertex_normals();
    let keys: Vec<usize> = (0..mesh.num_vertices()).step_by(10).collect();
    let radius = 10.0 * mesh.mean_edge_length();
    let a = compare_with_pcl(&tool, "armadillo", &mesh.positions, &normals, &keys, radius);
    assert!(a.median >= 0.99, "median cosine {} below 0.99", a.median);
}
