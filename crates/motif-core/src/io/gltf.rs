//! glTF 2.0 and GLB. The `gltf` crate parses and validates the JSON document; the GLB container,
//! the buffers (GLB `BIN` chunk, `data:` base64 URIs, external files next to the `.gltf`) and the
//! accessors are read here, with every offset checked against the bytes present.
//!
//! All mesh primitives of all nodes of the default scene (else scene 0, else every root node)
//! are read, with each node's world transform (the whole parent chain, TRS or matrix) applied to
//! positions, its inverse transpose to normals, and the winding flipped under mirroring
//! transforms. Modes: triangles, triangle strips and fans; points give vertices only; lines are
//! skipped with a warning. Sparse accessors are rejected. Colours (`COLOR_0`) are kept as 8-bit
//! values without colour-space conversion.

use std::borrow::Cow;
use std::path::{Component, Path, PathBuf};

use ::gltf::accessor::{DataType, Dimensions};
use ::gltf::buffer::Source;
use ::gltf::json;
use ::gltf::mesh::Mode;
use ::gltf::scene::Transform;
use ::gltf::{Accessor, Semantic};
use base64::Engine;

use super::common::{FaceSink, perr, unit_to_u8};
use super::{Format, Model};
use crate::error::Position;
use crate::geometry::{IDENTITY4, Mat4, Point3, is_finite, mat4_mul, normalize, transform_point};
use crate::{Error, PointCloud, Result};

/// Where the parts of a GLB are.
struct Container<'a> {
    json: &'a [u8],
    /// File offset of the JSON chunk's data.
    json_offset: u64,
    /// The BIN chunk's data and its file offset.
    bin: Option<(&'a [u8], u64)>,
}

/// A resolved buffer; `file_offset` is set when its bytes are part of the file being read (GLB
/// BIN chunk), so errors can give a byte offset in that file.
struct Buffer<'a> {
    data: Cow<'a, [u8]>,
    file_offset: Option<u64>,
}

pub(super) fn read(bytes: &[u8], path: &Path, format: Format, base_dir: Option<&Path>) -> Result<Model> {
    let container = if bytes.starts_with(b"glTF") {
        split_glb(bytes, path)?
    } else if format == Format::Glb {
        return Err(perr(
            path,
            Position::Byte(0),
            format!(
                "not a GLB file: expected the magic \"glTF\", found {}",
                super::common::show(&bytes[..bytes.len().min(4)])
            ),
        ));
    } else {
        Container { json: bytes, json_offset: 0, bin: None }
    };
    let in_glb = bytes.starts_with(b"glTF");
    let doc =
        parse_document(container.json).map_err(|e| json_error(path, e, in_glb, container.json_offset))?;

    // glTF 2.0, 5.1: a loader must not load an asset of a major version it does not know.
    let version = &doc.as_json().asset.version;
    if version.split('.').next() != Some("2") {
        return Err(perr(
            path,
            Position::Whole,
            format!("glTF version {version:?} is not supported (Motif reads glTF 2.x)"),
        ));
    }
    let mut warnings = Vec::new();
    for ext in doc.extensions_required() {
        if ext == "KHR_draco_mesh_compression" || ext == "EXT_meshopt_compression" {
            return Err(perr(
                path,
                Position::Whole,
                format!("the file requires the compression extension {ext}, which Motif does not read"),
            ));
        }
        warnings.push(format!("ignored the required extension {ext}"));
    }

    let buffers =
        doc.buffers().map(|b| resolve_buffer(&b, &container, path, base_dir)).collect::<Result<Vec<_>>>()?;
    let reader = Reader { path, buffers };

    // Roots: the default scene, else scene 0, else every node that is nobody's child.
    let roots: Vec<::gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(scene) => scene.nodes().collect(),
        None => {
            let mut child = vec![false; doc.nodes().len()];
            for n in doc.nodes() {
                for c in n.children() {
                    child[c.index()] = true;
                }
            }
            doc.nodes().filter(|n| !child[n.index()]).collect()
        }
    };

    let mut out = Assembly::default();
    let mut visited = vec![false; doc.nodes().len()];
    let mut stack: Vec<(::gltf::Node, Mat4)> = roots.into_iter().rev().map(|n| (n, IDENTITY4)).collect();
    while let Some((node, parent)) = stack.pop() {
        if std::mem::replace(&mut visited[node.index()], true) {
            return Err(perr(
                path,
                Position::Whole,
                format!("node {} is reached twice: the node hierarchy must be a tree", node.index()),
            ));
        }
        let world = mat4_mul(&parent, &local_transform(&node, path)?);
        if let Some(mesh) = node.mesh() {
            if node.skin().is_some() {
                out.skinned = true;
            }
            for (pi, prim) in mesh.primitives().enumerate() {
                reader.primitive(
                    &prim,
                    &format!("mesh {} primitive {pi}", mesh.index()),
                    &world,
                    &mut out,
                )?;
            }
        }
        stack.extend(node.children().collect::<Vec<_>>().into_iter().rev().map(|c| (c, world)));
    }
    out.finish(path, format, warnings)
}

