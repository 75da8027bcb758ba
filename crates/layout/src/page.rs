//! Page layout (pure): from a linkage and the coupler points of one page to a display
//! list of primitives in page points (1/72 in, f64, origin at the top-left corner, y
//! down). No pixels here: a renderer maps points to its device.
//!
//! A page (after Hrones & Nelson, 1951) shows one linkage drawn in one position with its
//! grid of coupler points, and the dashed coupler curves of up to `curves_per_page`
//! points, all in the linkage's own frame at one shared scale (so curves can be compared
//! and measured; the scale bar gives the crank length on paper). Each curve carries a
//! `(u, v)` label placed where it collides least with curves and other labels, a bold
//! θ = 0 dash with a dot at θ = 0 and an arrowhead for the direction of travel.
//! Everything is fitted to the frame: a curve is never cut.

use crate::font;
use coupler_kinematics::{DashError, DashPattern, Drawing};

/// Points per inch.
pub const PT_PER_INCH: f64 = 72.0;
/// Default resolution for raster pages (print quality).
pub const DEFAULT_DPI: f64 = 300.0;
/// Resolutions accepted for raster pages, dots per inch (spec `[pages] dpi` and
/// `--dpi` alike): a 1200 dpi tabloid page is a 269 MB buffer per worker.
pub const DPI_RANGE: std::ops::RangeInclusive<u32> = 36..=1200;
/// Default number of curves on a page.
pub const DEFAULT_CURVES_PER_PAGE: usize = 10;
/// Default page margin in points (0.5 in).
pub const DEFAULT_MARGIN_PT: f64 = 36.0;
/// Chord tolerance of dash polylines, in device pixels at the page's DPI.
pub const DEFAULT_CHORD_TOLERANCE_PX: f64 = 0.1;

/// Line widths and sizes, in points.
pub(crate) mod style {
    pub const DASH_WIDTH: f64 = 0.75;
    pub const ZERO_DASH_WIDTH: f64 = 1.9;
    pub const HEAVY_DASH_WIDTH: f64 = 1.5;
    pub const MIN_DASH_LENGTH: f64 = 1.0;
    pub const DOT_RADIUS: f64 = 0.75;
    pub const START_DOT_RADIUS: f64 = 1.9;
    pub const ARROW_LENGTH: f64 = 6.0;
    pub const ARROW_HALF_WIDTH: f64 = 2.4;
    pub const LINK_WIDTH: f64 = 1.6;
    pub const PIN_RADIUS: f64 = 2.6;
    pub const GRID_RADIUS: f64 = 1.5;
    pub const THIN: f64 = 0.4;
    pub const FRAME: f64 = 0.6;
    pub const TITLE_SIZE: f64 = 15.0;
    pub const TEXT_SIZE: f64 = 9.0;
    pub const LABEL_SIZE: f64 = 7.5;
    pub const SMALL_SIZE: f64 = 7.0;
    pub const HEADER_HEIGHT: f64 = 44.0;
    pub const FOOTER_HEIGHT: f64 = 58.0;
    pub const FRAME_PAD: f64 = 14.0;
}

/// Standard paper sizes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PaperSize {
    /// 11 × 17 in, the 1951 atlas.
    Tabloid,
    /// 8.5 × 11 in.
    Letter,
    /// 210 × 297 mm.
    A4,
    /// 297 × 420 mm.
    A3,
}

impl PaperSize {
    /// Every paper size, in the order they are listed to users.
    pub const ALL: [PaperSize; 4] = [
        PaperSize::Tabloid,
        PaperSize::Letter,
        PaperSize::A4,
        PaperSize::A3,
    ];

    /// The names of [`PaperSize::ALL`] as a list for messages, the last joined by
    /// `conjunction`: `"tabloid, letter, a4 or a3"`.
    pub fn names(conjunction: &str) -> String {
        let names: Vec<&str> = PaperSize::ALL.iter().map(|p| p.name()).collect();
        match names.split_last() {
            Some((last, rest)) if !rest.is_empty() => {
                format!("{} {conjunction} {last}", rest.join(", "))
            }
            _ => names.join(", "),
        }
    }

    /// (width, height) in portrait, points.
    pub fn portrait_pt(self) -> (f64, f64) {
        let mm = PT_PER_INCH / 25.4;
        match self {
            PaperSize::Tabloid => (11.0 * PT_PER_INCH, 17.0 * PT_PER_INCH),
            PaperSize::Letter => (8.5 * PT_PER_INCH, 11.0 * PT_PER_INCH),
            PaperSize::A4 => (210.0 * mm, 297.0 * mm),
            PaperSize::A3 => (297.0 * mm, 420.0 * mm),
        }
    }

    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            PaperSize::Tabloid => "tabloid",
            PaperSize::Letter => "letter",
            PaperSize::A4 => "a4",
            PaperSize::A3 => "a3",
        }
    }
}

impl std::fmt::Display for PaperSize {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for PaperSize {
    type Err = LayoutError;
    /// A paper size by name, any case: `tabloid` (also `ledger`, `11x17`), `letter`,
    /// `a4`, `a3`.
    fn from_str(s: &str) -> Result<PaperSize, LayoutError> {
        match s.trim().to_ascii_lowercase().as_str() {
            "ledger" | "11x17" => Ok(PaperSize::Tabloid),
            name => PaperSize::ALL
                .into_iter()
                .find(|p| p.name() == name)
                .ok_or_else(|| LayoutError::UnknownPageSize(s.to_string())),
        }
    }
}

/// Portrait, landscape, or chosen page by page.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Orientation {
    /// Long side vertical.
    Portrait,
    /// Long side horizontal.
    Landscape,
    /// Each page takes the orientation that gives its curves the larger scale (portrait
    /// on a tie, and for pages without curves: the contents).
    Auto,
}

impl Orientation {
    /// `"portrait"`, `"landscape"` or `"auto"`.
    pub fn name(self) -> &'static str {
        match self {
            Orientation::Portrait => "portrait",
            Orientation::Landscape => "landscape",
            Orientation::Auto => "auto",
        }
    }

    /// The orientations a page may take: one, or both for [`Orientation::Auto`]
    /// (portrait first: it wins ties).
    pub fn candidates(self) -> &'static [Orientation] {
        match self {
            Orientation::Portrait => &[Orientation::Portrait],
            Orientation::Landscape => &[Orientation::Landscape],
            Orientation::Auto => &[Orientation::Portrait, Orientation::Landscape],
        }
    }
}

impl std::fmt::Display for Orientation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Orientation {
    type Err = String;
    /// `portrait`, `landscape` or `auto`.
    fn from_str(s: &str) -> Result<Orientation, String> {
        match s {
            "portrait" => Ok(Orientation::Portrait),
            "landscape" => Ok(Orientation::Landscape),
            "auto" => Ok(Orientation::Auto),
            _ => Err(format!(
                "must be `portrait`, `landscape` or `auto`, got `{s}`"
            )),
        }
    }
}

/// A page size: paper and orientation. Parses from `tabloid`, `letter`, `a4`, `a3`,
/// optionally suffixed `-landscape`, `-auto` (each page chooses) or `-portrait` (the
/// default).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct PageSize {
    /// Paper.
    pub paper: PaperSize,
    /// Orientation.
    pub orientation: Orientation,
}

/// A layout setting that cannot be used.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LayoutError {
    /// Unknown page size name.
    #[error(
        "unknown page size {0:?} (expected {names}, optionally with -landscape or -auto)",
        names = PaperSize::names("or")
    )]
    UnknownPageSize(String),
    /// A setting out of range.
    #[error("invalid page setting: {0}")]
    BadSetting(String),
    /// A curve could not be dashed.
    #[error(transparent)]
    Dash(#[from] DashError),
}

impl Default for PageSize {
    fn default() -> Self {
        PageSize {
            paper: PaperSize::Tabloid,
            orientation: Orientation::Portrait,
        }
    }
}

impl std::str::FromStr for PageSize {
    type Err = LayoutError;
    fn from_str(s: &str) -> Result<PageSize, LayoutError> {
        let lower = s.trim().to_ascii_lowercase();
        let (name, orientation) = if let Some(n) = lower.strip_suffix("-landscape") {
            (n, Orientation::Landscape)
        } else if let Some(n) = lower.strip_suffix("-auto") {
            (n, Orientation::Auto)
        } else if let Some(n) = lower.strip_suffix("-portrait") {
            (n, Orientation::Portrait)
        } else {
            (lower.as_str(), Orientation::Portrait)
        };
        let paper: PaperSize = name
            .parse()
            .map_err(|_| LayoutError::UnknownPageSize(s.to_string()))?;
        Ok(PageSize { paper, orientation })
    }
}

