//! Procedural example shapes with known structure: symmetry groups, instance sets of repeated
//! parts and translational lattices, written exactly as the deformation (thesis ch. 3), retargeting
//! (ch. 4) and detection (ch. 5) pipelines consume them.
//!
//! Each generator takes an options struct and returns an [`Example`]: a triangle mesh and its
//! [`Structure`]. [`generate`] builds a named example with default options (the CLI's
//! `motif example NAME OUT`); [`names`] lists the names.
//!
//! Conventions: metres; y is up, x to the right, z towards the viewer. Meshes are unions of closed,
//! outward-wound parts (boards, blades, ...) that touch but are not welded to each other. Every
//! symmetry is built in, not measured: a symmetric part is the orbit of a fundamental piece under
//! its group, so each transform of the structure maps the vertices of its region onto mesh
//! vertices up to floating-point rounding (residuals ≤ 10⁻¹² of the diagonal, see
//! [`symmetry_residual`]), and group symmetries map triangles onto triangles. Every generator has a
//! `resolution` option that subdivides all parts while keeping this exactness.
//!
//! | name | shape | structure |
//! |---|---|---|
//! | `shelf` | 4 × 3 cells | `cell` instances, 2 lattice vectors |
//! | `shelf_sheared` | the same on a sheared lattice (thesis Fig. 4.7) | as `shelf` |
//! | `facade` | wall, 5 bays × 4 floors, two window styles, a door | `window_a`, `window_b`, `door`; lattice |
//! | `facade_irregular` | the same with seeded jitter of bays and floors | instances, no lattice |
//! | `fan` | hub and 6 flat blades | D₆ (rotation + mirror) on all; `blade` instances |
//! | `gear` | 17 teeth, bore | D₁₇ × mid-plane mirror on all; `tooth` instances |
//! | `chair` | seat, back, 4 legs | one mirror on all; `leg` instances |
//! | `windmill` | tower, nacelle, 4-blade rotor | mirror on all; C₄ on the rotor; a mirror per blade |
//! | `windmill_100k` | the windmill subdivided to ≥ 100k vertices | as `windmill` |
//! | `fence` | 8 posts, 2 rails per bay | `post` and `bay` instances; 1 lattice vector |

mod chair;
mod facade;
mod fan;
mod fence;
mod gear;
mod primitives;
mod shelf;
mod structure;
mod windmill;

use crate::mesh::TriMesh;
use crate::{Error, Result};

pub use chair::{ChairOptions, chair};
pub use facade::{FacadeOptions, FacadeSpacing, WindowLayout, facade};
pub use fan::{FanOptions, fan};
pub use fence::{FenceOptions, fence};
pub use gear::{GearOptions, gear};
pub use primitives::{box_mesh, cylinder_mesh};
pub use shelf::{ShelfLattice, ShelfOptions, shelf};
pub use structure::{
    DEFAULT_SYMMETRY_TOLERANCE, Instance, InstanceClass, Region, SYMMETRY_FORMAT, Structure, Symmetry,
    SymmetryAnnotation, SymmetryInstance, SymmetryKind, reflection, rigid_inverse, rotation_about,
    symmetry_residual, translation,
};
pub use windmill::{WindmillOptions, windmill};

/// A generated shape with its known structure.
#[derive(Debug, Clone, PartialEq)]
pub struct Example {
    /// The registry name (`"shelf"`, `"fan"`, ...).
    pub name: String,
    /// The shape: closed, outward-wound parts, no degenerate triangles.
    pub mesh: TriMesh,
    /// Its symmetries, lattice and repeated parts.
    pub structure: Structure,
}

/// Registry names, in the order of the table in the module documentation.
const NAMES: &[&str] = &[
    "shelf",
    "shelf_sheared",
    "facade",
    "facade_irregular",
    "fan",
    "gear",
    "chair",
    "windmill",
    "windmill_100k",
    "fence",
];

/// The names [`generate`] accepts.
pub fn names() -> &'static [&'static str] {
    NAMES
}

/// Generates the named example with default options. `seed` drives the only random choices
/// (the jitter of `facade_irregular`); every other example ignores it and is the same for every
/// seed. Unknown names give [`Error::InvalidOption`] listing the valid names.
pub fn generate(name: &str, seed: u64) -> Result<Example> {
    let mut ex = match name {
        "shelf" => shelf(&ShelfOptions::default()),
        "shelf_sheared" => shelf(&ShelfOptions::sheared()),
        "facade" => facade(&FacadeOptions { seed, ..Default::default() }),
        "facade_irregular" => facade(&FacadeOptions { seed, ..FacadeOptions::irregular() }),
        "fan" => fan(&FanOptions::default()),
        "gear" => gear(&GearOptions::default()),
        "chair" => chair(&ChairOptions::default()),
        "windmill" => windmill(&WindmillOptions::default()),
        "windmill_100k" => windmill(&WindmillOptions { resolution: 11, ..Default::default() }),
        "fence" => fence(&FenceOptions::default()),
        _ => {
            return Err(Error::InvalidOption {
                name: "example",
                message: format!("unknown example {name:?}; valid names: {}", NAMES.join(", ")),
            });
        }
    }?;
    ex.name = name.to_string();
    Ok(ex)
}
