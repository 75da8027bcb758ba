//! Ink arithmetic on 8-bit pixels shared by the scan converter (`capsule.rs`), the gray
//! layer (`layer.rs`) and the page raster (`raster.rs`): one pixel's overprint, and eight
//! pixels at a time in 16-bit lanes. A leaf: it imports none of them.

use wide::{i16x8, u8x16, u16x8};

/// Ink of level `g` (0..=255) with coverage `c` over the page's ink `dst`: `dst` when
/// `c` is 0.
#[inline(always)]
pub(crate) fn overprint(dst: u8, c: u8, g: u32) -> u8 {
    let (d, c) = (u32::from(dst), u32::from(c));
    (d + ((255 - d) * c * g + 32_512) / 65_025) as u8
}

/// `x / 255` in lanes, for every 16-bit `x`: `(x · 0x8081) >> 23` (tested for all).
#[inline(always)]
pub(crate) fn div255(x: u16x8) -> u16x8 {
    x.mul_keep_high(u16x8::splat(0x8081))
        .unbounded_shr_scalar(7)
}

/// Eight bytes in 16-bit lanes.
#[inline(always)]
pub(crate) fn widen(b: &[u8]) -> u16x8 {
    let mut a = [0u8; 16];
    a[..8].copy_from_slice(&b[..8]);
    u16x8::from_u8x16_low(u8x16::new(a))
}

/// [`widen`]'s inverse: eight 16-bit lanes, each at most 255, stored as bytes into
/// `b[..8]` (one saturating pack, the same values).
#[inline(always)]
pub(crate) fn narrow(v: u16x8, b: &mut [u8]) {
    let v = i16x8::new(v.to_array().map(|x| x as i16));
    b[..8].copy_from_slice(&u8x16::narrow_i16x8(v, i16x8::ZERO).to_array()[..8]);
}
