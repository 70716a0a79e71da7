//! The WebSocket protocol between the page and the server.
//!
//! Text messages are JSON objects tagged by `"type"` ([`ClientMessage`], [`ServerMessage`]).
//! Geometry travels in binary messages so a 100k-vertex frame is one 1.2 MB copy, not JSON:
//!
//! - server → client: a [`FRAME_HEADER_BYTES`]-byte little-endian header (timings in [`FrameTiming`]:
//!   `[kind u32, seq u32, vertices u32, triangles u32, solve_ms f32, queue_ms f32, encode_ms f32,
//!   flags u32, received_at f64, sent_at f64]`), then `vertices × 3` f32 positions, then (flag
//!   [`FLAG_NORMALS`]) `vertices × 3` f32 unit normals, then (kinds [`BinaryKind::Model`] and
//!   [`BinaryKind::Retargeted`]) `triangles × 3` u32 indices. A [`BinaryKind::File`] message
//!   instead carries a file for the browser to download: `vertices` is the length of its UTF-8
//!   name and `triangles` the length of its bytes, which follow the header in that order.
//!   `received_at` / `sent_at` are the server's wall clock (Unix epoch, ms) when the request
//!   arrived and when the reply was encoded, so the page can split a frame's time into request
//!   transfer, server time and reply transfer (same machine, same clock).
//! - client → server: an upload, `[name length u32][name UTF-8][file bytes]`.
//!
//! Conventions: positions in model units, transforms row-major 4×4 acting on column vectors
//! (`p' = M p`), as everywhere in Motif.

use motif_core::Point3;
use motif_core::geometry::Mat4;
use motif_core::procedural::SymmetryAnnotation;
use serde::{Deserialize, Serialize};

/// Bytes of the header of every server binary message.
pub const FRAME_HEADER_BYTES: usize = 48;

/// Header flag: unit vertex normals follow the positions.
pub const FLAG_NORMALS: u32 = 1;

/// The timing fields of a binary message's header (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FrameTiming {
    /// Server solve time, ms.
    pub solve_ms: f32,
    /// Time the request waited on the server before its solve started, ms.
    pub queue_ms: f32,
    /// Server wall clock when the request arrived, Unix epoch ms (0: not a reply to a request).
    pub received_at: f64,
}

/// The server's wall clock, Unix epoch milliseconds.
pub fn unix_ms() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs_f64() * 1e3)
        .unwrap_or(0.0)
}

/// What a server binary message holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum BinaryKind {
    /// The opened model: positions and triangles (none for a point cloud).
    Model = 1,
    /// A deformation frame: positions only, same vertex order as the model.
    DeformFrame = 2,
    /// The retargeted model: positions and triangles.
    Retargeted = 3,
    /// An exported file for the browser to download: name and bytes.
    File = 4,
}

/// One ball of a handle region, model units, placed on the rest shape.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Ball {
    /// Centre.
    pub center: Point3,
    /// Radius.
    pub radius: f64,
}

/// A handle: the union of the balls the user clicked (click: new handle; shift-click: add a ball).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HandleSpec {
    /// The balls; at least one.
    pub balls: Vec<Ball>,
}

/// Which model an export writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum ExportSource {
    /// The model as shown in the deform view (deformed when handles moved it).
    #[default]
    Deformed,
    /// The last retargeted model.
    Retargeted,
}

