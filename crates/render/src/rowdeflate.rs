//! The fast PNG encoder's zlib stream: `fdeflate`'s format, bit for bit, written row by
//! row by an encoder that knows where a row's zeros are.
//!
//! `fdeflate::Compressor` writes one dynamic-Huffman block whose code is fixed in the
//! header it writes first (short codes near 0 and 255, runs of zeros as distance-1
//! matches), and encodes each `write_data` call on its own: the bits of a call depend on
//! its bytes only, never on what came before. [`RowDeflate`] makes the same stream from
//! the same rows while skipping the zeros it knows of:
//!
//! - a **blank row** (the filter byte, then zeros) is a bit string made once per width
//!   and appended as it is; its Adler-32 is updated arithmetically (a zero byte adds
//!   nothing to the sum `a` and `a` to the sum `b`), so the row is never read;
//! - an **inked row** is read in 8-byte words as `fdeflate` reads it, but only the words
//!   that may hold ink; the words between are known to be zero and only lengthen the
//!   current run of zeros, and their Adler-32 is updated arithmetically too. The words
//!   are read twice: once to list those not all zero (each word stored at the list's
//!   end, which moves on only if it is not zero: no branch), then the listed ones are
//!   written as symbols without a branch on their bytes (a word's run of zeros one
//!   symbol, or two, its 8 bytes widened in one unpack and stored as literal symbols of
//!   which those up to its trailing zeros are kept), since on anti-aliased ink the
//!   branches per word and per byte of `fdeflate`'s loop are mispredicted; the symbols
//!   are then coded twenty-four at a time, three to a store, from one table (a row's
//!   last few with the next row's), so a word's bits cost what its run and its few
//!   literals do.
//!   A page's Up-filtered row is not even stored ([`RowDeflate::up_row`]): the words
//!   that meet the ink marks of the row and the row above are filtered eight bytes at
//!   once from the ink and go straight to the coder.
//!
//! The code (the lengths of the literal/length and distance codes) is read from the header
//! `fdeflate` writes, not copied: the two cannot drift apart, and the tests compare the
//! streams byte for byte.

use std::sync::OnceLock;
use wide::{i16x8, i32x4, u8x16, u16x8};

/// The Adler-32 modulus.
const ADLER_MOD: u64 = 65_521;

/// What `fdeflate`'s stream is made of: its header and its code.
struct Format {
    /// The zlib header and the block's header, whole bytes.
    header: Vec<u8>,
    /// The header's last bits (`header_bits.1` of them).
    header_bits: (u64, u32),
    /// Literal/length codes, bit-reversed for writing least significant bit first.
    code: [u16; 286],
    len: [u8; 286],
    /// The code of distance 1, and its length.
    dist: (u16, u8),
    /// The length symbol of a match of length `3 + i`, and its base length.
    length_symbol: [(u16, u16); 256],
    /// The bits of a run of `z ≤ ZRUN_MAX` zeros ([`Bits::zeros`]; none for `z = 0`),
    /// and their number.
    zrun: [(u64, u32); ZRUN_MAX as usize + 1],
    /// The code of each symbol `s` of a row's symbols ([`RUN`]) at `sym[s]`, and its
    /// length at `sym[2^16 + s]` (a code and a length are each one load, no shift to
    /// part them, from one base); two symbols that can follow each other fit a `put`
    /// (checked when they are made). An entry for every `u16`, so that a symbol indexes
    /// the table as it is (no mask and no bounds check); those past the symbols'
    /// ([`SYMBOLS`]) are zero and never read, so only the pages of the first few KiB of
    /// each half are ever touched.
    sym: Box<[u64; 1 << 17]>,
}

/// The longest run of zeros [`Format::zrun`] holds: a literal 0 and three matches of 258
/// (its codes are checked to fit a put beside a literal's).
const ZRUN_MAX: u32 = 3 * 258 + 1;

/// The symbols a row is first written as ([`Bits::coded`]), each coded by its entry in
/// [`Format::sym`]: `0..=255` the literal bytes; `RUN + z` a run of `z ≤ ZRUN_MAX` zeros
/// (the bits of [`Format::zrun`]; `RUN` alone has no bits and pads); `MATCH` a match of
/// 258 zeros; `REST + r` for `r < 258` the bits after the literal 0 of a run of `r + 1`
/// zeros. A longer run of `z` zeros is the literal 0, `(z − 1) / 258` matches and
/// `REST + (z − 1) % 258`, as `fdeflate` codes it ([`Bits::zeros_by_symbol`]).
const RUN: u16 = 256;
const MATCH: u16 = RUN + ZRUN_MAX as u16 + 1;
const REST: u16 = MATCH + 1;
/// The symbols that have codes (all below `REST + 258`, some unused).
const SYMBOLS: usize = 2048;

/// The symbols [`Bits::code_groups`] codes at a time.
const GROUP: usize = 24;

/// The longest run of zeros written as one symbol (`RUN + z`: a literal 0 and at most
/// one length, at most 20 bits); a longer one up to [`ZRUN_MAX`] is two, the literal 0
/// and one or two matches of 258 (`RUN + 1 + 258q`, the run of `1 + 258q` zeros) and
/// the rest (`REST + r`, or `MATCH` for the run of `3·258 + 1`), so that three symbols
/// that can follow each other fit a put.
const RUN_ONE: u32 = 259;

/// The symbols of a run of `z ≤ ZRUN_MAX` zeros at `RUN_SYMBOLS[z]`: the first in bits
/// 0–15, the second in bits 16–31 and their number (0 for `z = 0`, 1 up to
/// [`RUN_ONE`], else 2) in bits 62–63.
const RUN_SYMBOLS: [u64; ZRUN_MAX as usize + 1] = run_symbols();

const fn run_symbols() -> [u64; ZRUN_MAX as usize + 1] {
    let mut t = [0u64; ZRUN_MAX as usize + 1];
    let mut z = 1;
    while z <= ZRUN_MAX {
        t[z as usize] = if z <= RUN_ONE {
            (RUN as u64 + z as u64) | 1 << 62
        } else {
            let q = if z > 2 * 258 { 2 } else { 1 };
            let r = z - 1 - 258 * q;
            let second = if r == 258 { MATCH } else { REST + r as u16 };
            (RUN as u64 + 1 + 258 * q as u64) | (second as u64) << 16 | 2 << 62
        };
        z += 1;
    }
    t
}

/// The most bits [`Bits::put`] takes at once.
const PUT_MAX: u32 = 56;

/// Extra bits of the length symbols 257..=285 (RFC 1951, 3.2.5).
const LENGTH_EXTRA: [u8; 29] = [
    0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2, 3, 3, 3, 3, 4, 4, 4, 4, 5, 5, 5, 5, 0,
];

