//! Pre-processing (thesis 5.3.1, 5.4): uniform resampling at spacing ε, normals, maximum principal
//! curvature κ₁ and its direction t₁ by a quadratic fit over radius 4ε, and salient features as
//! local maxima of |κ₁| (non-maximum suppression over 2ε) with a scale-aware threshold.
//!
//! Every length in the detector is a multiple of ε, so once ε is fixed the whole pipeline is
//! scale-free. ε itself is relative to a rotation-invariant size of the input (the diagonal of its
//! principal-axes box, not of the world-axes box, so that detection is invariant to a rigid motion
//! of the input).

use motif_core::curvature::{
    CurvatureOptions, CurvatureStatus, FittingFrame, Neighbourhood, Weighting, principal_curvatures_points,
};
use motif_core::geometry::{cross, dot, normalize, scale, sub};
use motif_core::normals::{NormalsOptions, Orientation};
use motif_core::sampling::{ResampleMethod, ResampleOptions, resample};
use motif_core::spatial::KdTree;
use motif_core::{Point3, PointCloud};
use serde::{Deserialize, Serialize};

use crate::error::{DetectError, Result};
use crate::grid::SpatialHash;

/// How the processing resolution ε is chosen.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "mode", content = "value")]
pub enum Epsilon {
    /// ε = `rel` × the diagonal of the principal-axes bounding box — the thesis's convention
    /// (5.4: 0.0005 for single scanned shapes, 0.00005 for city scans).
    Relative(f64),
    /// ε in the input's units (metres for the generated scenes).
    Absolute(f64),
    /// The larger of the thesis's single-shape value (0.0005 × diagonal) and 1.02 × the input's
    /// own median nearest-neighbour spacing. Resampling can only remove points, so an ε finer than the
    /// data would leave the 4ε curvature balls with a handful of points and make every later
    /// length (HOC cells of 8ε, the 64ε pair radius) shorter than the data can support. The
    /// default; the chosen value is reported. The 2% keep ε off the distance between two input
    /// points: a pair exactly ε apart is kept or thinned by rounding, which a rigid motion of the
    /// input changes (on a generated facade, one such pair renumbered every later point).
    Auto,
}

/// The end of the warning given when ε is raised to the input's spacing ([`Epsilon::Auto`]);
/// [`crate::detect_mesh`] adds which option sets a mesh's density to it.
pub(crate) const SPARSER_THAN_THE_THESIS: &str = "the data is sparser than the thesis's resolution";

/// The largest ε accepted without `--force`, as a share of the diagonal: at 1/16 a HOC cell
/// (8ε) spans half the model and the pair radius (64ε) four times it.
pub const MAX_EPSILON_SHARE: f64 = 1.0 / 16.0;

/// Options of [`preprocess`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct PreprocessOptions {
    /// ε, the resampling spacing that sets the scale of detection (thesis 5.3.1, 5.4). Default
    /// [`Epsilon::Auto`].
    pub epsilon: Epsilon,
    /// Radius of the curvature fit, in ε (thesis 5.4: 4ε, quadratic MLS). Default 4.
    pub curvature_radius: f64,
    /// Non-maximum-suppression radius of feature selection, in ε (thesis 5.4: 2ε). Default 2.
    pub nms_radius: f64,
    /// Threshold on the dimensionless curvature |κ₁|·r, r = `curvature_radius`·ε (thesis 5.4:
    /// κ₁ > 0.15 without units). Multiplying by the fit radius makes the threshold independent of
    /// the model's size: a sharp crease measured at radius r reads |κ₁| r ≈ 0.5–1, a flat wall
    /// with scanner noise of amplitude σ reads about σ / r. Default 0.15.
    pub kappa_threshold: f64,
    /// Keep at most this many features, the strongest |κ₁| first. Not in the thesis: on noisy
    /// scans the threshold alone lets scanner noise through as features by the ten thousand,
    /// and the EM's cost grows with the square of the word sizes; the strongest creases carry
    /// the structure. Default 4,000.
    pub max_features: usize,
    /// Refuse inputs whose resampled point count, estimated before resampling, exceeds this (issue
    /// 5: an absurd ε is an error unless forced). Default 5·10⁷.
    pub max_points: usize,
    /// Seed of the Poisson-disc candidate order.
    pub seed: u64,
}

