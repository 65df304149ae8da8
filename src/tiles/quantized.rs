//! The quantized-mesh-1.0 terrain format, written as its specification and CesiumJS's reader
//! (`CesiumTerrainProvider`) read it: an 88-byte header, the vertices as zig-zag deltas of u,
//! v and height quantized to 0..=32767 over the tile, the triangles in high-water-mark order,
//! the vertices on each edge, then the extensions a client asked for.
//!
//! Our own writer rather than the `quantized-mesh` crate, which the tests use as a decoder:
//! that crate takes its header's trigonometry from the platform, so its bytes could differ
//! between machines, truncates oct-encoded normals where Cesium rounds them, and writes a
//! tile of exactly 65,536 vertices, which CesiumJS cannot read whatever its index width (it
//! steps over 16-bit indices but reads them as 32-bit); this writer adds an unused vertex.

use super::ellipsoid::{bounding_sphere, horizon_occlusion_point, to_ecef};
use super::scheme::Bounds;

/// The largest quantized coordinate: u, v and height are in 0..=32767.
pub const QUANTIZED_MAX: u16 = 32767;

/// The most vertices a tile with 16-bit indices holds (readers switch to 32-bit above it).
const MAX_16_BIT_VERTICES: usize = 65_536;

/// The id of the oct-encoded per-vertex normals extension.
const OCT_VERTEX_NORMALS: u8 = 1;

/// The id of the metadata extension.
const METADATA: u8 = 4;

/// A tile's triangle mesh, before quantization.
#[derive(Debug, Clone, Copy)]
pub struct TileMesh<'a> {
    /// The tile's bounds, in degrees.
    pub bounds: Bounds,
    /// Longitude and latitude (degrees) and height (metres) of each vertex, inside `bounds`.
    pub vertices: &'a [[f64; 3]],
    /// Vertex triples, counter-clockwise seen from above.
    pub triangles: &'a [[u32; 3]],
}

/// The extensions to write after the mesh, in the order of their ids.
#[derive(Debug, Clone, Copy, Default)]
pub struct Extensions<'a> {
    /// A unit normal per vertex, in Earth-centred (ECEF) axes, oct-encoded.
    pub normals: Option<&'a [[f64; 3]]>,
    /// The metadata extension's JSON (for instance, the availability of the tiles below).
    pub metadata: Option<&'a str>,
}

/// `mesh` as a quantized-mesh-1.0 tile with `extensions`, uncompressed.
///
/// Vertices are renumbered in the order the triangles first use them, which the
/// high-water-mark encoding of the indices needs; a vertex no triangle uses is left out.
///
/// # Panics
/// When a triangle names a vertex past the end of `mesh.vertices`, or `extensions.normals`
/// does not give one normal per vertex.
pub fn encode(mesh: &TileMesh<'_>, extensions: &Extensions<'_>) -> Vec<u8> {
    let (mut order, triangles) = first_use_order(mesh.vertices.len(), mesh.triangles);
    let mut vertices: Vec<[f64; 3]> = order.iter().map(|&v| mesh.vertices[v as usize]).collect();
    // The vertices triangles use. No tile may have exactly 64 Ki: CesiumJS steps over 16-bit
    // indices there but reads them into a 32-bit array, so no layout reads back. One unused
    // vertex more, named by no triangle and no edge, makes the indices 32-bit, which it reads.
    let used = vertices.len();
    if used == MAX_16_BIT_VERTICES {
        let last = *order.last().expect("64 Ki vertices");
        order.push(last);
        vertices.push(mesh.vertices[last as usize]);
    }
    let n = vertices.len();
    let b = mesh.bounds;
    let (min_height, max_height) = height_range(&vertices);
    let quantize = |value: f64, lo: f64, hi: f64| {
        if hi > lo {
            (((value - lo) / (hi - lo) * f64::from(QUANTIZED_MAX)).round())
                .clamp(0.0, f64::from(QUANTIZED_MAX)) as u16
        } else {
            0
        }
    };
    let u: Vec<u16> = vertices.iter().map(|p| quantize(p[0], b.west, b.east)).collect();
    let v: Vec<u16> = vertices.iter().map(|p| quantize(p[1], b.south, b.north)).collect();
    let h: Vec<u16> = vertices.iter().map(|p| quantize(p[2], min_height.into(), max_height.into())).collect();

    let mut out = Vec::with_capacity(88 + 4 + 6 * n + 4 + 12 * triangles.len() + 64);
    header(&mut out, &b, &vertices, min_height, max_height);
    out.extend_from_slice(&(n as u32).to_le_bytes());
    for stream in [&u, &v, &h] {
        let mut previous = 0i32;
        for &value in stream.iter() {
            let delta = i32::from(value) - previous;
            out.extend_from_slice(&(zigzag(delta) as u16).to_le_bytes());
            previous = i32::from(value);
        }
    }
    let wide = n > MAX_16_BIT_VERTICES;
    let index = |out: &mut Vec<u8>, i: u32| {
        if wide {
            out.extend_from_slice(&i.to_le_bytes());
        } else {
            out.extend_from_slice(&(i as u16).to_le_bytes());
        }
    };
    // 32-bit indices start on a 4-byte boundary (16-bit ones always fall on 2).
    if wide {
        out.resize(out.len().next_multiple_of(4), 0);
    }
    out.extend_from_slice(&(triangles.len() as u32).to_le_bytes());
    // High-water mark: 0 for the next new vertex, else how far below the highest so far.
    let mut highest = 0u32;
    for &i in triangles.iter().flatten() {
        let code = highest - i;
        if i == highest {
            highest += 1;
        }
        index(&mut out, code);
    }
    for side in edges(&b, &vertices[..used], &u[..used], &v[..used]) {
        out.extend_from_slice(&(side.len() as u32).to_le_bytes());
        for i in side {
            index(&mut out, i);
        }
    }
    if let Some(normals) = extensions.normals {
        assert_eq!(normals.len(), mesh.vertices.len(), "one normal per vertex");
        out.push(OCT_VERTEX_NORMALS);
        out.extend_from_slice(&(2 * n as u32).to_le_bytes());
        for &k in &order {
            out.extend_from_slice(&oct_encode(normals[k as usize]));
        }
    }
    if let Some(json) = extensions.metadata {
        out.push(METADATA);
        out.extend_from_slice(&(4 + json.len() as u32).to_le_bytes());
        out.extend_from_slice(&(json.len() as u32).to_le_bytes());
        out.extend_from_slice(json.as_bytes());
    }
    out
}

