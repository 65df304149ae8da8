//! A finished run as data: the mesh's arrays, its named fields, its report and its trace.

use super::field::{Field, Location, Role};
use super::stats::Summary;
use crate::geom::Vertex;
use crate::refine::Refinement;
use crate::refine::trace::Trace;
use std::sync::Arc;

/// A refined mesh of F or a solution on one: vertices in insertion order (any prefix is an
/// earlier step's vertex set), counter-clockwise triangles, and what is known on them.
#[derive(Debug, Clone, PartialEq)]
pub struct RunResult {
    /// x, y and z (F, or the solution u), in insertion order; the first four are the
    /// rectangle's corners.
    pub vertices: Vec<Vertex>,
    /// Vertex ids of each triangle, counter-clockwise.
    pub triangles: Vec<[u32; 3]>,
    /// Named quantities per vertex or triangle, in the order writers list them.
    pub fields: Vec<Field>,
    /// The run's counters and outcome.
    pub stats: Summary,
    /// What each step of the run did, so that smaller requests are answered from it (none
    /// for a result that was itself replayed from another).
    pub trace: Option<Arc<Trace>>,
}

/// The indicator field of a mesh of F: e(T) = max |F − F_n| sampled on each triangle.
pub fn triangle_errors(errors: Vec<f64>) -> Field {
    Field::cell_scalar("error", "triangle_errors", "", Role::Indicator, errors)
}

impl From<Refinement> for RunResult {
    fn from(r: Refinement) -> Self {
        Self {
            vertices: r.mesh.vertices().to_vec(),
            triangles: r.mesh.triangles().collect(),
            fields: r.triangle_errors.map(triangle_errors).into_iter().collect(),
            stats: Summary::Mesh(r.stats.into()),
            trace: None,
        }
    }
}

impl RunResult {
    /// The field named `name`, if the result has one.
    pub fn field(&self, name: &str) -> Option<&Field> {
        self.fields.iter().find(|f| f.name == name)
    }

    /// The refinement's measure of each triangle (e(T) of a mesh of F, η_T of a solution),
    /// when the run kept one.
    pub fn indicator(&self) -> Option<&[f64]> {
        self.with_role(Role::Indicator).map(|f| &self.fields[f].values[..])
    }

    /// The quantity the run is about, if it has one beyond z.
    pub fn main_field(&self) -> Option<&Field> {
        self.with_role(Role::Main).map(|f| &self.fields[f])
    }

    /// The index in [`RunResult::fields`] of the first field of `role`. Writers keep indices
    /// rather than borrows: their rows are made later, from a shared result.
    pub fn with_role(&self, role: Role) -> Option<usize> {
        self.fields.iter().position(|f| f.role == role)
    }

    /// The indices in [`RunResult::fields`] of the fields at `location`, in order.
    pub fn at(&self, location: Location) -> impl Iterator<Item = usize> + '_ {
        (0..self.fields.len()).filter(move |&f| self.fields[f].location == location)
    }

    /// Bytes the arrays take in memory: what a cache weighs it by.
    pub fn num_bytes(&self) -> usize {
        size_of::<Self>()
            + self.vertices.len() * size_of::<Vertex>()
            + self.triangles.len() * size_of::<[u32; 3]>()
            + self
                .fields
                .iter()
                .map(|f| size_of::<Field>() + f.values.len() * size_of::<f64>())
                .sum::<usize>()
            + self.trace.as_ref().map_or(0, |t| t.num_bytes())
    }

    /// The smallest and largest z, or (0, 0) for no vertices.
    pub fn z_range(&self) -> (f64, f64) {
        let mut zs = self.vertices.iter().map(|v| v.z);
        let first = zs.next().unwrap_or(0.0);
        zs.fold((first, first), |(lo, hi), z| (lo.min(z), hi.max(z)))
    }

    /// The rectangle [x0, x1] × [y0, y1] the vertices span.
    pub fn bounds(&self) -> [f64; 4] {
        let mut b = [f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY];
        for v in &self.vertices {
            b = [b[0].min(v.x), b[1].max(v.x), b[2].min(v.y), b[3].max(v.y)];
        }
        b
    }
}
