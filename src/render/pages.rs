//! Rendering an atlas's pages to files: the per-page job that `generate` calls from its
//! workers. Streaming: each worker borrows one raster buffer from a [`BufferPool`] for one
//! page at a time and writes the page as soon as it is drawn, so memory stays bounded by
//! the number of workers whatever the atlas size. Every page is a pure function of its
//! linkage, points and settings, so files are byte-identical for any thread count.

use super::{PageFormat, RasterPage, SvgPage, draw};
use crate::layout::{
    ContentsEntry, DisplayList, LayoutError, LinkagePage, PageSetup, compute_page, layout_contents,
    layout_page,
};
use crate::linkage::{Circuit, CouplerPoint, FourBar};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// How to render an atlas's pages.
#[derive(Clone, Debug, PartialEq)]
pub struct PageOptions {
    /// Layout settings (size, DPI, dash pattern, header/footer text).
    pub setup: PageSetup,
    /// Formats to write (one file per page per format).
    pub formats: Vec<PageFormat>,
    /// File name stem (the spec's name): pages are `STEM-0001.png`, contents
    /// `STEM-contents-1.png`.
    pub stem: String,
}

impl PageOptions {
    /// Options from a spec's `[pages]` and `[sampling]` sections: PNG only, the spec's
    /// size, orientation, DPI, curves per page and dash step.
    pub fn from_spec(spec: &crate::Spec) -> Result<PageOptions, LayoutError> {
        let p = &spec.pages;
        let size: crate::layout::PageSize = format!("{}-{}", p.size, p.orientation).parse()?;
        let setup = PageSetup {
            size,
            dpi: f64::from(p.dpi),
            curves_per_page: p.curves_per_page as usize,
            dash: crate::DashPattern::new(spec.sampling.dash_deg, crate::DEFAULT_DASH_FRACTION)?,
            spec_name: spec.name.clone(),
            settings: format!("spec {}", spec.name),
            ..PageSetup::default()
        };
        setup.validate()?;
        Ok(PageOptions {
            setup,
            formats: vec![PageFormat::Png],
            stem: spec.name.clone(),
        })
    }

    /// The file name of atlas page `number` (1-based) in `format`.
    pub fn page_file(&self, number: u64, format: PageFormat) -> String {
        format!("{}-{:04}.{}", self.stem, number, format.extension())
    }

    /// The file name of contents page `number` (1-based) in `format`.
    pub fn contents_file(&self, number: usize, format: PageFormat) -> String {
        format!("{}-contents-{}.{}", self.stem, number, format.extension())
    }
}

/// Why a page could not be rendered or written.
#[derive(Debug, thiserror::Error)]
pub enum PageError {
    /// Layout failed (bad settings, or a curve that cannot be dashed).
    #[error("page {page}: {source}")]
    Layout {
        /// Page number.
        page: u64,
        /// Cause.
        #[source]
        source: LayoutError,
    },
    /// Writing a file failed.
    #[error("cannot write {}: {source}", path.display())]
    Io {
        /// File.
        path: PathBuf,
        /// Cause.
        #[source]
        source: std::io::Error,
    },
    /// PNG encoding failed.
    #[error("cannot encode {}: {source}", path.display())]
    Png {
        /// File.
        path: PathBuf,
        /// Cause.
        #[source]
        source: png::EncodingError,
    },
    /// The raster size is zero.
    #[error("page size {0}×{1} px is empty")]
    EmptyRaster(u32, u32),
}

/// Raster buffers shared by workers: a worker takes one for a page and gives it back, so
/// at most one buffer per concurrently running page exists.
#[derive(Default)]
pub struct BufferPool {
    free: Mutex<Vec<RasterPage>>,
}

impl BufferPool {
    /// An empty pool.
    pub fn new() -> BufferPool {
        BufferPool::default()
    }

    fn take(&self, w: u32, h: u32, dpi: f64) -> Result<RasterPage, PageError> {
        let found = self.free.lock().map(|mut v| v.pop()).unwrap_or(None);
        match found {
            Some(mut b) if b.width() == w && b.height() == h && b.dpi() == dpi => {
                b.clear();
                Ok(b)
            }
            _ => RasterPage::new(w, h, dpi).ok_or(PageError::EmptyRaster(w, h)),
        }
    }

    fn give(&self, b: RasterPage) {
        if let Ok(mut v) = self.free.lock() {
            v.push(b);
        }
    }
}

/// Time spent per phase, summed over pages (nanoseconds), shared by workers.
#[derive(Debug, Default)]
pub struct PageTimings {
    /// Dash sampling and scale (compute).
    pub compute: AtomicU64,
    /// Display list.
    pub layout: AtomicU64,
    /// Rasterising / building SVG.
    pub draw: AtomicU64,
    /// PNG encoding.
    pub encode: AtomicU64,
    /// Writing files.
    pub write: AtomicU64,
    /// Pages done.
    pub pages: AtomicU64,
}

impl PageTimings {
    fn add(field: &AtomicU64, since: Instant) -> Instant {
        let now = Instant::now();
        field.fetch_add((now - since).as_nanos() as u64, Ordering::Relaxed);
        now
    }

