//! Vector backend: PDF with `pdf-writer` (typst's PDF writer) and the embedded font as a
//! subset (typst's `subsetter`).
//!
//! Pages are drawn one at a time into [`PdfPage`]s (in parallel: a page's content stream
//! is compressed on its own), and [`write_pdf`] assembles them into one document: the
//! pages in order with their page labels, an outline (bookmarks), links, and one font for
//! all pages, a subset of DejaVu Sans with the glyphs the document uses, embedded as a
//! CID font with a `ToUnicode` map, so that every word on a page can be searched,
//! selected and copied. Curves are exact polylines in page points; gray inks overprint
//! (the Multiply blend mode, as the raster pages composite), paper halos erase.

use super::{Canvas, anchored_x};
use coupler_layout::{self as font, Anchor, Ink, PagePoint};
use pdf_writer::types::{
    ActionType, AnnotationType, BlendMode, CidFontType, FontFlags, LineCapStyle, LineJoinStyle,
    NumberingStyle, SystemInfo, TextRenderingMode,
};
use pdf_writer::writers::PageLabel;
use pdf_writer::{Content, Filter, Finish, Name, Pdf, Rect, Ref, Str, TextStr};
use std::collections::BTreeMap;

/// Bézier constant for a quarter circle: 4/3·(√2 − 1).
const KAPPA: f64 = 0.552_284_749_830_793_4;

/// A page being drawn. Page points map to PDF user space through a y-flip
/// (`1 0 0 −1 0 H cm`), so the display list's y-down coordinates are used as they are.
pub struct PdfPage {
    content: Content,
    width: f64,
    height: f64,
    ink: Ink,
    /// Glyphs used, by original glyph id, with the text each stands for.
    glyphs: BTreeMap<u16, char>,
    font: ab_glyph::FontRef<'static>,
}

/// A finished page: its size, compressed content stream and the glyphs it uses.
#[derive(Clone, Debug, PartialEq)]
pub struct PdfPageContent {
    /// Width, points.
    pub width: f64,
    /// Height, points.
    pub height: f64,
    /// The content stream, deflated.
    pub stream: Vec<u8>,
    /// Glyphs used (original glyph id → character).
    pub glyphs: BTreeMap<u16, char>,
    /// Link areas on the page (`[x0, y0, x1, y1]` in page points, y down) and the index
    /// of the page (in the document) each one goes to.
    pub links: Vec<([f64; 4], usize)>,
}

/// A bookmark: its title and the index of its page in the document; children below it.
#[derive(Clone, Debug, PartialEq)]
pub struct Bookmark {
    /// Shown in the viewer's outline.
    pub title: String,
    /// Page index (0-based, in the document).
    pub page: usize,
    /// Bookmarks under it.
    pub children: Vec<Bookmark>,
}

/// How pages are numbered in the viewer, from `start` (0-based page index) on: `prefix`
/// then a decimal number from `first`.
#[derive(Clone, Debug, PartialEq)]
pub struct PageLabelRange {
    /// First page of the range (0-based index in the document).
    pub start: usize,
    /// Text before the number.
    pub prefix: String,
    /// The number of the range's first page.
    pub first: u32,
}

fn f(x: f64) -> f32 {
    x as f32
}

impl PdfPage {
    /// An empty page of `width × height` points.
    pub fn new(width: f64, height: f64) -> PdfPage {
        let mut content = Content::new();
        content.transform([1.0, 0.0, 0.0, -1.0, 0.0, f(height)]);
        content.set_fill_gray(0.0).set_stroke_gray(0.0);
        PdfPage {
            content,
            width,
            height,
            ink: Ink::Black,
            glyphs: BTreeMap::new(),
            font: font::embedded_font(),
        }
    }

    fn path(&mut self, points: &[PagePoint]) {
        for (i, p) in points.iter().enumerate() {
            if i == 0 {
                self.content.move_to(f(p[0]), f(p[1]));
            } else {
                self.content.line_to(f(p[0]), f(p[1]));
            }
        }
    }

