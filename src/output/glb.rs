//! Binary glTF 2.0 (`.glb`): one mesh of indexed triangles and the vertex colours of
//! [`colour::of`](super::colour::of) by z, for web viewers.
//!
//! glTF is +Y up and right-handed, so a point (x, y, z) of the mesh is written as glTF's
//! (x, z·z_scale, −y): x east, heights up, and +Z south (−y), a rotation that keeps the
//! triangles counter-clockwise seen from above, glTF's front face. Positions are f32 relative
//! to the centre of the mesh's bounding box, which the node's translation carries in full
//! precision: f32 keeps a millimetre at a kilometre from the centre, where absolute UTM
//! northings (10^6 m) would round to a quarter metre.
//!
//! The file is a 12-byte header, the JSON chunk (padded with spaces) and the BIN chunk: the
//! positions, then the colours, then the u32 indices. Every length is known from the counts,
//! so the header is written first and the arrays stream behind it.

use super::{Encoded, Options, Part, colour};
use crate::geom::Vertex;
use crate::result::RunResult;
use serde_json::json;
use std::sync::Arc;

/// glTF's codes for what a buffer view holds and what an accessor's components are.
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;
/// A primitive of separate triangles.
const TRIANGLES: u32 = 4;

/// Where (x, y, z) goes in glTF's +Y-up frame: (x, z·z_scale, −y).
fn upright(v: &Vertex, z_scale: f64) -> [f64; 3] {
    [v.x, v.z * z_scale, -v.y]
}