impl Default for PreprocessOptions {
    fn default() -> Self {
        PreprocessOptions {
            epsilon: Epsilon::Auto,
            curvature_radius: 4.0,
            nms_radius: 2.0,
            kappa_threshold: 0.15,
            max_features: 4_000,
            max_points: 50_000_000,
            seed: 0,
        }
    }
}

/// The thesis's ε for single shapes (5.4), relative to the diagonal.
pub const THESIS_EPSILON_SHAPES: f64 = 0.0005;

/// A salient feature with its local frame (thesis 5.4, "local feature frame").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Feature {
    /// Index of the feature's point in [`Preprocessed::points`].
    pub point: usize,
    /// Position.
    pub position: Point3,
    /// Local x axis: the unit normal.
    pub x: Point3,
    /// Local y axis: the maximum principal direction t₁, its sign canonicalised (see
    /// [`crate::hoc`]); the second frame of the thesis is the same frame turned 180° about x.
    pub y: Point3,
    /// |κ₁| (1 / input units).
    pub kappa: f64,
}

/// Of the features `ids`, the one nearest `to` (the lowest index on ties); `None` when `ids` is
/// empty.
pub(crate) fn nearest_feature(features: &[Feature], ids: &[usize], to: Point3) -> Option<usize> {
    ids.iter().copied().min_by(|&a, &b| {
        motif_core::geometry::dist2(features[a].position, to)
            .total_cmp(&motif_core::geometry::dist2(features[b].position, to))
            .then(a.cmp(&b))
    })
}

impl Feature {
    /// Local z axis, x × y.
    pub fn z(&self) -> Point3 {
        cross(self.x, self.y)
    }

    /// The frame's axes with the given flip (0: as stored, 1: turned 180° about x).
    pub fn axes(&self, flip: u8) -> [Point3; 3] {
        let s = if flip == 0 { 1.0 } else { -1.0 };
        [self.x, scale(self.y, s), scale(self.z(), s)]
    }

    /// World offset `v` expressed in the frame (`flip` as in [`Feature::axes`]).
    pub fn to_local(&self, flip: u8, v: Point3) -> Point3 {
        let a = self.axes(flip);
        [dot(a[0], v), dot(a[1], v), dot(a[2], v)]
    }

    /// Local offset `l` turned into a world position relative to the feature.
    pub fn to_world(&self, flip: u8, l: Point3) -> Point3 {
        let a = self.axes(flip);
        let mut p = self.position;
        for k in 0..3 {
            for d in 0..3 {
                p[d] += a[k][d] * l[k];
            }
        }
        p
    }
}

/// The pre-processed input.
#[derive(Debug, Clone)]
pub struct Preprocessed {
    /// ε in input units.
    pub epsilon: f64,
    /// The rotation-invariant diagonal ε is relative to.
    pub diagonal: f64,
    /// Resampled positions.
    pub points: Vec<Point3>,
    /// Unit normals of the resampled points.
    pub normals: Vec<Point3>,
    /// |κ₁| per resampled point (0 where the fit failed).
    pub kappa: Vec<f64>,
    /// Unit direction of the dominant principal curvature per resampled point.
    pub t1: Vec<Point3>,
    /// Input index of each resampled point.
    pub source: Vec<usize>,
    /// Salient features.
    pub features: Vec<Feature>,
    /// True when the input had no normals and they were estimated.
    pub normals_estimated: bool,
    /// Human-readable warnings (estimated normals, ε raised to the data's spacing, …).
    pub warnings: Vec<String>,
}

