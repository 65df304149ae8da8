//! PLY 1.0, binary little-endian: f64 vertices, then faces of three `int` indices, each with
//! the result's indicator field (`double error`) when it has one.
//!
//! Binary keeps every f64 exact at 24 bytes a vertex. Faces are counter-clockwise, 0-based.

use super::{Encoded, Options, Part};
use crate::result::{Role, RunResult};
use std::sync::Arc;

/// The PLY file of `result`.
pub(super) fn encode(result: &Arc<RunResult>, options: &Options) -> Encoded {
    // A face has room for one number: the refinement's indicator, under its field's name.
    let indicator = result.with_role(Role::Indicator);
    let mut head = format!(
        "ply\nformat binary_little_endian 1.0\ncomment meshfit\n\
         element vertex {}\nproperty double x\nproperty double y\nproperty double z\n\
         element face {}\nproperty list uchar int vertex_indices\n",
        result.vertices.len(),
        result.triangles.len()
    );
    if let Some(f) = indicator {
        head.push_str(&format!("property double {}\n", result.fields[f].name));
    }
    head.push_str("end_header\n");
    let (r, s, z_scale) = (result.clone(), result.clone(), options.z_scale);
    Encoded::new(vec![
        Part::Bytes(head.into_bytes()),
        Part::rows(result.vertices.len(), move |i, out| {
            let v = r.vertices[i];
            for c in [v.x, v.y, v.z * z_scale] {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }),
        Part::rows(result.triangles.len(), move |i, out| {
            out.push(3);
            for v in s.triangles[i] {
                // `int` is what readers expect for indices; a mesh stays far below 2^31 vertices.
                let v = i32::try_from(v).expect("vertex ids fit an int");
                out.extend_from_slice(&v.to_le_bytes());
            }
            if let Some(f) = indicator {
                out.extend_from_slice(&s.fields[f].values[i].to_le_bytes());
            }
        }),
    ])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::refine::Criterion;
    use crate::result::testing::sample;
    use ply_rs_bw::parser::Parser;
    use ply_rs_bw::ply::{DefaultElement, Ply, Property};

    fn read(result: &Arc<RunResult>) -> Ply<DefaultElement> {
        let bytes = encode(result, &Options::default()).to_vec();
        Parser::<DefaultElement>::new().read_ply(&mut bytes.as_slice()).unwrap()
    }

    fn double(e: &DefaultElement, name: &str) -> f64 {
        match e.get(name) {
            Some(Property::Double(d)) => *d,
            other => panic!("{name} is {other:?}"),
        }
    }

    #[test]
    fn ply_rs_reads_back_the_exact_vertices_faces_and_errors() {
        let result = Arc::new(sample(500, Criterion::Error));
        let ply = read(&result);
        let vertices = &ply.payload["vertex"];
        assert_eq!(vertices.len(), result.vertices.len());
        for (got, v) in vertices.iter().zip(&result.vertices) {
            assert_eq!([double(got, "x"), double(got, "y"), double(got, "z")], [v.x, v.y, v.z]);
        }
        let faces = &ply.payload["face"];
        let errors = result.indicator().unwrap();
        assert_eq!(faces.len(), result.triangles.len());
        for ((got, t), &e) in faces.iter().zip(&result.triangles).zip(errors) {
            let expected: Vec<i32> = t.iter().map(|&v| v as i32).collect();
            assert_eq!(got["vertex_indices"], Property::ListInt(expected));
            assert_eq!(double(got, "error").to_bits(), e.to_bits());
        }
    }

    #[test]
    fn without_triangle_errors_faces_have_no_error_property() {
        let result = Arc::new(sample(50, Criterion::Variation));
        let ply = read(&result);
        let face = &ply.header.elements["face"];
        assert_eq!(face.count, result.triangles.len());
        assert_eq!(face.properties.keys().collect::<Vec<_>>(), ["vertex_indices"]);
        assert!(ply.payload["face"].iter().all(|f| f.len() == 1));
    }
}