/// Splits a GLB into its JSON and BIN chunks, checking every length.
fn split_glb<'a>(bytes: &'a [u8], path: &Path) -> Result<Container<'a>> {
    let u32_at = |o: usize| bytes.get(o..o + 4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]));
    let (Some(version), Some(length)) = (u32_at(4), u32_at(8)) else {
        return Err(perr(
            path,
            Position::Byte(bytes.len() as u64),
            "truncated GLB header (12 bytes are needed)",
        ));
    };
    if version != 2 {
        return Err(perr(
            path,
            Position::Byte(4),
            format!("GLB version {version} is not supported (only 2)"),
        ));
    }
    if length as usize > bytes.len() {
        return Err(perr(
            path,
            Position::Byte(8),
            format!(
                "the GLB header gives a length of {length} bytes, but the file has {} (truncated?)",
                bytes.len()
            ),
        ));
    }
    let end = length as usize;
    let mut offset = 12usize;
    let mut json = None;
    let mut bin = None;
    while offset < end {
        let (Some(len), Some(kind)) = (u32_at(offset), bytes.get(offset + 4..offset + 8)) else {
            return Err(perr(path, Position::Byte(offset as u64), "truncated GLB chunk header"));
        };
        let start = offset + 8;
        let stop = start.checked_add(len as usize).filter(|&s| s <= end).ok_or_else(|| {
            perr(
                path,
                Position::Byte(offset as u64),
                format!("a GLB chunk of {len} bytes runs past the end of the file ({end} bytes)"),
            )
        })?;
        let data = &bytes[start..stop];
        match kind {
            b"JSON" if json.is_none() => json = Some((data, start as u64)),
            b"BIN\0" if bin.is_none() && json.is_some() => bin = Some((data, start as u64)),
            b"JSON" | b"BIN\0" => {
                return Err(perr(path, Position::Byte(offset as u64), "unexpected or repeated GLB chunk"));
            }
            // Unknown chunks must be ignored (glTF 2.0 specification, GLB chunks).
            _ => {}
        }
        offset = stop.next_multiple_of(4);
    }
    let Some((json, json_offset)) = json else {
        return Err(perr(path, Position::Byte(12), "the GLB has no JSON chunk"));
    };
    Ok(Container { json, json_offset, bin })
}

/// Parses and validates the JSON document. This is `gltf::Gltf::from_slice` except that missing
/// POSITION `min`/`max` bounds, which Motif does not use and some exporters omit, are tolerated;
/// every other validation error (indices out of range, invalid enum values, ...) still rejects
/// the file, which the `gltf` accessors rely on not to panic.
fn parse_document(json_bytes: &[u8]) -> std::result::Result<::gltf::Document, ::gltf::Error> {
    use json::validation::{Error as V, Validate};
    let root: json::Root = json::deserialize::from_slice(json_bytes)?;
    // gltf-json 1.4's validation indexes the accessor of every POSITION attribute before checking
    // that it exists (it panics on an index out of range), so that index is checked first.
    let mut errors = Vec::new();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (k, primitive) in mesh.primitives.iter().enumerate() {
            let position =
                primitive.attributes.get(&json::validation::Checked::Valid(json::mesh::Semantic::Positions));
            if position.is_some_and(|i| i.value() >= root.accessors.len()) {
                errors.push((
                    json::Path::new()
                        .field("meshes")
                        .index(m)
                        .field("primitives")
                        .index(k)
                        .field("attributes")
                        .key("POSITION"),
                    V::IndexOutOfBounds,
                ));
            }
        }
    }
    if !errors.is_empty() {
        return Err(::gltf::Error::Validation(errors));
    }
    root.validate(&root, json::Path::new, &mut |p, e| {
        let p = p();
        let bounds = p.as_str().ends_with(".min") || p.as_str().ends_with(".max");
        if !(bounds && matches!(e, V::Missing)) {
            errors.push((p, e));
        }
    });
    if !errors.is_empty() {
        return Err(::gltf::Error::Validation(errors));
    }
    Ok(::gltf::Document::from_json_without_validation(root))
}

fn json_error(path: &Path, e: ::gltf::Error, in_glb: bool, json_offset: u64) -> Error {
    match e {
        ::gltf::Error::Deserialize(e) if in_glb => perr(
            path,
            Position::Byte(json_offset),
            format!("invalid JSON in the GLB JSON chunk (line {}, column {}): {e}", e.line(), e.column()),
        ),
        ::gltf::Error::Deserialize(e) => {
            perr(path, Position::Line(e.line().max(1)), format!("invalid glTF JSON: {e}"))
        }
        ::gltf::Error::Validation(errors) => {
            let list: Vec<String> = errors.iter().take(3).map(|(p, e)| format!("{p}: {e}")).collect();
            let more =
                if errors.len() > 3 { format!(" and {} more", errors.len() - 3) } else { String::new() };
            let pos = if in_glb { Position::Byte(json_offset) } else { Position::Whole };
            perr(path, pos, format!("invalid glTF document: {}{more}", list.join("; ")))
        }
        e => perr(path, Position::Whole, format!("invalid glTF: {e}")),
    }
}

