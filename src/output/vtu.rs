//! VTK XML unstructured grid (`.vtu`), as ParaView opens it: f64 points `x y z`, the triangles
//! as cells of type 5, F as the point array "z", and every field of the result as a point or
//! cell array of its name (the triangle errors as "error", a magnetostatic solution's flux
//! density as the vector "B", …).
//!
//! Arrays are inline `format="binary"`: base64 of a UInt64 byte count followed by the
//! little-endian values, one base64 stream per array. Raw appended data would be a quarter
//! smaller, but vtkio, the reader the tests use, takes appended data only as base64 (0.7), or
//! reads the raw bytes as XML text and fails at the first byte 0x3C, `<` (0.6).

use super::{Encoded, Options, Part};
use crate::result::{Location, RunResult};
use base64::Engine;
use base64::engine::general_purpose::STANDARD;
use std::sync::Arc;

/// VTK's cell type of a 3-node triangle.
const VTK_TRIANGLE: u8 = 5;

/// The VTU file of `result`.
pub(super) fn encode(result: &Arc<RunResult>, options: &Options) -> Encoded {
    let (n, m) = (result.vertices.len(), result.triangles.len());
    let array = |attributes: &str| format!("<DataArray {attributes} format=\"binary\">").into_bytes();
    let mut parts = vec![
        Part::Bytes(
            format!(
                "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" \
                 byte_order=\"LittleEndian\" header_type=\"UInt64\">\n<UnstructuredGrid>\n\
                 <Piece NumberOfPoints=\"{n}\" NumberOfCells=\"{m}\">\n<PointData Scalars=\"z\">\n"
            )
            .into_bytes(),
        ),
        Part::Bytes(array("type=\"Float64\" Name=\"z\"")),
        {
            let r = result.clone();
            binary_array(n, 8, move |i, out| out.extend_from_slice(&r.vertices[i].z.to_le_bytes()))
        },
        Part::Bytes(b"</DataArray>\n".to_vec()),
    ];
    // Fields per vertex join z; fields per triangle are the cell data.
    for f in result.at(Location::Point) {
        parts.extend(data_array(result, f, n));
    }
    parts.push(Part::Bytes(b"</PointData>\n".to_vec()));
    let cell_fields: Vec<usize> = result.at(Location::Cell).collect();
    if !cell_fields.is_empty() {
        parts.push(Part::Bytes(b"<CellData>\n".to_vec()));
        for f in cell_fields {
            parts.extend(data_array(result, f, m));
        }
        parts.push(Part::Bytes(b"</CellData>\n".to_vec()));
    }
    let (r, s, z_scale) = (result.clone(), result.clone(), options.z_scale);
    parts.extend([
        Part::Bytes(b"<Points>\n".to_vec()),
        Part::Bytes(array("type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\"")),
        binary_array(n, 24, move |i, out| {
            let v = r.vertices[i];
            // The points are scaled for the view; the z array keeps the values.
            for c in [v.x, v.y, v.z * z_scale] {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }),
        Part::Bytes(b"</DataArray>\n</Points>\n<Cells>\n".to_vec()),
        Part::Bytes(array("type=\"Int64\" Name=\"connectivity\"")),
        binary_array(m, 24, move |i, out| {
            for v in s.triangles[i] {
                out.extend_from_slice(&i64::from(v).to_le_bytes());
            }
        }),
        Part::Bytes(b"</DataArray>\n".to_vec()),
        Part::Bytes(array("type=\"Int64\" Name=\"offsets\"")),
        // Offsets are where each cell's ids end: 3, 6, 9, ...
        binary_array(m, 8, |i, out| out.extend_from_slice(&(3 * i as i64 + 3).to_le_bytes())),
        Part::Bytes(b"</DataArray>\n".to_vec()),
        Part::Bytes(array("type=\"UInt8\" Name=\"types\"")),
        binary_array(m, 1, |_, out| out.push(VTK_TRIANGLE)),
        Part::Bytes(b"</DataArray>\n</Cells>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n".to_vec()),
    ]);
    Encoded::new(parts)
}

/// Field `f` of `result` as a data array of `count` values: a scalar as is, a vector in the
/// plane as three components (x, y, 0), which is what ParaView draws as vectors.
fn data_array(result: &Arc<RunResult>, f: usize, count: usize) -> [Part; 3] {
    let field = &result.fields[f];
    let vector = field.components > 1;
    let attributes = match vector {
        true => format!("type=\"Float64\" Name=\"{}\" NumberOfComponents=\"3\"", field.name),
        false => format!("type=\"Float64\" Name=\"{}\"", field.name),
    };
    let r = result.clone();
    [
        Part::Bytes(format!("<DataArray {attributes} format=\"binary\">").into_bytes()),
        binary_array(count, if vector { 24 } else { 8 }, move |i, out| {
            let value = r.fields[f].value(i);
            for c in value {
                out.extend_from_slice(&c.to_le_bytes());
            }
            if vector {
                out.extend_from_slice(&0.0f64.to_le_bytes());
            }
        }),
        Part::Bytes(b"</DataArray>\n".to_vec()),
    ]
}

/// Items per row of a [`binary_array`]: a row's scratch buffer and the two bytes it reads
/// ahead are then small beside its own bytes.
const ITEMS_PER_ROW: usize = 64;

/// The base64 text of a binary data array: a UInt64 byte count, then `count` items of `size`
/// bytes each, as `item(j, out)` appends them.
///
/// Base64 turns each 3 bytes into 4 characters, and the 8-byte count puts item boundaries off
/// that grid. So a row emits the groups that *start* in its own bytes, reading up to two bytes
/// of the next item to finish the last one. Each row thus depends on its index alone, and any
/// chunking gives the same text as encoding the whole array at once.
fn binary_array(
    count: usize,
    size: usize,
    item: impl Fn(usize, &mut Vec<u8>) + Send + Sync + 'static,
) -> Part {
    let total = 8 + count * size;
    let header = ((count * size) as u64).to_le_bytes();
    // Row 0 is the count; row r > 0 holds items (r - 1) * ITEMS_PER_ROW onwards. The row
    // after the last starts at `total`.
    let row_start = move |r: usize| if r == 0 { 0 } else { (8 + (r - 1) * ITEMS_PER_ROW * size).min(total) };
    let rows = 1 + count.div_ceil(ITEMS_PER_ROW);
    Part::rows(rows, move |r, out| {
        let (start, end) = (row_start(r), row_start(r + 1));
        // The groups starting in [start, end), the last one padded if the array ends there.
        let (from, to) = (start.next_multiple_of(3), end.next_multiple_of(3).min(total));
        if from >= to {
            return;
        }
        let mut raw = Vec::with_capacity(to - start + size);
        let mut next = if r == 0 {
            raw.extend_from_slice(&header);
            0
        } else {
            (r - 1) * ITEMS_PER_ROW
        };
        while start + raw.len() < to {
            item(next, &mut raw);
            next += 1;
        }
        let raw = &raw[from - start..to - start];
        let at = out.len();
        out.resize(at + raw.len().div_ceil(3) * 4, 0);
        STANDARD.encode_slice(raw, &mut out[at..]).expect("sized for padded base64");
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::refine::Criterion;
    use crate::result::testing::sample;
    use vtkio::model::{Attribute, CellType, DataSet, Piece, VertexNumbers};

    /// The one inline piece of the unstructured grid vtkio reads from `bytes`.
    fn read(bytes: &[u8]) -> vtkio::model::UnstructuredGridPiece {
        let vtk = vtkio::Vtk::parse_xml(bytes).unwrap();
        let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else { panic!("not a grid") };
        let [Piece::Inline(piece)] = <[_; 1]>::try_from(pieces).unwrap() else { panic!("not inline") };
        *piece
    }

    /// The f64 values of the attribute called `name`.
    fn values(attributes: &[Attribute], name: &str) -> Vec<f64> {
        let found = attributes.iter().find_map(|a| match a {
            Attribute::DataArray(d) if d.name == name => Some(d.data.clone()),
            _ => None,
        });
        found.unwrap_or_else(|| panic!("no {name}")).into_vec::<f64>().unwrap()
    }

    #[test]
    fn vtkio_reads_back_the_exact_points_cells_z_and_errors() {
        let result = Arc::new(sample(500, Criterion::Error));
        let piece = read(&encode(&result, &Options::default()).to_vec());
        let points = piece.points.into_vec::<f64>().unwrap();
        let expected: Vec<f64> = result.vertices.iter().flat_map(|v| [v.x, v.y, v.z]).collect();
        assert_eq!(points, expected);
        let VertexNumbers::XML { connectivity, offsets } = &piece.cells.cell_verts else { panic!("legacy") };
        let expected: Vec<u64> = result.triangles.iter().flatten().map(|&v| u64::from(v)).collect();
        assert_eq!(connectivity, &expected);
        assert_eq!(offsets, &(1..=result.triangles.len() as u64).map(|i| 3 * i).collect::<Vec<_>>());
        assert!(piece.cells.types.iter().all(|&t| t == CellType::Triangle));
        assert_eq!(piece.cells.types.len(), result.triangles.len());
        let z: Vec<f64> = result.vertices.iter().map(|v| v.z).collect();
        assert_eq!(values(&piece.data.point, "z"), z);
        assert_eq!(&values(&piece.data.cell, "error"), result.indicator().unwrap());
    }

    #[test]
    fn a_solution_carries_mu_r_and_each_triangles_region_as_cell_data() {
        let result = Arc::new(crate::result::testing::magnetic(300));
        let piece = read(&encode(&result, &Options::default()).to_vec());
        assert_eq!(values(&piece.data.cell, "region"), result.field("region").unwrap().values);
        let regions = values(&piece.data.cell, "region");
        assert!(regions.contains(&0.0) && regions.contains(&-1.0), "the conductor and the air around it");
        assert_eq!(values(&piece.data.cell, "mu_r"), result.field("mu_r").unwrap().values);
    }

    #[test]
    fn without_triangle_errors_there_is_no_cell_data() {
        let result = Arc::new(sample(50, Criterion::Variation));
        let piece = read(&encode(&result, &Options::default()).to_vec());
        assert!(piece.data.cell.is_empty());
        assert_eq!(piece.data.point.len(), 1);
    }

    #[test]
    fn a_binary_array_is_the_base64_of_its_count_and_items_for_every_length_and_item_size() {
        for size in [1, 2, 8, 24] {
            for count in [0, 1, 2, 3, 63, 64, 65, 200] {
                let item =
                    move |j: usize, out: &mut Vec<u8>| out.extend((0..size).map(|k| (j * 7 + k) as u8));
                let mut raw = ((count * size) as u64).to_le_bytes().to_vec();
                (0..count).for_each(|j| item(j, &mut raw));
                // Rows written last to first, so a row that leaned on its predecessor would show.
                let part = binary_array(count, size, item);
                assert!(matches!(part, Part::Rows { .. }), "a binary array streams as rows");
                let pieces = crate::output::encoded::tests::part_backwards(part);
                assert_eq!(pieces, STANDARD.encode(&raw).into_bytes(), "{count} items of {size}");
            }
        }
    }
}
