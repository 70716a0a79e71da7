//! From a layout to a scan: area-uniform surface samples, visibility from the virtual scanners,
//! Gaussian noise, outliers, a shuffled point order, and the ground truth.

use motif_core::geometry::{Aabb, Mat4, Point3, dot, mat4_mul, normalize, scale, sub};
use motif_core::procedural::rigid_inverse;
use motif_core::sampling::sample_surface;
use motif_core::{PointCloud, TriMesh};
use rand::Rng;
use rayon::prelude::*;

use super::bvh::Bvh;
use super::layout::{Layout, NOISE, ORDER, OUTLIERS, stream};
use super::{Scene, SceneKind, SceneOptions, SceneSettings, SceneStats};
use crate::detection::{DetectedClass, DetectedInstance, DetectionResult};
use crate::error::{DetectError, Result};

/// Who a triangle (and the points sampled on it) belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Owner {
    Background,
    Clutter,
    Instance(u32),
}

/// The whole scene as one mesh, with each triangle's owner and whether its part is closed and
/// outward-wound (so back faces are hidden without casting a ray).
struct SceneMesh {
    mesh: TriMesh,
    owner: Vec<Owner>,
    outward: Vec<bool>,
}

impl SceneMesh {
    fn push(&mut self, m: &TriMesh, owner: Owner, outward: bool) {
        self.mesh.append(m);
        self.owner.resize(self.mesh.num_triangles(), owner);
        self.outward.resize(self.mesh.num_triangles(), outward);
    }
}