#[cfg(test)]
impl Preprocessed {
    /// A resampling of `points` (with `normals`) at spacing `epsilon` with zero curvature and no
    /// features, for unit tests of the later stages.
    pub(crate) fn for_tests(
        points: Vec<Point3>,
        normals: Vec<Point3>,
        epsilon: f64,
        diagonal: f64,
    ) -> Preprocessed {
        let n = points.len();
        Preprocessed {
            epsilon,
            diagonal,
            points,
            normals,
            kappa: vec![0.0; n],
            t1: vec![[1.0, 0.0, 0.0]; n],
            source: (0..n).collect(),
            features: vec![],
            normals_estimated: false,
            warnings: vec![],
        }
    }
}

/// Diagonal of the principal-axes bounding box: invariant under rigid motions, unlike the
/// world-axes box.
pub fn principal_diagonal(points: &[Point3]) -> f64 {
    let n = points.len();
    if n < 2 {
        return 0.0;
    }
    let mut c = [0.0; 3];
    for p in points {
        for d in 0..3 {
            c[d] += p[d] / n as f64;
        }
    }
    let mut m = nalgebra::Matrix3::<f64>::zeros();
    for p in points {
        let v = nalgebra::Vector3::new(p[0] - c[0], p[1] - c[1], p[2] - c[2]);
        m += v * v.transpose();
    }
    let eig = nalgebra::SymmetricEigen::new(m);
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points {
        let v = nalgebra::Vector3::new(p[0] - c[0], p[1] - c[1], p[2] - c[2]);
        for k in 0..3 {
            let t = eig.eigenvectors.column(k).dot(&v);
            lo[k] = lo[k].min(t);
            hi[k] = hi[k].max(t);
        }
    }
    ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2) + (hi[2] - lo[2]).powi(2)).sqrt()
}

/// Median nearest-neighbour distance over (a deterministic subset of at most 4,000 of) the points.
pub fn median_spacing(points: &[Point3], tree: &KdTree) -> f64 {
    let n = points.len();
    if n < 2 {
        return 0.0;
    }
    let step = (n / 4000).max(1);
    let mut d: Vec<f64> = (0..n)
        .step_by(step)
        .filter_map(|i| tree.knn(points[i], 2).get(1).map(|nb| nb.distance))
        .filter(|d| *d > 0.0)
        .collect();
    if d.is_empty() {
        return 0.0;
    }
    d.sort_by(f64::total_cmp);
    d[d.len() / 2]
}

/// Checks the input: at least a few points, every coordinate (and normal) finite.
pub fn validate_input(cloud: &PointCloud) -> Result<()> {
    if let Some(i) = cloud.positions.iter().position(|p| !motif_core::geometry::is_finite(*p)) {
        return Err(DetectError::InvalidInput(format!(
            "point {i} has a NaN or infinite coordinate {:?}; remove or repair it",
            cloud.positions[i]
        )));
    }
    if let Some(n) = &cloud.normals {
        if n.len() != cloud.positions.len() {
            return Err(DetectError::InvalidInput(format!(
                "{} normals for {} points",
                n.len(),
                cloud.positions.len()
            )));
        }
        if let Some(i) = n.iter().position(|p| !motif_core::geometry::is_finite(*p)) {
            return Err(DetectError::InvalidInput(format!("normal {i} has a NaN or infinite component")));
        }
    }
    Ok(())
}

