//! Wavefront OBJ: `v x y z [w | r g b]`, `vn`, `f` with `i`, `i/t`, `i//n`, `i/t/n` and negative
//! (relative) indices and `\` line continuations; polygons are triangulated (convex ones as a
//! fan, concave ones by ear clipping: `FaceSink` in `common.rs`). `vt`, `usemtl`, `mtllib`, `o`, `g`, `s`,
//! `l`, `p` and comments are read past. A file without `f` records is a point cloud.
//!
//! The vertex count is the number of `v` records: vertices are never split by texture or normal
//! index. Per-vertex normals come from the `vn` each vertex is used with (the first one when a
//! vertex is used with several), or pair up with `v` by index when faces name none.

use std::io::{self, Write};
use std::path::Path;

use super::common::{
    FaceSink, Lines, bad_number, check_utf8, coord, perr, show, strip_comment, tokens, unit_to_u8,
};
use super::{Format, Model};
use crate::error::Position;
use crate::geometry::Point3;
use crate::{PointCloud, Result};

const NONE: u32 = u32::MAX;

/// A vertex reference of a face corner: 0-based vertex and normal indices (`NONE` when absent),
/// not yet checked against the final counts (OBJ allows nothing else, but tolerating forward
/// references costs nothing).
struct Corner {
    v: u32,
    n: u32,
}

/// The UTF-8 byte-order mark.
pub(super) const UTF8_BOM: &[u8] = b"\xEF\xBB\xBF";

