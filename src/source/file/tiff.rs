//! TIFF and GeoTIFF rasters: one band of integer or float samples, the georeferenced domain
//! and the `GDAL_NODATA` value.

use super::assemble::{NoData, Rows, Shape, check_size, into_grid};
use super::error::{GridFileError, detail};
use super::kind::GridFileKind;
use crate::geom::Rect;
use crate::source::Grid;
use ::tiff::decoder::ifd::Value;
use ::tiff::decoder::{Decoder, DecodingResult, Limits};
use ::tiff::tags::Tag;
use ::tiff::{TiffError, TiffResult};
use std::io::{Cursor, Read, Seek};

pub(super) const KIND: GridFileKind = GridFileKind::Tiff;

const SUPPORTED: &str = "one band of u8, u16, u32, i8, i16, i32, f32 or f64";

/// `GTRasterTypeGeoKey` in the GeoKeyDirectory, and its value for PixelIsPoint.
const RASTER_TYPE_KEY: u16 = 1025;
const PIXEL_IS_POINT: u16 = 2;

/// `GTModelTypeGeoKey` and its values for projected and geographic models.
const MODEL_TYPE_KEY: u16 = 1024;
const MODEL_PROJECTED: u16 = 1;
const MODEL_GEOGRAPHIC: u16 = 2;
/// `GeographicTypeGeoKey` and `ProjectedCSTypeGeoKey`: the EPSG code of each kind of model.
const GEOGRAPHIC_TYPE_KEY: u16 = 2048;
const PROJECTED_TYPE_KEY: u16 = 3072;

/// The coordinate reference system a GeoTIFF's keys name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Crs {
    /// Longitude and latitude in degrees, with the EPSG code of the datum's system (4326 for
    /// WGS84), or `None` when the file defines its own.
    Geographic(Option<u16>),
    /// Projected coordinates in metres or feet, with the EPSG code (3857, 326xx for UTM
    /// north…), or `None` when the file defines its own.
    Projected(Option<u16>),
}

pub(super) fn error(e: TiffError) -> GridFileError {
    match e {
        TiffError::UnsupportedError(e) => GridFileError::Unsupported { kind: KIND, detail: detail(e) },
        e => GridFileError::Corrupt { kind: KIND, detail: detail(e) },
    }
}

/// A decoded GeoTIFF: its grid, domain and system.
pub(super) type Decoded = (Grid, Option<Rect>, Option<Crs>);

/// What a GeoTIFF's first directory says, read before any sample.
pub(super) struct Header {
    pub(super) shape: Shape,
    pub(super) nodata: Option<NoData>,
    pub(super) domain: Option<Rect>,
    pub(super) crs: Option<Crs>,
}

/// The grid, its domain and system; a nodata sample is refused.
pub(super) fn decode(bytes: &[u8], max_points: usize) -> Result<Decoded, GridFileError> {
    let mut decoder = Decoder::new(Cursor::new(bytes)).map_err(error)?;
    let Header { shape, nodata, domain, crs } = header(&mut decoder, max_points)?;
    // The decoded buffer is at most nx·ny samples of 8 bytes; the default 256 MiB cap would
    // refuse a large grid the caller allows.
    let mut limits = Limits::default();
    limits.decoding_buffer_size = max_points.saturating_mul(8);
    let mut decoder = decoder.with_limits(limits);
    let values = samples(decoder.read_image().map_err(error)?)?;
    if values.len() != shape.points() {
        return Err(GridFileError::Corrupt {
            kind: KIND,
            detail: format!("decoded {} samples for {} x {} pixels", values.len(), shape.nx, shape.ny),
        });
    }
    let grid = into_grid(KIND, shape, Rows::TopFirst, values, nodata)?;
    Ok((grid, domain, crs))
}

/// Reads the first directory, which touches only the header and the tags: refuses colour,
/// several bands and sample types meshfit does not read, and more than `max_points` samples.
pub(super) fn header<R: Read + Seek>(
    decoder: &mut Decoder<R>,
    max_points: usize,
) -> Result<Header, GridFileError> {
    check_colour(decoder)?;
    let is_f32 = check_sample_type(decoder)? == (3, 32);
    let (width, height) = decoder.dimensions().map_err(error)?;
    let shape = check_size(u64::from(width), u64::from(height), max_points)?;
    let nodata = nodata(decoder, is_f32)?;
    let keys = decoder.find_tag_unsigned_vec::<u16>(Tag::GeoKeyDirectoryTag).map_err(error)?;
    let domain = domain(decoder, shape, keys.as_deref())?;
    let crs = crs(keys.as_deref());
    Ok(Header { shape, nodata, domain, crs })
}

