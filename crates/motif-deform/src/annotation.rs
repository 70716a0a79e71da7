//! Symmetry annotations (`motif_symmetry_v1`, thesis 3.2): parsing, group closure, validation of
//! transforms, and resolution of regions to vertex sets and point tests.
//!
//! The serde types are motif-core's ([`SymmetryAnnotation`], [`Symmetry`](motif_core::procedural::Symmetry), [`SymmetryKind`],
//! [`Region`]); this module turns them into a [`ResolvedAnnotation`]:
//! - a **group** symmetry becomes the closure of its generators (every product, deduplicated
//!   within the annotation's tolerance; at most [`MAX_GROUP_ORDER`] elements), acting on its
//!   region, which must be invariant;
//! - an **instance set** becomes its regions and transforms `T_i` (`instance_from_template`); the
//!   partial map from instance `b` to instance `a` is `T_a · T_b⁻¹` (thesis 3.2: a partial symmetry
//!   between copies). Instance sets are not groups: their "elements" are these partial maps.
//!
//! Regions are closed sets; boxes and balls are enlarged by [`REGION_MARGIN`] × the diagonal so
//! vertices on their boundary count (as in motif-core's `symmetry_residual`). A point that is not
//! a vertex (a sample) lies in a `vertices`/`faces` region when its nearest mesh vertex does.

use std::path::Path;

use motif_core::TriMesh;
use motif_core::geometry::{IDENTITY4, Mat4, Point3, dist2, mat4_mul, norm, transform_point};
use motif_core::procedural::{Region, SYMMETRY_FORMAT, SymmetryAnnotation, SymmetryKind, rigid_inverse};
use motif_core::spatial::KdTree;

use crate::error::{DeformError, Result};
use crate::mat3::{rigid_approx_eq, rigidity_deviation};

/// Largest group order accepted by [`group_closure`].
pub const MAX_GROUP_ORDER: usize = 1000;

/// Accepted deviation of a transform from a rigid motion or reflection (largest entry of
/// `|OᵀO − I|`), unless the annotation's tolerance is larger.
pub const ORTHOGONALITY_TOLERANCE: f64 = 1e-6;

/// Enlargement of box and ball regions, relative to the bounding-box diagonal, so that vertices
/// and samples on a region's boundary count as inside (rounding-level; matches motif-core).
pub const REGION_MARGIN: f64 = 1e-9;

/// The first symmetry entry of an annotation that does not parse, with its index and field and
/// what is wrong there; `None` when the entries are not what failed (the error is elsewhere).
fn diagnose_symmetries(json: &str) -> Option<String> {
    use motif_core::procedural::SymmetryInstance;
    let v: serde_json::Value = serde_json::from_str(json).ok()?;
    let entries = v.get("symmetries")?.as_array()?;
    for (i, e) in entries.iter().enumerate() {
        let Some(obj) = e.as_object() else {
            return Some(format!(
                "symmetries[{i}]: expected an object with `region` and `generators`, or `instances`"
            ));
        };
        let known = ["name", "region", "generators", "instances"];
        let unknown: Vec<&str> = obj.keys().map(|k| k.as_str()).filter(|k| !known.contains(k)).collect();
        let field = |k: &str| obj.get(k);
        if let Some(g) = field("generators") {
            let Some(gens) = g.as_array() else {
                return Some(format!("symmetries[{i}].generators: expected a list of 4×4 matrices"));
            };
            for (j, m) in gens.iter().enumerate() {
                if let Err(err) = serde_json::from_value::<Mat4>(m.clone()) {
                    return Some(format!(
                        "symmetries[{i}].generators[{j}]: expected a 4×4 matrix (4 rows of 4 numbers): {err}"
                    ));
                }
            }
            let Some(r) = field("region") else {
                return Some(format!(
                    "symmetries[{i}]: a group needs a `region` (\"all\" for the whole shape)"
                ));
            };
            if let Err(err) = serde_json::from_value::<Region>(r.clone()) {
                return Some(format!("symmetries[{i}].region: {err}"));
            }
        } else if let Some(list) = field("instances") {
            let Some(list) = list.as_array() else {
                return Some(format!("symmetries[{i}].instances: expected a list of {{region, transform}}"));
            };
            for (j, inst) in list.iter().enumerate() {
                if let Err(err) = serde_json::from_value::<SymmetryInstance>(inst.clone()) {
                    return Some(format!("symmetries[{i}].instances[{j}]: {err}"));
                }
            }
        } else {
            let also = if unknown.is_empty() {
                String::new()
            } else {
                format!(
                    " (unknown field{} `{}`)",
                    if unknown.len() > 1 { "s" } else { "" },
                    unknown.join("`, `")
                )
            };
            return Some(format!(
                "symmetries[{i}] has neither `generators` (a group on a `region`) nor `instances`{also}"
            ));
        }
        match field("name") {
            Some(name) if !name.is_string() => {
                return Some(format!("symmetries[{i}].name: expected a string"));
            }
            None => return Some(format!("symmetries[{i}]: missing `name`")),
            _ => {}
        }
    }
    None
}

