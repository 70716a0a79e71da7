//! STL, ASCII and binary, told apart by content: a binary file may begin with `solid` too, so a
//! file is binary when `84 + 50·n` equals its size (`n` = the triangle count at byte 80) and it
//! does not parse as text. Corners are welded by exact position (+0 and −0 are one position),
//! which is how the shared test manifest counts STL vertices; facet normals are not kept (they
//! are recomputed on write).

use std::io::{self, Write};
use std::path::Path;

use super::common::{FaceSink, Lines, check_utf8, coord, perr, show, tokens};
use super::{Format, Model, StlEncoding};
use crate::error::Position;
use crate::geometry::{Point3, cross, normalize, sub};
use crate::mesh::weld_map;
use crate::{Error, PointCloud, Result};

const HEADER: usize = 84;
const RECORD: usize = 50;

pub(super) fn read(bytes: &[u8], path: &Path) -> Result<Model> {
    let declared = (bytes.len() >= HEADER)
        .then(|| u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as u64);
    let binary_size_matches =
        declared.is_some_and(|n| HEADER as u64 + RECORD as u64 * n == bytes.len() as u64);
    // ASCII STL saved with a UTF-8 byte-order mark; a binary header may hold any bytes, so the
    // mark is dropped only when text follows it.
    let text = bytes.strip_prefix(super::obj::UTF8_BOM).unwrap_or(bytes);
    // Keywords are matched regardless of case: some exporters write `SOLID` / `FACET`.
    let starts_solid = text.trim_ascii_start().get(..5).is_some_and(|h| h.eq_ignore_ascii_case(b"solid"));
    if starts_solid {
        match read_ascii(text, path) {
            Ok(m) => return Ok(m),
            // A binary file whose header happens to begin with "solid".
            Err(_) if binary_size_matches => {}
            // Text that looks like text: its error is the useful one.
            Err(e) if !bytes[..bytes.len().min(HEADER)].contains(&0) || declared.is_none() => return Err(e),
            Err(_) => {}
        }
    }
    read_binary(bytes, path)
}

fn read_binary(bytes: &[u8], path: &Path) -> Result<Model> {
    if bytes.len() < HEADER {
        return Err(perr(
            path,
            Position::Byte(bytes.len() as u64),
            format!(
                "too short for a binary STL ({} bytes; the header alone is 84) and not ASCII STL (no \"solid\")",
                bytes.len()
            ),
        ));
    }
    let n = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as usize;
    let available = (bytes.len() - HEADER) / RECORD;
    if n > available {
        return Err(perr(
            path,
            Position::Byte((HEADER + available * RECORD) as u64),
            format!(
                "the header announces {n} triangles ({} bytes), but the file has {} bytes: it ends after {available} \
                 triangles (truncated?)",
                HEADER as u64 + RECORD as u64 * n as u64,
                bytes.len()
            ),
        ));
    }
    let mut warnings = Vec::new();
    let extra = bytes.len() - HEADER - n * RECORD;
    if extra > 0 {
        warnings.push(format!("ignored {extra} bytes after the {n} triangles the header announces"));
    }
    let mut corners: Vec<Point3> = Vec::with_capacity(3 * n);
    for t in 0..n {
        let rec = &bytes[HEADER + t * RECORD..HEADER + (t + 1) * RECORD];
        for k in 0..3 {
            let off = 12 + 12 * k;
            let c = |j: usize| {
                let o = off + 4 * j;
                f32::from_le_bytes([rec[o], rec[o + 1], rec[o + 2], rec[o + 3]]) as f64
            };
            let p = [c(0), c(1), c(2)];
            if !crate::geometry::is_finite(p) {
                return Err(perr(
                    path,
                    Position::Byte((HEADER + t * RECORD + off) as u64),
                    format!("triangle {t} has a NaN or infinite coordinate"),
                ));
            }
            corners.push(p);
        }
    }
    let facets = (0..n).map(|t| (3 * t..3 * t + 3, Position::Byte((HEADER + t * RECORD) as u64)));
    weld(corners, facets, path, warnings)
}