    /// The finished page, with `links` (areas and the page index each goes to).
    pub fn finish(self, links: Vec<([f64; 4], usize)>) -> PdfPageContent {
        let raw = self.content.finish();
        PdfPageContent {
            width: self.width,
            height: self.height,
            stream: miniz_oxide::deflate::compress_to_vec_zlib(&raw, 6),
            glyphs: self.glyphs,
            links,
        }
    }
}

impl Canvas for PdfPage {
    fn set_ink(&mut self, ink: Ink) {
        self.ink = ink;
        let g = f32::from(ink.gray()) / 255.0;
        self.content.set_fill_gray(g).set_stroke_gray(g);
        // Grays overprint (multiply), paper and black paint normally.
        let gs = match ink {
            Ink::Gray(_) => "Ov",
            _ => "Nm",
        };
        self.content.set_parameters(Name(gs.as_bytes()));
    }

    fn stroke_polyline(&mut self, points: &[PagePoint], width: f64) {
        self.stroke_polylines(&[points.to_vec()], width);
    }

    fn stroke_polylines(&mut self, lines: &[Vec<PagePoint>], width: f64) {
        let mut any = false;
        for l in lines.iter().filter(|l| !l.is_empty()) {
            if !any {
                self.content
                    .set_line_width(f(width))
                    .set_line_cap(LineCapStyle::RoundCap)
                    .set_line_join(LineJoinStyle::RoundJoin);
            }
            self.path(l);
            if l.len() == 1 {
                // A dot: a zero-length segment, drawn by the round cap.
                self.content.line_to(f(l[0][0]), f(l[0][1]));
            }
            any = true;
        }
        if any {
            self.content.stroke();
        }
    }

    fn stroke_rect(&mut self, rect: [f64; 4], width: f64) {
        let [x0, y0, x1, y1] = rect;
        self.content
            .set_line_width(f(width))
            .set_line_cap(LineCapStyle::ButtCap)
            .set_line_join(LineJoinStyle::MiterJoin)
            .rect(f(x0), f(y0), f(x1 - x0), f(y1 - y0))
            .stroke();
    }

    fn fill_polygon(&mut self, points: &[PagePoint]) {
        if points.len() < 3 {
            return;
        }
        self.path(points);
        self.content.close_path().fill_nonzero();
    }

    fn circle(&mut self, c: PagePoint, r: f64, width: Option<f64>) {
        let k = KAPPA * r;
        let (x, y) = (c[0], c[1]);
        self.content.move_to(f(x + r), f(y));
        let quads = [
            ([x + r, y + k], [x + k, y + r], [x, y + r]),
            ([x - k, y + r], [x - r, y + k], [x - r, y]),
            ([x - r, y - k], [x - k, y - r], [x, y - r]),
            ([x + k, y - r], [x + r, y - k], [x + r, y]),
        ];
        for (a, b, e) in quads {
            self.content
                .cubic_to(f(a[0]), f(a[1]), f(b[0]), f(b[1]), f(e[0]), f(e[1]));
        }
        self.content.close_path();
        match width {
            None => {
                self.content.fill_nonzero();
            }
            Some(w) => {
                self.content.set_line_width(f(w)).stroke();
            }
        }
    }

