//! What a refinement is asked to do: method, criterion and stop rules.

use std::fmt;
use std::str::FromStr;
use std::time::Duration;

/// Whether edges are flipped after each insertion, and after the last one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// No flips: old vertices and edges never move; the split edge becomes its halves.
    Recursive,
    /// Lawson flips after each insertion keep the mesh a Delaunay triangulation.
    #[default]
    SemiRecursive,
    /// `semi-recursive`, then data-dependent flips (Dyn, Levin and Rippa 1990) of the worst
    /// triangles: while a flip of the worst triangle's edge lowers the larger error of the two
    /// triangles beside it, the best such flip is made; flips that lowered no maximum are
    /// undone. The vertices are the same, the largest error never higher, and the mesh is the
    /// Delaunay one unless flips lowered the maximum. Grids with criterion `error` only: the
    /// flips compare the mesh with the grid's nodes.
    DataDependent,
}

/// How the worst edge is chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Criterion {
    /// The paper's exact algorithm: the edge with the largest |zᵢ − zⱼ|. With `recursive`, best
    /// where F's level lines are straight (exp(x + y)); blind to features between equal vertex
    /// values.
    Variation,
    /// An edge of the triangle with the largest sampled error max |F − F_n|: the end of its
    /// longest-edge path for `recursive`, its worst long edge for `semi-recursive`. Finds
    /// features between vertex values, down to the sampling lattice's resolution.
    #[default]
    Error,
    /// The edge whose midpoint the vertices' gradients say is worst interpolated:
    /// |(gᵢ − gⱼ)·(Pⱼ − Pᵢ)| / 8, each vertex's gradient the area-weighted mean of its
    /// triangles'. One evaluation a vertex, as `variation`, but spreads the interpolation
    /// error instead of the slope; blind, as `variation` is, to what no vertex has seen.
    Curvature,
}

/// The largest vertex budget the engine accepts: vertex and half-edge ids are `u32`, and a
/// mesh of n vertices has up to 6n half-edges.
pub const MAX_VERTICES: usize = 400_000_000;

/// Refinement parameters, checked where they are made: by [`Params::new`] for the defaults,
/// or by [`Params::builder`]'s [`build`](ParamsBuilder::build).
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    method: Method,
    criterion: Criterion,
    max_vertices: usize,
    tolerance: Option<f64>,
    time_limit: Option<Duration>,
    min_angle: Option<f64>,
    min_size: Option<f64>,
    max_size: Option<f64>,
}

/// The largest `min_angle` in degrees: Lepp-Delaunay refinement is known to end below it.
pub const MAX_MIN_ANGLE: f64 = 30.0;

/// A parameter out of range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ParamsError {
    /// The budget is below 4 (the corners) or above `max`: [`MAX_VERTICES`], or a server's
    /// lower limit.
    #[error("max_vertices must be between 4 and {max}, got {got}")]
    MaxVertices {
        /// The budget asked for.
        got: u64,
        /// The largest allowed.
        max: u64,
    },
    /// The tolerance is negative or not finite.
    #[error("tolerance must be a finite number >= 0, got {0}")]
    Tolerance(f64),
    /// The smallest angle asked for is not in (0, 30] degrees.
    #[error("min_angle must be above 0 and at most {MAX_MIN_ANGLE} degrees, got {0}")]
    MinAngle(f64),
    /// `min_angle` with a criterion of edges (`variation`, `curvature`), which has no
    /// triangles to repair first.
    #[error("min_angle needs criterion error: variation and curvature split their worst edge only")]
    MinAngleCriterion,
    /// `min_size` or `max_size` not a finite length above 0.
    #[error("{name} must be a finite length above 0, got {got}")]
    Size {
        /// `min_size` or `max_size`.
        name: &'static str,
        /// The length asked for.
        got: f64,
    },
    /// `min_size` or `max_size` with a criterion other than `curvature`.
    #[error(
        "{0} needs criterion curvature, whose edges it bounds (error and variation have size floors of their own)"
    )]
    SizeCriterion(&'static str),
    /// `max_size` below twice `min_size`: an edge longer than `max_size` could not be split.
    #[error("max_size must be at least twice min_size (an edge is split into halves), got {max} < 2 x {min}")]
    SizeOrder {
        /// `min_size`.
        min: f64,
        /// `max_size`.
        max: f64,
    },
    /// Method `data-dependent` without a grid and criterion `error`.
    #[error(
        "method data-dependent needs a grid and criterion error: its flips compare the mesh with the grid's nodes"
    )]
    DataDependentSource,
}

