//! The formats a client can ask for, by name or media type, the options they take, and the
//! one call that encodes a result in any of them.

use super::encoded::Encoded;
use super::options::Options;
use super::{glb, json, msh, obj, ply, png, stl, svg, vtu};
use crate::result::RunResult;
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
    /// Binary glTF 2.0, coloured by z, for web viewers.
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

    /// Whether `z_scale` applies: the formats whose positions are 3-D (the JSON document and
    /// msh carry z as a value, the pictures as a colour).
    pub fn takes_z_scale(self) -> bool {
        matches!(self, Format::Obj | Format::Ply | Format::Stl | Format::Vtu | Format::Glb)
    }

    /// Whether `size` applies: the raster picture.
    pub fn takes_size(self) -> bool {
        self == Format::Png
    }

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

/// `result` in `format`.
pub fn encode(result: &Arc<RunResult>, format: Format, options: &Options) -> Encoded {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::output::encoded::CHUNK_BYTES;
    use crate::output::encoded::tests::part_backwards;

    /// The bytes of `encoding` made without [`Chunks`]: every row on its own, last to first,
    /// then joined in order. A row that leaned on state left by the row before would differ.
    fn rows_one_by_one_backwards(encoding: Encoded) -> Vec<u8> {
        encoding.parts.into_iter().flat_map(part_backwards).collect()
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
