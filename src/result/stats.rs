//! What a finished run reports, a mesh's or a solution's, in the form the API, the JSON
//! document and the stored results carry.
//!
//! These are the wire's report types, apart from the engine's working types: the mesher's
//! [`Stats`] become a [`MeshStats`] once, as a run becomes a result, so renaming one of its
//! counters is a compile error here rather than a silent change of the API or of the cache's
//! files. A solution's report types live here too, below the solver that fills them, so
//! that a result (and every store and writer of one) knows nothing of how it was computed.

use crate::refine::{ErrorEstimate, Sample, Stats, StopReason};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// What a result's run reports: a mesh's stats or a solution's.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Summary {
    /// A mesh of F.
    Mesh(MeshStats),
    /// The solution of a boundary value problem.
    Solution(SolutionStats),
}

/// A mesh's counters and outcome, as reported.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MeshStats {
    /// Vertices n.
    pub vertices: usize,
    /// Triangles (2n − h − 2).
    pub triangles: usize,
    /// V_n = max |zᵢ − zⱼ| over the edges of the final mesh.
    pub variation: f64,
    /// For the `error` criterion: the largest triangle error estimate e(T) at the end.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_triangle_error: Option<f64>,
    /// Edge flips made.
    pub flips: u64,
    /// Edges retired instead of split.
    pub retired_edges: u64,
    /// Evaluations of F.
    pub evaluations: u64,
    /// Why the run stopped.
    pub stop: StopReason,
    /// Whether the final mesh passes the exact in-circle test on every interior edge.
    pub delaunay: bool,
    /// With `min_angle`: triangles of the final mesh with a smaller angle.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub below_min_angle: Option<u64>,
    /// V_n and the worst criterion value at vertex counts 4, 6, 8, 12, 16, 24, … and at the
    /// end: the run's convergence.
    pub history: Vec<Checkpoint>,
    /// The final mesh measured against F, when the request asked (`quality`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub quality: Option<Quality>,
}

/// The state of a run at one vertex count.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Checkpoint {
    /// Vertices n.
    pub vertices: usize,
    /// V_n.
    pub variation: f64,
    /// The worst criterion value compared with the tolerance, if checked at this count.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub worst: Option<f64>,
}

/// A mesh measured against F by sampling.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Quality {
    /// E_n ≈ max |F − F_n| over the samples.
    pub max_error: f64,
    /// Root mean square of F − F_n, area-weighted.
    pub rms_error: f64,
    /// The smallest interior angle of any triangle, in degrees.
    pub min_angle_deg: f64,
    /// How many points were sampled.
    pub samples: u64,
}

impl From<Stats> for MeshStats {
    fn from(s: Stats) -> Self {
        // Every field named, none by `..`: a counter added to the mesher must be placed here.
        let Stats {
            vertices,
            triangles,
            variation,
            max_triangle_error,
            flips,
            retired_edges,
            evaluations,
            stop,
            delaunay,
            below_min_angle,
            history,
            quality,
        } = s;
        Self {
            vertices,
            triangles,
            variation,
            max_triangle_error,
            flips,
            retired_edges,
            evaluations,
            stop,
            delaunay,
            below_min_angle,
            history: history.into_iter().map(Checkpoint::from).collect(),
            quality: quality.map(Quality::from),
        }
    }
}

impl From<Sample> for Checkpoint {
    fn from(Sample { vertices, variation, worst }: Sample) -> Self {
        Self { vertices, variation, worst }
    }
}

impl From<ErrorEstimate> for Quality {
    fn from(ErrorEstimate { max_error, rms_error, min_angle_deg, samples }: ErrorEstimate) -> Self {
        Self { max_error, rms_error, min_angle_deg, samples }
    }
}

