//! Greedy assembly of the detected group from validated elements (module documentation of
//! [`super`], step 3).

use motif_core::Point3;
use motif_core::geometry::{IDENTITY4, Mat4, dot, normalize, scale, sub};

use super::CandidateStatus;
use super::element::{SymmetryElement, closest_on_line, line_angle};
use super::group::{self, GroupStructure, group_closure, group_contains};
use super::options::SymmetryDetectOptions;
use super::report::{GroupReport, Scope};
use super::search::{Analysis, Found};
use super::shape::Shape;

/// A group assembled from found elements.
pub(crate) struct AssembledGroup {
    pub(crate) name: String,
    pub(crate) elements: Vec<Mat4>,
    pub(crate) generators: Vec<Mat4>,
    pub(crate) structure: GroupStructure,
    pub(crate) residual: f64,
    pub(crate) center: Point3,
    /// `max_rotation_order` of the options (for [`GroupReport::possibly_continuous`]).
    pub(crate) max_order: u32,
}

impl AssembledGroup {
    pub(crate) fn report(&self, scope: Scope, region_faces: Option<usize>) -> GroupReport {
        GroupReport {
            name: self.name.clone(),
            scope,
            structure: self.structure.clone(),
            generators: self.generators.iter().filter_map(|m| group::element_of(m, self.center)).collect(),
            generator_matrices: self.generators.clone(),
            max_residual: self.residual,
            region_faces,
            possibly_continuous: self
                .structure
                .rotation_axes
                .first()
                .is_some_and(|(_, n)| *n >= self.max_order),
        }
    }
}

/// Angle within which an element is snapped onto (or perpendicular to) the principal axis.
const SNAP: f64 = 3.0 * std::f64::consts::PI / 180.0;

/// The element moved so that it is exactly compatible with the principal axis `(a, p)`: planes
/// and 2-fold axes nearly containing / perpendicular to the axis are made exactly so.
pub(crate) fn snap(e: SymmetryElement, a: Point3, p: Point3) -> SymmetryElement {
    let perp = |d: Point3| dot(d, a).abs() < SNAP.sin();
    match e {
        SymmetryElement::Mirror { normal, point } => {
            if perp(normal) {
                let n = normalize(sub(normal, scale(a, dot(normal, a)))).unwrap_or(normal);
                SymmetryElement::Mirror { normal: n, point: p }
            } else if line_angle(normal, a) < SNAP {
                SymmetryElement::Mirror { normal: a, point: closest_on_line(point, p, a) }
            } else {
                e
            }
        }
        SymmetryElement::Rotation { axis, point, order } => {
            if perp(axis) {
                let b = normalize(sub(axis, scale(a, dot(axis, a)))).unwrap_or(axis);
                SymmetryElement::Rotation { axis: b, point: closest_on_line(point, p, a), order }
            } else if line_angle(axis, a) < SNAP {
                let b = if dot(axis, a) < 0.0 { scale(a, -1.0) } else { a };
                SymmetryElement::Rotation { axis: b, point: p, order }
            } else {
                e
            }
        }
        SymmetryElement::RotoReflection { axis, point, order } => {
            if line_angle(axis, a) < SNAP {
                let b = if dot(axis, a) < 0.0 { scale(a, -1.0) } else { a };
                SymmetryElement::RotoReflection { axis: b, point: closest_on_line(point, p, a), order }
            } else {
                e
            }
        }
        SymmetryElement::Inversion { center } => {
            SymmetryElement::Inversion { center: closest_on_line(center, p, a) }
        }
    }
}

/// Greedy group assembly (module documentation, step 3). `tol` is the acceptance tolerance of
/// the group's elements on the validation points.
pub(crate) fn assemble(
    shape: &Shape,
    analysis: &Analysis,
    o: &SymmetryDetectOptions,
    tol: f64,
    include_approx: bool,
) -> Option<AssembledGroup> {
    let mut list: Vec<Found> = analysis
        .found
        .iter()
        .copied()
        .filter(|f| f.status == CandidateStatus::Verified || include_approx)
        .collect();
    let rank = |e: &SymmetryElement| match e {
        SymmetryElement::Rotation { order, .. } => (0, u32::MAX - order),
        SymmetryElement::Mirror { .. } => (1, 0),
        SymmetryElement::RotoReflection { order, .. } => (2, u32::MAX - order),
        SymmetryElement::Inversion { .. } => (3, 0),
    };
    list.sort_by(|x, y| rank(&x.element).cmp(&rank(&y.element)).then(x.residual.total_cmp(&y.residual)));
    let metric = shape.metric();
    let merge = merge_distance(shape, tol);
    let mut elements = vec![IDENTITY4];
    let mut gens: Vec<Mat4> = Vec::new();
    let mut principal: Option<(Point3, Point3)> = None;
    let mut residual: f64 = 0.0;
    for f in list {
        let e = match principal {
            Some((a, p)) => snap(f.element, a, p),
            None => f.element,
        };
        let m = e.matrix();
        if group_contains(&elements, &m, &metric, merge) {
            continue;
        }
        let mut trial = gens.clone();
        trial.push(m);
        let Some(closure) = group_closure(&trial, &metric, merge, o.max_group_order) else { continue };
        // No axis of a higher order than was asked for (products of near-coincident elements
        // of a near-surface of revolution would otherwise build one).
        if group::classify(&closure).rotation_axes.first().is_some_and(|(_, n)| *n > o.max_rotation_order) {
            continue;
        }
        let new: Vec<&Mat4> =
            closure.iter().filter(|x| !group_contains(&elements, x, &metric, merge)).collect();
        let mut worst: f64 = 0.0;
        let mut ok = true;
        for x in new {
            let r = shape.surface.residual(&shape.validate, x, tol);
            if !r.complete || r.max > tol {
                ok = false;
                break;
            }
            worst = worst.max(r.max);
        }
        if !ok {
            continue;
        }
        residual = residual.max(worst).max(f.residual);
        gens = trial;
        elements = closure;
        if principal.is_none() {
            if let SymmetryElement::Rotation { axis, point, .. } = e {
                principal = Some((axis, point));
            }
        }
    }
    if elements.len() <= 1 {
        return None;
    }
    let structure = group::classify(&elements);
    let generators = group::choose_generators(&elements, &structure, &metric, merge);
    let name = group_name(&structure, &generators, shape.center);
    Some(AssembledGroup {
        name,
        elements,
        generators,
        structure,
        residual,
        center: shape.center,
        max_order: o.max_rotation_order,
    })
}

/// Distance below which two group elements are the same: five times the tolerance (products
/// of a few validated generators drift by about that much), at most 5% of the radius.
pub(crate) fn merge_distance(shape: &Shape, tol: f64) -> f64 {
    (5.0 * tol * shape.surface.diagonal).min(0.05 * shape.radius)
}

/// "mirror plane normal [...]", "rotation C10 about axis [...]", or
/// "C6v (order 12): rotation C6 about axis [...]; mirror plane normal [...]".
pub(crate) fn group_name(structure: &GroupStructure, generators: &[Mat4], center: Point3) -> String {
    let parts: Vec<String> =
        generators.iter().filter_map(|m| group::element_of(m, center)).map(|e| e.describe()).collect();
    if generators.len() == 1 && parts.len() == 1 {
        return parts[0].clone();
    }
    format!("{} (order {}): {}", structure.schoenflies, structure.order, parts.join("; "))
}
