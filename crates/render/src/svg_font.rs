//! The font subset an SVG page carries: the glyphs of the characters its text uses, as a
//! complete little TrueType font (with its own `cmap`, as a browser needs) in an
//! `@font-face` data URL.
//!
//! A PDF font subset (typst's `subsetter`) drops the `cmap`, `OS/2` and `hhea` tables,
//! which a PDF does not need but a web font does; so SVG pages get this subset instead:
//! the used glyphs (and the components of composite glyphs) renumbered from 1, with
//! `head`, `hhea`, `maxp`, `OS/2`, `name` copied from DejaVu Sans, `hmtx`, `loca`,
//! `glyf` cut down, a format-4 `cmap` of the used characters and a `post` without names.

use coupler_layout::FONT_BYTES;
use std::collections::{BTreeMap, BTreeSet};

/// The CSS family name of the embedded subset.
pub(crate) const FONT_CSS_FAMILY: &str = "'coupler-atlas DejaVu Sans'";

/// A `<style>` element with the `@font-face` rule for the characters `chars` (empty set:
/// none).
pub(crate) fn font_face_style(chars: &BTreeSet<char>) -> String {
    if chars.is_empty() {
        return String::new();
    }
    match subset_font(FONT_BYTES, chars) {
        Some(font) => format!(
            "<style>@font-face{{font-family:{FONT_CSS_FAMILY};src:url(data:font/ttf;base64,{})format(\"truetype\")}}</style>\n",
            base64(&font)
        ),
        None => String::new(),
    }
}

