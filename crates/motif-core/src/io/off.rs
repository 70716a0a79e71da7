//! Geomview OFF: `OFF`, `COFF` (vertex colours), `NOFF` (vertex normals), `CNOFF`, and the
//! texture-coordinate prefix `ST` (read past). The counts may stand on the header line; `#`
//! comments may appear anywhere. Faces are `k i1 … ik` optionally followed by a face colour,
//! which is read past. `4OFF`/`nOFF` (other dimensions) and binary OFF are rejected with a clear
//! error.
//!
//! Records are read one per line, which is what lets a face's trailing colour be told apart
//! from the next face.

use std::io::{self, Write};
use std::path::Path;

use super::common::{
    FaceSink, Lines, bad_number, check_utf8, coord, parse_f64, parse_i64, perr, show, strip_comment, tokens,
};
use super::{Format, Model};
use crate::error::Position;
use crate::{PointCloud, Result};

/// Which optional per-vertex fields the header announces.
#[derive(Debug, Clone, Copy, Default)]
struct Header {
    texture: bool,
    color: bool,
    normal: bool,
}

pub(super) fn read(bytes: &[u8], path: &Path) -> Result<Model> {
    let mut lines = Lines::new(bytes);
    let mut toks: Vec<&[u8]> = Vec::with_capacity(16);
    let Some(hl) = next_record(&mut lines, path, &mut toks)? else {
        return Err(perr(
            path,
            Position::Whole,
            "no OFF header: the file holds only blank lines and comments",
        ));
    };
    let htoks = toks.clone();
    let header = parse_header(path, hl, htoks[0])?;
    if htoks.get(1).is_some_and(|t| t.eq_ignore_ascii_case(b"BINARY")) {
        return Err(perr(
            path,
            Position::Line(hl),
            "binary OFF is not supported; convert it to text OFF or PLY",
        ));
    }
    let (cl, ctoks) = if htoks.len() > 1 {
        (hl, htoks[1..].to_vec())
    } else {
        match next_record(&mut lines, path, &mut toks)? {
            Some(l) => (l, toks.clone()),
            None => {
                return Err(perr(
                    path,
                    Position::Line(lines.line().max(1)),
                    "the file ends before the counts line",
                ));
            }
        }
    };
    if ctoks.len() < 2 {
        return Err(perr(path, Position::Line(cl), "expected the counts: #vertices #faces [#edges]"));
    }
    let count = |t: &[u8], what: &str| -> Result<u64> {
        match parse_i64(t) {
            Some(v) if v >= 0 => Ok(v as u64),
            _ => Err(perr(path, Position::Line(cl), bad_number(t, &format!("a non-negative {what} count")))),
        }
    };
    let nv = count(ctoks[0], "vertex")?;
    let nf = count(ctoks[1], "face")?;
    super::common::check_vertex_count(path, Position::Line(cl), nv)?;
    // Every vertex line needs at least "x y z\n" (6 bytes), every face line at least "k\n".
    let need = (nv as u128) * 6 + (nf as u128) * 2;
    let have = lines.remaining() as u128 + 1;
    if need > have {
        return Err(perr(
            path,
            Position::Line(cl),
            format!(
                "the counts announce {nv} vertices and {nf} faces, but only {} bytes follow, too few to hold \
                 them (is the file truncated?)",
                lines.remaining()
            ),
        ));
    }

    let nv = nv as usize;
    let mut positions = Vec::with_capacity(nv);
    let mut normals = header.normal.then(|| Vec::with_capacity(nv));
    let mut colors = header.color.then(|| Vec::with_capacity(nv));
    let mut any_real = false;
    let eof = |what: String, lines: &Lines<'_>| {
        perr(
            path,
            Position::Line(lines.line().max(1)),
            format!("the file ends after {what} (is it truncated?)"),
        )
    };
    for i in 0..nv {
        let Some(ln) = next_record(&mut lines, path, &mut toks)? else {
            return Err(eof(format!("{i} of {nv} {}", if nv == 1 { "vertex" } else { "vertices" }), &lines));
        };
        let pos = Position::Line(ln);
        let need = 3
            + if header.normal { 3 } else { 0 }
            + if header.color { 3 } else { 0 }
            + if header.texture { 2 } else { 0 };
        if toks.len() < need {
            return Err(perr(path, pos, format!("vertex {i} needs {need} values, found {}", toks.len())));
        }
        positions.push([coord(path, pos, toks[0])?, coord(path, pos, toks[1])?, coord(path, pos, toks[2])?]);
        let mut k = 3;
        if let Some(n) = &mut normals {
            n.push([coord(path, pos, toks[3])?, coord(path, pos, toks[4])?, coord(path, pos, toks[5])?]);
            k = 6;
        }
        if let Some(c) = &mut colors {
            let mut rgb = [(0.0, false); 3];
            for (j, v) in rgb.iter_mut().enumerate() {
                *v = color(path, pos, toks[k + j])?;
                any_real |= v.1;
            }
            c.push(rgb);
        }
    }
    // Colours are 0..1 reals or 0..255 integers for the whole file: one component written as a
    // real (`0.5`, `1.0`) makes a `1` elsewhere mean full intensity, not 1/255 (`%g` writes 1.0
    // as `1`). A file whose reals include one above 1 mixes the scales, and each number is then
    // read by its own form (integers 0..255, reals 0..1).
    let largest = colors.iter().flatten().flatten().filter(|v| v.1).fold(0.0f64, |m, v| m.max(v.0));
    let unit = any_real && largest <= 1.0 + 1e-6;
    let colors = colors.map(|c| {
        c.into_iter()
            .map(|rgb| {
                rgb.map(|(v, real)| {
                    if unit || real {
                        super::common::unit_to_u8(v)
                    } else {
                        v.clamp(0.0, 255.0).round() as u8
                    }
                })
            })
            .collect::<Vec<[u8; 3]>>()
    });

    let mut faces = FaceSink::with_capacity(nf.min(lines.remaining() as u64 / 2) as usize);
    let mut polygon = Vec::with_capacity(8);
    for f in 0..nf {
        let Some(ln) = next_record(&mut lines, path, &mut toks)? else {
            return Err(eof(format!("{f} of {nf} {}", if nf == 1 { "face" } else { "faces" }), &lines));
        };
        let pos = Position::Line(ln);
        let k = match parse_i64(toks[0]) {
            Some(k) if k >= 0 => k as usize,
            _ => return Err(perr(path, pos, bad_number(toks[0], "the face's vertex count"))),
        };
        if toks.len() < 1 + k {
            return Err(perr(
                path,
                pos,
                format!("face {f} announces {k} vertices but the line has only {}", toks.len() - 1),
            ));
        }
        polygon.clear();
        for t in &toks[1..=k] {
            match parse_i64(t) {
                Some(i) if i >= 0 && (i as u64) < nv as u64 => polygon.push(i as u32),
                Some(i) => {
                    return Err(perr(
                        path,
                        pos,
                        format!("face {f} refers to vertex {i}, but the file has {nv} vertices (0-based)"),
                    ));
                }
                None => return Err(perr(path, pos, bad_number(t, "a vertex index"))),
            }
        }
        // Anything after the indices is the face colour, which Motif does not keep.
        faces.add(&polygon, || pos);
    }

    let mut warnings = Vec::new();
    let (triangles, source_faces) = faces.finish(path, &positions, &mut warnings)?;
    Ok(Model {
        vertices: PointCloud { positions, normals, colors, attributes: Vec::new() },
        triangles,
        source_faces,
        format: Format::Off,
        warnings,
    })
}