impl std::fmt::Display for PageSize {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.orientation {
            Orientation::Portrait => write!(f, "{}", self.paper.name()),
            Orientation::Landscape => write!(f, "{}-landscape", self.paper.name()),
            Orientation::Auto => write!(f, "{}-auto", self.paper.name()),
        }
    }
}

impl PageSize {
    /// (width, height) in points (portrait for [`Orientation::Auto`]: the size of a
    /// page that does not choose, such as the contents).
    pub fn size_pt(&self) -> (f64, f64) {
        let (w, h) = self.paper.portrait_pt();
        match self.orientation {
            Orientation::Portrait | Orientation::Auto => (w, h),
            Orientation::Landscape => (h, w),
        }
    }

    /// This paper in orientation `o`.
    pub fn oriented(self, o: Orientation) -> PageSize {
        PageSize {
            paper: self.paper,
            orientation: o,
        }
    }
}

/// Everything about a page that does not depend on its linkage.
#[derive(Clone, Debug, PartialEq)]
pub struct PageSetup {
    /// Paper and orientation.
    pub size: PageSize,
    /// Margin on every side, points.
    pub margin_pt: f64,
    /// Raster resolution (dots per inch); also sets the dash chord tolerance.
    pub dpi: f64,
    /// Curves per page.
    pub curves_per_page: usize,
    /// Dash pattern.
    pub dash: DashPattern,
    /// Chord tolerance in device pixels.
    pub chord_tolerance_px: f64,
    /// Atlas (spec) name printed in the header.
    pub spec_name: String,
    /// Generation settings printed in the footer (free text, one line).
    pub settings: String,
}

impl Default for PageSetup {
    fn default() -> Self {
        PageSetup {
            size: PageSize::default(),
            margin_pt: DEFAULT_MARGIN_PT,
            dpi: DEFAULT_DPI,
            curves_per_page: DEFAULT_CURVES_PER_PAGE,
            dash: DashPattern::default(),
            chord_tolerance_px: DEFAULT_CHORD_TOLERANCE_PX,
            spec_name: String::from("atlas"),
            settings: String::new(),
        }
    }
}

impl PageSetup {
    /// Checks ranges (DPI in [`DPI_RANGE`], margin, curves per page ≥ 1, dash pattern).
    pub fn validate(&self) -> Result<(), LayoutError> {
        let (w, h) = self.size.size_pt();
        let dpi = f64::from(*DPI_RANGE.start())..=f64::from(*DPI_RANGE.end());
        if !(self.dpi.is_finite() && dpi.contains(&self.dpi)) {
            return Err(LayoutError::BadSetting(format!(
                "dpi {} not in {}..={}",
                self.dpi,
                DPI_RANGE.start(),
                DPI_RANGE.end()
            )));
        }
        if !(self.margin_pt.is_finite()
            && self.margin_pt >= 0.0
            && 2.0 * self.margin_pt < 0.5 * w.min(h))
        {
            return Err(LayoutError::BadSetting(format!(
                "margin {} pt",
                self.margin_pt
            )));
        }
        if self.curves_per_page == 0 {
            return Err(LayoutError::BadSetting(
                "curves per page must be ≥ 1".into(),
            ));
        }
        if !(self.chord_tolerance_px.is_finite() && self.chord_tolerance_px > 0.0) {
            return Err(LayoutError::BadSetting(
                "chord tolerance must be > 0".into(),
            ));
        }
        self.dash.validate()?;
        Ok(())
    }

    /// Page width and height in points.
    pub fn size_pt(&self) -> (f64, f64) {
        self.size.size_pt()
    }

    /// This setup with the page in orientation `o` (a page's own setup, once it has
    /// chosen under [`Orientation::Auto`]).
    pub fn oriented(&self, o: Orientation) -> PageSetup {
        PageSetup {
            size: self.size.oriented(o),
            ..self.clone()
        }
    }

    /// Device pixels per point.
    pub fn px_per_pt(&self) -> f64 {
        self.dpi / PT_PER_INCH
    }

    /// The frame (the plot area, inside the margins, below the header and above the
    /// footer) in points: `[x0, y0, x1, y1]`.
    pub fn frame_pt(&self) -> [f64; 4] {
        frame_of(self)
    }

    /// Raster size in pixels (rounded).
    pub fn size_px(&self) -> (u32, u32) {
        let (w, h) = self.size_pt();
        let k = self.px_per_pt();
        ((w * k).round() as u32, (h * k).round() as u32)
    }
}

/// Where text sits relative to its anchor point (horizontal), on its baseline.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Anchor {
    /// Anchor at the start of the text.
    Start,
    /// Anchor at the middle.
    Middle,
    /// Anchor at the end.
    End,
}

/// A point on the page, in points, y down.
pub type PagePoint = [f64; 2];

/// The ink a primitive is drawn with: black, a gray, or paper white (which erases what
/// is under it: label halos). Set by [`Primitive::Ink`] for the primitives after it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Ink {
    /// Full black.
    #[default]
    Black,
    /// A gray: the fraction of full ink, in 1/255 (0 = none, 255 = black). Grays
    /// overprint: ink only ever darkens what is under it, as on a press.
    Gray(u8),
    /// Paper: erases the ink under it (a label's halo).
    Paper,
}

impl Ink {
    /// Ink amount 0..=255 (paper 0, black 255).
    pub fn level(self) -> u8 {
        match self {
            Ink::Black => 255,
            Ink::Gray(g) => g,
            Ink::Paper => 0,
        }
    }

    /// The colour as an sRGB gray level, 0 = black, 255 = white.
    pub fn gray(self) -> u8 {
        255 - self.level()
    }
}

/// One drawing primitive in page points. Widths are in points; ink is black unless an
/// [`Primitive::Ink`] before it says otherwise.
#[derive(Clone, Debug, PartialEq)]
pub enum Primitive {
    /// The ink of the primitives that follow (until the next `Ink`).
    Ink(Ink),
    /// An open polyline with round caps and joins.
    Polyline {
        /// Vertices.
        points: Vec<PagePoint>,
        /// Stroke width.
        width: f64,
    },
    /// Several open polylines of one width stroked together (the dashes of a curve):
    /// the ink is the union of their strokes.
    Polylines {
        /// The polylines.
        lines: Vec<Vec<PagePoint>>,
        /// Stroke width.
        width: f64,
    },
    /// An axis-aligned rectangle `[x0, y0, x1, y1]` outlined with a stroke of `width`
    /// centred on its edges (mitred corners).
    Rect {
        /// Corners.
        rect: [f64; 4],
        /// Stroke width.
        width: f64,
    },
    /// A filled polygon (closed implicitly), non-zero rule.
    Polygon {
        /// Vertices.
        points: Vec<PagePoint>,
    },
    /// A circle: stroked outline of `width`, or filled when `width` is `None`.
    Circle {
        /// Centre.
        center: PagePoint,
        /// Radius.
        radius: f64,
        /// Outline width, or `None` for a filled disc.
        width: Option<f64>,
    },
    /// One line of text (embedded font), baseline through `pos`.
    Text {
        /// Anchor point on the baseline.
        pos: PagePoint,
        /// Em size in points.
        size: f64,
        /// Horizontal anchoring.
        anchor: Anchor,
        /// The text.
        text: String,
        /// Width of a paper-white halo stroked around the glyphs before they are filled
        /// (points; 0 for none), so that a label stays legible over curves.
        halo: f64,
    },
}

/// A page as a list of primitives, drawn in order.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct DisplayList {
    /// Page width, points.
    pub width: f64,
    /// Page height, points.
    pub height: f64,
    /// Primitives in drawing order.
    pub items: Vec<Primitive>,
}

impl DisplayList {
    /// An empty page.
    pub fn new(width: f64, height: f64) -> DisplayList {
        DisplayList {
            width,
            height,
            items: Vec::new(),
        }
    }

