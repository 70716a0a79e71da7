//! Surface sampling, Poisson-disc sampling and resampling: the guarantees, exactly.

use motif_core::geometry::{Point3, cross, dist, dot, normalize, sub};
use motif_core::procedural::{self, box_mesh};
use motif_core::sampling::{
    CandidateOrder, Constraints, ForcedOutput, NO_FACE, PoissonDiscOptions, PoissonDiscSampler,
    PoissonDiscSamples, ResampleMethod, ResampleOptions, SampleSource, Spacing, outside_forced,
    poisson_disc_cloud, poisson_disc_points, poisson_disc_surface, resample, sample_surface,
};
use motif_core::spatial::KdTree;
use motif_core::{AttributeData, PointCloud, TriMesh};

fn gear() -> TriMesh {
    procedural::generate("gear", 0).unwrap().mesh
}

/// (a): no two samples closer than r (forced samples `skip` first are exempt among themselves).
fn assert_separated(samples: &[Point3], r: f64, forced: usize) {
    let tree = KdTree::new(samples).unwrap();
    for (i, p) in samples.iter().enumerate() {
        for n in tree.within(*p, r) {
            if n.index == i || (i < forced && n.index < forced) {
                continue;
            }
            assert!(
                n.distance >= r * (1.0 - 1e-12),
                "samples {i} and {} are {} apart (r = {r})",
                n.index,
                n.distance
            );
        }
    }
}

/// (b): every candidate lies closer than r to a sample or exclusion point.
fn assert_covering(candidates: &[Point3], samples: &[Point3], exclusion: &[Point3], r: f64) {
    let mut all = samples.to_vec();
    all.extend_from_slice(exclusion);
    let tree = KdTree::new(&all).unwrap();
    for (i, c) in candidates.iter().enumerate() {
        let d = tree.nearest(*c).distance;
        assert!(d < r, "candidate {i} is {d} from every sample (r = {r})");
    }
}

fn cloud_points(n: usize) -> Vec<Point3> {
    sample_surface(&gear(), n, 11).unwrap().points
}

