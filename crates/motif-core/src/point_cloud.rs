//! Point clouds: positions with optional normals, colours and named per-point attributes.

use crate::geometry::{Aabb, Point3, norm, scale};
use crate::{Error, Result};

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