    /// `[compute, layout, draw, encode, write]` in seconds, and the page count.
    pub fn seconds(&self) -> ([f64; 5], u64) {
        let s = |a: &AtomicU64| a.load(Ordering::Relaxed) as f64 * 1e-9;
        (
            [
                s(&self.compute),
                s(&self.layout),
                s(&self.draw),
                s(&self.encode),
                s(&self.write),
            ],
            self.pages.load(Ordering::Relaxed),
        )
    }
}

/// Where one curve was drawn: page file (relative to the pages folder's parent, i.e.
/// `pages/NAME.png`) and bounding box in page pixels.
#[derive(Clone, Debug, PartialEq)]
pub struct CurveOnPage {
    /// `pages/STEM-0001.png` (the first format's file).
    pub file: String,
    /// `[x0, y0, x1, y1]` in pixels at the page DPI (x1, y1 exclusive).
    pub bbox_px: [u32; 4],
}

/// Writes `bytes` to `dir/name` (whole file at once; a page is small).
fn write_file(dir: &Path, name: &str, bytes: &[u8]) -> Result<(), PageError> {
    let path = dir.join(name);
    std::fs::write(&path, bytes).map_err(|source| PageError::Io { path, source })
}

/// Draws one display list in every format and writes the files into `dir`.
fn emit(
    display: &DisplayList,
    opts: &PageOptions,
    names: &[(PageFormat, String)],
    dir: &Path,
    pool: &BufferPool,
    timings: &PageTimings,
    mut t: Instant,
) -> Result<(), PageError> {
    for (format, name) in names {
        match format {
            PageFormat::Png => {
                let (w, h) = opts.setup.size_px();
                let mut buf = pool.take(w, h, opts.setup.dpi)?;
                draw(display, &mut buf);
                t = PageTimings::add(&timings.draw, t);
                let mut bytes = Vec::with_capacity(1 << 20);
                let r = buf.finish_png(&mut bytes);
                pool.give(buf);
                r.map_err(|source| PageError::Png {
                    path: dir.join(name),
                    source,
                })?;
                t = PageTimings::add(&timings.encode, t);
                write_file(dir, name, &bytes)?;
                t = PageTimings::add(&timings.write, t);
            }
            PageFormat::Svg => {
                let mut svg = SvgPage::new(display.width, display.height);
                draw(display, &mut svg);
                let text = svg.finish();
                t = PageTimings::add(&timings.draw, t);
                write_file(dir, name, text.as_bytes())?;
                t = PageTimings::add(&timings.write, t);
            }
        }
    }
    Ok(())
}

/// Renders the pages of one linkage (its points split into pages of
/// `curves_per_page`, numbered from `first_page` of `page_count`) into `dir`, and
/// returns where each point's curve went, in point order.
#[allow(clippy::too_many_arguments)]
pub fn render_linkage_pages(
    opts: &PageOptions,
    dir: &Path,
    pool: &BufferPool,
    timings: &PageTimings,
    linkage: FourBar,
    circuit: Circuit,
    points: &[CouplerPoint],
    first_page: u64,
    page_count: u64,
) -> Result<Vec<CurveOnPage>, PageError> {
    let per = opts.setup.curves_per_page.max(1);
    let mut out = Vec::with_capacity(points.len());
    for (k, chunk) in points.chunks(per).enumerate() {
        let number = first_page + k as u64;
        let t0 = Instant::now();
        let page = LinkagePage {
            linkage,
            circuit,
            points: chunk.to_vec(),
            grid: points.to_vec(),
            page_number: number as usize,
            page_count: page_count as usize,
        };
        let err = |source| PageError::Layout {
            page: number,
            source,
        };
        let geometry = compute_page(&page, &opts.setup).map_err(err)?;
        let t = PageTimings::add(&timings.compute, t0);
        let layout = layout_page(&page, &geometry, &opts.setup);
        let t = PageTimings::add(&timings.layout, t);
        let names: Vec<(PageFormat, String)> = opts
            .formats
            .iter()
            .map(|f| (*f, opts.page_file(number, *f)))
            .collect();
        emit(&layout.display, opts, &names, dir, pool, timings, t)?;
        timings.pages.fetch_add(1, Ordering::Relaxed);
        let first = names.first().map(|n| n.1.clone()).unwrap_or_default();
        for c in &layout.curves {
            out.push(CurveOnPage {
                file: format!("pages/{first}"),
                bbox_px: c.bbox_px(opts.setup.dpi),
            });
        }
    }
    Ok(out)
}

/// Renders the contents pages into `dir`; returns their file names (first format).
pub fn render_contents(
    opts: &PageOptions,
    dir: &Path,
    pool: &BufferPool,
    entries: &[ContentsEntry],
) -> Result<Vec<String>, PageError> {
    let timings = PageTimings::default();
    let mut files = Vec::new();
    for (i, display) in layout_contents(entries, &opts.setup).iter().enumerate() {
        let names: Vec<(PageFormat, String)> = opts
            .formats
            .iter()
            .map(|f| (*f, opts.contents_file(i + 1, *f)))
            .collect();
        emit(display, opts, &names, dir, pool, &timings, Instant::now())?;
        if let Some(n) = names.first() {
            files.push(n.1.clone());
        }
    }
    Ok(files)
}