/// A solution's stats with what u stands for.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SolutionStats {
    /// What u stands for.
    pub physics: Physics,
    /// `axisymmetric` when the problem is solved in (r, z) for A_φ; absent when planar.
    #[serde(skip_serializing_if = "Geometry::is_planar", default)]
    pub geometry: Geometry,
    /// The unit of every length in the request and the answer (vertices, areas in its
    /// square), when the request named one; fields and integrals stay SI.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub unit: Option<Unit>,
    /// The planar device's depth in `unit`, when given: forces, torques, energies, flux
    /// linkages and inductances are then totals (N, N·m, J, Wb, H), not per metre of depth.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub depth: Option<f64>,
    /// The adaptive loop's counters, estimate, energy and history.
    #[serde(flatten)]
    pub run: SolveStats,
}

/// Why a run stopped: one of the mesher's reasons, or a solver's own. Written as one name
/// (`"max_vertices"`, `"not_converged"`), whichever it is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(into = "StopName", from = "StopName")]
pub enum Stop {
    /// The mesher stopped: its budget, tolerance, time limit, cancellation or exhaustion.
    Mesh(StopReason),
    /// A boundary value problem's Newton iteration did not converge on the latest mesh; the
    /// result is the last round that did.
    NotConverged,
}

/// [`Stop`] as written: the mesher's name, or the solver's.
#[derive(Clone, Copy, Serialize, Deserialize)]
#[serde(untagged)]
enum StopName {
    Mesh(StopReason),
    Solver(SolverStop),
}

#[derive(Clone, Copy, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
enum SolverStop {
    NotConverged,
}

impl From<Stop> for StopName {
    fn from(stop: Stop) -> Self {
        match stop {
            Stop::Mesh(reason) => StopName::Mesh(reason),
            Stop::NotConverged => StopName::Solver(SolverStop::NotConverged),
        }
    }
}

impl From<StopName> for Stop {
    fn from(name: StopName) -> Self {
        match name {
            StopName::Mesh(reason) => Stop::Mesh(reason),
            StopName::Solver(SolverStop::NotConverged) => Stop::NotConverged,
        }
    }
}

impl Summary {
    /// Why the run stopped.
    pub fn stop(&self) -> Stop {
        match self {
            Summary::Mesh(s) => Stop::Mesh(s.stop),
            Summary::Solution(s) => s.run.stop,
        }
    }

    /// What u stands for, for a solution.
    pub fn physics(&self) -> Option<Physics> {
        match self {
            Summary::Mesh(_) => None,
            Summary::Solution(s) => Some(s.physics),
        }
    }
}

/// What u stands for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Physics {
    /// −∇·(k ∇u) = f as given.
    #[default]
    Poisson,
    /// u is the vector potential A_z (Wb/m): k = 1/(μ0 μr), f = J_z (A/m²), and the flux
    /// density is B = (∂A/∂y, −∂A/∂x) in tesla.
    Magnetostatic,
}

/// How the plane is read: a slice of an infinitely deep device, or a half-plane (r, z) turned
/// about the axis r = 0.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Geometry {
    /// x and y; u is A_z; figures per metre of depth.
    #[default]
    Planar,
    /// x is r ≥ 0 and y is z; u is A_φ; figures for the whole turn about the axis.
    Axisymmetric,
}

impl Geometry {
    /// Whether it is the default, planar.
    pub fn is_planar(&self) -> bool {
        *self == Geometry::Planar
    }
}

/// A unit of length for a device's geometry.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Unit {
    /// Metres.
    #[default]
    M,
    /// Centimetres.
    Cm,
    /// Millimetres.
    Mm,
}

impl Unit {
    /// How many of this unit make a metre: a length in metres is the length in this unit
    /// divided by it, and back again multiplied, each one correctly rounded operation.
    pub fn per_metre(self) -> f64 {
        match self {
            Unit::M => 1.0,
            Unit::Cm => 100.0,
            Unit::Mm => 1000.0,
        }
    }
}

/// One solve of the loop.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Step {
    /// Vertices of the mesh solved on.
    pub vertices: usize,
    /// The estimate on it.
    pub estimate: f64,
    /// ½ ∫ k |∇u_h|².
    pub energy: f64,
    /// max over vertices of |u − u_h|, with an exact solution.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub max_nodal_error: Option<f64>,
    /// ‖u − u_h‖_L2, with an exact solution.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub l2_error: Option<f64>,
    /// ‖k^½ ∇(u − u_h)‖_L2, with an exact solution.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub energy_error: Option<f64>,
    /// Newton steps of this solve (a nonlinear problem).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub newton_iterations: Option<u32>,
    /// Newton's final relative residual ‖R‖₂ / ‖R(u = 0 inside)‖₂ (a nonlinear problem).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub newton_residual: Option<f64>,
}