/// Checks a JSON document's `format` tag before its fields: a handles file given where an
/// annotation is expected is named as such, not reported as a missing field of an annotation.
/// Documents that are not objects with a string tag pass, and the typed parse reports them.
pub(crate) fn check_format_tag(json: &str, expected: &'static str, what: &str) -> Result<()> {
    let Ok(v) = serde_json::from_str::<serde_json::Value>(json) else { return Ok(()) };
    match v.get("format").and_then(|f| f.as_str()) {
        Some(found) if found != expected => {
            Err(DeformError::WrongFormat { what: what.to_string(), expected, found: found.to_string() })
        }
        _ => Ok(()),
    }
}

/// Parses a `motif_symmetry_v1` annotation from JSON text and checks its format tag and tolerance.
pub fn parse_annotation(json: &str) -> Result<SymmetryAnnotation> {
    parse_annotation_named(json, "symmetry annotation")
}

fn parse_annotation_named(json: &str, what: &str) -> Result<SymmetryAnnotation> {
    check_format_tag(json, SYMMETRY_FORMAT, what)?;
    let a: SymmetryAnnotation = serde_json::from_str(json).map_err(|source| {
        // The two kinds of symmetry are untagged, so serde's own message for a bad entry is "data
        // did not match any variant"; say which entry and which field instead.
        let source = match diagnose_symmetries(json) {
            Some(message) => <serde_json::Error as serde::de::Error>::custom(message),
            None => source,
        };
        DeformError::Json { what: what.to_string(), source }
    })?;
    // The two kinds of symmetry are told apart by their fields (untagged); an entry with the
    // fields of both would be read as a group and its instances dropped without a word.
    if let Ok(v) = serde_json::from_str::<serde_json::Value>(json) {
        let entries = v.get("symmetries").and_then(|s| s.as_array()).map_or(&[][..], |s| s.as_slice());
        for (i, e) in entries.iter().enumerate() {
            let has = |k: &str| e.get(k).is_some();
            if has("instances") && (has("generators") || has("region")) {
                return Err(DeformError::Json {
                    what: what.to_string(),
                    source: <serde_json::Error as serde::de::Error>::custom(format!(
                        "symmetries[{i}] has both `instances` and `region`/`generators`: a symmetry is \
                         either a group acting on a region or a set of instances; split it in two"
                    )),
                });
            }
        }
    }
    if a.format != SYMMETRY_FORMAT {
        return Err(DeformError::WrongFormat {
            what: what.to_string(),
            expected: SYMMETRY_FORMAT,
            found: a.format,
        });
    }
    if !(a.tolerance.is_finite() && a.tolerance > 0.0 && a.tolerance < 1.0) {
        return Err(DeformError::InvalidFileContent {
            field: "tolerance",
            message: format!(
                "{what}: the tolerance must lie in (0, 1) (relative to the diagonal), got {}",
                a.tolerance
            ),
        });
    }
    Ok(a)
}

/// Reads a `motif_symmetry_v1` annotation file.
pub fn read_annotation(path: &Path) -> Result<SymmetryAnnotation> {
    let text = std::fs::read_to_string(path)
        .map_err(|source| DeformError::Io { path: path.to_path_buf(), source })?;
    parse_annotation_named(&text, &path.display().to_string())
}