impl Format {
    fn get() -> &'static Format {
        static FORMAT: OnceLock<Format> = OnceLock::new();
        FORMAT.get_or_init(|| Format::read().expect("fdeflate's stream header"))
    }

    /// Reads the header of an empty `fdeflate` stream.
    fn read() -> Option<Format> {
        let empty = fdeflate::Compressor::new(Vec::new()).ok()?.finish().ok()?;
        if empty.len() < 3 || empty[0] & 0x0f != 8 {
            return None;
        }
        let mut r = BitReader {
            data: &empty[2..],
            pos: 0,
        };
        let (_last, kind) = (r.bits(1)?, r.bits(2)?);
        if kind != 2 {
            return None; // not a dynamic-Huffman block
        }
        let hlit = r.bits(5)? as usize + 257;
        let hdist = r.bits(5)? as usize + 1;
        let hclen = r.bits(4)? as usize + 4;
        const ORDER: [usize; 19] = [
            16, 17, 18, 0, 8, 7, 9, 6, 10, 5, 11, 4, 12, 3, 13, 2, 14, 1, 15,
        ];
        let mut cl = [0u8; 19];
        for &i in &ORDER[..hclen] {
            cl[i] = r.bits(3)? as u8;
        }
        let cl_codes = canonical(&cl);
        let mut lengths: Vec<u8> = Vec::with_capacity(hlit + hdist);
        while lengths.len() < hlit + hdist {
            let sym = r.symbol(&cl, &cl_codes)?;
            match sym {
                0..=15 => lengths.push(sym as u8),
                16 => {
                    let prev = *lengths.last()?;
                    let n = 3 + r.bits(2)?;
                    lengths.extend(std::iter::repeat_n(prev, n as usize));
                }
                17 => {
                    let n = 3 + r.bits(3)?;
                    lengths.extend(std::iter::repeat_n(0, n as usize));
                }
                _ => {
                    let n = 11 + r.bits(7)?;
                    lengths.extend(std::iter::repeat_n(0, n as usize));
                }
            }
        }
        if lengths.len() != hlit + hdist || hlit < 286 {
            return None;
        }
        let (lit, dist) = lengths.split_at(hlit);
        let lit_codes = canonical(lit);
        let dist_codes = canonical(dist);
        let mut code = [0u16; 286];
        let mut len = [0u8; 286];
        for s in 0..286 {
            code[s] = reverse(lit_codes[s], lit[s]);
            len[s] = lit[s];
        }
        // Literal 0 must have a code, and the stream's runs need a distance-1 code.
        if len[0] == 0 || len[256] == 0 || len[285] == 0 || dist[0] == 0 {
            return None;
        }
        let mut length_symbol = [(0u16, 0u16); 256];
        let mut base = 3u16;
        for (k, &extra) in LENGTH_EXTRA.iter().enumerate() {
            let n = if k == 28 { 1 } else { 1u16 << extra };
            for l in base..(base + n).min(259) {
                length_symbol[usize::from(l - 3)] = (257 + k as u16, base);
            }
            base += n;
            if k == 27 {
                base = 258;
            }
        }
        let bits = 16 + r.pos;
        let header = empty[..bits / 8].to_vec();
        let tail = u64::from(empty[bits / 8]) & ((1 << (bits % 8)) - 1);
        let mut f = Format {
            header,
            header_bits: (tail, (bits % 8) as u32),
            code,
            len,
            dist: (reverse(dist_codes[0], dist[0]), dist[0]),
            length_symbol,
            zrun: [(0, 0); ZRUN_MAX as usize + 1],
            sym: vec![0; 1 << 17].try_into().expect("2^17 entries"),
        };
        let mut zrun = [(0, 0); ZRUN_MAX as usize + 1];
        for (z, e) in zrun.iter_mut().enumerate().skip(1) {
            // Room for its bits (at most 8 bytes, checked below): no 64 KiB to grow.
            let mut b = Bits::new(vec![0; 16]);
            b.pos = 0;
            b.zeros_by_symbol(&f, z as u32);
            let (words, total) = b.into_words();
            if total > 56 {
                return None;
            }
            *e = (words[0], total as u32);
        }
        f.zrun = zrun;
        // The symbols' codes.
        let (zc, zl) = f.sym(0);
        let (c, l) = f.sym(285);
        let one = (c | u64::from(f.dist.0) << l, l + u32::from(f.dist.1));
        let mut syms = [(0u64, 0u32); SYMBOLS];
        for (b, e) in syms.iter_mut().take(256).enumerate() {
            *e = f.sym(b);
        }
        syms[usize::from(RUN)..usize::from(MATCH)].copy_from_slice(&f.zrun);
        syms[usize::from(MATCH)] = one;
        for r in 0..258 {
            // A run of `r + 1` zeros is the literal 0, then these bits.
            let (c, l) = f.zrun[r + 1];
            if c & ((1 << zl) - 1) != zc {
                return None;
            }
            syms[usize::from(REST) + r] = (c >> zl, l - zl);
        }
        // Three symbols that can follow each other fit a `put` ([`Bits::code_groups`]).
        // A run of up to `RUN_ONE` zeros (`RUN + z`) is written between literals (a
        // word's, the row's rest, the filter byte of the next row coded by `up_row`) or
        // padding `RUN`s (no bits); a longer one up to `ZRUN_MAX` is `RUN + 1 + 258q`
        // then `REST + r` (or `MATCH`), after a literal and before one; a longer one
        // still is the literal 0, matches and a rest, between literals. So three in a
        // row are at most two runs and a literal, a run, a rest or match and a literal,
        // or three of the literals, matches and rests.
        let most = |r: std::ops::Range<u16>| {
            let r = usize::from(r.start)..usize::from(r.end);
            syms[r].iter().map(|e| e.1).max().unwrap_or(0)
        };
        let lit = most(0..RUN);
        let run = RUN_SYMBOLS[1..]
            .iter()
            .map(|&e| syms[e as u16 as usize].1)
            .max()
            .unwrap_or(0);
        let other = most(MATCH..REST + 258).max(lit);
        if 2 * run + lit > PUT_MAX || run + other + lit > PUT_MAX || 3 * other > PUT_MAX {
            return None;
        }
        for (k, &(c, l)) in syms.iter().enumerate() {
            (f.sym[k], f.sym[(1 << 16) + k]) = (c, u64::from(l));
        }
        Some(f)
    }

    /// The bits of literal (or length symbol) `s`.
    #[inline]
    fn sym(&self, s: usize) -> (u64, u32) {
        (u64::from(self.code[s]), u32::from(self.len[s]))
    }
}

/// Canonical Huffman codes of `lengths` (RFC 1951, 3.2.2), most significant bit first.
fn canonical(lengths: &[u8]) -> Vec<u16> {
    let mut count = [0u16; 16];
    for &l in lengths {
        count[usize::from(l)] += 1;
    }
    count[0] = 0;
    let mut next = [0u16; 16];
    let mut code = 0u16;
    for bits in 1..16 {
        code = (code + count[bits - 1]) << 1;
        next[bits] = code;
    }
    lengths
        .iter()
        .map(|&l| {
            if l == 0 {
                return 0;
            }
            let c = next[usize::from(l)];
            next[usize::from(l)] += 1;
            c
        })
        .collect()
}

/// The low `len` bits of `code`, reversed.
fn reverse(code: u16, len: u8) -> u16 {
    if len == 0 {
        0
    } else {
        code.reverse_bits() >> (16 - u32::from(len))
    }
}

/// Reads a deflate stream's bits, least significant first.
struct BitReader<'a> {
    data: &'a [u8],
    pos: usize,
}

impl BitReader<'_> {
    fn bit(&mut self) -> Option<u32> {
        let b = self.data.get(self.pos / 8)?;
        let v = u32::from(b >> (self.pos % 8) & 1);
        self.pos += 1;
        Some(v)
    }

    fn bits(&mut self, n: u32) -> Option<u32> {
        let mut v = 0;
        for i in 0..n {
            v |= self.bit()? << i;
        }
        Some(v)
    }

    /// A symbol of the canonical code of `lengths` (codes `codes`), read bit by bit.
    fn symbol(&mut self, lengths: &[u8], codes: &[u16]) -> Option<usize> {
        let (mut code, mut len) = (0u16, 0u8);
        while len < 15 {
            code = code << 1 | self.bit()? as u16;
            len += 1;
            if let Some(s) = (0..lengths.len()).find(|&s| lengths[s] == len && codes[s] == code) {
                return Some(s);
            }
        }
        None
    }
}

/// A bit string being written, least significant bit first, into whole bytes.
struct Bits {
    /// The bytes written are `out[..pos]`; the bytes after are room to store into.
    out: Vec<u8>,
    pos: usize,
    /// The bits not yet in `out[..pos]`: fewer than 8 between calls.
    acc: u64,
    n: u32,
}

impl Bits {
    /// A string appended to `out`.
    fn new(out: Vec<u8>) -> Bits {
        Bits {
            pos: out.len(),
            out,
            acc: 0,
            n: 0,
        }
    }

    /// Appends the low `n ≤ PUT_MAX` bits of `bits` (the rest must be zero), without a
    /// branch on the data: the accumulator's 8 bytes are stored each time and the whole
    /// bytes among them kept.
    #[inline(always)]
    fn put(&mut self, bits: u64, n: u32) {
        debug_assert!(n <= PUT_MAX && self.n < 8 && bits.checked_shr(n).unwrap_or(0) == 0);
        if self.out.len() < self.pos + 8 {
            self.grow();
        }
        self.acc |= bits << self.n;
        self.n += n;
        self.out[self.pos..self.pos + 8].copy_from_slice(&self.acc.to_le_bytes());
        let whole = self.n / 8;
        self.pos += whole as usize;
        self.acc >>= 8 * whole;
        self.n -= 8 * whole;
    }

    /// More room after `pos`: 64 KiB more, the buffer's capacity growing as it would by
    /// appending (a page's PNG fits the capacity it is given, sized from the last page's).
    #[cold]
    #[inline(never)]
    fn grow(&mut self) {
        self.out.resize(self.pos + (1 << 16), 0);
    }

    /// Appends `n ≤ 64` bits.
    fn put_long(&mut self, bits: u64, n: u32) {
        if n > 32 {
            self.put(bits & 0xffff_ffff, 32);
            self.put(bits >> 32, n - 32);
        } else {
            self.put(bits, n);
        }
    }

    /// The bytes written, the last partial byte padded with zeros.
    fn into_bytes(mut self) -> Vec<u8> {
        self.out.truncate(self.pos);
        if self.n > 0 {
            self.out.push(self.acc as u8);
        }
        self.out
    }

    /// The string as 64-bit words and its length in bits.
    fn into_words(self) -> (Vec<u64>, u64) {
        let total = self.pos as u64 * 8 + u64::from(self.n);
        let bytes = self.into_bytes();
        let words = bytes
            .chunks(8)
            .map(|c| {
                let mut w = [0u8; 8];
                w[..c.len()].copy_from_slice(c);
                u64::from_le_bytes(w)
            })
            .collect();
        (words, total)
    }

    /// A run of `run ≥ 1` zeros: a literal 0, then distance-1 matches (as `fdeflate`).
    /// Used to make [`Format::zrun`]; [`Bits::zeros`] codes the same bits faster.
    fn zeros_by_symbol(&mut self, f: &Format, mut run: u32) {
        let (dc, dl) = (u64::from(f.dist.0), u32::from(f.dist.1));
        let (zc, zl) = f.sym(0);
        self.put(zc, zl);
        run -= 1;
        let (c, l) = f.sym(285);
        while run >= 258 {
            self.put(c | dc << l, l + dl);
            run -= 258;
        }
        if run > 4 {
            let (sym, base) = f.length_symbol[run as usize - 3];
            let extra = u32::from(LENGTH_EXTRA[usize::from(sym - 257)]);
            let (c, l) = f.sym(usize::from(sym));
            self.put(c, l);
            self.put(u64::from(run - u32::from(base)) | dc << extra, extra + dl);
        } else {
            for _ in 0..run {
                self.put(zc, zl);
            }
        }
    }

    /// A row whose bytes are zero outside the byte ranges `live` (ascending by start,
    /// possibly overlapping), as `fdeflate::Compressor::write_data(row)` encodes it; its
    /// bytes are added to `adler`. The words that meet `live` are read and the inked ones
    /// (not all zero) listed in `words`; then [`Bits::coded`] codes them.
    fn row(
        &mut self,
        f: &Format,
        row: &[u8],
        live: impl Iterator<Item = (usize, usize)>,
        adler: &mut Adler,
        words: &mut RowWords,
    ) {
        // A row of any filter type may begin with a run of zeros, so its symbols are not
        // coded beside another row's ([`RowWords::pending`]): none are pending before it
        // or after it.
        self.flush(f, words);
        let n = row.len() / 8;
        let list = words.begin(n);
        let (mut cnt, mut next) = (0, 0);
        for (s, e) in live {
            let e = e.div_ceil(8).min(n);
            for i in (s / 8).max(next)..e {
                let v = u64::from_le_bytes(row[8 * i..8 * i + 8].try_into().expect("8 bytes"));
                list[cnt] = (i, v);
                cnt += usize::from(v != 0);
            }
            next = next.max(e);
        }
        let rest = &row[8 * n..];
        let mut r = [0u8; 8];
        r[..rest.len()].copy_from_slice(rest);
        self.coded(f, words, n, cnt, (u64::from_le_bytes(r), rest.len()), adler);
        self.flush(f, words);
    }