/// The GLB file of `result`, its z multiplied by `options.z_scale`, upright in glTF's frame.
///
/// # Panics
/// If the file would pass 4 GiB, which a GLB cannot (its lengths are u32): about 190 million
/// vertices.
pub(super) fn encode(result: &Arc<RunResult>, options: &Options) -> Encoded {
    let (n, m) = (result.vertices.len(), result.triangles.len());
    let z_scale = options.z_scale;
    let centre = centre(result, z_scale);
    let position = move |v: &Vertex| {
        let p = upright(v, z_scale);
        std::array::from_fn::<f32, 3, _>(|k| (p[k] - centre[k]) as f32)
    };
    // POSITION requires its bounds; they are those of the f32 values, as a reader sees them.
    let first = result.vertices.first().map_or([0.0; 3], position);
    let (min, max) = result.vertices.iter().map(position).fold((first, first), |(lo, hi), p| {
        (std::array::from_fn(|k| lo[k].min(p[k])), std::array::from_fn(|k| hi[k].max(p[k])))
    });
    let (positions, colours, indices) = (12 * n, 12 * n, 12 * m);
    let bin = positions + colours + indices;
    let document = json!({
        "asset": {"version": "2.0", "generator": "meshfit"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "translation": centre}],
        "meshes": [{"primitives": [{
            "attributes": {"POSITION": 0, "COLOR_0": 1},
            "indices": 2,
            "mode": TRIANGLES,
        }]}],
        "buffers": [{"byteLength": bin}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": positions, "target": ARRAY_BUFFER},
            {"buffer": 0, "byteOffset": positions, "byteLength": colours, "target": ARRAY_BUFFER},
            {"buffer": 0, "byteOffset": positions + colours, "byteLength": indices,
             "target": ELEMENT_ARRAY_BUFFER},
        ],
        "accessors": [
            // f32 widened to f64 prints the exact f32, so the bounds match the data bit for bit.
            {"bufferView": 0, "componentType": FLOAT, "count": n, "type": "VEC3",
             "min": min.map(f64::from), "max": max.map(f64::from)},
            {"bufferView": 1, "componentType": FLOAT, "count": n, "type": "VEC3"},
            {"bufferView": 2, "componentType": UNSIGNED_INT, "count": 3 * m, "type": "SCALAR"},
        ],
    });
    let mut json = serde_json::to_vec(&document).expect("a json! value serializes");
    json.resize(json.len().next_multiple_of(4), b' ');
    // Every array is a whole number of 4-byte words, so the BIN chunk needs no padding.
    let total = 12 + 8 + json.len() + 8 + bin;
    let length = |bytes: usize| {
        u32::try_from(bytes)
            .unwrap_or_else(|_| panic!("a glb holds at most 4 GiB; this one needs {total} bytes"))
    };
    let mut head = Vec::with_capacity(28 + json.len());
    head.extend_from_slice(b"glTF");
    head.extend_from_slice(&2u32.to_le_bytes());
    head.extend_from_slice(&length(total).to_le_bytes());
    head.extend_from_slice(&length(json.len()).to_le_bytes());
    head.extend_from_slice(b"JSON");
    head.extend_from_slice(&json);
    head.extend_from_slice(&length(bin).to_le_bytes());
    head.extend_from_slice(b"BIN\0");

    let (lo, hi) = result.z_range();
    let linear = srgb_to_linear_table();
    let (r, s, t) = (result.clone(), result.clone(), result.clone());
    Encoded::new(vec![
        Part::Bytes(head),
        Part::rows(n, move |i, out| {
            for c in position(&r.vertices[i]) {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }),
        Part::rows(n, move |i, out| {
            // The colour of z itself: z_scale changes the shape, not the colour scale.
            for c in colour::of(s.vertices[i].z, lo, hi) {
                out.extend_from_slice(&linear[usize::from(c)].to_le_bytes());
            }
        }),
        Part::rows(m, move |i, out| {
            for v in t.triangles[i] {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }),
    ])
}

/// The centre of the bounding box of `result`'s upright points; the origin for no points.
fn centre(result: &RunResult, z_scale: f64) -> [f64; 3] {
    let mut points = result.vertices.iter().map(|v| upright(v, z_scale));
    let Some(first) = points.next() else { return [0.0; 3] };
    let (lo, hi) = points.fold((first, first), |(lo, hi), p| {
        (std::array::from_fn(|k| lo[k].min(p[k])), std::array::from_fn(|k| hi[k].max(p[k])))
    });
    // + 0.0: a centre of -0.0 is written as 0.
    std::array::from_fn(|k| lo[k] / 2.0 + hi[k] / 2.0 + 0.0)
}

/// Each 8-bit sRGB level as linear light.
///
/// glTF vertex colours are linear, and viewers multiply them into lighting as such; the colour
/// map's sRGB bytes written as they are would show lighter than viridis. f32 (rather than
/// normalized u8) keeps the dark end, where linear values crowd below 1/255, apart.
fn srgb_to_linear_table() -> [f32; 256] {
    std::array::from_fn(|level| {
        let c = level as f64 / 255.0;
        // The sRGB transfer function (IEC 61966-2-1); libm for the same bits on every machine.
        let linear = if c <= 0.04045 { c / 12.92 } else { libm::pow((c + 0.055) / 1.055, 2.4) };
        linear as f32
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::refine::Criterion;
    use crate::result::testing::sample;
    use gltf::mesh::Mode;

    /// What the gltf crate reads from the one primitive of a file.
    #[derive(Debug, PartialEq)]
    struct Read {
        positions: Vec<[f32; 3]>,
        colours: Vec<[f32; 3]>,
        indices: Vec<u32>,
        /// The POSITION accessor's min and max.
        bounds: gltf::mesh::Bounds<[f32; 3]>,
        /// The node's translation, as the JSON gives it (in full precision).
        translation: [f64; 3],
    }

    fn read(bytes: &[u8]) -> Read {
        let glb = gltf::Gltf::from_slice(bytes).unwrap();
        assert_eq!((glb.meshes().len(), glb.buffers().len()), (1, 1));
        let primitives: Vec<_> = glb.meshes().flat_map(|m| m.primitives()).collect();
        let [primitive] = &primitives[..] else { panic!("{} primitives", primitives.len()) };
        assert_eq!(primitive.mode(), Mode::Triangles);
        let reader = primitive.reader(|buffer| match buffer.source() {
            gltf::buffer::Source::Bin => glb.blob.as_deref(),
            gltf::buffer::Source::Uri(_) => None,
        });
        Read {
            positions: reader.read_positions().unwrap().collect(),
            colours: reader.read_colors(0).unwrap().into_rgb_f32().collect(),
            indices: reader.read_indices().unwrap().into_u32().collect(),
            bounds: primitive.bounding_box(),
            translation: translation(bytes),
        }
    }

    /// The node's translation from the JSON chunk itself: the gltf crate keeps it as f32.
    fn translation(bytes: &[u8]) -> [f64; 3] {
        let len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        let document: serde_json::Value = serde_json::from_slice(&bytes[20..20 + len]).unwrap();
        serde_json::from_value(document["nodes"][0]["translation"].clone()).unwrap()
    }

    /// Where the file puts each vertex: its f32 position plus the node's translation.
    fn placed(read: &Read) -> Vec<[f64; 3]> {
        let t = read.translation;
        read.positions.iter().map(|p| std::array::from_fn(|k| f64::from(p[k]) + t[k])).collect()
    }

    /// The bounds of `points`, as a validator recomputes them.
    fn bounds(points: &[[f32; 3]]) -> gltf::mesh::Bounds<[f32; 3]> {
        let (mut min, mut max) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        for p in points {
            for k in 0..3 {
                (min[k], max[k]) = (min[k].min(p[k]), max[k].max(p[k]));
            }
        }
        gltf::mesh::Bounds { min, max }
    }

    #[test]
    fn gltf_reads_back_positions_colours_by_z_and_the_triangles() {
        let result = Arc::new(sample(500, Criterion::Error));
        let bytes = encode(&result, &Options::default()).to_vec();
        assert_eq!(&bytes[8..12], &(bytes.len() as u32).to_le_bytes());
        let got = read(&bytes);
        let expected: Vec<[f32; 3]> = (result.vertices.iter())
            .map(|v| std::array::from_fn(|k| (upright(v, 1.0)[k] - got.translation[k]) as f32))
            .collect();
        assert_eq!(got.positions, expected);
        assert_eq!(got.bounds, bounds(&expected));
        let (lo, hi) = result.z_range();
        let table = srgb_to_linear_table();
        let expected: Vec<[f32; 3]> =
            result.vertices.iter().map(|v| colour::of(v.z, lo, hi).map(|c| table[usize::from(c)])).collect();
        assert_eq!(got.colours, expected);
        assert_eq!(got.indices, result.triangles.concat());
    }

    #[test]
    fn the_mesh_stands_upright_heights_on_y_and_faces_up() {
        let result = Arc::new(sample(300, Criterion::Error));
        let got = read(&encode(&result, &Options::default()).to_vec());
        let placed = placed(&got);
        for (p, v) in placed.iter().zip(&result.vertices) {
            // x east, heights up, +Z south.
            let want = [v.x, v.z, -v.y];
            assert!((0..3).all(|k| (p[k] - want[k]).abs() < 1e-6), "{p:?} for {v:?}");
        }
        // The bounding box's centre is the origin of the positions.
        let (lo, hi) = (got.bounds.min, got.bounds.max);
        assert!((0..3).all(|k| (lo[k] + hi[k]).abs() < 1e-6), "{lo:?} {hi:?}");
        // Every triangle's front face (counter-clockwise) looks up, +Y.
        for t in got.indices.chunks_exact(3) {
            let [a, b, c] = [0, 1, 2].map(|i| placed[t[i] as usize]);
            let (u, w) = ([b[0] - a[0], b[2] - a[2]], [c[0] - a[0], c[2] - a[2]]);
            // The Y component of (b − a) × (c − a).
            let up = u[1] * w[0] - u[0] * w[1];
            assert!(up > 0.0, "a triangle faces down: {t:?}");
        }
    }

    #[test]
    fn utm_coordinates_keep_their_millimetres() {
        // A mesh of 3 km at UTM-like eastings and northings, heights in metres.
        let mut result = sample(300, Criterion::Error);
        for v in &mut result.vertices {
            (v.x, v.y, v.z) = (500_000.0 + v.x * 1000.0, 4_000_000.0 + v.y * 1000.0, 800.0 + v.z * 50.0);
        }
        let got = read(&encode(&Arc::new(result.clone()), &Options::default()).to_vec());
        for (p, v) in placed(&got).iter().zip(&result.vertices) {
            let want = [v.x, v.z, -v.y];
            assert!((0..3).all(|k| (p[k] - want[k]).abs() < 1e-3), "{p:?} for {v:?}");
        }
    }

    #[test]
    fn z_scale_stretches_the_heights_and_their_bounds_but_not_the_colours() {
        let result = Arc::new(sample(200, Criterion::Variation));
        let plain = read(&encode(&result, &Options::default()).to_vec());
        let options = Options { z_scale: 4.0, ..Options::default() };
        let scaled = read(&encode(&result, &options).to_vec());
        for (p, v) in placed(&scaled).iter().zip(&result.vertices) {
            assert!((p[1] - 4.0 * v.z).abs() < 1e-6 && (p[0] - v.x).abs() < 1e-6, "{p:?} for {v:?}");
        }
        let height = |r: &Read| r.bounds.max[1] - r.bounds.min[1];
        assert!((height(&scaled) / height(&plain) - 4.0).abs() < 1e-5);
        assert_eq!((scaled.colours, scaled.indices), (plain.colours, plain.indices));
    }

    #[test]
    fn the_json_chunk_is_padded_with_spaces_to_a_word() {
        let result = Arc::new(sample(30, Criterion::Variation));
        let bytes = encode(&result, &Options::default()).to_vec();
        let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        assert_eq!((json_len % 4, &bytes[16..20]), (0, &b"JSON"[..]));
        let json = std::str::from_utf8(&bytes[20..20 + json_len]).unwrap();
        let document = json.trim_end_matches(' ');
        assert!(document.ends_with('}') && json.len() - document.len() < 4, "{json:?}");
        let bin_len = u32::from_le_bytes(bytes[20 + json_len..][..4].try_into().unwrap()) as usize;
        assert_eq!(bytes.len(), 20 + json_len + 8 + bin_len);
    }

    #[test]
    fn srgb_levels_map_to_linear_light_at_the_known_points() {
        let table = srgb_to_linear_table();
        assert_eq!((table[0], table[255]), (0.0, 1.0));
        assert!((table[10] - 10.0 / 255.0 / 12.92).abs() < 1e-9);
        // sRGB 188 is about half the light of white (0.5029).
        assert!((table[188] - 0.5029).abs() < 1e-4, "{}", table[188]);
        assert!(table.windows(2).all(|w| w[0] < w[1]));
    }
}