impl Params {
    /// Semi-recursive refinement by error up to `max_vertices` vertices (the paper's n).
    ///
    /// # Errors
    /// When `max_vertices` is below 4 or above [`MAX_VERTICES`].
    pub fn new(max_vertices: usize) -> Result<Self, ParamsError> {
        Self::builder(max_vertices).build()
    }

    /// Parameters to set one by one, checked together by [`ParamsBuilder::build`].
    pub fn builder(max_vertices: usize) -> ParamsBuilder {
        ParamsBuilder {
            max_vertices,
            method: Method::default(),
            criterion: Criterion::default(),
            tolerance: None,
            time_limit: None,
            min_angle: None,
            min_size: None,
            max_size: None,
            on_grid: false,
        }
    }

    /// The method.
    pub fn method(&self) -> Method {
        self.method
    }
    /// The criterion.
    pub fn criterion(&self) -> Criterion {
        self.criterion
    }
    /// The vertex budget n.
    pub fn max_vertices(&self) -> usize {
        self.max_vertices
    }
    /// The tolerance, if any.
    pub fn tolerance(&self) -> Option<f64> {
        self.tolerance
    }
    /// The time limit, if any.
    pub fn time_limit(&self) -> Option<Duration> {
        self.time_limit
    }
    /// The smallest angle in degrees that criterion `error` repairs up to, if any.
    pub fn min_angle(&self) -> Option<f64> {
        self.min_angle
    }
    /// Criterion `curvature`: no midpoint nearer than this to its edge's ends, if set.
    pub fn min_size(&self) -> Option<f64> {
        self.min_size
    }
    /// Criterion `curvature`: every edge longer than this is split first, if set.
    pub fn max_size(&self) -> Option<f64> {
        self.max_size
    }
}

/// [`Params`] set one by one; [`ParamsBuilder::build`] checks each value and how they fit
/// together, so every caller (the API, the command line, a library user) gets the same rules.
///
/// ```
/// use meshfit::refine::{Criterion, Method, Params, ParamsError};
/// let params = Params::builder(10_000).method(Method::Recursive).tolerance(1e-3).build().unwrap();
/// assert_eq!((params.max_vertices(), params.tolerance()), (10_000, Some(1e-3)));
/// let paper = Params::builder(100).criterion(Criterion::Variation).min_angle(20.0).build();
/// assert_eq!(paper, Err(ParamsError::MinAngleCriterion));
/// ```
#[derive(Debug, Clone, PartialEq)]
#[must_use = "a builder does nothing until it is built"]
pub struct ParamsBuilder {
    max_vertices: usize,
    method: Method,
    criterion: Criterion,
    tolerance: Option<f64>,
    time_limit: Option<Duration>,
    min_angle: Option<f64>,
    min_size: Option<f64>,
    max_size: Option<f64>,
    on_grid: bool,
}

impl ParamsBuilder {
    /// The method (default `semi-recursive`).
    pub fn method(mut self, method: Method) -> Self {
        self.method = method;
        self
    }

    /// The criterion (default `error`).
    pub fn criterion(mut self, criterion: Criterion) -> Self {
        self.criterion = criterion;
        self
    }

    /// Stops once the worst criterion value (the largest e(T) for `error`, the largest
    /// |zᵢ − zⱼ| for `variation`) is at most `tolerance`: finite and ≥ 0.
    pub fn tolerance(mut self, tolerance: f64) -> Self {
        self.tolerance = Some(tolerance);
        self
    }

