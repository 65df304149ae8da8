use super::*;
use crate::tiles::ellipsoid::to_ecef;
use crate::tiles::scheme::TileId;
use proptest::prelude::*;
use quantized_mesh::DecodedMesh;

/// A tile's mesh: an nx × ny lattice of vertices over the tile, heights from `height`, two
/// counter-clockwise triangles a cell; vertices listed in a scrambled order so that the
/// writer's renumbering is exercised.
struct Lattice {
    bounds: Bounds,
    vertices: Vec<[f64; 3]>,
    triangles: Vec<[u32; 3]>,
}

fn lattice(tile: TileId, nx: u32, ny: u32, height: impl Fn(u32, u32) -> f64) -> Lattice {
    let bounds = tile.bounds();
    // Vertex (i, j) is stored at slot (k · 7919) mod n: a fixed scramble (7919 is prime).
    let n = nx * ny;
    let slot = |i: u32, j: u32| ((u64::from(j * nx + i) * 7919) % u64::from(n)) as u32;
    let mut vertices = vec![[0.0; 3]; n as usize];
    for j in 0..ny {
        for i in 0..nx {
            // The last column and row sit exactly on the east and north edges.
            let lon = if i == nx - 1 {
                bounds.east
            } else {
                bounds.west + (bounds.east - bounds.west) * f64::from(i) / f64::from(nx - 1)
            };
            let lat = if j == ny - 1 {
                bounds.north
            } else {
                bounds.south + (bounds.north - bounds.south) * f64::from(j) / f64::from(ny - 1)
            };
            vertices[slot(i, j) as usize] = [lon, lat, height(i, j)];
        }
    }
    let mut triangles = Vec::new();
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            let (a, b, c, d) = (slot(i, j), slot(i + 1, j), slot(i + 1, j + 1), slot(i, j + 1));
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    Lattice { bounds, vertices, triangles }
}

impl Lattice {
    fn mesh(&self) -> TileMesh<'_> {
        TileMesh { bounds: self.bounds, vertices: &self.vertices, triangles: &self.triangles }
    }

    /// Each triangle as its corners' (u, v), in the order given.
    fn triangles_uv(&self) -> Vec<[(u16, u16); 3]> {
        self.triangles.iter().map(|t| t.map(|k| self.uv(k))).collect()
    }

    /// u and v of vertex `k`, quantized as the format says.
    fn uv(&self, k: u32) -> (u16, u16) {
        let (b, p) = (self.bounds, self.vertices[k as usize]);
        let q = |x: f64, lo: f64, hi: f64| ((x - lo) / (hi - lo) * 32767.0).round() as u16;
        (q(p[0], b.west, b.east), q(p[1], b.south, b.north))
    }
}

/// Each decoded triangle as its corners' (u, v), in the order written.
fn corners_uv(decoded: &DecodedMesh) -> Vec<[(u16, u16); 3]> {
    let uv = |k: u32| (decoded.vertices.u[k as usize], decoded.vertices.v[k as usize]);
    decoded.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]].map(uv)).collect()
}

fn hills(i: u32, j: u32) -> f64 {
    120.0 + 35.5 * (f64::from(i) * 0.4).sin() * (f64::from(j) * 0.3).cos() + f64::from(i * j % 5)
}

const METADATA_JSON: &str = r#"{"available":[[{"startX":10,"startY":4,"endX":11,"endY":5}]]}"#;