    fn text(&mut self, pos: PagePoint, size: f64, anchor: Anchor, text: &str, halo: f64) {
        if text.is_empty() {
            return;
        }
        let (glyphs, width) = font::shape_line(&self.font, size, text);
        let x = anchored_x(pos[0], width, anchor);
        for (g, ch) in glyphs.iter().zip(text.chars()) {
            self.glyphs.entry(g.id.0).or_insert(ch);
        }
        let upem = f64::from(ab_glyph::Font::units_per_em(&self.font).unwrap_or(2048.0));
        let advance = |id| f64::from(ab_glyph::Font::h_advance_unscaled(&self.font, id));
        // Glyph codes (2 bytes each: CID = the font's glyph id) with the kerning between
        // them as TJ adjustments (thousandths of an em, negative moves right).
        let mut runs: Vec<(Vec<u8>, f32)> = Vec::new();
        let mut pen = 0.0;
        let mut cur: Vec<u8> = Vec::new();
        for g in &glyphs {
            let adj = g.x - pen;
            if adj.abs() > 1e-6 && !cur.is_empty() {
                runs.push((std::mem::take(&mut cur), -(adj * 1000.0 / size) as f32));
            }
            cur.extend_from_slice(&g.id.0.to_be_bytes());
            pen = g.x + advance(g.id) * size / upem;
        }
        runs.push((cur, 0.0));
        let show = |c: &mut Content, mode: TextRenderingMode| {
            c.begin_text();
            c.set_font(Name(b"F0"), f(size));
            c.set_text_rendering_mode(mode);
            c.set_text_matrix([1.0, 0.0, 0.0, -1.0, f(x), f(pos[1])]);
            {
                let mut sp = c.show_positioned();
                let mut items = sp.items();
                for (bytes, adj) in &runs {
                    items.show(Str(bytes));
                    if *adj != 0.0 {
                        items.adjust(*adj);
                    }
                }
            }
            c.end_text();
        };
        if halo > 0.0 {
            let ink = self.ink;
            self.set_ink(Ink::Paper);
            self.content
                .set_line_width(f(2.0 * halo))
                .set_line_join(LineJoinStyle::RoundJoin);
            show(&mut self.content, TextRenderingMode::Stroke);
            self.set_ink(ink);
        }
        show(&mut self.content, TextRenderingMode::Fill);
    }
}

/// Why a PDF could not be written.
#[derive(Debug, thiserror::Error)]
pub enum PdfError {
    /// The font could not be subset.
    #[error("cannot subset the embedded font: {0}")]
    Font(String),
}