/// The finite group generated by `generators`: all products, deduplicated when the linear parts
/// agree within `tolerance` (entry-wise) and the translations within `tolerance × diagonal`.
/// Element 0 is the identity. Fails when a generator is not rigid (orthogonal linear part within
/// `max(ORTHOGONALITY_TOLERANCE, tolerance)`, last row `0 0 0 1`) or the group does not close
/// within [`MAX_GROUP_ORDER`] elements; errors name the symmetry `name`.
pub fn group_closure(name: &str, generators: &[Mat4], diagonal: f64, tolerance: f64) -> Result<Vec<Mat4>> {
    for (i, g) in generators.iter().enumerate() {
        let d = rigidity_deviation(g);
        if d > ORTHOGONALITY_TOLERANCE.max(tolerance) {
            return Err(DeformError::NonOrthogonal {
                symmetry: name.to_string(),
                transform: i,
                deviation: d,
            });
        }
    }
    for (i, g) in generators.iter().enumerate() {
        if let Some((degrees, k, n)) = odd_turn(g, tolerance.max(1e-12)) {
            return Err(DeformError::NotAFiniteTurn {
                symmetry: name.to_string(),
                transform: i,
                degrees,
                k,
                n,
            });
        }
    }
    let lin_tol = tolerance.max(1e-12);
    let trans_tol = lin_tol * diagonal;
    let mut elements = vec![IDENTITY4];
    let mut i = 0;
    while i < elements.len() {
        let e = elements[i];
        for g in generators {
            let p = mat4_mul(g, &e);
            if !elements.iter().any(|x| rigid_approx_eq(x, &p, lin_tol, trans_tol)) {
                if elements.len() >= MAX_GROUP_ORDER {
                    return Err(DeformError::GroupTooLarge {
                        symmetry: name.to_string(),
                        limit: MAX_GROUP_ORDER,
                    });
                }
                elements.push(p);
            }
        }
        i += 1;
    }
    Ok(elements)
}

/// Largest `n` for which a generator may turn by `k · 360° / n` with `k > 1` (two fifths of a
/// turn generates C5 as a fifth does; an annotation may give either). Beyond it the smallest turn
/// is asked for: no designed model has a 13-fold symmetry given by its third power, while an
/// angle that is no fraction of a turn (1 radian) matches `k / n` for some large `n` within any
/// tolerance (113 / 710).
const MAX_ORDER_OF_A_MULTIPLE_TURN: u64 = 12;

/// For a rotation or rotoreflection whose angle θ (0–180°, from the trace) is `k · 360° / n` in
/// lowest terms with `k > 1` and `n > MAX_ORDER_OF_A_MULTIPLE_TURN`, the angle in degrees and
/// `(k, n)`; `None` otherwise (mirrors, inversions, half turns, `k = 1`). `n` is the smallest
/// within [`MAX_GROUP_ORDER`] for which `n` turns by θ come within `tolerance` radians of whole
/// turns: where [`group_closure`], which merges elements within `tolerance` entry-wise, would
/// close the group.
fn odd_turn(g: &Mat4, tolerance: f64) -> Option<(f64, u64, u64)> {
    let l = [[g[0][0], g[0][1], g[0][2]], [g[1][0], g[1][1], g[1][2]], [g[2][0], g[2][1], g[2][2]]];
    let det = l[0][0] * (l[1][1] * l[2][2] - l[1][2] * l[2][1])
        - l[0][1] * (l[1][0] * l[2][2] - l[1][2] * l[2][0])
        + l[0][2] * (l[1][0] * l[2][1] - l[1][1] * l[2][0]);
    let trace = l[0][0] + l[1][1] + l[2][2];
    // A rotation has trace 1 + 2cosθ; a rotoreflection (det −1) 2cosθ − 1.
    let cos = if det >= 0.0 { (trace - 1.0) / 2.0 } else { (trace + 1.0) / 2.0 };
    let theta = cos.clamp(-1.0, 1.0).acos();
    let turns = theta / std::f64::consts::TAU;
    let n = (1..=MAX_GROUP_ORDER as u64).find(|&n| {
        let x = n as f64 * turns;
        std::f64::consts::TAU * (x - x.round()).abs() <= tolerance
    })?;
    let k = (n as f64 * turns).round() as u64;
    (k > 1 && n > MAX_ORDER_OF_A_MULTIPLE_TURN).then_some((theta.to_degrees(), k, n))
}

