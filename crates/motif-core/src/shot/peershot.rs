//! The `PEERSHOT` binary layout for SHOT descriptors, shared with the PCL reference tool
//! (`tools/pcl-shot/`), and a CSV export.
//!
//! Layout, little-endian: the 8 bytes `PEERSHOT`, `u32` keypoint count, `u32` descriptor length
//! (352), then per keypoint `u32` point index, `f32 frame[9]` (the `x`, `y`, `z` axes in turn) and
//! `f32 descriptor[352]`. An invalid keypoint is written with NaN frame and descriptor, as PCL
//! writes it; on reading, a keypoint is valid when its descriptor is finite.

use std::io::Write;
use std::path::Path;

use super::{SHOT_LEN, ShotDescriptors};
use crate::error::Position;
use crate::{Error, Result};

const MAGIC: &[u8; 8] = b"PEERSHOT";
const HEADER_LEN: usize = 16;
const RECORD_LEN: usize = 4 + 4 * 9 + 4 * SHOT_LEN;

/// Writes `shots` in the `PEERSHOT` layout (see the module docs). Fails when a keypoint index or
/// the count does not fit in a `u32`, or the writer fails.
pub fn write_peershot(w: &mut impl Write, shots: &ShotDescriptors) -> std::io::Result<()> {
    check_lengths(shots)?;
    let count = to_u32(shots.len(), "keypoint count")?;
    let mut buf = Vec::with_capacity(RECORD_LEN);
    buf.extend_from_slice(MAGIC);
    buf.extend_from_slice(&count.to_le_bytes());
    buf.extend_from_slice(&(SHOT_LEN as u32).to_le_bytes());
    w.write_all(&buf)?;
    for i in 0..shots.len() {
        buf.clear();
        buf.extend_from_slice(&to_u32(shots.keypoints[i], "keypoint index")?.to_le_bytes());
        let valid = shots.valid[i];
        for axis in &shots.frames[i] {
            for &c in axis {
                buf.extend_from_slice(&(if valid { c } else { f32::NAN }).to_le_bytes());
            }
        }
        for &v in &shots.descriptors[i * SHOT_LEN..(i + 1) * SHOT_LEN] {
            buf.extend_from_slice(&(if valid { v } else { f32::NAN }).to_le_bytes());
        }
        w.write_all(&buf)?;
    }
    Ok(())
}

/// Reads `PEERSHOT` data (see the module docs). Checks the magic, the descriptor length and that
/// the data holds exactly the announced number of records before allocating anything; errors
/// name the byte offset of the problem. Invalid keypoints (non-finite descriptor) come back with
/// `valid = false` and zero frame and descriptor.
pub fn read_peershot(bytes: &[u8]) -> Result<ShotDescriptors> {
    parse(bytes, Path::new("<PEERSHOT data>"))
}

/// [`read_peershot`] on a file; errors name the file.
pub fn read_peershot_file(path: impl AsRef<Path>) -> Result<ShotDescriptors> {
    let path = path.as_ref();
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    parse(&bytes, path)
}

/// Writes `shots` as CSV: a header `index,xx,xy,xz,yx,yy,yz,zx,zy,zz,f0,...,f351`, then one row
/// per keypoint with its point index, its frame's `x`, `y` and `z` axes (world components, as in
/// the PEERSHOT layout) and its descriptor (shortest round-trip decimal form; `NaN` for the frame
/// and descriptor of an invalid keypoint).
pub fn write_shot_csv(w: &mut impl Write, shots: &ShotDescriptors) -> std::io::Result<()> {
    check_lengths(shots)?;
    let mut line = String::with_capacity(16 * (SHOT_LEN + 10));
    line.push_str("index");
    for axis in ["x", "y", "z"] {
        for c in ["x", "y", "z"] {
            line.push_str(&format!(",{axis}{c}"));
        }
    }
    for k in 0..SHOT_LEN {
        line.push_str(&format!(",f{k}"));
    }
    line.push('\n');
    w.write_all(line.as_bytes())?;
    for i in 0..shots.len() {
        line.clear();
        line.push_str(&shots.keypoints[i].to_string());
        let frame = shots.frames[i].iter().flatten();
        for &v in frame.chain(&shots.descriptors[i * SHOT_LEN..(i + 1) * SHOT_LEN]) {
            let v = if shots.valid[i] { v } else { f32::NAN };
            line.push(',');
            line.push_str(&v.to_string());
        }
        line.push('\n');
        w.write_all(line.as_bytes())?;
    }
    Ok(())
}

