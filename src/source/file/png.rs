//! PNG heightmaps: 8- or 16-bit greyscale, alpha accepted only where every pixel is opaque.
//!
//! Alpha is neither ignored nor refused outright: exporters often write a grey-alpha PNG that
//! is opaque everywhere, and a transparent pixel marks a hole, which must not become a height
//! silently. So a pixel with alpha below its maximum, or equal to the `tRNS` grey of an image
//! without an alpha channel, is an error naming its (i, j).

use super::{GridFileError, GridFileKind, Rows, check_size, detail, find_in_grid_order, into_grid};
use crate::source::Grid;
use ::png::{BitDepth, ColorType, Decoder, Transformations};
use std::io::Cursor;

const KIND: GridFileKind = GridFileKind::Png;

/// Deflate's largest ratio of output to input: 258 bytes from one 2-bit code.
const MAX_DEFLATE_RATIO: u64 = 1032;

fn corrupt(message: impl std::fmt::Display) -> GridFileError {
    GridFileError::Corrupt { kind: KIND, detail: detail(message) }
}

pub(super) fn decode(bytes: &[u8], max_points: usize) -> Result<Grid, GridFileError> {
    let mut decoder = Decoder::new(Cursor::new(bytes));
    // Samples as stored: no expansion of tRNS into alpha, no scaling of 16 bits to 8.
    decoder.set_transformations(Transformations::IDENTITY);
    decoder.set_ignore_text_chunk(true);
    decoder.set_ignore_iccp_chunk(true);
    let info = decoder.read_header_info().map_err(corrupt)?;
    let (width, height, colour, depth) = (info.width, info.height, info.color_type, info.bit_depth);
    let alpha = match colour {
        ColorType::Grayscale => false,
        ColorType::GrayscaleAlpha => true,
        ColorType::Rgb => return Err(GridFileError::Colour { kind: KIND, model: "RGB" }),
        ColorType::Rgba => return Err(GridFileError::Colour { kind: KIND, model: "RGBA" }),
        ColorType::Indexed => return Err(GridFileError::Colour { kind: KIND, model: "palette" }),
    };
    let sixteen = match depth {
        BitDepth::Eight => false,
        BitDepth::Sixteen => true,
        other => {
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
    let bytes_per_pixel = (1 + usize::from(alpha)) * (1 + usize::from(sixteen));
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
    // tRNS for greyscale is one grey value (the png crate keeps one byte of it for 8-bit
    // images, two for 16-bit); an alpha channel makes it meaningless.
    let transparent_grey = match reader.info().trns.as_deref() {
        _ if alpha => None,
        Some(&[grey]) => Some(u16::from(grey)),
        Some(&[hi, lo]) => Some(u16::from_be_bytes([hi, lo])),
        _ => None,
    };

    let sample_len = 1 + usize::from(sixteen);
    let read = |b: &[u8]| if sixteen { u16::from_be_bytes([b[0], b[1]]) } else { u16::from(b[0]) };
    let pixel = |k: usize| &buf[k * bytes_per_pixel..(k + 1) * bytes_per_pixel];
    let max = if sixteen { u16::MAX } else { u16::from(u8::MAX) };
    let is_hole = |k: usize| {
        let p = pixel(k);
        let grey = read(p);
        (alpha && read(&p[sample_len..]) != max) || transparent_grey == Some(grey)
    };
    if let Some((i, j, row)) = find_in_grid_order(shape, Rows::TopFirst, is_hole) {
        return Err(GridFileError::Transparent { i, j, row });
    }
    let values = (0..shape.points()).map(|k| f64::from(read(pixel(k)))).collect();
    into_grid(KIND, shape, Rows::TopFirst, values, None)
}
