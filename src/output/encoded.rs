//! A file as parts, fixed bytes or rows made on demand, that is written whole or handed out in
//! chunks.

use std::io::{self, Write};

/// Writes row `i` of a part.
type RowFn = Box<dyn Fn(usize, &mut Vec<u8>) + Send + Sync>;

/// One piece of an encoding.
pub enum Part {
    /// Bytes known up front.
    Bytes(Vec<u8>),
    /// `count` rows, each written on demand.
    Rows {
        /// How many.
        count: usize,
        /// Appends row `i`.
        write: RowFn,
    },
}

impl Part {
    /// `count` rows written by `write`.
    pub fn rows(count: usize, write: impl Fn(usize, &mut Vec<u8>) + Send + Sync + 'static) -> Self {
        Part::Rows { count, write: Box::new(write) }
    }
}

/// A result in one format, as parts to write in order.
pub struct Encoded {
    pub(super) parts: Vec<Part>,
}

/// How many bytes a chunk of [`Encoded::into_chunks`] gathers before it is handed on.
pub(super) const CHUNK_BYTES: usize = 64 * 1024;

impl Encoded {
    /// The parts, in order.
    pub fn new(parts: Vec<Part>) -> Self {
        Self { parts }
    }

    /// Writes everything to `out`.
    ///
    /// # Errors
    /// Whatever writing to `out` returns.
    pub fn write_to(self, out: &mut impl Write) -> io::Result<()> {
        for chunk in self.into_chunks() {
            out.write_all(&chunk)?;
        }
        Ok(())
    }

    /// The bytes in chunks of about 64 KiB, made as they are asked for.
    pub fn into_chunks(self) -> Chunks {
        Chunks { parts: self.parts.into_iter(), current: None, buf: Vec::new() }
    }

    /// All of it in one buffer (tests, small results).
    pub fn to_vec(self) -> Vec<u8> {
        let mut out = Vec::new();
        self.write_to(&mut out).expect("writing to a Vec does not fail");
        out
    }
}

/// The chunks of an [`Encoded`].
pub struct Chunks {
    parts: std::vec::IntoIter<Part>,
    /// The rows part being written and its next row.
    current: Option<(usize, RowFn, usize)>,
    buf: Vec<u8>,
}

impl Iterator for Chunks {
    type Item = Vec<u8>;

    fn next(&mut self) -> Option<Vec<u8>> {
        self.buf.reserve(CHUNK_BYTES);
        while self.buf.len() < CHUNK_BYTES {
            if let Some((count, write, next)) = &mut self.current {
                while *next < *count && self.buf.len() < CHUNK_BYTES {
                    write(*next, &mut self.buf);
                    *next += 1;
                }
                if *next == *count {
                    self.current = None;
                }
                continue;
            }
            match self.parts.next() {
                Some(Part::Bytes(bytes)) if self.buf.is_empty() && bytes.len() >= CHUNK_BYTES => {
                    // A large fixed part (a rendered picture) goes out as it is, uncopied.
                    return Some(bytes);
                }
                Some(Part::Bytes(bytes)) => self.buf.extend_from_slice(&bytes),
                Some(Part::Rows { count, write }) => self.current = Some((count, write, 0)),
                None => break,
            }
        }
        (!self.buf.is_empty()).then(|| std::mem::take(&mut self.buf))
    }
}

/// Appends `x` as the shortest text that reads back as the same f64 (`0.1`, `1e-7`, `-0.0`).
pub(super) fn push_f64(out: &mut Vec<u8>, x: f64) {
    // ryu rather than `{}`: `{}` writes 1e-300 as 300 digits, and ryu is faster.
    out.extend_from_slice(ryu::Buffer::new().format(x).as_bytes());
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    #[test]
    fn chunks_hold_every_byte_in_order_and_stay_near_the_chunk_size() {
        let rows = 100_000;
        let encoding = Encoded::new(vec![
            Part::Bytes(b"head".to_vec()),
            Part::rows(rows, |i, out| out.extend_from_slice(format!("{i},").as_bytes())),
            Part::Bytes(vec![b'x'; 3 * CHUNK_BYTES]),
            Part::rows(0, |_, _| unreachable!()),
            Part::Bytes(b"tail".to_vec()),
        ]);
        let chunks: Vec<Vec<u8>> = encoding.into_chunks().collect();
        let mut expected = b"head".to_vec();
        (0..rows).for_each(|i| expected.extend_from_slice(format!("{i},").as_bytes()));
        expected.extend(vec![b'x'; 3 * CHUNK_BYTES]);
        expected.extend_from_slice(b"tail");
        assert_eq!(chunks.concat(), expected);
        // Every chunk but the last is full (a row may pass the mark by its own length).
        for c in &chunks[..chunks.len() - 1] {
            assert!(c.len() >= CHUNK_BYTES && c.len() < 4 * CHUNK_BYTES, "{}", c.len());
        }
    }

    /// One part's bytes, its rows made last to first and joined in order.
    pub(crate) fn part_backwards(part: Part) -> Vec<u8> {
        match part {
            Part::Bytes(bytes) => bytes,
            Part::Rows { count, write } => {
                let mut rows: Vec<Vec<u8>> = (0..count)
                    .rev()
                    .map(|i| {
                        let mut row = Vec::new();
                        write(i, &mut row);
                        row
                    })
                    .collect();
                rows.reverse();
                rows.concat()
            }
        }
    }
}