fn resolve_buffer<'a>(
    b: &::gltf::Buffer<'_>,
    container: &Container<'a>,
    path: &Path,
    base_dir: Option<&Path>,
) -> Result<Buffer<'a>> {
    let i = b.index();
    let buffer = match b.source() {
        Source::Bin => {
            let Some((data, off)) = container.bin else {
                return Err(perr(
                    path,
                    Position::Whole,
                    format!("buffer {i} refers to the GLB BIN chunk, but there is none"),
                ));
            };
            Buffer { data: Cow::Borrowed(data), file_offset: Some(off) }
        }
        Source::Uri(uri) if uri.starts_with("data:") => {
            let Some(comma) = uri.find(',') else {
                return Err(perr(path, Position::Whole, format!("buffer {i}: malformed data URI")));
            };
            if !uri[..comma].ends_with(";base64") {
                return Err(perr(
                    path,
                    Position::Whole,
                    format!("buffer {i}: only base64 data URIs are supported"),
                ));
            }
            let data = base64::engine::general_purpose::STANDARD.decode(&uri[comma + 1..]).map_err(|e| {
                perr(path, Position::Whole, format!("buffer {i}: bad base64 in its data URI: {e}"))
            })?;
            Buffer { data: Cow::Owned(data), file_offset: None }
        }
        Source::Uri(uri) => {
            let Some(base) = base_dir else {
                return Err(perr(
                    path,
                    Position::Whole,
                    format!(
                        "buffer {i} is the external file {uri:?}, which cannot be read here; \
                         use a .glb or a .gltf with embedded buffers"
                    ),
                ));
            };
            let file = external_path(base, uri)
                .map_err(|m| perr(path, Position::Whole, format!("buffer {i}: {m}")))?;
            let data = std::fs::read(&file).map_err(|e| {
                perr(path, Position::Whole, format!("buffer {i}: cannot read {}: {e}", file.display()))
            })?;
            Buffer { data: Cow::Owned(data), file_offset: None }
        }
    };
    if b.length() > buffer.data.len() {
        return Err(perr(
            path,
            Position::Whole,
            format!("buffer {i} declares {} bytes, but only {} are present", b.length(), buffer.data.len()),
        ));
    }
    Ok(buffer)
}

/// The file an external buffer URI names, which must stay inside the `.gltf` file's directory.
fn external_path(base: &Path, uri: &str) -> std::result::Result<PathBuf, String> {
    if uri.contains("://") || uri.contains(':') {
        return Err(format!("{uri:?} is not a relative file reference"));
    }
    let decoded = percent_decode(uri).ok_or_else(|| format!("{uri:?} has a malformed %-escape"))?;
    let rel = Path::new(&decoded);
    if !rel.components().all(|c| matches!(c, Component::Normal(_) | Component::CurDir)) {
        return Err(format!("{uri:?} leaves the directory of the glTF file, which is not allowed"));
    }
    let full = base.join(rel);
    // Symbolic links must not lead out either.
    if let (Ok(b), Ok(f)) = (base.canonicalize(), full.canonicalize()) {
        if !f.starts_with(&b) {
            return Err(format!("{uri:?} resolves outside the directory of the glTF file"));
        }
    }
    Ok(full)
}

fn percent_decode(s: &str) -> Option<String> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' {
            let hex = std::str::from_utf8(b.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

/// A node's local transform as a row-major matrix acting on column vectors.
fn local_transform(node: &::gltf::Node, path: &Path) -> Result<Mat4> {
    let m = match node.transform() {
        Transform::Matrix { matrix } => {
            // glTF stores column-major: matrix[column][row].
            let mut m = [[0.0; 4]; 4];
            for (c, col) in matrix.iter().enumerate() {
                for (r, v) in col.iter().enumerate() {
                    m[r][c] = *v as f64;
                }
            }
            m
        }
        Transform::Decomposed { translation: t, rotation: q, scale: s } => {
            let [x, y, z, w] = q.map(|v| v as f64);
            let n = (x * x + y * y + z * z + w * w).sqrt();
            let (x, y, z, w) = if n > 0.0 { (x / n, y / n, z / n, w / n) } else { (0.0, 0.0, 0.0, 1.0) };
            let r = [
                [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - z * w), 2.0 * (x * z + y * w)],
                [2.0 * (x * y + z * w), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - x * w)],
                [2.0 * (x * z - y * w), 2.0 * (y * z + x * w), 1.0 - 2.0 * (x * x + y * y)],
            ];
            let mut m = IDENTITY4;
            for i in 0..3 {
                for j in 0..3 {
                    m[i][j] = r[i][j] * s[j] as f64;
                }
                m[i][3] = t[i] as f64;
            }
            m
        }
    };
    if !m.iter().flatten().all(|v| v.is_finite()) {
        return Err(perr(
            path,
            Position::Whole,
            format!("node {} has a NaN or infinite transform", node.index()),
        ));
    }
    Ok(m)
}

