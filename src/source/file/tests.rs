//! Tests of grid-file decoding: the same grid through every format, orientation, the GeoTIFF
//! domain, holes, refusals with their places, size limits before allocation, and no panics on
//! arbitrary bytes. Every file is made here with the formats' own encoders (or, for .npy,
//! byte for byte as numpy writes it).

use super::kind::PNG_SIGNATURE;
use super::*;
use crate::geom::Rect;
use crate::source::Grid;
use crate::source::decode_values;
use ::png::{BitDepth, ColorType};
use ::tiff::encoder::colortype::{self, ColorType as TiffColour};
use ::tiff::encoder::{
    Compression, DeflateLevel, DirectoryEncoder, TiffEncoder, TiffKindStandard, TiffValue,
};
use ::tiff::tags::Tag;
use proptest::prelude::*;
use std::io::Cursor;

/// The default MESHFIT_MAX_GRID_POINTS.
const LIMIT: usize = 16_777_216;

/// An asymmetric grid, so a transposed or flipped decode cannot pass.
const NX: usize = 4;
const NY: usize = 3;

/// F at node (i, j): the value names its node.
fn f(i: usize, j: usize) -> f64 {
    (10 * i + j) as f64
}

/// The grid every format below encodes.
fn expected() -> Grid {
    Grid::new(NX, NY, (0..NY).flat_map(|j| (0..NX).map(move |i| f(i, j))).collect()).unwrap()
}

/// The samples in image order: the top row (j = NY − 1) first.
fn image<T>(conv: impl Fn(f64) -> T) -> Vec<T> {
    (0..NY).flat_map(|r| (0..NX).map(move |c| (c, NY - 1 - r))).map(|(i, j)| conv(f(i, j))).collect()
}

fn decode(bytes: &[u8]) -> Result<DecodedGrid, GridFileError> {
    decode_grid(bytes, &GridHints::default(), LIMIT)
}

fn no_hints() -> GridHints {
    GridHints::default()
}

fn raw_hints(nx: usize, ny: usize, dtype: RawType) -> GridHints {
    GridHints { nx: Some(nx), ny: Some(ny), dtype: Some(dtype), ..GridHints::default() }
}

/// A .npy file as numpy's `format.write_array` lays it out: version 1.0, the header padded with
/// spaces to a multiple of 64 bytes and ended by a newline.
fn npy(descr: &str, fortran: bool, shape: &[usize], data: &[u8]) -> Vec<u8> {
    let dims: Vec<String> = shape.iter().map(usize::to_string).collect();
    let dims = if dims.len() == 1 { format!("{},", dims[0]) } else { dims.join(", ") };
    let order = if fortran { "True" } else { "False" };
    let mut header = format!("{{'descr': '{descr}', 'fortran_order': {order}, 'shape': ({dims}), }}");
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend((header.len() as u16).to_le_bytes());
    out.extend(header.as_bytes());
    out.extend(data);
    out
}

/// The image-order samples of `expected()` as bytes, by `to_bytes`.
fn image_bytes<const N: usize>(to_bytes: impl Fn(f64) -> [u8; N]) -> Vec<u8> {
    image(to_bytes).concat()
}

fn png(width: u32, height: u32, colour: ColorType, depth: BitDepth, data: &[u8]) -> Vec<u8> {
    png_with(width, height, colour, depth, data, |_| {})
}

