//! Writing rendered images: linear radiance to 8-bit sRGB-ish PNG with gamma 2 (square root),
//! clamped, as in "Ray Tracing in One Weekend". Non-finite pixels are written black and counted.

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use glam::Vec3;

/// An image could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// The pixel buffer does not have `width * height` entries, or a side is zero.
    #[error("image is {width}x{height} but has {pixels} pixels")]
    Size {
        /// Declared width.
        width: u32,
        /// Declared height.
        height: u32,
        /// Pixels supplied.
        pixels: usize,
    },
    /// Creating or encoding the file failed.
    #[error("{path}: {reason}")]
    Write {
        /// The output file.
        path: String,
        /// What went wrong.
        reason: String,
    },
}

/// One linear channel value to 8 bits: `256 * clamp(sqrt(c), 0, 0.999)`.
fn to_byte(c: f32) -> u8 {
    (256.0 * c.max(0.0).sqrt().min(0.999)) as u8
}

/// Convert linear radiance (row-major, top row first) to RGB8 bytes. Returns the bytes and the
/// number of pixels that had a NaN or infinite channel (written as black).
pub fn to_rgb8(pixels: &[Vec3]) -> (Vec<u8>, usize) {
    let mut bytes = Vec::with_capacity(pixels.len() * 3);
    let mut nonfinite = 0;
    for p in pixels {
        if p.is_finite() {
            bytes.extend([to_byte(p.x), to_byte(p.y), to_byte(p.z)]);
        } else {
            nonfinite += 1;
            bytes.extend([0, 0, 0]);
        }
    }
    (bytes, nonfinite)
}

/// Write `pixels` (linear radiance, `width * height`, top row first) as an RGB8 PNG at `path`.
/// Returns the number of non-finite pixels that were written black.
pub fn write_png(
    path: &Path,
    width: u32,
    height: u32,
    pixels: &[Vec3],
) -> Result<usize, ImageError> {
    if width == 0 || height == 0 || pixels.len() as u64 != u64::from(width) * u64::from(height) {
        return Err(ImageError::Size {
            width,
            height,
            pixels: pixels.len(),
        });
    }
    let err = |reason: String| ImageError::Write {
        path: path.display().to_string(),
        reason,
    };
    let (bytes, nonfinite) = to_rgb8(pixels);
    let file = File::create(path).map_err(|e| err(e.to_string()))?;
    let mut encoder = png::Encoder::new(BufWriter::new(file), width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().map_err(|e| err(e.to_string()))?;
    writer
        .write_image_data(&bytes)
        .map_err(|e| err(e.to_string()))?;
    writer.finish().map_err(|e| err(e.to_string()))?;
    Ok(nonfinite)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gamma_two_and_clamp() {
        let (bytes, bad) = to_rgb8(&[Vec3::new(0.25, 2.0, -1.0)]);
        assert_eq!(bytes, vec![128, 255, 0]);
        assert_eq!(bad, 0);
    }

    #[test]
    fn nonfinite_pixels_are_black_and_counted() {
        let (bytes, bad) = to_rgb8(&[
            Vec3::new(f32::NAN, 1.0, 1.0),
            Vec3::splat(f32::INFINITY),
            Vec3::ONE,
        ]);
        assert_eq!(bytes, vec![0, 0, 0, 0, 0, 0, 255, 255, 255]);
        assert_eq!(bad, 2);
    }

    #[test]
    fn size_mismatch_is_an_error() {
        let path = std::env::temp_dir().join("vtq-image-size-mismatch.png");
        assert!(matches!(
            write_png(&path, 2, 2, &[Vec3::ZERO; 3]),
            Err(ImageError::Size { pixels: 3, .. })
        ));
    }
}