fn read_ascii(bytes: &[u8], path: &Path) -> Result<Model> {
    let mut corners: Vec<Point3> = Vec::new();
    // Corner range and line of each facet.
    let mut facets: Vec<(std::ops::Range<usize>, Position)> = Vec::new();
    let mut in_facet: Option<(usize, usize)> = None;
    let mut ended = false;
    let lines = Lines::new(bytes);
    let mut last = 1;
    for (ln, line) in lines {
        last = ln;
        let pos = Position::Line(ln);
        let mut toks = tokens(line);
        let Some(key) = toks.next() else { continue };
        // Keywords in any case (`FACET NORMAL`, `Vertex`); at most 8 bytes, lowered on the stack.
        let mut lowered = [0u8; 8];
        let key: &[u8] = if key.len() <= lowered.len() {
            lowered[..key.len()].copy_from_slice(key);
            lowered[..key.len()].make_ascii_lowercase();
            &lowered[..key.len()]
        } else {
            key
        };
        match key {
            b"solid" => {
                check_utf8(path, ln, line, "ASCII STL")?;
                ended = false;
            }
            b"facet" => {
                if in_facet.is_some() {
                    return Err(perr(
                        path,
                        pos,
                        "a facet begins before the previous one ended (missing endfacet)",
                    ));
                }
                in_facet = Some((corners.len(), ln));
            }
            b"outer" | b"endloop" => {}
            b"vertex" => {
                if in_facet.is_none() {
                    return Err(perr(path, pos, "a vertex outside a facet"));
                }
                let mut p = [0.0; 3];
                for c in &mut p {
                    let Some(t) = toks.next() else {
                        return Err(perr(path, pos, "a vertex needs 3 coordinates"));
                    };
                    *c = coord(path, pos, t)?;
                }
                corners.push(p);
            }
            b"endfacet" => {
                let Some((start, fl)) = in_facet.take() else {
                    return Err(perr(path, pos, "endfacet without facet"));
                };
                facets.push((start..corners.len(), Position::Line(fl)));
            }
            b"endsolid" => ended = true,
            other => {
                check_utf8(path, ln, line, "ASCII STL")?;
                return Err(perr(
                    path,
                    pos,
                    format!(
                        "expected facet, outer loop, vertex, endloop, endfacet or endsolid, found {}",
                        show(other)
                    ),
                ));
            }
        }
    }
    if in_facet.is_some() {
        return Err(perr(path, Position::Line(last), "the file ends inside a facet (truncated?)"));
    }
    let mut warnings = Vec::new();
    if !ended {
        warnings.push("the ASCII STL has no endsolid line (truncated?)".to_string());
    }
    weld(corners, facets.into_iter(), path, warnings)
}

/// Merges corners at exactly equal positions and builds the faces.
fn weld(
    corners: Vec<Point3>,
    facets: impl Iterator<Item = (std::ops::Range<usize>, Position)>,
    path: &Path,
    mut warnings: Vec<String>,
) -> Result<Model> {
    let (remap, kept) = weld_map(&corners, 0.0);
    super::common::check_vertex_count(path, Position::Whole, kept as u64)?;
    let mut positions = vec![[0.0; 3]; kept];
    for (i, &r) in remap.iter().enumerate().rev() {
        // Reverse order so the first corner of each cluster is the one kept.
        positions[r as usize] = corners[i];
    }
    let mut faces = FaceSink::with_capacity(corners.len() / 3);
    let mut polygon = Vec::with_capacity(3);
    for (range, pos) in facets {
        polygon.clear();
        polygon.extend(remap[range].iter().copied());
        faces.add(&polygon, || pos);
    }
    let (triangles, source_faces) = faces.finish(path, &positions, &mut warnings)?;
    Ok(Model {
        vertices: PointCloud::from_positions(positions),
        triangles,
        source_faces,
        format: Format::Stl,
        warnings,
    })
}