#[test]
fn surface_samples_lie_on_their_triangles() {
    let mesh = procedural::generate("fan", 0).unwrap().mesh;
    let s = sample_surface(&mesh, 20_000, 3).unwrap();
    assert_eq!(s.len(), 20_000);
    assert_eq!((s.normals.len(), s.faces.len(), s.barycentric.len()), (20_000, 20_000, 20_000));
    let fnormals = mesh.face_normals();
    for i in 0..s.len() {
        let f = s.faces[i] as usize;
        let [a, b, c] = mesh.corners(f);
        let w = s.barycentric[i];
        assert!(w.iter().all(|x| *x >= 0.0) && (w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        let q = [0, 1, 2].map(|k| w[0] * a[k] + w[1] * b[k] + w[2] * c[k]);
        assert!(dist(q, s.points[i]) < 1e-12);
        let n = normalize(cross(sub(b, a), sub(c, a))).unwrap();
        assert!(dot(sub(s.points[i], a), n).abs() < 1e-12, "off the triangle's plane");
        assert_eq!(s.normals[i], fnormals[f]);
    }
}

#[test]
fn surface_sampling_is_deterministic_per_seed() {
    let mesh = gear();
    let a = sample_surface(&mesh, 10_000, 5).unwrap();
    assert_eq!(a, sample_surface(&mesh, 10_000, 5).unwrap());
    assert_ne!(a.points, sample_surface(&mesh, 10_000, 6).unwrap().points);
    // A prefix of the blocks does not depend on how many samples follow.
    let b = sample_surface(&mesh, 4096, 5).unwrap();
    assert_eq!(b.points[..], a.points[..4096]);
}

#[test]
fn surface_sampling_is_area_weighted() {
    // Two disjoint triangles of areas 1 and 3, plus a degenerate one that must never be chosen.
    let mesh = TriMesh::new(
        vec![
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [5.0, 0.0, 0.0],
            [8.0, 0.0, 0.0],
            [5.0, 2.0, 0.0],
            [9.0, 0.0, 0.0],
        ],
        vec![[0, 1, 2], [3, 3, 6], [3, 4, 5]],
    )
    .unwrap();
    let s = sample_surface(&mesh, 200_000, 1).unwrap();
    let first = s.faces.iter().filter(|&&f| f == 0).count() as f64 / s.len() as f64;
    assert!((first - 0.25).abs() < 0.005, "{first}");
    assert!(s.faces.iter().all(|&f| f != 1));
    // Uniform inside a triangle: the mean is the centroid.
    let inside: Vec<Point3> = (0..s.len()).filter(|&i| s.faces[i] == 2).map(|i| s.points[i]).collect();
    let m = inside.iter().fold([0.0; 3], |a, p| [a[0] + p[0], a[1] + p[1], a[2] + p[2]]);
    let m = m.map(|c| c / inside.len() as f64);
    assert!(dist(m, [6.0, 2.0 / 3.0, 0.0]) < 0.01, "{m:?}");
}

#[test]
fn poisson_on_a_cloud_guarantees_separation_and_coverage() {
    let pts = cloud_points(30_000);
    let r = 0.004;
    let o = PoissonDiscOptions { spacing: Spacing::Radius(r), seed: 2, ..Default::default() };
    let s = poisson_disc_points(&pts, None, &Constraints::default(), &o).unwrap();
    assert!(s.len() > 100 && s.len() < pts.len());
    assert_eq!(s.radius, r);
    assert_eq!(s.num_candidates, pts.len());
    for (p, src) in s.positions.iter().zip(&s.sources) {
        let SampleSource::Candidate(i) = src else { panic!("no forced samples were given") };
        assert_eq!(*p, pts[*i]);
    }
    assert_separated(&s.positions, r, 0);
    assert_covering(&pts, &s.positions, &[], r);
}

#[test]
fn poisson_on_a_surface_guarantees_separation_and_coverage() {
    let mesh = procedural::generate("fan", 0).unwrap().mesh;
    let r = 0.01;
    let o = PoissonDiscOptions { spacing: Spacing::Radius(r), seed: 9, ..Default::default() };
    let s = poisson_disc_surface(&mesh, &Constraints::default(), &o).unwrap();
    assert!(s.len() > 200, "{}", s.len());
    assert_separated(&s.positions, r, 0);
    // The candidates are reproducible from the reported count and the seed.
    let cands = sample_surface(&mesh, s.num_candidates, 9).unwrap();
    assert_covering(&cands.points, &s.positions, &[], r);
    let faces = s.faces.as_ref().unwrap();
    let normals = s.normals.as_ref().unwrap();
    for (k, src) in s.sources.iter().enumerate() {
        let SampleSource::Candidate(i) = *src else { panic!() };
        assert_eq!(s.positions[k], cands.points[i]);
        assert_eq!(faces[k], cands.faces[i]);
        assert_eq!(normals[k], cands.normals[i]);
        // On the surface: in the plane of its triangle.
        let [a, b, c] = mesh.corners(faces[k] as usize);
        let n = normalize(cross(sub(b, a), sub(c, a))).unwrap();
        assert!(dot(sub(s.positions[k], a), n).abs() < 1e-12);
    }
    // Coverage of the surface itself (not only the candidates): a fresh dense sample is close.
    let fresh = sample_surface(&mesh, 20_000, 12345).unwrap();
    let tree = KdTree::new(&s.positions).unwrap();
    let d: Vec<f64> = fresh.points.iter().map(|p| tree.nearest(*p).distance).collect();
    let far = d.iter().filter(|&&x| x >= r).count();
    assert!(far < 200, "{far} of 20000 surface points are r or more from every sample");
    // Every surface point has a candidate within r (about 40 candidates per disc), hence a sample
    // within 2r.
    assert!(d.iter().all(|&x| x < 2.0 * r));
}

#[test]
fn poisson_is_deterministic_per_seed() {
    let pts = cloud_points(20_000);
    let o = PoissonDiscOptions { spacing: Spacing::Radius(0.005), seed: 4, ..Default::default() };
    let a = poisson_disc_points(&pts, None, &Constraints::default(), &o).unwrap();
    assert_eq!(a, poisson_disc_points(&pts, None, &Constraints::default(), &o).unwrap());
    let b = poisson_disc_points(
        &pts,
        None,
        &Constraints::default(),
        &PoissonDiscOptions { seed: 5, ..o.clone() },
    )
    .unwrap();
    assert_ne!(a.sources, b.sources);
    let mesh = gear();
    let sa = poisson_disc_surface(&mesh, &Constraints::default(), &o).unwrap();
    assert_eq!(sa, poisson_disc_surface(&mesh, &Constraints::default(), &o).unwrap());
    let sb =
        poisson_disc_surface(&mesh, &Constraints::default(), &PoissonDiscOptions { seed: 5, ..o.clone() })
            .unwrap();
    assert_ne!(sa.positions, sb.positions);
    // The given order takes the first candidate first.
    let g = poisson_disc_points(
        &pts,
        None,
        &Constraints::default(),
        &PoissonDiscOptions { order: CandidateOrder::Given, ..o },
    )
    .unwrap();
    assert_eq!(g.sources[0], SampleSource::Candidate(0));
}

#[test]
fn forced_samples_and_exclusion_points_are_respected() {
    let pts = cloud_points(20_000);
    let r = 0.006;
    let forced: Vec<Point3> = pts[..40].to_vec();
    let exclusion: Vec<Point3> = pts[1000..1040].to_vec();
    let c = Constraints { forced: &forced, exclusion: &exclusion };
    let o = PoissonDiscOptions { spacing: Spacing::Radius(r), seed: 1, ..Default::default() };
    let s = poisson_disc_points(&pts, None, &c, &o).unwrap();
    // Forced samples come first, unchanged.
    for (i, f) in forced.iter().enumerate() {
        assert_eq!(s.sources[i], SampleSource::Forced(i));
        assert_eq!(s.positions[i], *f);
    }
    assert_separated(&s.positions, r, forced.len());
    let ex_tree = KdTree::new(&exclusion).unwrap();
    for p in &s.positions[forced.len()..] {
        assert!(ex_tree.nearest(*p).distance >= r, "a sample lies in an exclusion zone");
        assert!(!exclusion.contains(p));
    }
    assert_covering(&pts, &s.positions, &exclusion, r);
    // Omitting forced samples drops exactly them.
    let omit = poisson_disc_points(
        &pts,
        None,
        &c,
        &PoissonDiscOptions { forced_output: ForcedOutput::Omit, ..o.clone() },
    )
    .unwrap();
    assert_eq!(omit.positions[..], s.positions[forced.len()..]);
    assert!(omit.sources.iter().all(|x| matches!(x, SampleSource::Candidate(_))));
    // On surfaces forced samples carry no face and no normal.
    let mesh = gear();
    let f2 = [mesh.positions[0]];
    let ss = poisson_disc_surface(&mesh, &Constraints { forced: &f2, exclusion: &[] }, &o).unwrap();
    assert_eq!(ss.faces.as_ref().unwrap()[0], NO_FACE);
    assert_eq!(ss.normals.as_ref().unwrap()[0], [0.0; 3]);
    // Candidates remaining after the forced samples excluded their neighbourhoods.
    let rest = outside_forced(&pts, &forced, r).unwrap();
    let ftree = KdTree::new(&forced).unwrap();
    for i in 0..pts.len() {
        assert_eq!(rest.binary_search(&i).is_ok(), ftree.nearest(pts[i]).distance >= r);
    }
}

#[test]
fn incremental_sampler_supports_symmetric_orbits() {
    // Thesis 3.4: insert a free candidate together with its orbit (here the gear's mirror y -> -y).
    let pts = cloud_points(10_000);
    let r = 0.008;
    let mut s = PoissonDiscSampler::new(r).unwrap();
    let tol = 1e-4 * 0.1;
    for p in &pts {
        let m = [p[0], -p[1], p[2]];
        if s.is_free(*p) && s.is_free(m) {
            s.insert_forced(*p).unwrap();
            if dist(*p, m) > tol {
                s.insert_forced(m).unwrap();
            }
        }
    }
    let samples = s.samples().to_vec();
    assert!(samples.len() > 50);
    let tree = KdTree::new(&samples).unwrap();
    for p in &samples {
        assert!(tree.nearest([p[0], -p[1], p[2]]).distance <= tol, "sampling is not mirror-symmetric");
    }
    // Orbit points closer than r to each other are the only violations of separation.
    assert!(s.try_insert(samples[0]).is_none());
}

#[test]
fn count_mode_hits_the_target() {
    let pts = cloud_points(50_000);
    for target in [300, 2000] {
        let o = PoissonDiscOptions { spacing: Spacing::Count(target), seed: 3, ..Default::default() };
        let s = poisson_disc_points(&pts, None, &Constraints::default(), &o).unwrap();
        let err = (s.len() as f64 - target as f64).abs();
        assert!(err <= (0.02 * target as f64).max(1.0), "{} samples for {target}", s.len());
        assert!(s.runs >= 1 && s.runs <= 40);
        assert_separated(&s.positions, s.radius, 0);
    }
    let mesh = procedural::generate("chair", 0).unwrap().mesh;
    let o = PoissonDiscOptions { spacing: Spacing::Count(1500), seed: 3, ..Default::default() };
    let s = poisson_disc_surface(&mesh, &Constraints::default(), &o).unwrap();
    assert!((s.len() as f64 - 1500.0).abs() <= 30.0, "{}", s.len());
    // Forced samples count when they are output.
    let forced = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]];
    let s = poisson_disc_points(
        &pts,
        None,
        &Constraints { forced: &forced, exclusion: &[] },
        &PoissonDiscOptions { spacing: Spacing::Count(500), ..Default::default() },
    )
    .unwrap();
    assert!((s.len() as f64 - 500.0).abs() <= 10.0);
    // Asking for more samples than there are candidates returns them all.
    let few = &pts[..50];
    let s = poisson_disc_points(
        few,
        None,
        &Constraints::default(),
        &PoissonDiscOptions { spacing: Spacing::Count(80), ..Default::default() },
    )
    .unwrap();
    assert_eq!(s.len(), 50);
}

