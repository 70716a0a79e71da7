//! Reading and writing meshes and point clouds: OBJ, PLY (ASCII and binary), OFF, STL (ASCII
//! and binary), glTF and GLB.
//!
//! Everything a file holds comes back as a [`Model`]: vertices with whatever per-vertex data the
//! format carries (normals, 8-bit colours, named scalar attributes), triangles (polygons are
//! fan-triangulated), the number of faces as stored, and warnings about what was dropped.
//!
//! # Why the parsers are hand-written
//! OBJ, PLY, OFF and STL are parsed here rather than with tobj / ply-rs / stl_io so that every
//! error names the file and the exact position (1-based line for text, byte offset for binary),
//! so that no allocation is ever sized by a count read from the file (a count is first checked
//! against the bytes that could hold it, so a 4-billion-vertex header in a 100-byte file is
//! rejected before anything is reserved), and so that they are byte-oriented and fast (a 10 MB
//! OBJ loads in tens of milliseconds in a release build). glTF uses the `gltf` crate for the JSON
//! document; the GLB container, buffers and accessors are read by hand with bounds checks.
//!
//! # Conventions
//! - Text files must be UTF-8 (in practice ASCII) outside comments; other bytes are an error
//!   with their line.
//! - Coordinates must be finite; NaN or infinity is an error with its position.
//! - Faces with fewer than 3 distinct vertices are dropped with a warning in
//!   [`Model::warnings`]; a file whose faces are all degenerate is an error.
//! - A file with no vertices is an error.
//! - Writers never leave a half-written file behind: see [`write_atomic`].
//! - What a format cannot hold is not written (OBJ and OFF have no named attributes, STL keeps
//!   triangles only, glTF stores f32 positions); PLY holds everything a [`Model`] has, with f64
//!   positions, so PLY round trips are exact.

mod atomic;
mod common;
mod gltf;
mod image;
mod obj;
mod off;
mod ply;
mod stl;

use std::path::Path;

use serde::{Deserialize, Serialize};

pub use atomic::{
    check_writable, commit_deferred, defer_renames, discard_deferred, remove_temporary_files_and,
    write_atomic,
};
pub use image::write_png_rgb;

use crate::error::Position;
use crate::{Error, PointCloud, Result, TriMesh};

/// A file format Motif reads and writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Format {
    /// Wavefront OBJ (text).
    Obj,
    /// Stanford PLY (ASCII or binary).
    Ply,
    /// Geomview OFF (text).
    Off,
    /// STL (ASCII or binary).
    Stl,
    /// glTF 2.0 JSON with embedded or external buffers.
    Gltf,
    /// Binary glTF 2.0.
    Glb,
}

impl Format {
    /// The format named by a path's extension (case-insensitive).
    pub fn from_path(path: &Path) -> Result<Format> {
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
        Ok(match ext.as_str() {
            "obj" => Format::Obj,
            "ply" => Format::Ply,
            "off" => Format::Off,
            "stl" => Format::Stl,
            "gltf" => Format::Gltf,
            "glb" => Format::Glb,
            _ => {
                return Err(Error::UnsupportedFormat {
                    path: path.to_path_buf(),
                    extension: path.extension().map(|e| e.to_string_lossy().into_owned()).unwrap_or_default(),
                });
            }
        })
    }

    /// The usual file extension, without the dot.
    pub fn extension(self) -> &'static str {
        match self {
            Format::Obj => "obj",
            Format::Ply => "ply",
            Format::Off => "off",
            Format::Stl => "stl",
            Format::Gltf => "gltf",
            Format::Glb => "glb",
        }
    }

    /// Guesses a format from the first bytes of a file (used for helpful error messages).
    fn sniff(bytes: &[u8]) -> Option<Format> {
        let head = &bytes[..bytes.len().min(512)];
        let trimmed = head.trim_ascii_start();
        if head.starts_with(b"glTF") {
            Some(Format::Glb)
        } else if head.starts_with(b"ply\n") || head.starts_with(b"ply\r\n") {
            Some(Format::Ply)
        } else if trimmed.starts_with(b"{") {
            Some(Format::Gltf)
        } else if ["OFF", "COFF", "NOFF", "CNOFF"].iter().any(|h| {
            trimmed.starts_with(h.as_bytes())
                && trimmed.get(h.len()).is_none_or(|b| b.is_ascii_whitespace() || *b == b'#')
        }) {
            Some(Format::Off)
        } else if trimmed.starts_with(b"solid") {
            Some(Format::Stl)
        } else if common::Lines::new(head).any(|(_, l)| {
            let l = l.trim_ascii_start();
            l.starts_with(b"v ") || l.starts_with(b"vn ") || l.starts_with(b"f ")
        }) {
            Some(Format::Obj)
        } else {
            None
        }
    }
}

