//! Stanford PLY: ASCII, binary little-endian and binary big-endian; properties in any order and
//! of every scalar type (`char uchar short ushort int uint float double` and the
//! `int8 … float64` aliases).
//!
//! Vertex properties: `x y z` (required), `nx ny nz`, `red green blue` (`uchar`, or reals in
//! 0..1, which are scaled); every other scalar becomes a named attribute ([`AttributeData::Int`]
//! for integer types, [`AttributeData::Float`] otherwise). Faces: the `vertex_indices` (or
//! `vertex_index`) list, any count and index types. Every other element and property is skipped,
//! lists by reading their counts. Before anything is reserved, the element counts are checked
//! against the bytes after the header (each record needs at least its fixed-size part), so a
//! header announcing billions of records in a small file is rejected at its line.

use std::io::{self, Write};
use std::path::Path;

use super::common::{
    FaceSink, Lines, check_utf8, check_vertex_count, parse_f64, parse_i64, perr, show, tokens, unit_to_u8,
};
use super::{Format, Model, PlyEncoding};
use crate::error::Position;
use crate::geometry::is_finite;
use crate::point_cloud::{Attribute, AttributeData};
use crate::{Error, PointCloud, Result};

/// A PLY scalar type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Ty {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Ty {
    fn parse(name: &[u8]) -> Option<Ty> {
        Some(match name {
            b"char" | b"int8" => Ty::I8,
            b"uchar" | b"uint8" => Ty::U8,
            b"short" | b"int16" => Ty::I16,
            b"ushort" | b"uint16" => Ty::U16,
            b"int" | b"int32" => Ty::I32,
            b"uint" | b"uint32" => Ty::U32,
            b"float" | b"float32" => Ty::F32,
            b"double" | b"float64" => Ty::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Ty::I8 | Ty::U8 => 1,
            Ty::I16 | Ty::U16 => 2,
            Ty::I32 | Ty::U32 | Ty::F32 => 4,
            Ty::F64 => 8,
        }
    }

    fn is_int(self) -> bool {
        !matches!(self, Ty::F32 | Ty::F64)
    }

    fn name(self) -> &'static str {
        match self {
            Ty::I8 => "char",
            Ty::U8 => "uchar",
            Ty::I16 => "short",
            Ty::U16 => "ushort",
            Ty::I32 => "int",
            Ty::U32 => "uint",
            Ty::F32 => "float",
            Ty::F64 => "double",
        }
    }

    fn range(self) -> (i64, i64) {
        match self {
            Ty::I8 => (i8::MIN as i64, i8::MAX as i64),
            Ty::U8 => (0, u8::MAX as i64),
            Ty::I16 => (i16::MIN as i64, i16::MAX as i64),
            Ty::U16 => (0, u16::MAX as i64),
            Ty::I32 => (i32::MIN as i64, i32::MAX as i64),
            Ty::U32 => (0, u32::MAX as i64),
            Ty::F32 | Ty::F64 => (i64::MIN, i64::MAX),
        }
    }
}

#[derive(Debug, Clone, Copy)]
enum Kind {
    Scalar(Ty),
    /// A list: count type, item type.
    List(Ty, Ty),
}

#[derive(Debug)]
struct Property {
    name: String,
    kind: Kind,
}

#[derive(Debug)]
struct Element {
    name: String,
    count: u64,
    props: Vec<Property>,
    /// Header line that declares the element.
    line: usize,
}

impl Element {
    /// The fewest bytes one record can take in the body.
    fn min_record_bytes(&self, encoding: PlyEncoding) -> u64 {
        self.props
            .iter()
            .map(|p| match (encoding, p.kind) {
                // A value and a separator.
                (PlyEncoding::Ascii, _) => 2,
                (_, Kind::Scalar(t)) | (_, Kind::List(t, _)) => t.size() as u64,
            })
            .sum()
    }
}

#[derive(Debug)]
struct Header {
    encoding: PlyEncoding,
    elements: Vec<Element>,
    body_start: usize,
}

/// A value read from the body.
#[derive(Debug, Clone, Copy)]
enum Val {
    I(i64),
    F(f64),
}

impl Val {
    #[inline]
    fn f64(self) -> f64 {
        match self {
            Val::I(i) => i as f64,
            Val::F(f) => f,
        }
    }
}

/// Why a value could not be read: the body ended, or the text is not a value of the type.
enum ReadErr {
    Eof(Position),
    Bad(Position, String),
}