#[test]
fn poisson_samples_are_evenly_spread_over_the_surface() {
    // A 1 x 1 x 4 box: its long faces have four times the area of its ends.
    let mesh = box_mesh([0.0, 0.0, 0.0], [1.0, 1.0, 4.0], [1, 1, 1]).unwrap();
    let o = PoissonDiscOptions { spacing: Spacing::Radius(0.05), seed: 8, ..Default::default() };
    let s = poisson_disc_surface(&mesh, &Constraints::default(), &o).unwrap();
    let normals = mesh.face_normals();
    let faces = s.faces.as_ref().unwrap();
    let (mut ends, mut sides) = (0usize, 0usize);
    for &f in faces {
        if normals[f as usize][2].abs() > 0.5 { ends += 1 } else { sides += 1 }
    }
    // Area per sample on the ends (area 2) and the sides (area 16) agree within 15 %.
    let (a_end, a_side) = (2.0 / ends as f64, 16.0 / sides as f64);
    assert!((a_end / a_side - 1.0).abs() < 0.15, "{a_end} vs {a_side}");
    // About one sample per 1.5 r² (a saturated disc packing: between r²·√3/2 and r²·π/2·... ).
    let per = 18.0 / s.len() as f64 / (0.05 * 0.05);
    assert!(per > 0.9 && per < 2.2, "{per} r² per sample");
}