/// The cofactor matrix of the upper-left 3×3 block: the inverse transpose times the determinant.
fn cofactor3(m: &Mat4) -> ([[f64; 3]; 3], f64) {
    let a = |i: usize, j: usize| m[i][j];
    let mut c = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            let (i1, i2) = ((i + 1) % 3, (i + 2) % 3);
            let (j1, j2) = ((j + 1) % 3, (j + 2) % 3);
            c[i][j] = a(i1, j1) * a(i2, j2) - a(i1, j2) * a(i2, j1);
        }
    }
    let det = (0..3).map(|j| a(0, j) * c[0][j]).sum();
    (c, det)
}

/// Model data gathered over all primitives.
#[derive(Default)]
struct Assembly {
    positions: Vec<Point3>,
    /// `None` once a primitive without normals was seen.
    normals: Option<Vec<Point3>>,
    colors: Option<Vec<[u8; 3]>>,
    missing_normals: bool,
    missing_colors: bool,
    /// Some primitive has normals / colours (dropping them is then worth a warning).
    any_normals: bool,
    any_colors: bool,
    faces: FaceSink,
    skipped_lines: usize,
    dropped_indices: usize,
    skinned: bool,
}

impl Assembly {
    fn finish(self, path: &Path, format: Format, mut warnings: Vec<String>) -> Result<Model> {
        let (triangles, source_faces) = self.faces.finish(path, &self.positions, &mut warnings)?;
        if self.skipped_lines > 0 {
            warnings.push(format!("skipped {} line primitives", self.skipped_lines));
        }
        if self.dropped_indices > 0 {
            warnings.push(format!(
                "ignored {} trailing indices that form no whole triangle",
                self.dropped_indices
            ));
        }
        if self.missing_normals && self.any_normals {
            warnings.push("dropped normals: some primitives have none".to_string());
        }
        if self.missing_colors && self.any_colors {
            warnings.push("dropped colours: some primitives have none".to_string());
        }
        if self.skinned {
            warnings.push("skinned meshes were read in their bind pose".to_string());
        }
        let vertices = PointCloud {
            normals: if self.missing_normals { None } else { self.normals },
            colors: if self.missing_colors { None } else { self.colors },
            positions: self.positions,
            attributes: Vec::new(),
        };
        Ok(Model { vertices, triangles, source_faces, format, warnings })
    }
}

/// Reads accessors out of the resolved buffers.
struct Reader<'a, 'p> {
    path: &'p Path,
    buffers: Vec<Buffer<'a>>,
}

/// An accessor's bytes: element `i` starts at `data[i * stride..]`.
struct Span<'b> {
    data: &'b [u8],
    stride: usize,
    count: usize,
    /// File offset of `data[0]` when the bytes are in the file read.
    file_offset: Option<u64>,
}

impl Span<'_> {
    fn position(&self, element: usize) -> Position {
        self.file_offset.map_or(Position::Whole, |o| Position::Byte(o + (element * self.stride) as u64))
    }
}