fn png_with(
    width: u32,
    height: u32,
    colour: ColorType,
    depth: BitDepth,
    data: &[u8],
    setup: impl FnOnce(&mut ::png::Encoder<'_, &mut Vec<u8>>),
) -> Vec<u8> {
    let mut bytes = Vec::new();
    let mut encoder = ::png::Encoder::new(&mut bytes, width, height);
    encoder.set_color(colour);
    encoder.set_depth(depth);
    setup(&mut encoder);
    let mut writer = encoder.write_header().unwrap();
    writer.write_image_data(data).unwrap();
    writer.finish().unwrap();
    bytes
}

type Dir<'a, 'b, K> = DirectoryEncoder<'a, Cursor<&'b mut Vec<u8>>, K>;

/// A TIFF of `C` samples written by the `tiff` crate, with `tags` added to its directory.
fn tiff_with<C: TiffColour>(
    width: u32,
    height: u32,
    data: &[C::Inner],
    compression: Compression,
    tags: impl FnOnce(&mut Dir<'_, '_, TiffKindStandard>),
) -> Vec<u8>
where
    [C::Inner]: TiffValue,
{
    let mut bytes = Vec::new();
    let mut encoder = TiffEncoder::new(Cursor::new(&mut bytes)).unwrap().with_compression(compression);
    let mut image = encoder.new_image::<C>(width, height).unwrap();
    tags(image.encoder());
    image.write_data(data).unwrap();
    bytes
}

fn tiff<C: TiffColour>(data: &[C::Inner]) -> Vec<u8>
where
    [C::Inner]: TiffValue,
{
    tiff_with::<C>(NX as u32, NY as u32, data, Compression::Uncompressed, |_| {})
}

fn big_tiff<C: TiffColour>(data: &[C::Inner]) -> Vec<u8>
where
    [C::Inner]: TiffValue,
{
    let mut bytes = Vec::new();
    let mut encoder = TiffEncoder::new_big(Cursor::new(&mut bytes)).unwrap();
    encoder.write_image::<C>(NX as u32, NY as u32, data).unwrap();
    bytes
}

fn json(nx: usize, ny: usize, values: &[f64]) -> Vec<u8> {
    serde_json::json!({"nx": nx, "ny": ny, "values": values}).to_string().into_bytes()
}

#[test]
fn the_same_grid_comes_out_of_every_format() {
    let grid_order: Vec<f64> = (0..NY).flat_map(|j| (0..NX).map(move |i| f(i, j))).collect();
    let u8s = image(|v| v as u8);
    let cases: Vec<(&str, Vec<u8>, GridHints)> = vec![
        ("json", json(NX, NY, &grid_order), no_hints()),
        ("npy <f8", npy("<f8", false, &[NY, NX], &image_bytes(f64::to_le_bytes)), no_hints()),
        ("npy >f8", npy(">f8", false, &[NY, NX], &image_bytes(f64::to_be_bytes)), no_hints()),
        ("npy <f4", npy("<f4", false, &[NY, NX], &image_bytes(|v| (v as f32).to_le_bytes())), no_hints()),
        ("npy >i2", npy(">i2", false, &[NY, NX], &image_bytes(|v| (v as i16).to_be_bytes())), no_hints()),
        ("npy <u2", npy("<u2", false, &[NY, NX], &image_bytes(|v| (v as u16).to_le_bytes())), no_hints()),
        ("npy |u1", npy("|u1", false, &[NY, NX], &u8s), no_hints()),
        ("npy <i4", npy("<i4", false, &[NY, NX], &image_bytes(|v| (v as i32).to_le_bytes())), no_hints()),
        (
            "npy <f8 fortran",
            {
                // Column-major: the first column top to bottom, then the next.
                let columns: Vec<[u8; 8]> =
                    (0..NX).flat_map(|c| (0..NY).map(move |r| f(c, NY - 1 - r).to_le_bytes())).collect();
                npy("<f8", true, &[NY, NX], &columns.concat())
            },
            no_hints(),
        ),
        ("png 8-bit", png(NX as u32, NY as u32, ColorType::Grayscale, BitDepth::Eight, &u8s), no_hints()),
        (
            "png 16-bit",
            png(
                NX as u32,
                NY as u32,
                ColorType::Grayscale,
                BitDepth::Sixteen,
                &image_bytes(|v| (v as u16).to_be_bytes()),
            ),
            no_hints(),
        ),
        ("tiff u8", tiff::<colortype::Gray8>(&u8s), no_hints()),
        ("tiff u16", tiff::<colortype::Gray16>(&image(|v| v as u16)), no_hints()),
        ("tiff u32", tiff::<colortype::Gray32>(&image(|v| v as u32)), no_hints()),
        ("tiff i8", tiff::<colortype::GrayI8>(&image(|v| v as i8)), no_hints()),
        ("tiff i16", tiff::<colortype::GrayI16>(&image(|v| v as i16)), no_hints()),
        ("tiff i32", tiff::<colortype::GrayI32>(&image(|v| v as i32)), no_hints()),
        ("tiff f32", tiff::<colortype::Gray32Float>(&image(|v| v as f32)), no_hints()),
        ("tiff f64", tiff::<colortype::Gray64Float>(&image(|v| v)), no_hints()),
        (
            "tiff f32 deflate",
            tiff_with::<colortype::Gray32Float>(
                NX as u32,
                NY as u32,
                &image(|v| v as f32),
                Compression::Deflate(DeflateLevel::Balanced),
                |_| {},
            ),
            no_hints(),
        ),
        (
            "tiff i16 lzw",
            tiff_with::<colortype::GrayI16>(
                NX as u32,
                NY as u32,
                &image(|v| v as i16),
                Compression::Lzw,
                |_| {},
            ),
            no_hints(),
        ),
        ("bigtiff f64", big_tiff::<colortype::Gray64Float>(&image(|v| v)), no_hints()),
        ("raw f32", image_bytes(|v| (v as f32).to_le_bytes()), raw_hints(NX, NY, RawType::F32)),
        ("raw f64", image_bytes(f64::to_le_bytes), raw_hints(NX, NY, RawType::F64)),
    ];
    for (name, bytes, hints) in cases {
        let decoded = decode_grid(&bytes, &hints, LIMIT).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(decoded.grid, expected(), "{name}");
        assert_eq!(decoded.domain, None, "{name}");
        let kind = name.split(' ').next().unwrap();
        let kind = if kind == "bigtiff" { "tiff" } else { kind };
        assert_eq!(decoded.kind.name().to_lowercase(), kind, "{name}");
    }
}

#[test]
fn node_i_j_is_column_i_of_the_image_row_counted_from_the_bottom() {
    // The top image row holds j = NY − 1 = 2: values 2, 12, 22, 32.
    let bytes = png(NX as u32, NY as u32, ColorType::Grayscale, BitDepth::Eight, &image(|v| v as u8));
    assert_eq!(&bytes_of_row(&bytes, 0), &[2, 12, 22, 32]);
    let grid = decode(&bytes).unwrap().grid;
    assert_eq!(grid.row(NY - 1), &[2.0, 12.0, 22.0, 32.0]);
    assert_eq!(grid.row(0), &[0.0, 10.0, 20.0, 30.0]);
    assert_eq!(grid.value(3, 1), 31.0);
}

/// Row `r` of an 8-bit greyscale PNG, decoded by the png crate directly.
fn bytes_of_row(bytes: &[u8], r: usize) -> Vec<u8> {
    let mut reader = ::png::Decoder::new(Cursor::new(bytes)).read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    reader.next_frame(&mut buf).unwrap();
    buf[r * NX..(r + 1) * NX].to_vec()
}

#[test]
fn files_written_by_numpy_decode_to_the_same_grid() {
    // python3 -c "import numpy as np, io; a = np.array([[10*c + 2 - r for c in range(4)]
    //   for r in range(3)]); b = io.BytesIO(); np.save(b, a.astype('<f8')); print(b.getvalue())"
    // (numpy 2.4.6), and likewise np.asfortranarray(a.astype('>i2')).
    let c_order_f8 = b"\x93NUMPY\x01\x00v\x00{'descr': '<f8', 'fortran_order': False, 'shape': (3, 4), }                                                          \x0a\x00\x00\x00\x00\x00\x00\x00@\x00\x00\x00\x00\x00\x00(@\x00\x00\x00\x00\x00\x006@\x00\x00\x00\x00\x00\x00@@\x00\x00\x00\x00\x00\x00\xf0?\x00\x00\x00\x00\x00\x00&@\x00\x00\x00\x00\x00\x005@\x00\x00\x00\x00\x00\x00?@\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00$@\x00\x00\x00\x00\x00\x004@\x00\x00\x00\x00\x00\x00>@";
    let fortran_i2_big_endian = b"\x93NUMPY\x01\x00v\x00{'descr': '>i2', 'fortran_order': True, 'shape': (3, 4), }                                                           \x0a\x00\x02\x00\x01\x00\x00\x00\x0c\x00\x0b\x00\x0a\x00\x16\x00\x15\x00\x14\x00 \x00\x1f\x00\x1e";
    for (name, bytes) in [("<f8 C order", &c_order_f8[..]), (">i2 Fortran order", &fortran_i2_big_endian[..])]
    {
        let decoded = decode(bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!((decoded.kind, decoded.grid), (GridFileKind::Npy, expected()), "{name}");
    }
}

#[test]
fn a_sixteen_bit_png_keeps_its_full_range() {
    let samples: [u16; 4] = [0, 1, 32768, 65535];
    let data: Vec<u8> = samples.iter().flat_map(|s| s.to_be_bytes()).collect();
    let grid = decode(&png(2, 2, ColorType::Grayscale, BitDepth::Sixteen, &data)).unwrap().grid;
    // Image rows [0, 1] (top) and [32768, 65535] (bottom): the bottom row is j = 0.
    assert_eq!(grid.row(0), &[32768.0, 65535.0]);
    assert_eq!(grid.row(1), &[0.0, 1.0]);
}

/// ModelPixelScale (10, 5) and the tie point raster (0, 0) ↦ model (1000, 2000).
fn geotiff(extra: impl FnOnce(&mut Dir<'_, '_, TiffKindStandard>)) -> Vec<u8> {
    tiff_with::<colortype::Gray32Float>(
        NX as u32,
        NY as u32,
        &image(|v| v as f32),
        Compression::Uncompressed,
        |d| {
            d.write_tag(Tag::ModelPixelScaleTag, &[10.0f64, 5.0, 0.0][..]).unwrap();
            d.write_tag(Tag::ModelTiepointTag, &[0.0f64, 0.0, 0.0, 1000.0, 2000.0, 0.0][..]).unwrap();
            extra(d);
        },
    )
}

#[test]
fn geotiff_domain_runs_through_the_corner_pixel_centres() {
    // PixelIsArea (the default): the tie point is the top-left corner of the top-left pixel,
    // whose centre is half a pixel in: x = 1000 + 0.5·10, y = 2000 − 0.5·5.
    let decoded = decode(&geotiff(|_| {})).unwrap();
    assert_eq!(decoded.grid, expected());
    let rect = Rect::new(1005.0, 1035.0, 1987.5, 1997.5).unwrap();
    assert_eq!(decoded.domain, Some(rect));
}

#[test]
fn geotiff_pixel_is_point_ties_the_pixel_centre() {
    // GeoKeyDirectory version 1.1.0 with one key: GTRasterTypeGeoKey = RasterPixelIsPoint.
    let keys: [u16; 8] = [1, 1, 0, 1, 1025, 0, 1, 2];
    let decoded = decode(&geotiff(|d| d.write_tag(Tag::GeoKeyDirectoryTag, &keys[..]).unwrap())).unwrap();
    assert_eq!(decoded.domain, Some(Rect::new(1000.0, 1030.0, 1990.0, 2000.0).unwrap()));
}

#[test]
fn geotiff_keys_name_the_coordinate_system() {
    use crate::source::Crs;
    let with =
        |keys: &[u16]| decode(&geotiff(|d| d.write_tag(Tag::GeoKeyDirectoryTag, keys).unwrap())).unwrap().crs;
    // GTModelType geographic, GeographicType 4326 (WGS84).
    assert_eq!(with(&[1, 1, 0, 2, 1024, 0, 1, 2, 2048, 0, 1, 4326]), Some(Crs::Geographic(Some(4326))));
    // GTModelType projected, ProjectedCSType 32633 (UTM 33N).
    assert_eq!(with(&[1, 1, 0, 2, 1024, 0, 1, 1, 3072, 0, 1, 32633]), Some(Crs::Projected(Some(32633))));
    // A user-defined projected system (32767), and no model type but an EPSG key.
    assert_eq!(with(&[1, 1, 0, 2, 1024, 0, 1, 1, 3072, 0, 1, 32767]), Some(Crs::Projected(None)));
    assert_eq!(with(&[1, 1, 0, 1, 3072, 0, 1, 3857]), Some(Crs::Projected(Some(3857))));
    assert_eq!(with(&[1, 1, 0, 1, 1025, 0, 1, 2]), None);
    assert_eq!(decode(&geotiff(|_| {})).unwrap().crs, None);
}

#[test]
fn an_axis_aligned_model_transformation_gives_the_same_domain() {
    #[rustfmt::skip]
    let matrix: [f64; 16] = [
        10.0, 0.0, 0.0, 1000.0,
        0.0, -5.0, 0.0, 2000.0,
        0.0, 0.0, 0.0, 0.0,
        0.0, 0.0, 0.0, 1.0,
    ];
    let bytes = tiff_with::<colortype::Gray8>(
        NX as u32,
        NY as u32,
        &image(|v| v as u8),
        Compression::Uncompressed,
        |d| d.write_tag(Tag::ModelTransformationTag, &matrix[..]).unwrap(),
    );
    assert_eq!(decode(&bytes).unwrap().domain, Some(Rect::new(1005.0, 1035.0, 1987.5, 1997.5).unwrap()));
}

#[test]
fn a_nodata_sample_is_an_error_naming_its_index() {
    let mut samples = image(|v| v as i16);
    // Image row 0 is the top row, j = NY − 1; column 2.
    samples[2] = -9999;
    let bytes =
        tiff_with::<colortype::GrayI16>(NX as u32, NY as u32, &samples, Compression::Uncompressed, |d| {
            d.write_tag(Tag::GdalNodata, "-9999").unwrap()
        });
    let err = decode(&bytes).unwrap_err();
    assert_eq!(err, GridFileError::NoData { i: 2, j: NY - 1, row: 0, value: -9999.0 });
    assert_eq!(err.index(), Some([2, 2]));
    assert_eq!(
        err.to_string(),
        "sample at index [2, 2] (file row 0, column 2) is the nodata value -9999; fill the holes before meshing"
    );
}

#[test]
fn a_float_nodata_written_with_few_digits_still_matches_its_f32_samples() {
    let mut samples = image(|v| v as f32);
    samples[NX + 1] = -3.4e38;
    let bytes =
        tiff_with::<colortype::Gray32Float>(NX as u32, NY as u32, &samples, Compression::Uncompressed, |d| {
            d.write_tag(Tag::GdalNodata, "-3.4e+38").unwrap()
        });
    assert_eq!(decode(&bytes).unwrap_err().index(), Some([1, 1]));
}

#[test]
fn a_nan_nodata_matches_nan_samples() {
    let mut samples = image(|v| v as f32);
    samples[NX * NY - 1] = f32::NAN;
    let bytes =
        tiff_with::<colortype::Gray32Float>(NX as u32, NY as u32, &samples, Compression::Uncompressed, |d| {
            d.write_tag(Tag::GdalNodata, "nan").unwrap()
        });
    assert!(matches!(decode(&bytes).unwrap_err(), GridFileError::NoData { i: 3, j: 0, row: 2, .. }));
}

#[test]
fn a_nodata_value_absent_from_the_samples_changes_nothing() {
    let bytes = tiff_with::<colortype::GrayI16>(
        NX as u32,
        NY as u32,
        &image(|v| v as i16),
        Compression::Uncompressed,
        |d| d.write_tag(Tag::GdalNodata, "-32768").unwrap(),
    );
    assert_eq!(decode(&bytes).unwrap().grid, expected());
}

#[test]
fn a_non_finite_sample_is_an_error_naming_its_index() {
    let mut samples = image(|v| v);
    samples[1] = f64::INFINITY; // top row, column 1
    let bytes =
        npy("<f8", false, &[NY, NX], &samples.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<_>>());
    let err = decode(&bytes).unwrap_err();
    assert_eq!(err, GridFileError::NonFinite { kind: GridFileKind::Npy, i: 1, j: 2, row: 0 });
    assert_eq!(err.index(), Some([1, 2]));
    let raw: Vec<u8> = samples.iter().flat_map(|v| (*v as f32).to_le_bytes()).collect();
    let err = decode_grid(&raw, &raw_hints(NX, NY, RawType::F32), LIMIT).unwrap_err();
    assert_eq!(err.index(), Some([1, 2]));
}

#[test]
fn negative_zero_becomes_zero() {
    let samples = [-0.0f64, 1.0, 2.0, 3.0];
    let bytes: Vec<u8> = samples.iter().flat_map(|v| v.to_le_bytes()).collect();
    let grid = decode_grid(&bytes, &raw_hints(2, 2, RawType::F64), LIMIT).unwrap().grid;
    assert!(grid.value(0, 1).is_sign_positive());
}

#[test]
fn an_opaque_grey_alpha_png_decodes_like_plain_grey() {
    let data: Vec<u8> = image(|v| [v as u8, 255]).concat();
    let bytes = png(NX as u32, NY as u32, ColorType::GrayscaleAlpha, BitDepth::Eight, &data);
    assert_eq!(decode(&bytes).unwrap().grid, expected());
}

#[test]
fn a_transparent_png_pixel_is_an_error_naming_its_index() {
    let mut data: Vec<[u8; 4]> = image(|v| {
        let [hi, lo] = (v as u16).to_be_bytes();
        [hi, lo, 255, 255]
    });
    data[NX * 2 + 3][3] = 254; // bottom row, column 3: alpha 65534 of 65535
    let bytes = png(NX as u32, NY as u32, ColorType::GrayscaleAlpha, BitDepth::Sixteen, &data.concat());
    let err = decode(&bytes).unwrap_err();
    assert_eq!(err, GridFileError::Transparent { i: 3, j: 0, row: 2 });
}

#[test]
fn a_png_grey_marked_transparent_by_trns_is_an_error() {
    let bytes =
        png_with(NX as u32, NY as u32, ColorType::Grayscale, BitDepth::Eight, &image(|v| v as u8), |e| {
            e.set_trns(vec![0, 21])
        });
    // 21 = f(2, 1).
    assert_eq!(decode(&bytes).unwrap_err().index(), Some([2, 1]));
}

#[test]
fn a_colour_png_is_refused_as_colour() {
    let rgb = png(2, 2, ColorType::Rgb, BitDepth::Eight, &[0; 12]);
    let err = decode(&rgb).unwrap_err();
    assert_eq!(err, GridFileError::Colour { kind: GridFileKind::Png, model: "RGB" });
    assert_eq!(
        err.to_string(),
        "PNG is RGB colour; send a greyscale heightmap, or give the encoding of an elevation tile \
         (terrain-rgb or terrarium)"
    );
    let rgba = png(2, 2, ColorType::Rgba, BitDepth::Eight, &[0; 16]);
    assert_eq!(decode(&rgba).unwrap_err(), GridFileError::Colour { kind: GridFileKind::Png, model: "RGBA" });
    let palette = png_with(2, 2, ColorType::Indexed, BitDepth::Eight, &[0; 4], |e| {
        e.set_palette(vec![0, 0, 0, 9, 9, 9])
    });
    assert_eq!(
        decode(&palette).unwrap_err(),
        GridFileError::Colour { kind: GridFileKind::Png, model: "palette" }
    );
}

fn tile(encoding: Encoding) -> GridHints {
    GridHints { encoding: Some(encoding), ..GridHints::default() }
}

/// The colour of height `h` in each encoding, by the formulas their publishers give.
fn colour_of(encoding: Encoding, h: f64) -> [u8; 3] {
    let code = match encoding {
        Encoding::TerrainRgb => ((h + 10000.0) * 10.0).round() as u32,
        Encoding::Terrarium => ((h + 32768.0) * 256.0).round() as u32,
    };
    [(code >> 16) as u8, (code >> 8) as u8, code as u8]
}

#[test]
fn elevation_tiles_in_both_encodings_decode_to_their_heights_north_up() {
    // Heights with tenths (Terrain-RGB's step) and 256ths (Terrarium's), below sea level too.
    let height = |v: f64| v * 37.5 - 412.3;
    for encoding in [Encoding::TerrainRgb, Encoding::Terrarium] {
        let rgb: Vec<u8> = image(|v| colour_of(encoding, height(v))).concat();
        let rgba: Vec<u8> = image(|v| {
            let [r, g, b] = colour_of(encoding, height(v));
            [r, g, b, 255]
        })
        .concat();
        for (colour, data) in [(ColorType::Rgb, rgb), (ColorType::Rgba, rgba)] {
            let bytes = png(NX as u32, NY as u32, colour, BitDepth::Eight, &data);
            let grid = decode_grid(&bytes, &tile(encoding), LIMIT).unwrap().grid;
            for j in 0..NY {
                for i in 0..NX {
                    let (got, want) = (grid.value(i, j), height(f(i, j)));
                    // Terrain-RGB keeps the tenths (as the nearest f64), Terrarium 256ths.
                    let step = if encoding == Encoding::Terrarium { 1.0 / 512.0 } else { 1e-9 };
                    assert!(
                        (got - want).abs() <= step,
                        "{encoding:?} {colour:?} ({i}, {j}): {got} vs {want}"
                    );
                }
            }
        }
    }
    // The formulas at their ends: Terrain-RGB's zero colour is −10000 m, Terrarium's 2^15 is 0.
    assert_eq!(Encoding::TerrainRgb.height([0, 0, 0]), -10000.0);
    assert_eq!(Encoding::TerrainRgb.height([1, 134, 160]), 0.0);
    assert_eq!(Encoding::TerrainRgb.height([255, 255, 255]), 1_667_721.5);
    assert_eq!(Encoding::Terrarium.height([128, 0, 0]), 0.0);
    assert_eq!(Encoding::Terrarium.height([0, 0, 0]), -32768.0);
    assert_eq!(Encoding::Terrarium.height([127, 255, 128]), -0.5);
}

#[test]
fn a_transparent_tile_pixel_is_nodata_naming_its_index() {
    let mut data: Vec<[u8; 4]> = image(|v| {
        let [r, g, b] = colour_of(Encoding::Terrarium, v);
        [r, g, b, 255]
    });
    data[3][3] = 0; // top row (j = 2), column 3
    let bytes = png(NX as u32, NY as u32, ColorType::Rgba, BitDepth::Eight, &data.concat());
    let err = decode_grid(&bytes, &tile(Encoding::Terrarium), LIMIT).unwrap_err();
    assert_eq!(err, GridFileError::Transparent { i: 3, j: 2, row: 0 });
    // An RGB tile's tRNS colour is a hole too.
    let rgb: Vec<u8> = image(|v| colour_of(Encoding::Terrarium, v)).concat();
    let [r, g, b] = colour_of(Encoding::Terrarium, f(1, 1));
    let keyed = png_with(NX as u32, NY as u32, ColorType::Rgb, BitDepth::Eight, &rgb, |e| {
        e.set_trns(vec![0, r, 0, g, 0, b])
    });
    assert_eq!(decode_grid(&keyed, &tile(Encoding::Terrarium), LIMIT).unwrap_err().index(), Some([1, 1]));
}

#[test]
fn an_encoding_is_refused_for_anything_but_an_eight_bit_colour_png() {
    let grey = png(NX as u32, NY as u32, ColorType::Grayscale, BitDepth::Eight, &image(|v| v as u8));
    let err = decode_grid(&grey, &tile(Encoding::TerrainRgb), LIMIT).unwrap_err();
    assert_eq!(err, GridFileError::NotATile { encoding: "terrain-rgb", found: "a greyscale PNG".into() });
    assert_eq!(
        err.to_string(),
        "encoding terrain-rgb is for 8-bit RGB or RGBA PNG tiles, not a greyscale PNG"
    );
    let deep = png(2, 2, ColorType::Rgb, BitDepth::Sixteen, &[0; 24]);
    let err = decode_grid(&deep, &tile(Encoding::Terrarium), LIMIT).unwrap_err();
    assert_eq!(err, GridFileError::NotATile { encoding: "terrarium", found: "a 16-bit colour PNG".into() });
    let npy = npy("<f8", false, &[NY, NX], &image_bytes(f64::to_le_bytes));
    let err = decode_grid(&npy, &tile(Encoding::Terrarium), LIMIT).unwrap_err();
    assert_eq!(err.to_string(), "encoding terrarium is for 8-bit RGB or RGBA PNG tiles, not an NPY file");
}

#[test]
fn a_png_of_fewer_than_eight_bits_is_an_unsupported_type() {
    let bytes = png(8, 2, ColorType::Grayscale, BitDepth::Four, &[0x12; 8]);
    assert!(matches!(
        decode(&bytes).unwrap_err(),
        GridFileError::UnsupportedType { kind: GridFileKind::Png, ref found, .. } if found == "4-bit greyscale"
    ));
}

#[test]
fn an_rgb_tiff_is_refused_as_colour() {
    let bytes = tiff_with::<colortype::RGB8>(2, 2, &[0; 12], Compression::Uncompressed, |_| {});
    assert_eq!(decode(&bytes).unwrap_err(), GridFileError::Colour { kind: GridFileKind::Tiff, model: "RGB" });
}

#[test]
fn a_multi_band_grey_tiff_is_refused() {
    // Three samples per pixel, declared grey (BlackIsZero) rather than RGB.
    let bytes = tiff_with::<colortype::RGB8>(2, 2, &[0; 12], Compression::Uncompressed, |d| {
        d.write_tag(Tag::PhotometricInterpretation, 1u16).unwrap()
    });
    let err = decode(&bytes).unwrap_err();
    assert_eq!(err, GridFileError::MultiBand { bands: 3 });
    assert_eq!(err.to_string(), "TIFF has 3 bands (samples per pixel); send a single-band raster");
}

#[test]
fn a_64_bit_integer_tiff_is_an_unsupported_type() {
    let bytes = tiff::<colortype::Gray64>(&image(|v| v as u64));
    assert!(matches!(
        decode(&bytes).unwrap_err(),
        GridFileError::UnsupportedType { kind: GridFileKind::Tiff, ref found, .. } if found == "64-bit unsigned integer"
    ));
}

#[test]
fn npy_arrays_that_are_not_2d_numbers_are_refused() {
    let three_d = npy("<f8", false, &[2, 2, 2], &[0; 64]);
    assert!(matches!(
        decode(&three_d).unwrap_err(),
        GridFileError::Unsupported { kind: GridFileKind::Npy, ref detail } if detail.contains("(2, 2, 2)")
    ));
    let complex = npy("<c16", false, &[2, 2], &[0; 64]);
    let err = decode(&complex).unwrap_err();
    assert!(matches!(err, GridFileError::UnsupportedType { ref found, .. } if found == "<c16"), "{err}");
    let int64 = npy("<i8", false, &[2, 2], &[0; 32]);
    assert!(matches!(decode(&int64).unwrap_err(), GridFileError::UnsupportedType { .. }));
}

#[test]
fn truncated_files_are_refused_as_corrupt_at_every_cut() {
    let u8s = image(|v| v as u8);
    let files = [
        (GridFileKind::Npy, npy("<f8", false, &[NY, NX], &image_bytes(f64::to_le_bytes))),
        (GridFileKind::Png, png(NX as u32, NY as u32, ColorType::Grayscale, BitDepth::Eight, &u8s)),
        (GridFileKind::Tiff, tiff::<colortype::Gray8>(&u8s)),
        (
            GridFileKind::Tiff,
            tiff_with::<colortype::Gray32Float>(
                NX as u32,
                NY as u32,
                &image(|v| v as f32),
                Compression::Deflate(DeflateLevel::Balanced),
                |_| {},
            ),
        ),
        (GridFileKind::Json, json(NX, NY, &expected_values())),
    ];
    for (kind, bytes) in files {
        // From past the magic bytes, so the format is still recognised, to before a PNG's
        // IEND chunk (12 bytes): without IEND, every pixel is still there.
        let end = if kind == GridFileKind::Png { bytes.len() - 12 } else { bytes.len() };
        for len in 8..end {
            let cut = &bytes[..len];
            match decode(cut) {
                Err(GridFileError::Corrupt { kind: k, .. } | GridFileError::SizeMismatch { kind: k, .. })
                    if k == kind => {}
                other => panic!("{kind} cut to {len} of {} bytes: {other:?}", bytes.len()),
            }
        }
    }
}

fn expected_values() -> Vec<f64> {
    (0..NY).flat_map(|j| (0..NX).map(move |i| f(i, j))).collect()
}

#[test]
fn a_truncated_npy_says_how_many_bytes_its_header_needs() {
    let bytes = npy("<f8", false, &[NY, NX], &image_bytes(f64::to_le_bytes));
    let err = decode(&bytes[..bytes.len() - 3]).unwrap_err();
    assert_eq!(err.to_string(), "NPY grid has 93 bytes of data, but the header's shape and dtype need 96");
}

#[test]
fn raw_data_of_the_wrong_size_is_refused() {
    let hints = raw_hints(NX, NY, RawType::F32);
    let err = decode_grid(&[0; 47], &hints, LIMIT).unwrap_err();
    assert_eq!(
        err,
        GridFileError::SizeMismatch {
            kind: GridFileKind::Raw,
            unit: "bytes of data",
            from: "the hints nx, ny and dtype",
            expected: 48,
            got: 47,
        }
    );
}

#[test]
fn raw_data_without_hints_names_the_missing_ones() {
    let hints = GridHints { nx: Some(4), ..GridHints::default() };
    let err = decode_grid(&[0; 48], &hints, LIMIT).unwrap_err();
    assert_eq!(err, GridFileError::MissingHints { missing: vec!["ny", "dtype"] });
    assert!(err.to_string().ends_with("(missing: ny, dtype)"), "{err}");
}

#[test]
fn an_empty_body_is_its_own_error() {
    assert_eq!(decode(b""), Err(GridFileError::Empty));
}

#[test]
fn a_body_starting_with_a_brace_is_json_unless_the_raw_hints_fit_it() {
    let body = format!("\n  {}", String::from_utf8(json(2, 2, &[1.0, 2.0, 3.0, 4.0])).unwrap());
    assert_eq!(decode(body.as_bytes()).unwrap().kind, GridFileKind::Json);
    // Four f32 samples whose first byte is `{`.
    let raw: Vec<u8> = [f32::from_le_bytes([b'{', 0, 0x80, 0x3f]), 2.0, 3.0, 4.0]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    assert_eq!(raw[0], b'{');
    let decoded = decode_grid(&raw, &raw_hints(2, 2, RawType::F32), LIMIT).unwrap();
    assert_eq!(decoded.kind, GridFileKind::Raw);
}

#[test]
fn json_errors_name_the_value_at_fault_or_come_from_the_json_parser_with_their_position() {
    let err = decode(br#"{"nx": 2, "ny": 2, "values": [1, 2, null, 4]}"#).unwrap_err();
    assert_eq!(err, GridFileError::NotANumber { i: 0, j: 1, index: 2, found: "null" });
    assert_eq!(err.index(), Some([0, 1]));
    let err = decode(br#"{"nx": 2, "ny": 2, "values": [1, 2, 3, 4"#).unwrap_err();
    assert!(
        matches!(&err, GridFileError::Corrupt { kind: GridFileKind::Json, detail } if detail.contains("column")),
        "{err}"
    );
    let err = decode(br#"{"nx": 2, "ny": 2, "values": [1, 2, 3, 4], "nz": 1}"#).unwrap_err();
    assert!(err.to_string().contains("unknown field `nz`"), "{err}");
    let err = decode(br#"{"nx": 2, "ny": 2, "values": [1, 2, 3]}"#).unwrap_err();
    assert_eq!(err.to_string(), "JSON grid has 3 values, but nx and ny need 4");
}

#[test]
fn the_api_values_decode_like_a_json_grid_file_and_check_the_limit_before_parsing() {
    let text = "[1, 2.5, -0.0, 4, 5, 6]";
    let grid = decode_values(text, 3, 2, LIMIT).unwrap();
    assert_eq!(grid, decode(br#"{"nx": 3, "ny": 2, "values": [1, 2.5, -0.0, 4, 5, 6]}"#).unwrap().grid);
    assert_eq!(grid.row(0), &[1.0, 2.5, 0.0]);
    assert!(grid.row(0)[2].is_sign_positive(), "-0.0 becomes 0.0");
    // Not valid JSON at all, but nx·ny is refused first.
    let err = decode_values("[oops", 1000, 1000, 10).unwrap_err();
    assert!(matches!(err, GridFileError::TooManyPoints { requested: 1_000_000, allowed: 10, .. }), "{err}");
    let err = decode_values(r#"[1, 2, "x", 4]"#, 2, 2, LIMIT).unwrap_err();
    assert_eq!(err.index(), Some([0, 1]));
}

#[test]
fn fewer_than_two_samples_along_an_axis_is_refused() {
    let bytes = png(5, 1, ColorType::Grayscale, BitDepth::Eight, &[0; 5]);
    assert_eq!(decode(&bytes).unwrap_err(), GridFileError::TooFewPoints { nx: 5, ny: 1 });
}

/// A PNG of only its signature, IHDR and IEND: the size it declares, none of the pixels.
fn png_header_only(width: u32, height: u32) -> Vec<u8> {
    let mut bytes = Vec::new();
    let mut encoder = ::png::Encoder::new(&mut bytes, width, height);
    encoder.set_color(ColorType::Grayscale);
    encoder.set_depth(BitDepth::Sixteen);
    drop(encoder.write_header().unwrap());
    bytes
}

/// A TIFF directory declaring `width` × `height` 8-bit samples in one strip of one byte.
fn tiff_header_only(width: u32, height: u32) -> Vec<u8> {
    let mut bytes = Vec::new();
    let mut encoder = TiffEncoder::new(Cursor::new(&mut bytes)).unwrap();
    let mut dir = encoder.image_directory().unwrap();
    let offset = dir.write_data(0u8).unwrap() as u32;
    for (tag, value) in [
        (Tag::ImageWidth, width),
        (Tag::ImageLength, height),
        (Tag::BitsPerSample, 8),
        (Tag::Compression, 1),
        (Tag::PhotometricInterpretation, 1),
        (Tag::StripOffsets, offset),
        (Tag::RowsPerStrip, height),
        (Tag::StripByteCounts, 1),
    ] {
        dir.write_tag(tag, value).unwrap();
    }
    dir.finish().unwrap();
    bytes
}

#[test]
fn huge_declared_dimensions_are_refused_from_the_header_alone() {
    let huge = 100_000usize;
    let requested = (huge * huge) as u64;
    let files = [
        ("npy", npy("<f8", false, &[huge, huge], &[])),
        ("png", png_header_only(huge as u32, huge as u32)),
        ("tiff", tiff_header_only(huge as u32, huge as u32)),
        ("json", json(huge, huge, &[])),
    ];
    for (name, bytes) in files {
        assert!(bytes.len() < 300, "{name}: {} bytes", bytes.len());
        let err = decode(&bytes).unwrap_err();
        assert_eq!(
            err,
            GridFileError::TooManyPoints { nx: huge as u64, ny: huge as u64, requested, allowed: LIMIT },
            "{name}"
        );
    }
    let hints = raw_hints(huge, huge, RawType::F64);
    assert!(matches!(decode_grid(&[0; 64], &hints, LIMIT), Err(GridFileError::TooManyPoints { .. })));
    let err = decode(&png_header_only(huge as u32, huge as u32)).unwrap_err();
    assert_eq!(
        err.to_string(),
        "grid nx * ny is 10000000000 (100000 x 100000), above the limit of 16777216 points"
    );
}

#[test]
fn a_png_too_short_for_its_declared_size_is_refused_before_its_buffer_is_allocated() {
    // 10^10 16-bit pixels would be 20 GB; with no limit on points, the file size still refuses
    // them, since deflate expands at most 1032-fold.
    let err = decode_grid(&png_header_only(100_000, 100_000), &no_hints(), usize::MAX).unwrap_err();
    assert!(
        matches!(&err, GridFileError::Corrupt { kind: GridFileKind::Png, detail } if detail.contains("cannot hold")),
        "{err}"
    );
}

/// A .npy header with `shape` written in as it stands, and no data.
fn npy_with_shape(shape: &str) -> Vec<u8> {
    let header = format!("{{'descr': '<f8', 'fortran_order': False, 'shape': {shape}, }}\n");
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend((header.len() as u16).to_le_bytes());
    out.extend(header.as_bytes());
    out
}

#[test]
fn a_dimension_beyond_u64_is_corrupt_not_a_panic() {
    let huge = 99_999_999_999_999_999_999u128;
    let err = decode(&npy_with_shape(&format!("({huge}, 1)"))).unwrap_err();
    assert!(matches!(err, GridFileError::Corrupt { kind: GridFileKind::Npy, .. }), "{err}");
    // 2^96 points: the product overflows u64 (npyz panics here under overflow checks).
    let err = decode(&npy_with_shape("(4294967296, 4294967296, 4294967296)")).unwrap_err();
    assert!(matches!(err, GridFileError::Unsupported { kind: GridFileKind::Npy, .. }), "{err}");
    let err = decode(&npy_with_shape("(4294967296, 4294967296)")).unwrap_err();
    assert!(matches!(err, GridFileError::TooManyPoints { requested: u64::MAX, .. }), "{err}");
}

#[test]
fn raw_types_deserialize_from_their_lowercase_names() {
    assert_eq!(serde_json::from_str::<RawType>(r#""f32""#).unwrap(), RawType::F32);
    assert_eq!(serde_json::from_str::<RawType>(r#""f64""#).unwrap(), RawType::F64);
    assert!(serde_json::from_str::<RawType>(r#""F32""#).is_err());
    assert_eq!(RawType::from_name("f64"), Some(RawType::F64));
    assert_eq!(RawType::F32.name(), "f32");
}

/// Valid files of every format, for mutation.
fn seeds() -> Vec<Vec<u8>> {
    let u8s = image(|v| v as u8);
    vec![
        npy("<f4", false, &[NY, NX], &image_bytes(|v| (v as f32).to_le_bytes())),
        npy(">i2", true, &[NY, NX], &image_bytes(|v| (v as i16).to_be_bytes())),
        png(
            NX as u32,
            NY as u32,
            ColorType::GrayscaleAlpha,
            BitDepth::Eight,
            &image(|v| [v as u8, 255]).concat(),
        ),
        tiff::<colortype::Gray8>(&u8s),
        geotiff(|d| d.write_tag(Tag::GdalNodata, "7").unwrap()),
        tiff_with::<colortype::GrayI16>(NX as u32, NY as u32, &image(|v| v as i16), Compression::Lzw, |_| {}),
        big_tiff::<colortype::Gray64Float>(&image(|v| v)),
        json(NX, NY, &expected_values()),
    ]
}

fn hints_strategy() -> impl Strategy<Value = GridHints> {
    (
        proptest::option::of(0usize..6),
        proptest::option::of(0usize..6),
        proptest::option::of(prop_oneof![Just(RawType::F32), Just(RawType::F64)]),
    )
        .prop_map(|(nx, ny, dtype)| GridHints { nx, ny, dtype, ..GridHints::default() })
}

/// Arbitrary bytes, bytes behind each format's magic, and valid files with bytes changed,
/// inserted or cut.
fn bytes_strategy() -> impl Strategy<Value = Vec<u8>> {
    let magic = prop_oneof![
        Just(b"\x93NUMPY\x01\x00".to_vec()),
        Just(b"\x93NUMPY\x02\x00".to_vec()),
        Just(PNG_SIGNATURE.to_vec()),
        Just(b"II*\0".to_vec()),
        Just(b"MM\0*".to_vec()),
        Just(b"II+\0\x08\0\0\0".to_vec()),
        Just(b"{".to_vec()),
    ];
    let seeds = seeds();
    let n = seeds.len();
    prop_oneof![
        proptest::collection::vec(any::<u8>(), 0..200),
        (magic, proptest::collection::vec(any::<u8>(), 0..200)).prop_map(|(m, tail)| [m, tail].concat()),
        (
            0..n,
            proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>(), 0..3u8), 1..6),
            any::<prop::sample::Index>()
        )
            .prop_map(move |(k, edits, cut)| {
                let mut bytes = seeds[k].clone();
                for (at, byte, op) in edits {
                    let at = at.index(bytes.len() + 1);
                    match op {
                        0 if at < bytes.len() => bytes[at] = byte,
                        1 => bytes.insert(at, byte),
                        _ => bytes.truncate(at.max(cut.index(bytes.len() + 1))),
                    }
                }
                bytes
            }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1024, ..ProptestConfig::default() })]

    #[test]
    fn decoding_arbitrary_bytes_never_panics(bytes in bytes_strategy(), hints in hints_strategy()) {
        let _ = decode_grid(&bytes, &hints, 1 << 16);
        let _ = decode_grid(&bytes, &GridHints::default(), 1 << 16);
    }

    #[test]
    fn raw_f64_samples_round_trip_exactly(values in proptest::collection::vec(-1e300f64..1e300, 6)) {
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        let grid = decode_grid(&bytes, &raw_hints(3, 2, RawType::F64), 64).unwrap().grid;
        // File row 0 is the top row, j = 1.
        for (k, v) in values.iter().enumerate() {
            prop_assert_eq!(grid.value(k % 3, 1 - k / 3), *v + 0.0);
        }
    }
}