/// Writes one PDF of `pages` (in order) with `bookmarks` (the outline), page labels
/// (`labels`, by range) and document `title`. Deterministic: the same pages give the same
/// bytes.
pub fn write_pdf(
    pages: &[PdfPageContent],
    bookmarks: &[Bookmark],
    labels: &[PageLabelRange],
    title: &str,
) -> Result<Vec<u8>, PdfError> {
    let mut next = 1;
    let mut alloc = || {
        let r = Ref::new(next);
        next += 1;
        r
    };
    let catalog = alloc();
    let tree = alloc();
    let info = alloc();
    let type0 = alloc();
    let cid = alloc();
    let descriptor = alloc();
    let font_file = alloc();
    let cid_map = alloc();
    let to_unicode = alloc();
    let gs_over = alloc();
    let gs_normal = alloc();
    let outline = alloc();
    let page_ids: Vec<Ref> = pages.iter().map(|_| alloc()).collect();
    let content_ids: Vec<Ref> = pages.iter().map(|_| alloc()).collect();
    let label_ids: Vec<Ref> = labels.iter().map(|_| alloc()).collect();

    // Every glyph the document uses.
    let mut glyphs: BTreeMap<u16, char> = BTreeMap::new();
    for p in pages {
        for (g, c) in &p.glyphs {
            glyphs.entry(*g).or_insert(*c);
        }
    }

    let mut pdf = Pdf::new();
    pdf.set_version(1, 7);
    pdf.document_info(info)
        .title(TextStr(title))
        .producer(TextStr(concat!(
            "coupler-atlas ",
            env!("CARGO_PKG_VERSION")
        )));

    {
        let mut cat = pdf.catalog(catalog);
        cat.pages(tree);
        if !bookmarks.is_empty() {
            cat.outlines(outline);
            cat.page_mode(pdf_writer::types::PageMode::UseOutlines);
        }
        if !labels.is_empty() {
            let mut nums = cat.page_labels();
            let mut entries = nums.nums();
            for (l, id) in labels.iter().zip(&label_ids) {
                entries.insert(l.start as i32, *id);
            }
        }
    }
    for (l, id) in labels.iter().zip(&label_ids) {
        let mut label = pdf.indirect(*id).start::<PageLabel>();
        label.style(NumberingStyle::Arabic);
        if !l.prefix.is_empty() {
            label.prefix(TextStr(&l.prefix));
        }
        label.offset(l.first as i32);
    }
    pdf.pages(tree)
        .kids(page_ids.iter().copied())
        .count(pages.len() as i32);

    // Link annotations, one object each.
    let mut annots: Vec<Vec<Ref>> = vec![Vec::new(); pages.len()];
    for (i, p) in pages.iter().enumerate() {
        for (rect, target) in &p.links {
            let Some(&dest) = page_ids.get(*target) else {
                continue;
            };
            let id = alloc();
            annots[i].push(id);
            let mut a = pdf.annotation(id);
            a.subtype(AnnotationType::Link)
                .rect(Rect::new(
                    f(rect[0]),
                    f(p.height - rect[3]),
                    f(rect[2]),
                    f(p.height - rect[1]),
                ))
                .border(0.0, 0.0, 0.0, None);
            a.action()
                .action_type(ActionType::GoTo)
                .destination()
                .page(dest)
                .fit();
        }
    }

    for (i, p) in pages.iter().enumerate() {
        let mut page = pdf.page(page_ids[i]);
        page.parent(tree)
            .media_box(Rect::new(0.0, 0.0, f(p.width), f(p.height)))
            .contents(content_ids[i]);
        if !annots[i].is_empty() {
            page.annotations(annots[i].iter().copied());
        }
        let mut res = page.resources();
        res.fonts().pair(Name(b"F0"), type0);
        res.ext_g_states()
            .pair(Name(b"Ov"), gs_over)
            .pair(Name(b"Nm"), gs_normal);
        res.finish();
        page.finish();
        pdf.stream(content_ids[i], &p.stream)
            .filter(Filter::FlateDecode);
    }
    pdf.ext_graphics(gs_over).blend_mode(BlendMode::Multiply);
    pdf.ext_graphics(gs_normal).blend_mode(BlendMode::Normal);

    // Outline.
    if !bookmarks.is_empty() {
        write_outline(&mut pdf, outline, bookmarks, &page_ids, &mut alloc);
    }

    // The font: a subset with the used glyphs, CID = the original glyph id, mapped to
    // the subset's glyph ids by a CIDToGIDMap stream.
    let face = font::embedded_font();
    let upem = f64::from(ab_glyph::Font::units_per_em(&face).unwrap_or(2048.0));
    let mut remapper = subsetter::GlyphRemapper::new();
    for g in glyphs.keys() {
        remapper.remap(*g);
    }
    let subset = subsetter::subset(font::FONT_BYTES, 0, &remapper)
        .map_err(|e| PdfError::Font(e.to_string()))?;
    let base = Name(b"CAAAAA+DejaVuSans");
    pdf.type0_font(type0)
        .base_font(base)
        .encoding_predefined(Name(b"Identity-H"))
        .descendant_font(cid)
        .to_unicode(to_unicode);
    {
        let mut c = pdf.cid_font(cid);
        c.subtype(CidFontType::Type2)
            .base_font(base)
            .system_info(SystemInfo {
                registry: Str(b"Adobe"),
                ordering: Str(b"Identity"),
                supplement: 0,
            })
            .font_descriptor(descriptor)
            .default_width(0.0)
            .cid_to_gid_map_stream(cid_map);
        let mut w = c.widths();
        for g in glyphs.keys() {
            let adv = f64::from(ab_glyph::Font::h_advance_unscaled(
                &face,
                ab_glyph::GlyphId(*g),
            ));
            w.consecutive(*g, [f((adv * 1000.0 / upem).round())]);
        }
    }
    let k = 1000.0 / upem;
    pdf.font_descriptor(descriptor)
        .name(base)
        .flags(FontFlags::NON_SYMBOLIC)
        .bbox(Rect::new(
            f(-2090.0 * k),
            f(-948.0 * k),
            f(3673.0 * k),
            f(2524.0 * k),
        ))
        .italic_angle(0.0)
        .ascent(f(f64::from(ab_glyph::Font::ascent_unscaled(&face)) * k))
        .descent(f(f64::from(ab_glyph::Font::descent_unscaled(&face)) * k))
        .cap_height(f(1493.0 * k))
        .stem_v(80.0)
        .font_file2(font_file);
    let compressed = miniz_oxide::deflate::compress_to_vec_zlib(&subset, 6);
    pdf.stream(font_file, &compressed)
        .filter(Filter::FlateDecode)
        .pair(Name(b"Length1"), subset.len() as i32);
    let max_cid = glyphs.keys().next_back().copied().unwrap_or(0) as usize;
    let mut map = vec![0u8; 2 * (max_cid + 1)];
    for g in glyphs.keys() {
        let new = remapper.get(*g).unwrap_or(0);
        map[2 * *g as usize..2 * *g as usize + 2].copy_from_slice(&new.to_be_bytes());
    }
    let map = miniz_oxide::deflate::compress_to_vec_zlib(&map, 6);
    pdf.stream(cid_map, &map).filter(Filter::FlateDecode);
    let mut cmap = pdf_writer::types::UnicodeCmap::new(
        Name(b"Custom"),
        SystemInfo {
            registry: Str(b"Adobe"),
            ordering: Str(b"UCS"),
            supplement: 0,
        },
    );
    for (g, c) in &glyphs {
        cmap.pair(*g, *c);
    }
    let cmap = cmap.finish();
    pdf.cmap(to_unicode, cmap.as_slice());
    Ok(pdf.finish())
}