/// A compiled region: answers "is this vertex / point inside?".
#[derive(Debug, Clone)]
pub(crate) enum RegionTest {
    All,
    /// Vertex mask (from `vertices` or `faces`); points use their nearest vertex.
    Mask(Vec<bool>),
    Aabb {
        min: Point3,
        max: Point3,
    },
    Sphere {
        center: Point3,
        radius: f64,
    },
    Union(Vec<RegionTest>),
}

impl RegionTest {
    /// Compiles `region` for `mesh`; `what` names the region in errors.
    pub(crate) fn compile(region: &Region, mesh: &TriMesh, margin: f64, what: &str) -> Result<RegionTest> {
        let n = mesh.num_vertices();
        Ok(match region {
            Region::All => RegionTest::All,
            Region::Vertices(v) => {
                let mut mask = vec![false; n];
                for &i in v {
                    let slot = mask.get_mut(i as usize).ok_or_else(|| DeformError::IndexOutOfRange {
                        what: what.to_string(),
                        kind: "vertex",
                        index: i,
                        count: n,
                    })?;
                    *slot = true;
                }
                RegionTest::Mask(mask)
            }
            Region::Faces(f) => {
                let mut mask = vec![false; n];
                for &t in f {
                    let tri = mesh.triangles.get(t as usize).ok_or_else(|| DeformError::IndexOutOfRange {
                        what: what.to_string(),
                        kind: "face",
                        index: t,
                        count: mesh.num_triangles(),
                    })?;
                    for &i in tri {
                        mask[i as usize] = true;
                    }
                }
                RegionTest::Mask(mask)
            }
            Region::Aabb { min, max } => {
                if !(min.iter().chain(max).all(|c| c.is_finite()) && (0..3).all(|k| min[k] <= max[k])) {
                    return Err(DeformError::InvalidFileContent {
                        field: "region",
                        message: format!("{what}: box needs finite min <= max, got {min:?} .. {max:?}"),
                    });
                }
                RegionTest::Aabb { min: min.map(|c| c - margin), max: max.map(|c| c + margin) }
            }
            Region::Sphere { center, radius } => {
                if !(center.iter().all(|c| c.is_finite()) && radius.is_finite() && *radius >= 0.0) {
                    return Err(DeformError::InvalidFileContent {
                        field: "region",
                        message: format!("{what}: sphere needs a finite centre and radius >= 0"),
                    });
                }
                RegionTest::Sphere { center: *center, radius: radius + margin }
            }
            Region::Union(parts) => RegionTest::Union(
                parts.iter().map(|r| RegionTest::compile(r, mesh, margin, what)).collect::<Result<_>>()?,
            ),
        })
    }

    /// True when the test needs the nearest mesh vertex of a point.
    pub(crate) fn needs_nearest(&self) -> bool {
        match self {
            RegionTest::Mask(_) => true,
            RegionTest::Union(p) => p.iter().any(RegionTest::needs_nearest),
            _ => false,
        }
    }

    /// Is the point `p`, whose nearest mesh vertex is `nearest` (when known), inside?
    pub(crate) fn contains_point(&self, p: Point3, nearest: Option<usize>) -> bool {
        match self {
            RegionTest::All => true,
            RegionTest::Mask(m) => nearest.is_some_and(|v| m[v]),
            RegionTest::Aabb { min, max } => (0..3).all(|k| p[k] >= min[k] && p[k] <= max[k]),
            RegionTest::Sphere { center, radius } => dist2(p, *center) <= radius * radius,
            RegionTest::Union(parts) => parts.iter().any(|r| r.contains_point(p, nearest)),
        }
    }

    /// Is vertex `v` at position `p` inside?
    pub(crate) fn contains_vertex(&self, v: usize, p: Point3) -> bool {
        match self {
            RegionTest::Mask(m) => m[v],
            RegionTest::Union(parts) => parts.iter().any(|r| r.contains_vertex(v, p)),
            other => other.contains_point(p, Some(v)),
        }
    }
}

/// A region resolved on a mesh.
#[derive(Debug, Clone)]
pub struct ResolvedRegion {
    /// The region as annotated.
    pub region: Region,
    /// The mesh vertices inside, ascending.
    pub vertices: Vec<u32>,
    pub(crate) test: RegionTest,
    /// Index of this region among all regions of the annotation (the "symbol" used by symmetric
    /// sampling and lifting to track which regions a point lies in).
    pub(crate) symbol: usize,
}

