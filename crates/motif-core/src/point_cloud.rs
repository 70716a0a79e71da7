//! Point clouds: positions with optional normals, colours and named per-point attributes.

use crate::geometry::{Aabb, Point3, dot, norm, scale};
use crate::{Error, Result};

/// Neighbours [`PointCloud::repair_degenerate_normals`] estimates a normal from, and orients it by.
pub const REPAIR_NEIGHBOURS: usize = 16;

/// What [`PointCloud::repair_degenerate_normals`] did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct NormalsRepair {
    /// Normals that were zero or not finite.
    pub degenerate: usize,
    /// Of those, how many were estimated (the others' cloud lost its normals).
    pub estimated: usize,
    /// Whether the normals were dropped (more than half degenerate, or too few points).
    pub dropped: bool,
}

/// Values of a named per-point attribute (e.g. `k1`, `class`, `instance`).
#[derive(Debug, Clone, PartialEq)]
pub enum AttributeData {
    /// Real values, written as PLY `float`/`double`.
    Float(Vec<f64>),
    /// Integer values (labels), written as PLY `int`.
    Int(Vec<i64>),
}

impl AttributeData {
    /// Number of values.
    pub fn len(&self) -> usize {
        match self {
            AttributeData::Float(v) => v.len(),
            AttributeData::Int(v) => v.len(),
        }
    }

    /// True when there are no values.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Value `i` as f64.
    pub fn get_f64(&self, i: usize) -> f64 {
        match self {
            AttributeData::Float(v) => v[i],
            AttributeData::Int(v) => v[i] as f64,
        }
    }
}

/// A named per-point attribute.
#[derive(Debug, Clone, PartialEq)]
pub struct Attribute {
    /// Property name as written to PLY/CSV (ASCII letters, digits and `_`).
    pub name: String,
    /// One value per point.
    pub data: AttributeData,
}

/// A point cloud: positions and optional per-point data, all of the same length.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PointCloud {
    /// Positions, `#P × 3`.
    pub positions: Vec<Point3>,
    /// Unit normals, `#P × 3`, when known.
    pub normals: Option<Vec<Point3>>,
    /// 8-bit RGB colours, `#P × 3`, when known.
    pub colors: Option<Vec<[u8; 3]>>,
    /// Further named scalar attributes, each `#P` long.
    pub attributes: Vec<Attribute>,
}