impl std::fmt::Display for Format {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Format::Obj => "OBJ",
            Format::Ply => "PLY",
            Format::Off => "OFF",
            Format::Stl => "STL",
            Format::Gltf => "glTF",
            Format::Glb => "GLB",
        })
    }
}

/// What a mesh or point-cloud file holds.
#[derive(Debug, Clone, PartialEq)]
pub struct Model {
    /// Positions, plus normals, colours and named scalar attributes when the file has them.
    pub vertices: PointCloud,
    /// Triangles (polygons triangulated: convex ones as a fan, concave ones by ear clipping; degenerate faces dropped); empty for point clouds.
    pub triangles: Vec<[u32; 3]>,
    /// Faces as stored in the file, before triangulation and before dropping degenerate faces
    /// (an OBJ quad counts 1; an STL facet counts 1).
    pub source_faces: usize,
    /// The format the model was read from ([`Format::Ply`], Motif's native format, for models
    /// built in memory).
    pub format: Format,
    /// What was dropped or repaired while reading, in words (e.g. "dropped 3 degenerate faces").
    pub warnings: Vec<String>,
}

impl Model {
    /// The triangle mesh (positions and triangles; per-vertex data is left out).
    pub fn mesh(&self) -> TriMesh {
        TriMesh { positions: self.vertices.positions.clone(), triangles: self.triangles.clone() }
    }

    /// The triangle mesh, without copying.
    pub fn into_mesh(self) -> TriMesh {
        TriMesh { positions: self.vertices.positions, triangles: self.triangles }
    }

    /// True when the model has at least one triangle.
    pub fn is_mesh(&self) -> bool {
        !self.triangles.is_empty()
    }

    /// A model holding a mesh (no per-vertex data).
    pub fn from_mesh(mesh: &TriMesh) -> Model {
        Model {
            vertices: PointCloud::from_positions(mesh.positions.clone()),
            triangles: mesh.triangles.clone(),
            source_faces: mesh.triangles.len(),
            format: Format::Ply,
            warnings: Vec::new(),
        }
    }

    /// A model holding a point cloud (no triangles).
    pub fn from_point_cloud(cloud: PointCloud) -> Model {
        Model {
            vertices: cloud,
            triangles: Vec::new(),
            source_faces: 0,
            format: Format::Ply,
            warnings: Vec::new(),
        }
    }
}

/// Reads a mesh or point cloud; the format is taken from the extension and checked against the
/// content.
pub fn read(path: &Path) -> Result<Model> {
    if path.is_dir() {
        let e = std::io::Error::new(
            std::io::ErrorKind::IsADirectory,
            "a directory, not a mesh or point cloud file",
        );
        return Err(Error::io(path, e));
    }
    let format = Format::from_path(path)?;
    // A device (`/dev/zero`) may never end: reading one grew to 7.5 GB of memory. A named pipe
    // (`<(cmd)`) ends when its writer does, and is read.
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if let Ok(t) = std::fs::metadata(path).map(|m| m.file_type())
            && (t.is_char_device() || t.is_block_device() || t.is_socket())
        {
            return Err(Error::InvalidInput(format!(
                "{}: a device or socket, not a file: save the data to a file first",
                path.display()
            )));
        }
    }
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    read_impl(&bytes, format, path, Some(dir))
}

/// Reads a model from memory (e.g. an upload); `name` is used in error messages only. glTF
/// files that refer to external `.bin` files cannot be read this way (nothing is read from
/// disk): use GLB or embedded buffers.
pub fn read_from_bytes(bytes: &[u8], format: Format, name: &Path) -> Result<Model> {
    read_impl(bytes, format, name, None)
}