/// Requests from the page.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum ClientMessage {
    /// Open a model file under the root (a sibling `NAME.sym.json` annotation is loaded too).
    Open {
        /// Path relative to the root (or absolute, inside it).
        path: String,
    },
    /// Open a generated example (`motif_core::procedural::generate`) with its known annotation.
    Example {
        /// Example name, e.g. `windmill`.
        name: String,
    },
    /// Detect symmetries (`motif_deform::symmetry_detect`), with progress; cancellable.
    DetectSymmetry,
    /// Load a `motif_symmetry_v1` annotation from a file under the root.
    LoadAnnotation {
        /// Path under the root.
        path: String,
    },
    /// Save the current annotation under the root.
    SaveAnnotation {
        /// Path under the root.
        path: String,
        /// Replace an existing file (inputs are never replaced).
        #[serde(default)]
        overwrite: bool,
    },
    /// Choose the handles: precomputes the deformation session for this handle set.
    SetHandles {
        /// The handles, in the order of `transforms` in [`ClientMessage::Drag`].
        handles: Vec<HandleSpec>,
        /// Target (rest → target transform) of each handle; `null` or missing: a handle equal to
        /// one of the previous set keeps that handle's current target, any other handle gets the
        /// rigid motion that best fits its region's current deformed positions. So adding a
        /// handle after a drag keeps the shape as it is. The chosen targets are sent back in
        /// [`ServerMessage::Handles`], followed by a [`BinaryKind::DeformFrame`] (sequence 0).
        #[serde(default)]
        transforms: Vec<Option<Mat4>>,
    },
    /// Move the handles; answered by a [`BinaryKind::DeformFrame`]. Only the newest pending drag
    /// is solved: older ones are dropped, never queued.
    Drag {
        /// Client sequence number, echoed in the frame.
        seq: u32,
        /// One transform per handle (rest → target).
        transforms: Vec<Mat4>,
        /// Also send unit vertex normals of the deformed mesh (for smooth shading).
        #[serde(default)]
        normals: bool,
    },
    /// The drag ended: measure the symmetry residual and the handle fit of the current frame.
    Release,
    /// Write a model (and its annotation as `STEM.sym.json`) under the root.
    Export {
        /// Output path under the root; the extension picks the format (obj, ply, glb, ...).
        path: String,
        /// Which model.
        #[serde(default)]
        source: ExportSource,
        /// Replace an existing file (inputs are never replaced).
        #[serde(default)]
        overwrite: bool,
        /// Also send the written files back as [`BinaryKind::File`] messages, for the browser to
        /// download.
        #[serde(default)]
        download: bool,
    },
    /// Principal offsets (`motif_retarget::offsets`), with progress; cancellable.
    Offsets,
    /// Resize by whole steps along the principal offsets; the newest pending request wins.
    Retarget {
        /// Client sequence number, echoed.
        seq: u32,
        /// Steps along principal offsets 0, 1, 2.
        steps: [i32; 3],
    },
    /// Load a detection result (`../shared/formats/detection.md`) under the root.
    LoadDetections {
        /// Path under the root.
        path: String,
    },
    /// Run building-block detection on the current model, with progress; cancellable.
    Detect,
    /// Write the detections shown (from `Detect` or `LoadDetections`) under the root, as a
    /// detection result (`../shared/formats/detection.md`, what `motif detect -o` writes).
    SaveDetections {
        /// Path under the root (`.json`).
        path: String,
        /// Replace an existing file (inputs are never replaced).
        #[serde(default)]
        overwrite: bool,
    },
    /// List the model files and JSON documents under the root (for the page's path fields).
    ListFiles,
    /// Cancel the running long computation.
    Cancel,
}

/// Sizes the server enforces (also sent to the page in [`ServerMessage::Hello`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Limits {
    /// Largest text message, bytes; larger ones are answered with an error. Default 1 MiB.
    pub max_text_bytes: usize,
    /// Largest upload (binary message), bytes. Larger ones are answered with an error on the same
    /// connection, up to twice this size (the WebSocket transport reads at most that much); a
    /// message larger still closes that connection with WebSocket code 1009 (the server keeps
    /// serving). Default 256 MiB.
    pub max_upload_bytes: usize,
    /// Most concurrent sessions (WebSocket connections). Default 64.
    pub max_sessions: usize,
}

impl Default for Limits {
    fn default() -> Self {
        Limits { max_text_bytes: 1 << 20, max_upload_bytes: 256 << 20, max_sessions: 64 }
    }
}

/// A symmetry group found by detection, for the structure panel.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GroupSummary {
    /// Description ("D4h (order 16): ...").
    pub name: String,
    /// Schoenflies symbol.
    pub schoenflies: String,
    /// Group order.
    pub order: usize,
    /// Largest validation residual, relative to the diagonal.
    pub max_residual: f64,
}

/// One detected (or annotated) class for the detections panel.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ClassSummary {
    /// Name (`class_j` when the file has none).
    pub name: String,
    /// Instance boxes `[min, max]`, model units.
    pub boxes: Vec<[Point3; 2]>,
    /// Vertices (points) coloured with this class.
    pub points: usize,
}

