//! Writes the README quick start's grid files into `examples/grids/`, one per format the API
//! reads, all holding the heights of the Terrarium tile in `examples/tiles/` (jacksboro, from
//! matplotlib's sample data: 256 × 256 SRTM-derived heights in whole metres, 310–1040 m).
//! Run with `cargo run --example sample_grids`; `tests/cli.rs` checks that every file
//! decodes to the tile's heights.
//!
//! Every file stores the tile's rows as the tile does, the first row north, so each decodes to
//! the same grid. The heights are whole numbers below 2^15, so 16-bit integers and f32 hold them
//! exactly.

use meshfit::source::{Encoding, Grid, GridHints, decode_grid};
use std::io::Cursor;
use std::path::Path;
use tiff::encoder::{Compression, DeflateLevel, TiffEncoder, colortype};
use tiff::tags::Tag;

/// Metres per pixel and the model coordinates of the first pixel's corner of `dem.tif`: an
/// illustrative placement (SRTM's 1 arc-second is about 30 m), not the tile's real one.
const PIXEL_METRES: f64 = 30.0;
const ORIGIN: (f64, f64) = (500_000.0, 4_000_000.0);

/// The same for `dem-4326.tif`, in degrees of longitude and latitude (EPSG:4326), for
/// `meshfit tiles`: one arc-second pixels, the first one's corner at 98.25°W 33.3°N, near
/// Jacksboro, Texas (again an illustrative placement).
const PIXEL_DEGREES: f64 = 1.0 / 3600.0;
const ORIGIN_DEGREES: (f64, f64) = (-98.25, 33.3);

/// A GeoKeyDirectory naming EPSG:4326: version 1.1.0 with two keys, GTModelTypeGeoKey =
/// geographic and GeographicTypeGeoKey = 4326.
const WGS84_KEYS: [u16; 12] = [1, 1, 0, 2, 1024, 0, 1, 2, 2048, 0, 1, 4326];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples");
    let tile = std::fs::read(root.join("tiles/jacksboro-terrarium.png"))?;
    let hints = GridHints { encoding: Some(Encoding::Terrarium), ..GridHints::default() };
    let grid = decode_grid(&tile, &hints, usize::MAX)?.grid;
    let heights = north_first(&grid);
    let (nx, ny) = (grid.nx(), grid.ny());
    let out = root.join("grids");
    std::fs::create_dir_all(&out)?;

    let as_i16: Vec<i16> = heights.iter().map(|&h| h as i16).collect();
    std::fs::write(out.join("heights.npy"), npy_i16(&as_i16, nx, ny))?;
    let as_f32: Vec<f32> = heights.iter().map(|&h| h as f32).collect();
    std::fs::write(
        out.join("heights.f32"),
        as_f32.iter().flat_map(|h| h.to_le_bytes()).collect::<Vec<u8>>(),
    )?;
    let as_u16: Vec<u16> = heights.iter().map(|&h| h as u16).collect();
    std::fs::write(out.join("heightmap.png"), png_u16(&as_u16, nx, ny)?)?;
    std::fs::write(out.join("dem.tif"), geotiff_f32(&as_f32, nx, ny, PIXEL_METRES, ORIGIN, None)?)?;
    let wgs84 = Some(&WGS84_KEYS[..]);
    std::fs::write(
        out.join("dem-4326.tif"),
        geotiff_f32(&as_f32, nx, ny, PIXEL_DEGREES, ORIGIN_DEGREES, wgs84)?,
    )?;
    println!("wrote {nx} x {ny} heights to {}", out.display());
    Ok(())
}

/// The grid's values with the northern row (the last, j = ny − 1) first, as images store them.
fn north_first(grid: &Grid) -> Vec<f64> {
    (0..grid.ny()).rev().flat_map(|j| grid.row(j).iter().copied()).collect()
}

/// A version 1.0 .npy of little-endian i16, C order, shape (rows, columns).
fn npy_i16(values: &[i16], nx: usize, ny: usize) -> Vec<u8> {
    let mut header = format!("{{'descr': '<i2', 'fortran_order': False, 'shape': ({ny}, {nx}), }}");
    // The magic (6), version (2) and length (2) and the header, newline included, fill a
    // multiple of 64 bytes.
    let unpadded = 10 + header.len() + 1;
    header.push_str(&" ".repeat(unpadded.next_multiple_of(64) - unpadded));
    header.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&u16::try_from(header.len()).expect("a short header").to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    bytes.extend(values.iter().flat_map(|v| v.to_le_bytes()));
    bytes
}

/// A 16-bit greyscale PNG.
fn png_u16(values: &[u16], nx: usize, ny: usize) -> Result<Vec<u8>, png::EncodingError> {
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, nx as u32, ny as u32);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::Sixteen);
    let mut writer = encoder.write_header()?;
    writer.write_image_data(&values.iter().flat_map(|v| v.to_be_bytes()).collect::<Vec<u8>>())?;
    writer.finish()?;
    Ok(bytes)
}

/// A deflated f32 GeoTIFF placed by ModelPixelScale (`pixel`) and ModelTiepoint (`origin`,
/// the first pixel's corner: pixel is area), with GeoKeys `keys` when given.
fn geotiff_f32(
    values: &[f32],
    nx: usize,
    ny: usize,
    pixel: f64,
    origin: (f64, f64),
    keys: Option<&[u16]>,
) -> Result<Vec<u8>, tiff::TiffError> {
    let mut bytes = Vec::new();
    let compression = Compression::Deflate(DeflateLevel::Best);
    let mut encoder = TiffEncoder::new(Cursor::new(&mut bytes))?.with_compression(compression);
    let mut image = encoder.new_image::<colortype::Gray32Float>(nx as u32, ny as u32)?;
    image.encoder().write_tag(Tag::ModelPixelScaleTag, &[pixel, pixel, 0.0][..])?;
    image.encoder().write_tag(Tag::ModelTiepointTag, &[0.0, 0.0, 0.0, origin.0, origin.1, 0.0][..])?;
    if let Some(keys) = keys {
        image.encoder().write_tag(Tag::GeoKeyDirectoryTag, keys)?;
    }
    image.write_data(values)?;
    Ok(bytes)
}