fn read_impl(bytes: &[u8], format: Format, path: &Path, base_dir: Option<&Path>) -> Result<Model> {
    if bytes.is_empty() {
        return Err(common::perr(
            path,
            Position::Whole,
            format!("the file is empty (expected {format} data)"),
        ));
    }
    let result = match format {
        Format::Obj => obj::read(bytes, path),
        Format::Ply => ply::read(bytes, path),
        Format::Off => off::read(bytes, path),
        Format::Stl => stl::read(bytes, path),
        Format::Gltf | Format::Glb => gltf::read(bytes, path, format, base_dir),
    };
    let model = result.map_err(|e| add_format_hint(e, bytes, format))?;
    if model.vertices.is_empty() {
        return Err(common::perr(path, Position::Whole, "the file contains no vertices"));
    }
    if let Some(message) = coordinate_range_problem(&model.vertices.positions) {
        return Err(common::perr(path, Position::Whole, message));
    }
    debug_assert!(validate_parts(&model.vertices, &model.triangles).is_ok());
    Ok(model)
}

/// Largest coordinate magnitude accepted on reading, in model units.
///
/// Motif's geometry works in f64 on squared distances and, in curvature and SHOT, on their
/// products: on the generated shelf scaled by 10⁸⁰ or 10⁻⁸⁰ these overflow or underflow, and
/// `motif retarget` welds vertices it should not (8 edges of four triangles), silently; at 10⁶⁰
/// and 10⁻⁶⁰ its output is the same as at 1. The bounds leave 20 orders of magnitude to that, and
/// any real unit (nanometres to light years, in metres) far inside.
pub const MAX_COORDINATE: f64 = 1e40;

/// Smallest extent (largest side of the bounding box) accepted on reading, in model units, for
/// a model that is not a single point (see [`MAX_COORDINATE`]).
pub const MIN_EXTENT: f64 = 1e-40;

/// Why the model's coordinates are outside the range Motif computes in reliably, if they are.
pub fn coordinate_range_problem(positions: &[crate::geometry::Point3]) -> Option<String> {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for (i, p) in positions.iter().enumerate() {
        if let Some(c) = p.iter().find(|c| c.abs() > MAX_COORDINATE) {
            return Some(format!(
                "vertex {i} has the coordinate {c:e}, beyond ±{MAX_COORDINATE:e}: distances squared \
                 overflow there; rescale the model (into metres or millimetres, say)"
            ));
        }
        for d in 0..3 {
            lo[d] = lo[d].min(p[d]);
            hi[d] = hi[d].max(p[d]);
        }
    }
    let extent = (0..3).map(|d| hi[d] - lo[d]).fold(0.0, f64::max);
    (extent > 0.0 && extent < MIN_EXTENT).then(|| {
        format!(
            "the model is {extent:e} across, below {MIN_EXTENT:e}: distances squared underflow \
             there; rescale the model (into metres or millimetres, say)"
        )
    })
}

/// When a file fails to parse and its content looks like another format, says so.
fn add_format_hint(e: Error, bytes: &[u8], format: Format) -> Error {
    match e {
        Error::Parse { path, position, message } => {
            let hint = match Format::sniff(bytes) {
                Some(other)
                    if other != format
                        && !(matches!(other, Format::Gltf | Format::Glb)
                            && matches!(format, Format::Gltf | Format::Glb)) =>
                {
                    format!(" (the content looks like {other}; is the extension wrong?)")
                }
                _ => String::new(),
            };
            Error::Parse { path, position, message: message + &hint }
        }
        e => e,
    }
}

/// Reads a triangle mesh; a file without faces is an error naming the file.
pub fn read_mesh(path: &Path) -> Result<TriMesh> {
    read_mesh_from(read(path)?, path)
}

/// The mesh of a model read from `path`, or the error [`read_mesh`] gives when it has no faces.
pub fn read_mesh_from(model: Model, path: &Path) -> Result<TriMesh> {
    if !model.is_mesh() {
        return Err(Error::InvalidInput(format!(
            "{}: has {} but no faces; a triangle mesh is needed here",
            path.display(),
            if model.vertices.len() == 1 {
                "1 vertex".to_string()
            } else {
                format!("{} vertices", model.vertices.len())
            }
        )));
    }
    Ok(model.into_mesh())
}

/// Reads a point cloud: the points of a point-cloud file, or the vertices of a mesh (with their
/// normals, colours and attributes when the file has them).
pub fn read_point_cloud(path: &Path) -> Result<PointCloud> {
    Ok(read(path)?.vertices)
}

/// Encoding of written PLY files.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PlyEncoding {
    /// Human-readable text.
    Ascii,
    /// Binary, little-endian (what almost every tool writes).
    #[default]
    BinaryLittleEndian,
    /// Binary, big-endian.
    BinaryBigEndian,
}

/// Encoding of written STL files.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StlEncoding {
    /// Binary (50 bytes per triangle, f32 coordinates).
    #[default]
    Binary,
    /// Text.
    Ascii,
}