pub(super) fn read(bytes: &[u8], path: &Path) -> Result<Model> {
    // A UTF-8 byte-order mark (some Windows editors write one) is not part of the first line:
    // read as text, it would hide the first statement, and every index after it would shift.
    let bytes = bytes.strip_prefix(UTF8_BOM).unwrap_or(bytes);
    let mut positions: Vec<Point3> = Vec::new();
    let mut colors: Vec<[u8; 3]> = Vec::new();
    let mut vn: Vec<Point3> = Vec::new();
    // Per vertex, allocated when the first face names normals: the first normal index it is
    // used with, the sum of the normals of all its corners, and whether they differ.
    let mut normal_of: Vec<u32> = Vec::new();
    let mut normal_sum: Vec<Point3> = Vec::new();
    let mut mixed: Vec<bool> = Vec::new();
    // Corners naming a normal not yet defined: (vertex, normal), summed at the end.
    let mut pending: Vec<(u32, u32)> = Vec::new();
    let mut faces = FaceSink::default();
    let mut polygon: Vec<u32> = Vec::with_capacity(8);
    let mut corners: Vec<Corner> = Vec::with_capacity(8);
    // Largest vertex / normal index referenced before it was defined, and where.
    let mut forward_v: Option<(u32, usize)> = None;
    let mut forward_n: Option<(u32, usize)> = None;
    let mut ignored: Vec<(String, usize)> = Vec::new();
    // Texture coordinates and materials are not read: said once each, as they will be missing
    // from anything written from this model.
    let (mut texture_coordinates, mut materials) = (0usize, 0usize);
    let lines = Lines::new(bytes);
    // A line ending in a backslash continues on the next (the OBJ specification's line
    // continuation): the pieces are joined with a space and read as one statement, reported at
    // its first line.
    let (mut carry, mut carry_line, mut joined) = (Vec::new(), 0, Vec::new());

    for (ln, raw) in lines {
        // A comment is not continued (a Windows path ending in `\` would swallow a statement).
        let comment = carry.is_empty() && raw.trim_ascii_start().starts_with(b"#");
        if let Some(head) = raw.trim_ascii_end().strip_suffix(b"\\").filter(|_| !comment) {
            if carry.is_empty() {
                carry_line = ln;
            }
            carry.extend_from_slice(head);
            carry.push(b' ');
            continue;
        }
        let (ln, raw) = if carry.is_empty() {
            (ln, raw)
        } else {
            joined.clear();
            joined.append(&mut carry);
            joined.extend_from_slice(raw);
            (carry_line, &joined[..])
        };
        let line = raw.trim_ascii_start();
        if line.is_empty() || line[0] == b'#' {
            continue;
        }
        let pos = Position::Line(ln);
        let mut toks = tokens(strip_comment(line));
        let Some(key) = toks.next() else { continue };
        match key {
            b"v" => {
                let mut vals = [0.0f64; 7];
                let mut k = 0;
                for t in toks {
                    if k == 7 {
                        return Err(perr(path, pos, "a vertex has more than 7 values (x y z [w | r g b])"));
                    }
                    vals[k] = coord(path, pos, t)?;
                    k += 1;
                }
                match k {
                    3 | 4 => {}
                    // Colours are kept only while every vertex so far has one (dropped below otherwise).
                    6 | 7 if colors.len() == positions.len() => {
                        colors.push([unit_to_u8(vals[3]), unit_to_u8(vals[4]), unit_to_u8(vals[5])]);
                    }
                    6 | 7 => {}
                    _ => {
                        return Err(perr(
                            path,
                            pos,
                            format!("a vertex needs x y z (optionally w, or r g b), found {k} values"),
                        ));
                    }
                }
                positions.push([vals[0], vals[1], vals[2]]);
            }
            b"vn" => {
                let mut n = [0.0; 3];
                let mut k = 0;
                for t in toks {
                    if k == 3 {
                        return Err(perr(path, pos, "a normal (vn) has more than 3 values"));
                    }
                    n[k] = coord(path, pos, t)?;
                    k += 1;
                }
                if k != 3 {
                    return Err(perr(path, pos, format!("a normal (vn) needs 3 values, found {k}")));
                }
                vn.push(n);
            }
            b"f" => {
                corners.clear();
                for t in toks {
                    corners.push(parse_corner(path, pos, t, positions.len(), vn.len())?);
                }
                polygon.clear();
                for c in &corners {
                    if c.v as usize >= positions.len() && forward_v.is_none_or(|(m, _)| c.v > m) {
                        forward_v = Some((c.v, ln));
                    }
                    polygon.push(c.v);
                    if c.n != NONE {
                        if c.n as usize >= vn.len() && forward_n.is_none_or(|(m, _)| c.n > m) {
                            forward_n = Some((c.n, ln));
                        }
                        let v = c.v as usize;
                        if normal_of.len() <= v {
                            normal_of.resize(v + 1, NONE);
                            normal_sum.resize(v + 1, [0.0; 3]);
                            mixed.resize(v + 1, false);
                        }
                        let old = normal_of[v];
                        if old == NONE {
                            normal_of[v] = c.n;
                        } else if old != c.n && vn.get(old as usize) != vn.get(c.n as usize) {
                            mixed[v] = true;
                        }
                        match vn.get(c.n as usize) {
                            Some(&q) => normal_sum[v] = crate::geometry::add(normal_sum[v], q),
                            None => pending.push((c.v, c.n)),
                        }
                    }
                }
                faces.add(&polygon, || pos);
            }
            _ => {
                check_utf8(path, ln, raw, "OBJ")?;
                match key {
                    b"vt" => texture_coordinates += 1,
                    b"usemtl" | b"mtllib" => materials += 1,
                    b"vp" | b"o" | b"g" | b"s" | b"l" | b"p" => {}
                    other => {
                        let other = String::from_utf8_lossy(other).into_owned();
                        match ignored.iter_mut().find(|(k, _)| *k == other) {
                            Some((_, n)) => *n += 1,
                            None => ignored.push((other, 1)),
                        }
                    }
                }
            }
        }
    }
    if !carry.is_empty() {
        return Err(perr(
            path,
            Position::Line(carry_line),
            "the file ends inside a statement continued with a backslash (\\)",
        ));
    }

    let nv = positions.len();
    if let Some((i, ln)) = forward_v.filter(|&(i, _)| i as usize >= nv) {
        return Err(perr(
            path,
            Position::Line(ln),
            format!("a face refers to vertex {}, but the file has only {nv} vertices", i as u64 + 1),
        ));
    }
    if let Some((i, ln)) = forward_n.filter(|&(i, _)| i as usize >= vn.len()) {
        return Err(perr(
            path,
            Position::Line(ln),
            format!("a face refers to normal {}, but the file has only {} normals", i as u64 + 1, vn.len()),
        ));
    }
    super::common::check_vertex_count(path, Position::Whole, nv as u64)?;

    let mut warnings = Vec::new();
    let (triangles, source_faces) = faces.finish(path, &positions, &mut warnings)?;

    let colors = if colors.is_empty() {
        None
    } else if colors.len() == nv {
        Some(colors)
    } else {
        warnings.push(format!("dropped vertex colours: only {} of {nv} vertices have one", colors.len()));
        None
    };

    let normals = if !normal_of.is_empty() {
        for (v, n) in pending {
            normal_sum[v as usize] = crate::geometry::add(normal_sum[v as usize], vn[n as usize]);
            mixed[v as usize] |= vn[n as usize] != vn[normal_of[v as usize] as usize];
        }
        let missing = (0..nv).filter(|&v| normal_of.get(v).is_none_or(|&n| n == NONE)).count();
        if missing == 0 {
            let averaged = mixed.iter().filter(|&&m| m).count();
            if averaged > 0 {
                warnings.push(format!(
                    "averaged the normals of {averaged} vertices that faces use with different normals \
                     (OBJ vertices are not split)"
                ));
            }
            // A vertex used with one normal keeps it exactly; mixed ones get the normalised mean.
            Some(
                (0..nv)
                    .map(|v| {
                        if mixed[v] {
                            crate::geometry::normalize(normal_sum[v]).unwrap_or([0.0; 3])
                        } else {
                            vn[normal_of[v] as usize]
                        }
                    })
                    .collect(),
            )
        } else {
            warnings.push(format!("dropped normals: {missing} of {nv} vertices are used with none"));
            None
        }
    } else if !vn.is_empty() && vn.len() == nv {
        Some(vn)
    } else {
        if !vn.is_empty() {
            warnings.push(format!(
                "ignored {} normals: faces name none and their number differs from the {nv} vertices",
                vn.len()
            ));
        }
        None
    };

    if texture_coordinates > 0 {
        warnings.push(format!(
            "ignored {texture_coordinates} texture coordinate {} (vt): Motif keeps positions, normals and colours only",
            if texture_coordinates == 1 { "line" } else { "lines" }
        ));
    }
    if materials > 0 {
        warnings.push(format!(
            "ignored {materials} material {} (usemtl, mtllib)",
            if materials == 1 { "line" } else { "lines" }
        ));
    }
    for (k, n) in ignored {
        warnings.push(format!("ignored {n} lines with the unsupported keyword {k:?}"));
    }

    Ok(Model {
        vertices: PointCloud { positions, normals, colors, attributes: Vec::new() },
        triangles,
        source_faces,
        format: Format::Obj,
        warnings,
    })
}

