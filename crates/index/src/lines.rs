//! Reading text files line by line with a bound on the line length, so that a damaged or
//! hostile file (a gigabyte without a newline) is refused after a bounded read rather
//! than read whole into memory.

use std::io::{self, BufRead};

/// Longest line of an index read back (16 MiB: a curve line is about 2 KB).
pub const MAX_INDEX_LINE: usize = 16 << 20;

/// Reads one line (through its `\n`, or to the end of the input) into `buf` (cleared
/// first), and returns its length in bytes (0 at the end of the input). A line longer
/// than `max` bytes is an error of kind `InvalidData`, found after reading at most
/// `max` bytes of it plus one buffer.
pub fn read_line_bounded<R: BufRead + ?Sized>(
    r: &mut R,
    buf: &mut Vec<u8>,
    max: usize,
) -> io::Result<usize> {
    buf.clear();
    loop {
        let available = match r.fill_buf() {
            Ok(b) => b,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        if available.is_empty() {
            return Ok(buf.len());
        }
        let (take, done) = match available.iter().position(|&b| b == b'\n') {
            Some(i) => (i + 1, true),
            None => (available.len(), false),
        };
        if buf.len() + take > max.saturating_add(1) {
            return Err(io::Error::new(
                io::ErrorKind::InvalidData,
                format!("a line is longer than {max} bytes"),
            ));
        }
        buf.extend_from_slice(&available[..take]);
        r.consume(take);
        if done {
            return Ok(buf.len());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_and_bounds() {
        let mut r = io::BufReader::with_capacity(4, &b"ab\ncdef\n\nlast"[..]);
        let mut buf = Vec::new();
        let mut got = Vec::new();
        while read_line_bounded(&mut r, &mut buf, 10).unwrap() > 0 {
            got.push(String::from_utf8(buf.clone()).unwrap());
        }
        assert_eq!(got, ["ab\n", "cdef\n", "\n", "last"]);
        let mut r = io::BufReader::with_capacity(4, &b"0123456789abcdef\n"[..]);
        let e = read_line_bounded(&mut r, &mut buf, 10).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::InvalidData);
        // An endless input without a newline stops after about `max` bytes.
        let mut zeros = io::BufReader::new(io::repeat(0));
        assert!(read_line_bounded(&mut zeros, &mut buf, 1 << 20).is_err());
        assert!(buf.len() <= (1 << 20) + 1);
    }
}
