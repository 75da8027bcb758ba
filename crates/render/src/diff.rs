//! Comparing two page images by their decoded pixels (for users' CI and our golden
//! tests). PNG byte streams may legitimately change with the encoder version; pixels
//! must not.
//!
//! Both images are decoded to 8-bit RGBA (gray, palette and RGB pages all compare). A
//! pixel *differs* when some channel differs by more than `tolerance` levels. The
//! **score** is the fraction of pixels that differ, in [0, 1]; a run passes when
//! `score ≤ threshold`.

use image::{Rgb, RgbImage, RgbaImage};
use std::path::{Path, PathBuf};

/// Why two images could not be compared.
#[derive(Debug, thiserror::Error)]
pub enum DiffError {
    /// A file is missing or not a decodable image.
    #[error("cannot read image {}: {source}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// Cause.
        #[source]
        source: image::ImageError,
    },
    /// The images have different sizes.
    #[error("image sizes differ: {}×{} ({}) vs {}×{} ({})", a.0, a.1, a_path.display(), b.0, b.1, b_path.display())]
    SizeMismatch {
        /// First size.
        a: (u32, u32),
        /// First file.
        a_path: PathBuf,
        /// Second size.
        b: (u32, u32),
        /// Second file.
        b_path: PathBuf,
    },
    /// The diff image could not be written.
    #[error("cannot write diff image {}: {source}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// Cause.
        #[source]
        source: image::ImageError,
    },
}

/// The result of a comparison.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageDiff {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Pixels that differ by more than the tolerance.
    pub differing: u64,
    /// Largest channel difference anywhere (0–255).
    pub max_delta: u8,
    /// Mean of the per-pixel largest channel difference, in levels (0–255).
    pub mean_delta: f64,
    /// Per-pixel tolerance used.
    pub tolerance: u8,
    /// Per-pixel largest channel difference, row-major (for the diff image).
    deltas: Vec<u8>,
    /// Luma of the first image, row-major (background of the diff image).
    luma: Vec<u8>,
}

impl ImageDiff {
    /// Fraction of pixels that differ, in [0, 1].
    pub fn score(&self) -> f64 {
        let n = u64::from(self.width) * u64::from(self.height);
        if n == 0 {
            0.0
        } else {
            self.differing as f64 / n as f64
        }
    }

    /// True when the images are identical within the tolerance.
    pub fn is_identical(&self) -> bool {
        self.differing == 0
    }

    /// A picture of the differences: the first image faded to light gray, differing
    /// pixels in red (darker red for larger differences).
    pub fn image(&self) -> RgbImage {
        let mut img = RgbImage::new(self.width, self.height);
        for (i, px) in img.pixels_mut().enumerate() {
            let d = self.deltas[i];
            *px = if d > self.tolerance {
                let k = 255 - d / 2;
                Rgb([255, k / 3, k / 3])
            } else {
                let l = 255 - (255 - self.luma[i]) / 4;
                Rgb([l, l, l])
            };
        }
        img
    }

    /// Writes [`ImageDiff::image`] as PNG.
    pub fn write_image(&self, path: &Path) -> Result<(), DiffError> {
        self.image().save(path).map_err(|source| DiffError::Write {
            path: path.to_path_buf(),
            source,
        })
    }

    /// One line for people: score, counts, largest difference.
    pub fn summary(&self) -> String {
        format!(
            "score {:.6} ({} of {} pixels differ by more than {} levels; max difference {}, mean {:.4})",
            self.score(),
            self.differing,
            u64::from(self.width) * u64::from(self.height),
            self.tolerance,
            self.max_delta,
            self.mean_delta
        )
    }
}

/// Compares two decoded images. Errors on a size mismatch (paths are for the message).
pub fn diff_images(
    a: &RgbaImage,
    b: &RgbaImage,
    tolerance: u8,
    paths: (&Path, &Path),
) -> Result<ImageDiff, DiffError> {
    if a.dimensions() != b.dimensions() {
        return Err(DiffError::SizeMismatch {
            a: a.dimensions(),
            a_path: paths.0.to_path_buf(),
            b: b.dimensions(),
            b_path: paths.1.to_path_buf(),
        });
    }
    let (width, height) = a.dimensions();
    let n = (width as usize) * (height as usize);
    let mut deltas = Vec::with_capacity(n);
    let mut luma = Vec::with_capacity(n);
    let (mut differing, mut max_delta, mut sum) = (0u64, 0u8, 0u64);
    for (p, q) in a.pixels().zip(b.pixels()) {
        let d = (0..4).map(|c| p.0[c].abs_diff(q.0[c])).max().unwrap_or(0);
        if d > tolerance {
            differing += 1;
        }
        max_delta = max_delta.max(d);
        sum += u64::from(d);
        deltas.push(d);
        let [r, g, bl, _] = p.0;
        luma.push(((u32::from(r) * 77 + u32::from(g) * 150 + u32::from(bl) * 29) >> 8) as u8);
    }
    Ok(ImageDiff {
        width,
        height,
        differing,
        max_delta,
        mean_delta: if n == 0 { 0.0 } else { sum as f64 / n as f64 },
        tolerance,
        deltas,
        luma,
    })
}

/// Reads an image file and decodes it to RGBA.
pub fn read_image(path: &Path) -> Result<RgbaImage, DiffError> {
    image::open(path)
        .map(|i| i.to_rgba8())
        .map_err(|source| DiffError::Read {
            path: path.to_path_buf(),
            source,
        })
}

/// Reads and compares two image files.
pub fn diff_files(a: &Path, b: &Path, tolerance: u8) -> Result<ImageDiff, DiffError> {
    let ia = read_image(a)?;
    let ib = read_image(b)?;
    diff_images(&ia, &ib, tolerance, (a, b))
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::Rgba;

    #[test]
    fn identical_and_one_pixel_off() {
        let a = RgbaImage::from_pixel(4, 3, Rgba([255, 255, 255, 255]));
        let mut b = a.clone();
        let p = (Path::new("a"), Path::new("b"));
        let d = diff_images(&a, &b, 0, p).unwrap();
        assert!(d.is_identical() && d.score() == 0.0);
        b.put_pixel(1, 2, Rgba([250, 255, 255, 255]));
        let d = diff_images(&a, &b, 0, p).unwrap();
        assert_eq!((d.differing, d.max_delta), (1, 5));
        assert!((d.score() - 1.0 / 12.0).abs() < 1e-15);
        assert_eq!(d.image().get_pixel(1, 2).0[0], 255);
        assert_eq!(
            d.image().get_pixel(1, 2).0[1],
            d.image().get_pixel(1, 2).0[2]
        );
        let d = diff_images(&a, &b, 5, p).unwrap();
        assert!(d.is_identical());
    }

    #[test]
    fn size_mismatch_is_an_error() {
        let a = RgbaImage::new(4, 3);
        let b = RgbaImage::new(3, 4);
        let e = diff_images(&a, &b, 0, (Path::new("a.png"), Path::new("b.png"))).unwrap_err();
        assert!(e.to_string().contains("4×3 (a.png) vs 3×4 (b.png)"), "{e}");
    }

    #[test]
    fn missing_file_is_an_error() {
        let e = diff_files(
            Path::new("/nonexistent/a.png"),
            Path::new("/nonexistent/b.png"),
            0,
        )
        .unwrap_err();
        assert!(e.to_string().contains("/nonexistent/a.png"), "{e}");
    }
}