fn base64(data: &[u8]) -> String {
    const T: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(data.len().div_ceil(3) * 4);
    for c in data.chunks(3) {
        let b = [c[0], *c.get(1).unwrap_or(&0), *c.get(2).unwrap_or(&0)];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= c.len() {
                out.push(T[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

fn u16_at(d: &[u8], o: usize) -> Option<u16> {
    Some(u16::from_be_bytes([*d.get(o)?, *d.get(o + 1)?]))
}

fn u32_at(d: &[u8], o: usize) -> Option<u32> {
    Some(u32::from_be_bytes([
        *d.get(o)?,
        *d.get(o + 1)?,
        *d.get(o + 2)?,
        *d.get(o + 3)?,
    ]))
}

/// The tables of a TrueType font by tag.
fn tables(font: &[u8]) -> Option<BTreeMap<[u8; 4], &[u8]>> {
    let n = u16_at(font, 4)? as usize;
    let mut t = BTreeMap::new();
    for i in 0..n {
        let r = 12 + 16 * i;
        let tag: [u8; 4] = font.get(r..r + 4)?.try_into().ok()?;
        let off = u32_at(font, r + 8)? as usize;
        let len = u32_at(font, r + 12)? as usize;
        t.insert(tag, font.get(off..off + len)?);
    }
    Some(t)
}

/// The glyph ids a composite glyph refers to, and where each id is stored in its data.
fn components(glyph: &[u8]) -> Vec<(usize, u16)> {
    let mut out = Vec::new();
    if glyph.len() < 10 || (u16_at(glyph, 0).unwrap_or(0) as i16) >= 0 {
        return out;
    }
    let mut o = 10;
    while let (Some(flags), Some(id)) = (u16_at(glyph, o), u16_at(glyph, o + 2)) {
        out.push((o + 2, id));
        o += 4 + if flags & 0x0001 != 0 { 4 } else { 2 };
        if flags & 0x0008 != 0 {
            o += 2;
        } else if flags & 0x0040 != 0 {
            o += 4;
        } else if flags & 0x0080 != 0 {
            o += 8;
        }
        if flags & 0x0020 == 0 {
            break;
        }
    }
    out
}

fn checksum(data: &[u8]) -> u32 {
    data.chunks(4).fold(0u32, |s, c| {
        let mut b = [0u8; 4];
        b[..c.len()].copy_from_slice(c);
        s.wrapping_add(u32::from_be_bytes(b))
    })
}

/// A TrueType font with the glyphs of `chars` only (see the module's documentation);
/// `None` if the font cannot be read.
pub(crate) fn subset_font(font: &[u8], chars: &BTreeSet<char>) -> Option<Vec<u8>> {
    let t = tables(font)?;
    let (head, hhea, maxp, hmtx, loca, glyf) = (
        *t.get(b"head")?,
        *t.get(b"hhea")?,
        *t.get(b"maxp")?,
        *t.get(b"hmtx")?,
        *t.get(b"loca")?,
        *t.get(b"glyf")?,
    );
    let long_loca = u16_at(head, 50)? == 1;
    let num_glyphs = u16_at(maxp, 4)? as usize;
    let glyph = |g: u16| -> Option<&[u8]> {
        let g = g as usize;
        if g >= num_glyphs {
            return None;
        }
        let (a, b) = if long_loca {
            (
                u32_at(loca, 4 * g)? as usize,
                u32_at(loca, 4 * g + 4)? as usize,
            )
        } else {
            (
                2 * u16_at(loca, 2 * g)? as usize,
                2 * u16_at(loca, 2 * g + 2)? as usize,
            )
        };
        glyf.get(a..b)
    };
    let face = coupler_layout::embedded_font();
    let cmap: BTreeMap<char, u16> = chars
        .iter()
        .filter(|c| (**c as u32) < 0xFFFF)
        .map(|c| (*c, ab_glyph::Font::glyph_id(&face, *c).0))
        .filter(|(_, g)| *g != 0)
        .collect();
    // The glyphs: .notdef, the characters', and the components of composites.
    let mut used: BTreeSet<u16> = std::iter::once(0).chain(cmap.values().copied()).collect();
    let mut todo: Vec<u16> = used.iter().copied().collect();
    while let Some(g) = todo.pop() {
        for (_, c) in components(glyph(g)?) {
            if used.insert(c) {
                todo.push(c);
            }
        }
    }
    let new_id: BTreeMap<u16, u16> = used
        .iter()
        .enumerate()
        .map(|(i, g)| (*g, i as u16))
        .collect();
    let n = used.len();
    // glyf and loca (long offsets), hmtx.
    let num_h = u16_at(hhea, 34)? as usize;
    let mut new_glyf = Vec::new();
    let mut new_loca = Vec::with_capacity(4 * (n + 1));
    let mut new_hmtx = Vec::with_capacity(4 * n);
    for &g in &used {
        new_loca.extend_from_slice(&(new_glyf.len() as u32).to_be_bytes());
        let mut data = glyph(g)?.to_vec();
        for (at, c) in components(&data.clone()) {
            data[at..at + 2].copy_from_slice(&new_id[&c].to_be_bytes());
        }
        new_glyf.extend_from_slice(&data);
        while new_glyf.len() % 4 != 0 {
            new_glyf.push(0);
        }
        let gi = g as usize;
        let (adv, lsb) = if gi < num_h {
            (u16_at(hmtx, 4 * gi)?, u16_at(hmtx, 4 * gi + 2)?)
        } else {
            (
                u16_at(hmtx, 4 * (num_h - 1))?,
                u16_at(hmtx, 4 * num_h + 2 * (gi - num_h))?,
            )
        };
        new_hmtx.extend_from_slice(&adv.to_be_bytes());
        new_hmtx.extend_from_slice(&lsb.to_be_bytes());
    }
    new_loca.extend_from_slice(&(new_glyf.len() as u32).to_be_bytes());
    let mut new_head = head.to_vec();
    new_head[8..12].fill(0);
    new_head[50..52].copy_from_slice(&1u16.to_be_bytes());
    let mut new_hhea = hhea.to_vec();
    new_hhea[34..36].copy_from_slice(&(n as u16).to_be_bytes());
    let mut new_maxp = maxp.to_vec();
    new_maxp[4..6].copy_from_slice(&(n as u16).to_be_bytes());
    let mut new_post = t.get(b"post")?.get(..32)?.to_vec();
    new_post[0..4].copy_from_slice(&0x0003_0000u32.to_be_bytes());
    // cmap: format 4, one segment per character, then the 0xFFFF end segment.
    let segs: Vec<(u16, u16)> = cmap
        .iter()
        .map(|(c, g)| (*c as u16, new_id[g]))
        .chain(std::iter::once((0xFFFF, 0)))
        .collect();
    let sc = segs.len();
    let mut sub = Vec::new();
    let entry = 15 - (sc as u16).leading_zeros() as u16;
    let search = 2 * (1u16 << entry);
    for v in [
        4u16,
        (16 + 8 * sc) as u16,
        0,
        (2 * sc) as u16,
        search,
        entry,
        (2 * sc) as u16 - search,
    ] {
        sub.extend_from_slice(&v.to_be_bytes());
    }
    for (c, _) in &segs {
        sub.extend_from_slice(&c.to_be_bytes());
    }
    sub.extend_from_slice(&0u16.to_be_bytes());
    for (c, _) in &segs {
        sub.extend_from_slice(&c.to_be_bytes());
    }
    for (c, g) in &segs {
        let delta = if *c == 0xFFFF {
            1u16
        } else {
            g.wrapping_sub(*c)
        };
        sub.extend_from_slice(&delta.to_be_bytes());
    }
    for _ in &segs {
        sub.extend_from_slice(&0u16.to_be_bytes());
    }
    let mut new_cmap = Vec::new();
    for v in [0u16, 1, 3, 1] {
        new_cmap.extend_from_slice(&v.to_be_bytes());
    }
    new_cmap.extend_from_slice(&12u32.to_be_bytes());
    new_cmap.extend_from_slice(&sub);

    let mut out_tables: Vec<([u8; 4], Vec<u8>)> = vec![
        (*b"OS/2", t.get(b"OS/2")?.to_vec()),
        (*b"cmap", new_cmap),
        (*b"glyf", new_glyf),
        (*b"head", new_head),
        (*b"hhea", new_hhea),
        (*b"hmtx", new_hmtx),
        (*b"loca", new_loca),
        (*b"maxp", new_maxp),
        (*b"name", t.get(b"name")?.to_vec()),
        (*b"post", new_post),
    ];
    out_tables.sort_by_key(|t| t.0);
    let nt = out_tables.len() as u16;
    let entry = 15 - nt.leading_zeros() as u16;
    let search = 16 * (1u16 << entry);
    let mut out = Vec::new();
    out.extend_from_slice(&0x0001_0000u32.to_be_bytes());
    for v in [nt, search, entry, 16 * nt - search] {
        out.extend_from_slice(&v.to_be_bytes());
    }
    let mut offset = 12 + 16 * out_tables.len();
    let mut head_at = 0;
    for (tag, data) in &out_tables {
        out.extend_from_slice(tag);
        out.extend_from_slice(&checksum(data).to_be_bytes());
        out.extend_from_slice(&(offset as u32).to_be_bytes());
        out.extend_from_slice(&(data.len() as u32).to_be_bytes());
        if tag == b"head" {
            head_at = offset;
        }
        offset += data.len().div_ceil(4) * 4;
    }
    for (_, data) in &out_tables {
        out.extend_from_slice(data);
        while out.len() % 4 != 0 {
            out.push(0);
        }
    }
    let adjust = 0xB1B0_AFBAu32.wrapping_sub(checksum(&out));
    out[head_at + 8..head_at + 12].copy_from_slice(&adjust.to_be_bytes());
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use ab_glyph::Font;

    #[test]
    fn the_subset_maps_its_characters_to_the_same_outlines() {
        let chars: BTreeSet<char> = "A = 2.5 (u, v) θ μ −0.375 ≤ ⚠ εₛ".chars().collect();
        let sub = subset_font(FONT_BYTES, &chars).unwrap();
        assert!(sub.len() < 80_000, "{} bytes", sub.len());
        let small = ab_glyph::FontRef::try_from_slice(&sub).unwrap();
        let full = coupler_layout::embedded_font();
        for c in chars.iter().filter(|c| **c != ' ') {
            let (a, b) = (small.glyph_id(*c), full.glyph_id(*c));
            assert_ne!(a.0, 0, "{c} is in the subset");
            assert_eq!(
                small.h_advance_unscaled(a),
                full.h_advance_unscaled(b),
                "{c}: same advance"
            );
            assert_eq!(
                small.outline(a).map(|o| o.curves.len()),
                full.outline(b).map(|o| o.curves.len()),
                "{c}: same outline"
            );
        }
        assert_eq!(base64(b"Man"), "TWFu");
        assert_eq!(base64(b"Ma"), "TWE=");
    }
}
