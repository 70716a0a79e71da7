//! Pieces shared by the hand-written parsers: a line cursor over raw bytes, strict number
//! parsing, the face collector that triangulates and drops degenerate faces, and size checks
//! that keep allocations bounded by the bytes actually present.

use std::path::Path;

use crate::error::Position;
use crate::{Error, Result};

/// Shorthand for a [`Error::Parse`].
pub(crate) fn perr(path: &Path, position: Position, message: impl Into<String>) -> Error {
    Error::parse(path, position, message)
}

/// A token as a user can read it in an error message: lossy UTF-8, at most 40 characters.
pub(crate) fn show(token: &[u8]) -> String {
    // A token cut at a byte count may end inside a character: that end is not a sign of binary.
    let token = match std::str::from_utf8(token) {
        Err(e) if e.error_len().is_none() => &token[..e.valid_up_to()],
        _ => token,
    };
    let s = String::from_utf8_lossy(token);
    // Bytes that are not text (a binary file, a wrong extension) are said to be so, rather than
    // printed as escapes and replacement characters. Line ends and tabs are text.
    if s.chars()
        .any(|c| c == char::REPLACEMENT_CHARACTER || (c.is_control() && !matches!(c, '\t' | '\n' | '\r')))
    {
        return "binary data, not text".to_string();
    }
    let mut out: String =
        s.chars().take(40).map(|c| if matches!(c, '\t' | '\n' | '\r') { ' ' } else { c }).collect();
    if s.chars().count() > 40 {
        out.push('…');
    }
    format!("\"{out}\"")
}

/// Iterates the lines of a text buffer as `(1-based line number, bytes without the line end)`.
pub(crate) struct Lines<'a> {
    bytes: &'a [u8],
    pos: usize,
    line: usize,
}

impl<'a> Lines<'a> {
    pub(crate) fn new(bytes: &'a [u8]) -> Self {
        Lines { bytes, pos: 0, line: 0 }
    }

    /// Bytes not yet returned.
    pub(crate) fn remaining(&self) -> usize {
        self.bytes.len() - self.pos
    }

    /// The number of the last line returned (0 before the first).
    pub(crate) fn line(&self) -> usize {
        self.line
    }
}