/// A symmetry resolved on a mesh.
#[derive(Debug, Clone)]
pub struct ResolvedSymmetry {
    /// The symmetry's name.
    pub name: String,
    /// The group or the instance set.
    pub kind: ResolvedKind,
}

/// The two kinds of resolved symmetry.
#[derive(Debug, Clone)]
pub enum ResolvedKind {
    /// A finite group acting on an invariant region.
    Group {
        /// The region.
        region: ResolvedRegion,
        /// The generators as annotated.
        generators: Vec<Mat4>,
        /// Every element of the group (the closure of the generators); element 0 is the identity.
        elements: Vec<Mat4>,
    },
    /// Congruent copies.
    Instances {
        /// The instances' regions.
        instances: Vec<ResolvedRegion>,
        /// `instance_from_template` of each instance.
        transforms: Vec<Mat4>,
        /// The inverses of `transforms`.
        inverses: Vec<Mat4>,
    },
}

impl ResolvedSymmetry {
    /// Group order, or number of instances.
    pub fn order(&self) -> usize {
        match &self.kind {
            ResolvedKind::Group { elements, .. } => elements.len(),
            ResolvedKind::Instances { instances, .. } => instances.len(),
        }
    }
}

/// One transform of a symmetry with the vertices it acts on: a non-identity group element on the
/// group's region, or the partial map `T_a · T_b⁻¹` from instance `b` to instance `a`.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SymmetryElement {
    /// Index of the symmetry in the annotation.
    pub symmetry: usize,
    /// The symmetry's name.
    pub name: String,
    /// "element 3" (group) or "instance 2 -> 0" (instance set).
    pub label: String,
    /// The transform, row-major 4×4.
    pub transform: Mat4,
    /// The vertices it maps (its domain), ascending.
    pub domain: Vec<u32>,
}

/// An annotation resolved on a mesh: groups closed, regions turned into vertex sets and tests.
#[derive(Debug, Clone)]
pub struct ResolvedAnnotation {
    /// Bounding-box diagonal of the mesh, the unit of relative tolerances.
    pub diagonal: f64,
    /// The annotation's tolerance, relative to the diagonal.
    pub tolerance: f64,
    /// The resolved symmetries, in annotation order (empty instance sets are dropped).
    pub symmetries: Vec<ResolvedSymmetry>,
    /// Notes about dropped or suspicious entries.
    pub warnings: Vec<String>,
    /// Absolute region margin (`REGION_MARGIN × diagonal`).
    pub(crate) margin: f64,
    /// Number of regions over all symmetries.
    pub(crate) num_symbols: usize,
}

/// `annotation` with each region given by place (a box, a sphere, or a union holding one)
/// replaced by the vertices of `mesh` it selects (with the margin every region gets), so that
/// it selects the same vertices once `mesh` is deformed: a symmetry-preserving deformation keeps
/// every transform exact, but moves the places (a windmill's blade leaves the box that held it,
/// and a deformed model saved with its rest annotation could not be opened with it again).
/// Regions given by vertices, faces or as the whole shape are kept as they are.
///
/// # Errors
/// As [`resolve_annotation`] for regions that are not valid on `mesh`.
pub fn regions_as_vertices(annotation: &SymmetryAnnotation, mesh: &TriMesh) -> Result<SymmetryAnnotation> {
    let diagonal = check_mesh(mesh)?;
    let margin = REGION_MARGIN * diagonal;
    let pin = |region: &Region, what: &str| -> Result<Region> {
        if matches!(region, Region::All | Region::Vertices(_) | Region::Faces(_)) {
            return Ok(region.clone());
        }
        let test = RegionTest::compile(region, mesh, margin, what)?;
        Ok(Region::Vertices(
            (0..mesh.num_vertices())
                .filter(|&v| test.contains_vertex(v, mesh.positions[v]))
                .map(|v| v as u32)
                .collect(),
        ))
    };
    let mut out = annotation.clone();
    for s in &mut out.symmetries {
        let what = format!("symmetry \"{}\"", s.name);
        match &mut s.kind {
            SymmetryKind::Group { region, .. } => *region = pin(region, &what)?,
            SymmetryKind::Instances { instances } => {
                for i in instances {
                    i.region = pin(&i.region, &what)?;
                }
            }
        }
    }
    Ok(out)
}

