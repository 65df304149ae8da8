//! Gmsh MSH 4.1, ASCII: the triangles as a 2-D mesh of the rectangle (nodes at `x y 0`), with
//! F as the node view "z" and every field of the result as a node or element view of its name
//! (the triangle errors as "error", a magnetostatic solution's flux density as the vector view
//! "B" (Bx, By, 0), …).
//!
//! The plane mesh and F apart is how a finite-element tool wants it: the domain is the
//! geometry, F a field on it. There is one surface entity (tag 1) holding every node and
//! element; node and element tags are the result's ids plus one (Gmsh counts from 1).
//! Numbers are the shortest text that reads back as the same f64.

use super::encoded::push_f64;
use super::{Encoded, Options, Part};
use crate::result::{Location, RunResult};
use std::io::Write;
use std::sync::Arc;

/// The MSH file of `result`.
pub(super) fn encode(result: &Arc<RunResult>, _options: &Options) -> Encoded {
    let (n, m) = (result.vertices.len(), result.triangles.len());
    // One surface entity, bounded by the rectangle; it has no physical groups and no curves.
    let [x0, x1, y0, y1] = result.bounds();
    let mut head = b"$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Entities\n0 0 1 0\n1 ".to_vec();
    for (i, c) in [x0, y0, 0.0, x1, y1, 0.0].into_iter().enumerate() {
        if i > 0 {
            head.push(b' ');
        }
        push_f64(&mut head, c);
    }
    // numEntityBlocks numNodes minNodeTag maxNodeTag, then the block: entityDim entityTag
    // parametric numNodesInBlock, its tags, its coordinates.
    write!(head, " 0 0\n$EndEntities\n$Nodes\n1 {n} 1 {n}\n2 1 0 {n}\n").expect("a Vec");
    let elements = format!("$EndNodes\n$Elements\n1 {m} 1 {m}\n2 1 2 {m}\n");
    let node_data = format!("$EndElements\n$NodeData\n1\n\"z\"\n1\n0\n3\n0\n1\n{n}\n");
    let (r, s, t) = (result.clone(), result.clone(), result.clone());
    let mut parts = vec![
        Part::Bytes(head),
        Part::rows(n, |i, out| writeln!(out, "{}", i + 1).expect("a Vec")),
        Part::rows(n, move |i, out| {
            let v = r.vertices[i];
            push_f64(out, v.x);
            out.push(b' ');
            push_f64(out, v.y);
            out.extend_from_slice(b" 0\n");
        }),
        Part::Bytes(elements.into_bytes()),
        Part::rows(m, move |i, out| {
            let [a, b, c] = s.triangles[i].map(|v| u64::from(v) + 1);
            writeln!(out, "{} {a} {b} {c}", i + 1).expect("a Vec");
        }),
        Part::Bytes(node_data.into_bytes()),
        Part::rows(n, move |i, out| {
            write!(out, "{} ", i + 1).expect("a Vec");
            push_f64(out, t.vertices[i].z);
            out.push(b'\n');
        }),
    ];
    let mut tail = b"$EndNodeData\n".to_vec();
    // Each field is a view of its own after z's: per node, then per element.
    for location in [Location::Point, Location::Cell] {
        let (section, count) = match location {
            Location::Point => ("NodeData", n),
            Location::Cell => ("ElementData", m),
        };
        for f in result.at(location) {
            let field = &result.fields[f];
            // A vector in the plane is a 3-component view (x, y, 0), as Gmsh draws vectors.
            let vector = field.components > 1;
            let components = if vector { 3 } else { 1 };
            tail.extend_from_slice(
                format!("${section}\n1\n\"{}\"\n1\n0\n3\n0\n{components}\n{count}\n", field.name).as_bytes(),
            );
            parts.push(Part::Bytes(std::mem::take(&mut tail)));
            let r = result.clone();
            parts.push(Part::rows(count, move |i, out| {
                write!(out, "{}", i + 1).expect("a Vec");
                for &c in r.fields[f].value(i) {
                    out.push(b' ');
                    push_f64(out, c);
                }
                out.extend_from_slice(if vector { b" 0\n" } else { b"\n" });
            }));
            tail.extend_from_slice(format!("$End{section}\n").as_bytes());
        }
    }
    parts.push(Part::Bytes(tail));
    Encoded::new(parts)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::refine::Criterion;
    use crate::result::testing::sample;
    use mshio::mshfile::ElementType;

    /// The `(tag, value)` rows of the view named `name` in section `$section`.
    ///
    /// mshio skips post-processing sections, so the views are read here, as the format
    /// describes them: 1 string tag (the name), 1 real tag, 3 integer tags, then the rows.
    fn view(text: &str, section: &str, name: &str) -> Vec<(u64, f64)> {
        let start = text.find(&format!("${section}\n")).unwrap_or_else(|| panic!("no ${section}"));
        let end = text.find(&format!("$End{section}\n")).unwrap();
        let lines: Vec<&str> = text[start..end].lines().skip(1).collect();
        assert_eq!(lines[..3], ["1", &format!("\"{name}\""), "1"]);
        assert_eq!(lines[4..7], ["3", "0", "1"]);
        let rows: Vec<(u64, f64)> = lines[8..]
            .iter()
            .map(|l| {
                let (tag, value) = l.split_once(' ').unwrap();
                (tag.parse().unwrap(), value.parse().unwrap())
            })
            .collect();
        assert_eq!(lines[7].parse::<usize>().unwrap(), rows.len());
        rows
    }

    #[test]
    fn mshio_reads_back_the_exact_nodes_and_triangles() {
        let result = Arc::new(sample(500, Criterion::Error));
        let bytes = encode(&result, &Options::default()).to_vec();
        let msh = mshio::parse_msh_bytes(&bytes).unwrap();
        assert_eq!((msh.header.version, msh.header.file_type), (4.1, 0));
        let surfaces = &msh.data.entities.as_ref().unwrap().surfaces;
        assert_eq!(surfaces.len(), 1);
        let nodes = msh.data.nodes.unwrap();
        assert_eq!(nodes.num_nodes as usize, result.vertices.len());
        let [block] = &nodes.node_blocks[..] else { panic!("{} node blocks", nodes.node_blocks.len()) };
        assert_eq!((block.entity_dim, block.entity_tag, surfaces[0].tag), (2, 1, 1));
        assert!(block.node_tags.is_none(), "tags are 1..=n in order");
        for (got, v) in block.nodes.iter().zip(&result.vertices) {
            assert_eq!([got.x, got.y, got.z], [v.x, v.y, 0.0]);
        }
        assert_eq!(block.nodes.len(), result.vertices.len());
        let elements = msh.data.elements.unwrap();
        let [block] = &elements.element_blocks[..] else { panic!("several element blocks") };
        assert_eq!(block.element_type, ElementType::Tri3);
        assert_eq!(block.elements.len(), result.triangles.len());
        for (i, (got, t)) in block.elements.iter().zip(&result.triangles).enumerate() {
            assert_eq!(got.element_tag, i as u64 + 1);
            assert_eq!(got.nodes, t.map(|v| u64::from(v) + 1));
        }
    }

    #[test]
    fn the_views_hold_z_per_node_and_the_error_per_triangle() {
        let result = Arc::new(sample(500, Criterion::Error));
        let text = String::from_utf8(encode(&result, &Options::default()).to_vec()).unwrap();
        let z: Vec<(u64, f64)> =
            result.vertices.iter().enumerate().map(|(i, v)| (i as u64 + 1, v.z)).collect();
        assert_eq!(view(&text, "NodeData", "z"), z);
        let errors = result.indicator().unwrap();
        let e: Vec<(u64, f64)> = errors.iter().enumerate().map(|(i, &e)| (i as u64 + 1, e)).collect();
        assert_eq!(view(&text, "ElementData", "error"), e);
    }

    #[test]
    fn without_triangle_errors_there_is_no_element_view() {
        let result = Arc::new(sample(50, Criterion::Variation));
        let bytes = encode(&result, &Options::default()).to_vec();
        let text = std::str::from_utf8(&bytes).unwrap();
        assert!(!text.contains("$ElementData") && text.ends_with("$EndNodeData\n"));
        assert!(mshio::parse_msh_bytes(&bytes).is_ok());
    }
}