/// The body of a PLY file, ASCII or binary.
trait Body {
    fn scalar(&mut self, ty: Ty) -> Result<Val, ReadErr>;
    fn skip(&mut self, ty: Ty, n: u64) -> Result<(), ReadErr>;
    /// Where the next value starts.
    fn position(&self) -> Position;
    /// A record (one vertex, one face) starts: an ASCII record is one line.
    fn begin_record(&mut self) {}
    /// The record's values are read: an ASCII line must hold no more.
    fn end_record(&mut self) -> Result<(), ReadErr> {
        Ok(())
    }
}

struct Binary<'a> {
    bytes: &'a [u8],
    pos: usize,
    big: bool,
}

impl Binary<'_> {
    #[inline]
    fn take<const N: usize>(&mut self) -> Result<[u8; N], ReadErr> {
        match self.bytes.get(self.pos..self.pos + N) {
            Some(s) => {
                self.pos += N;
                let mut a = [0u8; N];
                a.copy_from_slice(s);
                Ok(a)
            }
            None => Err(ReadErr::Eof(Position::Byte(self.pos as u64))),
        }
    }
}

macro_rules! num {
    ($self:ident, $t:ty) => {{
        let b = $self.take::<{ std::mem::size_of::<$t>() }>()?;
        if $self.big { <$t>::from_be_bytes(b) } else { <$t>::from_le_bytes(b) }
    }};
}

impl Body for Binary<'_> {
    #[inline]
    fn scalar(&mut self, ty: Ty) -> Result<Val, ReadErr> {
        Ok(match ty {
            Ty::I8 => Val::I(num!(self, i8) as i64),
            Ty::U8 => Val::I(num!(self, u8) as i64),
            Ty::I16 => Val::I(num!(self, i16) as i64),
            Ty::U16 => Val::I(num!(self, u16) as i64),
            Ty::I32 => Val::I(num!(self, i32) as i64),
            Ty::U32 => Val::I(num!(self, u32) as i64),
            Ty::F32 => Val::F(num!(self, f32) as f64),
            Ty::F64 => Val::F(num!(self, f64)),
        })
    }

    fn skip(&mut self, ty: Ty, n: u64) -> Result<(), ReadErr> {
        let len = (ty.size() as u64).saturating_mul(n);
        if len > (self.bytes.len() - self.pos) as u64 {
            return Err(ReadErr::Eof(Position::Byte(self.pos as u64)));
        }
        self.pos += len as usize;
        Ok(())
    }

    fn position(&self) -> Position {
        Position::Byte(self.pos as u64)
    }
}

/// An ASCII body, read record by record, each record one line (the PLY format's rule): a value
/// too many or too few on one line is an error on that line. Read as a plain stream of numbers,
/// one extra value silently shifted every point after it, and a missing one was reported far
/// down the file, where the counts finally ran out.
struct Ascii<'a> {
    bytes: &'a [u8],
    pos: usize,
    line: usize,
    /// The line of the record being read.
    record_line: Option<usize>,
}

impl<'a> Ascii<'a> {
    #[inline]
    fn token(&mut self) -> Result<(&'a [u8], Position), ReadErr> {
        let b = self.bytes;
        while self.pos < b.len() && b[self.pos].is_ascii_whitespace() {
            if b[self.pos] == b'\n' {
                self.line += 1;
            }
            self.pos += 1;
        }
        let start = self.pos;
        while self.pos < b.len() && !b[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        if start == self.pos {
            return Err(ReadErr::Eof(Position::Line(self.line)));
        }
        if let Some(line) = self.record_line.filter(|&l| l != self.line) {
            return Err(ReadErr::Bad(
                Position::Line(line),
                "the line ends before the record does: fewer values than the header's properties declare"
                    .into(),
            ));
        }
        Ok((&b[start..self.pos], Position::Line(self.line)))
    }
}

impl Body for Ascii<'_> {
    #[inline]
    fn scalar(&mut self, ty: Ty) -> Result<Val, ReadErr> {
        let (t, pos) = self.token()?;
        if ty.is_int() {
            let (lo, hi) = ty.range();
            match parse_i64(t) {
                Some(v) if (lo..=hi).contains(&v) => Ok(Val::I(v)),
                Some(v) => {
                    Err(ReadErr::Bad(pos, format!("value {v} is out of range for type {}", ty.name())))
                }
                None => Err(ReadErr::Bad(
                    pos,
                    super::common::bad_number(t, &format!("an integer ({})", ty.name())),
                )),
            }
        } else {
            match parse_f64(t) {
                // A `float` property holds an f32, whatever digits the writer printed; rounding
                // makes ASCII and binary files of the same data read alike.
                Some(v) if ty == Ty::F32 => Ok(Val::F(v as f32 as f64)),
                Some(v) => Ok(Val::F(v)),
                None => Err(ReadErr::Bad(pos, super::common::bad_number(t, "a number"))),
            }
        }
    }

