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
//!   current run of zeros, and their Adler-32 is updated arithmetically too.
//!
//! The code (the lengths of the literal/length and distance codes) is read from the header
//! `fdeflate` writes, not copied: the two cannot drift apart, and the tests compare the
//! streams byte for byte.

use std::sync::OnceLock;

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
}

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
        Some(Format {
            header,
            header_bits: (tail, (bits % 8) as u32),
            code,
            len,
            dist: (reverse(dist_codes[0], dist[0]), dist[0]),
            length_symbol,
        })
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
    out: Vec<u8>,
    acc: u64,
    n: u32,
}

impl Bits {
    /// Appends the low `n ≤ 64` bits of `bits` (the rest must be zero).
    #[inline]
    fn put(&mut self, bits: u64, n: u32) {
        self.acc |= bits.checked_shl(self.n).unwrap_or(0);
        self.n += n;
        if self.n >= 64 {
            self.out.extend_from_slice(&self.acc.to_le_bytes());
            self.n -= 64;
            self.acc = bits.checked_shr(n - self.n).unwrap_or(0);
        }
    }

    /// The string as 64-bit words and its length in bits.
    fn into_words(self) -> (Vec<u64>, u64) {
        let total = self.out.len() as u64 * 8 + u64::from(self.n);
        let mut words: Vec<u64> = self
            .out
            .chunks_exact(8)
            .map(|c| u64::from_le_bytes(c.try_into().expect("8 bytes")))
            .collect();
        if self.n > 0 {
            words.push(self.acc);
        }
        (words, total)
    }

    /// `literal` codes of `bytes`, a few at a time.
    #[inline]
    fn literals(&mut self, f: &Format, bytes: &[u8]) {
        let (mut acc, mut n) = (0u64, 0u32);
        for &b in bytes {
            let (c, l) = f.sym(usize::from(b));
            acc |= c << n;
            n += l;
            if n >= 48 {
                self.put(acc, n);
                (acc, n) = (0, 0);
            }
        }
        if n > 0 {
            self.put(acc, n);
        }
    }

    /// A run of `run ≥ 1` zeros: a literal 0, then distance-1 matches (as `fdeflate`).
    fn zeros(&mut self, f: &Format, mut run: u32) {
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

    /// One 8-byte word of a row, `fdeflate`'s way: a pending run of zeros takes the word's
    /// leading zeros, the bytes up to its trailing zeros are literals, and its trailing
    /// zeros start the next run.
    #[inline]
    fn word(&mut self, f: &Format, w: &[u8], run: &mut u32) {
        let v = u64::from_le_bytes(w.try_into().expect("8 bytes"));
        if v == 0 {
            *run += 8;
            return;
        }
        let mut from = 0;
        if *run > 0 {
            let lead = v.trailing_zeros() / 8;
            self.zeros(f, *run + lead);
            from = lead as usize;
        }
        let tail = v.leading_zeros() / 8;
        self.literals(f, &w[from..8 - tail as usize]);
        *run = tail;
    }

    /// A row whose bytes are zero outside the byte ranges `live` (ascending), as
    /// `fdeflate::Compressor::write_data(row)` encodes it.
    fn row(&mut self, f: &Format, row: &[u8], live: impl Iterator<Item = (usize, usize)>) {
        let words = row.len() / 8;
        let (mut next, mut run) = (0usize, 0u32);
        for (s, e) in live {
            let (w0, w1) = ((s / 8).max(next), e.div_ceil(8).min(words));
            if w0 >= w1 {
                continue;
            }
            run += 8 * (w0 - next) as u32;
            for w in row[8 * w0..8 * w1].chunks_exact(8) {
                self.word(f, w, &mut run);
            }
            next = w1;
        }
        run += 8 * (words - next) as u32;
        if run > 0 {
            self.zeros(f, run);
        }
        self.literals(f, &row[8 * words..]);
    }
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
    /// The bits of a blank row of `blank.0` bytes (filter type `blank.1`).
    blank: Option<(usize, u8, Vec<u64>, u64)>,
}

impl RowDeflate {
    /// A stream appended to `out`.
    pub(crate) fn new(mut out: Vec<u8>) -> RowDeflate {
        let f = Format::get();
        out.extend_from_slice(&f.header);
        let mut bits = Bits { out, acc: 0, n: 0 };
        bits.put(f.header_bits.0, f.header_bits.1);
        RowDeflate {
            f,
            bits,
            adler: Adler::new(),
            blank: None,
        }
    }

    /// A row (its filter byte first) whose bytes are zero outside the byte ranges `live`
    /// (ascending; the filter byte is always read).
    pub(crate) fn row(&mut self, row: &[u8], live: impl Iterator<Item = (usize, usize)> + Clone) {
        let live = std::iter::once((0, 1)).chain(live);
        self.bits.row(self.f, row, live.clone());
        let mut next = 0;
        for (s, e) in live {
            let (s, e) = (s.max(next), e.min(row.len()));
            if s >= e {
                continue;
            }
            self.adler.zeros(s - next);
            self.adler.bytes(&row[s..e]);
            next = e;
        }
        self.adler.zeros(row.len() - next);
    }

    /// `count` blank rows of `len` bytes: filter type `filter`, then zeros.
    pub(crate) fn blank_rows(&mut self, len: usize, filter: u8, count: usize) {
        if len == 0 || count == 0 {
            return;
        }
        let f = self.f;
        let fresh = !matches!(&self.blank, Some((l, t, ..)) if *l == len && *t == filter);
        if fresh {
            let mut row = vec![0u8; len];
            row[0] = filter;
            let mut b = Bits {
                out: Vec::new(),
                acc: 0,
                n: 0,
            };
            b.row(f, &row, std::iter::once((0, 1)));
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
                self.bits.put(w, 64);
            }
            if rest > 0 {
                self.bits.put(words[full], rest);
            }
            self.adler.bytes(&[filter]);
            self.adler.zeros(len - 1);
        }
    }

    /// Ends the stream (end of block, padding, Adler-32) and gives the buffer back.
    pub(crate) fn finish(mut self) -> Vec<u8> {
        let (c, l) = self.f.sym(256);
        self.bits.put(c, l);
        let Bits { mut out, acc, n } = self.bits;
        out.extend_from_slice(&acc.to_le_bytes()[..n.div_ceil(8) as usize]);
        out.extend_from_slice(&self.adler.finish().to_be_bytes());
        out
    }
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
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
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
}