impl Reader<'_, '_> {
    /// Locates an accessor's bytes, checking every offset against the buffer view and buffer.
    fn span(&self, acc: &Accessor, what: &str) -> Result<Span<'_>> {
        let path = self.path;
        let i = acc.index();
        if acc.sparse().is_some() {
            return Err(perr(
                path,
                Position::Whole,
                format!("accessor {i} ({what}) is sparse, which Motif does not read"),
            ));
        }
        let Some(view) = acc.view() else {
            return Err(perr(path, Position::Whole, format!("accessor {i} ({what}) has no bufferView")));
        };
        let buffer = &self.buffers[view.buffer().index()];
        let data: &[u8] = &buffer.data;
        let at = |o: u64| buffer.file_offset.map_or(Position::Whole, |f| Position::Byte(f + o));
        let (vo, vl) = (view.offset() as u64, view.length() as u64);
        if vo.checked_add(vl).is_none_or(|e| e > data.len() as u64) {
            return Err(perr(
                path,
                at(vo.min(data.len() as u64)),
                format!(
                    "buffer view {} (bytes {vo}..{}) runs past the end of buffer {} ({} bytes)",
                    view.index(),
                    vo.saturating_add(vl),
                    view.buffer().index(),
                    data.len()
                ),
            ));
        }
        let elem = acc.size();
        let stride = view.stride().unwrap_or(elem);
        if stride < elem {
            return Err(perr(
                path,
                at(vo),
                format!(
                    "buffer view {} has a byteStride of {stride}, less than the {elem}-byte elements of accessor {i}",
                    view.index()
                ),
            ));
        }
        let count = acc.count();
        let ao = acc.offset() as u64;
        let need = if count == 0 {
            Some(0)
        } else {
            (count as u64 - 1).checked_mul(stride as u64).and_then(|s| s.checked_add(elem as u64 + ao))
        };
        if need.is_none_or(|n| n > vl) {
            return Err(perr(
                path,
                at(vo + ao.min(vl)),
                format!(
                    "accessor {i} ({what}) needs {} bytes of buffer view {} from offset {ao}, but the view has {vl} \
                     (count {count}, stride {stride})",
                    need.map_or_else(|| "more than 2^64".to_string(), |n| (n - ao).to_string()),
                    view.index()
                ),
            ));
        }
        let start = (vo + ao) as usize;
        let len = need.unwrap_or(0).saturating_sub(ao) as usize;
        Ok(Span {
            data: &data[start..start + len],
            stride,
            count,
            file_offset: buffer.file_offset.map(|f| f + vo + ao),
        })
    }

    /// Reads a float-valued accessor of one of the `dims` (normalised integers allowed),
    /// returning the values and the component count.
    fn floats(&self, acc: &Accessor, what: &str, dims: &[Dimensions]) -> Result<(Vec<f64>, usize, Span<'_>)> {
        let d = acc.dimensions();
        if !dims.contains(&d) {
            return Err(perr(
                self.path,
                Position::Whole,
                format!("accessor {} ({what}) has type {d:?}, expected one of {dims:?}", acc.index()),
            ));
        }
        let k = d.multiplicity();
        let span = self.span(acc, what)?;
        let ty = acc.data_type();
        let (size, norm) = (ty.size(), acc.normalized());
        let mut out = Vec::with_capacity(span.count * k);
        for e in 0..span.count {
            let base = e * span.stride;
            for c in 0..k {
                out.push(component(ty, &span.data[base + c * size..], norm));
            }
        }
        Ok((out, k, span))
    }

    fn indices(&self, acc: &Accessor, what: &str, vertices: usize) -> Result<Vec<u32>> {
        let ty = acc.data_type();
        if acc.dimensions() != Dimensions::Scalar
            || !matches!(ty, DataType::U8 | DataType::U16 | DataType::U32)
        {
            return Err(perr(
                self.path,
                Position::Whole,
                format!("accessor {} ({what}) must be unsigned integer scalars", acc.index()),
            ));
        }
        let span = self.span(acc, what)?;
        let mut out = Vec::with_capacity(span.count);
        for e in 0..span.count {
            let v = component(ty, &span.data[e * span.stride..], false) as u64;
            if v >= vertices as u64 {
                return Err(perr(
                    self.path,
                    span.position(e),
                    format!(
                        "index {e} of accessor {} ({what}) is {v}, but there are {vertices} vertices",
                        acc.index()
                    ),
                ));
            }
            out.push(v as u32);
        }
        Ok(out)
    }

    fn primitive(
        &self,
        prim: &::gltf::Primitive,
        what: &str,
        world: &Mat4,
        out: &mut Assembly,
    ) -> Result<()> {
        let mode = prim.mode();
        if matches!(mode, Mode::Lines | Mode::LineLoop | Mode::LineStrip) {
            out.skipped_lines += 1;
            return Ok(());
        }
        let Some(pa) = prim.get(&Semantic::Positions) else {
            return Err(perr(self.path, Position::Whole, format!("{what} has no POSITION attribute")));
        };
        let (p, _, span) = self.floats(&pa, &format!("POSITION of {what}"), &[Dimensions::Vec3])?;
        let n = p.len() / 3;
        let base = out.positions.len();
        if base as u64 + n as u64 > u32::MAX as u64 {
            return Err(perr(self.path, Position::Whole, "more vertices than Motif can index (u32)"));
        }
        out.positions.reserve(n);
        for (e, c) in p.chunks_exact(3).enumerate() {
            let q = [c[0], c[1], c[2]];
            if !is_finite(q) {
                return Err(perr(
                    self.path,
                    span.position(e),
                    format!("vertex {e} of {what} has a NaN or infinite coordinate"),
                ));
            }
            out.positions.push(transform_point(world, q));
        }

        let (cof, det) = cofactor3(world);
        out.any_normals |= prim.get(&Semantic::Normals).is_some();
        out.any_colors |= prim.get(&Semantic::Colors(0)).is_some();
        match prim.get(&Semantic::Normals) {
            Some(na) if !out.missing_normals => {
                let (v, _, _) = self.floats(&na, &format!("NORMAL of {what}"), &[Dimensions::Vec3])?;
                self.same_count(v.len() / 3, n, "NORMAL", what)?;
                let normals = out.normals.get_or_insert_with(Vec::new);
                let sign = if det < 0.0 { -1.0 } else { 1.0 };
                normals.extend(v.chunks_exact(3).map(|c| {
                    let t =
                        [0, 1, 2].map(|i| sign * (cof[i][0] * c[0] + cof[i][1] * c[1] + cof[i][2] * c[2]));
                    normalize(t).unwrap_or([0.0; 3])
                }));
            }
            _ => out.missing_normals |= n > 0,
        }
        match prim.get(&Semantic::Colors(0)) {
            Some(ca) if !out.missing_colors => {
                let (v, k, _) =
                    self.floats(&ca, &format!("COLOR_0 of {what}"), &[Dimensions::Vec3, Dimensions::Vec4])?;
                self.same_count(v.len() / k, n, "COLOR_0", what)?;
                let colors = out.colors.get_or_insert_with(Vec::new);
                colors.extend(
                    v.chunks_exact(k).map(|c| [unit_to_u8(c[0]), unit_to_u8(c[1]), unit_to_u8(c[2])]),
                );
            }
            _ => out.missing_colors |= n > 0,
        }

        let idx = match prim.indices() {
            Some(ia) => self.indices(&ia, &format!("indices of {what}"), n)?,
            None => (0..n as u32).collect(),
        };
        let flip = det < 0.0;
        let mut emit = |a: u32, b: u32, c: u32| {
            let b0 = base as u32;
            let (b, c) = if flip { (c, b) } else { (b, c) };
            out.faces.add(&[a + b0, b + b0, c + b0], || Position::Whole);
        };
        match mode {
            Mode::Triangles => {
                for t in idx.chunks_exact(3) {
                    emit(t[0], t[1], t[2]);
                }
                out.dropped_indices += idx.len() % 3;
            }
            Mode::TriangleStrip => {
                for i in 0..idx.len().saturating_sub(2) {
                    if i % 2 == 0 {
                        emit(idx[i], idx[i + 1], idx[i + 2]);
                    } else {
                        emit(idx[i], idx[i + 2], idx[i + 1]);
                    }
                }
            }
            Mode::TriangleFan => {
                for i in 1..idx.len().saturating_sub(1) {
                    emit(idx[i], idx[i + 1], idx[0]);
                }
            }
            // Points: the vertices are the data.
            _ => {}
        }
        Ok(())
    }

    fn same_count(&self, got: usize, want: usize, attr: &str, what: &str) -> Result<()> {
        if got != want {
            return Err(perr(
                self.path,
                Position::Whole,
                format!("{attr} of {what} has {got} elements but POSITION has {want}"),
            ));
        }
        Ok(())
    }
}