    /// Codes the symbols left pending ([`RowWords::pending`]), padded with `RUN`s (no
    /// bits) to a whole group: the bits written are then all the rows'.
    fn flush(&mut self, f: &Format, words: &mut RowWords) {
        let p = words.pending;
        if p == 0 {
            return;
        }
        words.syms[p..GROUP].fill(RUN);
        if self.out.len() < self.pos + 72 {
            self.out.resize(self.pos + (1 << 16), 0);
        }
        self.code_groups(f, &words.syms[..GROUP]);
        words.pending = 0;
    }

    /// Codes `syms` (whole groups of [`GROUP`] symbols), twenty-four at a time in eight
    /// `put`s (three codes that can follow each other fit one: checked when the table
    /// is made), with one room check: each store is at most 7 bytes after the one
    /// before (it moves on by the whole bytes of at most 63 bits, `k & 0x38`, so the
    /// compiler sees every offset in the window without a mask). `out` must have room
    /// for their bits and the 72 bytes the stores reach.
    #[inline(always)]
    fn code_groups(&mut self, f: &Format, syms: &[u16]) {
        let (out, tab) = (&mut self.out[..], &f.sym);
        let (mut pos, mut acc, mut nb) = (self.pos, self.acc, self.n);
        for g in syms.chunks_exact(GROUP) {
            let g: &[u16; GROUP] = g.try_into().expect("a group");
            let e = |k: usize| {
                let s = usize::from(g[k]);
                (tab[s], tab[(1 << 16) + s] as u32)
            };
            let win: &mut [u8; 72] = (&mut out[pos..pos + 72]).try_into().expect("room");
            let mut o = 0;
            for h in 0..8 {
                let ((c0, l0), (c1, l1), (c2, l2)) = (e(3 * h), e(3 * h + 1), e(3 * h + 2));
                let l01 = l0 + l1;
                let bits = c0 | c1 << l0 | c2 << l01;
                let x = acc | bits << nb;
                let k = nb + l01 + l2;
                win[o..o + 8].copy_from_slice(&x.to_le_bytes());
                // The whole bytes' bits (`k < 64`: at most 7 bytes): the `h`th store's
                // offset is at most 7h, which the compiler sees (no mask, no check).
                let whole = k & 0x38;
                o += (whole / 8) as usize;
                acc = x >> whole;
                nb = k & 7;
            }
            pos += o;
        }
        (self.pos, self.acc, self.n) = (pos, acc, nb);
    }

    /// A row of `n` whole 8-byte words and then the bytes `rest`, as
    /// `fdeflate::Compressor::write_data(row)` encodes it; its bytes are added to `adler`.
    /// Its inked words are the first `cnt` of `words.list` (index and value, ascending):
    /// every other whole word is zero. The inked words are coded in order (their sums
    /// added), and the zero words between only lengthen the run of zeros, their sums
    /// arithmetic. (Inlined into [`RowDeflate::up_row`]'s two bodies, so that each is
    /// compiled with its own instruction set.)
    #[inline(always)]
    fn coded(
        &mut self,
        f: &Format,
        words: &mut RowWords,
        n: usize,
        cnt: usize,
        (rest, t): (u64, usize),
        adler: &mut Adler,
    ) {
        let RowWords {
            list,
            syms,
            pending,
        } = words;
        let list = &list[..cnt];
        debug_assert!(t < 8 && rest.checked_shr(8 * t as u32).unwrap_or(0) == 0);
        debug_assert!(list.windows(2).all(|w| w[0].0 < w[1].0) && list.iter().all(|w| w.0 < n));
        // Room for the row's symbols after those pending: per word at most a long run (a
        // literal 0, its matches — fewer than one per 32 words of zeros — and its rest),
        // two run symbols and 8 literals, then the row's last run and its rest, the
        // symbols a word's stores reach past its own, and a group moved to the start.
        let room = *pending + 12 * n + 72 + GROUP;
        // (A row taken in lanes has room in the first `LANE_SYMS`: see there.)
        let room = room.max(LANE_SYMS + 16);
        if syms.len() < room {
            syms.resize(room, 0);
        }
        let syms = &mut syms[..];
        let len = 8 * n + t;
        // Adler-32 of the row after sums `(a₀, b₀)`: `a = a₀ + Σ xₚ` and
        // `b = b₀ + len·a₀ + Σ (len − p)·xₚ` over the row's bytes `xₚ`, so each word adds
        // its own terms, independent of the others ([`word_symbols`]).
        let r = len as u64;
        let (a, b) = (u64::from(adler.a), u64::from(adler.b));
        // Below 2^33, reduced at the row's end (a row in lanes is shorter than
        // `ADLER_MOD`: its length needs no reduction).
        const _: () = assert!((LANE_ROW as u64) < ADLER_MOD);
        // First the row as symbols: the pending run of zeros starts at byte `zero` (the
        // bytes before it are written) and the symbols are `syms[..p]`. The words' sums
        // in 16-bit lanes when the weights `len − p` fit them.
        let (mut p, zero, mut a, mut b) = if len <= LANE_ROW {
            word_symbols::<true>(list, syms, *pending, r, (a, b + r * a))
        } else {
            let b = b + (r % ADLER_MOD) * a;
            word_symbols::<false>(list, syms, *pending, r, (a, b))
        };
        let run = (8 * n - zero) as u32;
        p = if run > ZRUN_MAX {
            long_run(syms, p, run)
        } else {
            let e = RUN_SYMBOLS[run as usize];
            (syms[p], syms[p + 1]) = (e as u16, (e >> 16) as u16);
            p + (e >> 62) as usize
        };
        // The rest, each byte a literal (zeros too); its bytes at `p = 8n + k` add
        // `(len − p)·x = (t − k)·x` to `b`.
        let win: &mut [u16; 8] = (&mut syms[p..p + 8]).try_into().expect("room");
        win.copy_from_slice(&literals(rest));
        p += t;
        let (sum, weighted) = word_sums(rest);
        a += sum;
        b += weighted - (8 - t as u64) * sum;
        (adler.a, adler.b) = ((a % ADLER_MOD) as u32, (b % ADLER_MOD) as u32);
        // Then the row's whole groups of symbols coded ([`Bits::code_groups`]), and the
        // symbols after them moved to the start, pending: the next row's follow them (a
        // row coded by [`RowDeflate::up_row`] begins with its filter byte's literal), so no
        // row's symbols are padded. Room for the row's bits: at most 12 a byte (a
        // literal's; a run of zeros takes fewer), the bits pending, the symbols pending
        // (at most 8 `put`s) and the 72 bytes the stores reach.
        let room = self.pos + 2 * len + 64 + 64 + 72;
        if self.out.len() < room {
            self.out.resize(room.max(self.pos + (1 << 16)), 0);
        }
        let done = GROUP * (p / GROUP);
        self.code_groups(f, &syms[..done]);
        // (A whole group moved, the same few stores whatever the count.)
        let left: [u16; GROUP] = syms[done..done + GROUP].try_into().expect("room");
        syms[..GROUP].copy_from_slice(&left);
        *pending = p - done;
    }
}

/// The longest row whose Adler-32 weights `len − p` (at most `len`) [`word_symbols`]
/// takes in 16-bit lanes.
const LANE_ROW: usize = i16::MAX as usize;

/// The symbols of a row of at most [`LANE_ROW`] bytes (and those pending before it)
/// are all below this place ([`word_symbols`]).
const LANE_SYMS: usize = 1 << 16;
const _: () = assert!(12 * LANE_ROW.div_ceil(8) + 72 + 2 * GROUP <= LANE_SYMS);

/// The offsets `j` of a word's bytes `j = 0..8` from its first.
const RAMP: [u64; 8] = [0, 1, 2, 3, 4, 5, 6, 7];

