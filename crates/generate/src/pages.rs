//! Rendering an atlas's pages: the per-page job behind `generate`'s [`Renderer`] hook.
//! Streaming: each worker borrows one raster buffer from a [`BufferPool`] for one page at
//! a time and hands the encoded page to the pipeline, which writes it at once (per group),
//! so memory stays bounded by the number of workers whatever the atlas size. Every page
//! is a pure function of its linkage, points and settings, so files are byte-identical
//! for any thread count.

use crate::{Artifact, Group, Job, PageFailure, Rendered, Renderer, compute_group};
use coupler_features::CurveFeatures;
use coupler_index::{IndexCurve, PageRef};
use coupler_kinematics::{AngleTables, Circuit, CouplerPoint, DashPattern, Linkage};
use coupler_layout::{
    ContentsEntry, CurvePlacement, DisplayList, EXTENT_STEP_DEG, LayoutError, LinkagePage,
    Orientation, PageGeometry, PageSetup, compute_page, compute_page_with_tables, layout_contents,
    layout_page,
};
use coupler_render::{
    Bookmark, PageFormat, PageLabelRange, PdfPage, PdfPageContent, PngCompression, RasterPage,
    SvgPage, draw, write_pdf,
};
use coupler_specs::{PageSettings, Sampling, Spec};
use rayon::prelude::*;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// How to render an atlas's pages.
#[derive(Clone, PartialEq)]
pub struct PageOptions {
    /// Layout settings (size, DPI, dash pattern, header/footer text).
    pub setup: PageSetup,
    /// Formats to write (one file per page per format).
    pub formats: Vec<PageFormat>,
    /// File name stem (the spec's name): pages are `STEM-0001.png`, contents
    /// `STEM-0000-contents-001.png` (so that they come first in file order).
    pub stem: String,
    /// How hard PNG pages are compressed (same pixels either way).
    pub png_compression: PngCompression,
}