/// Moves to the next line with content (comments removed), leaving its tokens in `toks`;
/// returns its number, or `None` at the end of the file.
fn next_record<'a>(lines: &mut Lines<'a>, path: &Path, toks: &mut Vec<&'a [u8]>) -> Result<Option<usize>> {
    for (ln, raw) in lines.by_ref() {
        let line = strip_comment(raw);
        check_utf8(path, ln, line, "OFF")?;
        toks.clear();
        toks.extend(tokens(line));
        if !toks.is_empty() {
            return Ok(Some(ln));
        }
    }
    Ok(None)
}

/// Parses `[ST][C][N]OFF`; rejects `4OFF`, `nOFF` and anything else.
fn parse_header(path: &Path, ln: usize, tok: &[u8]) -> Result<Header> {
    let pos = Position::Line(ln);
    let Some(mut prefix) = tok.strip_suffix(b"OFF") else {
        return Err(perr(
            path,
            pos,
            format!("not an OFF file: expected a header OFF, COFF, NOFF or CNOFF, found {}", show(tok)),
        ));
    };
    let mut h = Header::default();
    if let Some(r) = prefix.strip_prefix(b"ST") {
        h.texture = true;
        prefix = r;
    }
    if let Some(r) = prefix.strip_prefix(b"C") {
        h.color = true;
        prefix = r;
    }
    if let Some(r) = prefix.strip_prefix(b"N") {
        h.normal = true;
        prefix = r;
    }
    if prefix.is_empty() {
        Ok(h)
    } else if prefix.ends_with(b"4") || prefix.ends_with(b"n") {
        Err(perr(
            path,
            pos,
            format!(
                "{} (homogeneous or n-dimensional OFF) is not supported; only 3-D OFF, COFF, NOFF and CNOFF are",
                show(tok)
            ),
        ))
    } else {
        Err(perr(path, pos, format!("unknown OFF header {}", show(tok))))
    }
}

