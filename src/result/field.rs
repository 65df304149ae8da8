//! Named quantities on a result's mesh: point data (one value per vertex) and cell data (one
//! per triangle), each with its unit and components, the meshio / scikit-fem model.
//!
//! Whoever makes a result names what it knows (the refinement its error per triangle, a
//! physics the quantities it derives from its solution); writers loop over the fields they can
//! carry and know no physics.

use serde::{Deserialize, Serialize};
use std::borrow::Cow;

/// Where a field's values sit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Location {
    /// One value (of `components` numbers) per vertex, in vertex order.
    Point,
    /// One value per triangle, in triangle order.
    Cell,
}

/// What a field is to the run that made it, which tells each writer whether to carry it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Role {
    /// The refinement's measure of each triangle: e(T) for a mesh of F, η_T for a solution.
    /// Every format with per-face data carries it.
    Indicator,
    /// The quantity the run is about: the mesh document carries it and pictures colour by its
    /// magnitude. At most one per result.
    Main,
    /// Carried by the full formats (VTU, MSH) only.
    Extra,
}

/// The contours of z that a field's lines follow (a magnetic field's lines are the contours
/// of the vector potential A), so that a picture can draw and name them.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Lines {
    /// What the lines are called ("field lines").
    pub name: Cow<'static, str>,
    /// What z stands for ("A").
    pub z: Cow<'static, str>,
    /// z's unit ("Wb/m").
    pub z_unit: Cow<'static, str>,
    /// Whether the lines follow x·z rather than z: an axisymmetric field's lines are the
    /// contours of r·A_φ, the flux through the circle of radius r over 2π.
    #[serde(default)]
    pub times_x: bool,
}

/// A named array on the mesh.
///
/// `values` holds `components` numbers per vertex or triangle, interleaved: `[x0, y0, x1, y1,
/// …]` for a vector of two components. The metadata serializes without the values, which
/// stores keep in binary.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Field {
    /// The short name formats with a name per array use ("error", "B").
    pub name: Cow<'static, str>,
    /// The long name a JSON document keys it by ("triangle_errors", "flux_density").
    pub key: Cow<'static, str>,
    /// Its SI unit ("T", "A/m"), empty for F's own unit or none.
    pub unit: Cow<'static, str>,
    /// Per vertex or per triangle.
    pub location: Location,
    /// Numbers per value: 1 for a scalar, 2 for a vector in the plane.
    pub components: u8,
    /// Which writers carry it.
    pub role: Role,
    /// For a vector field: the contours of z its lines follow.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lines: Option<Lines>,
    /// The numbers, `components` per value.
    #[serde(skip)]
    pub values: Vec<f64>,
}

impl Field {
    /// A scalar per triangle.
    pub fn cell_scalar(
        name: &'static str,
        key: &'static str,
        unit: &'static str,
        role: Role,
        values: Vec<f64>,
    ) -> Self {
        Self {
            name: name.into(),
            key: key.into(),
            unit: unit.into(),
            location: Location::Cell,
            components: 1,
            role,
            lines: None,
            values,
        }
    }

    /// A vector in the plane per triangle.
    pub fn cell_vector(
        name: &'static str,
        key: &'static str,
        unit: &'static str,
        role: Role,
        values: impl IntoIterator<Item = [f64; 2]>,
    ) -> Self {
        let values = values.into_iter().flatten().collect();
        Self { components: 2, ..Self::cell_scalar(name, key, unit, role, values) }
    }

    /// How many vertices or triangles the field has values for.
    pub fn len(&self) -> usize {
        self.values.len() / usize::from(self.components.max(1))
    }

    /// Whether the field has no values.
    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    /// The value of vertex or triangle `i`: its `components` numbers.
    pub fn value(&self, i: usize) -> &[f64] {
        let c = usize::from(self.components);
        &self.values[c * i..c * i + c]
    }

    /// The length of value `i`: |v| for a scalar, the Euclidean norm of a vector.
    pub fn magnitude(&self, i: usize) -> f64 {
        match *self.value(i) {
            [v] => v.abs(),
            [x, y] => x.hypot(y),
            ref v => v.iter().map(|c| c * c).sum::<f64>().sqrt(),
        }
    }
}
