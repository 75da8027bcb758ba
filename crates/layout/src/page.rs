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
use coupler_kinematics::{
    Circuit, CouplerPoint, CrankAngle, CrankTable, Curve, DashError, DashPattern, DashedCurve,
    Drawing, Linkage, Mechanism, dash_curve,
};

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
/// Crank angle (degrees) at which the linkage is drawn: θ = 0, so every coupler point of
/// the page sits on the start (θ = 0 dot) of its own curve.
pub const DRAWN_CRANK_ANGLE_DEG: f64 = 0.0;

/// Line widths and sizes, in points.
pub(crate) mod style {
    pub const DASH_WIDTH: f64 = 0.75;
    pub const ZERO_DASH_WIDTH: f64 = 1.9;
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

/// Portrait or landscape.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Orientation {
    /// Long side vertical.
    Portrait,
    /// Long side horizontal.
    Landscape,
}

impl Orientation {
    /// `"portrait"` or `"landscape"`.
    pub fn name(self) -> &'static str {
        match self {
            Orientation::Portrait => "portrait",
            Orientation::Landscape => "landscape",
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
    /// `portrait` or `landscape`.
    fn from_str(s: &str) -> Result<Orientation, String> {
        match s {
            "portrait" => Ok(Orientation::Portrait),
            "landscape" => Ok(Orientation::Landscape),
            _ => Err(format!("must be `portrait` or `landscape`, got `{s}`")),
        }
    }
}

/// A page size: paper and orientation. Parses from `tabloid`, `letter`, `a4`, `a3`,
/// optionally suffixed `-landscape` (or `-portrait`, the default).
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
        "unknown page size {0:?} (expected {names}, optionally with -landscape)",
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
        }
    }
}