impl<'a> Iterator for Lines<'a> {
    type Item = (usize, &'a [u8]);

    #[inline]
    fn next(&mut self) -> Option<Self::Item> {
        if self.pos >= self.bytes.len() {
            return None;
        }
        let rest = &self.bytes[self.pos..];
        let (line, advance) = match rest.iter().position(|&b| b == b'\n') {
            Some(i) => (&rest[..i], i + 1),
            None => (rest, rest.len()),
        };
        self.pos += advance;
        self.line += 1;
        let line = line.strip_suffix(b"\r").unwrap_or(line);
        Some((self.line, line))
    }
}

/// Splits a line into whitespace-separated tokens.
#[inline]
pub(crate) fn tokens(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    line.split(|b| b.is_ascii_whitespace()).filter(|t| !t.is_empty())
}

/// The part of a line before a `#` comment.
#[inline]
pub(crate) fn strip_comment(line: &[u8]) -> &[u8] {
    match line.iter().position(|&b| b == b'#') {
        Some(i) => &line[..i],
        None => line,
    }
}

/// Checks that a line is UTF-8; the error says where the first bad byte is.
pub(crate) fn check_utf8(path: &Path, line_no: usize, line: &[u8], format: &str) -> Result<()> {
    match std::str::from_utf8(line) {
        Ok(_) => Ok(()),
        Err(e) => {
            let at = e.valid_up_to();
            Err(perr(
                path,
                Position::Line(line_no),
                format!(
                    "invalid UTF-8 (byte 0x{:02X} at column {}); {format} files must be UTF-8 text",
                    line[at],
                    at + 1
                ),
            ))
        }
    }
}

/// Parses a decimal real number; `None` when the token is not one. Accepts `nan`/`inf`, which the
/// callers then reject with a message of their own.
#[inline]
pub(crate) fn parse_f64(token: &[u8]) -> Option<f64> {
    std::str::from_utf8(token).ok()?.parse::<f64>().ok()
}

/// Parses a decimal integer with optional sign; `None` on anything else or overflow.
#[inline]
pub(crate) fn parse_i64(token: &[u8]) -> Option<i64> {
    let (neg, digits) = match token.first()? {
        b'-' => (true, &token[1..]),
        b'+' => (false, &token[1..]),
        _ => (false, token),
    };
    if digits.is_empty() {
        return None;
    }
    let mut v: i64 = 0;
    for &d in digits {
        if !d.is_ascii_digit() {
            return None;
        }
        v = v.checked_mul(10)?.checked_sub((d - b'0') as i64)?;
    }
    if neg { Some(v) } else { v.checked_neg() }
}

/// What went wrong with a token that should have been a number, in words.
pub(crate) fn bad_number(token: &[u8], expected: &str) -> String {
    if std::str::from_utf8(token).is_err() {
        format!("invalid UTF-8 where {expected} was expected (the file must be UTF-8 text)")
    } else {
        format!("expected {expected}, found {}", show(token))
    }
}

/// Parses a coordinate: a finite real number.
#[inline]
pub(crate) fn coord(path: &Path, pos: Position, token: &[u8]) -> Result<f64> {
    match parse_f64(token) {
        Some(v) if v.is_finite() => Ok(v),
        Some(_) => Err(perr(path, pos, format!("coordinate {} is NaN or infinite", show(token)))),
        None => Err(perr(path, pos, bad_number(token, "a number"))),
    }
}

/// Converts a vertex count to `u32` range (triangles index with `u32`).
pub(crate) fn check_vertex_count(path: &Path, pos: Position, count: u64) -> Result<()> {
    if count > u32::MAX as u64 {
        return Err(perr(
            path,
            pos,
            format!("{count} vertices is more than Motif can index (at most {})", u32::MAX),
        ));
    }
    Ok(())
}

/// A real colour component in 0..1 as an 8-bit value.
#[inline]
pub(crate) fn unit_to_u8(v: f64) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// Collects faces as stored in a file, triangulates polygons and drops degenerate ones.
///
/// A polygon is split as a fan from its first corner when it is added, which is what every
/// reader and writer of these formats does, and is right for a convex polygon. Once every
/// position is known ([`FaceSink::finish`]; PLY may list faces first), a concave polygon (a
/// corner turning against its Newell normal) is ear-clipped (earcut) in the plane across the
/// Newell normal's largest axis, relative to its first corner, and its fan triangles are replaced
/// in place, so that its triangles cover it without folding over one another whichever corner
/// the file lists first. Triangles keep the polygon's winding. A polygon with a repeated corner,
/// or one that earcut cannot split into n − 2 triangles covering its area (self-intersecting,
/// or two corners at one position), keeps its fan.
///
/// A face is degenerate when it yields no triangle with three distinct vertices (for a
/// triangle: fewer than 3 distinct indices). Degenerate faces are dropped and reported as a
/// warning; a file whose faces are all degenerate is an error (see [`FaceSink::finish`]).
#[derive(Debug, Default)]
pub(crate) struct FaceSink {
    pub(crate) triangles: Vec<[u32; 3]>,
    /// Faces as stored, degenerate ones included.
    pub(crate) source_faces: usize,
    degenerate_faces: usize,
    first_degenerate: Option<Position>,
    /// Triangles dropped from polygons that still gave at least one good triangle.
    degenerate_fan_triangles: usize,
    /// Polygons of more than three corners whose whole fan was kept: the index of their first
    /// triangle in `triangles` and their number of triangles (their corners are read back from
    /// the fan in `finish`).
    polygons: Vec<(usize, u32)>,
}

impl FaceSink {
    pub(crate) fn with_capacity(triangles: usize) -> Self {
        FaceSink { triangles: Vec::with_capacity(triangles), ..Default::default() }
    }

