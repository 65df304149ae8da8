//! Results as bytes: each format a client can ask for, encoded from a [`MeshResult`].
//!
//! An encoder does not write the whole file at once. It returns an [`Encoded`]: a list of
//! parts, each either fixed bytes (a header) or rows made on demand (one vertex, one triangle).
//! [`Encoded::write_to`] writes it to a file or stdout; [`Encoded::into_chunks`] makes it
//! piece by piece for an HTTP body, so a client reading a 10^6-vertex mesh costs one chunk of
//! memory beyond the shared result, however slowly it reads.

pub mod colour;
mod contour;
mod glb;
pub mod json;
mod msh;
mod obj;
mod picture;
mod ply;
pub mod png;
mod stl;
pub mod svg;
mod vtu;

use crate::result::MeshResult;
use std::io::{self, Write};
use std::sync::Arc;

/// A way to write a mesh out.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Format {
    /// The mesh document (JSON).
    Json,
    /// Wavefront OBJ: text positions and 1-based faces, for any modeller.
    Obj,
    /// Binary little-endian PLY with f64 positions and, when known, each triangle's error.
    Ply,
    /// Binary STL: f32 facets with normals, for slicers and CAD.
    Stl,
    /// VTK XML unstructured grid with z and the triangle errors as data, for ParaView.
    Vtu,
    /// Gmsh 4.1 ASCII with z and the triangle errors as views, for Gmsh and FEM tools.
    Msh,
    /// Binary glTF 2.0, coloured by z, for web viewers (`z_scale` applies).
    Glb,
    /// The mesh seen from above, coloured by z, as SVG.
    Svg,
    /// The mesh seen from above, coloured by z, as PNG.
    Png,
}

impl Format {
    /// Every format, in the order they are listed to clients.
    pub const ALL: &[Format] = &[
        Format::Json,
        Format::Obj,
        Format::Ply,
        Format::Stl,
        Format::Vtu,
        Format::Msh,
        Format::Glb,
        Format::Svg,
        Format::Png,
    ];

    /// The name used by `?format=`, `--format` and as the file extension.
    pub fn name(self) -> &'static str {
        match self {
            Format::Json => "json",
            Format::Obj => "obj",
            Format::Ply => "ply",
            Format::Stl => "stl",
            Format::Vtu => "vtu",
            Format::Msh => "msh",
            Format::Glb => "glb",
            Format::Svg => "svg",
            Format::Png => "png",
        }
    }

    /// The media type of the response.
    pub fn media_type(self) -> &'static str {
        match self {
            Format::Json => "application/json",
            Format::Obj => "model/obj",
            Format::Ply => "application/x-ply",
            Format::Stl => "model/stl",
            Format::Vtu => "application/vnd.vtk.vtu+xml",
            Format::Msh => "text/x-gmsh",
            Format::Glb => "model/gltf-binary",
            Format::Svg => "image/svg+xml",
            Format::Png => "image/png",
        }
    }

    /// The format called `name` (case-insensitive).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|f| f.name().eq_ignore_ascii_case(name))
    }

    /// The format whose media type is `media_type` (parameters and case ignored).
    pub fn from_media_type(media_type: &str) -> Option<Self> {
        let essence = media_type.split(';').next().unwrap_or("").trim();
        Self::ALL.iter().copied().find(|f| f.media_type().eq_ignore_ascii_case(essence))
    }

    /// The names of all formats, comma-separated, for error messages.
    pub fn names() -> String {
        Self::ALL.iter().map(|f| f.name()).collect::<Vec<_>>().join(", ")
    }
}

impl std::fmt::Display for Format {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// What an encoding may be asked besides the mesh.
#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    /// The job id, written where a format has room for it (the JSON document's `id`).
    pub id: Option<String>,
    /// Factor on z for 3-D formats that a viewer shows to scale (glb).
    pub z_scale: f64,
    /// Width in pixels of a raster picture (png).
    pub size: u32,
}

impl Default for Options {
    fn default() -> Self {
        Self { id: None, z_scale: 1.0, size: 1024 }
    }
}

/// Writes row `i` of a part.
type RowFn = Box<dyn Fn(usize, &mut Vec<u8>) + Send + Sync>;

/// One piece of an encoding.
pub enum Part {
    /// Bytes known up front.
    Bytes(Vec<u8>),
    /// `count` rows, each written on demand.
    Rows {
        /// How many.
        count: usize,
        /// Appends row `i`.
        write: RowFn,
    },
}

impl Part {
    /// `count` rows written by `write`.
    pub fn rows(count: usize, write: impl Fn(usize, &mut Vec<u8>) + Send + Sync + 'static) -> Self {
        Part::Rows { count, write: Box::new(write) }
    }
}

/// A result in one format, as parts to write in order.
pub struct Encoded {
    parts: Vec<Part>,
}

/// How many bytes a chunk of [`Encoded::into_chunks`] gathers before it is handed on.
const CHUNK_BYTES: usize = 64 * 1024;

impl Encoded {
    /// The parts, in order.
    pub fn new(parts: Vec<Part>) -> Self {
        Self { parts }
    }

    /// Writes everything to `out`.
    ///
    /// # Errors
    /// Whatever writing to `out` returns.
    pub fn write_to(self, out: &mut impl Write) -> io::Result<()> {
        for chunk in self.into_chunks() {
            out.write_all(&chunk)?;
        }
        Ok(())
    }

    /// The bytes in chunks of about 64 KiB, made as they are asked for.
    pub fn into_chunks(self) -> Chunks {
        Chunks { parts: self.parts.into_iter(), current: None, buf: Vec::new() }
    }

    /// All of it in one buffer (tests, small results).
    pub fn to_vec(self) -> Vec<u8> {
        let mut out = Vec::new();
        self.write_to(&mut out).expect("writing to a Vec does not fail");
        out
    }
}

