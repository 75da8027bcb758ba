//! Comparing two page images by their decoded pixels (for users' CI and our golden
//! tests). PNG byte streams may legitimately change with the encoder version; pixels
//! must not. Files are compared a row at a time, after their declared size is checked,
//! so a small file declaring a huge image (a 500 KB PNG of 23,000² pixels) costs no
//! memory: it is refused.
//!
//! Both images are decoded to 8-bit RGBA (gray, palette and RGB pages all compare). A
//! pixel *differs* when some channel differs by more than `tolerance` levels. The
//! **score** is the fraction of pixels that differ, in [0, 1]; a run passes when
//! `score ≤ threshold`.

use image::{Rgb, RgbImage, RgbaImage};
use std::io::{BufReader, BufWriter};
use std::path::{Path, PathBuf};

/// The largest image [`diff_files`] compares: 300 megapixels (a tabloid page at the
/// highest resolution pages allow, 1200 dpi, is 270). Checked on the size the file
/// declares, before any pixel is decoded.
pub const MAX_DIFF_PIXELS: u64 = 300_000_000;

/// The widest image [`diff_files`] compares (one row of each image is held at a time).
pub const MAX_DIFF_WIDTH: u32 = 100_000;

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
    /// A file is missing or not a decodable PNG.
    #[error("cannot read image {}: {message}", path.display())]
    Decode {
        /// The file.
        path: PathBuf,
        /// Cause.
        message: String,
    },
    /// The image declares more pixels than are compared.
    #[error("image {} declares {width}×{height} pixels, more than the {max} compared (at most {MAX_DIFF_WIDTH} wide and {MAX_DIFF_PIXELS} pixels): it is not a page", path.display(), max = MAX_DIFF_PIXELS)]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Declared width.
        width: u32,
        /// Declared height.
        height: u32,
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

/// Where a comparison's pixels are: decoded in memory, or in two PNG files that are read
/// again, a row at a time, to draw the diff image.
#[derive(Clone, Debug, PartialEq)]
enum Pixels {
    /// Per-pixel largest channel difference and the first image's luma, row-major.
    Memory { deltas: Vec<u8>, luma: Vec<u8> },
    /// The two files.
    Files(PathBuf, PathBuf),
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
    pixels: Pixels,
}

/// The diff image's pixel for channel difference `d` over first-image luma `l`.
fn diff_pixel(d: u8, l: u8, tolerance: u8) -> [u8; 3] {
    if d > tolerance {
        let k = 255 - d / 2;
        [255, k / 3, k / 3]
    } else {
        let l = 255 - (255 - l) / 4;
        [l, l, l]
    }
}