    /// Adds one polygon (indices already validated against the vertex count).
    #[inline]
    pub(crate) fn add(&mut self, polygon: &[u32], pos: impl FnOnce() -> Position) {
        self.source_faces += 1;
        if let [a, b, c] = *polygon {
            if a != b && b != c && a != c {
                self.triangles.push([a, b, c]);
            } else {
                self.degenerate(pos);
            }
            return;
        }
        let first = self.triangles.len();
        let mut good = 0;
        let mut bad = 0;
        if polygon.len() >= 3 {
            let a = polygon[0];
            for w in polygon[1..].windows(2) {
                let (b, c) = (w[0], w[1]);
                if a != b && b != c && a != c {
                    self.triangles.push([a, b, c]);
                    good += 1;
                } else {
                    bad += 1;
                }
            }
        }
        if good == 0 {
            self.degenerate(pos);
        } else {
            self.degenerate_fan_triangles += bad;
            if bad == 0 {
                self.polygons.push((first, good));
            }
        }
    }

    /// Replaces the fan `tris` (a polygon's n − 2 triangles from its first corner) by an ear
    /// clipping when the polygon is concave and earcut splits it cleanly. `corners`, `flat` and
    /// `ears` are scratch buffers.
    fn clip_concave(
        tris: &mut [[u32; 3]],
        positions: &[[f64; 3]],
        earcut: &mut earcut::Earcut<f64>,
        corners: &mut Vec<u32>,
        flat: &mut Vec<[f64; 2]>,
        ears: &mut Vec<u32>,
    ) {
        corners.clear();
        corners.extend_from_slice(&tris[0]);
        corners.extend(tris[1..].iter().map(|t| t[2]));
        let n = corners.len();
        let at = |v: u32| positions.get(v as usize).copied().unwrap_or([0.0; 3]);
        // Newell's normal, then the turn at each corner about it.
        let mut normal = [0.0; 3];
        for i in 0..n {
            let (p, q) = (at(corners[i]), at(corners[(i + 1) % n]));
            normal[0] += (p[1] - q[1]) * (p[2] + q[2]);
            normal[1] += (p[2] - q[2]) * (p[0] + q[0]);
            normal[2] += (p[0] - q[0]) * (p[1] + q[1]);
        }
        let concave = (0..n).any(|i| {
            let (u, v, w) = (at(corners[(i + n - 1) % n]), at(corners[i]), at(corners[(i + 1) % n]));
            let (a, b) = (crate::geometry::sub(v, u), crate::geometry::sub(w, v));
            crate::geometry::dot(crate::geometry::cross(a, b), normal) < 0.0
        });
        if !concave {
            return;
        }
        // A repeated corner (a fan may keep all its triangles with one: 4 5 6 5) keeps the fan.
        flat.clear();
        let mut sorted = std::mem::take(ears);
        sorted.clear();
        sorted.extend_from_slice(corners);
        sorted.sort_unstable();
        let distinct = sorted.windows(2).all(|w| w[0] != w[1]);
        *ears = sorted;
        if !distinct {
            return;
        }
        let axis = (0..3).max_by(|&a, &b| normal[a].abs().total_cmp(&normal[b].abs())).unwrap_or(2);
        let (d1, d2) = ((axis + 1) % 3, (axis + 2) % 3);
        // Relative to the first corner, so that far-off coordinates keep earcut's precision.
        let o = at(corners[0]);
        flat.extend(corners.iter().map(|&v| [at(v)[d1] - o[d1], at(v)[d2] - o[d2]]));
        earcut.earcut_slice(flat, &[], ears);
        if ears.len() != 3 * (n - 2) || earcut::deviation(flat.iter().copied(), &[], ears) >= 1e-9 {
            return;
        }
        let up = normal[axis].signum();
        for (t, e) in tris.iter_mut().zip(ears.chunks_exact(3)) {
            let (a, b, c) = (e[0] as usize, e[1] as usize, e[2] as usize);
            let area = (flat[b][0] - flat[a][0]) * (flat[c][1] - flat[a][1])
                - (flat[c][0] - flat[a][0]) * (flat[b][1] - flat[a][1]);
            *t = if area * up >= 0.0 {
                [corners[a], corners[b], corners[c]]
            } else {
                [corners[a], corners[c], corners[b]]
            };
        }
    }