/// The inked words `list` (index and value, in order) of a row of `r` bytes as symbols
/// in `syms` from `p` on ([`Bits::coded`]), and their bytes added to the Adler-32 sums
/// `(a, b)` as `a += Σ xₚ`, `b += Σ (r − p)·xₚ` (the byte `xₚ` at `p`). Gives the end of
/// the symbols, the end of the last word's ink (where the pending run of zeros starts)
/// and the sums, not reduced (below 2^40, from `a` below 2^16 and `b` below 2^33).
///
/// With `LANES` (rows of at most [`LANE_ROW`] bytes) a word's sums are taken from its
/// literals' 16-bit lanes, the ones the symbols are stored from, its literals starting
/// at `q` (`q + j` for lane `j`, `q < r ≤ 2^15 − 1`, an `i16`): `a`'s lanes add the bytes
/// and `b`'s multiply them by `q` and add them in pairs into 32-bit lanes. Every 64
/// words they are added up: `Σ xₚ` is `a`'s lanes' sum `A`, and `Σ (r − p)·xₚ` is
/// `r·A − P − Σ j·aⱼ` (`P` the sum of `b`'s lanes, `aⱼ` `a`'s lane `j`), a number at least
/// 0 taken in wrapping `u64` arithmetic. A lane of `a` holds at most 64·255 = 16,320
/// (below 2^15) and one of `b` at most 64·2·255·(2^15 − 1) = 1,069,515,840 (below
/// 2^31), all of them at least 0. Each 64 words add less than 2^17 to `a` and 2^33 to
/// `b` (the bytes past a word's ink, whose weights `r − p` may be below 0, are zeros),
/// and a row has at most 64 times 64 words: the sums are left for the row's end to
/// reduce. Without lanes, each word's sums are
/// taken in a `u64` ([`word_sums`]) and reduced every 64 words: `b` grows by at most
/// 64·(r·2040 + 2040) between reductions.
#[inline(always)]
fn word_symbols<const LANES: bool>(
    list: &[(usize, u64)],
    syms: &mut [u16],
    p: usize,
    r: u64,
    (mut a, mut b): (u64, u64),
) -> (usize, usize, u64, u64) {
    let (mut zero, mut p) = (0usize, p);
    // A row in lanes (at most `LANE_ROW` bytes: fewer than 2^12 words) has its symbols
    // in the first `LANE_SYMS` (at most 12 a word and 72 + `GROUP` more, with those
    // pending): a word's window is masked to them, which changes nothing and lets the
    // compiler drop its bounds checks (with the room checked here once).
    assert!(
        !LANES || syms.len() >= LANE_SYMS + 16,
        "room for a row's symbols"
    );
    for part in list.chunks(64) {
        let (mut la, mut lb) = (i16x8::ZERO, i32x4::ZERO);
        for &(i, v) in part {
            // A pending run of zeros takes the word's leading zero bytes, the bytes up
            // to its trailing zeros are literals, and the trailing zeros start the next
            // run. No branch on the bytes (only runs longer than `ZRUN_MAX` take the
            // long way): the run is one symbol (none when the run is empty), and the
            // literals are the word shifted down past the run's bytes, all 8 stored as
            // symbols, of which the `c` that are the word's are kept. (A run longer than
            // `RUN_ONE` is two symbols: [`RUN_SYMBOLS`].)
            let run = (8 * i - zero) as u32;
            let (lead, tail) = (v.trailing_zeros() / 8, v.leading_zeros() / 8);
            let from = if run > 0 { lead } else { 0 };
            let z = run + from;
            let c = 8 - tail - from;
            let u = v >> (8 * from);
            zero = 8 * i + 8 - tail as usize;
            let z = if z > ZRUN_MAX {
                p = long_run(syms, p, z);
                0
            } else {
                z
            };
            // The run's symbols (none if the run is empty), then the literals after them.
            let e = RUN_SYMBOLS[z as usize];
            let has = (e >> 62) as usize;
            let lits = i16x8::from_u8x16_low(u8x16::new(u128::from(u).to_le_bytes()));
            let at = if LANES { p & (LANE_SYMS - 1) } else { p };
            let win: &mut [u16; 11] = (&mut syms[at..at + 11]).try_into().expect("room");
            (win[0], win[1]) = (e as u16, (e >> 16) as u16);
            win[has..has + 8].copy_from_slice(&lits.to_array().map(|x| x as u16));
            p += has + c as usize;
            if LANES {
                // The literals' first byte is at `q = 8i + from`; the rest of each
                // byte's weight `r − q − j` is taken every 64 words.
                let q = (8 * i) as i16 + from as i16;
                la += lits;
                lb += lits.dot(i16x8::splat(q));
            } else {
                let (sum, weighted) = word_sums(v);
                a += sum;
                b += (r - 8 - 8 * i as u64) * sum + weighted;
            }
        }
        if LANES {
            // Every lane as the unsigned number it is (at least 0, below 2^31).
            let la = la.to_array().map(|x| u64::from(x as u16));
            let sum: u64 = la.iter().sum();
            let ramp: u64 = la.iter().zip(RAMP).map(|(&x, j)| j * x).sum();
            let firsts: u64 = lb.to_array().iter().map(|&x| u64::from(x as u32)).sum();
            a += sum;
            b = b.wrapping_add((r * sum).wrapping_sub(firsts).wrapping_sub(ramp));
        }
        if !LANES {
            (a, b) = (a % ADLER_MOD, b % ADLER_MOD);
        }
    }
    (p, zero, a, b)
}

/// The eight bytes of `x` (the first in the low byte) as eight literal symbols.
#[inline(always)]
fn literals(x: u64) -> [u16; 8] {
    u16x8::from_u8x16_low(u8x16::new(u128::from(x).to_le_bytes())).to_array()
}

/// A run of `z ≥ 1` zeros as symbols at `p` in `syms` (the literal 0, a match per
/// whole 258 after it, and the rest; see [`RUN`]); gives the position after them.
#[cold]
#[inline(never)]
fn long_run(syms: &mut [u16], mut p: usize, z: u32) -> usize {
    let (q, r) = ((z - 1) / 258, (z - 1) % 258);
    let mut put = |s: u16| {
        syms[p] = s;
        p += 1;
    };
    put(0);
    for _ in 0..q {
        put(MATCH);
    }
    put(REST + r as u16);
    p
}

/// The inked (not all zero) whole 8-byte words of the row being coded, and its symbols.
#[derive(Default)]
pub(crate) struct RowWords {
    /// `(index, value)` of the inked words, in order (the entries after them are
    /// scratch: a word is stored, then kept if it is inked).
    list: Vec<(usize, u64)>,
    /// The row's symbols ([`RUN`]).
    syms: Vec<u16>,
    /// The symbols at the start of `syms` not yet coded (fewer than a [`GROUP`]): the
    /// end of the rows coded before, to be coded with the next row's symbols, or
    /// padded ([`Bits::flush`]) before any other bits are written.
    pending: usize,
}

impl RowWords {
    /// Room for the inked words of a row of `n` whole words.
    fn begin(&mut self, n: usize) -> &mut [(usize, u64)] {
        if self.list.len() < n {
            self.list.resize(n, (0, 0));
        }
        &mut self.list[..n]
    }
}

/// `a − b` byte by byte (wrapping), of two words as they are stored (the first byte
/// first): each read straight into the low half of a vector, then one vector
/// subtraction of bytes (where the same in one `u64`, a byte's borrow kept from the
/// next by the top bits, took eight instructions, and a word read into a register
/// first took two more moves).
#[inline(always)]
fn sub_bytes(a: &[u8; 8], b: &[u8; 8]) -> u64 {
    let v = |x: &[u8; 8]| {
        let mut y = [0u8; 16];
        y[..8].copy_from_slice(x);
        u8x16::new(y)
    };
    u128::from_le_bytes((v(a) - v(b)).to_array()) as u64
}

/// The sums of an 8-byte word's bytes `x₀..x₇` (`x₀` first in the row) that Adler-32
/// adds: `Σ xᵢ` to `a`, and `Σ (8 − i)·xᵢ` to `b` (beside `8·a`). In 16-bit lanes: the
/// lane products stay below 2^16 (at most 255·20), so no carry crosses a lane.
#[inline(always)]
fn word_sums(v: u64) -> (u64, u64) {
    const LANES: u64 = 0x00ff_00ff_00ff_00ff;
    let (even, odd) = (v & LANES, v >> 8 & LANES);
    // Lane k of `even` holds x_{2k}, of `odd` x_{2k+1}; multiplying by
    // Σ c_k·2^{16k} puts Σ_k lane_k·c_{3−k} in the top lane.
    let sum = (even + odd).wrapping_mul(0x0001_0001_0001_0001) >> 48;
    let weighted = (even.wrapping_mul(0x0008_0006_0004_0002) >> 48)
        + (odd.wrapping_mul(0x0007_0005_0003_0001) >> 48);
    (sum, weighted)
}

/// Adler-32 of a stream, zeros added without reading them: the sums `(a, b)` kept as
/// they are (an inked row is a few short spans between zeros, which the vectorised
/// checksum took longer to set up and leave than to sum).
struct Adler {
    a: u32,
    b: u32,
}

/// Spans this long and longer are summed by `simd_adler32`, shorter ones here.
const ADLER_SHORT: usize = 64;

impl Adler {
    fn new() -> Adler {
        Adler { a: 1, b: 0 }
    }

    fn bytes(&mut self, data: &[u8]) {
        if data.len() >= ADLER_SHORT {
            let mut h = simd_adler32::Adler32::from_checksum(self.finish());
            h.write(data);
            let c = h.finish();
            (self.a, self.b) = (c & 0xffff, c >> 16);
            return;
        }
        // Below 64 bytes the sums stay far below 2^32: 65520 + 64·255 and
        // 65520 + 64·(65520 + 64·255).
        let (mut a, mut b) = (self.a, self.b);
        for &x in data {
            a += u32::from(x);
            b += a;
        }
        (self.a, self.b) = (a % ADLER_MOD as u32, b % ADLER_MOD as u32);
    }

    /// `zeros` zero bytes.
    fn zeros(&mut self, zeros: usize) {
        if zeros == 0 {
            return;
        }
        let (a, b) = (u64::from(self.a), u64::from(self.b));
        self.b = ((b + (zeros as u64 % ADLER_MOD) * a) % ADLER_MOD) as u32;
    }

    fn finish(&self) -> u32 {
        self.b << 16 | self.a
    }
}

/// A zlib stream of PNG rows, the bytes `fdeflate::Compressor` makes of them, appended to
/// a buffer.
pub(crate) struct RowDeflate {
    f: &'static Format,
    bits: Bits,
    adler: Adler,
    /// The whole words of the row being coded.
    words: RowWords,
    /// The bits of a blank row of `blank.0` bytes (filter type `blank.1`).
    blank: Option<(usize, u8, Vec<u64>, u64)>,
    /// Whether [`RowDeflate::up_row`] runs its body compiled for AVX2, BMI1, BMI2 and
    /// LZCNT ([`x86_fast`](crate::cpu::x86_fast)): found once per stream. The same
    /// integer operations either way, so the same bytes: the features only let the
    /// compiler use three-operand shifts by a variable count (`shlx`, `shrx`: the
    /// coder's), `tzcnt`/`lzcnt` (a word's zero bytes) and VEX-coded vectors.
    fast: bool,
}