/// Largest channel difference of two RGBA pixels, and the first one's luma.
fn compare_pixel(p: &[u8], q: &[u8]) -> (u8, u8) {
    let d = (0..4).map(|c| p[c].abs_diff(q[c])).max().unwrap_or(0);
    let luma = ((u32::from(p[0]) * 77 + u32::from(p[1]) * 150 + u32::from(p[2]) * 29) >> 8) as u8;
    (d, luma)
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
    /// pixels in red (darker red for larger differences). In memory: for large files,
    /// [`ImageDiff::write_image`] streams instead.
    pub fn image(&self) -> Result<RgbImage, DiffError> {
        let mut img = RgbImage::new(self.width, self.height);
        match &self.pixels {
            Pixels::Memory { deltas, luma } => {
                for (i, px) in img.pixels_mut().enumerate() {
                    *px = Rgb(diff_pixel(deltas[i], luma[i], self.tolerance));
                }
            }
            Pixels::Files(a, b) => {
                let (mut ra, mut rb) = (PngRows::open(a)?, PngRows::open(b)?);
                for y in 0..self.height {
                    let (pa, pb) = (ra.next_row()?.to_vec(), rb.next_row()?);
                    for x in 0..self.width as usize {
                        let (d, l) = compare_pixel(&pa[4 * x..4 * x + 4], &pb[4 * x..4 * x + 4]);
                        img.put_pixel(x as u32, y, Rgb(diff_pixel(d, l, self.tolerance)));
                    }
                }
            }
        }
        Ok(img)
    }

    /// Writes the picture of [`ImageDiff::image`] as PNG; a comparison of files is drawn
    /// a row at a time (memory holds one row of each image).
    pub fn write_image(&self, path: &Path) -> Result<(), DiffError> {
        let write_err = |e: std::io::Error| DiffError::Write {
            path: path.to_path_buf(),
            source: image::ImageError::IoError(e),
        };
        let (a, b) = match &self.pixels {
            Pixels::Memory { .. } => {
                return self.image()?.save(path).map_err(|source| DiffError::Write {
                    path: path.to_path_buf(),
                    source,
                });
            }
            Pixels::Files(a, b) => (a, b),
        };
        let (mut ra, mut rb) = (PngRows::open(a)?, PngRows::open(b)?);
        let file = std::fs::File::create(path).map_err(write_err)?;
        let mut enc = png::Encoder::new(BufWriter::new(file), self.width, self.height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc
            .write_header()
            .map_err(|e| write_err(std::io::Error::other(e)))?;
        let mut s = w
            .stream_writer()
            .map_err(|e| write_err(std::io::Error::other(e)))?;
        let mut row = vec![0u8; 3 * self.width as usize];
        for _ in 0..self.height {
            let (pa, pb) = (ra.next_row()?.to_vec(), rb.next_row()?);
            for x in 0..self.width as usize {
                let (d, l) = compare_pixel(&pa[4 * x..4 * x + 4], &pb[4 * x..4 * x + 4]);
                row[3 * x..3 * x + 3].copy_from_slice(&diff_pixel(d, l, self.tolerance));
            }
            std::io::Write::write_all(&mut s, &row).map_err(write_err)?;
        }
        s.finish().map_err(|e| write_err(std::io::Error::other(e)))
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
        let (d, l) = compare_pixel(&p.0, &q.0);
        if d > tolerance {
            differing += 1;
        }
        max_delta = max_delta.max(d);
        sum += u64::from(d);
        deltas.push(d);
        luma.push(l);
    }
    Ok(ImageDiff {
        width,
        height,
        differing,
        max_delta,
        mean_delta: if n == 0 { 0.0 } else { sum as f64 / n as f64 },
        tolerance,
        pixels: Pixels::Memory { deltas, luma },
    })
}

/// Reads an image file and decodes it to RGBA (in memory: for pages, [`diff_files`]
/// streams).
pub fn read_image(path: &Path) -> Result<RgbaImage, DiffError> {
    image::open(path)
        .map(|i| i.to_rgba8())
        .map_err(|source| DiffError::Read {
            path: path.to_path_buf(),
            source,
        })
}

/// A PNG decoded a row at a time, each row as 8-bit RGBA.
struct PngRows {
    path: PathBuf,
    reader: png::Reader<BufReader<std::fs::File>>,
    color: png::ColorType,
    width: u32,
    height: u32,
    /// The whole frame, for an interlaced image (rows come in passes).
    frame: Option<Vec<u8>>,
    next: u32,
    row: Vec<u8>,
}

impl PngRows {
    /// Opens a PNG and checks its declared size before decoding any pixel.
    fn open(path: &Path) -> Result<PngRows, DiffError> {
        let err = |message: String| DiffError::Decode {
            path: path.to_path_buf(),
            message,
        };
        let file = std::fs::File::open(path).map_err(|e| err(e.to_string()))?;
        let mut dec =
            png::Decoder::new_with_limits(BufReader::new(file), png::Limits { bytes: 64 << 20 });
        dec.set_transformations(png::Transformations::normalize_to_color8());
        let mut reader = dec.read_info().map_err(|e| err(e.to_string()))?;
        let (width, height) = (reader.info().width, reader.info().height);
        if width > MAX_DIFF_WIDTH || u64::from(width) * u64::from(height) > MAX_DIFF_PIXELS {
            return Err(DiffError::TooLarge {
                path: path.to_path_buf(),
                width,
                height,
            });
        }
        let (color, _) = reader.output_color_type();
        let frame = if reader.info().interlaced {
            // Passes cover the image out of order: decode the frame whole (bounded by
            // the size checked above).
            let size = reader
                .output_buffer_size()
                .ok_or_else(|| err("image too large".into()))?;
            let mut buf = vec![0u8; size];
            reader
                .next_frame(&mut buf)
                .map_err(|e| err(e.to_string()))?;
            Some(buf)
        } else {
            None
        };
        Ok(PngRows {
            path: path.to_path_buf(),
            reader,
            color,
            width,
            height,
            frame,
            next: 0,
            row: vec![0u8; 4 * width as usize],
        })
    }

    /// The next row as RGBA.
    fn next_row(&mut self) -> Result<&[u8], DiffError> {
        let err = |message: String| DiffError::Decode {
            path: self.path.clone(),
            message,
        };
        if self.next >= self.height {
            return Err(err("fewer rows than declared".into()));
        }
        let channels = self.color.samples();
        let line = channels * self.width as usize;
        let data: &[u8] = match &self.frame {
            Some(f) => &f[self.next as usize * line..(self.next as usize + 1) * line],
            None => self
                .reader
                .next_row()
                .map_err(|e| err(e.to_string()))?
                .ok_or_else(|| err("fewer rows than declared".into()))?
                .data(),
        };
        if data.len() < line {
            return Err(DiffError::Decode {
                path: self.path.clone(),
                message: "a row is short".into(),
            });
        }
        for (x, px) in self.row.chunks_exact_mut(4).enumerate() {
            let s = &data[x * channels..(x + 1) * channels];
            px.copy_from_slice(&match channels {
                1 => [s[0], s[0], s[0], 255],
                2 => [s[0], s[0], s[0], s[1]],
                3 => [s[0], s[1], s[2], 255],
                _ => [s[0], s[1], s[2], s[3]],
            });
        }
        self.next += 1;
        Ok(&self.row)
    }
}

/// Reads and compares two PNG files, a row at a time: memory holds one row of each,
/// whatever their size. Each file's declared size is checked before decoding (at most
/// [`MAX_DIFF_PIXELS`] pixels, [`MAX_DIFF_WIDTH`] wide).
pub fn diff_files(a: &Path, b: &Path, tolerance: u8) -> Result<ImageDiff, DiffError> {
    let mut ra = PngRows::open(a)?;
    let mut rb = PngRows::open(b)?;
    if (ra.width, ra.height) != (rb.width, rb.height) {
        return Err(DiffError::SizeMismatch {
            a: (ra.width, ra.height),
            a_path: a.to_path_buf(),
            b: (rb.width, rb.height),
            b_path: b.to_path_buf(),
        });
    }
    let (width, height) = (ra.width, ra.height);
    let (mut differing, mut max_delta, mut sum) = (0u64, 0u8, 0u64);
    for _ in 0..height {
        let pa = ra.next_row()?.to_vec();
        let pb = rb.next_row()?;
        for (p, q) in pa.chunks_exact(4).zip(pb.chunks_exact(4)) {
            let (d, _) = compare_pixel(p, q);
            if d > tolerance {
                differing += 1;
            }
            max_delta = max_delta.max(d);
            sum += u64::from(d);
        }
    }
    let n = u64::from(width) * u64::from(height);
    Ok(ImageDiff {
        width,
        height,
        differing,
        max_delta,
        mean_delta: if n == 0 { 0.0 } else { sum as f64 / n as f64 },
        tolerance,
        pixels: Pixels::Files(a.to_path_buf(), b.to_path_buf()),
    })
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
        let img = d.image().unwrap();
        assert_eq!(img.get_pixel(1, 2).0[0], 255);
        assert_eq!(img.get_pixel(1, 2).0[1], img.get_pixel(1, 2).0[2]);
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