    /// With criterion `error`, repairs every triangle whose smallest angle is below `degrees`
    /// (above 0, at most [`MAX_MIN_ANGLE`]) before any error-driven split (see the
    /// refinement's docs).
    pub fn min_angle(mut self, degrees: f64) -> Self {
        self.min_angle = Some(degrees);
        self
    }

    /// With criterion `curvature`, never splits an edge shorter than twice `length` (in the
    /// rectangle's units), so no midpoint is nearer than `length` to its edge's ends: a kink
    /// or a step cannot draw the whole budget.
    pub fn min_size(mut self, length: f64) -> Self {
        self.min_size = Some(length);
        self
    }

    /// With criterion `curvature`, splits every edge longer than `length` before any other
    /// (longest first, and the tolerance waits for them): no part of the rectangle is left
    /// unseen at a coarser scale.
    pub fn max_size(mut self, length: f64) -> Self {
        self.max_size = Some(length);
        self
    }

    /// Stops once this much time has passed.
    pub fn time_limit(mut self, limit: Duration) -> Self {
        self.time_limit = Some(limit);
        self
    }

    /// Whether F is a sampled grid, which method `data-dependent` needs (elsewhere
    /// [`refine`](super::refine) would run it as `semi-recursive`).
    pub fn on_grid(mut self, on_grid: bool) -> Self {
        self.on_grid = on_grid;
        self
    }

    /// The parameters, once each is in range and they fit together.
    ///
    /// # Errors
    /// The first of, in this order: [`ParamsError::MaxVertices`] for a budget below 4 or
    /// above [`MAX_VERTICES`], [`ParamsError::Tolerance`], [`ParamsError::MinAngleCriterion`]
    /// for `min_angle` with criterion `variation`, [`ParamsError::MinAngle`], and
    /// [`ParamsError::DataDependentSource`] for `data-dependent` off a grid or without
    /// criterion `error`; then [`ParamsError::SizeCriterion`], [`ParamsError::Size`] and
    /// [`ParamsError::SizeOrder`].
    pub fn build(self) -> Result<Params, ParamsError> {
        let Self {
            max_vertices,
            method,
            criterion,
            tolerance,
            time_limit,
            min_angle,
            min_size,
            max_size,
            on_grid,
        } = self;
        if !(4..=MAX_VERTICES).contains(&max_vertices) {
            return Err(ParamsError::MaxVertices { got: max_vertices as u64, max: MAX_VERTICES as u64 });
        }
        if let Some(t) = tolerance.filter(|t| !(t.is_finite() && *t >= 0.0)) {
            return Err(ParamsError::Tolerance(t));
        }
        if let Some(degrees) = min_angle {
            if criterion != Criterion::Error {
                return Err(ParamsError::MinAngleCriterion);
            }
            if !(degrees > 0.0 && degrees <= MAX_MIN_ANGLE) {
                return Err(ParamsError::MinAngle(degrees));
            }
        }
        if method == Method::DataDependent && !(on_grid && criterion == Criterion::Error) {
            return Err(ParamsError::DataDependentSource);
        }
        for (name, size) in [("min_size", min_size), ("max_size", max_size)] {
            let Some(got) = size else { continue };
            if criterion != Criterion::Curvature {
                return Err(ParamsError::SizeCriterion(name));
            }
            if !(got.is_finite() && got > 0.0) {
                return Err(ParamsError::Size { name, got });
            }
        }
        if let (Some(min), Some(max)) = (min_size, max_size)
            && max < 2.0 * min
        {
            return Err(ParamsError::SizeOrder { min, max });
        }
        Ok(Params { method, criterion, max_vertices, tolerance, time_limit, min_angle, min_size, max_size })
    }
}

