//! What a finished solution says at points and along lines: its fields at points, the flux
//! through a polyline, and H's line integral along it.
//!
//! Lengths are the result's own (the request's unit); what comes out is SI. The flux through
//! a polyline from a to b is exact for P1: planar B = (∂A/∂y, −∂A/∂x), so ∫ B·n ds with n the
//! normal to the right of travel is A(b) − A(a), per metre of depth (times the depth when the
//! request gave one); axisymmetric, the surface the polyline sweeps about the axis carries
//! 2π (r_b A(b) − r_a A(a)). H is constant on each triangle, so ∫ H·dl is a sum over the
//! pieces of the polyline between the triangles' edges, which a walk from triangle to
//! triangle finds ([`Locator::crossings`]).

use super::locate::Locator;
use super::{Geometry, RunResult, Summary};
use crate::geom::Point;

/// Why a polyline cannot be measured.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LineError {
    /// A point lies outside the mesh.
    #[error("point {0} of the polyline lies outside the domain")]
    Outside(usize),
    /// The result carries no field H: it is not a magnetostatic solution.
    #[error("the result has no magnetic field: a polyline is measured on magnetostatic solutions")]
    NotMagnetic,
}

/// The flux through a polyline and H's line integral along it.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Line {
    /// Wb: per metre of depth planar without a depth, else the total.
    pub flux: f64,
    /// ∫ H·dl in A (ampere-turns): around a closed polyline, the current it encloses.
    pub mmf: f64,
    /// Whether the polyline is closed (its last point its first).
    pub closed: bool,
}

/// A solution's length unit per metre, its depth in metres, and its geometry.
fn frame(result: &RunResult) -> (f64, Option<f64>, Geometry) {
    match &result.stats {
        Summary::Solution(s) => {
            let per_metre = s.unit.unwrap_or_default().per_metre();
            (per_metre, s.depth.map(|d| d / per_metre), s.geometry)
        }
        Summary::Mesh(_) => (1.0, None, Geometry::Planar),
    }
}

/// A vector per point, `None` where the point lies outside the mesh.
pub type AtPoints = Vec<Option<[f64; 2]>>;

/// B and H of the triangle holding each of `points`, each point located once; `None` when the
/// result carries no B and H (it is not a magnetostatic solution).
pub fn fields_at(result: &RunResult, locator: &Locator, points: &[Point]) -> Option<(AtPoints, AtPoints)> {
    let per_triangle =
        |name| result.field(name).filter(|f| f.components == 2 && f.len() == result.triangles.len());
    let (b, h) = (per_triangle("B")?, per_triangle("H")?);
    let at = |f: &super::Field, t: u32| <[f64; 2]>::try_from(f.value(t as usize)).expect("two components");
    Some(
        (points.iter())
            .map(|&p| match locator.locate(p) {
                Some(t) => (Some(at(b, t)), Some(at(h, t))),
                None => (None, None),
            })
            .unzip(),
    )
}

/// The flux through `polyline` and H's line integral along it.
///
/// # Errors
/// [`LineError::Outside`] naming the first point outside the mesh, and
/// [`LineError::NotMagnetic`] for a result without H.
pub fn line(result: &RunResult, locator: &Locator, polyline: &[Point]) -> Result<Line, LineError> {
    let h = result.field("H").filter(|f| f.components == 2).ok_or(LineError::NotMagnetic)?;
    let (per_metre, depth, geometry) = frame(result);
    let mut a = Vec::with_capacity(polyline.len());
    for (i, &p) in polyline.iter().enumerate() {
        a.push(locator.value(p).ok_or(LineError::Outside(i))?);
    }
    let (first, last) = (polyline[0], polyline[polyline.len() - 1]);
    let (a0, a1) = (a[0], a[a.len() - 1]);
    let flux = match geometry {
        Geometry::Planar => (a1 - a0) * depth.unwrap_or(1.0),
        Geometry::Axisymmetric => 2.0 * std::f64::consts::PI * (last.x * a1 - first.x * a0) / per_metre,
    };
    let mut mmf = 0.0;
    for (i, pair) in polyline.windows(2).enumerate() {
        let [p, q] = [pair[0], pair[1]];
        let step = [(q.x - p.x) / per_metre, (q.y - p.y) / per_metre];
        let whole = locator.crossings(p, q, |t, fraction| {
            let v = h.value(t as usize);
            mmf += fraction * (v[0] * step[0] + v[1] * step[1]);
        });
        if !whole {
            return Err(LineError::Outside(i + 1));
        }
    }
    Ok(Line { flux, mmf, closed: polyline.len() > 2 && first == last })
}