    /// The raster size of this page at `dpi`, pixels (rounded).
    pub fn size_px(&self, dpi: f64) -> (u32, u32) {
        let k = dpi / PT_PER_INCH;
        (
            (self.width * k).round() as u32,
            (self.height * k).round() as u32,
        )
    }

    /// Portrait or landscape, by its size.
    pub fn orientation(&self) -> Orientation {
        if self.width > self.height {
            Orientation::Landscape
        } else {
            Orientation::Portrait
        }
    }

    pub(crate) fn line(&mut self, points: Vec<PagePoint>, width: f64) {
        self.items.push(Primitive::Polyline { points, width });
    }

    pub(crate) fn text(
        &mut self,
        pos: PagePoint,
        size: f64,
        anchor: Anchor,
        text: impl Into<String>,
    ) {
        self.items.push(Primitive::Text {
            pos,
            size,
            anchor,
            text: text.into(),
            halo: 0.0,
        });
    }

    /// Text with a paper-white halo of `halo` points around its glyphs.
    pub(crate) fn text_halo(
        &mut self,
        pos: PagePoint,
        size: f64,
        anchor: Anchor,
        text: impl Into<String>,
        halo: f64,
    ) {
        self.items.push(Primitive::Text {
            pos,
            size,
            anchor,
            text: text.into(),
            halo,
        });
    }

    /// Sets the ink of the primitives that follow.
    pub(crate) fn ink(&mut self, ink: Ink) {
        self.items.push(Primitive::Ink(ink));
    }

    pub(crate) fn circle(&mut self, center: PagePoint, radius: f64, width: Option<f64>) {
        self.items.push(Primitive::Circle {
            center,
            radius,
            width,
        });
    }

    pub(crate) fn rect(&mut self, r: [f64; 4], width: f64) {
        self.items.push(Primitive::Rect { rect: r, width });
    }
}

/// The affine map from curve units (y up) to page points (y down): uniform scale.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorldToPage {
    /// Points per crank unit.
    pub scale: f64,
    /// Page position of the world origin O2.
    pub origin: PagePoint,
}

impl WorldToPage {
    /// Maps a world point to the page.
    pub fn map(&self, x: f64, y: f64) -> PagePoint {
        [
            self.origin[0] + self.scale * x,
            self.origin[1] - self.scale * y,
        ]
    }
}

/// Inches per crank unit offered for the page scale (the largest that fits is chosen),
/// so that the printed scale is a round number: steps of 0.025 in up to 1 in, 0.05 in up
/// to 3 in, 0.25 in up to 10 in (never more than 5 % below the exact fit above 0.5 in).
pub(crate) fn nice_inches_per_unit() -> Vec<f64> {
    let mut v: Vec<f64> = (4..=40).map(|k| f64::from(k) * 0.025).collect();
    v.extend((21..=60).map(|k| f64::from(k) * 0.05));
    v.extend((13..=40).map(|k| f64::from(k) * 0.25));
    v
}

pub(crate) fn frame_of(setup: &PageSetup) -> [f64; 4] {
    frame_for(setup, setup.size.orientation)
}

/// The frame of a page of `setup` in orientation `o`.
pub(crate) fn frame_for(setup: &PageSetup, o: Orientation) -> [f64; 4] {
    let (w, h) = setup.size.oriented(o).size_pt();
    let m = setup.margin_pt;
    [
        m,
        m + style::HEADER_HEIGHT,
        w - m,
        h - m - style::FOOTER_HEIGHT,
    ]
}

pub(crate) fn union(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
    [
        a[0].min(b[0]),
        a[1].min(b[1]),
        a[2].max(b[2]),
        a[3].max(b[3]),
    ]
}

/// `r` shrunk by `d` on every side.
pub(crate) fn inset_rect(r: [f64; 4], d: f64) -> [f64; 4] {
    [r[0] + d, r[1] + d, r[2] - d, r[3] - d]
}

/// The transform that centres `world` (a curve-unit box, padded by 2 % of its extent) in
/// the page rectangle `inner` at the largest scale of `nice` (inches per unit, ascending)
/// that fits (the exact fit if even the smallest is too large).
pub(crate) fn fit_into(world: [f64; 4], inner: [f64; 4], nice: &[f64]) -> WorldToPage {
    // A margin of 2 % of the extent (sampled extents can miss a sliver of a sharp tip).
    let pad = 0.02 * (world[2] - world[0]).max(world[3] - world[1]);
    let world = [
        world[0] - pad,
        world[1] - pad,
        world[2] + pad,
        world[3] + pad,
    ];
    let fit = ((inner[2] - inner[0]) / (world[2] - world[0]))
        .min((inner[3] - inner[1]) / (world[3] - world[1]));
    let fit_in = fit / PT_PER_INCH;
    let scale_in = nice
        .iter()
        .rev()
        .copied()
        .find(|&s| s <= fit_in)
        .unwrap_or(fit_in); // tiny: keep the exact fit rather than overrun
    let scale = scale_in * PT_PER_INCH;
    let cx = 0.5 * (world[0] + world[2]);
    let cy = 0.5 * (world[1] + world[3]);
    let mid = [0.5 * (inner[0] + inner[2]), 0.5 * (inner[1] + inner[3])];
    WorldToPage {
        scale,
        origin: [mid[0] - scale * cx, mid[1] + scale * cy],
    }
}

/// Formats a length or coordinate compactly ("3", "2.5", "-1.25").
pub fn fmt_num(x: f64) -> String {
    let s = format!("{x}");
    if s == "-0" { "0".into() } else { s }
}

/// A coarse occupancy grid over the frame, for placing labels where they cover the least
/// ink; queried through a summed-area table.
///
/// **Its buffers are kept per thread.** A page's grid (about 93 000 cells and as many
/// table entries on a tabloid page) is taken from this thread's [`GRIDS`] and given back
/// when dropped, so that a worker laying out page after page allocates it once: the
/// cells are zeroed for each page; the table is not, since [`Occupancy::build`] writes
/// every entry a query reads (its first row and column are zeroed there, the rows above
/// the first marked one zeroed, the others summed), and a query before any build reads
/// an empty table as a fresh grid did.
pub(crate) struct Occupancy {
    x0: f64,
    y0: f64,
    cell: f64,
    nx: usize,
    ny: usize,
    cells: Vec<u32>,
    sat: Vec<u32>,
    /// The weights marked so far, summed (on the grid or not): a bound on every cell and
    /// every sum of cells.
    marked: u64,
    /// No cell of a row above this one was marked since the last build (or since the
    /// grid was made): the table's rows up to it are those of that build (or all zero).
    clean_rows: usize,
    /// Whether the table has been built at least once (before that, it reads as zero).
    built: bool,
}

/// Each thread's spare grid buffers (cells, table), reused by [`Occupancy::new`].
const GRID_SPARES: usize = 2;

thread_local! {
    static GRIDS: std::cell::RefCell<Vec<(Vec<u32>, Vec<u32>)>> =
        const { std::cell::RefCell::new(Vec::new()) };
}

impl Drop for Occupancy {
    fn drop(&mut self) {
        let bufs = (
            std::mem::take(&mut self.cells),
            std::mem::take(&mut self.sat),
        );
        // (During the thread's own teardown the spares are gone: the buffers are freed.)
        let _ = GRIDS.try_with(|g| {
            let mut g = g.borrow_mut();
            if g.len() < GRID_SPARES {
                g.push(bufs);
            }
        });
    }
}

/// `⌈x⌉` as an index, for `x ≤` a small whole number (or NaN, or negative: 0): the same
/// value as `x.ceil() as usize` without a call to `ceil` (the truncation, plus one where
/// it fell below `x`; exact, as the truncation is a whole `f64`).
#[inline]
fn ceil_index(x: f64) -> usize {
    let t = x as usize;
    t.saturating_add(usize::from((t as f64) < x))
}

impl Occupancy {
    pub(crate) fn new(frame: [f64; 4], cell: f64) -> Occupancy {
        let nx = ((frame[2] - frame[0]) / cell).ceil() as usize + 1;
        let ny = ((frame[3] - frame[1]) / cell).ceil() as usize + 1;
        let (mut cells, mut sat) = GRIDS
            .try_with(|g| g.borrow_mut().pop())
            .ok()
            .flatten()
            .unwrap_or_default();
        cells.clear();
        cells.resize(nx * ny, 0);
        // Not zeroed: `build` writes every entry read (see the type's documentation).
        sat.resize((nx + 1) * (ny + 1), 0);
        Occupancy {
            x0: frame[0],
            y0: frame[1],
            cell,
            nx,
            ny,
            cells,
            sat,
            marked: 0,
            clean_rows: ny,
            built: false,
        }
    }