/// One little-endian component as f64, normalised to 0..1 / −1..1 when asked.
#[inline]
fn component(ty: DataType, b: &[u8], normalized: bool) -> f64 {
    match ty {
        DataType::I8 => {
            let v = b[0] as i8 as f64;
            if normalized { (v / 127.0).max(-1.0) } else { v }
        }
        DataType::U8 => {
            let v = b[0] as f64;
            if normalized { v / 255.0 } else { v }
        }
        DataType::I16 => {
            let v = i16::from_le_bytes([b[0], b[1]]) as f64;
            if normalized { (v / 32767.0).max(-1.0) } else { v }
        }
        DataType::U16 => {
            let v = u16::from_le_bytes([b[0], b[1]]) as f64;
            if normalized { v / 65535.0 } else { v }
        }
        DataType::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
        DataType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
    }
}

/// Builds a glTF (embedded base64 buffer) or GLB file: one mesh with one primitive, f32
/// positions with min/max, f32 normals and normalised u8 RGBA colours when present, u32
/// indices; a point cloud becomes a `POINTS` primitive.
pub(super) fn to_bytes(cloud: &PointCloud, triangles: &[[u32; 3]], format: Format) -> Result<Vec<u8>> {
    use json::validation::Checked::Valid;
    use json::validation::USize64;

    let mut bin: Vec<u8> = Vec::new();
    let mut root = json::Root {
        asset: json::Asset { generator: Some("Motif".to_string()), ..Default::default() },
        ..Default::default()
    };
    let buffer = json::Index::new(0);
    // Appends a tightly packed view (4-byte aligned) and an accessor over it.
    let mut add = |root: &mut json::Root,
                   bytes: Vec<u8>,
                   count: usize,
                   ty: json::accessor::ComponentType,
                   dims: json::accessor::Type,
                   normalized: bool,
                   target: json::buffer::Target,
                   bounds: Option<(json::Value, json::Value)>| {
        while bin.len() % 4 != 0 {
            bin.push(0);
        }
        let view = root.push(json::buffer::View {
            buffer,
            byte_length: USize64::from(bytes.len()),
            byte_offset: Some(USize64::from(bin.len())),
            byte_stride: None,
            name: None,
            target: Some(Valid(target)),
            extensions: None,
            extras: Default::default(),
        });
        bin.extend_from_slice(&bytes);
        let (min, max) = bounds.map_or((None, None), |(a, b)| (Some(a), Some(b)));
        root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: USize64::from(count),
            component_type: Valid(json::accessor::GenericComponentType(ty)),
            extensions: None,
            extras: Default::default(),
            type_: Valid(dims),
            min,
            max,
            name: None,
            normalized,
            sparse: None,
        })
    };
    use json::accessor::{ComponentType as C, Type as T};
    use json::buffer::Target::{ArrayBuffer, ElementArrayBuffer};

    let mut pos = Vec::with_capacity(cloud.len() * 12);
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for p in &cloud.positions {
        for k in 0..3 {
            let v = p[k] as f32;
            if !v.is_finite() {
                return Err(Error::InvalidInput(format!(
                    "coordinate {} does not fit the f32 positions of glTF",
                    p[k]
                )));
            }
            lo[k] = lo[k].min(v);
            hi[k] = hi[k].max(v);
            pos.extend_from_slice(&v.to_le_bytes());
        }
    }
    let bounds = (!cloud.is_empty()).then(|| (serde_json::json!(lo), serde_json::json!(hi)));
    let mut attributes = std::collections::BTreeMap::new();
    let pa = add(&mut root, pos, cloud.len(), C::F32, T::Vec3, false, ArrayBuffer, bounds);
    attributes.insert(Valid(Semantic::Positions), pa);
    if let Some(normals) = &cloud.normals {
        let bytes: Vec<u8> = normals.iter().flatten().flat_map(|&c| (c as f32).to_le_bytes()).collect();
        let na = add(&mut root, bytes, cloud.len(), C::F32, T::Vec3, false, ArrayBuffer, None);
        attributes.insert(Valid(Semantic::Normals), na);
    }
    if let Some(colors) = &cloud.colors {
        let bytes: Vec<u8> = colors.iter().flat_map(|c| [c[0], c[1], c[2], 255]).collect();
        let ca = add(&mut root, bytes, cloud.len(), C::U8, T::Vec4, true, ArrayBuffer, None);
        attributes.insert(Valid(Semantic::Colors(0)), ca);
    }
    let indices = (!triangles.is_empty()).then(|| {
        let bytes: Vec<u8> = triangles.iter().flatten().flat_map(|i| i.to_le_bytes()).collect();
        add(&mut root, bytes, triangles.len() * 3, C::U32, T::Scalar, false, ElementArrayBuffer, None)
    });
    let mode = if triangles.is_empty() { Mode::Points } else { Mode::Triangles };
    let mesh = root.push(json::Mesh {
        extensions: None,
        extras: Default::default(),
        name: None,
        primitives: vec![json::mesh::Primitive {
            attributes,
            extensions: None,
            extras: Default::default(),
            indices,
            material: None,
            mode: Valid(mode),
            targets: None,
        }],
        weights: None,
    });
    let node = root.push(json::Node { mesh: Some(mesh), ..Default::default() });
    let scene = root.push(json::Scene {
        extensions: None,
        extras: Default::default(),
        name: None,
        nodes: vec![node],
    });
    root.scene = Some(scene);
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    let json_err = |e: json::Error| Error::InvalidInput(format!("cannot encode the glTF JSON: {e}"));
    if format == Format::Gltf {
        root.push(json::Buffer {
            byte_length: USize64::from(bin.len()),
            name: None,
            uri: Some(format!(
                "data:application/octet-stream;base64,{}",
                base64::engine::general_purpose::STANDARD.encode(&bin)
            )),
            extensions: None,
            extras: Default::default(),
        });
        return root.to_vec_pretty().map_err(json_err);
    }
    root.push(json::Buffer {
        byte_length: USize64::from(bin.len()),
        name: None,
        uri: None,
        extensions: None,
        extras: Default::default(),
    });
    let json_bytes = root.to_vec().map_err(json_err)?;
    if json_bytes.len() + bin.len() > u32::MAX as usize - 64 {
        return Err(Error::InvalidInput("the model is too large for a GLB file (4 GiB)".to_string()));
    }
    let glb = ::gltf::binary::Glb {
        header: ::gltf::binary::Header { magic: *b"glTF", version: 2, length: 0 },
        json: Cow::Owned(json_bytes),
        bin: Some(Cow::Owned(bin)),
    };
    glb.to_vec().map_err(|e| Error::InvalidInput(format!("cannot encode the GLB: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri() -> (PointCloud, Vec<[u32; 3]>) {
        let mut c = PointCloud::from_positions(vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
        c.normals = Some(vec![[0.0, 0.0, 1.0]; 3]);
        c.colors = Some(vec![[255, 0, 0], [0, 255, 0], [0, 0, 255]]);
        (c, vec![[0, 1, 2]])
    }

    #[test]
    fn glb_and_gltf_round_trip() {
        let (c, t) = tri();
        for f in [Format::Glb, Format::Gltf] {
            let bytes = to_bytes(&c, &t, f).unwrap();
            let m = read(&bytes, Path::new("t"), f, None).unwrap();
            assert_eq!(m.vertices, c);
            assert_eq!(m.triangles, t);
        }
    }

    /// A minimal glTF around a hand-made buffer.
    fn gltf_json(nodes: &str, extra_accessors: &str, buffer: &[u8]) -> Vec<u8> {
        let b64 = base64::engine::general_purpose::STANDARD.encode(buffer);
        format!(
            r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":{nodes},
            "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}{extra_accessors}}}]}}],
            "buffers":[{{"byteLength":{},"uri":"data:application/octet-stream;base64,{b64}"}}],
            "bufferViews":[{{"buffer":0,"byteLength":36}},{{"buffer":0,"byteOffset":36,"byteLength":6}}],
            "accessors":[{{"bufferView":0,"count":3,"componentType":5126,"type":"VEC3"}},
                         {{"bufferView":1,"count":3,"componentType":5123,"type":"SCALAR"}}]}}"#,
            buffer.len()
        )
        .into_bytes()
    }

    fn tri_buffer() -> Vec<u8> {
        let mut b: Vec<u8> =
            [0f32, 0., 0., 1., 0., 0., 0., 1., 0.].iter().flat_map(|v| v.to_le_bytes()).collect();
        b.extend([0u16, 1, 2].iter().flat_map(|v| v.to_le_bytes()));
        b
    }

    #[test]
    fn node_transforms_compose_and_mirror_flips_winding() {
        // Parent translates by x+10, child mirrors z and scales by 2.
        let nodes = r#"[{"translation":[10,0,0],"children":[1]},
                        {"mesh":0,"matrix":[2,0,0,0, 0,2,0,0, 0,0,-2,0, 0,0,0,1]}]"#;
        let json = gltf_json(nodes, r#","indices":1"#, &tri_buffer());
        let m = read(&json, Path::new("t.gltf"), Format::Gltf, None).unwrap();
        assert_eq!(m.vertices.positions, vec![[10.0, 0.0, 0.0], [12.0, 0.0, 0.0], [10.0, 2.0, 0.0]]);
        assert_eq!(m.triangles, vec![[0, 2, 1]]);
    }

    #[test]
    fn strips_fans_and_points() {
        for (mode, want) in [(5, vec![[0, 1, 2]]), (6, vec![[1, 2, 0]]), (0, vec![])] {
            let json = gltf_json(r#"[{"mesh":0}]"#, &format!(r#","indices":1,"mode":{mode}"#), &tri_buffer());
            let m = read(&json, Path::new("t.gltf"), Format::Gltf, None).unwrap();
            assert_eq!(m.triangles, want, "mode {mode}");
            assert_eq!(m.vertices.len(), 3);
        }
    }

    #[test]
    fn without_scenes_every_root_node_is_read() {
        let nodes = r#"[{"mesh":0},{"mesh":0,"translation":[0,0,5],"children":[2]},{"mesh":0}]"#;
        let json = String::from_utf8(gltf_json(nodes, "", &tri_buffer())).unwrap();
        let json = json.replace(r#""scene":0,"scenes":[{"nodes":[0]}],"#, "");
        let m = read(json.as_bytes(), Path::new("t.gltf"), Format::Gltf, None).unwrap();
        // Node 0, node 1 and its child 2 (which inherits the translation).
        assert_eq!(m.vertices.len(), 9);
        assert_eq!(m.triangles.len(), 3);
        assert_eq!(m.vertices.positions[8], [0.0, 1.0, 5.0]);
    }

    #[test]
    fn accessor_out_of_bounds_and_cycles_are_errors() {
        let mut json =
            String::from_utf8(gltf_json(r#"[{"mesh":0}]"#, r#","indices":1"#, &tri_buffer())).unwrap();
        json = json.replace(r#""count":3,"componentType":5126"#, r#""count":4,"componentType":5126"#);
        let e = read(json.as_bytes(), Path::new("t.gltf"), Format::Gltf, None).unwrap_err();
        assert!(e.to_string().contains("accessor 0"), "{e}");
        let cyc = gltf_json(r#"[{"mesh":0,"children":[1]},{"children":[0]}]"#, "", &tri_buffer());
        let e = read(&cyc, Path::new("t.gltf"), Format::Gltf, None).unwrap_err();
        assert!(e.to_string().contains("twice"), "{e}");
    }

    #[test]
    fn external_buffers_stay_in_their_directory() {
        let base = Path::new("/tmp/x");
        assert!(external_path(base, "../secret.bin").is_err());
        assert!(external_path(base, "/etc/passwd").is_err());
        assert!(external_path(base, "http://example.invalid/a.bin").is_err());
        assert_eq!(external_path(base, "a%20b.bin").unwrap(), base.join("a b.bin"));
    }
}