    fn skip(&mut self, ty: Ty, n: u64) -> Result<(), ReadErr> {
        for _ in 0..n {
            self.scalar(ty)?;
        }
        Ok(())
    }

    fn begin_record(&mut self) {
        let b = self.bytes;
        while self.pos < b.len() && b[self.pos].is_ascii_whitespace() {
            if b[self.pos] == b'\n' {
                self.line += 1;
            }
            self.pos += 1;
        }
        self.record_line = Some(self.line);
    }

    fn end_record(&mut self) -> Result<(), ReadErr> {
        self.record_line = None;
        let b = self.bytes;
        let mut p = self.pos;
        // The whitespace `token` skips, but for the line's end.
        while p < b.len() && b[p].is_ascii_whitespace() && b[p] != b'\n' {
            p += 1;
        }
        if p < b.len() && b[p] != b'\n' {
            return Err(ReadErr::Bad(
                Position::Line(self.line),
                "more values on the line than the header's properties declare".into(),
            ));
        }
        Ok(())
    }

    fn position(&self) -> Position {
        // The next token may start on a later line; the current one is close enough for errors.
        let mut line = self.line;
        let mut p = self.pos;
        while p < self.bytes.len() && self.bytes[p].is_ascii_whitespace() {
            if self.bytes[p] == b'\n' {
                line += 1;
            }
            p += 1;
        }
        Position::Line(line)
    }
}

pub(super) fn read(bytes: &[u8], path: &Path) -> Result<Model> {
    let header = parse_header(bytes, path)?;
    match header.encoding {
        PlyEncoding::Ascii => {
            // Line numbers go on counting from the header.
            let line = bytes[..header.body_start].iter().filter(|&&b| b == b'\n').count() + 1;
            let mut body = Ascii { bytes, pos: header.body_start, line, record_line: None };
            read_body(&header, &mut body, bytes.len() - header.body_start, path)
        }
        PlyEncoding::BinaryLittleEndian | PlyEncoding::BinaryBigEndian => {
            let big = header.encoding == PlyEncoding::BinaryBigEndian;
            let mut body = Binary { bytes, pos: header.body_start, big };
            read_body(&header, &mut body, bytes.len() - header.body_start, path)
        }
    }
}

fn parse_header(bytes: &[u8], path: &Path) -> Result<Header> {
    let mut lines = Lines::new(bytes);
    match lines.next() {
        Some((_, b"ply")) => {}
        first => {
            let found = first.map(|(_, l)| show(&l[..l.len().min(20)])).unwrap_or_default();
            return Err(perr(
                path,
                Position::Line(1),
                format!("not a PLY file: the first line must be \"ply\", found {found}"),
            ));
        }
    }
    if !bytes.windows(10).any(|w| w == b"end_header") {
        return Err(perr(
            path,
            Position::Whole,
            "the PLY header never ends: no end_header line (truncated file?)",
        ));
    }
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    for (ln, line) in lines.by_ref() {
        let pos = Position::Line(ln);
        check_utf8(path, ln, line, "PLY header")?;
        let toks: Vec<&[u8]> = tokens(line).collect();
        let Some(&key) = toks.first() else { continue };
        match key {
            b"comment" | b"obj_info" => {}
            b"end_header" => {
                let Some(encoding) = encoding else {
                    return Err(perr(
                        path,
                        pos,
                        "the header has no format line (format ascii|binary_little_endian|binary_big_endian 1.0)",
                    ));
                };
                return Ok(Header { encoding, elements, body_start: bytes.len() - lines.remaining() });
            }
            b"format" => {
                encoding = Some(match toks.get(1).copied() {
                    Some(b"ascii") => PlyEncoding::Ascii,
                    Some(b"binary_little_endian") => PlyEncoding::BinaryLittleEndian,
                    Some(b"binary_big_endian") => PlyEncoding::BinaryBigEndian,
                    other => {
                        return Err(perr(
                            path,
                            pos,
                            format!(
                                "unknown PLY format {}: expected ascii, binary_little_endian or binary_big_endian",
                                show(other.unwrap_or(b""))
                            ),
                        ));
                    }
                });
            }
            b"element" => {
                let (Some(name), Some(count), None) = (toks.get(1), toks.get(2), toks.get(3)) else {
                    return Err(perr(path, pos, "expected: element <name> <count>"));
                };
                let count = match parse_i64(count) {
                    Some(c) if c >= 0 => c as u64,
                    _ => return Err(perr(path, pos, format!("bad element count {}", show(count)))),
                };
                let name = String::from_utf8_lossy(name).into_owned();
                if elements.iter().any(|e| e.name == name) {
                    return Err(perr(path, pos, format!("element {name:?} is declared twice")));
                }
                elements.push(Element { name, count, props: Vec::new(), line: ln });
            }
            b"property" => {
                let Some(element) = elements.last_mut() else {
                    return Err(perr(path, pos, "a property before any element"));
                };
                let ty = |t: &[u8]| {
                    Ty::parse(t).ok_or_else(|| perr(path, pos, format!("unknown property type {}", show(t))))
                };
                let (kind, name) = match toks[1..] {
                    [b"list", count, item, name] => {
                        let count = ty(count)?;
                        if !count.is_int() {
                            return Err(perr(
                                path,
                                pos,
                                format!("a list count must have an integer type, not {}", count.name()),
                            ));
                        }
                        (Kind::List(count, ty(item)?), name)
                    }
                    [t, name] if t != b"list" => (Kind::Scalar(ty(t)?), name),
                    _ => {
                        return Err(perr(
                            path,
                            pos,
                            "expected: property <type> <name> or property list <count type> <item type> <name>",
                        ));
                    }
                };
                let name = String::from_utf8_lossy(name).into_owned();
                if element.props.iter().any(|p| p.name == name) {
                    return Err(perr(
                        path,
                        pos,
                        format!("property {name:?} of element {:?} is declared twice", element.name),
                    ));
                }
                element.props.push(Property { name, kind });
            }
            other => return Err(perr(path, pos, format!("unknown header keyword {}", show(other)))),
        }
    }
    Err(perr(path, Position::Whole, "the PLY header never ends: no end_header line (truncated file?)"))
}

