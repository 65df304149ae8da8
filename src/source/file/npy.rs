//! NumPy .npy arrays: the header (a Python dict literal) and 2-D numeric data.
//!
//! The format is NEP 1: the magic `\x93NUMPY`, a version, a little-endian header length,
//! then `{'descr': '<f8', 'fortran_order': False, 'shape': (3, 4), }` padded with spaces.
//! The header is parsed here, not with the `npyz` crate: npyz multiplies the shape's
//! dimensions unchecked (a panic under overflow checks on a crafted header), allocates the
//! declared header length before reading it (up to 4 GiB from a 12-byte file) and quotes the
//! whole header in its errors. A dict of three flat entries needs no recursive parser.

use super::assemble::{Rows, array, check_size, into_grid};
use super::error::{GridFileError, detail};
use super::kind::GridFileKind;
use crate::source::Grid;

const KIND: GridFileKind = GridFileKind::Npy;

/// The sample types read, as the error lists them.
const SUPPORTED: &str = "f4, f8, i1, u1, i2, u2, i4 or u4 (either byte order)";

fn corrupt(message: impl std::fmt::Display) -> GridFileError {
    GridFileError::Corrupt { kind: KIND, detail: detail(message) }
}

pub(super) fn decode(bytes: &[u8], max_points: usize) -> Result<Grid, GridFileError> {
    let (header, data) = split(bytes)?;
    let header = Header::parse(header)?;
    let read = reader(&header.descr)?;
    let &[rows, cols] = header.shape.as_slice() else {
        let dims: Vec<String> = header.shape.iter().map(u64::to_string).collect();
        let detail = format!("array of shape ({}) is not 2-D (rows, columns)", dims.join(", "));
        return Err(GridFileError::Unsupported { kind: KIND, detail: super::error::detail(detail) });
    };
    let shape = check_size(cols, rows, max_points)?;
    let width = read.width;
    // Saturates only for a limit near usize::MAX, where no file can match anyway.
    let expected = (shape.points() as u64).saturating_mul(width as u64);
    if data.len() as u64 != expected {
        return Err(GridFileError::SizeMismatch {
            kind: KIND,
            unit: "bytes of data",
            from: "the header's shape and dtype",
            expected,
            got: data.len() as u64,
        });
    }
    let sample = |k: usize| (read.read)(&data[k * width..(k + 1) * width]);
    let values: Vec<f64> = if header.fortran_order {
        // Column-major: element (r, c) is the (c·rows + r)-th.
        (0..shape.ny).flat_map(|r| (0..shape.nx).map(move |c| c * shape.ny + r)).map(sample).collect()
    } else {
        (0..shape.points()).map(sample).collect()
    };
    into_grid(KIND, shape, Rows::TopFirst, values, None)
}

/// Splits the file into the header text and the data after it.
fn split(bytes: &[u8]) -> Result<(&[u8], &[u8]), GridFileError> {
    let (major, minor) = match bytes.get(6..8) {
        Some(&[major, minor]) => (major, minor),
        _ => return Err(corrupt("the file ends inside the magic string")),
    };
    // Versions 2 and 3 widen the length to 4 bytes; 3 also allows UTF-8 in the header.
    let (len, start) = match major {
        1 => (bytes.get(8..10).map(|b| u16::from_le_bytes(array(b)) as usize), 10),
        2 | 3 => (bytes.get(8..12).map(|b| u32::from_le_bytes(array(b)) as usize), 12),
        _ => {
            let detail = format!("format version {major}.{minor} (1.0, 2.0 and 3.0 are read)");
            return Err(GridFileError::Unsupported { kind: KIND, detail });
        }
    };
    let len = len.ok_or_else(|| corrupt("the file ends inside the header length"))?;
    let rest = &bytes[start.min(bytes.len())..];
    if len > rest.len() {
        return Err(corrupt(format!("the header claims {len} bytes, but only {} follow", rest.len())));
    }
    Ok(rest.split_at(len))
}