/// Resamples, estimates normals and curvature, and selects features (thesis 5.3.1, 5.4).
pub fn preprocess(cloud: &PointCloud, o: &PreprocessOptions, force: bool) -> Result<Preprocessed> {
    validate_input(cloud)?;
    for (name, v) in [
        ("curvature_radius", o.curvature_radius),
        ("nms_radius", o.nms_radius),
        ("kappa_threshold", o.kappa_threshold),
    ] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(DetectError::InvalidOption {
                name,
                message: format!("must be finite and ≥ 0, got {v}"),
            });
        }
    }
    let mut warnings = Vec::new();
    let diagonal = principal_diagonal(&cloud.positions);
    if cloud.len() < 10 || diagonal.is_nan() || diagonal <= 0.0 {
        // The ε asked for (for `Auto`, the thesis's, which a larger input would raise to its
        // spacing), so the report does not say 0; a relative ε of a shape with no extent is 0.
        let epsilon = match o.epsilon {
            Epsilon::Absolute(e) => e,
            Epsilon::Relative(r) if diagonal > 0.0 => r * diagonal,
            Epsilon::Auto if diagonal > 0.0 => THESIS_EPSILON_SHAPES * diagonal,
            _ => 0.0,
        };
        return Ok(Preprocessed {
            epsilon,
            diagonal,
            points: Vec::new(),
            normals: Vec::new(),
            kappa: Vec::new(),
            t1: Vec::new(),
            source: Vec::new(),
            features: Vec::new(),
            normals_estimated: cloud.normals.is_none(),
            warnings: vec![if cloud.len() == 1 {
                "only 1 point: nothing to detect".to_string()
            } else if cloud.len() < 10 {
                format!("only {} points: nothing to detect", cloud.len())
            } else {
                format!("the {} points span no extent (all coincide): nothing to detect", cloud.len())
            }],
        });
    }
    let tree = KdTree::new(&cloud.positions)?;
    let epsilon = match o.epsilon {
        Epsilon::Relative(r) => r * diagonal,
        Epsilon::Absolute(e) => e,
        Epsilon::Auto => {
            let thesis = THESIS_EPSILON_SHAPES * diagonal;
            let spacing = 1.02 * median_spacing(&cloud.positions, &tree);
            if spacing > thesis {
                warnings.push(format!(
                    "ε raised from the thesis's 0.0005 × diagonal ({thesis:.4}) to 1.02 × the input's \
                     median spacing, {spacing:.4}: {SPARSER_THAN_THE_THESIS}"
                ));
                spacing
            } else {
                thesis
            }
        }
    };
    if !(epsilon.is_finite() && epsilon > 0.0) {
        return Err(DetectError::InvalidOption {
            name: "epsilon",
            message: format!("ε must be positive and finite, got {epsilon}"),
        });
    }
    // Which ε it is, in the terms the user gave it (or did not: the automatic one).
    let which = match o.epsilon {
        Epsilon::Relative(r) => format!("ε = {r:e} × the diagonal = {epsilon:.3e}"),
        Epsilon::Absolute(_) => format!("ε = {epsilon:.3e}"),
        Epsilon::Auto => format!(
            "the automatic ε ({epsilon:.3e}, 1.02 × the input's median point spacing, as the input is sparser \
             than the thesis's 0.0005 × diagonal)"
        ),
    };
    if epsilon > MAX_EPSILON_SHARE * diagonal && !force {
        return Err(DetectError::InvalidOption {
            name: "epsilon",
            message: format!(
                "{which} is {:.2} of the diagonal ({diagonal:.3e}); above 1/16 of it the surface \
                 resamples to a few hundred points and one HOC cell (8ε) spans half the model, so \
                 nothing can repeat (the thesis uses 0.0005 × diagonal for shapes, 0.00005 for city \
                 scans); {}",
                epsilon / diagonal,
                if o.epsilon == Epsilon::Auto {
                    "the input has too few points for detection (pass --force to try anyway)"
                } else {
                    "choose a smaller ε or pass --force"
                }
            ),
        });
    }
    // The surface resampled at spacing ε holds about area / ε² points; the principal box's
    // diagonal squared bounds the area of a scene-like surface within a small factor. The input
    // may hold fewer points (resampling never adds any), but an ε this small also shrinks every
    // length of the detector (HOC cells, pair radius) below anything the data can show.
    let estimate = diagonal * diagonal / (epsilon * epsilon);
    if estimate > o.max_points as f64 && !force {
        return Err(DetectError::InvalidOption {
            name: "epsilon",
            message: format!(
                "{which} is {:.1e} of the diagonal: a surface this size sampled that densely holds about \
                 {estimate:.1e} points (limit {:.0e}), and the detector's lengths (HOC cells of 8ε, \
                 pairs within 64ε) would lie far below what the data can show; choose a larger ε or \
                 pass --force",
                epsilon / diagonal,
                o.max_points as f64
            ),
        });
    }
    let rs = resample(
        cloud,
        &ResampleOptions { spacing: epsilon, method: ResampleMethod::PoissonDisc, seed: o.seed },
    )?;
    let points = rs.cloud.positions.clone();
    let normals_estimated = rs.cloud.normals.is_none();
    let radius = o.curvature_radius * epsilon;
    let copts = CurvatureOptions {
        neighbourhood: Neighbourhood::Radius(radius),
        // MLS-style weights (Alexa et al. 2003, as the thesis cites): closer points count more.
        weighting: Weighting::Gaussian { sigma: 0.5 },
        frame: FittingFrame::Pca,
        normals: NormalsOptions {
            neighbours: 16,
            orientation: Orientation::Consistent,
            ..Default::default()
        },
    };
    if normals_estimated {
        warnings.push(
            "the input has no normals: estimated from 16 nearest neighbours, oriented consistently".into(),
        );
    }
    let curv = principal_curvatures_points(&points, rs.cloud.normals.as_deref(), &copts)?;
    let mut normals = Vec::with_capacity(points.len());
    let mut kappa = Vec::with_capacity(points.len());
    let mut t1 = Vec::with_capacity(points.len());
    for c in &curv {
        let ok = matches!(c.status, CurvatureStatus::Fitted | CurvatureStatus::Unoriented);
        let (k, d) = c.dominant();
        normals.push(c.normal);
        kappa.push(if ok && k.is_finite() { k.abs() } else { 0.0 });
        t1.push(d);
    }
    let features = select_features(&points, &normals, &kappa, &t1, epsilon, o);
    Ok(Preprocessed {
        epsilon,
        diagonal,
        points,
        normals,
        kappa,
        t1,
        source: rs.indices,
        features,
        normals_estimated,
        warnings,
    })
}