/// Resolves `annotation` on `mesh`: closes groups, compiles and checks regions (no empty region,
/// indices in range, rigid transforms). Does not measure how well the transforms fit the shape:
/// see [`crate::check_annotation`] and [`crate::SymmetryMaps`].
pub fn resolve_annotation(mesh: &TriMesh, annotation: &SymmetryAnnotation) -> Result<ResolvedAnnotation> {
    let diagonal = check_mesh(mesh)?;
    if !(annotation.tolerance.is_finite() && annotation.tolerance > 0.0 && annotation.tolerance < 1.0) {
        return Err(DeformError::InvalidFileContent {
            field: "tolerance",
            message: format!(
                "the annotation's tolerance must lie in (0, 1) (relative to the diagonal), got {}",
                annotation.tolerance
            ),
        });
    }
    let mut out = ResolvedAnnotation {
        diagonal,
        tolerance: annotation.tolerance,
        symmetries: Vec::new(),
        warnings: Vec::new(),
        margin: REGION_MARGIN * diagonal,
        num_symbols: 0,
    };
    for s in &annotation.symmetries {
        match resolve_symmetry(mesh, s, diagonal, annotation.tolerance, out.margin, &mut out.num_symbols)? {
            Some(r) => out.symmetries.push(r),
            None => out.warnings.push(format!("symmetry {:?} has no instances and is ignored", s.name)),
        }
    }
    Ok(out)
}

/// Checks that the mesh can be deformed; returns its diagonal.
pub(crate) fn check_mesh(mesh: &TriMesh) -> Result<f64> {
    mesh.validate()?;
    if mesh.num_vertices() == 0 {
        return Err(DeformError::InvalidMesh("the mesh has no vertices".into()));
    }
    if mesh.num_triangles() == 0 {
        return Err(DeformError::InvalidMesh(
            "the mesh has no triangles (a surface is needed for sampling)".into(),
        ));
    }
    let d = mesh.diagonal();
    if !d.is_finite() {
        return Err(DeformError::InvalidMesh(
            "the mesh's diagonal overflows (coordinates too large to square; rescale it)".into(),
        ));
    }
    if d <= 0.0 {
        return Err(DeformError::InvalidMesh("the mesh has no extent (all vertices coincide)".into()));
    }
    Ok(d)
}

/// Resolves one symmetry (`None` for an instance set without instances).
pub(crate) fn resolve_symmetry(
    mesh: &TriMesh,
    s: &motif_core::procedural::Symmetry,
    diagonal: f64,
    tolerance: f64,
    margin: f64,
    next_symbol: &mut usize,
) -> Result<Option<ResolvedSymmetry>> {
    let mut region = |r: &Region, what: String| -> Result<ResolvedRegion> {
        let test = RegionTest::compile(r, mesh, margin, &what)?;
        let vertices: Vec<u32> = (0..mesh.num_vertices())
            .filter(|&v| test.contains_vertex(v, mesh.positions[v]))
            .map(|v| v as u32)
            .collect();
        if vertices.is_empty() {
            return Err(DeformError::EmptyRegion { what });
        }
        let symbol = *next_symbol;
        *next_symbol += 1;
        Ok(ResolvedRegion { region: r.clone(), vertices, test, symbol })
    };
    let kind = match &s.kind {
        SymmetryKind::Group { region: r, generators } => {
            // Elements are told apart by their linear parts (in a finite group no two share
            // one). A translation c − Rc of a rotation about a centre c far from the origin
            // carries the generators' rounding times |c|, so translations are compared at the
            // scale of the farthest vertex too: a model placed 10⁷ from the origin closes as it
            // does at the origin.
            let reach = mesh.positions.iter().map(|p| norm(*p)).fold(0.0, f64::max);
            let elements = group_closure(&s.name, generators, diagonal + reach, tolerance)?;
            ResolvedKind::Group {
                region: region(r, format!("the region of symmetry {:?}", s.name))?,
                generators: generators.clone(),
                elements,
            }
        }
        SymmetryKind::Instances { instances } => {
            if instances.is_empty() {
                return Ok(None);
            }
            let mut regions = Vec::with_capacity(instances.len());
            let mut transforms = Vec::with_capacity(instances.len());
            let mut inverses = Vec::with_capacity(instances.len());
            for (i, inst) in instances.iter().enumerate() {
                let d = rigidity_deviation(&inst.transform);
                if d > ORTHOGONALITY_TOLERANCE.max(tolerance) {
                    return Err(DeformError::NonOrthogonal {
                        symmetry: s.name.clone(),
                        transform: i,
                        deviation: d,
                    });
                }
                regions.push(region(&inst.region, format!("instance {i} of symmetry {:?}", s.name))?);
                transforms.push(inst.transform);
                inverses.push(rigid_inverse(&inst.transform));
            }
            ResolvedKind::Instances { instances: regions, transforms, inverses }
        }
    };
    Ok(Some(ResolvedSymmetry { name: s.name.clone(), kind }))
}

