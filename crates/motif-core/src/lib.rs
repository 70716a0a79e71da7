//! Motif's geometry core: the types every pipeline shares (triangle meshes, point clouds), reading
//! and writing standard formats, spatial queries, sampling, normals, curvature, the SHOT
//! descriptor, rigid registration, and procedural example shapes with known structure.
//!
//! Conventions used throughout:
//! - positions are `[f64; 3]` ([`Point3`]), triangles `[u32; 3]` with counter-clockwise winding
//!   seen from outside (normals point out by the right-hand rule);
//! - transforms are row-major 4×4 matrices acting on column vectors (`p' = M p`), named by the
//!   spaces they map (`world_from_local`);
//! - tolerances given "relative to the diagonal" are multiplied by the bounding-box diagonal.
//!
//! The pipelines (`motif-deform`, `motif-retarget`, `motif-detect`) build on this crate and never
//! reach around it; see `ARCHITECTURE.md` at the repository root.

#![warn(missing_docs)]

pub mod curvature;
pub mod data;
pub mod error;
pub mod geometry;
pub mod hole_fill;
pub mod icp;
pub mod io;
pub mod mesh;
pub mod normals;
pub mod plotting;
pub mod point_cloud;
pub mod procedural;
pub mod progress;
pub mod sampling;
pub mod shot;
pub mod spatial;

pub use error::{Error, Result};
pub use geometry::{Aabb, Point3};
pub use mesh::TriMesh;
pub use point_cloud::{Attribute, AttributeData, NormalsRepair, PointCloud};
