//! Wavefront OBJ: a `v x y z` line per vertex, then an `f i j k` line per triangle.
//!
//! Face indices are 1-based (OBJ counts from 1), in the result's counter-clockwise order.
//! Numbers are the shortest text that reads back as the same f64. OBJ has no place for the
//! triangle errors, so they are left out.

use super::encoded::push_f64;
use super::{Encoded, Options, Part};
use crate::result::RunResult;
use std::io::Write;
use std::sync::Arc;

/// The OBJ file of `result`.
pub(super) fn encode(result: &Arc<RunResult>, options: &Options) -> Encoded {
    let head =
        format!("# meshfit: {} vertices, {} triangles\n", result.vertices.len(), result.triangles.len());
    let (r, s, z_scale) = (result.clone(), result.clone(), options.z_scale);
    Encoded::new(vec![
        Part::Bytes(head.into_bytes()),
        Part::rows(result.vertices.len(), move |i, out| {
            let v = r.vertices[i];
            out.extend_from_slice(b"v ");
            push_f64(out, v.x);
            out.push(b' ');
            push_f64(out, v.y);
            out.push(b' ');
            push_f64(out, v.z * z_scale);
            out.push(b'\n');
        }),
        Part::rows(result.triangles.len(), move |i, out| {
            let [a, b, c] = s.triangles[i].map(|v| u64::from(v) + 1);
            writeln!(out, "f {a} {b} {c}").expect("writing to a Vec does not fail");
        }),
    ])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::refine::Criterion;
    use crate::result::testing::sample;

    #[test]
    fn tobj_reads_back_every_corner_of_every_triangle_exactly() {
        let result = Arc::new(sample(500, Criterion::Error));
        let bytes = encode(&result, &Options::default()).to_vec();
        let (models, _) =
            tobj::load_obj_buf(&mut bytes.as_slice(), &tobj::LoadOptions::default(), |_| unreachable!())
                .unwrap();
        assert_eq!(models.len(), 1);
        let mesh = &models[0].mesh;
        // tobj renumbers the vertices in the order faces first use them, so compare corner by
        // corner: that checks the indices and the positions together.
        assert_eq!(mesh.positions.len(), 3 * result.vertices.len());
        assert_eq!(mesh.indices.len(), 3 * result.triangles.len());
        for (t, corners) in result.triangles.iter().zip(mesh.indices.chunks(3)) {
            for (&v, &got) in t.iter().zip(corners) {
                let v = result.vertices[v as usize];
                let p = &mesh.positions[3 * got as usize..][..3];
                assert_eq!(p, [v.x, v.y, v.z], "triangle {t:?}");
            }
        }
    }
}
