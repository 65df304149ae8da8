//! The size floors below which no edge is split and no triangle is made.

use crate::geom::{Point, Rect};

/// Edges shorter than this fraction of the rectangle's diagonal are never split.
pub const LENGTH_FLOOR: f64 = 1e-9;

/// No split creates a triangle smaller than this fraction of the rectangle's area.
pub const AREA_FLOOR: f64 = 1e-18;

/// The smallest edge a refinement splits and the smallest triangle it makes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Floors {
    /// Fixed fractions of the rectangle ([`LENGTH_FLOOR`], [`AREA_FLOOR`]): a mesh never
    /// needs finer, and the floors stop value-driven splitting from creeping toward a point.
    Rect {
        /// Squared length floor.
        length_sq: f64,
        /// Floor on twice a new triangle's area.
        area_x2: f64,
    },
    /// What floating point resolves around the edge: [`RESOLUTION`] of its coordinates'
    /// magnitude, and never below [`ABSOLUTE_FLOOR`]. A solution's singular point may need
    /// vertices many orders of magnitude closer to it than the rectangle's size.
    Resolution,
}

/// The relative length floor of a solution's mesh: about 10^6 units in the last place of the
/// edge's coordinates, so a singular point gets vertices as close as floating point resolves.
pub const RESOLUTION: f64 = 1.0 / (1u64 << 32) as f64;

/// The absolute length floor of a solution's mesh: the exact predicates multiply up to
/// four coordinate differences, and 1e-60⁴ stays far above the subnormal range.
pub const ABSOLUTE_FLOOR: f64 = 1e-60;

impl Floors {
    /// The floors of a mesh of `rect`.
    pub(crate) fn of_rect(rect: Rect) -> Self {
        Self::Rect {
            length_sq: (LENGTH_FLOOR * rect.diagonal()).powi(2),
            area_x2: 2.0 * AREA_FLOOR * rect.area(),
        }
    }

    /// (squared length floor, floor on twice a new triangle's area) for the edge a–b.
    #[inline]
    pub(super) fn at(&self, a: Point, b: Point) -> (f64, f64) {
        match *self {
            Self::Rect { length_sq, area_x2 } => (length_sq, area_x2),
            Self::Resolution => {
                let scale = a.x.abs().max(a.y.abs()).max(b.x.abs()).max(b.y.abs());
                let floor = (RESOLUTION * scale).max(ABSOLUTE_FLOOR);
                (floor * floor, floor * floor)
            }
        }
    }
}