/// The chunks of an [`Encoded`].
pub struct Chunks {
    parts: std::vec::IntoIter<Part>,
    /// The rows part being written and its next row.
    current: Option<(usize, RowFn, usize)>,
    buf: Vec<u8>,
}

impl Iterator for Chunks {
    type Item = Vec<u8>;

    fn next(&mut self) -> Option<Vec<u8>> {
        self.buf.reserve(CHUNK_BYTES);
        while self.buf.len() < CHUNK_BYTES {
            if let Some((count, write, next)) = &mut self.current {
                while *next < *count && self.buf.len() < CHUNK_BYTES {
                    write(*next, &mut self.buf);
                    *next += 1;
                }
                if *next == *count {
                    self.current = None;
                }
                continue;
            }
            match self.parts.next() {
                Some(Part::Bytes(bytes)) if self.buf.is_empty() && bytes.len() >= CHUNK_BYTES => {
                    // A large fixed part (a rendered picture) goes out as it is, uncopied.
                    return Some(bytes);
                }
                Some(Part::Bytes(bytes)) => self.buf.extend_from_slice(&bytes),
                Some(Part::Rows { count, write }) => self.current = Some((count, write, 0)),
                None => break,
            }
        }
        (!self.buf.is_empty()).then(|| std::mem::take(&mut self.buf))
    }
}

/// `result` in `format`.
pub fn encode(result: &Arc<MeshResult>, format: Format, options: &Options) -> Encoded {
    match format {
        Format::Json => json::encode(result, options),
        Format::Obj => obj::encode(result, options),
        Format::Ply => ply::encode(result, options),
        Format::Stl => stl::encode(result, options),
        Format::Vtu => vtu::encode(result, options),
        Format::Msh => msh::encode(result, options),
        Format::Glb => glb::encode(result, options),
        Format::Svg => svg::encode(result, options),
        Format::Png => png::encode(result, options),
    }
}

/// Appends `x` as the shortest text that reads back as the same f64 (`0.1`, `1e-7`, `-0.0`).
fn push_f64(out: &mut Vec<u8>, x: f64) {
    // ryu rather than `{}`: `{}` writes 1e-300 as 300 digits, and ryu is faster.
    out.extend_from_slice(ryu::Buffer::new().format(x).as_bytes());
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunks_hold_every_byte_in_order_and_stay_near_the_chunk_size() {
        let rows = 100_000;
        let encoding = Encoded::new(vec![
            Part::Bytes(b"head".to_vec()),
            Part::rows(rows, |i, out| out.extend_from_slice(format!("{i},").as_bytes())),
            Part::Bytes(vec![b'x'; 3 * CHUNK_BYTES]),
            Part::rows(0, |_, _| unreachable!()),
            Part::Bytes(b"tail".to_vec()),
        ]);
        let chunks: Vec<Vec<u8>> = encoding.into_chunks().collect();
        let mut expected = b"head".to_vec();
        (0..rows).for_each(|i| expected.extend_from_slice(format!("{i},").as_bytes()));
        expected.extend(vec![b'x'; 3 * CHUNK_BYTES]);
        expected.extend_from_slice(b"tail");
        assert_eq!(chunks.concat(), expected);
        // Every chunk but the last is full (a row may pass the mark by its own length).
        for c in &chunks[..chunks.len() - 1] {
            assert!(c.len() >= CHUNK_BYTES && c.len() < 4 * CHUNK_BYTES, "{}", c.len());
        }
    }

    /// The bytes of `encoding` made without [`Chunks`]: every row on its own, last to first,
    /// then joined in order. A row that leaned on state left by the row before would differ.
    fn rows_one_by_one_backwards(encoding: Encoded) -> Vec<u8> {
        encoding.parts.into_iter().flat_map(part_backwards).collect()
    }

    /// One part's bytes, its rows made last to first and joined in order.
    pub(super) fn part_backwards(part: Part) -> Vec<u8> {
        match part {
            Part::Bytes(bytes) => bytes,
            Part::Rows { count, write } => {
                let mut rows: Vec<Vec<u8>> = (0..count)
                    .rev()
                    .map(|i| {
                        let mut row = Vec::new();
                        write(i, &mut row);
                        row
                    })
                    .collect();
                rows.reverse();
                rows.concat()
            }
        }
    }

    #[test]
    fn every_format_streams_the_bytes_it_would_write_whole() {
        use crate::refine::Criterion;
        use crate::result::testing::sample;
        let result = Arc::new(sample(20_000, Criterion::Error));
        let options = Options { id: Some("abc".into()), z_scale: 2.5, ..Options::default() };
        for &format in Format::ALL {
            let chunks: Vec<Vec<u8>> = encode(&result, format, &options).into_chunks().collect();
            // A png is drawn whole: one part, handed on as it is.
            if format != Format::Png {
                assert!(chunks.len() > 2, "{format}: {} chunks", chunks.len());
                assert!(chunks.iter().all(|c| c.len() < 2 * CHUNK_BYTES), "{format}");
            }
            let streamed = chunks.concat();
            assert!(streamed == encode(&result, format, &options).to_vec(), "{format}");
            assert!(streamed == rows_one_by_one_backwards(encode(&result, format, &options)), "{format}");
        }
    }

    #[test]
    fn names_and_media_types_map_back_to_their_format() {
        for &f in Format::ALL {
            assert_eq!(Format::from_name(f.name()), Some(f));
            assert_eq!(Format::from_name(&f.name().to_uppercase()), Some(f));
            assert_eq!(Format::from_media_type(&format!("{}; q=0.9", f.media_type())), Some(f));
        }
        assert_eq!(Format::from_name("xyz"), None);
    }
}