impl PageSize {
    /// (width, height) in points.
    pub fn size_pt(&self) -> (f64, f64) {
        let (w, h) = self.paper.portrait_pt();
        match self.orientation {
            Orientation::Portrait => (w, h),
            Orientation::Landscape => (h, w),
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

    /// Device pixels per point.
    pub fn px_per_pt(&self) -> f64 {
        self.dpi / PT_PER_INCH
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

/// One drawing primitive in page points. All ink is black; widths are in points.
#[derive(Clone, Debug, PartialEq)]
pub enum Primitive {
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
        });
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

/// What one linkage page shows.
#[derive(Clone, Debug, PartialEq)]
pub struct LinkagePage<M: Mechanism = Linkage> {
    /// The mechanism.
    pub linkage: M,
    /// Its circuit.
    pub circuit: Circuit,
    /// Coupler points whose curves are on this page (in order).
    pub points: Vec<CouplerPoint>,
    /// The linkage's whole grid of coupler points (drawn as small circles).
    pub grid: Vec<CouplerPoint>,
    /// Page number in the atlas (1-based).
    pub page_number: usize,
    /// Pages in the atlas.
    pub page_count: usize,
}

/// Curves of a page computed for a given setup: the dash polylines, and the world
/// (curve-unit) window and scale they are drawn at.
#[derive(Clone, Debug, PartialEq)]
pub struct PageGeometry {
    /// Dashed curves, one per point of the page, same order.
    pub curves: Vec<DashedCurve>,
    /// Page transform: page = (origin.x + s·x, origin.y − s·y) for curve coordinates.
    pub transform: WorldToPage,
    /// The frame (plot area) in points: `[x0, y0, x1, y1]`.
    pub frame: [f64; 4],
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

/// Inches per crank unit offered for the page scale (largest that fits is chosen), so that
/// the printed scale is a round number and pages of similar linkages share it.
const NICE_INCHES_PER_UNIT: [f64; 26] = [
    0.1, 0.125, 0.15, 0.175, 0.2, 0.225, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5, 0.6, 0.7, 0.75, 0.8, 0.9,
    1.0, 1.1, 1.2, 1.25, 1.4, 1.5, 1.75, 2.0, 2.5,
];

fn frame_of(setup: &PageSetup) -> [f64; 4] {
    let (w, h) = setup.size_pt();
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

/// The mechanism at the drawn angle (crank-rockers assemble everywhere).
fn drawn<M: Mechanism>(page: &LinkagePage<M>) -> Drawing {
    page.linkage.drawing(
        page.circuit,
        &CrankAngle::from_degrees(DRAWN_CRANK_ANGLE_DEG),
    )
}

/// World bounding box of what must be on the page besides the curves: the crank paths,
/// the ground pivots, and, at the drawn angle, the moving joints and this page's coupler
/// points. The rest of the grid is context: it is drawn where it falls inside the frame.
fn linkage_bbox<M: Mechanism>(page: &LinkagePage<M>) -> [f64; 4] {
    let drawing = drawn(page);
    let mut b = [f64::INFINITY, f64::INFINITY, -f64::INFINITY, -f64::INFINITY];
    for (c, r) in &drawing.paths {
        b = union(b, [c.x - r, c.y - r, c.x + r, c.y + r]);
    }
    for j in &drawing.joints {
        b = union(b, [j.position.x, j.position.y, j.position.x, j.position.y]);
    }
    if let Some(f) = drawing.coupler {
        for q in &page.points {
            let m = f.point(*q);
            b = union(b, [m.x, m.y, m.x, m.y]);
        }
    }
    b
}

/// The frame of the page and the transform that centres `world` (a curve-unit box, padded
/// by 2 % of its extent) in it
/// at the largest round scale that fits (inches per unit from `nice`, ascending, so pages
/// of similar linkages share a scale; the exact fit if even the smallest is too large).
pub(crate) fn fit_transform(
    world: [f64; 4],
    setup: &PageSetup,
    nice: &[f64],
) -> (WorldToPage, [f64; 4]) {
    // A margin of 2 % of the extent (sampled extents can miss a sliver of a sharp tip).
    let pad = 0.02 * (world[2] - world[0]).max(world[3] - world[1]);
    let world = [
        world[0] - pad,
        world[1] - pad,
        world[2] + pad,
        world[3] + pad,
    ];
    let frame = frame_of(setup);
    let inner = [
        frame[0] + style::FRAME_PAD,
        frame[1] + style::FRAME_PAD,
        frame[2] - style::FRAME_PAD,
        frame[3] - style::FRAME_PAD,
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
    let transform = WorldToPage {
        scale,
        origin: [mid[0] - scale * cx, mid[1] + scale * cy],
    };
    (transform, frame)
}

/// Computes the page's curves: estimates their extent from a 2° trace (one pose table
/// shared by every point), picks the largest round scale at which the linkage and all
/// curves fit in the frame, then dashes every curve with a chord tolerance of
/// `setup.chord_tolerance_px` pixels at that scale.
pub fn compute_page<M: Mechanism>(
    page: &LinkagePage<M>,
    setup: &PageSetup,
) -> Result<PageGeometry, LayoutError> {
    setup.validate()?;
    let table = CrankTable::over(2.0, page.linkage.period_deg()).expect("valid step");
    let poses = page.linkage.pose_table(page.circuit, &table);
    let mut world = linkage_bbox(page);
    let mut curve = Curve::default();
    for p in &page.points {
        poses.trace_into(*p, &mut curve);
        for k in 0..curve.len() {
            if curve.is_valid(k) {
                world = union(world, [curve.x[k], curve.y[k], curve.x[k], curve.y[k]]);
            }
        }
    }
    // 2° sampling may miss a sliver of a sharp tip: fit_transform pads by 2 %.
    let (transform, frame) = fit_transform(world, setup, &NICE_INCHES_PER_UNIT);
    let scale = transform.scale;
    let tol_world = setup.chord_tolerance_px / setup.px_per_pt() / scale;
    let curves = page
        .points
        .iter()
        .map(|p| dash_curve(&page.linkage, page.circuit, *p, &setup.dash, tol_world))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(PageGeometry {
        curves,
        transform,
        frame,
    })
}

/// Where one curve ended up on its page.
#[derive(Clone, Debug, PartialEq)]
pub struct CurvePlacement {
    /// The coupler point.
    pub point: CouplerPoint,
    /// Bounding box of the drawn curve (dash ink), `[x0, y0, x1, y1]` in points.
    pub bbox_pt: [f64; 4],
    /// Bounding box of its label, points.
    pub label_pt: [f64; 4],
}

impl CurvePlacement {
    /// The curve's bounding box in device pixels at `dpi`, rounded outwards:
    /// `[x0, y0, x1, y1]` with `x1`, `y1` exclusive.
    pub fn bbox_px(&self, dpi: f64) -> [u32; 4] {
        let k = dpi / PT_PER_INCH;
        let b = self.bbox_pt;
        [
            (b[0] * k).floor().max(0.0) as u32,
            (b[1] * k).floor().max(0.0) as u32,
            (b[2] * k).ceil().max(0.0) as u32,
            (b[3] * k).ceil().max(0.0) as u32,
        ]
    }
}

/// A laid-out page: the display list, and where each curve is.
#[derive(Clone, Debug, PartialEq)]
pub struct PageLayout {
    /// What to draw.
    pub display: DisplayList,
    /// One entry per curve, in the page's point order.
    pub curves: Vec<CurvePlacement>,
    /// Points per crank unit.
    pub scale_pt_per_unit: f64,
}

/// Formats a length or coordinate compactly ("3", "2.5", "-1.25").
pub fn fmt_num(x: f64) -> String {
    let s = format!("{x}");
    if s == "-0" { "0".into() } else { s }
}

/// A coarse occupancy grid over the frame, for placing labels where they cover the least
/// ink; queried through a summed-area table.
pub(crate) struct Occupancy {
    x0: f64,
    y0: f64,
    cell: f64,
    nx: usize,
    ny: usize,
    cells: Vec<u32>,
    sat: Vec<u32>,
}

impl Occupancy {
    pub(crate) fn new(frame: [f64; 4], cell: f64) -> Occupancy {
        let nx = ((frame[2] - frame[0]) / cell).ceil() as usize + 1;
        let ny = ((frame[3] - frame[1]) / cell).ceil() as usize + 1;
        Occupancy {
            x0: frame[0],
            y0: frame[1],
            cell,
            nx,
            ny,
            cells: vec![0; nx * ny],
            sat: vec![0; (nx + 1) * (ny + 1)],
        }
    }

    pub(crate) fn mark_point(&mut self, p: PagePoint, weight: u32) {
        let i = ((p[0] - self.x0) / self.cell).floor();
        let j = ((p[1] - self.y0) / self.cell).floor();
        if i >= 0.0 && j >= 0.0 && (i as usize) < self.nx && (j as usize) < self.ny {
            let k = j as usize * self.nx + i as usize;
            self.cells[k] = self.cells[k].saturating_add(weight);
        }
    }

    pub(crate) fn mark_segment(&mut self, a: PagePoint, b: PagePoint, weight: u32) {
        let len = libm::hypot(b[0] - a[0], b[1] - a[1]);
        let n = (len / (0.5 * self.cell)).ceil().max(1.0) as usize;
        for s in 0..=n {
            let t = s as f64 / n as f64;
            self.mark_point([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])], weight);
        }
    }

    pub(crate) fn build(&mut self) {
        let w = self.nx + 1;
        for j in 0..self.ny {
            let mut row = 0u32;
            for i in 0..self.nx {
                row = row.saturating_add(self.cells[j * self.nx + i]);
                self.sat[(j + 1) * w + i + 1] = self.sat[j * w + i + 1].saturating_add(row);
            }
        }
    }

    /// Ink in a rectangle (cells it touches); `None` if it leaves the grid.
    pub(crate) fn cost(&self, r: [f64; 4]) -> Option<u64> {
        let i0 = ((r[0] - self.x0) / self.cell).floor();
        let j0 = ((r[1] - self.y0) / self.cell).floor();
        let i1 = ((r[2] - self.x0) / self.cell).ceil();
        let j1 = ((r[3] - self.y0) / self.cell).ceil();
        if i0 < 0.0 || j0 < 0.0 || i1 > self.nx as f64 || j1 > self.ny as f64 {
            return None;
        }
        let (i0, j0, i1, j1) = (i0 as usize, j0 as usize, i1 as usize, j1 as usize);
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

/// Draws dashes (`pts`: each dash's polyline already on the page): the dash at `bold`
/// wide, the others as one primitive; a dash shorter than a point becomes a dot at its
/// midpoint (so a dash shrunk at a cusp still counts). Returns the ink's box.
pub(crate) fn draw_dashes(
    dl: &mut DisplayList,
    t: &WorldToPage,
    dashes: &[coupler_kinematics::Dash],
    pts: &[Vec<PagePoint>],
    bold: Option<usize>,
) -> [f64; 4] {
    let mut bbox = [f64::INFINITY, f64::INFINITY, -f64::INFINITY, -f64::INFINITY];
    // Regular dashes of a curve go out as one primitive (one path, one fill).
    let mut regular: Vec<Vec<PagePoint>> = Vec::with_capacity(dashes.len());
    for (k, (d, pts)) in dashes.iter().zip(pts).enumerate() {
        let is_bold = bold == Some(k);
        let len: f64 = pts
            .windows(2)
            .map(|s| libm::hypot(s[1][0] - s[0][0], s[1][1] - s[0][1]))
            .sum();
        let wdt = if is_bold {
            style::ZERO_DASH_WIDTH
        } else {
            style::DASH_WIDTH
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
            if is_bold {
                dl.line(pts.clone(), wdt);
            } else {
                regular.push(pts.clone());
            }
            for p in pts {
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
        }
    }
    dl.items.push(Primitive::Polylines {
        lines: regular,
        width: style::DASH_WIDTH,
    });
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
            dl.line(vec![a2, b2], style::LINK_WIDTH);
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

/// Lays out a linkage page from its computed geometry.
pub fn layout_page<M: Mechanism>(
    page: &LinkagePage<M>,
    geometry: &PageGeometry,
    setup: &PageSetup,
) -> PageLayout {
    let (w, h) = setup.size_pt();
    let mut dl = DisplayList::new(w, h);
    let t = geometry.transform;
    let frame = geometry.frame;
    let l = &page.linkage;

    // Header.
    let title = l
        .dimensions()
        .iter()
        .map(|(name, x)| format!("{name} = {}", fmt_num(*x)))
        .collect::<Vec<_>>()
        .join("   ");
    let subtitle = format!(
        "class {}   {} circuit   {}",
        l.class_description(),
        page.circuit.name(),
        l.convention()
    );
    header(
        &mut dl,
        setup,
        title,
        subtitle,
        [page.page_number, page.page_count],
    );
    dl.rect(frame, style::FRAME);

    // Curves.
    let mut placements = Vec::with_capacity(geometry.curves.len());
    let mut occ = Occupancy::new(frame, 3.0);
    let mut page_curves: Vec<Vec<Vec<PagePoint>>> = Vec::with_capacity(geometry.curves.len());
    for c in &geometry.curves {
        let mut dashes = Vec::with_capacity(c.dashes.len());
        for d in &c.dashes {
            let pts: Vec<PagePoint> = d.points.iter().map(|p| t.map(p.x, p.y)).collect();
            for s in pts.windows(2) {
                occ.mark_segment(s[0], s[1], 1);
            }
            dashes.push(pts);
        }
        page_curves.push(dashes);
    }
    for ((c, dashes), point) in geometry.curves.iter().zip(&page_curves).zip(&page.points) {
        let mut bbox = draw_dashes(&mut dl, &t, &c.dashes, dashes, Some(0));
        let d0 = &c.dashes[0];
        bbox = union(
            bbox,
            start_marker(
                &mut dl,
                &t,
                c.start,
                d0.points[d0.points.len() - 1],
                c.start_direction,
            ),
        );
        placements.push(CurvePlacement {
            point: *point,
            bbox_pt: bbox,
            label_pt: [0.0; 4], // set when the label is placed, below
        });
    }

    // Linkage at θ = 0.
    let mut link_segments: Vec<(PagePoint, PagePoint)> = Vec::new();
    // Boxes of text already on the frame (pivot names): curve labels avoid them.
    let mut taken: Vec<[f64; 4]> = Vec::new();
    let drawing = drawn(page);
    if let Some(pose) = drawing.coupler {
        let pins = draw_links(&mut dl, &t, &drawing, &mut link_segments);
        // Crank circles (paths of the crank pins), thin.
        for (c, r) in &drawing.paths {
            let circle: Vec<PagePoint> = (0..=120)
                .map(|k| {
                    let (s, co) = coupler_kinematics::sincos_deg(3.0 * k as f64);
                    t.map(c.x + r * co, c.y + r * s)
                })
                .collect();
            dl.line(circle, style::THIN);
        }
        // The coupler plate: the outline of the grid's extent in the coupler frame.
        if !page.grid.is_empty() {
            let (mut u0, mut v0, mut u1, mut v1) = (0.0f64, 0.0f64, l.coupler_length(), 0.0f64);
            for q in &page.grid {
                (u0, v0, u1, v1) = (u0.min(q.u), v0.min(q.v), u1.max(q.u), v1.max(q.v));
            }
            let plate: Vec<PagePoint> = [(u0, v0), (u1, v0), (u1, v1), (u0, v1), (u0, v0)]
                .iter()
                .map(|&(u, v)| {
                    let m = pose.point(CouplerPoint::new(u, v));
                    t.map(m.x, m.y)
                })
                .collect();
            // Context, not a curve: clipped to the frame.
            for w in plate.windows(2) {
                if let Some((a, b)) = clip_segment(w[0], w[1], frame) {
                    dl.line(vec![a, b], style::THIN);
                }
            }
        }
        // Grid: small hollow circles (those inside the frame).
        for q in &page.grid {
            let mq = pose.point(*q);
            let p = t.map(mq.x, mq.y);
            let r = style::GRID_RADIUS;
            if p[0] - r >= frame[0]
                && p[0] + r <= frame[2]
                && p[1] - r >= frame[1]
                && p[1] + r <= frame[3]
            {
                dl.circle(p, r, Some(style::THIN));
                occ.mark_point(p, 2);
            }
        }
        taken.extend(pivot_labels(&mut dl, pins));
    }
    for (a, b) in &link_segments {
        occ.mark_segment(*a, *b, 4);
    }
    occ.build();

    // Labels: greedy, each at the candidate beside its own curve covering the least ink
    // and no earlier label.
    let asc = font::ascent(style::LABEL_SIZE);
    let desc = font::descent(style::LABEL_SIZE);
    for (ci, (dashes, p)) in page_curves.iter().zip(&page.points).enumerate() {
        let label = format!("({}, {})", fmt_num(p.u), fmt_num(p.v));
        let tw = font::text_width(style::LABEL_SIZE, &label);
        let mut best: Option<(u64, [f64; 4], PagePoint, PagePoint)> = None;
        for (k, pts) in dashes.iter().enumerate() {
            if pts.len() < 2 {
                continue;
            }
            let a = pts[0];
            let b = pts[pts.len() - 1];
            let mid = pts[pts.len() / 2];
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let len = libm::hypot(dx, dy);
            let nrm = if len > 1e-9 {
                [-dy / len, dx / len]
            } else {
                [0.0, -1.0]
            };
            for side in [1.0, -1.0] {
                for gap in [4.0, 10.0] {
                    let anchor = [mid[0] + side * nrm[0] * gap, mid[1] + side * nrm[1] * gap];
                    // Box corner nearest the curve at the anchor.
                    let bx = if side * nrm[0] >= 0.0 {
                        anchor[0]
                    } else {
                        anchor[0] - tw
                    };
                    let by = if side * nrm[1] >= 0.0 {
                        anchor[1]
                    } else {
                        anchor[1] - asc - desc
                    };
                    let r = [bx - 1.0, by - 1.0, bx + tw + 1.0, by + asc + desc + 1.0];
                    let Some(ink) = occ.cost(r) else { continue };
                    let overlap = taken.iter().filter(|q| rects_overlap(**q, r)).count() as u64;
                    let cost = ink * 10 + overlap * 1_000_000 + (gap as u64) + (k as u64 % 2);
                    if best.is_none_or(|bst| cost < bst.0) {
                        best = Some((cost, r, anchor, mid));
                    }
                }
            }
        }
        let (r, anchor, on_curve) = match best {
            Some((_, r, a, m)) => (r, a, m),
            None => {
                let b = placements[ci].bbox_pt;
                let r = [b[0], b[1] - asc - desc - 2.0, b[0] + tw + 2.0, b[1]];
                (r, [b[0], b[1]], [b[0], b[1]])
            }
        };
        dl.text(
            [r[0] + 1.0, r[1] + 1.0 + asc],
            style::LABEL_SIZE,
            Anchor::Start,
            label,
        );
        // A short leader from the label's anchor to its curve.
        dl.line(vec![on_curve, anchor], style::THIN);
        taken.push(r);
        placements[ci].label_pt = r;
    }

    legend(&mut dl, page, geometry, setup);
    PageLayout {
        display: dl,
        curves: placements,
        scale_pt_per_unit: t.scale,
    }
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

/// Legend and footer: dash meaning, θ = 0 mark, crank sense, circuit, scale bar,
/// generation settings.
fn legend<M: Mechanism>(
    dl: &mut DisplayList,
    page: &LinkagePage<M>,
    geometry: &PageGeometry,
    setup: &PageSetup,
) {
    let m = setup.margin_pt;
    let ts = style::SMALL_SIZE;
    let unit = 12.0;
    let y = dash_legend(
        dl,
        setup,
        "one dash = {step}° of crank ({drawn}° drawn); bold dash and dot: θ = 0; arrowhead: direction of travel",
    );
    // Crank sense: a small counter-clockwise arc arrow.
    let y2 = y + 14.0;
    let c = [m + 8.0, y2];
    let arc: Vec<PagePoint> = (0..=27)
        .map(|k| {
            let (s, co) = coupler_kinematics::sincos_deg(-60.0 + 10.0 * k as f64);
            [c[0] + 5.0 * co, c[1] - 5.0 * s]
        })
        .collect();
    let end = arc[arc.len() - 1];
    dl.line(arc, 0.6);
    // Tangent at 210° (counter-clockwise travel, y down): direction (sin 210°, cos 210°)·…
    let (s, co) = coupler_kinematics::sincos_deg(210.0);
    let dir = [-s, -co];
    let nrm = [-dir[1], dir[0]];
    dl.items.push(Primitive::Polygon {
        points: vec![
            [end[0] + 3.0 * dir[0], end[1] + 3.0 * dir[1]],
            [end[0] + 1.8 * nrm[0], end[1] + 1.8 * nrm[1]],
            [end[0] - 1.8 * nrm[0], end[1] - 1.8 * nrm[1]],
        ],
    });
    dl.text(
        [m + 3.0 * unit + 4.0, y2 + 2.5],
        ts,
        Anchor::Start,
        format!(
            "crank turns counter-clockwise, θ from O2→{};  {} circuit;  linkage drawn at θ = {}°",
            // The second ground pivot: O4 of a four-bar, O5 of a geared five-bar.
            drawn(page).joints.get(1).map_or("O4", |j| j.name),
            page.circuit.name(),
            fmt_num(DRAWN_CRANK_ANGLE_DEG)
        ),
    );
    scale_bar(
        dl,
        m,
        y2 + 14.0,
        geometry.transform.scale,
        "crank length 1 = {} in on this page",
    );
    footer(dl, setup, footer_settings(setup));
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

/// A scale bar one unit (`scale` points) long at `(x, y)` + 2 pt, with a half tick, and
/// `label` with `{}` replaced by the unit's length in inches.
pub(crate) fn scale_bar(dl: &mut DisplayList, x: f64, y: f64, scale: f64, label: &str) {
    let x0 = x + 2.0;
    dl.line(
        vec![
            [x0, y - 3.0],
            [x0, y],
            [x0 + scale, y],
            [x0 + scale, y - 3.0],
        ],
        0.8,
    );
    let half = [x0 + 0.5 * scale, y];
    dl.line(vec![half, [half[0], y - 2.0]], 0.5);
    dl.text(
        [x0 + scale + 6.0, y + 1.0],
        style::SMALL_SIZE,
        Anchor::Start,
        label.replace(
            "{}",
            &fmt_num((scale / PT_PER_INCH * 1000.0).round() / 1000.0),
        ),
    );
}

/// The footer line: generation settings that shape the page, then `setup.settings`.
pub fn footer_settings(setup: &PageSetup) -> String {
    let mut s = format!(
        "dash {}° of crank, {} % drawn · {} dpi · {} · chord tolerance {} px",
        fmt_num(setup.dash.step_deg),
        fmt_num((setup.dash.fraction * 100.0).round()),
        fmt_num(setup.dpi),
        setup.size,
        fmt_num(setup.chord_tolerance_px)
    );
    if !setup.settings.is_empty() {
        s.push_str(" · ");
        s.push_str(&setup.settings);
    }
    s
}

/// One line of the contents: a linkage and the pages it occupies.
#[derive(Clone, Debug, PartialEq)]
pub struct ContentsEntry {
    /// The mechanism.
    pub linkage: Linkage,
    /// Its circuit.
    pub circuit: Circuit,
    /// Number of coupler points (curves).
    pub curves: usize,
    /// First page (1-based, inclusive).
    pub first_page: usize,
    /// Last page (inclusive).
    pub last_page: usize,
}

/// Column offsets of the contents table, points.
const CONTENTS_COLUMNS: [f64; 6] = [0.0, 25.0, 50.0, 75.0, 112.0, 145.0];

/// Lays out the contents: a table of linkages with their page ranges, in as many columns
/// and pages as needed (returns at least one page).
pub fn layout_contents(entries: &[ContentsEntry], setup: &PageSetup) -> Vec<DisplayList> {
    let (w, h) = setup.size_pt();
    let m = setup.margin_pt;
    let row = 11.0;
    let top = m + 50.0;
    let rows = (((h - m - 20.0) - top) / row).floor().max(1.0) as usize;
    let col_w = 195.0;
    let cols = (((w - 2.0 * m) / col_w).floor() as usize).max(1);
    let per_page = rows * cols;
    let n_pages = entries.len().div_ceil(per_page).max(1);
    let mut pages = Vec::with_capacity(n_pages);
    for pi in 0..n_pages {
        let mut dl = DisplayList::new(w, h);
        dl.text(
            [m, m + style::TITLE_SIZE],
            style::TITLE_SIZE,
            Anchor::Start,
            format!("Contents: {}", setup.spec_name),
        );
        dl.text(
            [w - m, m + style::TITLE_SIZE],
            style::TEXT_SIZE,
            Anchor::End,
            format!("contents page {} of {}", pi + 1, n_pages),
        );
        let chunk = entries.iter().skip(pi * per_page).take(per_page);
        for (i, e) in chunk.enumerate() {
            let (c, r) = (i / rows, i % rows);
            let x = m + c as f64 * col_w;
            let y = top + r as f64 * row;
            // The mechanism's dimensions, then circuit, curves and pages.
            let dims = e.linkage.dimensions();
            if r == 0 {
                let heads = dims
                    .iter()
                    .map(|(name, _)| *name)
                    .chain(["circuit", "curves", "pages"]);
                for (dx, head) in CONTENTS_COLUMNS.iter().zip(heads) {
                    dl.text([x + dx, top - row], style::SMALL_SIZE, Anchor::Start, head);
                }
            }
            let pages = if e.first_page == e.last_page {
                e.first_page.to_string()
            } else {
                format!("{}–{}", e.first_page, e.last_page)
            };
            let cells = dims.iter().map(|(_, v)| fmt_num(*v)).chain([
                e.circuit.name().to_string(),
                e.curves.to_string(),
                pages,
            ]);
            for (dx, s) in CONTENTS_COLUMNS.iter().zip(cells) {
                dl.text([x + dx, y], style::SMALL_SIZE, Anchor::Start, s);
            }
        }
        dl.text([w - m, h - m], 6.0, Anchor::End, footer_settings(setup));
        pages.push(dl);
    }
    pages
}

#[cfg(test)]
mod tests {
    use super::*;
    use coupler_kinematics::{FourBar, Pose};

    fn page() -> LinkagePage<FourBar> {
        let grid: Vec<CouplerPoint> = (0..4)
            .flat_map(|i| (0..3).map(move |j| CouplerPoint::new(i as f64, j as f64 - 1.0)))
            .collect();
        LinkagePage {
            linkage: FourBar::new(3.0, 2.0, 3.0).unwrap(),
            circuit: Circuit::Open,
            points: grid[..10].to_vec(),
            grid,
            page_number: 1,
            page_count: 2,
        }
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
    fn everything_inside_the_frame_and_labels_disjoint() {
        let setup = PageSetup::default();
        let pg = page();
        let geo = compute_page(&pg, &setup).unwrap();
        let lay = layout_page(&pg, &geo, &setup);
        assert_eq!(lay.curves.len(), 10);
        let f = geo.frame;
        for c in &lay.curves {
            let b = c.bbox_pt;
            assert!(
                b[0] >= f[0] && b[1] >= f[1] && b[2] <= f[2] && b[3] <= f[3],
                "{b:?} outside {f:?}"
            );
            let px = c.bbox_px(setup.dpi);
            assert!(px[2] <= 3300 && px[3] <= 5100 && px[0] < px[2]);
        }
        for (i, a) in lay.curves.iter().enumerate() {
            for b in &lay.curves[i + 1..] {
                assert!(!rects_overlap(a.label_pt, b.label_pt), "{a:?} {b:?}");
            }
        }
        // Scale is a round number of inches per crank unit.
        let s_in = lay.scale_pt_per_unit / PT_PER_INCH;
        assert!(NICE_INCHES_PER_UNIT.contains(&s_in), "{s_in}");
    }

    #[test]
    fn far_points_are_fitted_not_cut() {
        let mut pg = page();
        pg.points = vec![
            CouplerPoint::new(20.0, 15.0),
            CouplerPoint::new(-10.0, -12.0),
        ];
        let setup = PageSetup::default();
        let geo = compute_page(&pg, &setup).unwrap();
        let lay = layout_page(&pg, &geo, &setup);
        for c in &lay.curves {
            let b = c.bbox_pt;
            let f = geo.frame;
            assert!(b[0] >= f[0] && b[1] >= f[1] && b[2] <= f[2] && b[3] <= f[3]);
        }
    }

    #[test]
    fn a_dash_shrunk_at_a_cusp_stays_a_countable_dot() {
        let setup = PageSetup::default();
        let mut pg = page();
        pg.points.truncate(1);
        let mut geo = compute_page(&pg, &setup).unwrap();
        // Collapse dash 7 to a point, as at a cusp where the speed vanishes.
        let d = &mut geo.curves[0].dashes[7];
        let p = d.points[0];
        d.points = vec![p, p];
        let lay = layout_page(&pg, &geo, &setup);
        let at = geo.transform.map(p.x, p.y);
        let dots = lay
            .display
            .items
            .iter()
            .filter(|i| matches!(i, Primitive::Circle { center, width: None, radius } if *center == at && *radius >= 0.5))
            .count();
        assert_eq!(
            dots, 1,
            "the collapsed dash must be drawn as one filled dot"
        );
        // The other 35 dashes are strokes: 1 bold θ = 0 dash + 34 in the curve's set.
        let regular: usize = lay
            .display
            .items
            .iter()
            .map(|i| match i {
                Primitive::Polylines { lines, .. } => lines.len(),
                _ => 0,
            })
            .sum();
        assert_eq!(regular, 34);
    }

    /// The coupler point that sits on the instant centre at θ0 has a cusp there (its
    /// velocity vanishes). Its page still shows all 36 dashes, each a stroke or a dot.
    #[test]
    fn real_cusp_keeps_every_dash() {
        let l = FourBar::new(3.0, 2.0, 3.0).unwrap();
        let theta0 = 33.0; // the middle of dash 3 (30°–36°)
        let pose = Pose::solve(&l, Circuit::Open, &CrankAngle::from_degrees(theta0)).unwrap();
        // Instant centre: O2 + s·Pa = O4 + t·e4 (lines O2Pa and O4Pb).
        let (a, e4) = (pose.crank_pin.coords, pose.rocker_dir);
        let det = a.x * (-e4.y) - a.y * (-e4.x);
        let s_ = (l.ground * (-e4.y)) / det;
        let ic = a * s_;
        let d = ic - pose.crank_pin.coords;
        let e = pose.coupler_dir;
        let p = CouplerPoint::new(d.dot(&e), -d.x * e.y + d.y * e.x);
        assert!(
            pose.velocity(p).norm() < 1e-9,
            "not a cusp: {}",
            pose.velocity(p).norm()
        );
        let mut pg = page();
        pg.points = vec![p];
        let setup = PageSetup::default();
        let geo = compute_page(&pg, &setup).unwrap();
        let cusp = &geo.curves[0].dashes[3];
        assert!(cusp.length() < 0.2 * geo.curves[0].dashes[20].length());
        let lay = layout_page(&pg, &geo, &setup);
        let strokes: usize = lay
            .display
            .items
            .iter()
            .map(|i| match i {
                Primitive::Polylines { lines, .. } => lines.len(),
                _ => 0,
            })
            .sum();
        let dots = lay
            .display
            .items
            .iter()
            .filter(|i| matches!(i, Primitive::Circle { width: None, radius, .. } if *radius < style::START_DOT_RADIUS))
            .count();
        // 1 bold θ = 0 dash + the others as strokes or dots.
        assert_eq!(1 + strokes + dots, 36, "strokes {strokes}, dots {dots}");
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

    #[test]
    fn contents_paginates() {
        let e = ContentsEntry {
            linkage: FourBar::new(3.0, 2.0, 3.0).unwrap().into(),
            circuit: Circuit::Open,
            curves: 40,
            first_page: 1,
            last_page: 4,
        };
        let many = vec![e; 1000];
        let pages = layout_contents(&many, &PageSetup::default());
        assert!(pages.len() >= 2);
        assert!(!layout_contents(&[], &PageSetup::default()).is_empty());
    }
}