/// The vertices in the order the triangles first use them (old indices), and the triangles
/// renumbered to that order.
fn first_use_order(count: usize, triangles: &[[u32; 3]]) -> (Vec<u32>, Vec<[u32; 3]>) {
    let mut new = vec![u32::MAX; count];
    let mut order = Vec::with_capacity(count);
    let renumbered = triangles
        .iter()
        .map(|t| {
            t.map(|v| {
                let slot = &mut new[v as usize];
                if *slot == u32::MAX {
                    *slot = order.len() as u32;
                    order.push(v);
                }
                *slot
            })
        })
        .collect();
    (order, renumbered)
}

/// The heights' range as the header's f32 values hold it, widened outward so that every
/// height quantizes inside it.
fn height_range(vertices: &[[f64; 3]]) -> (f32, f32) {
    let (lo, hi) =
        vertices.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| (lo.min(p[2]), hi.max(p[2])));
    if lo > hi {
        return (0.0, 0.0);
    }
    let (mut min, mut max) = (lo as f32, hi as f32);
    if f64::from(min) > lo {
        min = min.next_down();
    }
    if f64::from(max) < hi {
        max = max.next_up();
    }
    (min, max)
}

/// The 88-byte header: the tile's centre (ECEF), its height range, a bounding sphere and the
/// horizon occlusion point of its vertices.
fn header(out: &mut Vec<u8>, b: &Bounds, vertices: &[[f64; 3]], min_height: f32, max_height: f32) {
    let (lon, lat) = b.centre();
    let centre = to_ecef(lon, lat, f64::from(min_height) / 2.0 + f64::from(max_height) / 2.0);
    let points: Vec<[f64; 3]> = vertices.iter().map(|p| to_ecef(p[0], p[1], p[2])).collect();
    let (sphere, radius) = bounding_sphere(&points);
    let occlusion = horizon_occlusion_point(&sphere, &points);
    let start = out.len();
    for c in centre {
        out.extend_from_slice(&c.to_le_bytes());
    }
    out.extend_from_slice(&min_height.to_le_bytes());
    out.extend_from_slice(&max_height.to_le_bytes());
    for c in sphere {
        out.extend_from_slice(&c.to_le_bytes());
    }
    out.extend_from_slice(&radius.to_le_bytes());
    for c in occlusion {
        out.extend_from_slice(&c.to_le_bytes());
    }
    debug_assert_eq!(out.len() - start, 88);
}

/// The (new) indices of the vertices on the west, south, east and north edges, each sorted
/// along its edge. A vertex is on an edge when its coordinate is the edge's, exactly.
fn edges(b: &Bounds, vertices: &[[f64; 3]], u: &[u16], v: &[u16]) -> [Vec<u32>; 4] {
    let on = |test: &dyn Fn(&[f64; 3]) -> bool, along: &[u16]| {
        let mut side: Vec<u32> =
            (0..vertices.len() as u32).filter(|&i| test(&vertices[i as usize])).collect();
        side.sort_by_key(|&i| (along[i as usize], i));
        side
    };
    [
        on(&|p| p[0] == b.west, v),
        on(&|p| p[1] == b.south, u),
        on(&|p| p[0] == b.east, v),
        on(&|p| p[1] == b.north, u),
    ]
}

/// Zig-zag: 0, −1, 1, −2, … as 0, 1, 2, 3, …
fn zigzag(value: i32) -> u32 {
    ((value << 1) ^ (value >> 31)) as u32
}

/// A unit vector as two bytes on the octahedron, rounded as CesiumJS's
/// `AttributeCompression.octEncode` rounds.
fn oct_encode(n: [f64; 3]) -> [u8; 2] {
    let l1 = n[0].abs() + n[1].abs() + n[2].abs();
    if l1 == 0.0 {
        return [128, 128];
    }
    let (mut x, mut y) = (n[0] / l1, n[1] / l1);
    if n[2] < 0.0 {
        let sign = |v: f64| if v < 0.0 { -1.0 } else { 1.0 };
        (x, y) = ((1.0 - y.abs()) * sign(x), (1.0 - x.abs()) * sign(y));
    }
    let snorm = |v: f64| ((v.clamp(-1.0, 1.0) * 0.5 + 0.5) * 255.0).round() as u8;
    [snorm(x), snorm(y)]
}

#[cfg(test)]
mod tests;