/// Writes the outline's items (one level of children).
fn write_outline(
    pdf: &mut Pdf,
    root: Ref,
    bookmarks: &[Bookmark],
    page_ids: &[Ref],
    alloc: &mut impl FnMut() -> Ref,
) {
    let ids: Vec<Ref> = bookmarks.iter().map(|_| alloc()).collect();
    let child_ids: Vec<Vec<Ref>> = bookmarks
        .iter()
        .map(|b| b.children.iter().map(|_| alloc()).collect())
        .collect();
    let total: usize = bookmarks.len();
    pdf.outline(root)
        .first(ids[0])
        .last(ids[ids.len() - 1])
        .count(total as i32);
    for (i, b) in bookmarks.iter().enumerate() {
        let mut item = pdf.outline_item(ids[i]);
        item.title(TextStr(&b.title)).parent(root);
        if i > 0 {
            item.prev(ids[i - 1]);
        }
        if i + 1 < ids.len() {
            item.next(ids[i + 1]);
        }
        let kids = &child_ids[i];
        if !kids.is_empty() {
            item.first(kids[0])
                .last(kids[kids.len() - 1])
                .count(-(kids.len() as i32));
        }
        if let Some(&p) = page_ids.get(b.page) {
            item.dest().page(p).fit();
        }
        item.finish();
        for (j, c) in b.children.iter().enumerate() {
            let mut ci = pdf.outline_item(kids[j]);
            ci.title(TextStr(&c.title)).parent(ids[i]);
            if j > 0 {
                ci.prev(kids[j - 1]);
            }
            if j + 1 < kids.len() {
                ci.next(kids[j + 1]);
            }
            if let Some(&p) = page_ids.get(c.page) {
                ci.dest().page(p).fit();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_document_with_text_links_and_an_outline() {
        let mut p = PdfPage::new(100.0, 50.0);
        p.stroke_polyline(&[[1.0, 2.0], [3.0, 4.0]], 0.5);
        p.text([5.0, 20.0], 10.0, Anchor::Start, "A = 2.5", 1.0);
        let a = p.finish(vec![([0.0, 0.0, 10.0, 10.0], 1)]);
        let b = PdfPage::new(100.0, 50.0).finish(Vec::new());
        let bm = [Bookmark {
            title: "A = 2.5".into(),
            page: 1,
            children: Vec::new(),
        }];
        let pdf = write_pdf(&[a, b], &bm, &[], "test").unwrap();
        assert!(pdf.starts_with(b"%PDF-1.7"));
        let has = |needle: &[u8]| pdf.windows(needle.len()).any(|w| w == needle);
        assert!(has(b"/Type /Annot"));
        assert!(has(b"/Outlines"));
        assert!(has(b"/ToUnicode"));
        assert!(has(b"/FontFile2"));
    }
}