/// Parses `i`, `i/t`, `i//n` or `i/t/n` into 0-based indices, resolving negative ones against
/// the counts so far.
#[inline]
fn parse_corner(path: &Path, pos: Position, token: &[u8], nv: usize, nn: usize) -> Result<Corner> {
    let mut parts = token.split(|&b| b == b'/');
    let v = parts.next().unwrap_or(b"");
    let _t = parts.next();
    let n = parts.next();
    if parts.next().is_some() {
        return Err(perr(
            path,
            pos,
            format!("bad face corner {}: expected i, i/t, i//n or i/t/n", show(token)),
        ));
    }
    let v = resolve(path, pos, v, nv, "vertex")?;
    let n = match n {
        Some(n) if !n.is_empty() => resolve(path, pos, n, nn, "normal")?,
        _ => NONE,
    };
    Ok(Corner { v, n })
}

#[inline]
fn resolve(path: &Path, pos: Position, token: &[u8], count: usize, what: &str) -> Result<u32> {
    let Some(i) = super::common::parse_i64(token) else {
        return Err(perr(path, pos, bad_number(token, &format!("a {what} index"))));
    };
    let r = if i > 0 {
        i - 1
    } else if i < 0 {
        let r = count as i64 + i;
        if r < 0 {
            return Err(perr(
                path,
                pos,
                format!("relative {what} index {i} reaches before the first {what} (only {count} so far)"),
            ));
        }
        r
    } else {
        return Err(perr(path, pos, format!("{what} index 0 is invalid: OBJ indices start at 1")));
    };
    if r >= NONE as i64 {
        return Err(perr(path, pos, format!("{what} index {i} is out of range")));
    }
    Ok(r as u32)
}