/// Parses the kebab-case names used on the command line and in the API.
macro_rules! names {
    ($ty:ty, $what:literal, $($name:literal => $variant:path),+) => {
        impl FromStr for $ty {
            type Err = String;
            fn from_str(s: &str) -> Result<Self, String> {
                match s {
                    $($name => Ok($variant),)+
                    _ => Err(format!(concat!("unknown ", $what, " `{}`; expected one of: {}"), s, [$($name),+].join(", "))),
                }
            }
        }
        impl fmt::Display for $ty {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                let name = match self { $($variant => $name,)+ };
                f.write_str(name)
            }
        }
    };
}

names!(
    Method,
    "method",
    "recursive" => Method::Recursive,
    "semi-recursive" => Method::SemiRecursive,
    "data-dependent" => Method::DataDependent
);
names!(
    Criterion,
    "criterion",
    "variation" => Criterion::Variation,
    "error" => Criterion::Error,
    "curvature" => Criterion::Curvature
);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn out_of_range_parameters_are_refused() {
        assert_eq!(Params::new(3), Err(ParamsError::MaxVertices { got: 3, max: MAX_VERTICES as u64 }));
        assert!(Params::new(4).is_ok());
        assert!(Params::new(MAX_VERTICES + 1).is_err());
        let p = Params::builder(10);
        assert_eq!(p.clone().tolerance(-1.0).build(), Err(ParamsError::Tolerance(-1.0)));
        assert!(p.clone().tolerance(f64::NAN).build().is_err());
        assert_eq!(p.clone().tolerance(0.0).build().unwrap().tolerance(), Some(0.0));
        for bad in [0.0, -1.0, 30.5, f64::NAN, f64::INFINITY] {
            assert!(matches!(p.clone().min_angle(bad).build(), Err(ParamsError::MinAngle(_))), "{bad}");
        }
        assert_eq!(p.clone().min_angle(30.0).build().unwrap().min_angle(), Some(30.0));
    }

    #[test]
    fn parameters_that_do_not_fit_together_are_refused_whatever_the_order_they_were_set_in() {
        let p = Params::builder(10);
        // min_angle repairs triangles, which the paper's variation does not rank.
        let paper = p.clone().min_angle(20.0).criterion(Criterion::Variation);
        assert_eq!(paper.build(), Err(ParamsError::MinAngleCriterion));
        assert_eq!(
            p.clone().criterion(Criterion::Variation).min_angle(99.0).build(),
            Err(ParamsError::MinAngleCriterion),
            "the combination is named before the range"
        );
        let dd = p.clone().method(Method::DataDependent);
        assert_eq!(dd.clone().on_grid(true).build().map(|p| p.method()), Ok(Method::DataDependent));
        assert_eq!(dd.clone().build(), Err(ParamsError::DataDependentSource));
        let variation = dd.on_grid(true).criterion(Criterion::Variation);
        assert_eq!(variation.clone().build(), Err(ParamsError::DataDependentSource));
        assert!(variation.method(Method::SemiRecursive).on_grid(false).build().is_ok());
        let sizes = p.clone().min_size(0.1).max_size(0.15);
        assert_eq!(sizes.clone().build(), Err(ParamsError::SizeCriterion("min_size")));
        let curvature = sizes.criterion(Criterion::Curvature);
        assert_eq!(curvature.clone().build(), Err(ParamsError::SizeOrder { min: 0.1, max: 0.15 }));
        assert_eq!(curvature.clone().max_size(0.2).build().map(|p| p.max_size()), Ok(Some(0.2)));
        assert_eq!(curvature.max_size(-1.0).build(), Err(ParamsError::Size { name: "max_size", got: -1.0 }));
    }

    #[test]
    fn names_round_trip_and_unknown_names_list_the_choices() {
        for m in [Method::Recursive, Method::SemiRecursive, Method::DataDependent] {
            assert_eq!(m.to_string().parse::<Method>(), Ok(m));
        }
        let err = "semi".parse::<Method>().unwrap_err();
        assert_eq!(err, "unknown method `semi`; expected one of: recursive, semi-recursive, data-dependent");
    }
}