#[test]
fn bad_input_is_refused() {
    let pts = cloud_points(100);
    let c = Constraints::default();
    let bad_r = PoissonDiscOptions { spacing: Spacing::Radius(0.0), ..Default::default() };
    assert!(poisson_disc_points(&pts, None, &c, &bad_r).is_err());
    let nan_r = PoissonDiscOptions { spacing: Spacing::Radius(f64::NAN), ..Default::default() };
    assert!(poisson_disc_points(&pts, None, &c, &nan_r).is_err());
    let zero = PoissonDiscOptions { spacing: Spacing::Count(0), ..Default::default() };
    assert!(poisson_disc_points(&pts, None, &c, &zero).is_err());
    let mut nan = pts.clone();
    nan[3][1] = f64::NAN;
    assert!(poisson_disc_points(&nan, None, &c, &PoissonDiscOptions::default()).is_err());
    assert!(poisson_disc_points(&pts, Some(&pts[..5]), &c, &PoissonDiscOptions::default()).is_err());
    let forced_nan = [[f64::INFINITY, 0.0, 0.0]];
    let fc = Constraints { forced: &forced_nan, exclusion: &[] };
    assert!(poisson_disc_points(&pts, None, &fc, &PoissonDiscOptions::default()).is_err());
    let mesh = gear();
    let over = PoissonDiscOptions { oversampling: 0.5, ..Default::default() };
    assert!(poisson_disc_surface(&mesh, &c, &over).is_err());
    let tiny = PoissonDiscOptions { spacing: Spacing::Radius(1e-7), ..Default::default() };
    assert!(poisson_disc_surface(&mesh, &c, &tiny).is_err(), "too many candidates must be refused");
    assert!(poisson_disc_surface(&TriMesh::default(), &c, &PoissonDiscOptions::default()).is_err());
    assert!(
        resample(&PointCloud::from_positions(pts), &ResampleOptions { spacing: -1.0, ..Default::default() })
            .is_err()
    );
}

