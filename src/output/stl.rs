//! Binary STL: an 80-byte header, the facet count, then per facet its unit normal, its three
//! corners (all f32) and a zero attribute word.
//!
//! STL has no shared vertices and no data: each facet repeats its corners, in the result's
//! counter-clockwise order, so the normal points up (+z) wherever the surface is a graph.

use super::{Encoded, Options, Part};
use crate::geom::Vertex;
use crate::result::RunResult;
use std::sync::Arc;

/// The header; readers take a file that starts with `solid` for ASCII STL, so this must not.
const HEADER: &[u8] = b"meshfit binary STL";

/// The STL file of `result`.
pub(super) fn encode(result: &Arc<RunResult>, options: &Options) -> Encoded {
    let mut head = HEADER.to_vec();
    head.resize(80, b' ');
    // Triangle ids are u32, so their count fits the u32 field.
    let count = u32::try_from(result.triangles.len()).expect("triangle ids are u32");
    head.extend_from_slice(&count.to_le_bytes());
    let (r, z_scale) = (result.clone(), options.z_scale);
    Encoded::new(vec![
        Part::Bytes(head),
        Part::rows(result.triangles.len(), move |i, out| {
            let corners = r.triangles[i].map(|v| {
                let v = r.vertices[v as usize];
                Vertex { z: v.z * z_scale, ..v }
            });
            for v in std::iter::once(normal(corners)).chain(corners.map(|v| [v.x, v.y, v.z])) {
                for c in v {
                    out.extend_from_slice(&(c as f32).to_le_bytes());
                }
            }
            out.extend_from_slice(&0u16.to_le_bytes());
        }),
    ])
}

/// The unit normal of the triangle `a b c` by the right-hand rule, or zero if it has no area.
fn normal([a, b, c]: [Vertex; 3]) -> [f64; 3] {
    let (u, v) = ([b.x - a.x, b.y - a.y, b.z - a.z], [c.x - a.x, c.y - a.y, c.z - a.z]);
    let n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
    let length = n.iter().map(|c| c * c).sum::<f64>().sqrt();
    // Computed in f64, so a sliver that is degenerate in f32 still gets its direction.
    if length > 0.0 && length.is_finite() { n.map(|c| c / length) } else { [0.0; 3] }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::refine::Criterion;
    use crate::result::testing::sample;
    use std::io::Cursor;

    #[test]
    fn stl_io_reads_back_every_facet_in_f32_with_upward_unit_normals() {
        let result = Arc::new(sample(500, Criterion::Error));
        let bytes = encode(&result, &Options::default()).to_vec();
        assert_eq!(bytes.len(), 84 + 50 * result.triangles.len());
        let facets: Vec<stl_io::Triangle> =
            stl_io::create_stl_reader(&mut Cursor::new(bytes)).unwrap().collect::<Result<_, _>>().unwrap();
        assert_eq!(facets.len(), result.triangles.len());
        for (facet, t) in facets.iter().zip(&result.triangles) {
            for (got, &v) in facet.vertices.iter().zip(t) {
                let v = result.vertices[v as usize];
                assert_eq!(got.0, [v.x as f32, v.y as f32, v.z as f32], "triangle {t:?}");
            }
            let n = facet.normal.0;
            let length = n.iter().map(|c| c * c).sum::<f32>().sqrt();
            assert!((length - 1.0).abs() < 1e-6 && n[2] > 0.0, "triangle {t:?} has normal {n:?}");
        }
    }

    #[test]
    fn the_normal_follows_the_right_hand_rule_and_is_zero_for_a_degenerate_triangle() {
        let v = |x, y, z| Vertex { x, y, z };
        let flat = [v(0.0, 0.0, 5.0), v(2.0, 0.0, 5.0), v(0.0, 3.0, 5.0)];
        assert_eq!(normal(flat), [0.0, 0.0, 1.0]);
        assert_eq!(normal([flat[0], flat[2], flat[1]]), [0.0, 0.0, -1.0]);
        let tilted = normal([v(0.0, 0.0, 0.0), v(1.0, 0.0, 1.0), v(0.0, 1.0, 0.0)]);
        let h = std::f64::consts::FRAC_1_SQRT_2;
        assert!(tilted.iter().zip([-h, 0.0, h]).all(|(a, b)| (a - b).abs() < 1e-15), "{tilted:?}");
        assert_eq!(normal([v(0.0, 0.0, 0.0), v(1.0, 1.0, 1.0), v(2.0, 2.0, 2.0)]), [0.0; 3]);
    }
}