impl RowDeflate {
    /// A stream appended to `out`.
    #[cfg(test)]
    pub(crate) fn new(out: Vec<u8>) -> RowDeflate {
        let pos = out.len();
        RowDeflate::at(out, pos)
    }

    /// A stream written into `out` from byte `pos ≤ out.len()` on: the bytes from `pos`
    /// on are only room to write into, whatever they hold (a buffer of an earlier page,
    /// not zeroed again), and [`RowDeflate::finish`] gives `out` cut after the stream.
    pub(crate) fn at(mut out: Vec<u8>, pos: usize) -> RowDeflate {
        let f = Format::get();
        let end = pos + f.header.len();
        if out.len() < end {
            out.resize(end, 0);
        }
        out[pos..end].copy_from_slice(&f.header);
        let mut bits = Bits {
            out,
            pos: end,
            acc: 0,
            n: 0,
        };
        bits.put(f.header_bits.0, f.header_bits.1);
        RowDeflate {
            f,
            bits,
            adler: Adler::new(),
            words: WORDS.take().unwrap_or_default(),
            blank: None,
            fast: crate::cpu::x86_fast(),
        }
    }

    /// A row (its filter byte first) whose bytes are zero outside the byte ranges `live`
    /// (ascending; the filter byte is always read).
    pub(crate) fn row(&mut self, row: &[u8], live: impl Iterator<Item = (usize, usize)>) {
        let live = std::iter::once((0, 1)).chain(live);
        self.bits
            .row(self.f, row, live, &mut self.adler, &mut self.words);
    }

    /// The row, after rows before it, of a page of ink coverage written as gray (255 −
    /// ink) with the Up filter: the filter byte 2, then `above[x] − this[x]` (the gray
    /// of the pixel minus the gray above it) for every pixel `x`, the same bits as
    /// [`RowDeflate::row`] of that row. `marks` are the 8-pixel blocks (a bit per block,
    /// block `k` being pixels `8k..8k + 8`, 64 to a word) of the two rows that may hold
    /// ink: outside them both rows are 0 and so are the filtered bytes. Only the filtered
    /// row's whole words that meet a marked block (and the first, which holds the filter
    /// byte, and the bytes after the last whole word) are computed, eight bytes at once,
    /// and no filtered row is stored: the words go straight to the coder.
    ///
    /// Where the processor has AVX2 and BMI ([`x86_fast`](crate::cpu::x86_fast)) the same code compiled for
    /// them runs instead: the same bytes.
    pub(crate) fn up_row(
        &mut self,
        above: &mut [u8],
        this: &[u8],
        marks: (&[u64], &[u64]),
        clear: bool,
    ) {
        #[cfg(target_arch = "x86_64")]
        if self.fast {
            // SAFETY: `up_row_avx2` needs AVX2, BMI1, BMI2 and LZCNT, which the processor
            // was found to have when the stream began (`x86_fast`); it has no other
            // requirement (it is the safe `up_row_body` compiled for them).
            #[allow(unsafe_code)]
            unsafe {
                self.up_row_avx2(above, this, marks, clear)
            };
            return;
        }
        self.up_row_body(above, this, marks, clear);
    }

    /// [`RowDeflate::up_row_body`] compiled for AVX2 and BMI (called only where the
    /// processor has them).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,bmi1,bmi2,lzcnt")]
    fn up_row_avx2(&mut self, above: &mut [u8], this: &[u8], marks: (&[u64], &[u64]), clear: bool) {
        self.up_row_body(above, this, marks, clear);
    }

    /// [`RowDeflate::up_row`] itself, the row filtered and coded; inlined into each of
    /// its two callers so that each is compiled for its own instruction set.
    #[inline(always)]
    fn up_row_body(&mut self, above: &mut [u8], this: &[u8], marks: (&[u64], &[u64]), clear: bool) {
        const UP: u8 = 2;
        let w = this.len();
        assert_eq!(above.len(), w, "rows of one width");
        fn word(row: &[u8], s: usize) -> &[u8; 8] {
            row[s..].first_chunk().expect("8 bytes")
        }
        // The row is `w + 1` bytes: `n` whole words, then `t < 8` bytes, `rest`.
        let n = (w + 1) / 8;
        let list = self.words.begin(n);
        // The inked words are `list[..cnt]`: each candidate word is stored at `cnt`, which
        // then moves on if it is not zero.
        let mut cnt = 0;
        let (rest, t) = if w < 8 {
            // Word 0 (if whole) and the rest, byte by byte.
            let mut v = u64::from(UP);
            for x in 0..w {
                v |= u64::from(above[x].wrapping_sub(this[x])) << (8 * (x + 1));
            }
            if clear {
                above.fill(0);
            }
            if n == 1 {
                (list[0], cnt) = ((0, v), 1);
                (0, 0)
            } else {
                (v, w + 1)
            }
        } else {
            // Word 0: the filter byte, then pixels 0..7 (pixel 7 is word 1's).
            list[0] = (
                0,
                sub_bytes(word(above, 0), word(this, 0)) << 8 | u64::from(UP),
            );
            cnt = 1;
            if clear {
                above[..7].copy_from_slice(&[0; 7]);
            }
            // Word `i ≥ 1` is pixels `8i − 1..8i + 7`: blocks `i − 1` and `i`. The words
            // are apart, so the row above can be cleared as it is read.
            // The two rows' mark words taken together (one bounds check for all), word 0
            // (done above) left out of the first and the words past `n` out of the last.
            let (ma, mb) = marks;
            let last = n.div_ceil(64) - 1;
            let tail = u64::MAX >> ((64 - n % 64) % 64);
            let (mut carry, mut first) = (0, !1u64);
            for (k, (&a, &b)) in ma[..=last].iter().zip(&mb[..=last]).enumerate() {
                let m = a | b;
                let mut c = (m | m << 1 | carry) & first;
                (carry, first) = (m >> 63, u64::MAX);
                if k == last {
                    c &= tail;
                }
                while c != 0 {
                    let i = 64 * k + c.trailing_zeros() as usize;
                    c &= c - 1;
                    // Never past `w − 8` (`i < n`, so `8i + 7 ≤ 8n − 1 ≤ w`): saying so
                    // lets the compiler drop the reads' bounds checks.
                    let s = (8 * i - 1).min(w - 8);
                    // The word above, read then cleared, and this row's: `s` in the row,
                    // then 8 bytes from there (no sum to overflow).
                    let up = above[s..].first_chunk_mut::<8>().expect("8 bytes");
                    let th = this[s..].first_chunk::<8>().expect("8 bytes");
                    let v = sub_bytes(up, th);
                    if clear {
                        *up = [0; 8];
                    }
                    list[cnt] = (i, v);
                    cnt += usize::from(v != 0);
                }
            }
            // The rest: pixels `8n − 1..w`, the last `t` of the row's last 8.
            let t = w + 1 - 8 * n;
            let v = sub_bytes(word(above, w - 8), word(this, w - 8));
            if clear {
                // The last `t` bytes cleared in the last 8 (one store, not a fill).
                let end = above[w - 8..].first_chunk_mut::<8>().expect("8 bytes");
                *end = (u64::from_le_bytes(*end) & u64::MAX >> (8 * t)).to_le_bytes();
            }
            (v.checked_shr(8 * (8 - t) as u32).unwrap_or(0), t)
        };
        self.bits
            .coded(self.f, &mut self.words, n, cnt, (rest, t), &mut self.adler);
    }

    /// `count` blank rows of `len` bytes: filter type `filter`, then zeros.
    pub(crate) fn blank_rows(&mut self, len: usize, filter: u8, count: usize) {
        if len == 0 || count == 0 {
            return;
        }
        let f = self.f;
        self.bits.flush(f, &mut self.words);
        let fresh = !matches!(&self.blank, Some((l, t, ..)) if *l == len && *t == filter);
        if fresh {
            let mut row = vec![0u8; len];
            row[0] = filter;
            // (Coded with the stream's own room: nothing is pending after the flush
            // above, nor after the row.)
            let mut b = Bits::new(Vec::new());
            b.row(
                f,
                &row,
                std::iter::once((0, 1)),
                &mut Adler::new(),
                &mut self.words,
            );
            let (words, total) = b.into_words();
            self.blank = Some((len, filter, words, total));
        }
        let Some((_, _, words, total)) = &self.blank else {
            unreachable!("made above")
        };
        let full = (*total / 64) as usize;
        let rest = (*total % 64) as u32;
        for _ in 0..count {
            for &w in &words[..full] {
                self.bits.put_long(w, 64);
            }
            if rest > 0 {
                self.bits.put_long(words[full], rest);
            }
            self.adler.bytes(&[filter]);
            self.adler.zeros(len - 1);
        }
    }

    /// Ends the stream (end of block, padding, Adler-32) and gives the buffer back.
    pub(crate) fn finish(mut self) -> Vec<u8> {
        self.bits.flush(self.f, &mut self.words);
        let (c, l) = self.f.sym(256);
        self.bits.put(c, l);
        let mut out = self.bits.into_bytes();
        out.extend_from_slice(&self.adler.finish().to_be_bytes());
        // Nothing pending: the next stream made on this thread takes the room as it is.
        WORDS.set(Some(self.words));
        out
    }
}