/// Local maxima of |κ₁| over the NMS radius whose dimensionless curvature passes the threshold,
/// strongest first (near-ties by index), each with its frame (x = normal, y = t₁ orthogonalised).
fn select_features(
    points: &[Point3],
    normals: &[Point3],
    kappa: &[f64],
    t1: &[Point3],
    epsilon: f64,
    o: &PreprocessOptions,
) -> Vec<Feature> {
    let r_fit = o.curvature_radius * epsilon;
    let threshold = o.kappa_threshold / r_fit.max(f64::MIN_POSITIVE);
    let mut candidates: Vec<usize> = (0..points.len()).filter(|&i| kappa[i] > threshold).collect();
    // Strongest first, curvatures within 1e-7 of the threshold's scale counting as ties (broken
    // by index): a rigid motion of the input changes κ₁ in its last bits, and along a straight
    // crease of a clean model many neighbours tie, so an exact comparison picked other maxima
    // after a motion. Indices of the resampled points do not depend on the motion.
    let key = |i: usize| (kappa[i] / threshold * 1e7).round() as i64;
    candidates.sort_by(|&a, &b| key(b).cmp(&key(a)).then(a.cmp(&b)));
    let r_nms = o.nms_radius * epsilon;
    // A candidate is a feature when no stronger point lies within the NMS radius. Stronger
    // points are all earlier in `candidates`, so hash every candidate and compare values.
    let cand_pts: Vec<Point3> = candidates.iter().map(|&i| points[i]).collect();
    let hash = SpatialHash::new(&cand_pts, r_nms.max(epsilon));
    let mut features = Vec::new();
    for (rank, &i) in candidates.iter().enumerate() {
        let mut is_max = true;
        hash.for_each_within(points[i], r_nms, |j, _| {
            if j < rank {
                is_max = false;
            }
        });
        if !is_max {
            continue;
        }
        let x = match normalize(normals[i]) {
            Some(x) => x,
            None => continue,
        };
        let y = match normalize(sub(t1[i], scale(x, dot(t1[i], x)))) {
            Some(y) => y,
            None => continue,
        };
        features.push(Feature { point: i, position: points[i], x, y, kappa: kappa[i] });
        if features.len() >= o.max_features.max(1) {
            break;
        }
    }
    features
}