fn check_lengths(shots: &ShotDescriptors) -> std::io::Result<()> {
    let k = shots.keypoints.len();
    if shots.descriptors.len() != k * SHOT_LEN || shots.frames.len() != k || shots.valid.len() != k {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            format!(
                "inconsistent SHOT descriptors: {k} keypoints, {} descriptor values, {} frames, {} flags",
                shots.descriptors.len(),
                shots.frames.len(),
                shots.valid.len()
            ),
        ));
    }
    Ok(())
}

fn to_u32(v: usize, what: &str) -> std::io::Result<u32> {
    u32::try_from(v).map_err(|_| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            format!("{what} {v} does not fit in the PEERSHOT format's 32 bits"),
        )
    })
}

fn parse(bytes: &[u8], path: &Path) -> Result<ShotDescriptors> {
    let fail = |at: usize, msg: String| Error::parse(path, Position::Byte(at as u64), msg);
    if bytes.len() < HEADER_LEN {
        return Err(fail(
            bytes.len(),
            format!("truncated PEERSHOT header: {} bytes, a header needs {HEADER_LEN}", bytes.len()),
        ));
    }
    if &bytes[..8] != MAGIC {
        return Err(fail(0, "not PEERSHOT data: the first 8 bytes are not \"PEERSHOT\"".into()));
    }
    let count = u32_at(bytes, 8) as usize;
    let dim = u32_at(bytes, 12) as usize;
    if dim != SHOT_LEN {
        return Err(fail(
            12,
            format!("descriptor length {dim}, but SHOT descriptors have {SHOT_LEN} values"),
        ));
    }
    // Compare in u64 so a huge announced count cannot overflow; nothing is allocated before this.
    let expected = HEADER_LEN as u64 + count as u64 * RECORD_LEN as u64;
    if bytes.len() as u64 != expected {
        let at = bytes.len().min(HEADER_LEN + (bytes.len() - HEADER_LEN) / RECORD_LEN * RECORD_LEN);
        return Err(fail(
            at,
            format!(
                "the header announces {count} keypoints ({expected} bytes) but the data has {} bytes{}",
                bytes.len(),
                if (bytes.len() as u64) < expected { ": truncated" } else { ": trailing bytes" }
            ),
        ));
    }
    let mut out = ShotDescriptors {
        keypoints: Vec::with_capacity(count),
        descriptors: Vec::with_capacity(count * SHOT_LEN),
        frames: Vec::with_capacity(count),
        valid: Vec::with_capacity(count),
    };
    for record in bytes[HEADER_LEN..].chunks_exact(RECORD_LEN) {
        out.keypoints.push(u32_at(record, 0) as usize);
        let mut frame = [[0.0_f32; 3]; 3];
        for (k, c) in frame.iter_mut().flatten().enumerate() {
            *c = f32_at(record, 4 + 4 * k);
        }
        let desc_at = 4 + 4 * 9;
        let valid = (0..SHOT_LEN).all(|k| f32_at(record, desc_at + 4 * k).is_finite());
        if valid {
            out.descriptors.extend((0..SHOT_LEN).map(|k| f32_at(record, desc_at + 4 * k)));
            if !frame.iter().flatten().all(|c| c.is_finite()) {
                frame = [[0.0; 3]; 3];
            }
        } else {
            out.descriptors.extend(std::iter::repeat_n(0.0, SHOT_LEN));
            frame = [[0.0; 3]; 3];
        }
        out.frames.push(frame);
        out.valid.push(valid);
    }
    Ok(out)
}

/// Little-endian u32 at `at`; callers have checked the length.
fn u32_at(bytes: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]])
}

fn f32_at(bytes: &[u8], at: usize) -> f32 {
    f32::from_bits(u32_at(bytes, at))
}