impl ResolvedAnnotation {
    /// True when some region needs the nearest mesh vertex of a point (vertex or face regions).
    pub(crate) fn needs_nearest(&self) -> bool {
        self.symmetries.iter().any(|s| match &s.kind {
            ResolvedKind::Group { region, .. } => region.test.needs_nearest(),
            ResolvedKind::Instances { instances, .. } => instances.iter().any(|r| r.test.needs_nearest()),
        })
    }

    /// The transforms to check and test exactness on: every non-identity group element on its
    /// region, and for instance sets the maps between instance 0 and every other instance, both
    /// ways (every other partial map `T_a · T_b⁻¹` is a composition of these, so exactness on them
    /// implies exactness on all).
    pub fn elements(&self) -> Vec<SymmetryElement> {
        let mut out = Vec::new();
        for (si, s) in self.symmetries.iter().enumerate() {
            match &s.kind {
                ResolvedKind::Group { region, elements, .. } => {
                    for (e, g) in elements.iter().enumerate().skip(1) {
                        out.push(SymmetryElement {
                            symmetry: si,
                            name: s.name.clone(),
                            label: format!("element {e}"),
                            transform: *g,
                            domain: region.vertices.clone(),
                        });
                    }
                }
                ResolvedKind::Instances { instances, transforms, inverses } => {
                    for a in 1..instances.len() {
                        for (to, from) in [(a, 0), (0, a)] {
                            out.push(SymmetryElement {
                                symmetry: si,
                                name: s.name.clone(),
                                label: format!("instance {from} -> {to}"),
                                transform: mat4_mul(&transforms[to], &inverses[from]),
                                domain: instances[from].vertices.clone(),
                            });
                        }
                    }
                }
            }
        }
        out
    }

    /// The annotation with only the identity: what [`crate::SymmetryMode::Ignore`] uses.
    pub(crate) fn identity_only(diagonal: f64, tolerance: f64) -> ResolvedAnnotation {
        ResolvedAnnotation {
            diagonal,
            tolerance,
            symmetries: Vec::new(),
            warnings: Vec::new(),
            margin: REGION_MARGIN * diagonal,
            num_symbols: 0,
        }
    }
}

/// Nearest-vertex lookups for points, built only when some region needs them.
pub(crate) struct NearestVertex {
    tree: Option<KdTree>,
}

impl NearestVertex {
    pub(crate) fn new(mesh: &TriMesh, resolved: &ResolvedAnnotation) -> Result<Self> {
        Ok(NearestVertex {
            tree: if resolved.needs_nearest() { Some(KdTree::new(&mesh.positions)?) } else { None },
        })
    }

    pub(crate) fn get(&self, p: Point3) -> Option<usize> {
        self.tree.as_ref().map(|t| t.nearest(p).index)
    }
}

/// Applies `m` to `p` (re-exported helper so modules share one definition).
#[inline]
pub(crate) fn apply(m: &Mat4, p: Point3) -> Point3 {
    transform_point(m, p)
}

#[cfg(test)]
mod tests {
    use super::*;
    use motif_core::procedural::{reflection, rotation_about};

    #[test]
    fn dihedral_closure_has_2n_elements() {
        let r = rotation_about([0.0, 0.0, 1.0], [0.0; 3], std::f64::consts::TAU / 6.0);
        let m = reflection([0.0, 1.0, 0.0], [0.0; 3]);
        let g = group_closure("d6", &[r, m], 1.0, 1e-4).unwrap();
        assert_eq!(g.len(), 12);
    }