/// Replies and notifications from the server.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum ServerMessage {
    /// Sent once after connecting.
    Hello {
        /// Crate version.
        version: String,
        /// The root folder files are read from and written to.
        root: String,
        /// Size limits.
        limits: Limits,
        /// Names of the generated examples.
        examples: Vec<String>,
    },
    /// A model was opened; a [`BinaryKind::Model`] message follows.
    Model {
        /// File or example name.
        name: String,
        /// Vertices (points).
        vertices: usize,
        /// Triangles (0 for a point cloud).
        triangles: usize,
        /// Bounding box `[min, max]`.
        bbox: [Point3; 2],
        /// Bounding-box diagonal.
        diagonal: f64,
        /// The annotation that came with it, if any.
        annotation: Option<SymmetryAnnotation>,
        /// Reading notes.
        warnings: Vec<String>,
    },
    /// Progress of a long computation.
    Progress {
        /// Which computation.
        job: String,
        /// Stage name.
        stage: String,
        /// Units done.
        done: u64,
        /// Units in the stage (0: unknown).
        total: u64,
    },
    /// A long computation was cancelled.
    Cancelled {
        /// Which computation.
        job: String,
    },
    /// The current annotation changed (detected or loaded).
    Annotation {
        /// The annotation.
        annotation: SymmetryAnnotation,
        /// Groups found by detection (empty for a loaded file).
        groups: Vec<GroupSummary>,
        /// Largest residual of the annotation on the model (`check_annotation`), relative.
        max_residual: f64,
        /// Whether every symmetry fits within the annotation's tolerance.
        ok: bool,
        /// Milliseconds spent.
        ms: f64,
    },
    /// The files under the root ([`ClientMessage::ListFiles`]), relative paths, sorted.
    Files {
        /// Meshes and point clouds Motif reads (by extension).
        models: Vec<String>,
        /// JSON documents (annotations, detection results, ground truth, reports).
        json: Vec<String>,
        /// True when the listing stopped at its limit (deep or very large folders).
        truncated: bool,
    },
    /// A file was written.
    Saved {
        /// Paths written, relative to the root.
        paths: Vec<String>,
        /// What was left out and why (a deformed model's annotation beside an STL).
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        notes: Vec<String>,
    },
    /// The handle set was precomputed.
    Handles {
        /// Number of handles.
        handles: usize,
        /// Samples per handle.
        samples: Vec<usize>,
        /// Sampling size and degrees of freedom.
        total_samples: usize,
        /// Reduced degrees of freedom.
        dof: usize,
        /// Factorisation time for this handle set, ms.
        prefactor_ms: f64,
        /// Session precomputation (sampling, basis, lift), ms; 0 when reused.
        session_ms: f64,
        /// The target of each handle (rest → target): as given, kept from the previous set, or
        /// fitted to the current shape (see [`ClientMessage::SetHandles`]).
        transforms: Vec<Mat4>,
    },
    /// Measurements of the current deformation (after [`ClientMessage::Release`]).
    Deformed {
        /// Largest symmetry residual (eq. 3.2) relative to the diagonal; `None` without symmetries.
        residual: Option<f64>,
        /// The same on the rest shape.
        rest_residual: Option<f64>,
        /// Largest handle fit error relative to the diagonal.
        handle_error: f64,
        /// Last solve time, ms.
        solve_ms: f64,
    },
    /// Principal offsets found; retargeting is ready when `principal` is non-empty.
    Offsets {
        /// Principal offsets, model units, oriented along +x/+y/+z.
        principal: Vec<Point3>,
        /// Whole cells of the input along each principal offset.
        cells: Vec<usize>,
        /// The most negative steps a resize accepts along each principal offset
        /// (`RetargetSession::min_steps`), so the page's sliders stop there.
        min_steps: Vec<i32>,
        /// The repetition verdict in words.
        summary: String,
        /// Milliseconds spent (analysis and retargeting precomputation).
        ms: f64,
    },
    /// A retargeted model; a [`BinaryKind::Retargeted`] message follows.
    Retargeted {
        /// Echo of the request.
        seq: u32,
        /// Steps used.
        steps: [i32; 3],
        /// Whole cells along each principal offset of the output.
        cells: Vec<usize>,
        /// Product of `cells`.
        total_cells: usize,
        /// Output vertices.
        vertices: usize,
        /// Output triangles.
        triangles: usize,
        /// Solve time, ms.
        ms: f64,
        /// Set when no seam-consistent stitching was found (seams of infinite cost): what is
        /// wrong and how many edges the result leaves open.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        warning: Option<String>,
    },
    /// Detections to show.
    Detections {
        /// Scene name from the file.
        scene: String,
        /// Classes with boxes.
        classes: Vec<ClassSummary>,
        /// Class of each vertex / point (`-1`: none), for colouring.
        point_class: Vec<i32>,
    },
    /// Something went wrong; the session keeps working.
    Error {
        /// What and what to do.
        message: String,
        /// The request type it answers, when known.
        request: Option<String>,
    },
}