/// The three entries of the header dict.
#[derive(Debug)]
struct Header {
    descr: String,
    fortran_order: bool,
    shape: Vec<u64>,
}

/// A value of the header dict.
enum Value {
    Str(String),
    Bool(bool),
    Tuple(Vec<u64>),
}

impl Header {
    /// `{'descr': <str>, 'fortran_order': <bool>, 'shape': <tuple of ints>}`, keys in any order
    /// and each exactly once, as numpy's reader requires.
    fn parse(text: &[u8]) -> Result<Header, GridFileError> {
        let mut p = Parser { text, pos: 0 };
        p.expect(b'{')?;
        let (mut descr, mut fortran_order, mut shape) = (None, None, None);
        loop {
            if p.eat(b'}') {
                break;
            }
            let key = p.string()?;
            p.expect(b':')?;
            let value = p.value()?;
            let slot_taken = match (key.as_str(), value) {
                ("descr", Value::Str(s)) => descr.replace(s).is_some(),
                ("fortran_order", Value::Bool(b)) => fortran_order.replace(b).is_some(),
                ("shape", Value::Tuple(t)) => shape.replace(t).is_some(),
                ("descr" | "fortran_order" | "shape", _) => {
                    return Err(corrupt(format!("the header's '{key}' has the wrong type")));
                }
                _ => return Err(corrupt(format!("the header has an unknown key '{key}'"))),
            };
            if slot_taken {
                return Err(corrupt(format!("the header repeats the key '{key}'")));
            }
            if !p.eat(b',') {
                p.expect(b'}')?;
                break;
            }
        }
        if p.peek().is_some() {
            return Err(p.error("the end of the header"));
        }
        let missing = |key| corrupt(format!("the header has no '{key}'"));
        Ok(Header {
            descr: descr.ok_or_else(|| missing("descr"))?,
            fortran_order: fortran_order.ok_or_else(|| missing("fortran_order"))?,
            shape: shape.ok_or_else(|| missing("shape"))?,
        })
    }
}

/// A cursor over the header text that skips whitespace between tokens.
struct Parser<'a> {
    text: &'a [u8],
    pos: usize,
}