    #[test]
    fn closure_errors_name_the_symmetry() {
        let mut s = IDENTITY4;
        s[0][0] = 2.0;
        let e = group_closure("stretchy", &[s], 1.0, 1e-4).unwrap_err();
        assert!(e.to_string().contains("stretchy"), "{e}");
        let irrational = rotation_about([0.0, 0.0, 1.0], [0.0; 3], 1.0);
        let e = group_closure("spinner", &[irrational], 1.0, 1e-9).unwrap_err();
        assert!(matches!(e, DeformError::GroupTooLarge { .. }), "{e}");
        let t = motif_core::procedural::translation([1.0, 0.0, 0.0]);
        assert!(group_closure("slide", &[t], 1.0, 1e-4).is_err());
        // Within a loose tolerance a 1 rad rotation "closes" after 710 steps (710 ≡ 6e-5 mod 2π):
        // refused as 113·360°/710, not taken for a group of 710 elements.
        let e = group_closure("loose", &[irrational], 1.0, 1e-4).unwrap_err();
        assert!(matches!(e, DeformError::NotAFiniteTurn { k: 113, n: 710, .. }), "{e}");
        // Two fifths of a turn generate C5 as a fifth does, and a 45° turn written with four
        // decimals closes within the annotation's tolerance.
        let two_fifths = rotation_about([0.0, 0.0, 1.0], [0.0; 3], 2.0 * std::f64::consts::TAU / 5.0);
        assert_eq!(group_closure("c5", &[two_fifths], 1.0, 1e-4).unwrap().len(), 5);
        let mut eighth = rotation_about([0.0, 0.0, 1.0], [0.0; 3], std::f64::consts::TAU / 8.0);
        for row in eighth.iter_mut().take(3) {
            for x in row.iter_mut().take(3) {
                *x = (*x * 1e4).round() / 1e4;
            }
        }
        assert_eq!(group_closure("c8", &[eighth], 1.0, 1e-3).unwrap().len(), 8);
    }

    #[test]
    fn parse_checks_the_format_tag() {
        let ok = r#"{"format":"motif_symmetry_v1","tolerance":1e-3,"symmetries":[{"name":"m","region":"all","generators":[[[-1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]]}]}"#;
        let a = parse_annotation(ok).unwrap();
        assert_eq!(a.symmetries.len(), 1);
        let bad = ok.replace("motif_symmetry_v1", "motif_symmetry_v9");
        assert!(matches!(parse_annotation(&bad), Err(DeformError::WrongFormat { .. })));
        // A handles file is named by its tag, not reported as an annotation missing `tolerance`.
        let handles = r#"{"format":"motif_handles_v1","handles":[{"region":"all"}],"frames":[]}"#;
        let e = parse_annotation(handles).unwrap_err();
        assert!(
            matches!(e, DeformError::WrongFormat { .. }) && e.to_string().contains("motif_handles_v1"),
            "{e}"
        );
        assert!(matches!(parse_annotation("{"), Err(DeformError::Json { .. })));
        // A group with instances too would be read as the group, the instances dropped.
        let both = ok.replace(r#""region":"all","#, r#""region":"all","instances":[],"#);
        let e = parse_annotation(&both).unwrap_err();
        assert!(matches!(e, DeformError::Json { .. }) && e.to_string().contains("symmetries[0]"), "{e}");
    }

    #[test]
    fn parse_errors_name_the_entry_and_field() {
        let ok = r#"{"format":"motif_symmetry_v1","tolerance":1e-3,"symmetries":[{"name":"m","region":"all","generators":[[[-1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]]}]}"#;
        let cases = [
            // A 3×3 matrix.
            (ok.replace(",[0,0,0,1]]]", "]]"), "symmetries[0].generators[0]"),
            (ok.replace(r#""region":"all""#, r#""region":{"vertices":[-1]}"#), "symmetries[0].region"),
            (ok.replace("generators", "generator"), "unknown field `generator`"),
            (ok.replace(r#""name":"m","#, ""), "missing `name`"),
        ];
        for (json, expected) in cases {
            let e = parse_annotation(&json).unwrap_err().to_string();
            assert!(e.contains(expected) && !e.contains("untagged"), "{expected}: {e}");
        }
    }
}
