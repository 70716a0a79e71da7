//! Handles (`motif_handles_v1`): regions of the mesh that the user fixes or moves rigidly (thesis
//! 3.5, the constraints `A ū ≈ a` of eq. 3.3), and optional `frames` replaying a drag.
//!
//! ```json
//! { "format": "motif_handles_v1",
//!   "handles": [ { "region": {"sphere": {"center": [0.4, 0.1, 0], "radius": 0.05}},
//!                  "transform": [[1,0,0,0.1],[0,1,0,0],[0,0,1,0],[0,0,0,1]] },
//!                { "region": {"vertices": [12, 13, 14]} } ],
//!   "frames": [ [ [[...]], [[...]] ] ] }
//! ```
//! A handle without `transform` stays where it is. `frames[f][h]` is handle `h`'s transform in
//! frame `f`.

use std::path::Path;

use serde::{Deserialize, Serialize};

use motif_core::geometry::{IDENTITY4, Mat4};
use motif_core::procedural::Region;

use crate::error::{DeformError, Result};

/// The format tag of handle files.
pub const HANDLES_FORMAT: &str = "motif_handles_v1";

/// One handle: a region of the mesh and where it goes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Handle {
    /// The handle's region (same forms as annotation regions).
    pub region: Region,
    /// Rigid transform applied to the handle's rest positions, row-major 4×4; `None`: fixed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub transform: Option<Mat4>,
}

impl Handle {
    /// A fixed handle.
    pub fn fixed(region: Region) -> Handle {
        Handle { region, transform: None }
    }

    /// A handle moved by `transform`.
    pub fn moved(region: Region, transform: Mat4) -> Handle {
        Handle { region, transform: Some(transform) }
    }

    /// The transform, identity for a fixed handle.
    pub fn transform_or_identity(&self) -> Mat4 {
        self.transform.unwrap_or(IDENTITY4)
    }
}

/// A `motif_handles_v1` document.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HandlesFile {
    /// Always [`HANDLES_FORMAT`].
    pub format: String,
    /// The handles.
    pub handles: Vec<Handle>,
    /// Optional animation: `frames[f][h]` is the transform of handle `h` in frame `f`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub frames: Vec<Vec<Mat4>>,
}

impl HandlesFile {
    /// A document with these handles and no frames.
    pub fn new(handles: Vec<Handle>) -> HandlesFile {
        HandlesFile { format: HANDLES_FORMAT.to_string(), handles, frames: Vec::new() }
    }

    /// Parses JSON text; checks the format tag and that every frame has one transform per handle.
    pub fn from_json(json: &str) -> Result<HandlesFile> {
        Self::parse(json, "handles")
    }

    fn parse(json: &str, what: &str) -> Result<HandlesFile> {
        crate::annotation::check_format_tag(json, HANDLES_FORMAT, what)?;
        let f: HandlesFile = serde_json::from_str(json)
            .map_err(|source| DeformError::Json { what: what.to_string(), source })?;
        if f.format != HANDLES_FORMAT {
            return Err(DeformError::WrongFormat {
                what: what.to_string(),
                expected: HANDLES_FORMAT,
                found: f.format,
            });
        }
        for (i, fr) in f.frames.iter().enumerate() {
            if fr.len() != f.handles.len() {
                return Err(DeformError::InvalidFileContent {
                    field: "frames",
                    message: format!(
                        "{what}: frame {i} has {} {} for {} {} (one per handle is needed)",
                        fr.len(),
                        if fr.len() == 1 { "transform" } else { "transforms" },
                        f.handles.len(),
                        if f.handles.len() == 1 { "handle" } else { "handles" }
                    ),
                });
            }
        }
        Ok(f)
    }

    /// Reads a handles file.
    pub fn read(path: &Path) -> Result<HandlesFile> {
        let text = std::fs::read_to_string(path)
            .map_err(|source| DeformError::Io { path: path.to_path_buf(), source })?;
        Self::parse(&text, &path.display().to_string())
    }

    /// Pretty JSON text.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_default()
    }

    /// The handles' own transforms (identity for fixed ones): the single frame to solve when the
    /// file has no `frames`.
    pub fn transforms(&self) -> Vec<Mat4> {
        self.handles.iter().map(Handle::transform_or_identity).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_the_documented_example() {
        let j = r#"{"format":"motif_handles_v1","handles":[
            {"region":{"sphere":{"center":[0.4,0.1,0],"radius":0.05}},"transform":[[1,0,0,0.1],[0,1,0,0],[0,0,1,0],[0,0,0,1]]},
            {"region":{"vertices":[12,13,14]}}],
            "frames":[[[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]],[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]]]}"#;
        let f = HandlesFile::from_json(j).unwrap();
        assert_eq!(f.handles.len(), 2);
        assert!(f.handles[1].transform.is_none());
        assert_eq!(f.transforms()[0][0][3], 0.1);
        assert_eq!(f.frames.len(), 1);
        let back = HandlesFile::from_json(&f.to_json()).unwrap();
        assert_eq!(back, f);
        let bad = j.replace("motif_handles_v1", "nope");
        assert!(matches!(HandlesFile::from_json(&bad), Err(DeformError::WrongFormat { .. })));
        let short = r#"{"format":"motif_handles_v1","handles":[{"region":"all"}],"frames":[[]]}"#;
        assert!(HandlesFile::from_json(short).is_err());
    }
}