#[test]
fn the_quantized_mesh_crate_reads_back_vertices_triangles_edges_and_extensions() {
    let tile = TileId::new(4, 17, 9).unwrap();
    let lattice = lattice(tile, 20, 15, hills);
    let normals: Vec<[f64; 3]> = lattice
        .vertices
        .iter()
        .map(|p| {
            let e = to_ecef(p[0], p[1], 0.0);
            let l = (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt();
            e.map(|c| c / l)
        })
        .collect();
    let extensions = Extensions { normals: Some(&normals), metadata: Some(METADATA_JSON) };
    let bytes = encode(&lattice.mesh(), &extensions);
    let decoded = DecodedMesh::decode(&bytes).unwrap();
    let n = lattice.vertices.len();
    assert_eq!(decoded.vertices.u.len(), n);
    // Each triangle, as the positions of its corners, comes back in the order given.
    let decoded_uv = |k: u32| (decoded.vertices.u[k as usize], decoded.vertices.v[k as usize]);
    assert_eq!(corners_uv(&decoded), lattice.triangles_uv());
    // Heights within half a quantum of the range the header gives.
    let (lo, hi) = (f64::from(decoded.header.min_height), f64::from(decoded.header.max_height));
    let quantum = (hi - lo) / 32767.0;
    for (t, tri) in decoded.indices.chunks_exact(3).zip(&lattice.triangles) {
        for (&k, &original) in t.iter().zip(tri) {
            let h = lo + f64::from(decoded.vertices.height[k as usize]) * quantum;
            assert!((h - lattice.vertices[original as usize][2]).abs() <= quantum / 2.0 + 1e-9);
        }
    }
    // The edge lists hold exactly the vertices at u or v of 0 or 32767, sorted along the edge.
    let side = |test: &dyn Fn(u16, u16) -> bool, along: &dyn Fn(u32) -> u16| {
        let mut side: Vec<u32> = (0..n as u32).filter(|&k| test(decoded_uv(k).0, decoded_uv(k).1)).collect();
        side.sort_by_key(|&k| along(k));
        side
    };
    let (u, v) = (|k: u32| decoded_uv(k).0, |k: u32| decoded_uv(k).1);
    assert_eq!(decoded.edge_indices.west, side(&|u, _| u == 0, &v));
    assert_eq!(decoded.edge_indices.south, side(&|_, v| v == 0, &u));
    assert_eq!(decoded.edge_indices.east, side(&|u, _| u == 32767, &v));
    assert_eq!(decoded.edge_indices.north, side(&|_, v| v == 32767, &u));
    assert_eq!((decoded.edge_indices.west.len(), decoded.edge_indices.north.len()), (15, 20));
    // Normals within the oct encoding's step of the given ones, in the vertices' new order.
    let got_normals = decoded.extensions.normals.unwrap();
    let mut first_use = Vec::new();
    for &k in lattice.triangles.iter().flatten() {
        if !first_use.contains(&k) {
            first_use.push(k);
        }
    }
    for (got, &k) in got_normals.iter().zip(&first_use) {
        let want = normals[k as usize];
        assert!((0..3).all(|c| (f64::from(got[c]) - want[c]).abs() < 0.02), "{got:?} vs {want:?}");
    }
    let metadata = decoded.extensions.metadata.unwrap();
    assert_eq!(
        serde_json::to_value(&metadata).unwrap(),
        serde_json::from_str::<serde_json::Value>(METADATA_JSON).unwrap()
    );
}

#[test]
fn an_independent_decoder_reads_the_same_tile() {
    let lattice = lattice(TileId::new(9, 700, 300).unwrap(), 33, 33, hills);
    let bytes = encode(&lattice.mesh(), &Extensions { normals: None, metadata: Some(METADATA_JSON) });
    let other = quantized_mesh_decoder::from_reader(&bytes[..]).unwrap();
    let ours = DecodedMesh::decode(&bytes).unwrap();
    let n = ours.vertices.u.len();
    assert_eq!(other.vertex_data[..n], ours.vertices.u[..]);
    assert_eq!(other.vertex_data[n..2 * n], ours.vertices.v[..]);
    assert_eq!(other.vertex_data[2 * n..], ours.vertices.height[..]);
    let quantized_mesh_decoder::Indices::IndexData16(indices) = other.triangle_indices else {
        panic!("16-bit")
    };
    assert_eq!(indices.iter().map(|&i| u32::from(i)).collect::<Vec<_>>(), ours.indices);
    assert_eq!(other.header.minimum_height, ours.header.min_height);
    assert_eq!(other.extension.metadata.as_deref(), Some(METADATA_JSON));
}

#[test]
fn past_65536_vertices_the_indices_are_32_bit_and_aligned() {
    // 257 × 257 = 66,049 vertices: an odd count, so the indices need two bytes of padding.
    let lattice = lattice(TileId::new(12, 5000, 1000).unwrap(), 257, 257, hills);
    let bytes = encode(&lattice.mesh(), &Extensions::default());
    let n = lattice.vertices.len();
    assert_eq!((88 + 4 + 6 * n) % 4, 2, "the vertex data ends off a 4-byte boundary");
    assert_eq!(&bytes[88 + 4 + 6 * n..][..2], &[0, 0], "padding");
    let decoded = DecodedMesh::decode(&bytes).unwrap();
    assert_eq!(corners_uv(&decoded), lattice.triangles_uv());
}

#[test]
fn a_tile_of_exactly_65536_vertices_gets_one_more_and_32_bit_indices() {
    // CesiumJS advances 16-bit indices at exactly 64 Ki vertices but reads them as 32-bit:
    // no layout of that count reads back, so the writer adds one vertex no triangle uses.
    let lattice = lattice(TileId::new(12, 5000, 1000).unwrap(), 256, 256, hills);
    assert_eq!(lattice.vertices.len(), 65_536);
    let bytes = encode(&lattice.mesh(), &Extensions::default());
    let n = u32::from_le_bytes(bytes[88..92].try_into().unwrap()) as usize;
    assert_eq!(n, 65_537);
    let decoded = DecodedMesh::decode(&bytes).unwrap();
    assert_eq!(corners_uv(&decoded), lattice.triangles_uv());
    assert!(decoded.indices.iter().all(|&k| (k as usize) < 65_536), "no triangle names the extra vertex");
    let e = &decoded.edge_indices;
    assert_eq!([e.west.len(), e.south.len(), e.east.len(), e.north.len()], [256; 4], "nor does an edge");
}

#[test]
fn oct_encoding_rounds_as_cesium_does() {
    assert_eq!(oct_encode([0.0, 0.0, 1.0]), [128, 128]);
    assert_eq!(oct_encode([1.0, 0.0, 0.0]), [255, 128]);
    assert_eq!(oct_encode([0.0, -1.0, 0.0]), [128, 0]);
    assert_eq!(oct_encode([0.0, 0.0, -1.0]), [255, 255]);
    // x = 0.5745098 lands at 200.75 of 255: rounded to 201 (truncation would give 200).
    assert_eq!(oct_encode([0.5745098, 0.0, 0.4254902]), [201, 128]);
}

#[test]
fn a_flat_tile_quantizes_every_height_to_zero() {
    let lattice = lattice(TileId::new(3, 1, 1).unwrap(), 5, 5, |_, _| 250.0);
    let decoded = DecodedMesh::decode(&encode(&lattice.mesh(), &Extensions::default())).unwrap();
    assert!(decoded.vertices.height.iter().all(|&h| h == 0));
    assert!(decoded.header.min_height <= 250.0 && decoded.header.max_height >= 250.0);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Any heights, any tile: every vertex comes back within half a quantum in u, v and height,
    /// and the header's sphere holds every vertex.
    #[test]
    fn any_tile_round_trips_within_half_a_quantum(
        z in 0u8..20, fx in 0.0f64..1.0, fy in 0.0f64..1.0,
        nx in 2u32..12, ny in 2u32..12,
        heights in prop::collection::vec(-500.0f64..9000.0, 144),
    ) {
        let x = ((f64::from(crate::tiles::scheme::columns(z)) * fx) as u32).min(crate::tiles::scheme::columns(z) - 1);
        let y = ((f64::from(crate::tiles::scheme::rows(z)) * fy) as u32).min(crate::tiles::scheme::rows(z) - 1);
        let tile = TileId::new(u32::from(z), x, y).unwrap();
        let lattice = lattice(tile, nx, ny, |i, j| heights[(j * 12 + i) as usize]);
        let bytes = encode(&lattice.mesh(), &Extensions::default());
        let decoded = DecodedMesh::decode(&bytes).unwrap();
        let (lo, hi) = (f64::from(decoded.header.min_height), f64::from(decoded.header.max_height));
        let quantum = (hi - lo) / 32767.0;
        let b = lattice.bounds;
        for (t, tri) in decoded.indices.chunks_exact(3).zip(&lattice.triangles) {
            for (&k, &original) in t.iter().zip(tri) {
                let p = lattice.vertices[original as usize];
                let (u, v, h) = (decoded.vertices.u[k as usize], decoded.vertices.v[k as usize], decoded.vertices.height[k as usize]);
                let lon = b.west + f64::from(u) / 32767.0 * (b.east - b.west);
                let lat = b.south + f64::from(v) / 32767.0 * (b.north - b.south);
                // Half a quantum, and the rounding of degrees near ±180 (an ulp there is 3e-14).
                prop_assert!((lon - p[0]).abs() <= (b.east - b.west) / 65534.0 + 1e-12);
                prop_assert!((lat - p[1]).abs() <= (b.north - b.south) / 65534.0 + 1e-12);
                prop_assert!((lo + f64::from(h) * quantum - p[2]).abs() <= quantum / 2.0 + 1e-9);
            }
        }
        let c = decoded.header.bounding_sphere_center;
        for p in &lattice.vertices {
            let e = to_ecef(p[0], p[1], p[2]);
            let d = ((e[0] - c[0]).powi(2) + (e[1] - c[1]).powi(2) + (e[2] - c[2]).powi(2)).sqrt();
            prop_assert!(d <= decoded.header.bounding_sphere_radius * (1.0 + 1e-12));
        }
    }
}
