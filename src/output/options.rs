//! What a client may set on any format: the id a document names, the 3-D formats' z scale and
//! a picture's size.

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
