//! What each physics derives from a solution, as the named fields of its result: η_T for
//! every problem, the region each triangle lies in when there are regions, and in
//! magnetostatics the flux density B, the field strength H and the relative permeability μr
//! per triangle.

use super::adapt::Adapted;
use super::element::Element;
use super::physics::MU_0;
use crate::geom::Vertex;
use crate::result::{Field, Geometry, Lines, Physics, Role, RunResult, SolutionStats, Summary};

impl Adapted {
    /// The result of this solve: z = u at every vertex, η_T per triangle, the fields of
    /// `physics`, and each triangle's region (its index, −1 for none).
    pub fn into_result(self, physics: Physics) -> RunResult {
        let vertices = self.mesh.vertices().to_vec();
        let triangles: Vec<[u32; 3]> = self.mesh.triangles().collect();
        let mut fields: Vec<Field> =
            self.indicators.map(crate::result::triangle_errors).into_iter().collect();
        if physics == Physics::Magnetostatic {
            fields.extend(magnetostatic(self.geometry, &vertices, &triangles, &self.fields));
        }
        if !self.region_of.is_empty() {
            let region = self.region_of.iter().map(|&i| f64::from(i)).collect();
            fields.push(Field::cell_scalar("region", "region", "", Role::Extra, region));
        }
        RunResult {
            vertices,
            triangles,
            fields,
            stats: Summary::Solution(SolutionStats {
                physics,
                geometry: self.geometry,
                unit: None,
                depth: None,
                run: self.stats,
            }),
            trace: None,
        }
    }
}

/// B = (∂A/∂y, −∂A/∂x) from the potential at the vertices, in tesla; H = (q_y, −q_x) from the
/// flux q the weak form tests, in A/m; and μr = 1/(μ0 ν), the secant permeability B/(μ0 H)
/// on a B–H curve. `flux` holds [q_x, q_y, ν] per triangle.
fn magnetostatic(
    geometry: Geometry,
    vertices: &[Vertex],
    triangles: &[[u32; 3]],
    flux: &[[f64; 3]],
) -> [Field; 3] {
    [
        flux_density(geometry, vertices, triangles),
        Field::cell_vector(
            "H",
            "magnetic_field",
            "A/m",
            Role::Extra,
            flux.iter().map(|&[qx, qy, _]| [qy, -qx]),
        ),
        Field::cell_scalar(
            "mu_r",
            "relative_permeability",
            "",
            Role::Extra,
            flux.iter().map(|&[_, _, k]| 1.0 / (MU_0 * k)).collect(),
        ),
    ]
}

/// B = (∂A/∂y, −∂A/∂x) per triangle, in tesla, from A = z at the vertices; its field lines
/// are the contours of A. Axisymmetric, B = (B_r, B_z) from A_φ (see [`Element`]), and the
/// field lines are the contours of r·A_φ.
pub(crate) fn flux_density(geometry: Geometry, vertices: &[Vertex], triangles: &[[u32; 3]]) -> Field {
    let b = triangles.iter().enumerate().map(|(t, &tri)| {
        let z = tri.map(|v| vertices[v as usize].z);
        // The solver's triangles are counter-clockwise, so this never fails.
        let g = Element::in_geometry(geometry, vertices, tri, t).map_or([0.0; 2], |e| e.field(z));
        [g[1], -g[0]]
    });
    let lines = match geometry {
        Geometry::Planar => {
            Lines { name: "field lines".into(), z: "A".into(), z_unit: "Wb/m".into(), times_x: false }
        }
        Geometry::Axisymmetric => {
            Lines { name: "field lines".into(), z: "r·A".into(), z_unit: "Wb/rad".into(), times_x: true }
        }
    };
    Field { lines: Some(lines), ..Field::cell_vector("B", "flux_density", "T", Role::Main, b) }
}