/// Decoded samples as f64, which holds every accepted type exactly.
pub(super) fn samples(result: DecodingResult) -> Result<Vec<f64>, GridFileError> {
    Ok(match result {
        DecodingResult::U8(v) => v.into_iter().map(f64::from).collect(),
        DecodingResult::U16(v) => v.into_iter().map(f64::from).collect(),
        DecodingResult::U32(v) => v.into_iter().map(f64::from).collect(),
        DecodingResult::I8(v) => v.into_iter().map(f64::from).collect(),
        DecodingResult::I16(v) => v.into_iter().map(f64::from).collect(),
        DecodingResult::I32(v) => v.into_iter().map(f64::from).collect(),
        DecodingResult::F32(v) => v.into_iter().map(f64::from).collect(),
        DecodingResult::F64(v) => v,
        other => return Err(unsupported_type(result_type(&other))),
    })
}

fn unsupported_type(found: &str) -> GridFileError {
    GridFileError::UnsupportedType { kind: KIND, found: found.to_string(), supported: SUPPORTED }
}

fn result_type(r: &DecodingResult) -> &'static str {
    match r {
        DecodingResult::F16(_) => "f16",
        DecodingResult::U64(_) => "u64",
        DecodingResult::I64(_) => "i64",
        _ => "another type",
    }
}

/// Refuses colour models first, then more than one sample per pixel.
fn check_colour<R: Read + Seek>(decoder: &mut Decoder<R>) -> Result<(), GridFileError> {
    // TIFF 6.0 PhotometricInterpretation values; 32844/32845 are LogL/LogLuv.
    let model = match decoder.find_tag_unsigned::<u16>(Tag::PhotometricInterpretation).map_err(error)? {
        Some(2) => Some("RGB"),
        Some(3) => Some("palette"),
        Some(5) => Some("CMYK"),
        Some(6) => Some("YCbCr"),
        Some(8..=10) => Some("CIELab"),
        Some(32844 | 32845) => Some("LogLuv"),
        _ => None,
    };
    if let Some(model) = model {
        return Err(GridFileError::Colour { kind: KIND, model });
    }
    let bands = decoder.find_tag_unsigned::<u16>(Tag::SamplesPerPixel).map_err(error)?.unwrap_or(1);
    if bands != 1 {
        return Err(GridFileError::MultiBand { bands });
    }
    if decoder.find_tag_unsigned::<u16>(Tag::PhotometricInterpretation).map_err(error)? == Some(0) {
        // The tiff crate inverts WhiteIsZero samples, which is meaningless for heights.
        let detail = "WhiteIsZero (inverted) greyscale; write it as BlackIsZero (MinIsBlack)".to_string();
        return Err(GridFileError::Unsupported { kind: KIND, detail });
    }
    Ok(())
}

/// Accepts 8-, 16- and 32-bit integers and 32- and 64-bit floats and returns their
/// (SampleFormat, BitsPerSample); refuses the rest before decoding (1-bit samples, say, would
/// come out packed eight to a byte).
fn check_sample_type<R: Read + Seek>(decoder: &mut Decoder<R>) -> Result<(u16, u16), GridFileError> {
    let first = |v: Option<Vec<u16>>, default| v.and_then(|v| v.first().copied()).unwrap_or(default);
    let bits = first(decoder.find_tag_unsigned_vec::<u16>(Tag::BitsPerSample).map_err(error)?, 1);
    let format = first(decoder.find_tag_unsigned_vec::<u16>(Tag::SampleFormat).map_err(error)?, 1);
    let found = match (format, bits) {
        (1, 8 | 16 | 32) | (2, 8 | 16 | 32) | (3, 32 | 64) => return Ok((format, bits)),
        (1, _) => format!("{bits}-bit unsigned integer"),
        (2, _) => format!("{bits}-bit signed integer"),
        (3, _) => format!("{bits}-bit float"),
        _ => format!("{bits}-bit samples of SampleFormat {format}"),
    };
    Err(GridFileError::UnsupportedType { kind: KIND, found, supported: SUPPORTED })
}

/// `GDAL_NODATA` (tag 42113): the value as ASCII, compared as the samples' own type would.
fn nodata<R: Read + Seek>(decoder: &mut Decoder<R>, is_f32: bool) -> Result<Option<NoData>, GridFileError> {
    let Some(value) = decoder.find_tag(Tag::GdalNodata).map_err(error)? else { return Ok(None) };
    let text = value.into_string().map_err(error)?;
    let text = text.trim_matches(|c: char| c.is_whitespace() || c == '\0');
    let value: f64 = text.parse().map_err(|_| GridFileError::Unsupported {
        kind: KIND,
        detail: detail(format!("GDAL_NODATA `{text}` is not a number")),
    })?;
    // GDAL may write fewer digits than an f32 needs (-3.4e+38): compare after rounding the
    // value to f32, as GDAL does.
    Ok(Some(NoData(if is_f32 { f64::from(value as f32) } else { value })))
}