/// The outcome of the loop; the same request gives the same stats, bit for bit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SolveStats {
    /// Vertices of the final mesh.
    pub vertices: usize,
    /// Its triangles.
    pub triangles: usize,
    /// Unknowns of the final solve (vertices not on the boundary).
    pub unknowns: usize,
    /// Solves made.
    pub solves: usize,
    /// The estimate on the final mesh.
    pub estimate: f64,
    /// ½ ∫ k |∇u_h|² on the final mesh (J/m for magnetostatics); on a curve or in a magnet,
    /// ∫ H·dB along the material's law from where H = 0.
    pub energy: f64,
    /// ∫ B·H minus the energy: the coenergy (J/m), whose derivative is the force at
    /// constant current.
    pub coenergy: f64,
    /// Edge flips made.
    pub flips: u64,
    /// Edges retired instead of split.
    pub retired_edges: u64,
    /// Why the loop stopped.
    pub stop: Stop,
    /// Whether the final mesh passes the exact in-circle test on every interior edge that is
    /// not a region's side: a constrained Delaunay triangulation when there are regions.
    pub delaunay: bool,
    /// Interior edges that lie on a region's side (the mesh follows every side).
    #[serde(skip_serializing_if = "is_zero", default)]
    pub constrained_edges: usize,
    /// One entry per region, in the problem's order.
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub regions: Vec<RegionStats>,
    /// One entry per circuit, by name.
    #[serde(skip_serializing_if = "BTreeMap::is_empty", default)]
    pub circuits: BTreeMap<String, CircuitStats>,
    /// One entry per solve, in order.
    pub history: Vec<Step>,
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

/// One region's figures, in the request's order of regions.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RegionStats {
    /// The region's name, when the request gave one.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub name: Option<String>,
    /// The area the region's shape encloses (m², or the square of the request's unit).
    pub area: f64,
    /// f over that area: the region's current in A (ampere-turns for a coil side) in
    /// magnetostatics.
    pub current: f64,
    /// The mean of u over the triangles inside (Wb/m: flux linkage per turn is the difference
    /// of two coil sides' means).
    pub mean_a: f64,
    /// The force on everything inside, [fx, fy] (N/m, or N for a depth).
    pub force: [f64; 2],
    /// The torque about the region's `torque_about` point, the origin by default (N·m/m, or
    /// N·m for a depth).
    pub torque: f64,
}

/// One circuit's figures: the coil sides that name it in series, each turn carrying its
/// current.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CircuitStats {
    /// The current in every turn (A).
    pub current: f64,
    /// λ = Σ over its coil sides of direction · turns · the side's mean A (Wb/m, or Wb for a
    /// depth).
    pub flux_linkage: f64,
    /// The apparent inductance λ/I (H/m, or H for a depth); absent at zero current.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub inductance: Option<f64>,
    /// The incremental inductance dλ/dI at this operating point, from the tangent system of
    /// the final solve (H/m, or H for a depth): equal to λ/I for a linear device without
    /// magnets, below it for saturated iron.
    pub incremental_inductance: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stop_is_written_as_one_name_whichever_part_stopped_and_reads_back() {
        for (stop, name) in [
            (Stop::Mesh(StopReason::TimeLimit), "\"time_limit\""),
            (Stop::Mesh(StopReason::Exhausted), "\"exhausted\""),
            (Stop::NotConverged, "\"not_converged\""),
        ] {
            assert_eq!(serde_json::to_string(&stop).unwrap(), name);
            assert_eq!(serde_json::from_str::<Stop>(name).unwrap(), stop);
        }
        assert!(serde_json::from_str::<Stop>("\"tired\"").is_err());
    }
}