/// What a vertex property is used for.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Role {
    Pos(usize),
    Normal(usize),
    Color(usize),
    Attr(usize),
    Skip,
}

fn read_body(header: &Header, body: &mut dyn Body, body_len: usize, path: &Path) -> Result<Model> {
    // Reject counts the remaining bytes cannot hold, before anything is reserved.
    let mut need: u128 = 0;
    let slack = if header.encoding == PlyEncoding::Ascii { 1 } else { 0 };
    for e in &header.elements {
        let min = e.min_record_bytes(header.encoding) as u128;
        need += e.count as u128 * min;
        if need > body_len as u128 + slack {
            return Err(perr(
                path,
                Position::Line(e.line),
                format!(
                    "element {:?} declares {} records of at least {min} bytes each, but only {body_len} bytes \
                     follow the header (is the file truncated?)",
                    e.name, e.count
                ),
            ));
        }
    }
    let Some(ve) = header.elements.iter().find(|e| e.name == "vertex") else {
        return Err(perr(path, Position::Whole, "the file has no vertex element"));
    };
    check_vertex_count(path, Position::Line(ve.line), ve.count)?;
    let nv = ve.count as usize;

    let mut warnings = Vec::new();
    let mut cloud = PointCloud::default();
    let mut faces = FaceSink::default();
    for e in &header.elements {
        if e.props.is_empty() {
            continue;
        }
        match e.name.as_str() {
            "vertex" => cloud = read_vertices(e, body, path, &mut warnings)?,
            "face" => read_faces(e, body, nv, path, &mut warnings, false, &mut faces)?,
            "tristrips" => read_faces(e, body, nv, path, &mut warnings, true, &mut faces)?,
            _ => {
                for r in 0..e.count {
                    body.begin_record();
                    for p in &e.props {
                        skip_property(body, p).map_err(|err| context(path, err, e, r))?;
                    }
                    body.end_record().map_err(|err| context(path, err, e, r))?;
                }
            }
        }
    }
    let (triangles, source_faces) = faces.finish(path, &cloud.positions, &mut warnings)?;
    Ok(Model { vertices: cloud, triangles, source_faces, format: Format::Ply, warnings })
}

/// Turns a body read error into a parse error that says which record of which element.
fn context(path: &Path, err: ReadErr, e: &Element, record: u64) -> Error {
    match err {
        ReadErr::Eof(pos) => perr(
            path,
            pos,
            format!("the file ends in record {record} of {} {:?} records (truncated?)", e.count, e.name),
        ),
        ReadErr::Bad(pos, msg) => perr(path, pos, format!("{msg} (record {record} of element {:?})", e.name)),
    }
}

#[inline]
fn skip_property(body: &mut dyn Body, p: &Property) -> Result<(), ReadErr> {
    match p.kind {
        Kind::Scalar(t) => body.skip(t, 1),
        Kind::List(ct, it) => {
            let pos = body.position();
            let n = list_len(body.scalar(ct)?, pos)?;
            body.skip(it, n)
        }
    }
}