    /// Adds one triangle strip (indices already validated): triangle `i` is `s[i], s[i+1],
    /// s[i+2]`, every other one reversed so that all face the same way. Triangles with a repeated
    /// vertex are left out without a warning: strips use them on purpose to turn or to join.
    pub(crate) fn add_strip(&mut self, strip: &[u32], pos: impl FnOnce() -> Position) {
        if strip.is_empty() {
            return;
        }
        self.source_faces += 1;
        let before = self.triangles.len();
        for (i, w) in strip.windows(3).enumerate() {
            let (a, b, c) = if i % 2 == 0 { (w[0], w[1], w[2]) } else { (w[1], w[0], w[2]) };
            if a != b && b != c && a != c {
                self.triangles.push([a, b, c]);
            }
        }
        if self.triangles.len() == before {
            self.degenerate(pos);
        }
    }

    fn degenerate(&mut self, pos: impl FnOnce() -> Position) {
        self.degenerate_faces += 1;
        if self.first_degenerate.is_none() {
            self.first_degenerate = Some(pos());
        }
    }

    /// Ear-clips the concave polygons (see the type's documentation), reports dropped faces as
    /// warnings; errors when there were faces but none survived.
    pub(crate) fn finish(
        mut self,
        path: &Path,
        positions: &[[f64; 3]],
        warnings: &mut Vec<String>,
    ) -> Result<(Vec<[u32; 3]>, usize)> {
        if !self.polygons.is_empty() {
            let (mut earcut, mut corners, mut flat, mut ears) =
                (earcut::Earcut::new(), Vec::new(), Vec::new(), Vec::new());
            for &(first, count) in &self.polygons {
                Self::clip_concave(
                    &mut self.triangles[first..first + count as usize],
                    positions,
                    &mut earcut,
                    &mut corners,
                    &mut flat,
                    &mut ears,
                );
            }
        }
        if self.source_faces > 0 && self.triangles.is_empty() {
            return Err(perr(
                path,
                self.first_degenerate.unwrap_or(Position::Whole),
                format!(
                    "all {} faces are degenerate (fewer than 3 distinct vertices), so there is no surface",
                    self.source_faces
                ),
            ));
        }
        if self.degenerate_faces > 0 {
            let at = match self.first_degenerate {
                Some(p) if p != Position::Whole => format!(", first at {p}"),
                _ => String::new(),
            };
            warnings.push(format!(
                "dropped {} degenerate faces (fewer than 3 distinct vertices{at})",
                self.degenerate_faces
            ));
        }
        if self.degenerate_fan_triangles > 0 {
            warnings.push(format!(
                "dropped {} degenerate triangles from polygons with repeated vertices",
                self.degenerate_fan_triangles
            ));
        }
        Ok((self.triangles, self.source_faces))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tokens_are_shown_as_text_or_said_to_be_binary() {
        assert_eq!(show(b"solid cube"), "\"solid cube\"");
        // Cut inside a two-byte character (é): still text, shown up to the cut.
        assert_eq!(show(&"Mxxx éxyz".as_bytes()[..6]), "\"Mxxx \"");
        // Line ends in a JSON glTF's first bytes are text too, shown as spaces.
        assert_eq!(show(b"{\n  \""), "\"{   \"\"");
        assert_eq!(show(&[0, 159, 146, 150, 7]), "binary data, not text");
        assert_eq!(show(&[0xff, b'a', b'b']), "binary data, not text");
    }

    #[test]
    fn integers_parse_strictly() {
        assert_eq!(parse_i64(b"-12"), Some(-12));
        assert_eq!(parse_i64(b"+7"), Some(7));
        assert_eq!(parse_i64(b"9223372036854775807"), Some(i64::MAX));
        assert_eq!(parse_i64(b"-9223372036854775808"), Some(i64::MIN));
        assert_eq!(parse_i64(b"9223372036854775808"), None);
        assert_eq!(parse_i64(b"1.0"), None);
        assert_eq!(parse_i64(b"-"), None);
        assert_eq!(parse_i64(b""), None);
    }

    #[test]
    fn lines_strip_crlf_and_count() {
        let v: Vec<_> = Lines::new(b"a\r\nb\n\nc").collect();
        assert_eq!(v, vec![(1, &b"a"[..]), (2, &b"b"[..]), (3, &b""[..]), (4, &b"c"[..])]);
    }

    #[test]
    fn polygons_fan_and_degenerates_drop() {
        let mut s = FaceSink::default();
        s.add(&[0, 1, 2, 3], || Position::Line(1));
        s.add(&[0, 0, 1], || Position::Line(2));
        s.add(&[4, 5, 4, 6], || Position::Line(3));
        let mut w = Vec::new();
        let square = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
        let (t, n) = s.finish(Path::new("x"), &square, &mut w).unwrap();
        assert_eq!(n, 3);
        assert_eq!(t, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].contains("dropped 2 degenerate faces") && w[0].contains("line 2"), "{w:?}");
    }

