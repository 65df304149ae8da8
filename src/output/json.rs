//! The mesh document: `{"vertices": [[x, y, z], ...], "triangles": [[i, j, k], ...], "stats": {...}}`.
//!
//! Numbers are written by serde_json's shortest round-trip formatting, so a reader gets back
//! the exact f64 values. Vertices are in insertion order, triangles counter-clockwise.

use crate::refine::{ErrorEstimate, Refinement, Stats};
use serde::Serialize;
use serde::ser::{SerializeStruct, Serializer};
use std::io::{self, Write};

/// Borrowed view of a refinement that serialises as the mesh document without copying it;
/// the API's document starts with the job id.
pub struct MeshDocument<'a> {
    refinement: &'a Refinement,
    id: Option<&'a str>,
}

impl<'a> MeshDocument<'a> {
    /// The document without an id (the command line's).
    pub fn new(refinement: &'a Refinement) -> Self {
        Self { refinement, id: None }
    }

    /// The document with `"id"` first (the API's).
    pub fn with_id(refinement: &'a Refinement, id: &'a str) -> Self {
        Self { refinement, id: Some(id) }
    }
}

impl Serialize for MeshDocument<'_> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mesh = &self.refinement.mesh;
        let mut doc = serializer.serialize_struct("MeshDocument", 4)?;
        if let Some(id) = self.id {
            doc.serialize_field("id", id)?;
        }
        doc.serialize_field("vertices", &Vertices(mesh.vertices()))?;
        doc.serialize_field("triangles", &Triangles(mesh))?;
        doc.serialize_field("stats", &self.refinement.stats)?;
        doc.end()
    }
}

struct Vertices<'a>(&'a [crate::geom::Vertex]);

impl Serialize for Vertices<'_> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_seq(self.0.iter().map(|v| [v.x, v.y, v.z]))
    }
}

struct Triangles<'a>(&'a crate::geom::Mesh);

impl Serialize for Triangles<'_> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_seq(self.0.triangles())
    }
}

/// Writes the mesh document to `out`.
///
/// # Errors
/// Whatever writing to `out` returns.
pub fn write_mesh(refinement: &Refinement, out: &mut impl Write) -> io::Result<()> {
    serde_json::to_writer(&mut *out, &MeshDocument::new(refinement)).map_err(io::Error::from)
}

/// The stats-only document: `{"stats": {...}, "error": {...}}`.
#[derive(Serialize)]
pub struct StatsDocument<'a> {
    /// The run's counters and outcome.
    pub stats: &'a Stats,
    /// The E_n estimate.
    pub error: ErrorEstimate,
}

/// Writes the stats-only document to `out`.
///
/// # Errors
/// Whatever writing to `out` returns.
pub fn write_stats(stats: &Stats, error: ErrorEstimate, out: &mut impl Write) -> io::Result<()> {
    serde_json::to_writer_pretty(&mut *out, &StatsDocument { stats, error }).map_err(io::Error::from)
}