thread_local! {
    /// The room for the rows' words and symbols ([`RowWords`]) of the last stream
    /// finished on the thread (a row in lanes takes [`LANE_SYMS`] symbols' room), for
    /// the next: made and zeroed once per thread, not once per page.
    static WORDS: std::cell::Cell<Option<RowWords>> = const { std::cell::Cell::new(None) };
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `fdeflate`'s stream of `rows` (one `write_data` each).
    fn reference(rows: &[Vec<u8>]) -> Vec<u8> {
        let mut z = fdeflate::Compressor::new(Vec::new()).unwrap();
        for r in rows {
            z.write_data(r).unwrap();
        }
        z.finish().unwrap()
    }

    /// A small deterministic generator.
    /// The PNG rows (filter byte 2, Up) of an ink layer `w` by `h` as the page stores it
    /// (0 = paper): each byte the ink above minus its own, the first row against zero.
    fn up_rows(ink: &[u8], w: usize, h: usize) -> Vec<Vec<u8>> {
        (0..h)
            .map(|j| {
                let mut row = vec![2u8; w + 1];
                for x in 0..w {
                    let above = if j == 0 { 0 } else { ink[(j - 1) * w + x] };
                    row[1 + x] = above.wrapping_sub(ink[j * w + x]);
                }
                row
            })
            .collect()
    }

    fn lcg(s: &mut u64) -> u64 {
        *s = s
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        *s >> 33
    }

    /// Rows with ink in a few spans (zero elsewhere), blank rows and full rows of every
    /// kind of byte: the stream is `fdeflate`'s, byte for byte, and inflates to the rows.
    /// The sums kept by hand are `simd_adler32`'s checksum of the same bytes: short and
    /// long spans of every value, runs of zeros shorter and longer than the modulus.
    #[test]
    fn adler_is_the_checksum_of_the_bytes() {
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut rand = |n: u64| {
            seed = crate::xorshift(seed);
            seed % n
        };
        for _ in 0..200 {
            let (mut ours, mut all) = (Adler::new(), Vec::new());
            for _ in 0..rand(40) {
                if rand(2) == 0 {
                    let n = [rand(8), rand(64), 63, 64, 65, rand(3000)][rand(6) as usize];
                    let v: Vec<u8> = (0..n)
                        .map(|_| if rand(3) == 0 { 255 } else { rand(256) as u8 })
                        .collect();
                    ours.bytes(&v);
                    all.extend_from_slice(&v);
                } else {
                    let n = [rand(20), rand(6000), 65_521, 70_000 + rand(9)][rand(4) as usize];
                    ours.zeros(n as usize);
                    all.resize(all.len() + n as usize, 0);
                }
            }
            let mut want = simd_adler32::Adler32::new();
            want.write(&all);
            assert_eq!(ours.finish(), want.finish());
        }
    }

    #[test]
    fn rows_make_fdeflates_stream_byte_for_byte() {
        let mut seed = 7u64;
        for width in [1usize, 5, 7, 8, 9, 15, 16, 17, 100, 257, 600, 1000, 3301] {
            let mut rows = Vec::new();
            let mut z = RowDeflate::new(Vec::new());
            for j in 0..40 {
                let mut row = vec![0u8; width + 1];
                row[0] = 2;
                match j % 5 {
                    // Blank rows, one or several.
                    0 | 1 => {
                        z.blank_rows(width + 1, 2, 1);
                        rows.push(row);
                        continue;
                    }
                    // Every byte set at random, zero runs of every length included.
                    2 => {
                        for b in &mut row[1..] {
                            let r = lcg(&mut seed);
                            *b = if r % 3 == 0 { 0 } else { (r >> 8) as u8 };
                        }
                        let all = [(0, width + 1)];
                        z.row(&row, all.iter().copied());
                    }
                    // Ink in spans, possibly touching, at any byte offset.
                    _ => {
                        let mut spans = Vec::new();
                        let mut x = (lcg(&mut seed) % 40) as usize + 1;
                        while x < width + 1 {
                            let e = (x + (lcg(&mut seed) % 60) as usize + 1).min(width + 1);
                            for b in &mut row[x..e] {
                                let r = lcg(&mut seed);
                                *b = if r % 4 == 0 { 0 } else { (r >> 5) as u8 | 1 };
                            }
                            spans.push((x, e));
                            x = e + (lcg(&mut seed) % 300) as usize;
                        }
                        z.row(&row, spans.iter().copied());
                    }
                }
                rows.push(row);
            }
            z.blank_rows(width + 1, 2, 3);
            rows.extend(std::iter::repeat_n(
                {
                    let mut r = vec![0u8; width + 1];
                    r[0] = 2;
                    r
                },
                3,
            ));
            let got = z.finish();
            assert!(got == reference(&rows), "width {width}: streams differ");
            let back = fdeflate::decompress_to_vec(&got).unwrap();
            assert_eq!(back, rows.concat(), "width {width}");
        }
    }

    /// Rows as a page's are (sparse ink: a few bytes, often one, at any offset within
    /// their words, in spans far apart), some longer than 4096 words: runs of zeros of
    /// every length around the table's end and 258's multiples, zero words inside the
    /// spans, spans that overlap or hold no ink. Each stream is `fdeflate`'s.
    #[test]
    fn sparse_and_long_rows_match() {
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        for width in [16usize, 63, 64, 520, 3301, 40_001] {
            let mut rows = Vec::new();
            let mut z = RowDeflate::new(Vec::new());
            for j in 0..60 {
                let mut row = vec![0u8; width];
                row[0] = if j % 7 == 3 { 0 } else { 2 };
                let mut spans = Vec::new();
                let mut x = (lcg(&mut seed) % 600) as usize;
                while x < width {
                    let len = [1, 2, 8, 9, 17, 64, 300][(lcg(&mut seed) % 7) as usize];
                    let e = (x + len).min(width);
                    for b in &mut row[x..e] {
                        if lcg(&mut seed) % 3 == 0 {
                            *b = (lcg(&mut seed) % 255) as u8 + 1;
                        }
                    }
                    spans.push((x, e));
                    if lcg(&mut seed) % 5 == 0 {
                        // An overlapping span.
                        spans.push((x.saturating_sub(3), e));
                    }
                    let gap = [0, 1, 7, 250, 259, 260, 517, 1100, 5000];
                    x = e + gap[(lcg(&mut seed) % 9) as usize];
                }
                spans.sort_unstable();
                z.row(&row, spans.iter().copied());
                rows.push(row);
            }
            let got = z.finish();
            assert!(got == reference(&rows), "width {width}: streams differ");
        }
    }

    /// Every pair of bytes, at even and odd offsets within the row's words, written as
    /// literals (zeros inside a word included): each is coded as `fdeflate` codes it.
    #[test]
    fn every_byte_pair_matches() {
        let all: Vec<u8> = (0..1usize << 16)
            .flat_map(|i| [(i & 0xff) as u8, (i >> 8) as u8])
            .collect();
        for lead in 0..3 {
            let mut row = vec![4u8; 1 + lead];
            row.extend_from_slice(&all);
            let mut z = RowDeflate::new(Vec::new());
            z.row(&row, std::iter::once((0, row.len())));
            assert!(
                z.finish() == reference(&[row]),
                "lead {lead}: streams differ"
            );
        }
    }

    /// `sub_bytes` is the byte-wise wrapping difference for every pair of bytes, in
    /// every byte of the word.
    #[test]
    fn sub_bytes_is_the_difference_of_every_byte_pair() {
        for a in 0..=255u8 {
            for b in 0..=255u8 {
                let d = a.wrapping_sub(b);
                for lane in 0..8 {
                    // The other lanes hold other pairs, so a borrow would show.
                    let (x, y) = (0x00ff_7f80_01fe_ff00u64, 0xff00_807f_fe01_00ffu64);
                    let (mx, my) = (!(0xffu64 << (8 * lane)), 8 * lane);
                    let (x, y) = (x & mx | u64::from(a) << my, y & mx | u64::from(b) << my);
                    let got = sub_bytes(&x.to_le_bytes(), &y.to_le_bytes());
                    assert_eq!((got >> my) as u8, d, "{a} − {b} in lane {lane}");
                    for o in (0..8).filter(|&o| o != lane) {
                        let (xo, yo) = ((x >> (8 * o)) as u8, (y >> (8 * o)) as u8);
                        assert_eq!((got >> (8 * o)) as u8, xo.wrapping_sub(yo));
                    }
                }
            }
        }
    }

    /// Pages of ink in marked blocks only (some marked blocks blank, ink at the row's
    /// start and in the bytes after its last whole word, blocks marked in one row of a
    /// pair only): the rows coded by `up_row` from the ink and the marks are `fdeflate`'s
    /// stream of the whole Up-filtered gray rows, byte for byte, and `clear_row` leaves
    /// every row blank.
    #[test]
    fn up_rows_from_the_marks_are_fdeflates_stream() {
        use crate::dirty::{BLOCK, Dirty};
        let mut seed = 0x51_7cc1_b727_220au64;
        let widths = [
            1usize, 2, 6, 7, 8, 9, 14, 15, 16, 17, 23, 63, 64, 65, 511, 512, 513,
        ];
        for w in widths
            .into_iter()
            .chain([520, 1000, 1001, 3300, 3301, 5100])
        {
            let h = 24;
            let mut ink = vec![0u8; w * h];
            let mut dirty = Dirty::new(w, h);
            let blocks = w.div_ceil(BLOCK);
            for j in 0..h {
                if j % 5 == 4 {
                    continue; // a blank row
                }
                for _ in 0..1 + lcg(&mut seed) % 6 {
                    // The first and last blocks, and the last of a word of marks
                    // (its last pixel is in the next word of marks' first row word).
                    let k = match lcg(&mut seed) % 5 {
                        0 => 0,
                        1 => blocks - 1,
                        2 => 63 % blocks,
                        _ => (lcg(&mut seed) as usize) % blocks,
                    };
                    let run = 1 + (lcg(&mut seed) as usize) % 3;
                    let (x0, x1) = (BLOCK * k, (BLOCK * (k + run)).min(w));
                    dirty.mark_px(x0, j, x1, j + 1);
                    if lcg(&mut seed) % 4 != 0 {
                        // The block's last pixel, in the row word after the block's.
                        ink[j * w + (BLOCK * k + BLOCK - 1).min(w - 1)] = 9;
                        for x in x0..x1 {
                            if lcg(&mut seed) % 3 != 0 {
                                ink[j * w + x] = (lcg(&mut seed) % 256) as u8;
                            }
                        }
                    }
                }
            }
            let rows = up_rows(&ink, w, h);
            // The encoder clears the row above as it reads it, or `clear_row` after.
            let clear = w % 2 == 1;
            let mut z = RowDeflate::new(Vec::new());
            z.row(&rows[0], std::iter::once((0, w + 1)));
            for j in 1..h {
                let (above, this) = ink[(j - 1) * w..(j + 1) * w].split_at_mut(w);
                z.up_row(above, this, dirty.row_pair_words(j), clear);
                if !clear {
                    dirty.clear_row(j - 1, above);
                }
            }
            dirty.clear_row(h - 1, &mut ink[(h - 1) * w..]);
            assert!(z.finish() == reference(&rows), "width {w}: streams differ");
            assert!(ink.iter().all(|&x| x == 0), "width {w}: left blank");
        }
    }

    /// Runs of zeros of every length up to past `258·8` (up to 9 matches), between inked words, at
    /// the start and at the end of rows: each coded as `fdeflate` codes it.
    #[test]
    fn runs_of_every_length_match() {
        let mut rows = Vec::new();
        let mut z = RowDeflate::new(Vec::new());
        for run in 1..258 * 8 + 300 {
            let mut row = vec![0u8; 16 + run + 9];
            row[0] = 2;
            row[15] = 7;
            row[16 + run] = 200;
            z.row(&row, [(0, 16), (16 + run, 17 + run)].into_iter());
            rows.push(row);
            let mut row = vec![0u8; 1 + run];
            row[0] = 1;
            z.row(&row, std::iter::empty());
            rows.push(row);
        }
        assert!(z.finish() == reference(&rows), "streams differ");
    }

    /// Rows at the lanes' limit ([`LANE_ROW`] bytes, one less and one more: the sums in
    /// lanes and in a `u64`) and around zlib's 5,552-byte block: every byte 255 (the
    /// largest sums a lane holds), and words of random bytes between zero words. The
    /// streams, their Adler-32 included, are `fdeflate`'s.
    #[test]
    fn rows_at_the_lane_limit_match() {
        let mut seed = 0x2b99_2ddf_a232_49d6u64;
        let mut rows = Vec::new();
        let mut z = RowDeflate::new(Vec::new());
        for len in [5551, 5552, 5553, LANE_ROW - 1, LANE_ROW, LANE_ROW + 1] {
            let full = vec![255u8; len];
            z.row(&full, std::iter::once((0, len)));
            rows.push(full);
            let mut mixed = vec![0u8; len];
            for (k, b) in mixed.iter_mut().enumerate() {
                let r = lcg(&mut seed);
                if (k / 8) % 5 != 0 && r % 4 != 0 {
                    *b = (r >> 8) as u8;
                }
            }
            z.row(&mixed, std::iter::once((0, len)));
            rows.push(mixed);
        }
        assert!(z.finish() == reference(&rows), "streams differ");
    }

    /// The words' Adler-32 sums taken in lanes (each 64 words' `r·A − P − Σ j·aⱼ`) are
    /// the sums taken word by word in a `u64` and the sums of the bytes by hand:
    /// rows up to [`LANE_ROW`] bytes, runs of inked words longer than 64 (every
    /// offset of the 64-word parts), words with leading and trailing zero bytes
    /// after a run of zeros and right after the word before, bytes of 255.
    #[test]
    fn lane_sums_are_the_weighted_bytes() {
        let mut seed = 0x6a09_e667_f3bc_c908u64;
        for r in [9usize, 64, 520, 1031, 4100, 20_000, LANE_ROW - 7, LANE_ROW] {
            let n = r / 8;
            for round in 0..6 {
                let mut list = Vec::new();
                for i in 0..n {
                    let x = lcg(&mut seed);
                    if round > 0 && x % (1 + round as u64) != 0 {
                        continue;
                    }
                    let mut v = 0u64;
                    let (from, to) = ((x >> 3) % 8, 8 - (x >> 6) % 8);
                    for j in from..to.max(from + 1) {
                        let b = if round == 5 {
                            255
                        } else {
                            lcg(&mut seed) as u8 | 1
                        };
                        v |= u64::from(b) << (8 * j);
                    }
                    list.push((i, v));
                }
                let (a0, b0) = (lcg(&mut seed) % ADLER_MOD, lcg(&mut seed) % ADLER_MOD);
                let (mut a, mut b) = (a0, b0);
                for &(i, v) in &list {
                    for j in 0..8 {
                        let x = (v >> (8 * j)) & 0xff;
                        a += x;
                        b += (r - 8 * i - j) as u64 * x;
                    }
                }
                // (Rows in lanes are given the room of the longest.)
                let mut syms = vec![0u16; (12 * n + 72 + GROUP).max(LANE_SYMS + 16)];
                let lanes = word_symbols::<true>(&list, &mut syms, 0, r as u64, (a0, b0));
                let mut other = vec![0u16; 12 * n + 72 + GROUP];
                let words = word_symbols::<false>(&list, &mut other, 0, r as u64, (a0, b0));
                assert_eq!(
                    (lanes.0, lanes.1),
                    (words.0, words.1),
                    "r {r} round {round}"
                );
                assert_eq!(syms[..lanes.0], other[..words.0], "r {r} round {round}");
                let m = |(_, _, a, b): (usize, usize, u64, u64)| (a % ADLER_MOD, b % ADLER_MOD);
                assert_eq!(
                    m(lanes),
                    (a % ADLER_MOD, b % ADLER_MOD),
                    "r {r} round {round}"
                );
                assert_eq!(
                    m(words),
                    (a % ADLER_MOD, b % ADLER_MOD),
                    "r {r} round {round}"
                );
            }
        }
    }

    /// An empty stream and a stream of one byte are `fdeflate`'s too.
    #[test]
    fn tiny_streams_match() {
        assert_eq!(RowDeflate::new(Vec::new()).finish(), reference(&[]));
        let mut z = RowDeflate::new(vec![1, 2, 3]);
        z.row(&[0], std::iter::empty());
        let mut want = vec![1, 2, 3];
        want.extend(reference(&[vec![0]]));
        assert_eq!(z.finish(), want);
    }

    /// The symbol table's codes: each literal's is its code in `fdeflate`'s header, and
    /// every run of zeros up to past `258·8`, as symbols ([`RUN_SYMBOLS`], or the long
    /// way), has
    /// the bits `fdeflate` gives it ([`Bits::zeros_by_symbol`]).
    #[test]
    fn symbols_code_as_the_header_says() {
        let f = Format::get();
        let entry = |s: u16| {
            let s = usize::from(s);
            (f.sym[s], f.sym[(1 << 16) + s] as u32)
        };
        for b in 0..256u16 {
            assert_eq!(entry(b), f.sym(usize::from(b)), "literal {b}");
        }
        for z in 1..258 * 8 + 300u32 {
            let mut want = Bits::new(Vec::new());
            want.zeros_by_symbol(f, z);
            let mut syms = vec![0u16; z as usize / 258 + 4];
            let end = if z > ZRUN_MAX {
                long_run(&mut syms, 0, z)
            } else {
                let e = RUN_SYMBOLS[z as usize];
                (syms[0], syms[1]) = (e as u16, (e >> 16) as u16);
                (e >> 62) as usize
            };
            if z <= ZRUN_MAX {
                assert_eq!(end, 1 + usize::from(z > RUN_ONE), "symbols of a run of {z}");
            }
            let mut got = Bits::new(Vec::new());
            for &s in &syms[..end] {
                let (c, l) = entry(s);
                got.put(c, l);
            }
            assert_eq!(got.into_words(), want.into_words(), "a run of {z}");
        }
    }

    /// Rows where the symbols' codes are as long as they get (the longest literal, after
    /// the runs of one and of two symbols with the longest codes, at every offset of a
    /// word): the stores of eight `put`s reach furthest from where they start, and the
    /// stream is `fdeflate`'s.
    #[test]
    fn the_longest_codes_match() {
        let f = Format::get();
        let longest = |r: std::ops::Range<usize>| r.max_by_key(|&s| f.len[s]).unwrap();
        let b = longest(1..256) as u8;
        // The longest run of one symbol, and of two.
        let one = (1..=RUN_ONE as usize).max_by_key(|&z| f.zrun[z].1);
        let two = (RUN_ONE as usize + 1..=ZRUN_MAX as usize).max_by_key(|&z| f.zrun[z].1);
        let mut rows = Vec::new();
        let mut coder = RowDeflate::new(Vec::new());
        for (lits, z) in (1..20).flat_map(|l| [(l, one.unwrap()), (l, two.unwrap())]) {
            for lead in 0..8 {
                let mut row = vec![b; 1 + lead];
                for _ in 0..12 {
                    row.extend(std::iter::repeat_n(0, z));
                    row.extend(std::iter::repeat_n(b, lits));
                }
                coder.row(&row, std::iter::once((0, row.len())));
                rows.push(row);
            }
        }
        assert!(coder.finish() == reference(&rows), "streams differ");
    }

    /// Up rows whose symbols are coded together with the next rows' (a row's last
    /// symbols pending until a group is whole), between blank rows and generic rows
    /// that first code what is pending: runs of zeros around one and two symbols' limits
    /// and 258's multiples, the longest literals, rows of every length modulo a group.
    /// The stream is `fdeflate`'s of the whole filtered rows, byte for byte.
    #[test]
    fn symbols_pending_across_rows_match() {
        use crate::dirty::Dirty;
        let f = Format::get();
        // Ink whose filtered byte (above − this, the row above blank) has the longest code.
        let b = (1..256usize).max_by_key(|&s| f.len[s]).unwrap() as u8;
        let ink_of = |x: u8| 0u8.wrapping_sub(x);
        let mut seed = 0x3c6e_f372_fe94_f82bu64;
        for w in [300usize, 1031, 1039, 2600] {
            let h = 90;
            let mut ink = vec![0u8; w * h];
            let mut dirty = Dirty::new(w, h);
            for j in 0..h {
                if j % 9 == 5 || j % 9 == 6 || j % 13 == 0 {
                    continue; // blank rows, alone or two (then a blank filtered row)
                }
                let mut x = (lcg(&mut seed) % 40) as usize;
                while x < w {
                    let n = 1 + (lcg(&mut seed) % 11) as usize;
                    for k in x..(x + n).min(w) {
                        ink[j * w + k] = if lcg(&mut seed) % 4 == 0 {
                            (lcg(&mut seed) % 256) as u8
                        } else {
                            ink_of(b)
                        };
                    }
                    dirty.mark_px(x, j, (x + n).min(w), j + 1);
                    let gaps = [
                        1, 3, 8, 258, 259, 260, 261, 516, 517, 518, 774, 775, 776, 777,
                    ];
                    x += n + gaps[(lcg(&mut seed) % 14) as usize];
                }
            }
            let mut rows = up_rows(&ink, w, h);
            let mut z = RowDeflate::new(Vec::new());
            z.row(&rows[0], std::iter::once((0, w + 1)));
            let mut blank = 0;
            for j in 1..h {
                if dirty.row_pair_blank(j) {
                    blank += 1;
                    continue;
                }
                z.blank_rows(w + 1, 2, blank);
                blank = 0;
                if j % 17 == 0 {
                    // A row of another filter type after pending symbols, beginning with
                    // a run of zeros (of two symbols, or of one) and a few inked bytes.
                    let row = &mut rows[j];
                    row[0] = 0;
                    let run = [300, 700, 200][(j / 17) % 3].min(w);
                    row[1..run].fill(0);
                    z.row(row, std::iter::once((0, w + 1)));
                    continue;
                }
                let (above, this) = ink[(j - 1) * w..(j + 1) * w].split_at_mut(w);
                z.up_row(above, this, dirty.row_pair_words(j), false);
            }
            z.blank_rows(w + 1, 2, blank);
            assert!(z.finish() == reference(&rows), "width {w}: streams differ");
        }
        // Up rows that end with a run of two symbols, then a row beginning with one of
        // two symbols, the rows' symbols at every offset of a `put`'s three.
        let w = 607;
        let (mut rows, mut z) = (Vec::new(), RowDeflate::new(Vec::new()));
        for (ups, px) in (1..7).flat_map(|u| (1..8).map(move |p| (u, p))) {
            let mut ink = vec![0u8; 2 * w];
            for _ in 0..ups {
                for x in 0..px {
                    ink[w + x] = ink[x].wrapping_add(1 + (lcg(&mut seed) % 200) as u8);
                }
                let mut row = vec![2u8; w + 1];
                for x in 0..w {
                    row[1 + x] = ink[x].wrapping_sub(ink[w + x]);
                }
                let (above, this) = ink.split_at_mut(w);
                let marks = [1u64; 10];
                z.up_row(above, this, (&marks, &marks), false);
                rows.push(row);
                ink.copy_within(w.., 0);
            }
            let row = vec![0u8; w + 1];
            z.row(&row, std::iter::empty());
            rows.push(row);
        }
        assert!(z.finish() == reference(&rows), "streams differ");
    }

    /// A page like the atlas's (11 by 17 inches: cells of four-bar coupler curves in
    /// black over their grays, frames, pivots and labels).
    fn atlas_like_page() -> coupler_layout::DisplayList {
        use coupler_layout::{Anchor, DisplayList, Ink, Primitive};
        // The coupler point of a crank-rocker (ground 0–(g, 0), crank r1, coupler r2,
        // rocker r3, point (p, q) on the coupler) at crank angle `t`.
        let coupler = |[g, r1, r2, r3, p, q]: [f64; 6], t: f64| {
            let (bx, by) = (r1 * t.cos(), r1 * t.sin());
            let (dx, dy) = (g - bx, -by);
            let d = (dx * dx + dy * dy).sqrt();
            let a = (r2 * r2 - r3 * r3 + d * d) / (2.0 * d);
            let h = (r2 * r2 - a * a).max(0.0).sqrt();
            let (ux, uy) = (dx / d, dy / d);
            let (cx, cy) = (bx + a * ux - h * uy, by + a * uy + h * ux);
            let (vx, vy) = ((cx - bx) / r2, (cy - by) / r2);
            [bx + p * vx - q * vy, by + p * vy + q * vx]
        };
        let mut dl = DisplayList::new(792.0, 1224.0);
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        for cell in 0..20 {
            let (x0, y0) = (
                36.0 + 180.0 * (cell % 4) as f64,
                36.0 + 230.0 * (cell / 4) as f64,
            );
            let rnd = |s: &mut u64| (lcg(s) % 1000) as f64 / 1000.0;
            let link = [
                4.0,
                1.0,
                3.0 + rnd(&mut seed),
                3.0 + rnd(&mut seed),
                1.0 + 2.0 * rnd(&mut seed),
                2.0 * rnd(&mut seed) - 1.0,
            ];
            let curve: Vec<[f64; 2]> = (0..=720)
                .map(|i| {
                    let [x, y] = coupler(link, i as f64 * std::f64::consts::PI / 360.0);
                    [x0 + 80.0 + 18.0 * x, y0 + 110.0 - 18.0 * y]
                })
                .collect();
            dl.items.push(Primitive::Ink(Ink::Black));
            dl.items.push(Primitive::Rect {
                rect: [x0, y0, x0 + 170.0, y0 + 220.0],
                width: 0.5,
            });
            dl.items.push(Primitive::Ink(Ink::Gray(150)));
            dl.items.push(Primitive::Polylines {
                lines: curve.chunks(40).map(<[[f64; 2]]>::to_vec).collect(),
                width: 2.0,
            });
            dl.items.push(Primitive::Ink(Ink::Black));
            dl.items.push(Primitive::Polyline {
                points: curve,
                width: 0.75,
            });
            dl.items.push(Primitive::Circle {
                center: [x0 + 80.0, y0 + 110.0],
                radius: 2.0,
                width: None,
            });
            dl.items.push(Primitive::Text {
                pos: [x0 + 6.0, y0 + 212.0],
                size: 7.0,
                anchor: Anchor::Start,
                text: format!("{cell}: {:.3} {:.3} {:.3}", link[2], link[3], link[4]),
                halo: 1.2,
            });
        }
        dl
    }

    /// The page of [`atlas_like_page`] at 300 dpi drawn and encoded as pages are (band
    /// by band): the PNG of the path the processor takes ([`x86_fast`](crate::cpu::x86_fast)) and of the
    /// baseline path are the same bytes, and decode to the page.
    #[test]
    fn both_paths_write_the_same_page() {
        use crate::raster::{PngCompression, RasterPage};
        let dl = atlas_like_page();
        let png = |baseline: bool| {
            crate::cpu::baseline_only(baseline, || {
                let mut page = RasterPage::new(3300, 5100, 300.0).unwrap();
                let (bytes, _) = page.render_png(&dl, PngCompression::Fast).unwrap();
                bytes
            })
        };
        let (ours, baseline) = (png(false), png(true));
        assert!(ours == baseline, "the two paths' pages differ");
        let mut page = RasterPage::new(3300, 5100, 300.0).unwrap();
        crate::draw(&dl, &mut page);
        let mut r = png::Decoder::new(std::io::Cursor::new(&ours[..]))
            .read_info()
            .unwrap();
        let mut buf = vec![0; r.output_buffer_size().unwrap()];
        r.next_frame(&mut buf).unwrap();
        assert!(buf == page.to_gray(), "the page decodes to its pixels");
    }

    /// Lab (not a check): the thread's CPU time (Linux's `schedstat`) to encode the page
    /// of [`atlas_like_page`] at 300 dpi, the path the processor takes against the
    /// baseline path, in alternated batches of 100. Run with `cargo test --release -p
    /// coupler-render up_row_paths_times -- --ignored --nocapture`.
    #[test]
    #[ignore = "a measurement, not a check"]
    fn up_row_paths_times() {
        use crate::raster::RasterPage;
        let cpu = || {
            let s = std::fs::read_to_string("/proc/thread-self/schedstat").expect("schedstat");
            let ns: f64 = s
                .split_whitespace()
                .next()
                .expect("run time")
                .parse()
                .unwrap();
            ns * 1e-9
        };
        let mut page = RasterPage::new(3300, 5100, 300.0).unwrap();
        crate::draw(&atlas_like_page(), &mut page);
        let (batches, per) = (30, 100);
        let mut t = [Vec::new(), Vec::new()];
        for round in 0..batches {
            for k in [round % 2, 1 - round % 2] {
                let t0 = cpu();
                crate::cpu::baseline_only(k == 1, || {
                    for _ in 0..per {
                        let mut v = Vec::new();
                        page.finish_png(&mut v).unwrap();
                    }
                });
                t[k].push((cpu() - t0) / per as f64);
            }
        }
        println!("fast path taken: {}", crate::cpu::x86_fast());
        for (k, t) in t.iter_mut().enumerate() {
            t.sort_by(f64::total_cmp);
            println!(
                "{}: per page min {:.3} ms, quartile {:.3} ms, median {:.3} ms",
                ["processor's path", "baseline path"][k],
                1e3 * t[0],
                1e3 * t[batches / 4],
                1e3 * t[batches / 2]
            );
        }
    }
}