#[inline]
fn list_len(v: Val, pos: Position) -> Result<u64, ReadErr> {
    match v {
        Val::I(n) if n >= 0 => Ok(n as u64),
        _ => Err(ReadErr::Bad(pos, format!("negative list length {}", v.f64()))),
    }
}

fn read_vertices(
    e: &Element,
    body: &mut dyn Body,
    path: &Path,
    warnings: &mut Vec<String>,
) -> Result<PointCloud> {
    let n = e.count as usize;
    let find = |names: &[&str]| -> Option<usize> {
        e.props.iter().position(|p| names.contains(&p.name.as_str()) && matches!(p.kind, Kind::Scalar(_)))
    };
    let (Some(x), Some(y), Some(z)) = (find(&["x"]), find(&["y"]), find(&["z"])) else {
        return Err(perr(
            path,
            Position::Line(e.line),
            "the vertex element lacks one of the scalar properties x, y, z",
        ));
    };
    let mut roles = vec![Role::Skip; e.props.len()];
    roles[x] = Role::Pos(0);
    roles[y] = Role::Pos(1);
    roles[z] = Role::Pos(2);
    let triple = |names: [&[&str]; 3]| match (find(names[0]), find(names[1]), find(names[2])) {
        (Some(a), Some(b), Some(c)) => Some([a, b, c]),
        _ => None,
    };
    let normal = triple([&["nx"], &["ny"], &["nz"]]);
    if let Some(idx) = normal {
        for (k, i) in idx.into_iter().enumerate() {
            roles[i] = Role::Normal(k);
        }
    }
    let color = triple([&["red", "diffuse_red"], &["green", "diffuse_green"], &["blue", "diffuse_blue"]]);
    if let Some(idx) = color {
        for (k, i) in idx.into_iter().enumerate() {
            roles[i] = Role::Color(k);
        }
    }
    let mut attrs: Vec<Attribute> = Vec::new();
    for (i, p) in e.props.iter().enumerate() {
        if roles[i] != Role::Skip {
            continue;
        }
        match p.kind {
            Kind::Scalar(t) => {
                roles[i] = Role::Attr(attrs.len());
                let data = if t.is_int() {
                    AttributeData::Int(Vec::with_capacity(n))
                } else {
                    AttributeData::Float(Vec::with_capacity(n))
                };
                attrs.push(Attribute { name: p.name.clone(), data });
            }
            Kind::List(..) => {
                warnings.push(format!("ignored the list property {:?} of the vertices", p.name))
            }
        }
    }

    let mut positions = Vec::with_capacity(n);
    let mut normals = normal.map(|_| Vec::with_capacity(n));
    let mut colors = color.map(|_| Vec::with_capacity(n));
    let mut bad_normals = 0usize;
    for r in 0..e.count {
        body.begin_record();
        let start = body.position();
        let (mut p, mut nr, mut c) = ([0.0; 3], [0.0; 3], [0u8; 3]);
        for (prop, &role) in e.props.iter().zip(&roles) {
            let v = match prop.kind {
                Kind::Scalar(t) => body.scalar(t),
                Kind::List(..) => skip_property(body, prop).map(|_| Val::I(0)),
            };
            let v = v.map_err(|err| context(path, err, e, r))?;
            match role {
                Role::Pos(k) => p[k] = v.f64(),
                Role::Normal(k) => nr[k] = v.f64(),
                Role::Color(k) => c[k] = to_u8(v, prop),
                Role::Attr(k) => match (&mut attrs[k].data, v) {
                    (AttributeData::Int(d), Val::I(i)) => d.push(i),
                    (AttributeData::Float(d), v) => d.push(v.f64()),
                    (AttributeData::Int(d), Val::F(f)) => d.push(f as i64),
                },
                Role::Skip => {}
            }
        }
        body.end_record().map_err(|err| context(path, err, e, r))?;
        if !is_finite(p) {
            return Err(perr(path, start, format!("vertex {r} has a NaN or infinite coordinate {p:?}")));
        }
        positions.push(p);
        if let Some(ns) = &mut normals {
            if !is_finite(nr) {
                bad_normals += 1;
                nr = [0.0; 3];
            }
            ns.push(nr);
        }
        if let Some(cs) = &mut colors {
            cs.push(c);
        }
    }
    if bad_normals > 0 {
        warnings.push(format!("replaced {bad_normals} NaN or infinite normals by zero vectors"));
    }
    Ok(PointCloud { positions, normals, colors, attributes: attrs })
}

/// A colour component as 8 bits: `uchar` as is, reals in 0..1 scaled, 16-bit values scaled,
/// other integers clamped.
fn to_u8(v: Val, p: &Property) -> u8 {
    match (v, p.kind) {
        (Val::F(f), _) => unit_to_u8(if f.is_nan() { 0.0 } else { f }),
        (Val::I(i), Kind::Scalar(Ty::U16)) => ((i as f64) * 255.0 / 65535.0).round() as u8,
        (Val::I(i), _) => i.clamp(0, 255) as u8,
    }
}