    /// A grid on buffers of its own, zeroed (as every grid was before they were kept per
    /// thread): the tests' reference.
    #[cfg(test)]
    fn fresh(frame: [f64; 4], cell: f64) -> Occupancy {
        let mut o = Occupancy::new(frame, cell);
        o.cells = vec![0; o.cells.len()];
        o.sat = vec![0; o.sat.len()];
        o
    }

    /// The cell of page point `p`, if on the grid. The cell's column is
    /// `⌊(x − x0) / cell⌋` and is on the grid when `0 ≤ (x − x0) / cell < nx` (the
    /// same test, as `nx` is whole: no `floor` call, NaN off the grid); likewise rows.
    #[inline]
    fn cell_of(&self, p: PagePoint) -> Option<usize> {
        let i = (p[0] - self.x0) / self.cell;
        let j = (p[1] - self.y0) / self.cell;
        (i >= 0.0 && j >= 0.0 && i < self.nx as f64 && j < self.ny as f64)
            .then(|| j as usize * self.nx + i as usize)
    }

    /// Records that rows from the one holding page height `y` on (one row less, for the
    /// rounding of a point interpolated towards `y`) may have been marked; NaN: all.
    #[inline]
    fn touch_rows_from(&mut self, y: f64) {
        let j = (y - self.y0) / self.cell;
        // `j as usize` is 0 for NaN and negative `j`.
        let row = (j as usize).saturating_sub(1);
        self.clean_rows = self.clean_rows.min(row);
    }

    pub(crate) fn mark_point(&mut self, p: PagePoint, weight: u32) {
        self.marked += u64::from(weight);
        if let Some(k) = self.cell_of(p) {
            self.cells[k] = self.cells[k].saturating_add(weight);
            self.clean_rows = self.clean_rows.min(k / self.nx);
        }
    }

    pub(crate) fn mark_segment(&mut self, a: PagePoint, b: PagePoint, weight: u32) {
        let len = libm::hypot(b[0] - a[0], b[1] - a[1]);
        let n = ceil_index(len / (0.5 * self.cell)).max(1);
        // Every sample's height is between the ends' up to rounding (NaN ends: all rows).
        self.touch_rows_from(if a[1].is_nan() || b[1].is_nan() {
            f64::NAN
        } else {
            a[1].min(b[1])
        });
        // The weight of every sample, at once.
        self.marked = self
            .marked
            .saturating_add(u64::from(weight).saturating_mul((n as u64).saturating_add(1)));
        let (nx, ny) = (self.nx as f64, self.ny as f64);
        for s in 0..=n {
            let t = s as f64 / n as f64;
            // `cell_of`'s test and cell; a column or row on the grid is below `nx` or
            // `ny`, so its truncation as a `u32` is its truncation as a `usize`.
            let i = (a[0] + t * (b[0] - a[0]) - self.x0) / self.cell;
            let j = (a[1] + t * (b[1] - a[1]) - self.y0) / self.cell;
            if i >= 0.0 && j >= 0.0 && i < nx && j < ny {
                let k = j as u32 as usize * self.nx + i as u32 as usize;
                self.cells[k] = self.cells[k].saturating_add(weight);
            }
        }
    }

    /// The summed-area table of the cells, row by row: the row's running sums first
    /// (serial), then each added to the row above (independent, vectorised); the same
    /// saturating sums in the same order per entry. While the weights marked sum to at
    /// most `u32::MAX` (every page), no sum can saturate: plain sums then, the same
    /// values for fewer instructions. Rows above the first row marked since the last
    /// build keep their entries (the first build: zero), so a second build after a few
    /// marks low on the page sums only the rows from there.
    pub(crate) fn build(&mut self) {
        let w = self.nx + 1;
        let from = self.clean_rows.min(self.ny);
        if !self.built {
            // The table's first row and column are zero, and so are the rows above the
            // first marked one (the buffer may hold an earlier page's table).
            self.sat[..(from + 1) * w].fill(0);
            for j in from + 1..=self.ny {
                self.sat[j * w] = 0;
            }
        }
        self.built = true;
        self.clean_rows = self.ny;
        let mut run = vec![0u32; self.nx];
        if self.marked <= u64::from(u32::MAX) {
            for j in from..self.ny {
                let mut row = 0u32;
                for (r, &c) in run
                    .iter_mut()
                    .zip(&self.cells[j * self.nx..(j + 1) * self.nx])
                {
                    row = row.wrapping_add(c);
                    *r = row;
                }
                let (above, this) = self.sat[j * w..(j + 2) * w].split_at_mut(w);
                for ((s, &a), &r) in this[1..].iter_mut().zip(&above[1..]).zip(&run) {
                    *s = a.wrapping_add(r);
                }
            }
            return;
        }
        for j in from..self.ny {
            let mut row = 0u32;
            for (r, &c) in run
                .iter_mut()
                .zip(&self.cells[j * self.nx..(j + 1) * self.nx])
            {
                row = row.saturating_add(c);
                *r = row;
            }
            let (above, this) = self.sat[j * w..(j + 2) * w].split_at_mut(w);
            for ((s, &a), &r) in this[1..].iter_mut().zip(&above[1..]).zip(&run) {
                *s = a.saturating_add(r);
            }
        }
    }

    /// Ink along the segment `a`–`b`: the cells it passes through, each counted once
    /// (sampled every half cell); cells off the grid count nothing.
    pub(crate) fn segment_cost(&self, a: PagePoint, b: PagePoint) -> u64 {
        let len = libm::hypot(b[0] - a[0], b[1] - a[1]);
        let n = ceil_index(len / (0.5 * self.cell)).max(1);
        let mut last = usize::MAX;
        let mut sum = 0u64;
        for s in 0..=n {
            let t = s as f64 / n as f64;
            if let Some(k) = self.cell_of([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]) {
                if k != last {
                    sum += u64::from(self.cells[k]);
                    last = k;
                }
            }
        }
        sum
    }

    /// Ink in a rectangle (cells it touches); `None` if it leaves the grid.
    ///
    /// The cells are those from `⌊(r₀ − x0) / cell⌋` to `⌈(r₂ − x0) / cell⌉` (likewise
    /// rows), found without `floor` and `ceil` calls: a quotient `q` of the near side is
    /// off the grid when `q < 0` (as `⌊q⌋ < 0` is), and then `⌊q⌋` is its truncation; one
    /// of the far side is off when `q > nx` (as `⌈q⌉ > nx` is, `nx` being whole), and
    /// then `⌈q⌉` is [`ceil_index`]'s (NaN, as before, reads as 0).
    pub(crate) fn cost(&self, r: [f64; 4]) -> Option<u64> {
        let i0 = (r[0] - self.x0) / self.cell;
        let j0 = (r[1] - self.y0) / self.cell;
        let i1 = (r[2] - self.x0) / self.cell;
        let j1 = (r[3] - self.y0) / self.cell;
        if i0 < 0.0 || j0 < 0.0 || i1 > self.nx as f64 || j1 > self.ny as f64 {
            return None;
        }
        if !self.built {
            return Some(0);
        }
        let (i0, j0, i1, j1) = (i0 as usize, j0 as usize, ceil_index(i1), ceil_index(j1));
        let w = self.nx + 1;
        let s = |i: usize, j: usize| u64::from(self.sat[j * w + i]);
        Some(s(i1, j1) + s(i0, j0) - s(i0, j1) - s(i1, j0))
    }
}

/// The part of segment `a`–`b` inside the rectangle `r` (Liang–Barsky), if any.
pub fn clip_segment(a: PagePoint, b: PagePoint, r: [f64; 4]) -> Option<(PagePoint, PagePoint)> {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (p, q) in [
        (-dx, a[0] - r[0]),
        (dx, r[2] - a[0]),
        (-dy, a[1] - r[1]),
        (dy, r[3] - a[1]),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else {
            let t = q / p;
            if p < 0.0 {
                t0 = t0.max(t);
            } else {
                t1 = t1.min(t);
            }
        }
    }
    (t0 < t1).then(|| {
        (
            [a[0] + t0 * dx, a[1] + t0 * dy],
            [a[0] + t1 * dx, a[1] + t1 * dy],
        )
    })
}

