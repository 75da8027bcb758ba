//! # coupler-layout
//!
//! Page layout, pure: from a mechanism and the coupler points of one page to a display
//! list of primitives in page points (1/72 in, f64, origin top-left, y down): paper
//! sizes, transforms, dashes, labels, the linkage drawn, headers and footers; the
//! full-curve pages of a page set and the contents. Text is measured with the embedded
//! font's metrics (DejaVu Sans, compiled in), the same font every renderer draws with.
//! No pixels, no files: a renderer (`coupler-render`) strokes what comes out of here.

mod card;
mod classic;
mod font;
mod page;

pub use card::{CARD_HEIGHT_PT, CARD_WIDTH_PT, dwell_card, straight_family_chart, wrap};
pub use classic::{
    BRACKETED_TOLERANCE, ClassicGeometry, ClassicPage, Leg, compute_classic, layout_classic,
};
pub use font::{
    FONT_BYTES, FONT_FAMILY, OutlineCmd, PlacedGlyph, ascent, descent, embedded_font, px_scale,
    shape_line, text_outline, text_width,
};
pub use page::{
    Anchor, ContentsEntry, CurvePlacement, DEFAULT_CHORD_TOLERANCE_PX, DEFAULT_CURVES_PER_PAGE,
    DEFAULT_DPI, DEFAULT_MARGIN_PT, DPI_RANGE, DRAWN_CRANK_ANGLE_DEG, DisplayList, LayoutError,
    LinkagePage, Orientation, PT_PER_INCH, PageGeometry, PageLayout, PagePoint, PageSetup,
    PageSize, PaperSize, Primitive, WorldToPage, clip_segment, compute_page, fmt_num,
    footer_settings, layout_contents, layout_page,
};
