//! Writing 8-bit RGB images as PNG, atomically (plots and pictures of every pipeline).

use std::path::Path;

use crate::{Error, Result};

/// Writes a `width × height` 8-bit RGB buffer (row-major, 3 bytes per pixel) to `path` as PNG,
/// through [`super::write_atomic`], so a failed write leaves no partial file.
pub fn write_png_rgb(path: &Path, width: u32, height: u32, rgb: &[u8]) -> Result<()> {
    if rgb.len() != width as usize * height as usize * 3 {
        return Err(Error::InvalidInput(format!(
            "{}: an RGB image of {width}×{height} needs {} bytes, got {}",
            path.display(),
            width as usize * height as usize * 3,
            rgb.len()
        )));
    }
    let mut bytes = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut bytes, width, height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let to_io = |e: png::EncodingError| Error::io(path, std::io::Error::other(e.to_string()));
        let mut w = enc.write_header().map_err(to_io)?;
        w.write_image_data(rgb).map_err(to_io)?;
        w.finish().map_err(to_io)?;
    }
    super::write_atomic(path, |w| w.write_all(&bytes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_a_png_and_rejects_a_short_buffer() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("a.png");
        write_png_rgb(&p, 2, 1, &[255, 0, 0, 0, 255, 0]).unwrap();
        let b = std::fs::read(&p).unwrap();
        assert_eq!(&b[1..4], b"PNG");
        assert!(write_png_rgb(&d.path().join("b.png"), 2, 2, &[0; 3]).is_err());
        assert!(!d.path().join("b.png").exists());
    }
}
