//! PNG heightmaps: 8- or 16-bit greyscale, or an 8-bit RGB or RGBA web-map elevation tile
//! whose [`Encoding`] the caller names; alpha accepted only where every pixel is opaque.
//!
//! Alpha is neither ignored nor refused outright: exporters often write a grey-alpha PNG that
//! is opaque everywhere, and a transparent pixel marks a hole (a tile's nodata), which must not
//! become a height silently. So a pixel with alpha below its maximum, or equal to the `tRNS`
//! colour of an image without an alpha channel, is an error naming its (i, j).

use super::assemble::{Rows, check_size, find_in_grid_order, into_grid};
use super::error::{GridFileError, detail};
use super::hints::Encoding;
use super::kind::GridFileKind;
use crate::source::Grid;
use ::png::{BitDepth, ColorType, Decoder, Transformations};
use std::io::Cursor;

const KIND: GridFileKind = GridFileKind::Png;

/// Deflate's largest ratio of output to input: 258 bytes from one 2-bit code.
const MAX_DEFLATE_RATIO: u64 = 1032;

fn corrupt(message: impl std::fmt::Display) -> GridFileError {
    GridFileError::Corrupt { kind: KIND, detail: detail(message) }
}

pub(super) fn decode(
    bytes: &[u8],
    encoding: Option<Encoding>,
    max_points: usize,
) -> Result<Grid, GridFileError> {
    let mut decoder = Decoder::new(Cursor::new(bytes));
    // Samples as stored: no expansion of tRNS into alpha, no scaling of 16 bits to 8.
    decoder.set_transformations(Transformations::IDENTITY);
    decoder.set_ignore_text_chunk(true);
    decoder.set_ignore_iccp_chunk(true);
    let info = decoder.read_header_info().map_err(corrupt)?;
    let (width, height, colour, depth) = (info.width, info.height, info.color_type, info.bit_depth);
    let not_a_tile = |encoding: Encoding, found: &str| GridFileError::NotATile {
        encoding: encoding.name(),
        found: format!("{found} PNG"),
    };
    // Channels of height data (grey, or R G B) and whether an alpha channel follows them.
    let (channels, alpha) = match (colour, encoding) {
        (ColorType::Grayscale | ColorType::GrayscaleAlpha, Some(e)) => {
            return Err(not_a_tile(e, "a greyscale"));
        }
        (ColorType::Indexed, Some(e)) => return Err(not_a_tile(e, "a palette")),
        (ColorType::Grayscale, None) => (1, false),
        (ColorType::GrayscaleAlpha, None) => (1, true),
        (ColorType::Rgb, Some(_)) => (3, false),
        (ColorType::Rgba, Some(_)) => (3, true),
        (ColorType::Rgb, None) => return Err(GridFileError::Colour { kind: KIND, model: "RGB" }),
        (ColorType::Rgba, None) => return Err(GridFileError::Colour { kind: KIND, model: "RGBA" }),
        (ColorType::Indexed, None) => return Err(GridFileError::Colour { kind: KIND, model: "palette" }),
    };
    let sixteen = match (depth, encoding) {
        (BitDepth::Eight, _) => false,
        (BitDepth::Sixteen, None) => true,
        (other, Some(e)) => return Err(not_a_tile(e, &format!("a {}-bit colour", other as u8))),
        (other, None) => {
            return Err(GridFileError::UnsupportedType {
                kind: KIND,
                found: format!("{}-bit greyscale", other as u8),
                supported: "8- or 16-bit greyscale",
            });
        }
    };
    let shape = check_size(u64::from(width), u64::from(height), max_points)?;
    // A tiny file that declares a large image cannot hold it: refuse it before the output
    // buffer is allocated. Each row also has a filter byte.
    let sample_len = 1 + usize::from(sixteen);
    let bytes_per_pixel = (channels + usize::from(alpha)) * sample_len;
    let raw_len =
        (shape.points() as u64).saturating_mul(bytes_per_pixel as u64).saturating_add(shape.ny as u64);
    if raw_len > MAX_DEFLATE_RATIO.saturating_mul(bytes.len() as u64) {
        return Err(corrupt(format!("{} bytes cannot hold {width} x {height} pixels", bytes.len())));
    }
    let mut reader = decoder.read_info().map_err(corrupt)?;
    let len = reader.output_buffer_size().ok_or_else(|| corrupt("the image is too large to address"))?;
    if Some(len) != shape.points().checked_mul(bytes_per_pixel) {
        // The indexing below relies on packed rows of whole samples.
        return Err(corrupt(format!("unexpected output size {len} for {width} x {height} pixels")));
    }
    let mut buf = vec![0; len];
    reader.next_frame(&mut buf).map_err(corrupt)?;
    let read = |b: &[u8]| if sixteen { u16::from_be_bytes([b[0], b[1]]) } else { u16::from(b[0]) };
    // tRNS without an alpha channel is one transparent colour, a 16-bit value per channel (the
    // png crate may keep one byte per channel of an 8-bit image); with alpha it is meaningless.
    let transparent: Option<Vec<u16>> = match reader.info().trns.as_deref() {
        _ if alpha => None,
        Some(trns) if trns.len() == channels => Some(trns.iter().copied().map(u16::from).collect()),
        Some(trns) if trns.len() == 2 * channels => Some(trns.chunks(2).map(read_be).collect()),
        _ => None,
    };
    let pixel = |k: usize| &buf[k * bytes_per_pixel..(k + 1) * bytes_per_pixel];
    let max = if sixteen { u16::MAX } else { u16::from(u8::MAX) };
    let is_hole = |k: usize| {
        let p = pixel(k);
        let matches_key = transparent
            .as_deref()
            .is_some_and(|key| key.iter().enumerate().all(|(c, &v)| read(&p[c * sample_len..]) == v));
        (alpha && read(&p[channels * sample_len..]) != max) || matches_key
    };
    if let Some((i, j, row)) = find_in_grid_order(shape, Rows::TopFirst, is_hole) {
        return Err(GridFileError::Transparent { i, j, row });
    }
    let values = match encoding {
        None => (0..shape.points()).map(|k| f64::from(read(pixel(k)))).collect(),
        Some(encoding) => {
            (0..shape.points()).map(|k| encoding.height([0, 1, 2].map(|c| pixel(k)[c]))).collect()
        }
    };
    into_grid(KIND, shape, Rows::TopFirst, values, None)
}

fn read_be(b: &[u8]) -> u16 {
    u16::from_be_bytes([b[0], b[1]])
}