/// As derived, but the PNG compression is shown only when it is not the default, so that
/// run keys made from this text before the choice existed stay the same.
impl std::fmt::Debug for PageOptions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut d = f.debug_struct("PageOptions");
        d.field("setup", &self.setup)
            .field("formats", &self.formats)
            .field("stem", &self.stem);
        if self.png_compression != PngCompression::Fast {
            d.field("png_compression", &self.png_compression);
        }
        d.finish()
    }
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
            png_compression: PngCompression::Fast,
        })
    }

    /// The file name of atlas page `number` (1-based) in `format`.
    pub fn page_file(&self, number: u64, format: PageFormat) -> String {
        format!("{}-{:04}.{}", self.stem, number, format.extension())
    }

    /// The file name of contents page `number` (1-based) in `format`: numbered 0000 so
    /// that the contents come first in file order.
    pub fn contents_file(&self, number: usize, format: PageFormat) -> String {
        format!(
            "{}-0000-contents-{:03}.{}",
            self.stem,
            number,
            format.extension()
        )
    }

    /// The file of the whole atlas as one PDF.
    pub fn pdf_file(&self) -> String {
        format!("{}.pdf", self.stem)
    }

    /// Formats written page by page (all but PDF, which is one document).
    fn page_formats(&self) -> impl Iterator<Item = PageFormat> + '_ {
        self.formats
            .iter()
            .copied()
            .filter(|f| *f != PageFormat::Pdf)
    }

    fn wants_pdf(&self) -> bool {
        self.formats.contains(&PageFormat::Pdf)
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
    /// The PDF could not be written.
    #[error(transparent)]
    Pdf(#[from] coupler_render::PdfError),
    /// The atlas's curves could not be computed again for the PDF.
    #[error("{0}")]
    Curves(String),
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

    /// A cleared buffer of `w × h` pixels at `dpi`: a free one of that size, or a free
    /// one turned to it (a portrait page's buffer serves a landscape page: same pixels),
    /// else a new one.
    fn take(&self, w: u32, h: u32, dpi: f64) -> Result<RasterPage, PageError> {
        let found = self.free.lock().map(|mut v| v.pop()).unwrap_or(None);
        if let Some(mut b) = found.filter(|b| b.dpi() == dpi) {
            if (b.width(), b.height()) == (w, h) {
                b.clear();
                return Ok(b);
            }
            if b.reshape(w, h) {
                return Ok(b);
            }
        }
        RasterPage::new(w, h, dpi).ok_or(PageError::EmptyRaster(w, h))
    }

    fn give(&self, b: RasterPage) {
        if let Ok(mut v) = self.free.lock() {
            v.push(b);
        }
    }

    /// Lets go of all free buffers but `n` (a page buffer is tens of MB at 300 dpi).
    fn keep(&self, n: usize) {
        if let Ok(mut v) = self.free.lock() {
            v.truncate(n);
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
    /// Writing files: `generate` writes and hashes the files a renderer returns, and
    /// records here how long that took (per group, on the worker).
    pub write: AtomicU64,
    /// `generate`'s own work on a group that has pages, on the worker: its curves and
    /// their features, its index lines and shape records.
    pub index: AtomicU64,
    /// Pages done.
    pub pages: AtomicU64,
}

impl PageTimings {
    /// Adds the time since `since` to `field`; gives the time now.
    pub fn add(field: &AtomicU64, since: Instant) -> Instant {
        let now = Instant::now();
        field.fetch_add((now - since).as_nanos() as u64, Ordering::Relaxed);
        now
    }

    /// `[compute, layout, draw, encode, write, index]` in seconds, and the page count.
    pub fn seconds(&self) -> ([f64; 6], u64) {
        let s = |a: &AtomicU64| a.load(Ordering::Relaxed) as f64 * 1e-9;
        (
            [
                s(&self.compute),
                s(&self.layout),
                s(&self.draw),
                s(&self.encode),
                s(&self.write),
                s(&self.index),
            ],
            self.pages.load(Ordering::Relaxed),
        )
    }
}

/// Renders one display list in every page-by-page format (PNG, SVG): `(format, bytes)`.
fn emit(
    display: &DisplayList,
    opts: &PageOptions,
    pool: &BufferPool,
    timings: &PageTimings,
    mut t: Instant,
) -> Result<Vec<(PageFormat, Vec<u8>)>, PageError> {
    let mut out = Vec::with_capacity(opts.formats.len());
    for format in opts.page_formats() {
        match format {
            PageFormat::Png => {
                // The page's own size: under `auto` each page is portrait or landscape.
                let (w, h) = display.size_px(opts.setup.dpi);
                let mut buf = pool.take(w, h, opts.setup.dpi)?;
                // Drawn and encoded band by band, and the buffer cleared on the way,
                // for the next page.
                let r = buf.render_png(display, opts.png_compression);
                pool.give(buf);
                let (bytes, encode) = r.map_err(PageError::Png)?;
                let now = Instant::now();
                let draw = (now - t).saturating_sub(encode);
                timings
                    .draw
                    .fetch_add(draw.as_nanos() as u64, Ordering::Relaxed);
                timings
                    .encode
                    .fetch_add(encode.as_nanos() as u64, Ordering::Relaxed);
                t = now;
                out.push((format, bytes));
            }
            PageFormat::Svg => {
                let mut svg = SvgPage::new(display.width, display.height);
                draw(display, &mut svg);
                out.push((format, svg.finish().into_bytes()));
                t = PageTimings::add(&timings.draw, t);
            }
            PageFormat::Pdf => {}
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
    /// Where each curve is on the page (points), in point order.
    pub curves: Vec<CurvePlacement>,
    /// The page's orientation (its own under `auto`).
    pub orientation: Orientation,
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
        curves: layout.curves.clone(),
        orientation: layout.display.orientation(),
    })
}

/// An atlas page to render: `points` of `linkage` (whose whole grid is `grid`), with the
/// features of their curves (same order; may be shorter), page `number` of `page_count`.
#[derive(Clone, Copy, Debug)]
pub struct PageJob<'a> {
    /// The mechanism.
    pub linkage: Linkage,
    /// Its circuit.
    pub circuit: Circuit,
    /// The page's coupler points.
    pub points: &'a [CouplerPoint],
    /// The linkage's grid.
    pub grid: &'a [CouplerPoint],
    /// The run's shared input-angle tables for the page's extent trace (`None`: built for
    /// the page; the same page either way).
    pub tables: Option<&'a AngleTables>,
    /// The curves' features, marked on the page.
    pub features: &'a [Option<CurveFeatures>],
    /// Page number (1-based).
    pub number: u64,
    /// Pages in the atlas.
    pub page_count: u64,
}

impl PageJob<'_> {
    /// Computes and lays out the page.
    pub fn layout(
        &self,
        setup: &PageSetup,
        timings: &PageTimings,
    ) -> Result<coupler_layout::PageLayout, PageError> {
        let t0 = Instant::now();
        let page = self.page();
        let geometry = self.geometry(&page, setup)?;
        let t = PageTimings::add(&timings.compute, t0);
        let layout = layout_page(&page, &geometry, setup);
        PageTimings::add(&timings.layout, t);
        Ok(layout)
    }

    /// The page to lay out: its mechanism, points, grid, features and number.
    pub fn page(&self) -> LinkagePage {
        LinkagePage {
            linkage: self.linkage,
            circuit: self.circuit,
            points: self.points.to_vec(),
            grid: self.grid.to_vec(),
            page_number: self.number as usize,
            page_count: self.page_count as usize,
            features: self.features.to_vec(),
        }
    }

    /// The geometry of `page` (this job's [`PageJob::page`]) that [`PageJob::layout`]
    /// lays out: with the run's shared tables when the job has them.
    pub fn geometry(
        &self,
        page: &LinkagePage,
        setup: &PageSetup,
    ) -> Result<PageGeometry, PageError> {
        match self.tables {
            Some(tables) => compute_page_with_tables(page, setup, tables),
            None => compute_page(page, setup),
        }
        .map_err(|source| PageError::Layout {
            page: self.number,
            source,
        })
    }
}

/// What laying a job's pages out again from scratch needs (the multi-page PDF, the
/// page-cost example): the crank table, the feature tolerances and the dash pattern of the
/// job's spec, the curves per page and the page count. The one place that sets up a page's
/// curves and [`PageJob`] outside the streaming renderer.
pub struct PageSource<'j> {
    job: &'j Job,
    table: AngleTables,
    dash: DashPattern,
    per: usize,
    page_count: u64,
}