impl Parser<'_> {
    fn peek(&mut self) -> Option<u8> {
        while self.text.get(self.pos).is_some_and(|b| b.is_ascii_whitespace()) {
            self.pos += 1;
        }
        self.text.get(self.pos).copied()
    }

    fn eat(&mut self, c: u8) -> bool {
        let found = self.peek() == Some(c);
        if found {
            self.pos += 1;
        }
        found
    }

    fn error(&self, expected: &str) -> GridFileError {
        corrupt(format!("expected {expected} at byte {} of the header", self.pos))
    }

    fn expect(&mut self, c: u8) -> Result<(), GridFileError> {
        if self.eat(c) { Ok(()) } else { Err(self.error(&format!("'{}'", c as char))) }
    }

    /// A quoted string without escapes (numpy writes none in these three entries).
    fn string(&mut self) -> Result<String, GridFileError> {
        let quote = match self.peek() {
            Some(q @ (b'\'' | b'"')) => q,
            _ => return Err(self.error("a quoted string")),
        };
        let start = self.pos + 1;
        let len = self.text[start..]
            .iter()
            .position(|&b| b == quote)
            .ok_or_else(|| self.error("a closing quote"))?;
        self.pos = start + len + 1;
        Ok(String::from_utf8_lossy(&self.text[start..start + len]).into_owned())
    }

    fn value(&mut self) -> Result<Value, GridFileError> {
        match self.peek() {
            Some(b'\'' | b'"') => self.string().map(Value::Str),
            Some(b'(' | b'[') => self.tuple().map(Value::Tuple),
            _ if self.text[self.pos..].starts_with(b"True") => {
                self.pos += 4;
                Ok(Value::Bool(true))
            }
            _ if self.text[self.pos..].starts_with(b"False") => {
                self.pos += 5;
                Ok(Value::Bool(false))
            }
            _ => Err(self.error("a string, True, False or a tuple of integers")),
        }
    }

    /// `(3, 4)`, `(5,)`, `()`; a list of tuples (a structured dtype) is refused here.
    fn tuple(&mut self) -> Result<Vec<u64>, GridFileError> {
        let close = if self.eat(b'(') { b')' } else { self.expect(b'[').map(|()| b']')? };
        let mut items = Vec::new();
        loop {
            if self.eat(close) {
                return Ok(items);
            }
            if matches!(self.peek(), Some(b'(' | b'[' | b'\'' | b'"')) {
                let detail = "structured (record) dtypes are not grids".to_string();
                return Err(GridFileError::Unsupported { kind: KIND, detail });
            }
            items.push(self.integer()?);
            if !self.eat(b',') {
                self.expect(close)?;
                return Ok(items);
            }
        }
    }

    /// A non-negative decimal integer; Python 2 files may end it with `L`.
    fn integer(&mut self) -> Result<u64, GridFileError> {
        self.peek();
        let digits = self.text[self.pos..].iter().take_while(|b| b.is_ascii_digit()).count();
        if digits == 0 {
            return Err(self.error("a dimension (a non-negative integer)"));
        }
        let mut n: u64 = 0;
        for &d in &self.text[self.pos..self.pos + digits] {
            n = n
                .checked_mul(10)
                .and_then(|n| n.checked_add(u64::from(d - b'0')))
                .ok_or_else(|| corrupt("a dimension in the header's shape is beyond 2^64"))?;
        }
        self.pos += digits;
        if self.text.get(self.pos) == Some(&b'L') {
            self.pos += 1;
        }
        Ok(n)
    }
}

/// How to read one sample: its width in bytes and the exact conversion to f64.
struct Reader {
    width: usize,
    read: fn(&[u8]) -> f64,
}

/// The reader for a dtype string such as `<f8`, `>i2` or `|u1`.
fn reader(descr: &str) -> Result<Reader, GridFileError> {
    let unsupported =
        || GridFileError::UnsupportedType { kind: KIND, found: detail(descr), supported: SUPPORTED };
    let (order, ty) = match descr.as_bytes() {
        [order @ (b'<' | b'>' | b'|'), ty @ ..] => (*order, ty),
        _ => return Err(unsupported()),
    };
    let read: fn(&[u8]) -> f64 = match (order, ty) {
        (b'<', b"f4") => |b| f64::from(f32::from_le_bytes(array(b))),
        (b'>', b"f4") => |b| f64::from(f32::from_be_bytes(array(b))),
        (b'<', b"f8") => |b| f64::from_le_bytes(array(b)),
        (b'>', b"f8") => |b| f64::from_be_bytes(array(b)),
        (_, b"i1") => |b| f64::from(b[0] as i8),
        (_, b"u1") => |b| f64::from(b[0]),
        (b'<', b"i2") => |b| f64::from(i16::from_le_bytes(array(b))),
        (b'>', b"i2") => |b| f64::from(i16::from_be_bytes(array(b))),
        (b'<', b"u2") => |b| f64::from(u16::from_le_bytes(array(b))),
        (b'>', b"u2") => |b| f64::from(u16::from_be_bytes(array(b))),
        (b'<', b"i4") => |b| f64::from(i32::from_le_bytes(array(b))),
        (b'>', b"i4") => |b| f64::from(i32::from_be_bytes(array(b))),
        (b'<', b"u4") => |b| f64::from(u32::from_le_bytes(array(b))),
        (b'>', b"u4") => |b| f64::from(u32::from_be_bytes(array(b))),
        _ => return Err(unsupported()),
    };
    // The size is the last character of every accepted type string.
    let width = usize::from(ty[1] - b'0');
    Ok(Reader { width, read })
}