/// STL stores triangles only, and binary STL single-precision coordinates: a coordinate beyond
/// f32's range (about 3.4e38) would be written as infinite, in a file no reader (Motif's
/// included) accepts.
pub(super) fn check(triangles: &[[u32; 3]], positions: &[[f64; 3]], encoding: StlEncoding) -> Result<()> {
    if encoding == StlEncoding::Binary
        && let Some(c) =
            triangles.iter().flatten().flat_map(|&i| positions[i as usize]).find(|c| !(*c as f32).is_finite())
    {
        return Err(Error::InvalidInput(format!(
            "coordinate {c:e} does not fit the f32 coordinates of binary STL (at most about 3.4e38): \
             rescale the model, or write ASCII STL (--stl-encoding ascii) or another format"
        )));
    }
    if triangles.is_empty() {
        return Err(Error::InvalidInput(
            "STL stores triangles only; write a point cloud as .ply (or .obj/.off)".to_string(),
        ));
    }
    if triangles.len() > u32::MAX as usize {
        return Err(Error::InvalidInput(format!("{} triangles do not fit a binary STL", triangles.len())));
    }
    Ok(())
}

/// Writes binary (f32 coordinates) or ASCII STL; facet normals are computed from the corners.
pub(super) fn write(
    w: &mut dyn Write,
    cloud: &PointCloud,
    triangles: &[[u32; 3]],
    encoding: StlEncoding,
) -> io::Result<()> {
    let p = &cloud.positions;
    let normal = |t: &[u32; 3]| {
        let [a, b, c] = t.map(|i| p[i as usize]);
        normalize(cross(sub(b, a), sub(c, a))).unwrap_or([0.0; 3])
    };
    match encoding {
        StlEncoding::Binary => {
            // The header must not start with "solid", or readers may take the file for text.
            let mut header = [b' '; 80];
            header[..22].copy_from_slice(b"binary STL from Motif ");
            w.write_all(&header)?;
            w.write_all(&(triangles.len() as u32).to_le_bytes())?;
            let mut rec = [0u8; RECORD];
            for t in triangles {
                let vals = std::iter::once(normal(t)).chain(t.iter().map(|&i| p[i as usize]));
                for (k, v) in vals.enumerate() {
                    for j in 0..3 {
                        let o = 12 * k + 4 * j;
                        rec[o..o + 4].copy_from_slice(&(v[j] as f32).to_le_bytes());
                    }
                }
                w.write_all(&rec)?;
            }
        }
        StlEncoding::Ascii => {
            writeln!(w, "solid motif")?;
            for t in triangles {
                let n = normal(t);
                writeln!(w, "  facet normal {:?} {:?} {:?}\n    outer loop", n[0], n[1], n[2])?;
                for &i in t {
                    let v = p[i as usize];
                    writeln!(w, "      vertex {:?} {:?} {:?}", v[0], v[1], v[2])?;
                }
                writeln!(w, "    endloop\n  endfacet")?;
            }
            writeln!(w, "endsolid motif")?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn binary(tris: &[[[f32; 3]; 3]], header_start: &[u8]) -> Vec<u8> {
        let mut b = vec![0u8; 80];
        b[..header_start.len()].copy_from_slice(header_start);
        b.extend((tris.len() as u32).to_le_bytes());
        for t in tris {
            b.extend([0u8; 12]);
            for c in t {
                for x in c {
                    b.extend(x.to_le_bytes());
                }
            }
            b.extend([0u8; 2]);
        }
        b
    }

    const TWO: [[[f32; 3]; 3]; 2] =
        [[[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]], [[1., 0., 0.], [1., 1., 0.], [0., 1., -0.]]];

    #[test]
    fn binary_starting_with_solid_is_binary_and_welded() {
        let m = read(&binary(&TWO, b"solid trap"), Path::new("t.stl")).unwrap();
        assert_eq!((m.vertices.len(), m.triangles.len(), m.source_faces), (4, 2, 2));
        assert_eq!(m.triangles, vec![[0, 1, 2], [1, 3, 2]]);
    }

    #[test]
    fn ascii_parses_and_truncation_is_reported() {
        let s = "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n\
                 endsolid x\n";
        let m = read(s.as_bytes(), Path::new("t.stl")).unwrap();
        assert_eq!(m.triangles.len(), 1);
        let e = read(&s.as_bytes()[..60], Path::new("t.stl")).unwrap_err();
        assert!(matches!(e, Error::Parse { position: Position::Line(5), .. }), "{e:?}");
        let mut b = binary(&TWO, b"model");
        b.truncate(b.len() - 7);
        let e = read(&b, Path::new("t.stl")).unwrap_err();
        assert!(matches!(e, Error::Parse { position: Position::Byte(134), .. }), "{e:?}");
    }
}