/// A colour component and whether it was written as a real (0..1) rather than an integer
/// (0..255); which scale applies is decided for the whole file.
fn color(path: &Path, pos: Position, t: &[u8]) -> Result<(f64, bool)> {
    if let Some(i) = parse_i64(t) {
        return Ok((i.clamp(0, 255) as f64, false));
    }
    match parse_f64(t) {
        Some(v) if v.is_finite() => Ok((v, true)),
        _ => Err(perr(path, pos, bad_number(t, "a colour component"))),
    }
}

/// Writes `OFF` (`NOFF`, `COFF`, `CNOFF` when normals or colours are present), positions with
/// the shortest decimal that reads back exactly, colours as 0..255 integers with alpha 255.
pub(super) fn write(w: &mut dyn Write, cloud: &PointCloud, triangles: &[[u32; 3]]) -> io::Result<()> {
    let c = if cloud.colors.is_some() { "C" } else { "" };
    let n = if cloud.normals.is_some() { "N" } else { "" };
    writeln!(w, "{c}{n}OFF")?;
    writeln!(w, "{} {} 0", cloud.len(), triangles.len())?;
    for (i, p) in cloud.positions.iter().enumerate() {
        write!(w, "{:?} {:?} {:?}", p[0], p[1], p[2])?;
        if let Some(nr) = &cloud.normals {
            let q = nr[i];
            write!(w, " {:?} {:?} {:?}", q[0], q[1], q[2])?;
        }
        if let Some(col) = &cloud.colors {
            let q = col[i];
            write!(w, " {} {} {} 255", q[0], q[1], q[2])?;
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
    use crate::Error;

    fn parse(s: &str) -> Result<Model> {
        read(s.as_bytes(), Path::new("t.off"))
    }

    fn line_of(e: Error) -> usize {
        match e {
            Error::Parse { position: Position::Line(l), .. } => l,
            e => panic!("expected a parse error with a line, got {e:?}"),
        }
    }

    #[test]
    fn variants_comments_and_face_colours() {
        let m = parse("# c\nOFF 4 1 0\n0 0 0\n1 0 0 # x\n\n1 1 0\n0 1 0\n4 0 1 2 3 255 0 0\n").unwrap();
        assert_eq!((m.triangles.len(), m.source_faces), (2, 1));
        let m =
            parse("CNOFF\n3 1\n0 0 0 0 0 1 255 0 0\n1 0 0 0 0 1 0 1.0 0\n0 1 0 0 0 1 0 0 255 255\n3 0 1 2\n")
                .unwrap();
        assert_eq!(m.vertices.colors.unwrap(), vec![[255, 0, 0], [0, 255, 0], [0, 0, 255]]);
        assert_eq!(m.vertices.normals.unwrap()[2], [0.0, 0.0, 1.0]);
        // 0..1 colours written with %g: a `1` is full intensity once any component is a real.
        let m =
            parse("COFF\n3 1 0\n0 0 0 1 1 1 1\n1 0 0 0.5 0.5 0.5 1\n0 1 0 1.0 0 1 1.0\n3 0 1 2\n").unwrap();
        assert_eq!(m.vertices.colors.unwrap(), vec![[255, 255, 255], [128, 128, 128], [255, 0, 255]]);
        // All integers: the 0..255 scale.
        let m = parse("COFF\n3 1 0\n0 0 0 1 1 1\n1 0 0 128 0 0\n0 1 0 0 0 255\n3 0 1 2\n").unwrap();
        assert_eq!(m.vertices.colors.unwrap(), vec![[1, 1, 1], [128, 0, 0], [0, 0, 255]]);
    }

    #[test]
    fn bad_input_names_the_line() {
        assert_eq!(line_of(parse("4OFF\n1 0 0\n0 0 0 1\n").unwrap_err()), 1);
        assert_eq!(line_of(parse("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n").unwrap_err()), 6);
        // Counts too large for the bytes that follow: caught at the counts line.
        assert_eq!(line_of(parse("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n").unwrap_err()), 2);
        // Plausible counts, but the file stops early: caught at its last line.
        assert_eq!(line_of(parse("OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n").unwrap_err()), 6);
        assert_eq!(line_of(parse("OFF\n1000000 1 0\n0 0 0\n").unwrap_err()), 2);
        assert_eq!(line_of(parse("OFF\n2 0 0\n0 0 0\n0 inf 0\n").unwrap_err()), 4);
        assert_eq!(line_of(parse("PLY\n").unwrap_err()), 1);
    }
}