/// A standard normal deviate (Box–Muller; `rand` has no normal distribution without `rand_distr`).
fn gaussian(rng: &mut impl Rng) -> f64 {
    let u1: f64 = 1.0 - rng.random::<f64>();
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// A kept sample: position on the surface, unit normal, owner.
type Sample = (Point3, Point3, Owner);

/// The seed of sampling round `round`, mixed so rounds and seeds do not collide.
fn round_seed(seed: u64, round: u64) -> u64 {
    seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ (round + 1).wrapping_mul(0xD1B5_4A32_D192_ED03)
}

/// Counters of the visibility test.
#[derive(Default)]
struct Seen {
    drawn: usize,
    kept: usize,
    instance_drawn: usize,
    instance_kept: usize,
    /// Per instance: samples drawn on it, and of those, samples a scanner saw.
    per_instance: Vec<(usize, usize)>,
}

/// Draws `n` surface samples that some scanner sees (all of them for complete sampling).
fn visible_samples(
    sm: &SceneMesh,
    scanners: &[Point3],
    n: usize,
    seed: u64,
    seen: &mut Seen,
) -> Result<Vec<Sample>> {
    let normals: Vec<Point3> = sm.mesh.face_normals();
    let bvh = (!scanners.is_empty())
        .then(|| Bvh::new((0..sm.mesh.num_triangles()).map(|f| sm.mesh.corners(f)).collect()));
    let slack = 1e-6 * sm.mesh.diagonal().max(1.0);
    let mut out: Vec<Sample> = Vec::with_capacity(n);
    let mut fraction: f64 = if scanners.is_empty() { 1.0 } else { 0.5 };
    for round in 0..64u64 {
        let need = n - out.len();
        if need == 0 {
            break;
        }
        let draw = ((need as f64 / fraction.max(0.02) * 1.15).ceil() as usize + 256).min(4_000_000);
        let s = sample_surface(&sm.mesh, draw, round_seed(seed, round))?;
        let kept: Vec<Option<Point3>> = (0..s.len())
            .into_par_iter()
            .map(|i| {
                let (p, f) = (s.points[i], s.faces[i] as usize);
                let nf = normals[f];
                let Some(bvh) = &bvh else { return Some(nf) };
                for &eye in scanners {
                    let towards = dot(nf, sub(eye, p));
                    if sm.outward[f] && towards <= 0.0 {
                        continue;
                    }
                    if !bvh.occluded(eye, p, f as u32, slack) {
                        return Some(if towards < 0.0 { scale(nf, -1.0) } else { nf });
                    }
                }
                None
            })
            .collect();
        for (i, k) in kept.iter().enumerate() {
            let owner = sm.owner[s.faces[i] as usize];
            let inst = matches!(owner, Owner::Instance(_));
            seen.drawn += 1;
            seen.instance_drawn += inst as usize;
            if let Owner::Instance(j) = owner {
                seen.per_instance[j as usize].0 += 1;
                seen.per_instance[j as usize].1 += k.is_some() as usize;
            }
            if let Some(nrm) = k {
                seen.kept += 1;
                seen.instance_kept += inst as usize;
                if out.len() < n {
                    out.push((s.points[i], *nrm, owner));
                }
            }
        }
        fraction = seen.kept as f64 / seen.drawn.max(1) as f64;
    }
    if out.len() < n {
        return Err(DetectError::InvalidInput(format!(
            "the scanners see only {:.3}% of the scene's surface; could not collect {n} points",
            100.0 * fraction
        )));
    }
    Ok(out)
}

/// The share of an instance's surface the scanners must see for it to be annotated (in the
/// ground truth): 1%. The thesis's ground truth is what people marked on the scans (5.5.1), and
/// no one can mark a block the scan does not show. Measured as the share of the random surface
/// samples drawn on the instance that some scanner sees (complete sampling shows every instance
/// whole). On the hard streets of seeds 1–12 (one scanner behind parked cars) 12 of the 586
/// instances, all bins, show less than 0.5% of their surface (0–8 points; ten show nothing),
/// and every other instance 2% or more (47 points and up, a patch where a bin was); the
/// threshold lies in that gap. Every instance of the hard facades of seeds 1–12 shows 22% or
/// more.
pub const MIN_VISIBLE_SURFACE: f64 = 0.01;

/// Samples the layout into a scene.
pub(crate) fn build(
    kind: SceneKind,
    options: &SceneOptions,
    s: &SceneSettings,
    layout: Layout,
) -> Result<Scene> {
    let mut sm = SceneMesh { mesh: TriMesh::default(), owner: Vec::new(), outward: Vec::new() };
    sm.push(&layout.background, Owner::Background, true);
    for (k, inst) in layout.instances.iter().enumerate() {
        sm.push(&inst.mesh, Owner::Instance(k as u32), layout.templates[inst.class].outward);
    }
    for c in &layout.clutter {
        sm.push(c, Owner::Clutter, true);
    }
    let smallest = layout.templates.iter().map(|t| t.bounds().diagonal()).fold(f64::INFINITY, f64::min);
    let element_size = if smallest.is_finite() { smallest } else { 1.0 };
    let sigma = s.noise * element_size;

    let n_out = ((s.outlier_fraction * options.points as f64).round() as usize).min(options.points);
    let n_surface = options.points - n_out;
    let mut seen = Seen { per_instance: vec![(0, 0); layout.instances.len()], ..Default::default() };
    let samples = visible_samples(&sm, &layout.scanners, n_surface, options.seed, &mut seen)?;

    let mut positions = Vec::with_capacity(options.points);
    let mut normals = Vec::with_capacity(options.points);
    // Owner code per point: instance index, or -1 background, -2 clutter, -3 outlier.
    let mut owner: Vec<i64> = Vec::with_capacity(options.points);
    let mut rng = stream(options.seed, NOISE);
    for (p, n, o) in samples {
        let q = if sigma > 0.0 {
            [
                p[0] + sigma * gaussian(&mut rng),
                p[1] + sigma * gaussian(&mut rng),
                p[2] + sigma * gaussian(&mut rng),
            ]
        } else {
            p
        };
        positions.push(q);
        normals.push(n);
        owner.push(match o {
            Owner::Background => -1,
            Owner::Clutter => -2,
            Owner::Instance(k) => k as i64,
        });
    }
    let bounds = sm.mesh.aabb().unwrap_or(Aabb { min: [0.0; 3], max: [1.0; 3] });
    let mut rng = stream(options.seed, OUTLIERS);
    for _ in 0..n_out {
        let p: Point3 = std::array::from_fn(|k| {
            let (lo, hi) = (bounds.min[k] - 0.5, bounds.max[k] + 0.5);
            lo + rng.random::<f64>() * (hi - lo)
        });
        let n = loop {
            let v = [gaussian(&mut rng), gaussian(&mut rng), gaussian(&mut rng)];
            if let Some(u) = normalize(v) {
                break u;
            }
        };
        positions.push(p);
        normals.push(n);
        owner.push(-3);
    }

    // Shuffle (Fisher–Yates) so the order of the points tells nothing.
    let total = positions.len();
    let mut perm: Vec<usize> = (0..total).collect();
    let mut rng = stream(options.seed, ORDER);
    for i in (1..total).rev() {
        let j = rng.random_range(0..=i);
        perm.swap(i, j);
    }
    let positions: Vec<Point3> = perm.iter().map(|&i| positions[i]).collect();
    let normals: Vec<Point3> = perm.iter().map(|&i| normals[i]).collect();
    let owner: Vec<i64> = perm.iter().map(|&i| owner[i]).collect();

    // Ground truth: the instances the scanners show (MIN_VISIBLE_SURFACE); instance 0 of each
    // class is the first of those placed.
    let n_inst = layout.instances.len();
    let mut points_of: Vec<Vec<u32>> = vec![Vec::new(); n_inst];
    for (i, &o) in owner.iter().enumerate() {
        if o >= 0 {
            points_of[o as usize].push(i as u32);
        }
    }
    let (mut hidden_instances, mut hidden_points) = (0usize, 0usize);
    let mut classes: Vec<(Mat4, DetectedClass)> = Vec::new();
    let mut class_slot: Vec<Option<usize>> = vec![None; layout.templates.len()];
    for (k, inst) in layout.instances.iter().enumerate() {
        let (drawn, kept) = seen.per_instance[k];
        if (kept as f64) < MIN_VISIBLE_SURFACE * drawn as f64 {
            hidden_instances += 1;
            hidden_points += points_of[k].len();
            continue;
        }
        let slot = match class_slot[inst.class] {
            Some(c) => c,
            None => {
                classes.push((
                    rigid_inverse(&inst.world_from_local),
                    DetectedClass {
                        name: Some(layout.templates[inst.class].name.clone()),
                        instances: Vec::new(),
                    },
                ));
                class_slot[inst.class] = Some(classes.len() - 1);
                classes.len() - 1
            }
        };
        let mut b = inst.mesh.aabb().unwrap_or(Aabb { min: [0.0; 3], max: [0.0; 3] });
        for &i in &points_of[k] {
            b.grow(positions[i as usize]);
        }
        let (local_from_world0, class) = &mut classes[slot];
        class.instances.push(DetectedInstance {
            bbox_min: b.min,
            bbox_max: b.max,
            transform: Some(mat4_mul(&inst.world_from_local, local_from_world0)),
            points: Some(std::mem::take(&mut points_of[k])),
        });
    }
    let ground_truth = DetectionResult {
        scene: kind.name().to_string(),
        classes: classes.into_iter().map(|(_, c)| c).collect(),
    };

    let count = |code: i64| owner.iter().filter(|&&o| o == code).count();
    let stats = SceneStats {
        kind: kind.name().to_string(),
        settings: s.clone(),
        element_size,
        noise_sigma: sigma,
        scanners: layout.scanners.clone(),
        visible_fraction: seen.kept as f64 / seen.drawn.max(1) as f64,
        instance_visible_fraction: seen.instance_kept as f64 / seen.instance_drawn.max(1) as f64,
        instance_points: owner.iter().filter(|&&o| o >= 0).count() - hidden_points,
        background_points: count(-1),
        clutter_points: count(-2),
        outlier_points: count(-3),
        clutter_objects: layout.clutter.len(),
        hidden_instances,
        hidden_points,
        triangles: sm.mesh.num_triangles(),
    };
    let cloud = PointCloud { positions, normals: Some(normals), ..Default::default() };
    Ok(Scene { cloud, ground_truth, stats })
}