pub(crate) fn rects_overlap(a: [f64; 4], b: [f64; 4]) -> bool {
    a[0] < b[2] && b[0] < a[2] && a[1] < b[3] && b[1] < a[3]
}

/// How a curve's dashes are drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct CurveStyle {
    /// Ink of the dashes.
    pub ink: Ink,
    /// Width of a regular dash.
    pub width: f64,
    /// Width of the dash that starts each 90° of travel (for quick counting; `width` for
    /// none).
    pub heavy: f64,
    /// Width of the first (θ = 0) dash.
    pub bold: f64,
}

impl CurveStyle {
    /// Black, the standard widths.
    pub(crate) const BLACK: CurveStyle = CurveStyle {
        ink: Ink::Black,
        width: style::DASH_WIDTH,
        heavy: style::HEAVY_DASH_WIDTH,
        bold: style::ZERO_DASH_WIDTH,
    };
}

/// Whether dash `k` (of `step_deg`, counted from the start of travel) holds a multiple of
/// 90° of travel other than 0: the heavier dashes that make counting quick.
pub(crate) fn is_quarter_dash(k: i64, step_deg: f64) -> bool {
    let a = k as f64 * step_deg;
    k > 0 && (a / 90.0).ceil() * 90.0 < a + step_deg - 1e-9
}

/// Draws dashes (`pts`: each dash's polyline already on the page, moved into the display
/// list's primitives, not copied) in `st`: the dash at
/// `bold` bold, every quarter dash (by [`is_quarter_dash`] with `step_deg`, counted from
/// `index0`) heavy, the others as one primitive; a dash shorter than a point becomes a
/// dot at its midpoint (so a dash shrunk at a cusp still counts). Returns the ink's box.
#[allow(clippy::too_many_arguments)]
pub(crate) fn draw_dashes(
    dl: &mut DisplayList,
    t: &WorldToPage,
    dashes: &[coupler_kinematics::Dash],
    pts: Vec<Vec<PagePoint>>,
    bold: Option<usize>,
    st: &CurveStyle,
    step_deg: f64,
    index0: i64,
) -> [f64; 4] {
    let mut bbox = [f64::INFINITY, f64::INFINITY, -f64::INFINITY, -f64::INFINITY];
    dl.ink(st.ink);
    // Regular dashes of a curve go out as one primitive (one path, one fill), the heavy
    // ones as another.
    let mut regular: Vec<Vec<PagePoint>> = Vec::with_capacity(dashes.len());
    let mut heavy: Vec<Vec<PagePoint>> = Vec::new();
    for (k, (d, pts)) in dashes.iter().zip(pts).enumerate() {
        let is_bold = bold == Some(k);
        let is_heavy =
            !is_bold && st.heavy > st.width && is_quarter_dash(d.index - index0, step_deg);
        let len: f64 = pts
            .windows(2)
            .map(|s| libm::hypot(s[1][0] - s[0][0], s[1][1] - s[0][1]))
            .sum();
        let wdt = if is_bold {
            st.bold
        } else if is_heavy {
            st.heavy
        } else {
            st.width
        };
        if len < style::MIN_DASH_LENGTH {
            // Shrunk near a cusp: a dot, so it still counts.
            let mp = d.midpoint();
            let p = t.map(mp.x, mp.y);
            let r = if is_bold {
                style::START_DOT_RADIUS
            } else {
                style::DOT_RADIUS.max(0.5 * wdt)
            };
            dl.circle(p, r, None);
            bbox = union(bbox, [p[0] - r, p[1] - r, p[0] + r, p[1] + r]);
        } else {
            for p in &pts {
                bbox = union(
                    bbox,
                    [
                        p[0] - 0.5 * wdt,
                        p[1] - 0.5 * wdt,
                        p[0] + 0.5 * wdt,
                        p[1] + 0.5 * wdt,
                    ],
                );
            }
            if is_bold {
                dl.line(pts, wdt);
            } else if is_heavy {
                heavy.push(pts);
            } else {
                regular.push(pts);
            }
        }
    }
    dl.items.push(Primitive::Polylines {
        lines: regular,
        width: st.width,
    });
    if !heavy.is_empty() {
        dl.items.push(Primitive::Polylines {
            lines: heavy,
            width: st.heavy,
        });
    }
    dl.ink(Ink::Black);
    bbox
}

/// The start of a curve: a dot at `start`, and an arrowhead just past `first_dash_end`
/// along `direction` (world units, y up; none if zero). Returns the ink's box.
pub(crate) fn start_marker(
    dl: &mut DisplayList,
    t: &WorldToPage,
    start: nalgebra::Point2<f64>,
    first_dash_end: nalgebra::Point2<f64>,
    direction: nalgebra::Vector2<f64>,
) -> [f64; 4] {
    let s0 = t.map(start.x, start.y);
    dl.circle(s0, style::START_DOT_RADIUS, None);
    let r = style::START_DOT_RADIUS;
    let mut bbox = [s0[0] - r, s0[1] - r, s0[0] + r, s0[1] + r];
    let tip = t.map(first_dash_end.x, first_dash_end.y);
    let dir = [direction.x, -direction.y];
    if dir[0] != 0.0 || dir[1] != 0.0 {
        let tip = [
            tip[0] + dir[0] * 0.5 * style::ARROW_LENGTH,
            tip[1] + dir[1] * 0.5 * style::ARROW_LENGTH,
        ];
        let base = [
            tip[0] - dir[0] * style::ARROW_LENGTH,
            tip[1] - dir[1] * style::ARROW_LENGTH,
        ];
        let n = [
            -dir[1] * style::ARROW_HALF_WIDTH,
            dir[0] * style::ARROW_HALF_WIDTH,
        ];
        let tri = vec![
            tip,
            [base[0] + n[0], base[1] + n[1]],
            [base[0] - n[0], base[1] - n[1]],
        ];
        for p in &tri {
            bbox = union(bbox, [p[0], p[1], p[0], p[1]]);
        }
        dl.items.push(Primitive::Polygon { points: tri });
    }
    bbox
}

/// Draws a mechanism: its links stopping at the pin circles, its pins, the ground
/// symbols at its ground pivots; records the link strokes (and ground symbols) in
/// `segments` for label placement. Returns each joint on the page with its name.
pub(crate) fn draw_links(
    dl: &mut DisplayList,
    t: &WorldToPage,
    drawing: &Drawing,
    segments: &mut Vec<(PagePoint, PagePoint)>,
) -> Vec<(PagePoint, &'static str)> {
    draw_links_width(dl, t, drawing, segments, style::LINK_WIDTH)
}