/// Reads a `face` element (polygons) or, with `strips`, a `tristrips` element (triangle strips
/// whose lists may hold several strips separated by −1, as written by Stanford's and VCG's
/// tools), adding the triangles to `faces`.
fn read_faces(
    e: &Element,
    body: &mut dyn Body,
    nv: usize,
    path: &Path,
    warnings: &mut Vec<String>,
    strips: bool,
    faces: &mut FaceSink,
) -> Result<()> {
    let list = e.props.iter().position(|p| {
        matches!(p.name.as_str(), "vertex_indices" | "vertex_index") && matches!(p.kind, Kind::List(..))
    });
    let Some(list) = list else {
        warnings.push(format!("ignored the {} element: it has no vertex_indices list", e.name));
        for r in 0..e.count {
            body.begin_record();
            for p in &e.props {
                skip_property(body, p).map_err(|err| context(path, err, e, r))?;
            }
            body.end_record().map_err(|err| context(path, err, e, r))?;
        }
        return Ok(());
    };
    if let Kind::List(_, it) = e.props[list].kind {
        if !it.is_int() {
            return Err(perr(
                path,
                Position::Line(e.line),
                format!("face indices have the non-integer type {}", it.name()),
            ));
        }
    }
    faces.triangles.reserve(e.count as usize);
    let mut polygon: Vec<u32> = Vec::with_capacity(8);
    for r in 0..e.count {
        body.begin_record();
        let start = body.position();
        for (i, p) in e.props.iter().enumerate() {
            let Kind::List(ct, it) = p.kind else {
                skip_property(body, p).map_err(|err| context(path, err, e, r))?;
                continue;
            };
            if i != list {
                skip_property(body, p).map_err(|err| context(path, err, e, r))?;
                continue;
            }
            let k =
                body.scalar(ct).and_then(|v| list_len(v, start)).map_err(|err| context(path, err, e, r))?;
            polygon.clear();
            for _ in 0..k {
                let v = body.scalar(it).map_err(|err| context(path, err, e, r))?;
                match v {
                    Val::I(idx) if idx >= 0 && (idx as u64) < nv as u64 => polygon.push(idx as u32),
                    Val::I(-1) if strips => {
                        faces.add_strip(&polygon, || start);
                        polygon.clear();
                    }
                    _ => {
                        return Err(perr(
                            path,
                            start,
                            format!("face {r} refers to vertex {}, but the file has {nv} vertices", v.f64()),
                        ));
                    }
                }
            }
        }
        body.end_record().map_err(|err| context(path, err, e, r))?;
        if strips {
            faces.add_strip(&polygon, || start);
        } else {
            faces.add(&polygon, || start);
        }
    }
    Ok(())
}

/// The header of a written file, and the type chosen for each attribute.
pub(super) struct Layout {
    header: String,
    attr_types: Vec<Ty>,
    index_type: Ty,
}

/// Builds the header; errors when an attribute cannot be stored (bad name, integers beyond 32
/// bits).
pub(super) fn header(cloud: &PointCloud, triangles: &[[u32; 3]], encoding: PlyEncoding) -> Result<Layout> {
    let mut reserved: Vec<&str> = vec!["x", "y", "z"];
    let mut h = String::from("ply\n");
    h += match encoding {
        PlyEncoding::Ascii => "format ascii 1.0\n",
        PlyEncoding::BinaryLittleEndian => "format binary_little_endian 1.0\n",
        PlyEncoding::BinaryBigEndian => "format binary_big_endian 1.0\n",
    };
    h += "comment written by Motif\n";
    h +=
        &format!("element vertex {}\nproperty double x\nproperty double y\nproperty double z\n", cloud.len());
    if cloud.normals.is_some() {
        h += "property float nx\nproperty float ny\nproperty float nz\n";
        reserved.extend(["nx", "ny", "nz"]);
    }
    if cloud.colors.is_some() {
        h += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
        reserved.extend(["red", "green", "blue"]);
    }
    let mut attr_types = Vec::with_capacity(cloud.attributes.len());
    for (i, a) in cloud.attributes.iter().enumerate() {
        let name = &a.name;
        if name.is_empty() || !name.bytes().all(|b| b.is_ascii_graphic()) {
            return Err(Error::InvalidInput(format!(
                "attribute name {name:?} cannot be a PLY property name (use ASCII letters, digits, _)"
            )));
        }
        if reserved.contains(&name.as_str()) || cloud.attributes[..i].iter().any(|b| &b.name == name) {
            return Err(Error::InvalidInput(format!(
                "attribute name {name:?} is used twice in the PLY vertex"
            )));
        }
        let ty = match &a.data {
            AttributeData::Float(_) => Ty::F64,
            AttributeData::Int(v) => {
                let (lo, hi) = v.iter().fold((0, 0), |(lo, hi), &x| (x.min(lo), x.max(hi)));
                if lo >= i32::MIN as i64 && hi <= i32::MAX as i64 {
                    Ty::I32
                } else if lo >= 0 && hi <= u32::MAX as i64 {
                    Ty::U32
                } else {
                    return Err(Error::InvalidInput(format!(
                        "integer attribute {name:?} has values in {lo}..={hi}, beyond the 32 bits PLY can store"
                    )));
                }
            }
        };
        h += &format!("property {} {name}\n", ty.name());
        attr_types.push(ty);
    }
    let index_type = if cloud.len() > i32::MAX as usize { Ty::U32 } else { Ty::I32 };
    if !triangles.is_empty() {
        h += &format!(
            "element face {}\nproperty list uchar {} vertex_indices\n",
            triangles.len(),
            index_type.name()
        );
    }
    h += "end_header\n";
    Ok(Layout { header: h, attr_types, index_type })
}