/// Every number in a tag's value, of whatever numeric type.
fn numbers(value: Value) -> Vec<f64> {
    match value {
        Value::List(list) => list.into_iter().flat_map(numbers).collect(),
        Value::Double(v) => vec![v],
        Value::Float(v) => vec![f64::from(v)],
        Value::Short(v) => vec![f64::from(v)],
        Value::Unsigned(v) => vec![f64::from(v)],
        Value::Signed(v) => vec![f64::from(v)],
        _ => Vec::new(),
    }
}

fn find_numbers<R: Read + Seek>(decoder: &mut Decoder<R>, tag: Tag) -> TiffResult<Option<Vec<f64>>> {
    Ok(decoder.find_tag(tag)?.map(numbers))
}

/// The rectangle through the centres of the corner pixels, from ModelPixelScale and
/// ModelTiepoint or from an axis-aligned ModelTransformation; `None` when the file has
/// neither, or only a rotation or ground control points.
fn domain<R: Read + Seek>(
    decoder: &mut Decoder<R>,
    shape: Shape,
    keys: Option<&[u16]>,
) -> Result<Option<Rect>, GridFileError> {
    let scale = find_numbers(decoder, Tag::ModelPixelScaleTag).map_err(error)?;
    let tiepoint = find_numbers(decoder, Tag::ModelTiepointTag).map_err(error)?;
    let transform = find_numbers(decoder, Tag::ModelTransformationTag).map_err(error)?;
    // (raster point I, J) ↦ (model X, Y), and the size of a pixel in model units.
    let (i0, j0, x0, y0, sx, sy) = match (scale.as_deref(), tiepoint.as_deref(), transform.as_deref()) {
        (Some([sx, sy, ..]), Some([i, j, _, x, y, ..]), _) => (*i, *j, *x, *y, *sx, *sy),
        // Row-major 4×4: X = a·I + b·J + d, Y = e·I + f·J + h; axis-aligned when b = e = 0.
        (_, _, Some([a, b, _, d, e, f, _, h, ..])) if *b == 0.0 && *e == 0.0 => (0.0, 0.0, *d, *h, *a, -*f),
        _ => return Ok(None),
    };
    if !(sx > 0.0 && sy > 0.0) {
        let detail = format!("GeoTIFF pixel size ({sx}, {sy}) must be positive, with north up");
        return Err(GridFileError::Unsupported { kind: KIND, detail });
    }
    // PixelIsArea (the default) ties the raster point to a pixel's corner; its centre is half
    // a pixel further in. PixelIsPoint ties it to the centre.
    let centre = if raster_type(keys) == Some(PIXEL_IS_POINT) { 0.0 } else { 0.5 };
    let x = |column: usize| x0 + (column as f64 + centre - i0) * sx;
    // Image rows run down, model y up.
    let y = |row: usize| y0 - (row as f64 + centre - j0) * sy;
    let rect = Rect::new(x(0), x(shape.nx - 1), y(shape.ny - 1), y(0)).map_err(GridFileError::Domain)?;
    Ok(Some(rect))
}

/// The value of `GTRasterTypeGeoKey` in a GeoKeyDirectory.
fn raster_type(keys: Option<&[u16]>) -> Option<u16> {
    key(keys, RASTER_TYPE_KEY)
}

/// The value of short key `id` in a GeoKeyDirectory: a header of four shorts (the fourth the
/// number of keys), then four shorts per key (id, location, count, value); location 0 means
/// the value is the short itself.
fn key(keys: Option<&[u16]>, id: u16) -> Option<u16> {
    let keys = keys?;
    let count = usize::from(*keys.get(3)?);
    keys.get(4..)?.chunks_exact(4).take(count).find(|k| k[0] == id && k[1] == 0).map(|k| k[3])
}

/// The system the keys name: by the model type, else by whichever EPSG key is there.
/// 32767 is GeoTIFF's "user-defined".
fn crs(keys: Option<&[u16]>) -> Option<Crs> {
    let code = |id| key(keys, id).filter(|&c| c != 0 && c != 32767);
    match key(keys, MODEL_TYPE_KEY) {
        Some(MODEL_GEOGRAPHIC) => Some(Crs::Geographic(code(GEOGRAPHIC_TYPE_KEY))),
        Some(MODEL_PROJECTED) => Some(Crs::Projected(code(PROJECTED_TYPE_KEY))),
        _ => match (code(PROJECTED_TYPE_KEY), code(GEOGRAPHIC_TYPE_KEY)) {
            (Some(p), _) => Some(Crs::Projected(Some(p))),
            (None, Some(g)) => Some(Crs::Geographic(Some(g))),
            (None, None) => None,
        },
    }
}