    /// A concave quad (a dart) covers its own area, facing the polygon's way, whichever corner
    /// is listed first; a fan from the reflex corner's neighbour used to fold over itself.
    #[test]
    fn concave_polygons_are_ear_clipped_from_any_first_corner() {
        // Also far from the origin, where earcut's area check needs coordinates relative to the
        // polygon.
        for shift in [0.0, 1e7] {
            concave_dart(shift);
        }
    }

    fn concave_dart(shift: f64) {
        let dart = [[0.0, 0.0, 0.0], [2.0, 1.0, 0.0], [0.0, 2.0, 0.0], [1.0, 1.0, 0.0]]
            .map(|p: [f64; 3]| [p[0] + shift, p[1] - shift, p[2] + shift]);
        for first in 0..4u32 {
            for reversed in [false, true] {
                let mut polygon: Vec<u32> = (0..4).map(|i| (first + i) % 4).collect();
                if reversed {
                    polygon.reverse();
                }
                let mut s = FaceSink::default();
                // A triangle before and after: the polygon's triangles stay in place.
                s.add(&[0, 1, 2], || Position::Line(1));
                s.add(&polygon, || Position::Line(2));
                s.add(&[0, 2, 3], || Position::Line(3));
                let (t, _) = s.finish(Path::new("x"), &dart, &mut Vec::new()).unwrap();
                assert_eq!(t.len(), 4, "{polygon:?}");
                assert_eq!((t[0], t[3]), ([0, 1, 2], [0, 2, 3]));
                let t = &t[1..3];
                let mut area = 0.0;
                for tri in t {
                    let [a, b, c] = tri.map(|v| dart[v as usize]);
                    let z = crate::geometry::cross(crate::geometry::sub(b, a), crate::geometry::sub(c, a))[2];
                    assert!(
                        z * if reversed { -1.0 } else { 1.0 } > 0.0,
                        "{polygon:?} → {t:?} folds or flips"
                    );
                    area += 0.5 * z.abs();
                }
                assert!((area - 1.0).abs() < 1e-6, "{polygon:?}: area {area}");
            }
        }
    }

    #[test]
    fn all_degenerate_is_an_error() {
        let mut s = FaceSink::default();
        s.add(&[1, 1, 2], || Position::Line(7));
        let e = s.finish(Path::new("x.obj"), &[[0.0; 3]; 3], &mut Vec::new()).unwrap_err();
        assert!(e.to_string().contains("line 7"), "{e}");
    }
}