/// Writes the file: x y z as double (exact round trip), normals float, colours uchar, attributes
/// int/uint/double, faces `list uchar int vertex_indices`.
pub(super) fn write(
    w: &mut dyn Write,
    cloud: &PointCloud,
    triangles: &[[u32; 3]],
    layout: &Layout,
    encoding: PlyEncoding,
) -> io::Result<()> {
    w.write_all(layout.header.as_bytes())?;
    if encoding == PlyEncoding::Ascii {
        return write_ascii(w, cloud, triangles);
    }
    let big = encoding == PlyEncoding::BinaryBigEndian;
    let mut rec: Vec<u8> = Vec::with_capacity(64);
    macro_rules! put {
        ($v:expr) => {
            if big {
                rec.extend_from_slice(&$v.to_be_bytes())
            } else {
                rec.extend_from_slice(&$v.to_le_bytes())
            }
        };
    }
    for (i, p) in cloud.positions.iter().enumerate() {
        rec.clear();
        for c in p {
            put!(*c);
        }
        if let Some(n) = &cloud.normals {
            for c in n[i] {
                put!(c as f32);
            }
        }
        if let Some(c) = &cloud.colors {
            rec.extend_from_slice(&c[i]);
        }
        for (a, ty) in cloud.attributes.iter().zip(&layout.attr_types) {
            match (&a.data, ty) {
                (AttributeData::Float(v), _) => put!(v[i]),
                (AttributeData::Int(v), Ty::U32) => put!(v[i] as u32),
                (AttributeData::Int(v), _) => put!(v[i] as i32),
            }
        }
        w.write_all(&rec)?;
    }
    for t in triangles {
        rec.clear();
        rec.push(3);
        for &i in t {
            if layout.index_type == Ty::U32 {
                put!(i);
            } else {
                put!(i as i32);
            }
        }
        w.write_all(&rec)?;
    }
    Ok(())
}