/// Builds a server binary message: header, positions, optional normals, triangles. The header's
/// `encode_ms` and `sent_at` are filled in last.
pub fn encode_binary(
    kind: BinaryKind,
    seq: u32,
    positions: &[Point3],
    normals: Option<&[Point3]>,
    triangles: &[[u32; 3]],
    timing: FrameTiming,
) -> Vec<u8> {
    let start = std::time::Instant::now();
    let n = positions.len();
    let floats = n * 3 * if normals.is_some() { 2 } else { 1 };
    let mut out = Vec::with_capacity(FRAME_HEADER_BYTES + floats * 4 + triangles.len() * 12);
    let flags = if normals.is_some() { FLAG_NORMALS } else { 0 };
    for v in [kind as u32, seq, n as u32, triangles.len() as u32] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for v in [timing.solve_ms, timing.queue_ms, 0.0] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out.extend_from_slice(&flags.to_le_bytes());
    out.extend_from_slice(&timing.received_at.to_le_bytes());
    out.extend_from_slice(&0f64.to_le_bytes());
    for p in positions.iter().chain(normals.unwrap_or(&[])) {
        for c in p {
            out.extend_from_slice(&(*c as f32).to_le_bytes());
        }
    }
    for t in triangles {
        for i in t {
            out.extend_from_slice(&i.to_le_bytes());
        }
    }
    let encode_ms = start.elapsed().as_secs_f32() * 1e3;
    out[24..28].copy_from_slice(&encode_ms.to_le_bytes());
    out[40..48].copy_from_slice(&unix_ms().to_le_bytes());
    out
}

/// Builds a [`BinaryKind::File`] message: a file for the browser to download.
pub fn encode_file(name: &str, bytes: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(FRAME_HEADER_BYTES + name.len() + bytes.len());
    for v in [BinaryKind::File as u32, 0, name.len() as u32, bytes.len() as u32] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out.resize(FRAME_HEADER_BYTES, 0);
    out.extend_from_slice(name.as_bytes());
    out.extend_from_slice(bytes);
    out
}

/// Splits an upload message into file name and bytes.
pub fn decode_upload(bytes: &[u8]) -> Option<(String, &[u8])> {
    let len = u32::from_le_bytes(bytes.get(..4)?.try_into().ok()?) as usize;
    let name = bytes.get(4..4usize.checked_add(len)?)?;
    let name = std::str::from_utf8(name).ok()?.to_string();
    Some((name, &bytes[4 + len..]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_round_trip() {
        let m: ClientMessage =
            serde_json::from_str(r#"{"type":"retarget","seq":3,"steps":[1,0,0]}"#).unwrap();
        assert_eq!(m, ClientMessage::Retarget { seq: 3, steps: [1, 0, 0] });
        assert!(serde_json::from_str::<ClientMessage>(r#"{"type":"nope"}"#).is_err());
        let timing = FrameTiming { solve_ms: 1.5, queue_ms: 0.25, received_at: 1e12 };
        let b = encode_binary(BinaryKind::Model, 7, &[[1.0, 2.0, 3.0]], None, &[[0, 0, 0]], timing);
        assert_eq!(b.len(), FRAME_HEADER_BYTES + 12 + 12);
        assert_eq!(u32::from_le_bytes(b[4..8].try_into().unwrap()), 7);
        assert_eq!(f32::from_le_bytes(b[16..20].try_into().unwrap()), 1.5);
        assert_eq!(f32::from_le_bytes(b[20..24].try_into().unwrap()), 0.25);
        assert_eq!(f64::from_le_bytes(b[32..40].try_into().unwrap()), 1e12);
        assert!(f64::from_le_bytes(b[40..48].try_into().unwrap()) > 1e12);
        let b = encode_binary(BinaryKind::DeformFrame, 1, &[[1.0; 3]], Some(&[[0.0, 0.0, 1.0]]), &[], timing);
        assert_eq!(u32::from_le_bytes(b[28..32].try_into().unwrap()), FLAG_NORMALS);
        assert_eq!(
            f32::from_le_bytes(b[FRAME_HEADER_BYTES + 20..FRAME_HEADER_BYTES + 24].try_into().unwrap()),
            1.0
        );
        let f = encode_file("a.obj", b"v 0 0 0");
        assert_eq!(u32::from_le_bytes(f[0..4].try_into().unwrap()), BinaryKind::File as u32);
        assert_eq!(&f[FRAME_HEADER_BYTES..FRAME_HEADER_BYTES + 5], b"a.obj");
        assert_eq!(&f[FRAME_HEADER_BYTES + 5..], b"v 0 0 0");
        let mut up = 3u32.to_le_bytes().to_vec();
        up.extend_from_slice(b"a.oRest");
        assert_eq!(decode_upload(&up), Some(("a.o".to_string(), &b"Rest"[..])));
        assert_eq!(decode_upload(&[255, 255, 255, 255, 1]), None);
    }
}