/// Options of [`write()`].
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct WriteOptions {
    /// Encoding of `.ply` files; default binary little-endian.
    pub ply: PlyEncoding,
    /// Encoding of `.stl` files; default binary.
    pub stl: StlEncoding,
}

/// Writes a model in the format named by the path's extension, atomically (see
/// [`write_atomic`]). Positions are written with full f64 precision to PLY (exact round trip),
/// OBJ and OFF (shortest exact decimal), and as f32 to STL and glTF. What a format cannot hold is
/// left out: named attributes in OBJ/OFF/STL/glTF, normals and colours in STL.
///
/// Errors: [`Error::UnsupportedFormat`] for an unknown extension, [`Error::InvalidInput`] for an
/// inconsistent model or one the format cannot store (a point cloud as STL, an integer
/// attribute beyond 32 bits as PLY), [`Error::Io`] when the file cannot be written.
pub fn write(path: &Path, model: &Model, options: &WriteOptions) -> Result<()> {
    write_parts(path, &model.vertices, &model.triangles, options)
}

/// What writing `cloud` as `format` leaves out, in words (empty when the format holds it all):
/// only PLY holds named per-vertex attributes, and STL holds neither vertex normals nor colours.
/// `motif convert` says so rather than drop them silently.
pub fn lost_in(format: Format, cloud: &PointCloud) -> Vec<String> {
    let mut lost = Vec::new();
    if format != Format::Ply && !cloud.attributes.is_empty() {
        let names: Vec<&str> = cloud.attributes.iter().map(|a| a.name.as_str()).collect();
        lost.push(format!("the per-vertex attributes {} (only PLY holds them)", names.join(", ")));
    }
    if format == Format::Stl {
        if cloud.normals.is_some() {
            lost.push("the vertex normals (STL keeps facet normals only, computed from the corners)".into());
        }
        if cloud.colors.is_some() {
            lost.push("the vertex colours (STL holds none)".into());
        }
    }
    lost
}

/// [`write`] on borrowed parts, so writing a point cloud or mesh copies nothing large.
fn write_parts(
    path: &Path,
    cloud: &PointCloud,
    triangles: &[[u32; 3]],
    options: &WriteOptions,
) -> Result<()> {
    let format = Format::from_path(path)?;
    validate_parts(cloud, triangles)?;
    match format {
        Format::Obj => write_atomic(path, |w| obj::write(w, cloud, triangles)),
        Format::Off => write_atomic(path, |w| off::write(w, cloud, triangles)),
        Format::Ply => {
            let header = ply::header(cloud, triangles, options.ply)?;
            write_atomic(path, |w| ply::write(w, cloud, triangles, &header, options.ply))
        }
        Format::Stl => {
            stl::check(triangles, &cloud.positions, options.stl)?;
            write_atomic(path, |w| stl::write(w, cloud, triangles, options.stl))
        }
        Format::Gltf | Format::Glb => {
            let bytes = gltf::to_bytes(cloud, triangles, format)?;
            write_atomic(path, |w| w.write_all(&bytes))
        }
    }
}

/// Checks what the writers rely on: per-vertex data of the right length, finite positions,
/// indices in range.
fn validate_parts(cloud: &PointCloud, triangles: &[[u32; 3]]) -> Result<()> {
    cloud.validate()?;
    let n = cloud.len() as u64;
    if n > u32::MAX as u64 {
        return Err(Error::InvalidInput(format!("{n} vertices cannot be indexed with u32")));
    }
    for (f, t) in triangles.iter().enumerate() {
        if let Some(&bad) = t.iter().find(|&&i| i as u64 >= n) {
            return Err(Error::InvalidInput(format!(
                "triangle {f} refers to vertex {bad}, but there are only {n} vertices"
            )));
        }
    }
    Ok(())
}

/// Writes a triangle mesh (format by extension, default options).
pub fn write_mesh(path: &Path, mesh: &TriMesh) -> Result<()> {
    let cloud = PointCloud::from_positions(mesh.positions.clone());
    write_parts(path, &cloud, &mesh.triangles, &WriteOptions::default())
}

/// Writes a point cloud with its normals, colours and attributes where the format can hold them
/// (format by extension, default options). STL cannot hold a point cloud.
pub fn write_point_cloud(path: &Path, cloud: &PointCloud) -> Result<()> {
    write_parts(path, cloud, &[], &WriteOptions::default())
}