impl<'j> PageSource<'j> {
    /// The source of `job`'s pages with `per` coupler points each.
    pub fn new(job: &'j Job, per: usize) -> Result<PageSource<'j>, PageError> {
        let table = AngleTables::new(job.spec.sampling.crank_step_deg)
            .ok_or_else(|| PageError::Curves("bad crank step".into()))?;
        Ok(PageSource {
            job,
            table,
            dash: job.spec.sampling.dash_pattern(),
            per: per.max(1),
            page_count: job.pages(),
        })
    }

    /// The features of `group`'s curves (in the order of its points; `None` everywhere
    /// when the spec has features off).
    pub fn features(&self, group: &Group) -> Result<Vec<Option<CurveFeatures>>, PageError> {
        let tolerances = self
            .job
            .spec
            .features
            .enabled
            .then_some(&self.job.spec.features.tolerances);
        let curves = compute_group(&self.table, group, tolerances, &self.dash)
            .map_err(|e| PageError::Curves(e.to_string()))?;
        Ok(curves.into_iter().map(|c| c.features).collect())
    }

    /// `group`'s pages, with `features` from [`PageSource::features`].
    pub fn pages<'a>(
        &'a self,
        group: &'a Group,
        features: &'a [Option<CurveFeatures>],
    ) -> impl Iterator<Item = PageJob<'a>> + 'a {
        PageJob::of_group(
            group,
            self.per,
            self.page_count,
            Some(&self.table),
            features,
        )
    }
}

impl<'a> PageJob<'a> {
    /// The pages of `group`, `per` coupler points each, numbered from the group's first
    /// page, with their curves' `features` (in the order of the group's points; may be
    /// shorter: a page gets those there are).
    pub fn of_group(
        group: &'a Group,
        per: usize,
        page_count: u64,
        tables: Option<&'a AngleTables>,
        features: &'a [Option<CurveFeatures>],
    ) -> impl Iterator<Item = PageJob<'a>> + 'a {
        let per = per.max(1);
        group
            .points
            .chunks(per)
            .enumerate()
            .map(move |(k, points)| {
                let fs = features.get(k * per..).unwrap_or(&[]);
                PageJob {
                    linkage: group.linkage,
                    circuit: group.circuit,
                    points,
                    grid: &group.points,
                    tables,
                    features: &fs[..fs.len().min(points.len())],
                    number: group.first_page + k as u64,
                    page_count,
                }
            })
    }
}

