//! # coupler-layout
//!
//! Page layout, pure: from a mechanism and the coupler points of one page to a display
//! list of primitives in page points (1/72 in, f64, origin top-left, y down): paper
//! sizes, transforms, dashes, labels, the linkage drawn, headers and footers; the
//! full-curve pages of a page set and the contents. Text is measured with the embedded
//! font's metrics (DejaVu Sans, compiled in), the same font every renderer draws with.
//! No pixels, no files: a renderer (`coupler-render`) strokes what comes out of here.

mod atlas;
mod card;
mod classic;
mod contents;
mod font;
mod labels;
mod page;

pub use atlas::{
    CurvePlacement, DRAWN_CRANK_ANGLE_DEG, EXTENT_STEP_DEG, Inset, LinkagePage, MU_WARNING_DEG,
    PageGeometry, PageLayout, compute_page, compute_page_with_tables, fmt_sig, is_pin_point,
    layout_page,
};
pub use card::{CARD_HEIGHT_PT, CARD_WIDTH_PT, dwell_card, straight_family_chart, wrap};
pub use classic::{
    BRACKETED_TOLERANCE, ClassicGeometry, ClassicPage, Leg, compute_classic, layout_classic,
    mirror_branch, run_velocity_variation,
};
pub use contents::{ContentsEntry, ContentsPage, layout_contents};
pub use font::{
    FONT_BYTES, FONT_FAMILY, OutlineCmd, PlacedGlyph, Shaper, ascent, descent, embedded_font,
    px_scale, shape_line, text_outline, text_width,
};
pub use labels::{own_dot_is_nearest, rect_distance};
pub use page::{
    Anchor, DEFAULT_CHORD_TOLERANCE_PX, DEFAULT_CURVES_PER_PAGE, DEFAULT_DPI, DEFAULT_MARGIN_PT,
    DPI_RANGE, DisplayList, Ink, LayoutError, Orientation, PT_PER_INCH, PagePoint, PageSetup,
    PageSize, PaperSize, Primitive, WorldToPage, clip_segment, fmt_num, footer_settings,
};