impl PointCloud {
    /// A cloud of bare positions.
    pub fn from_positions(positions: Vec<Point3>) -> Self {
        PointCloud { positions, ..Default::default() }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// True when there are no points.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Drops the normals when any of them is zero or not finite (readers turn NaN normals into
    /// zero vectors), so that callers estimate them as for a cloud without normals: a zero normal
    /// used as a direction flips curvature signs and skews descriptors. Otherwise makes them unit
    /// length. Returns how many were degenerate (0 when the normals were kept or absent).
    pub fn drop_degenerate_normals(&mut self) -> usize {
        let Some(normals) = &mut self.normals else { return 0 };
        let degenerate = normals.iter().filter(|n| !(norm(**n) > 1e-12 && norm(**n).is_finite())).count();
        if degenerate > 0 {
            self.normals = None;
        } else {
            for n in normals.iter_mut() {
                *n = scale(*n, 1.0 / norm(*n));
            }
        }
        degenerate
    }

    /// Repairs zero or non-finite normals (readers turn NaN normals into zero vectors): a zero
    /// normal used as a direction flips curvature signs and skews descriptors.
    ///
    /// When at most half of them are degenerate, those are estimated by PCA over their
    /// [`REPAIR_NEIGHBOURS`] nearest points and each is turned to agree with the file's normals
    /// of its [`REPAIR_NEIGHBOURS`] nearest points that have one (weighted by inverse distance),
    /// so that a scan with a few bad normals keeps the rest. When more are degenerate, or the
    /// points are too few to estimate from, the normals are dropped, so that callers estimate
    /// them all as for a cloud without normals ([`PointCloud::drop_degenerate_normals`]).
    /// Valid normals are made unit length either way.
    pub fn repair_degenerate_normals(&mut self) -> NormalsRepair {
        let Some(normals) = &self.normals else { return NormalsRepair::default() };
        let valid = |n: &Point3| norm(*n) > 1e-12 && norm(*n).is_finite();
        let degenerate = normals.iter().filter(|n| !valid(n)).count();
        if degenerate == 0 || 2 * degenerate > normals.len() || normals.len() < REPAIR_NEIGHBOURS {
            let dropped = self.drop_degenerate_normals() > 0;
            return NormalsRepair { degenerate, estimated: 0, dropped };
        }
        let options = crate::normals::NormalsOptions {
            neighbours: REPAIR_NEIGHBOURS,
            orientation: crate::normals::Orientation::Unoriented,
            ..Default::default()
        };
        let Ok(estimated) = crate::normals::estimate_normals(&self.positions, &options) else {
            self.drop_degenerate_normals();
            return NormalsRepair { degenerate, estimated: 0, dropped: true };
        };
        let normals = self.normals.as_mut().expect("checked above");
        let keep: Vec<usize> = (0..normals.len()).filter(|&i| valid(&normals[i])).collect();
        let kept: Vec<Point3> = keep.iter().map(|&i| self.positions[i]).collect();
        let Ok(tree) = crate::spatial::KdTree::new(&kept) else {
            self.drop_degenerate_normals();
            return NormalsRepair { degenerate, estimated: 0, dropped: true };
        };
        for i in 0..normals.len() {
            if valid(&normals[i]) {
                normals[i] = scale(normals[i], 1.0 / norm(normals[i]));
                continue;
            }
            let mut around = [0.0; 3];
            for nb in tree.knn(self.positions[i], REPAIR_NEIGHBOURS) {
                let n = normals[keep[nb.index]];
                let w = 1.0 / (nb.distance + 1e-300) / norm(n);
                around = [around[0] + w * n[0], around[1] + w * n[1], around[2] + w * n[2]];
            }
            let e = estimated[i];
            normals[i] = if dot(e, around) < 0.0 { scale(e, -1.0) } else { e };
        }
        NormalsRepair { degenerate, estimated: degenerate, dropped: false }
    }

    /// Bounding box, `None` when empty.
    pub fn aabb(&self) -> Option<Aabb> {
        Aabb::from_points(&self.positions)
    }

    /// Length of the bounding-box diagonal (0 when empty).
    pub fn diagonal(&self) -> f64 {
        self.aabb().map_or(0.0, |b| b.diagonal())
    }

    /// Adds or replaces a named attribute.
    pub fn set_attribute(&mut self, name: &str, data: AttributeData) {
        if let Some(a) = self.attributes.iter_mut().find(|a| a.name == name) {
            a.data = data;
        } else {
            self.attributes.push(Attribute { name: name.to_string(), data });
        }
    }

    /// Looks up a named attribute.
    pub fn attribute(&self, name: &str) -> Option<&AttributeData> {
        self.attributes.iter().find(|a| a.name == name).map(|a| &a.data)
    }

    /// Checks lengths agree and every coordinate is finite.
    pub fn validate(&self) -> Result<()> {
        let n = self.positions.len();
        if let Some(i) = self.positions.iter().position(|p| !crate::geometry::is_finite(*p)) {
            return Err(Error::InvalidInput(format!("point {i} has a NaN or infinite coordinate")));
        }
        if let Some(nr) = &self.normals {
            if nr.len() != n {
                return Err(Error::InvalidInput(format!("{} normals for {n} points", nr.len())));
            }
        }
        if let Some(c) = &self.colors {
            if c.len() != n {
                return Err(Error::InvalidInput(format!("{} colours for {n} points", c.len())));
            }
        }
        for a in &self.attributes {
            if a.data.len() != n {
                return Err(Error::InvalidInput(format!(
                    "attribute {} has {} values for {n} points",
                    a.name,
                    a.data.len()
                )));
            }
        }
        Ok(())
    }

    /// Keeps the points at `indices` (in that order), with all their per-point data.
    pub fn select(&self, indices: &[usize]) -> PointCloud {
        PointCloud {
            positions: indices.iter().map(|&i| self.positions[i]).collect(),
            normals: self.normals.as_ref().map(|n| indices.iter().map(|&i| n[i]).collect()),
            colors: self.colors.as_ref().map(|c| indices.iter().map(|&i| c[i]).collect()),
            attributes: self
                .attributes
                .iter()
                .map(|a| Attribute {
                    name: a.name.clone(),
                    data: match &a.data {
                        AttributeData::Float(v) => {
                            AttributeData::Float(indices.iter().map(|&i| v[i]).collect())
                        }
                        AttributeData::Int(v) => AttributeData::Int(indices.iter().map(|&i| v[i]).collect()),
                    },
                })
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit sphere of `n` points (Fibonacci spiral) with outward normals times `sign`.
    fn sphere(n: usize, sign: f64) -> PointCloud {
        let positions: Vec<Point3> = (0..n)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let r = (1.0 - z * z).sqrt();
                let phi = i as f64 * 2.399_963_229_728_653;
                [r * phi.cos(), r * phi.sin(), z]
            })
            .collect();
        let normals = positions.iter().map(|p| scale(*p, sign)).collect();
        PointCloud { positions, normals: Some(normals), colors: None, attributes: Vec::new() }
    }

    #[test]
    fn a_few_zero_normals_are_estimated_and_oriented_like_their_neighbours() {
        // Every seventh normal zero, one NaN (read as zero); the file's normals point outward, or,
        // in the second cloud, inward: the repaired ones follow them.
        for sign in [1.0, -1.0] {
            let mut c = sphere(2000, sign);
            let normals = c.normals.as_mut().unwrap();
            for i in (0..2000).step_by(7) {
                normals[i] = [0.0; 3];
            }
            normals[1] = [f64::NAN, 0.0, 0.0];
            let r = c.repair_degenerate_normals();
            assert_eq!(r, NormalsRepair { degenerate: 287, estimated: 287, dropped: false });
            let normals = c.normals.as_ref().unwrap();
            for (p, n) in c.positions.iter().zip(normals) {
                assert!((norm(*n) - 1.0).abs() < 1e-12);
                assert!(dot(*p, *n) * sign > 0.99, "{p:?} {n:?}");
            }
        }
    }

    #[test]
    fn mostly_zero_normals_are_dropped() {
        let mut c = sphere(100, 1.0);
        for n in c.normals.as_mut().unwrap().iter_mut().take(51) {
            *n = [0.0; 3];
        }
        assert_eq!(
            c.repair_degenerate_normals(),
            NormalsRepair { degenerate: 51, estimated: 0, dropped: true }
        );
        assert!(c.normals.is_none());
        // Valid normals are only made unit length.
        let mut c = sphere(100, 2.0);
        assert_eq!(c.repair_degenerate_normals(), NormalsRepair::default());
        assert!(c.normals.unwrap().iter().all(|n| (norm(*n) - 1.0).abs() < 1e-12));
    }
}