/// Writes `v x y z [r g b]`, `vn`, and `f a b c` (or `f a//a b//b c//c` with normals); positions
/// with the shortest decimal that reads back exactly.
pub(super) fn write(w: &mut dyn Write, cloud: &PointCloud, triangles: &[[u32; 3]]) -> io::Result<()> {
    writeln!(w, "# written by Motif: {} vertices, {} triangles", cloud.len(), triangles.len())?;
    for (i, p) in cloud.positions.iter().enumerate() {
        write!(w, "v {:?} {:?} {:?}", p[0], p[1], p[2])?;
        if let Some(c) = &cloud.colors {
            let c = c[i];
            // Four decimals recover the 8-bit value exactly (three would, just).
            write!(w, " {:.4} {:.4} {:.4}", c[0] as f64 / 255.0, c[1] as f64 / 255.0, c[2] as f64 / 255.0)?;
        }
        writeln!(w)?;
    }
    if let Some(normals) = &cloud.normals {
        for n in normals {
            writeln!(w, "vn {:?} {:?} {:?}", n[0], n[1], n[2])?;
        }
    }
    let with_normals = cloud.normals.is_some();
    for t in triangles {
        let [a, b, c] = t.map(|i| i as u64 + 1);
        if with_normals {
            writeln!(w, "f {a}//{a} {b}//{b} {c}//{c}")?;
        } else {
            writeln!(w, "f {a} {b} {c}")?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Error;

    fn parse(s: &str) -> Result<Model> {
        read(s.as_bytes(), Path::new("t.obj"))
    }

    fn line_of(e: Error) -> usize {
        match e {
            Error::Parse { position: Position::Line(l), .. } => l,
            e => panic!("expected a parse error with a line, got {e:?}"),
        }
    }

    #[test]
    fn corners_of_every_form_and_relative_indices() {
        let m = parse(
            "# cube corner\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n\
             f 1/1/1 2/1/1 3/1/1\nf -4//1 -2//1 -1//1\nf 1/1 2/1 3/1 4/1\nl 1 2\ng grp\ns off\nusemtl m\n",
        )
        .unwrap();
        assert_eq!(m.source_faces, 3);
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 1, 2], [0, 2, 3]]);
        assert_eq!(m.vertices.normals.as_ref().unwrap()[1], [0.0, 0.0, 1.0]);
        // Groups, smoothing and lines pass without a word; what an output would lack is named.
        assert_eq!(
            m.warnings,
            [
                "ignored 1 texture coordinate line (vt): Motif keeps positions, normals and colours only",
                "ignored 1 material line (usemtl, mtllib)"
            ]
        );
    }

    #[test]
    fn a_backslash_continues_a_statement_on_the_next_line() {
        let m = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 \\\n 3\nv \\\r\n 1 1 0\nf 2 4 3\n").unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2], [1, 3, 2]]);
        assert_eq!(m.vertices.positions[3], [1.0, 1.0, 0.0]);
        // An error in a continued statement is reported at its first line.
        assert_eq!(line_of(parse("v 0 0 0\nv 1 \\\n x 0\n").unwrap_err()), 2);
        assert_eq!(line_of(parse("v 0 0 0\nf 1 \\\n").unwrap_err()), 2);
        // A comment ending in a backslash ends at its line.
        let m = parse("# C:\\models\\\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
        assert_eq!(m.vertices.positions.len(), 3);
    }

    #[test]
    fn colours_and_points_only() {
        let m = parse("v 0 0 0 1 0 0\nv 1 0 0 0 0.5 1\n").unwrap();
        assert!(!m.is_mesh());
        assert_eq!(m.vertices.colors, Some(vec![[255, 0, 0], [0, 128, 255]]));
    }

    #[test]
    fn bad_input_names_the_line() {
        assert_eq!(line_of(parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n").unwrap_err()), 4);
        assert_eq!(line_of(parse("v 0 0 0\nv nan 0 0\n").unwrap_err()), 2);
        assert_eq!(line_of(parse("v 0 0 0\nv 1 0\n").unwrap_err()), 2);
        assert_eq!(line_of(parse("v 0 0 0\nf 0 1 1\n").unwrap_err()), 2);
        assert_eq!(line_of(parse("v 0 0 0\nf -2 1 1\n").unwrap_err()), 2);
        assert_eq!(line_of(parse("v 0 0 0\nf 1 1 x\n").unwrap_err()), 2);
        assert_eq!(line_of(read(b"v 0 0 0\ng \xff\xfe\n", Path::new("t.obj")).unwrap_err()), 2);
        // Non-UTF-8 in a comment is harmless.
        assert!(read(b"# caf\xe9\nv 0 0 0\n", Path::new("t.obj")).is_ok());
    }

    #[test]
    fn degenerate_faces_are_dropped_with_a_warning() {
        let m = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 1 2\nf 1 2\n").unwrap();
        assert_eq!((m.triangles.len(), m.source_faces), (1, 3));
        assert!(m.warnings[0].contains("dropped 2 degenerate faces"), "{:?}", m.warnings);
        assert_eq!(line_of(parse("v 0 0 0\nv 1 0 0\nf 1 2 2\n").unwrap_err()), 3);
    }

    #[test]
    fn forward_references_resolve_at_the_end() {
        let m = parse("f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n").unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
    }
}