fn attributed_cloud() -> PointCloud {
    let s = sample_surface(&gear(), 30_000, 21).unwrap();
    let n = s.len();
    let mut c = PointCloud::from_positions(s.points);
    c.normals = Some(s.normals);
    c.colors = Some((0..n).map(|i| [(i % 256) as u8, (i / 256 % 256) as u8, 7]).collect());
    c.set_attribute("id", AttributeData::Int((0..n as i64).collect()));
    c.set_attribute("face", AttributeData::Float(s.faces.iter().map(|&f| f as f64).collect()));
    c
}

#[test]
fn poisson_resampling_keeps_point_data() {
    let c = attributed_cloud();
    // Thesis 5.4 gives ε relative to the diagonal (0.0005 for scans); coarser here for a small test.
    let eps = 0.02 * c.diagonal();
    let o = ResampleOptions { spacing: eps, method: ResampleMethod::PoissonDisc, seed: 3 };
    let r = resample(&c, &o).unwrap();
    assert!(r.indices.windows(2).all(|w| w[0] < w[1]));
    assert!(r.cloud.len() > 100 && r.cloud.len() < c.len());
    r.cloud.validate().unwrap();
    let ids = match r.cloud.attribute("id").unwrap() {
        AttributeData::Int(v) => v.clone(),
        _ => panic!(),
    };
    for (k, &i) in r.indices.iter().enumerate() {
        assert_eq!(r.cloud.positions[k], c.positions[i]);
        assert_eq!(r.cloud.normals.as_ref().unwrap()[k], c.normals.as_ref().unwrap()[i]);
        assert_eq!(r.cloud.colors.as_ref().unwrap()[k], c.colors.as_ref().unwrap()[i]);
        assert_eq!(ids[k], i as i64);
    }
    assert_separated(&r.cloud.positions, eps, 0);
    assert_covering(&c.positions, &r.cloud.positions, &[], eps);
    assert_eq!(r, resample(&c, &o).unwrap());
    assert_ne!(r.indices, resample(&c, &ResampleOptions { seed: 4, ..o }).unwrap().indices);
}

#[test]
fn voxel_resampling_keeps_one_point_per_voxel() {
    let c = attributed_cloud();
    let eps = 0.002;
    let o = ResampleOptions { spacing: eps, method: ResampleMethod::VoxelGrid, seed: 0 };
    let r = resample(&c, &o).unwrap();
    let key = |p: Point3| p.map(|x| (x / eps).floor() as i64);
    let occupied: std::collections::HashSet<[i64; 3]> = c.positions.iter().map(|p| key(*p)).collect();
    let kept: std::collections::HashSet<[i64; 3]> = r.cloud.positions.iter().map(|p| key(*p)).collect();
    assert_eq!(kept.len(), r.cloud.len(), "two points kept in one voxel");
    assert_eq!(kept, occupied, "a voxel lost all its points");
    assert_eq!(r, resample(&c, &o).unwrap());
    assert_eq!(r.cloud.attribute("face").unwrap().len(), r.cloud.len());
}

#[test]
fn cloud_sampling_carries_normals() {
    let c = attributed_cloud();
    let o = PoissonDiscOptions { spacing: Spacing::Radius(0.003), ..Default::default() };
    let s: PoissonDiscSamples = poisson_disc_cloud(&c, &Constraints::default(), &o).unwrap();
    let normals = s.normals.as_ref().unwrap();
    for (k, i) in s.candidate_indices().into_iter().enumerate() {
        assert_eq!(normals[k], c.normals.as_ref().unwrap()[i]);
    }
}
