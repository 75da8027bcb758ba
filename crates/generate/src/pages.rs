//! Rendering an atlas's pages: the per-page job behind `generate`'s [`Renderer`] hook.
//! Streaming: each worker borrows one raster buffer from a [`BufferPool`] for one page at
//! a time and hands the encoded page to the pipeline, which writes it at once (per group),
//! so memory stays bounded by the number of workers whatever the atlas size. Every page
//! is a pure function of its linkage, points and settings, so files are byte-identical
//! for any thread count.

use crate::{Artifact, Group, Job, PageFailure, Rendered, Renderer};
use coupler_index::{IndexCurve, PageRef};
use coupler_kinematics::{Circuit, CouplerPoint, Linkage};
use coupler_layout::{
    ContentsEntry, DisplayList, LayoutError, LinkagePage, PageSetup, compute_page, layout_contents,
    layout_page,
};
use coupler_render::{PageFormat, RasterPage, SvgPage, draw};
use coupler_specs::{PageSettings, Sampling, Spec};
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
    pub fn from_spec(spec: &Spec) -> Result<PageOptions, LayoutError> {
        PageOptions::from_settings(&spec.name, &spec.sampling, &spec.pages)
    }

    /// Options from the `[sampling]` and `[pages]` settings of the spec named `name`
    /// (either kind of spec).
    pub fn from_settings(
        name: &str,
        sampling: &Sampling,
        p: &PageSettings,
    ) -> Result<PageOptions, LayoutError> {
        let size = coupler_layout::PageSize {
            paper: p.size,
            orientation: p.orientation,
        };
        let setup = PageSetup {
            size,
            dpi: f64::from(p.dpi),
            curves_per_page: p.curves_per_page as usize,
            dash: sampling.dash_pattern(),
            spec_name: name.to_string(),
            settings: format!("spec {name}"),
            ..PageSetup::default()
        };
        setup.validate()?;
        Ok(PageOptions {
            setup,
            formats: vec![PageFormat::Png],
            stem: name.to_string(),
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
    /// PNG encoding failed.
    #[error("cannot encode PNG: {0}")]
    Png(#[source] png::EncodingError),
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
    /// Writing files (unused by [`PageRenderer`]: `generate` writes and hashes the
    /// files it returns).
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

/// Renders one display list in every format: `(format, bytes)` per format.
fn emit(
    display: &DisplayList,
    opts: &PageOptions,
    pool: &BufferPool,
    timings: &PageTimings,
    mut t: Instant,
) -> Result<Vec<(PageFormat, Vec<u8>)>, PageError> {
    let mut out = Vec::with_capacity(opts.formats.len());
    for format in &opts.formats {
        match format {
            PageFormat::Png => {
                let (w, h) = opts.setup.size_px();
                let mut buf = pool.take(w, h, opts.setup.dpi)?;
                draw(display, &mut buf);
                t = PageTimings::add(&timings.draw, t);
                let mut bytes = Vec::with_capacity(1 << 19);
                let r = buf.finish_png(&mut bytes);
                pool.give(buf);
                r.map_err(PageError::Png)?;
                t = PageTimings::add(&timings.encode, t);
                out.push((*format, bytes));
            }
            PageFormat::Svg => {
                let mut svg = SvgPage::new(display.width, display.height);
                draw(display, &mut svg);
                out.push((*format, svg.finish().into_bytes()));
                t = PageTimings::add(&timings.draw, t);
            }
            #[cfg(feature = "pdf")]
            PageFormat::Pdf => {
                let mut pdf = coupler_render::PdfPage::new(display.width, display.height);
                draw(display, &mut pdf);
                out.push((*format, pdf.finish()));
                t = PageTimings::add(&timings.draw, t);
            }
        }
    }
    Ok(out)
}

/// One rendered page: its files (name relative to the pages folder, bytes) and where
/// each of its curves is, in pixels.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderedPage {
    /// `(file name, bytes)`, one per format, in the order of `PageOptions::formats`.
    pub files: Vec<(String, Vec<u8>)>,
    /// Each curve's box `[x0, y0, x1, y1]` in pixels at the page DPI, in point order.
    pub bbox_px: Vec<[u32; 4]>,
}

/// Encodes a laid-out page in every format and counts it.
fn finish_page(
    opts: &PageOptions,
    pool: &BufferPool,
    timings: &PageTimings,
    number: u64,
    layout: &coupler_layout::PageLayout,
    t: Instant,
) -> Result<RenderedPage, PageError> {
    let files = emit(&layout.display, opts, pool, timings, t)?
        .into_iter()
        .map(|(f, bytes)| (opts.page_file(number, f), bytes))
        .collect();
    timings.pages.fetch_add(1, Ordering::Relaxed);
    Ok(RenderedPage {
        files,
        bbox_px: layout
            .curves
            .iter()
            .map(|c| c.bbox_px(opts.setup.dpi))
            .collect(),
    })
}

/// Renders atlas page `number` of `page_count`: `points` of `linkage` (whose whole grid is
/// `grid`). Pure apart from the shared buffer pool and timing counters.
#[allow(clippy::too_many_arguments)]
pub fn render_page(
    opts: &PageOptions,
    pool: &BufferPool,
    timings: &PageTimings,
    linkage: Linkage,
    circuit: Circuit,
    points: &[CouplerPoint],
    grid: &[CouplerPoint],
    number: u64,
    page_count: u64,
) -> Result<RenderedPage, PageError> {
    let t0 = Instant::now();
    let page = LinkagePage {
        linkage,
        circuit,
        points: points.to_vec(),
        grid: grid.to_vec(),
        page_number: number as usize,
        page_count: page_count as usize,
    };
    let geometry = compute_page(&page, &opts.setup).map_err(|source| PageError::Layout {
        page: number,
        source,
    })?;
    let t = PageTimings::add(&timings.compute, t0);
    let layout = layout_page(&page, &geometry, &opts.setup);
    let t = PageTimings::add(&timings.layout, t);
    finish_page(opts, pool, timings, number, &layout, t)
}

/// Renders page `page.page_number` of a full-curve page set (one named curve).
pub fn render_classic(
    opts: &PageOptions,
    pool: &BufferPool,
    timings: &PageTimings,
    page: &coupler_layout::ClassicPage,
) -> Result<RenderedPage, PageError> {
    use coupler_layout::{compute_classic, layout_classic};
    let number = page.page_number as u64;
    let t0 = Instant::now();
    let geometry = compute_classic(page, &opts.setup).map_err(|source| PageError::Layout {
        page: number,
        source,
    })?;
    let t = PageTimings::add(&timings.compute, t0);
    let layout = layout_classic(page, &geometry, &opts.setup);
    let t = PageTimings::add(&timings.layout, t);
    finish_page(opts, pool, timings, number, &layout, t)
}

/// Renders the contents pages: `(file name, bytes)` per page and format.
pub fn render_contents(
    opts: &PageOptions,
    pool: &BufferPool,
    entries: &[ContentsEntry],
) -> Result<Vec<(String, Vec<u8>)>, PageError> {
    let timings = PageTimings::default();
    let mut files = Vec::new();
    for (i, display) in layout_contents(entries, &opts.setup).iter().enumerate() {
        for (f, bytes) in emit(display, opts, pool, &timings, Instant::now())? {
            files.push((opts.contents_file(i + 1, f), bytes));
        }
    }
    Ok(files)
}

/// The page renderer `generate` uses: implements its [`Renderer`] hook. Files go to
/// `pages/` in the atlas folder; each curve's index record gets its page file (the first
/// format's) and box in pixels.
pub struct PageRenderer {
    /// Settings.
    pub opts: PageOptions,
    pool: BufferPool,
    /// Time spent per phase, summed over workers.
    pub timings: PageTimings,
}

impl PageRenderer {
    /// A renderer with an empty buffer pool.
    pub fn new(opts: PageOptions) -> PageRenderer {
        PageRenderer {
            opts,
            pool: BufferPool::new(),
            timings: PageTimings::default(),
        }
    }
}

impl PageRenderer {
    /// The format whose file names a page in messages and in the index.
    fn first_format(&self) -> PageFormat {
        self.opts
            .formats
            .first()
            .copied()
            .unwrap_or(PageFormat::Png)
    }

    /// A page that could not be made: `file` in the pages folder.
    fn failure(&self, file: String, e: PageError) -> PageFailure {
        PageFailure {
            page: format!("pages/{file}"),
            message: e.to_string(),
        }
    }

    /// Renders page `page.page_number` of a full-curve page set: its files (names
    /// relative to the atlas folder) and its curve's box, or why it failed.
    pub fn classic_page(
        &self,
        page: &coupler_layout::ClassicPage,
    ) -> Result<(Vec<Artifact>, Option<PageRef>), PageFailure> {
        let number = page.page_number as u64;
        let rendered = render_classic(&self.opts, &self.pool, &self.timings, page)
            .map_err(|e| self.failure(self.opts.page_file(number, self.first_format()), e))?;
        let place = match (rendered.files.first(), rendered.bbox_px.first()) {
            (Some(first), Some(b)) => Some(PageRef {
                file: format!("pages/{}", first.0),
                bbox_px: b.map(f64::from),
            }),
            _ => None,
        };
        let files = rendered
            .files
            .into_iter()
            .map(|(name, bytes)| Artifact {
                name: format!("pages/{name}"),
                bytes,
            })
            .collect();
        Ok((files, place))
    }
}

impl Renderer for PageRenderer {
    fn render_group(&self, job: &Job, group: &Group, curves: &mut [IndexCurve]) -> Rendered {
        let per = self.opts.setup.curves_per_page.max(1);
        let page_count = job.pages();
        let mut out = Vec::new();
        for (k, chunk) in group.points.chunks(per).enumerate() {
            let number = group.first_page + k as u64;
            let page = match render_page(
                &self.opts,
                &self.pool,
                &self.timings,
                group.linkage,
                group.circuit,
                chunk,
                &group.points,
                number,
                page_count,
            ) {
                Ok(page) => page,
                Err(e) => {
                    out.push(Err(
                        self.failure(self.opts.page_file(number, self.first_format()), e)
                    ));
                    continue;
                }
            };
            let first = page
                .files
                .first()
                .map(|f| format!("pages/{}", f.0))
                .unwrap_or_default();
            for (i, b) in page.bbox_px.iter().enumerate() {
                if let Some(c) = curves.get_mut(k * per + i) {
                    c.page = Some(PageRef {
                        file: first.clone(),
                        bbox_px: b.map(f64::from),
                    });
                }
            }
            out.extend(page.files.into_iter().map(|(name, bytes)| {
                Ok(Artifact {
                    name: format!("pages/{name}"),
                    bytes,
                })
            }));
        }
        out
    }

    fn render_atlas(&self, job: &Job) -> Rendered {
        let per = self.opts.setup.curves_per_page.max(1) as u64;
        let entries: Vec<ContentsEntry> = job
            .groups()
            .map(|g| ContentsEntry {
                linkage: g.linkage,
                circuit: g.circuit,
                curves: g.points.len(),
                first_page: g.first_page as usize,
                last_page: (g.first_page + (g.points.len() as u64).div_ceil(per)).saturating_sub(1)
                    as usize,
            })
            .collect();
        match render_contents(&self.opts, &self.pool, &entries) {
            Ok(files) => files
                .into_iter()
                .map(|(name, bytes)| {
                    Ok(Artifact {
                        name: format!("pages/{name}"),
                        bytes,
                    })
                })
                .collect(),
            Err(e) => vec![Err(
                self.failure(self.opts.contents_file(1, self.first_format()), e)
            )],
        }
    }

    fn pages(&self, job: &Job) -> u64 {
        job.pages()
    }

    fn page_options(&self) -> Option<&PageOptions> {
        Some(&self.opts)
    }

    fn group_files(&self, _job: &Job, group: &Group) -> Option<Vec<String>> {
        let per = self.opts.setup.curves_per_page.max(1);
        let pages = group.points.len().div_ceil(per) as u64;
        Some(
            (group.first_page..group.first_page + pages)
                .flat_map(|n| {
                    self.opts
                        .formats
                        .iter()
                        .map(move |&f| format!("pages/{}", self.opts.page_file(n, f)))
                })
                .collect(),
        )
    }

    fn settings(&self) -> String {
        let s = &self.opts.setup;
        format!(
            "pages {} formats {:?} {} dpi {} margin {} pt dash {}°×{} tolerance {} px curves/page {} stem {}",
            env!("CARGO_PKG_VERSION"),
            self.opts.formats,
            s.dpi,
            s.size,
            s.margin_pt,
            s.dash.step_deg,
            s.dash.fraction,
            s.chord_tolerance_px,
            s.curves_per_page,
            self.opts.stem
        )
    }
}