/// [`draw_links`] with links `width` wide (a ghost of the linkage: thin).
pub(crate) fn draw_links_width(
    dl: &mut DisplayList,
    t: &WorldToPage,
    drawing: &Drawing,
    segments: &mut Vec<(PagePoint, PagePoint)>,
    width: f64,
) -> Vec<(PagePoint, &'static str)> {
    let pins: Vec<(PagePoint, &'static str)> = drawing
        .joints
        .iter()
        .map(|j| (t.map(j.position.x, j.position.y), j.name))
        .collect();
    let r = style::PIN_RADIUS;
    // Links stop at the pin circles (ink only: nothing is painted white).
    let mut link = |a: PagePoint, b: PagePoint, dl: &mut DisplayList| {
        let len = libm::hypot(b[0] - a[0], b[1] - a[1]);
        if len > 2.0 * r {
            let u = [(b[0] - a[0]) / len, (b[1] - a[1]) / len];
            let a2 = [a[0] + u[0] * r, a[1] + u[1] * r];
            let b2 = [b[0] - u[0] * r, b[1] - u[1] * r];
            dl.line(vec![a2, b2], width);
            segments.push((a2, b2));
        }
    };
    for [a, b] in &drawing.links {
        link(pins[*a].0, pins[*b].0, dl);
    }
    for (p, _) in &pins {
        dl.circle(*p, r, Some(0.9));
    }
    for (j, (p, _)) in drawing.joints.iter().zip(&pins) {
        if j.ground {
            ground_symbol(dl, *p, r);
            segments.push(([p[0] - 8.0, p[1] + r], [p[0] + 8.0, p[1] + 12.0]));
        }
    }
    pins
}

/// Small names beside pins (up and to the right); returns their boxes (labels avoid them).
pub(crate) fn pivot_labels<'a>(
    dl: &mut DisplayList,
    pins: impl IntoIterator<Item = (PagePoint, &'a str)>,
) -> Vec<[f64; 4]> {
    let r = style::PIN_RADIUS;
    let mut taken = Vec::new();
    for (p, s) in pins {
        let pos = [p[0] + r + 1.5, p[1] - r - 1.5];
        let w = font::text_width(style::SMALL_SIZE, s);
        taken.push([
            pos[0] - 1.0,
            pos[1] - font::ascent(style::SMALL_SIZE) - 1.0,
            pos[0] + w + 1.0,
            pos[1] + font::descent(style::SMALL_SIZE) + 1.0,
        ]);
        dl.text(pos, style::SMALL_SIZE, Anchor::Start, s);
    }
    taken
}

/// The page header: `title` large at the left, "page N of M" at the right; `subtitle`
/// below it, the spec's name at the right.
pub(crate) fn header(
    dl: &mut DisplayList,
    setup: &PageSetup,
    title: String,
    subtitle: String,
    [number, count]: [usize; 2],
) {
    let (w, _) = setup.size_pt();
    let m = setup.margin_pt;
    dl.text(
        [m, m + style::TITLE_SIZE],
        style::TITLE_SIZE,
        Anchor::Start,
        title,
    );
    dl.text(
        [w - m, m + style::TITLE_SIZE],
        style::TITLE_SIZE,
        Anchor::End,
        format!("page {number} of {count}"),
    );
    dl.text(
        [m, m + style::TITLE_SIZE + 15.0],
        style::TEXT_SIZE,
        Anchor::Start,
        subtitle,
    );
    dl.text(
        [w - m, m + style::TITLE_SIZE + 15.0],
        style::TEXT_SIZE,
        Anchor::End,
        setup.spec_name.clone(),
    );
}

fn ground_symbol(dl: &mut DisplayList, p: PagePoint, r: f64) {
    let y = p[1] + r + 4.0;
    dl.line(
        vec![
            [p[0] - 1.2 * r, p[1] + 0.8 * r],
            [p[0] - 4.0, y],
            [p[0] + 4.0, y],
            [p[0] + 1.2 * r, p[1] + 0.8 * r],
        ],
        0.6,
    );
    dl.line(vec![[p[0] - 7.0, y], [p[0] + 7.0, y]], 0.8);
    for k in 0..5 {
        let x = p[0] - 6.0 + 3.0 * k as f64;
        dl.line(vec![[x, y], [x - 3.0, y + 3.5]], 0.4);
    }
}

/// The legend's first line: sample dashes and `text` with `{step}` and `{drawn}` replaced
/// by the dash step and its drawn part (degrees). Returns the line's y.
pub(crate) fn dash_legend(dl: &mut DisplayList, setup: &PageSetup, text: &str) -> f64 {
    let (_, h) = setup.size_pt();
    let m = setup.margin_pt;
    let y = h - m - style::FOOTER_HEIGHT + 16.0;
    let pat = setup.dash;
    let x = dash_sample(dl, m, y, pat.fraction);
    let text = text
        .replace("{step}", &fmt_num(pat.step_deg))
        .replace("{drawn}", &fmt_num(pat.step_deg * pat.fraction));
    dl.text([x, y + 2.5], style::SMALL_SIZE, Anchor::Start, text);
    y
}

/// The footer: `settings` at the bottom right, the program and version at the left.
pub(crate) fn footer(dl: &mut DisplayList, setup: &PageSetup, settings: String) {
    let (w, h) = setup.size_pt();
    let m = setup.margin_pt;
    dl.text([w - m, h - m], 6.0, Anchor::End, settings);
    dl.text(
        [m, h - m],
        6.0,
        Anchor::Start,
        format!("coupler-atlas {}", env!("CARGO_PKG_VERSION")),
    );
}

/// Three sample dashes (the first bold, with the start dot) at `(x, y)`, 12 pt per step;
/// returns where the explaining text starts.
fn dash_sample(dl: &mut DisplayList, x: f64, y: f64, fraction: f64) -> f64 {
    let unit = 12.0;
    for k in 0..3 {
        let x0 = x + k as f64 * unit;
        let wdt = if k == 0 {
            style::ZERO_DASH_WIDTH
        } else {
            style::DASH_WIDTH
        };
        dl.line(vec![[x0, y], [x0 + fraction * unit, y]], wdt);
    }
    dl.circle([x, y], style::START_DOT_RADIUS, None);
    x + 3.0 * unit + 4.0
}

/// Longest scale bar drawn, points (3 in): a longer unit gets a bar for a round part
/// of it.
const SCALE_BAR_MAX: f64 = 216.0;

/// A scale bar at `(x, y)` + 2 pt, with a half tick: one unit (`scale` points) long, or
/// the largest of ½, ⅕, 1/10 … of a unit that is at most 3 in when a unit is longer
/// (then marked with its fraction). `label` with `{}` replaced by the unit's length in
/// inches follows it.
pub(crate) fn scale_bar(dl: &mut DisplayList, x: f64, y: f64, scale: f64, label: &str) {
    let x0 = x + 2.0;
    let part = [1.0, 0.5, 0.2, 0.1, 0.05, 0.02, 0.01]
        .into_iter()
        .find(|f| f * scale <= SCALE_BAR_MAX)
        .unwrap_or(0.01);
    let len = part * scale;
    dl.line(
        vec![[x0, y - 3.0], [x0, y], [x0 + len, y], [x0 + len, y - 3.0]],
        0.8,
    );
    let half = [x0 + 0.5 * len, y];
    dl.line(vec![half, [half[0], y - 2.0]], 0.5);
    let mut text = label.replace(
        "{}",
        &fmt_num((scale / PT_PER_INCH * 1000.0).round() / 1000.0),
    );
    if part < 1.0 {
        text = format!("bar = {} unit;  {text}", fmt_num(part));
    }
    dl.text(
        [x0 + len + 6.0, y + 1.0],
        style::SMALL_SIZE,
        Anchor::Start,
        text,
    );
}

/// The footer line: generation settings that shape the page, then `setup.settings`.
pub fn footer_settings(setup: &PageSetup) -> String {
    let mut s = format!(
        "dash {}° of crank, {} % drawn · {} dpi · {} · chord tolerance {} px",
        fmt_num(setup.dash.step_deg),
        fmt_num((setup.dash.fraction * 100.0).round()),
        fmt_num(setup.dpi),
        // The page as printed: a page that did not choose (the contents) is portrait.
        match setup.size.orientation {
            Orientation::Auto => setup.size.oriented(Orientation::Portrait),
            _ => setup.size,
        },
        fmt_num(setup.chord_tolerance_px)
    );
    if !setup.settings.is_empty() {
        s.push_str(" · ");
        s.push_str(&setup.settings);
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Uniform floats in `[0, 1)` from a xorshift generator seeded with `seed` (the
    /// tests' random cases, the same sequence for the same seed).
    fn unit_floats(mut seed: u64) -> impl FnMut() -> f64 {
        move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// The occupancy grid as it was written first (`floor` per sample, the table in one
    /// loop): the reference for the faster one.
    struct OldOccupancy(Occupancy);

    impl OldOccupancy {
        fn mark_point(&mut self, p: PagePoint, weight: u32) {
            let o = &mut self.0;
            let i = ((p[0] - o.x0) / o.cell).floor();
            let j = ((p[1] - o.y0) / o.cell).floor();
            if i >= 0.0 && j >= 0.0 && (i as usize) < o.nx && (j as usize) < o.ny {
                let k = j as usize * o.nx + i as usize;
                o.cells[k] = o.cells[k].saturating_add(weight);
            }
        }

        fn mark_segment(&mut self, a: PagePoint, b: PagePoint, weight: u32) {
            let len = libm::hypot(b[0] - a[0], b[1] - a[1]);
            let n = (len / (0.5 * self.0.cell)).ceil().max(1.0) as usize;
            for s in 0..=n {
                let t = s as f64 / n as f64;
                self.mark_point([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])], weight);
            }
        }

        fn build(&mut self) {
            let o = &mut self.0;
            let w = o.nx + 1;
            for j in 0..o.ny {
                let mut row = 0u32;
                for i in 0..o.nx {
                    row = row.saturating_add(o.cells[j * o.nx + i]);
                    o.sat[(j + 1) * w + i + 1] = o.sat[j * w + i + 1].saturating_add(row);
                }
            }
        }

        /// `cost` with `floor` and `ceil`, as first written.
        fn cost(&self, r: [f64; 4]) -> Option<u64> {
            let o = &self.0;
            let i0 = ((r[0] - o.x0) / o.cell).floor();
            let j0 = ((r[1] - o.y0) / o.cell).floor();
            let i1 = ((r[2] - o.x0) / o.cell).ceil();
            let j1 = ((r[3] - o.y0) / o.cell).ceil();
            if i0 < 0.0 || j0 < 0.0 || i1 > o.nx as f64 || j1 > o.ny as f64 {
                return None;
            }
            let (i0, j0, i1, j1) = (i0 as usize, j0 as usize, i1 as usize, j1 as usize);
            let w = o.nx + 1;
            let s = |i: usize, j: usize| u64::from(o.sat[j * w + i]);
            Some(s(i1, j1) + s(i0, j0) - s(i0, j1) - s(i1, j0))
        }

        fn segment_cost(&self, a: PagePoint, b: PagePoint) -> u64 {
            let o = &self.0;
            let len = libm::hypot(b[0] - a[0], b[1] - a[1]);
            let n = (len / (0.5 * o.cell)).ceil().max(1.0) as usize;
            let mut last = usize::MAX;
            let mut sum = 0u64;
            for s in 0..=n {
                let t = s as f64 / n as f64;
                let i = ((a[0] + t * (b[0] - a[0]) - o.x0) / o.cell).floor();
                let j = ((a[1] + t * (b[1] - a[1]) - o.y0) / o.cell).floor();
                if i >= 0.0 && j >= 0.0 && (i as usize) < o.nx && (j as usize) < o.ny {
                    let k = j as usize * o.nx + i as usize;
                    if k != last {
                        sum += u64::from(o.cells[k]);
                        last = k;
                    }
                }
            }
            sum
        }
    }

    /// Points and segments on, off and along the grid's edges (cell boundaries hit
    /// exactly, -0, NaN, infinities, huge weights that saturate): the same cells, the
    /// same table and the same segment costs as the first version.
    #[test]
    fn occupancy_is_the_first_versions() {
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut rand = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        // Huge weights (that saturate: the saturating table) and small ones (the plain
        // sums' table).
        for (frame, huge) in [
            ([36.0, 36.0, 756.0, 1188.0], true),
            ([0.5, -3.25, 40.0, 29.0], true),
            ([36.0, 36.0, 756.0, 1188.0], false),
            ([0.5, -3.25, 40.0, 29.0], false),
        ] {
            for cell in [3.0, 0.7] {
                let mut new = Occupancy::new(frame, cell);
                let mut old = OldOccupancy(Occupancy::fresh(frame, cell));
                let special = [
                    f64::NAN,
                    f64::INFINITY,
                    f64::NEG_INFINITY,
                    -0.0,
                    frame[0],
                    frame[0] - 1e-9,
                    frame[2],
                    frame[0] + cell * (new.nx as f64),
                    frame[1] + cell * (new.ny as f64),
                    frame[1] + 3.0 * cell,
                ];
                let mut coord = |k: usize| {
                    let r = rand();
                    if r % 5 == 0 {
                        special[(r >> 8) as usize % special.len()]
                    } else {
                        let lo = frame[k % 2] - 20.0;
                        let hi = frame[2 + k % 2] + 20.0;
                        lo + (hi - lo) * ((r >> 11) as f64 / (1u64 << 53) as f64)
                    }
                };
                let mut queries = Vec::new();
                for round in 0..2 {
                    for q in 0..3000 {
                        let a = [coord(0), coord(1)];
                        let b = [coord(0), coord(1)];
                        let weight = if huge && q % 97 == 0 {
                            u32::MAX / 3
                        } else {
                            q as u32 % 41
                        };
                        if q % 3 == 0 {
                            new.mark_point(a, weight);
                            old.mark_point(a, weight);
                        } else if a.iter().chain(&b).all(|x| x.is_finite()) {
                            new.mark_segment(a, b, weight);
                            old.mark_segment(a, b, weight);
                            queries.push((a, b));
                        }
                    }
                    new.build();
                    old.build();
                    assert_eq!(new.marked > u64::from(u32::MAX), huge);
                    assert!(new.cells == old.0.cells, "round {round}: cells differ");
                    assert!(new.sat == old.0.sat, "round {round}: tables differ");
                    for &(a, b) in &queries {
                        assert_eq!(new.segment_cost(a, b), old.segment_cost(a, b));
                    }
                }
            }
        }
    }

    /// Grids made on this thread's kept buffers (left dirty by a grid of another size
    /// just before) are fresh grids: the same cells, table and costs after each build,
    /// whether the marks since the last build reach the top of the page, only its lower
    /// rows, or none, and after one long segment whose samples' weights pass `u32::MAX`
    /// together (one sample's do not: the table then saturates); and an unbuilt grid's
    /// costs are a fresh one's. Rectangles on and
    /// off the grid, along cell boundaries, NaN near sides.
    #[test]
    fn grids_on_kept_buffers_are_fresh_grids() {
        let mut rand = unit_floats(0x9e37_79b9_7f4a_7c15);
        let frames = [
            [36.0, 36.0, 756.0, 1188.0],
            [0.5, -3.25, 40.0, 29.0],
            [36.0, 36.0, 1188.0, 756.0],
            [10.0, 20.0, 100.0, 400.0],
        ];
        for round in 0..3 {
            for (f, &frame) in frames.iter().enumerate() {
                for cell in [3.0, 0.7] {
                    // Leave this thread's spare buffers dirty, from a grid of another size.
                    {
                        let other = frames[(f + 1 + round) % frames.len()];
                        let mut dirty = Occupancy::new(other, cell);
                        for k in 0..200 {
                            let p = [
                                other[0] + rand() * (other[2] - other[0]),
                                other[1] + rand() * (other[3] - other[1]),
                            ];
                            dirty.mark_segment(p, [p[0] + 9.0, p[1] + 4.0], 1 + k % 7);
                        }
                        dirty.build();
                    }
                    let mut new = Occupancy::new(frame, cell);
                    let mut old = OldOccupancy(Occupancy::fresh(frame, cell));
                    let (w, h) = (frame[2] - frame[0], frame[3] - frame[1]);
                    let rects: Vec<[f64; 4]> = (0..400)
                        .map(|k| {
                            let x = frame[0] - 5.0 + rand() * (w + 10.0);
                            let y = frame[1] - 5.0 + rand() * (h + 10.0);
                            let (dx, dy) = (rand() * 60.0, rand() * 20.0);
                            match k % 8 {
                                // On cell boundaries.
                                0 => {
                                    let i = (rand() * new.nx as f64).floor();
                                    let j = (rand() * new.ny as f64).floor();
                                    let (x, y) = (frame[0] + i * cell, frame[1] + j * cell);
                                    [x, y, x + 3.0 * cell, y + 2.0 * cell]
                                }
                                // Off the grid's top left by less than a cell.
                                1 => [frame[0] - 0.3 * cell, y, x + dx, y + dy],
                                2 => [f64::NAN, y, x + dx, y + dy],
                                3 => [x, f64::NAN, x + dx, y + dy],
                                4 => [frame[0], frame[1], frame[2], frame[3]],
                                _ => [x, y, x + dx, y + dy],
                            }
                        })
                        .collect();
                    let same = |new: &Occupancy, old: &OldOccupancy, when: &str| {
                        assert!(new.cells == old.0.cells, "{frame:?} {cell} {when}: cells");
                        for r in &rects {
                            assert_eq!(new.cost(*r), old.cost(*r), "{frame:?} {cell} {when}");
                        }
                    };
                    same(&new, &old, "before any build");
                    // Marks over the whole page, then only below its middle, then none.
                    for (phase, top) in [(0, 0.0), (1, 0.5), (2, 0.9), (3, 2.0)] {
                        for k in 0..300u32 {
                            let y0 = frame[1] + top * h;
                            let p = [frame[0] + rand() * w, y0 + rand() * (frame[3] - y0)];
                            if top > 1.0 {
                                break;
                            }
                            if k % 5 == 0 {
                                new.mark_point(p, k % 40);
                                old.mark_point(p, k % 40);
                            } else {
                                let q = [p[0] + (rand() - 0.5) * 30.0, p[1] + rand() * 10.0];
                                new.mark_segment(p, q, 1 + k % 4);
                                old.mark_segment(p, q, 1 + k % 4);
                            }
                        }
                        new.build();
                        old.build();
                        assert!(
                            new.sat == old.0.sat,
                            "{frame:?} {cell} phase {phase}: table"
                        );
                        same(&new, &old, &format!("phase {phase}"));
                    }
                    // Last, one long segment whose samples' weights together (not one
                    // sample's) pass `u32::MAX`: the saturating table from then on.
                    let heavy = u32::MAX / 8;
                    let (a, b) = ([frame[0], frame[1]], [frame[2], frame[3]]);
                    new.mark_segment(a, b, heavy);
                    old.mark_segment(a, b, heavy);
                    assert!(new.marked > u64::from(u32::MAX));
                    new.build();
                    old.build();
                    assert!(new.sat == old.0.sat, "{frame:?} {cell} heavy: table");
                    // (No costs asked: a saturated table's differences are not sums.)
                    assert!(new.cells == old.0.cells, "{frame:?} {cell} heavy: cells");
                }
            }
        }
    }

    /// What [`draw_dashes`] must draw, stated dash by dash: the curve's ink; in dash
    /// order, a dot for each dash shorter than `MIN_DASH_LENGTH` (at its midpoint; the
    /// start dot's radius for the bold one, else half the stroke but at least a dot) and
    /// a polyline of its own for the bold dash; then the regular dashes as one
    /// primitive and the heavy quarter dashes (if any) as another; black ink again. The
    /// box holds every dot and every stroke's half width around its points.
    #[allow(clippy::too_many_arguments)]
    fn dashes_as_stated(
        t: &WorldToPage,
        dashes: &[coupler_kinematics::Dash],
        pts: &[Vec<PagePoint>],
        bold: Option<usize>,
        st: &CurveStyle,
        step_deg: f64,
        index0: i64,
    ) -> (Vec<Primitive>, [f64; 4]) {
        let mut items = vec![Primitive::Ink(st.ink)];
        let (mut regular, mut heavy) = (Vec::new(), Vec::new());
        let mut extents: Vec<(PagePoint, f64)> = Vec::new();
        for (k, (d, line)) in dashes.iter().zip(pts).enumerate() {
            let length: f64 = line
                .windows(2)
                .map(|s| libm::hypot(s[1][0] - s[0][0], s[1][1] - s[0][1]))
                .sum();
            let quarter = is_quarter_dash(d.index - index0, step_deg);
            let (width, list) = match (bold == Some(k), st.heavy > st.width && quarter) {
                (true, _) => (st.bold, None),
                (false, true) => (st.heavy, Some(&mut heavy)),
                (false, false) => (st.width, Some(&mut regular)),
            };
            if length < style::MIN_DASH_LENGTH {
                let center = t.map(d.midpoint().x, d.midpoint().y);
                let radius = match list {
                    None => style::START_DOT_RADIUS,
                    Some(_) => style::DOT_RADIUS.max(0.5 * width),
                };
                items.push(Primitive::Circle {
                    center,
                    radius,
                    width: None,
                });
                extents.push((center, radius));
                continue;
            }
            extents.extend(line.iter().map(|&p| (p, 0.5 * width)));
            match list {
                None => items.push(Primitive::Polyline {
                    points: line.clone(),
                    width,
                }),
                Some(list) => list.push(line.clone()),
            }
        }
        items.push(Primitive::Polylines {
            lines: regular,
            width: st.width,
        });
        if !heavy.is_empty() {
            items.push(Primitive::Polylines {
                lines: heavy,
                width: st.heavy,
            });
        }
        items.push(Primitive::Ink(Ink::Black));
        let bbox = extents.iter().fold(
            [f64::INFINITY, f64::INFINITY, -f64::INFINITY, -f64::INFINITY],
            |b, &(p, r)| union(b, [p[0] - r, p[1] - r, p[0] + r, p[1] + r]),
        );
        (items, bbox)
    }

    /// Dashes whose page points are moved into the display list draw what is stated
    /// for them: the same primitives in the same order, the same box, to the bit. Random
    /// curves of 1–40 dashes (some shorter than a point, so drawn as dots), a bold dash
    /// or none, styles with and without heavy quarter dashes and strokes wider than a
    /// dot, two dash steps and offsets.
    #[test]
    fn dashes_draw_as_stated() {
        use coupler_kinematics::Dash;
        use nalgebra::Point2;
        let mut next = unit_floats(0x9e37_79b9_7f4a_7c15);
        let t = WorldToPage {
            scale: 37.5,
            origin: [300.0, 500.0],
        };
        let styles = [
            CurveStyle::BLACK,
            CurveStyle {
                ink: Ink::Gray(128),
                width: 0.6,
                heavy: 0.6,
                bold: 1.4,
            },
            // Strokes wider than a dot: a short dash's dot is half the stroke.
            CurveStyle {
                ink: Ink::Gray(64),
                width: 1.8,
                heavy: 2.4,
                bold: 3.0,
            },
        ];
        let (mut dots, mut lines) = (0, 0);
        for case in 0..400 {
            let count = 1 + (next() * 40.0) as usize;
            let step = if case % 2 == 0 { 10.0 } else { 5.0 };
            let index0 = (case % 3) as i64;
            let mut dashes = Vec::new();
            for k in 0..count {
                // A dash's size in world units: a few in twenty well under a point.
                let size = if next() < 0.15 { 0.004 } else { 0.5 };
                let (x, y) = (4.0 * next() - 2.0, 4.0 * next() - 2.0);
                let points: Vec<Point2<f64>> = (0..1 + (next() * 9.0) as usize)
                    .map(|_| Point2::new(x + size * next(), y + size * next()))
                    .collect();
                dashes.push(Dash {
                    index: k as i64 + index0,
                    theta_start: k as f64 * step,
                    theta_end: (k as f64 + 0.6) * step,
                    points,
                });
            }
            let pts: Vec<Vec<PagePoint>> = dashes
                .iter()
                .map(|d| d.points.iter().map(|p| t.map(p.x, p.y)).collect())
                .collect();
            let bold = match case % 3 {
                0 => None,
                1 => Some(0),
                _ => Some((next() * count as f64) as usize),
            };
            let st = styles[(case / 6) % 3];
            let (want, want_box) = dashes_as_stated(&t, &dashes, &pts, bold, &st, step, index0);
            let mut got = DisplayList::new(792.0, 1224.0);
            let got_box = draw_dashes(&mut got, &t, &dashes, pts, bold, &st, step, index0);
            assert_eq!(
                format!("{:?} {got_box:?}", got.items),
                format!("{want:?} {want_box:?}")
            );
            for item in &want {
                match item {
                    Primitive::Circle { .. } => dots += 1,
                    Primitive::Polylines { lines: l, .. } => lines += l.len(),
                    _ => {}
                }
            }
        }
        // Both kinds of dash were drawn, many times.
        assert!(dots > 500 && lines > 3000, "{dots} dots, {lines} lines");
    }

    #[test]
    fn page_sizes_parse() {
        let p: PageSize = "tabloid".parse().unwrap();
        assert_eq!(p.size_pt(), (792.0, 1224.0));
        let p: PageSize = "A4-landscape".parse().unwrap();
        assert!((p.size_pt().0 - 841.889).abs() < 1e-2);
        assert!("b5".parse::<PageSize>().is_err());
        let s = PageSetup::default();
        assert_eq!(s.size_px(), (3300, 5100));
    }

    #[test]
    fn clipping() {
        let r = [0.0, 0.0, 10.0, 10.0];
        assert_eq!(
            clip_segment([-5.0, 5.0], [15.0, 5.0], r),
            Some(([0.0, 5.0], [10.0, 5.0]))
        );
        assert_eq!(
            clip_segment([2.0, 2.0], [3.0, 3.0], r),
            Some(([2.0, 2.0], [3.0, 3.0]))
        );
        assert_eq!(clip_segment([-5.0, -5.0], [-1.0, 20.0], r), None);
    }
}