/// Renders an atlas page in the page-by-page formats. Pure apart from the shared buffer
/// pool and timing counters.
pub fn render_page(
    opts: &PageOptions,
    pool: &BufferPool,
    timings: &PageTimings,
    job: &PageJob<'_>,
) -> Result<RenderedPage, PageError> {
    let layout = job.layout(&opts.setup, timings)?;
    finish_page(opts, pool, timings, job.number, &layout, Instant::now())
}

/// A page as PDF content (links: none).
fn pdf_content(display: &DisplayList) -> PdfPageContent {
    let mut pdf = PdfPage::new(display.width, display.height);
    draw(display, &mut pdf);
    pdf.finish(Vec::new())
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

/// Renders the contents pages in the page-by-page formats: `(file name, bytes)` per page
/// and format.
pub fn render_contents(
    opts: &PageOptions,
    pool: &BufferPool,
    entries: &[ContentsEntry],
) -> Result<Vec<(String, Vec<u8>)>, PageError> {
    let timings = PageTimings::default();
    let mut files = Vec::new();
    for (i, page) in layout_contents(entries, &opts.setup).iter().enumerate() {
        for (f, bytes) in emit(&page.display, opts, pool, &timings, Instant::now())? {
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
    /// Input-angle tables shared by every page's extent trace (a geared five-bar's gear
    /// tables built once per gears, not per page).
    tables: AngleTables,
    /// Time spent per phase, summed over workers.
    pub timings: PageTimings,
}

impl PageRenderer {
    /// A renderer with an empty buffer pool.
    pub fn new(opts: PageOptions) -> PageRenderer {
        PageRenderer {
            opts,
            pool: BufferPool::new(),
            tables: AngleTables::new(EXTENT_STEP_DEG).expect("a valid step"),
            timings: PageTimings::default(),
        }
    }
}

impl PageRenderer {
    /// The format whose file names a page in messages and in the index.
    fn first_format(&self) -> PageFormat {
        self.opts.page_formats().next().unwrap_or(PageFormat::Pdf)
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
        let place = match (rendered.files.first(), rendered.curves.first()) {
            (Some(first), Some(c)) => Some(PageRef {
                orientation: Some(rendered.orientation.name().to_string()),
                ..PageRef::new(
                    format!("pages/{}", first.0),
                    c.bbox_px(self.opts.setup.dpi).map(f64::from),
                )
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

/// A curve's place on its page, for the index.
fn page_ref(
    file: &str,
    number: u64,
    c: &CurvePlacement,
    dpi: f64,
    orientation: Orientation,
) -> PageRef {
    PageRef {
        orientation: Some(orientation.name().to_string()),
        file: file.to_string(),
        bbox_px: c.bbox_px(dpi).map(f64::from),
        number: Some(number),
        dot_px: Some(c.dot_px(dpi)),
        label_bbox_px: Some(c.label_bbox_px(dpi).map(f64::from)),
        label: Some(c.label.clone()),
        ghost: c.ghost,
    }
}

impl PageRenderer {
    /// The atlas as one PDF: the contents first (linked to the pages), then every page,
    /// an outline entry per linkage (and per page under it), page labels that match the
    /// printed numbers. The pages are laid out again here, in parallel on `job.jobs`
    /// threads, with their curves' features computed again (the index's are in the chunk
    /// records, but the PDF is one file made once the chunks are done).
    fn atlas_pdf(&self, job: &Job, entries: &[ContentsEntry]) -> Result<Vec<u8>, PageError> {
        // A paged atlas is bounded (docs/scale.md), so its groups fit in memory.
        let groups: Vec<Group> = job.groups().collect();
        let source = PageSource::new(job, self.opts.setup.curves_per_page)?;
        let timings = PageTimings::default();
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(job.jobs)
            .build()
            .map_err(|e| PageError::Curves(e.to_string()))?;
        let pages: Result<Vec<Vec<PdfPageContent>>, PageError> = pool.install(|| {
            groups
                .par_iter()
                .map(|g| {
                    let feats = source.features(g)?;
                    source
                        .pages(g, &feats)
                        .map(|pj| Ok(pdf_content(&pj.layout(&self.opts.setup, &timings)?.display)))
                        .collect()
                })
                .collect()
        });
        let atlas: Vec<PdfPageContent> = pages?.into_iter().flatten().collect();
        let contents = layout_contents(entries, &self.opts.setup);
        let n_contents = contents.len();
        let mut doc: Vec<PdfPageContent> = contents
            .iter()
            .map(|c| {
                let mut pdf = PdfPage::new(c.display.width, c.display.height);
                draw(&c.display, &mut pdf);
                let links = c
                    .links
                    .iter()
                    .map(|(r, number)| (*r, n_contents + number - 1))
                    .collect();
                pdf.finish(links)
            })
            .collect();
        doc.extend(atlas);
        let mut bookmarks = vec![Bookmark {
            title: "Contents".into(),
            page: 0,
            children: Vec::new(),
        }];
        for e in entries {
            let dims = coupler_kinematics::Mechanism::dimensions(&e.linkage)
                .iter()
                .map(|(n, v)| format!("{n} = {}", coupler_layout::fmt_sig(*v)))
                .collect::<Vec<_>>()
                .join("  ");
            let title = if job.spec.circuits.len() > 1 {
                format!("{dims} ({})", e.circuit.name())
            } else {
                dims
            };
            bookmarks.push(Bookmark {
                title,
                page: n_contents + e.first_page - 1,
                children: (e.first_page..=e.last_page)
                    .map(|p| Bookmark {
                        title: format!("page {p}"),
                        page: n_contents + p - 1,
                        children: Vec::new(),
                    })
                    .collect(),
            });
        }
        let labels = [
            PageLabelRange {
                start: 0,
                prefix: "contents ".into(),
                first: 1,
            },
            PageLabelRange {
                start: n_contents,
                prefix: String::new(),
                first: 1,
            },
        ];
        Ok(write_pdf(&doc, &bookmarks, &labels, &job.spec.title)?)
    }

    /// The contents entries of a job.
    /// The contents pages' files of `entries` (names relative to the atlas folder), or
    /// the failure of the first.
    fn contents_files(&self, entries: &[ContentsEntry]) -> Rendered {
        match render_contents(&self.opts, &self.pool, entries) {
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

    fn contents_entries(&self, job: &Job) -> Vec<ContentsEntry> {
        let per = self.opts.setup.curves_per_page.max(1);
        job.groups()
            .map(|g| ContentsEntry {
                linkage: g.linkage,
                circuit: g.circuit,
                curves: g.points.len(),
                first_page: g.first_page as usize,
                last_page: (g.first_page + (g.points.len() as u64).div_ceil(per as u64))
                    .saturating_sub(1) as usize,
                pages: g.points.chunks(per).map(|c| c.to_vec()).collect(),
            })
            .collect()
    }
}

impl PageRenderer {
    /// `group`'s pages ([`Renderer::render_group`]); with `shared`, drawn as rayon tasks
    /// (whichever worker of the pool is free draws some), else one after another on the
    /// calling thread. Each page is a pure function of its job, and the pages are taken
    /// in their order either way, so the files and the curves' places are the same.
    fn group_pages(
        &self,
        job: &Job,
        group: &Group,
        curves: &mut [IndexCurve],
        shared: bool,
    ) -> Rendered {
        let per = self.opts.setup.curves_per_page.max(1);
        let page_count = job.pages();
        let features: Vec<Option<CurveFeatures>> =
            curves.iter().map(|c| c.features.clone()).collect();
        let jobs: Vec<PageJob<'_>> =
            PageJob::of_group(group, per, page_count, Some(&self.tables), &features).collect();
        let render = |pj: &PageJob<'_>| render_page(&self.opts, &self.pool, &self.timings, pj);
        let pages: Vec<Result<RenderedPage, PageError>> = if shared {
            jobs.par_iter().with_max_len(1).map(render).collect()
        } else {
            jobs.iter().map(render).collect()
        };
        let mut out = Vec::new();
        for (k, (pj, page)) in jobs.iter().zip(pages).enumerate() {
            let number = pj.number;
            let page = match page {
                Ok(page) => page,
                Err(e) => {
                    out.push(Err(
                        self.failure(self.opts.page_file(number, self.first_format()), e)
                    ));
                    continue;
                }
            };
            let first = match page.files.first() {
                Some(f) => format!("pages/{}", f.0),
                None => format!("pages/{}", self.opts.pdf_file()),
            };
            for (i, c) in page.curves.iter().enumerate() {
                if let Some(ic) = curves.get_mut(k * per + i) {
                    ic.page = Some(page_ref(
                        &first,
                        number,
                        c,
                        self.opts.setup.dpi,
                        page.orientation,
                    ));
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
}

impl Renderer for PageRenderer {
    fn render_group(&self, job: &Job, group: &Group, curves: &mut [IndexCurve]) -> Rendered {
        self.group_pages(job, group, curves, false)
    }

    /// The group's pages as rayon tasks, so that a worker of the run's pool with no unit
    /// left draws some of them (see [`Renderer::render_group_shared`]).
    fn render_group_shared(&self, job: &Job, group: &Group, curves: &mut [IndexCurve]) -> Rendered {
        self.group_pages(job, group, curves, true)
    }

    fn render_atlas(&self, job: &Job) -> Rendered {
        let entries = self.contents_entries(job);
        // The contents pages are drawn one after another: one buffer serves them, the
        // others (one per worker of the run) are let go first, so that the run's memory
        // peaks no higher here than while the workers draw.
        self.pool.keep(1);
        let mut out = self.contents_files(&entries);
        // Nothing is drawn into a raster buffer after the contents.
        self.pool.keep(0);
        if self.opts.wants_pdf() {
            out.push(match self.atlas_pdf(job, &entries) {
                Ok(bytes) => Ok(Artifact {
                    name: format!("pages/{}", self.opts.pdf_file()),
                    bytes,
                }),
                Err(e) => Err(self.failure(self.opts.pdf_file(), e)),
            });
        }
        out
    }

    /// The contents pages (they depend on the job alone) when they are all the atlas
    /// files: drawn on the calling worker with the buffer it draws its pages with (the
    /// pool is not trimmed: the workers go on drawing). An atlas PDF is drawn on a pool
    /// of its own, after the groups ([`Renderer::render_atlas`]).
    fn render_atlas_alongside(&self, job: &Job) -> Option<Rendered> {
        if self.opts.wants_pdf() {
            return None;
        }
        Some(self.contents_files(&self.contents_entries(job)))
    }

    fn pages(&self, job: &Job) -> u64 {
        job.pages()
    }

    fn page_options(&self) -> Option<&PageOptions> {
        Some(&self.opts)
    }

    fn timings(&self) -> Option<&PageTimings> {
        Some(&self.timings)
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
        // The default compression adds nothing, so that runs made before the choice
        // existed keep their key.
        let png = match self.opts.png_compression {
            PngCompression::Fast => String::new(),
            c => format!(" png {}", c.name()),
        };
        format!(
            "pages {} formats {:?} {} dpi {} margin {} pt dash {}°×{} tolerance {} px curves/page {} stem {}{png}",
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The contents pages made alongside the groups are those made at the end, name for
    /// name and byte for byte (PNG and SVG, at a low resolution, for both quick jobs);
    /// with a PDF wanted nothing is made alongside (the atlas PDF is drawn at the end).
    #[test]
    fn contents_made_alongside_are_those_made_at_the_end() {
        for job in crate::job::quick_jobs() {
            let mut opts = PageOptions::from_spec(&job.spec).unwrap();
            opts.setup.dpi = 30.0;
            opts.formats = vec![PageFormat::Png, PageFormat::Svg];
            let files = |r: Rendered| -> Vec<(String, Vec<u8>)> {
                r.into_iter()
                    .map(|a| a.map(|a| (a.name, a.bytes)).unwrap())
                    .collect()
            };
            let renderer = PageRenderer::new(opts.clone());
            let alongside = files(renderer.render_atlas_alongside(&job).unwrap());
            let at_end = files(PageRenderer::new(opts.clone()).render_atlas(&job));
            assert!(alongside.len() >= 2, "{} files", alongside.len());
            assert!(alongside == at_end, "{}", job.spec.name);
            opts.formats.push(PageFormat::Pdf);
            assert!(
                PageRenderer::new(opts)
                    .render_atlas_alongside(&job)
                    .is_none()
            );
        }
    }

    /// A group's pages drawn as shared tasks (on pools of two and of three workers, as the
    /// run's last units are) are the files drawn one after another, name for name, byte
    /// for byte and in the same order, and the curves are given the same places.
    #[test]
    fn a_groups_pages_drawn_as_shared_tasks_are_those_drawn_in_turn() {
        let mut jobs = crate::job::quick_jobs();
        jobs.push(Job::new(Spec::default_atlas(), "default", "unused", 1));
        let files = |r: Rendered| -> Vec<(String, Vec<u8>)> {
            r.into_iter()
                .map(|a| a.map(|a| (a.name, a.bytes)).unwrap())
                .collect()
        };
        let mut several = 0;
        for job in jobs {
            let mut opts = PageOptions::from_spec(&job.spec).unwrap();
            opts.setup.dpi = 72.0;
            opts.formats = vec![PageFormat::Png, PageFormat::Svg];
            let per = opts.setup.curves_per_page;
            let renderer = PageRenderer::new(opts);
            let table = AngleTables::new(job.spec.sampling.crank_step_deg).unwrap();
            let tolerances = job
                .spec
                .features
                .enabled
                .then_some(&job.spec.features.tolerances);
            let dash = job.spec.sampling.dash_pattern();
            for group in job.groups().take(2) {
                let curves = compute_group(&table, &group, tolerances, &dash).unwrap();
                let mut alone = curves.clone();
                let want = files(renderer.render_group(&job, &group, &mut alone));
                assert!(alone.iter().all(|c| c.page.is_some()));
                several += usize::from(group.points.len() > 2 * per);
                for threads in [2, 3] {
                    let pool = rayon::ThreadPoolBuilder::new()
                        .num_threads(threads)
                        .build()
                        .unwrap();
                    let mut shared = curves.clone();
                    let got = pool
                        .install(|| files(renderer.render_group_shared(&job, &group, &mut shared)));
                    assert!(got == want, "{} on {threads} workers", job.spec.name);
                    assert!(shared == alone, "{} on {threads} workers", job.spec.name);
                }
            }
        }
        assert!(several >= 2, "the test needs groups of several pages");
    }

    /// A group's page jobs cover its points in order, `per` each, numbered from the
    /// group's first page, each with the features of its own points (fewer when the
    /// features run short).
    #[test]
    fn a_groups_page_jobs_split_points_and_features_alike() {
        let job = Job::new(Spec::default_atlas(), "default", "unused", 1);
        let per = job.spec.pages.curves_per_page as usize;
        let source = PageSource::new(&job, per).expect("source");
        let group = job.groups().nth(1).expect("a second group");
        let feats = source.features(&group).expect("features");
        assert_eq!(feats.len(), group.points.len());
        let pages: Vec<PageJob<'_>> = source.pages(&group, &feats).collect();
        assert_eq!(pages.len(), group.points.len().div_ceil(per));
        assert!(pages.len() > 1, "the test needs a group of several pages");
        for (k, pj) in pages.iter().enumerate() {
            assert_eq!(pj.number, group.first_page + k as u64);
            assert_eq!(pj.page_count, job.pages());
            assert_eq!(pj.points, &group.points[k * per..][..pj.points.len()]);
            assert_eq!(pj.features, &feats[k * per..][..pj.points.len()]);
            assert!(pj.tables.is_some());
        }
        let short = &feats[..per + 1];
        let lens: Vec<usize> = PageJob::of_group(&group, per, 9, None, short)
            .map(|pj| pj.features.len())
            .collect();
        assert_eq!(lens[..2], [per, 1]);
        assert!(lens[2..].iter().all(|&n| n == 0));
    }
}