fn write_ascii(w: &mut dyn Write, cloud: &PointCloud, triangles: &[[u32; 3]]) -> io::Result<()> {
    for (i, p) in cloud.positions.iter().enumerate() {
        write!(w, "{:?} {:?} {:?}", p[0], p[1], p[2])?;
        if let Some(n) = &cloud.normals {
            let n = n[i].map(|c| c as f32);
            write!(w, " {:?} {:?} {:?}", n[0], n[1], n[2])?;
        }
        if let Some(c) = &cloud.colors {
            write!(w, " {} {} {}", c[i][0], c[i][1], c[i][2])?;
        }
        for a in &cloud.attributes {
            match &a.data {
                AttributeData::Float(v) => write!(w, " {:?}", v[i])?,
                AttributeData::Int(v) => write!(w, " {}", v[i])?,
            }
        }
        writeln!(w)?;
    }
    for t in triangles {
        writeln!(w, "3 {} {} {}", t[0], t[1], t[2])?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(b: &[u8]) -> Result<Model> {
        read(b, Path::new("t.ply"))
    }

    fn pos_of(e: Error) -> Position {
        match e {
            Error::Parse { position, .. } => position,
            e => panic!("expected a parse error, got {e:?}"),
        }
    }

    #[test]
    fn ascii_with_extra_elements_and_properties() {
        let m = parse(
            b"ply\nformat ascii 1.0\ncomment hi\nelement vertex 3\nproperty float x\nproperty float y\n\
              property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nproperty int label\n\
              property float quality\nelement face 1\nproperty uchar flags\nproperty list uchar int vertex_indices\n\
              element edge 1\nproperty list int int e\nend_header\n\
              0 0 0 255 0 0 7 0.5\n1 0 0 0 255 0 8 0.25\n0 1 0 0 0 255 9 1\n5 3 0 1 2\n2 0 1\n",
        )
        .unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
        assert_eq!(m.vertices.attribute("label"), Some(&AttributeData::Int(vec![7, 8, 9])));
        assert_eq!(m.vertices.attribute("quality"), Some(&AttributeData::Float(vec![0.5, 0.25, 1.0])));
        assert_eq!(m.vertices.colors.as_ref().unwrap()[1], [0, 255, 0]);
    }

    #[test]
    fn binary_big_endian_with_skipped_lists() {
        let mut b = b"ply\nformat binary_big_endian 1.0\nelement material 1\nproperty list ushort float m\n\
                      element vertex 3\nproperty short x\nproperty double y\nproperty int8 z\n\
                      element face 1\nproperty list int ushort vertex_index\nend_header\n"
            .to_vec();
        b.extend(2u16.to_be_bytes());
        b.extend(1f32.to_be_bytes());
        b.extend(2f32.to_be_bytes());
        for (x, y, z) in [(0i16, 0f64, 0i8), (1, 0.0, 0), (0, 1.0, -1)] {
            b.extend(x.to_be_bytes());
            b.extend(y.to_be_bytes());
            b.extend(z.to_be_bytes());
        }
        b.extend(3i32.to_be_bytes());
        for i in [0u16, 1, 2] {
            b.extend(i.to_be_bytes());
        }
        let m = parse(&b).unwrap();
        assert_eq!(m.vertices.positions[2], [0.0, 1.0, -1.0]);
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
    }

    #[test]
    fn an_ascii_record_is_one_line() {
        let head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                    property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
        let good = format!("{head}0 0 0\n1 0 0\r\n0 1 0   \n3 0 1 2\n");
        assert_eq!(parse(good.as_bytes()).unwrap().triangles.len(), 1);
        // One value too many on line 11 (the second vertex): said there, not read as the next
        // vertex's x.
        let extra = format!("{head}0 0 0\n1 0 0 0.25\n0 1 0\n3 0 1 2\n");
        let e = parse(extra.as_bytes()).unwrap_err();
        assert_eq!(pos_of(e), Position::Line(11));
        let e = parse(extra.as_bytes()).unwrap_err().to_string();
        assert!(e.contains("more values on the line") && e.contains("record 1 of element \"vertex\""), "{e}");
        // One too few: said on the record's line, not where the counts run out.
        let short = format!("{head}0 0 0\n1 0\n0 1 0\n3 0 1 2\n");
        assert_eq!(pos_of(parse(short.as_bytes()).unwrap_err()), Position::Line(11));
        let e = parse(short.as_bytes()).unwrap_err().to_string();
        assert!(e.contains("fewer values than the header's properties declare"), "{e}");
        // A face with an index too many.
        let face = format!("{head}0 0 0\n1 0 0\n0 1 0\n3 0 1 2 2\n");
        assert_eq!(pos_of(parse(face.as_bytes()).unwrap_err()), Position::Line(13));
        // The last record may end the file without a newline.
        let last = format!("{head}0 0 0\n1 0 0\n0 1 0\n3 0 1 2");
        assert_eq!(parse(last.as_bytes()).unwrap().triangles.len(), 1);
    }

    #[test]
    fn bad_headers_and_bodies() {
        assert_eq!(pos_of(parse(b"plx\nformat ascii 1.0\nend_header\n").unwrap_err()), Position::Line(1));
        let huge = b"ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\n\
                     property float y\nproperty float z\nend_header\n\0\0\0\0";
        assert_eq!(pos_of(parse(huge).unwrap_err()), Position::Line(3));
        let truncated = b"ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\n\
                          property float y\nproperty double z\nend_header\n\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0";
        assert_eq!(pos_of(parse(truncated).unwrap_err()), Position::Line(3));
        let ascii = b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
                      property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
                      0 0 0\n1 0 0\n3 0 1 2\n";
        let e = parse(ascii).unwrap_err();
        assert_eq!(pos_of(e), Position::Line(12));
        let nan = b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
                    property float z\nend_header\n0 0 0\n1 nan 0\n";
        assert_eq!(pos_of(parse(nan).unwrap_err()), Position::Line(9));
        let range = b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
                      property float z\nproperty uchar red\nend_header\n0 0 0 256\n";
        assert_eq!(pos_of(parse(range).unwrap_err()), Position::Line(9));
    }
}
