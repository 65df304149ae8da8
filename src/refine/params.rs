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
}

/// The largest vertex budget the engine accepts: vertex and half-edge ids are `u32`, and a
/// mesh of n vertices has up to 6n half-edges.
pub const MAX_VERTICES: usize = 400_000_000;

/// Refinement parameters, validated by [`Params::new`] and the `with_*` setters.
///
/// ```
/// use meshfit::refine::{Method, Params};
/// let params = Params::new(10_000).unwrap().with_method(Method::Recursive).with_tolerance(1e-3).unwrap();
/// assert_eq!(params.max_vertices(), 10_000);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    method: Method,
    criterion: Criterion,
    max_vertices: usize,
    tolerance: Option<f64>,
    time_limit: Option<Duration>,
    min_angle: Option<f64>,
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
    /// `min_angle` with the paper's criterion, which has no triangles to repair first.
    #[error("min_angle needs criterion error: the paper's variation splits only its worst edge")]
    MinAngleCriterion,
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
        if !(4..=MAX_VERTICES).contains(&max_vertices) {
            return Err(ParamsError::MaxVertices { got: max_vertices as u64, max: MAX_VERTICES as u64 });
        }
        Ok(Self {
            method: Method::default(),
            criterion: Criterion::default(),
            max_vertices,
            tolerance: None,
            time_limit: None,
            min_angle: None,
        })
    }

    /// Sets the method.
    pub fn with_method(mut self, method: Method) -> Self {
        self.method = method;
        self
    }

    /// Sets the criterion.
    pub fn with_criterion(mut self, criterion: Criterion) -> Self {
        self.criterion = criterion;
        self
    }

    /// Stops once the worst criterion value (the largest e(T) for `error`, the largest
    /// |zᵢ − zⱼ| for `variation`) is at most `tolerance`.
    ///
    /// # Errors
    /// When `tolerance` is negative, NaN or infinite.
    pub fn with_tolerance(mut self, tolerance: f64) -> Result<Self, ParamsError> {
        if !(tolerance.is_finite() && tolerance >= 0.0) {
            return Err(ParamsError::Tolerance(tolerance));
        }
        self.tolerance = Some(tolerance);
        Ok(self)
    }

    /// With criterion `error`, repairs every triangle whose smallest angle is below `degrees`
    /// before any error-driven split (see the refinement's docs).
    ///
    /// # Errors
    /// When `degrees` is not above 0 and at most [`MAX_MIN_ANGLE`].
    pub fn with_min_angle(mut self, degrees: f64) -> Result<Self, ParamsError> {
        if !(degrees > 0.0 && degrees <= MAX_MIN_ANGLE) {
            return Err(ParamsError::MinAngle(degrees));
        }
        self.min_angle = Some(degrees);
        Ok(self)
    }

    /// Checks the method against the source: `data-dependent` needs a grid (`grid` true) and
    /// criterion `error`. (Elsewhere [`refine`](super::refine) would run it as `semi-recursive`.)
    ///
    /// # Errors
    /// [`ParamsError::DataDependentSource`] when it does not fit.
    pub fn check_source(&self, grid: bool) -> Result<(), ParamsError> {
        let fits = self.method != Method::DataDependent || (grid && self.criterion == Criterion::Error);
        if fits { Ok(()) } else { Err(ParamsError::DataDependentSource) }
    }

    /// Stops once this much time has passed.
    pub fn with_time_limit(mut self, limit: Duration) -> Self {
        self.time_limit = Some(limit);
        self
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
names!(Criterion, "criterion", "variation" => Criterion::Variation, "error" => Criterion::Error);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn out_of_range_parameters_are_refused() {
        assert_eq!(Params::new(3), Err(ParamsError::MaxVertices { got: 3, max: MAX_VERTICES as u64 }));
        assert!(Params::new(4).is_ok());
        assert!(Params::new(MAX_VERTICES + 1).is_err());
        let p = Params::new(10).unwrap();
        assert!(p.clone().with_tolerance(-1.0).is_err());
        assert!(p.clone().with_tolerance(f64::NAN).is_err());
        assert_eq!(p.clone().with_tolerance(0.0).unwrap().tolerance(), Some(0.0));
        for bad in [0.0, -1.0, 30.5, f64::NAN, f64::INFINITY] {
            assert!(matches!(p.clone().with_min_angle(bad), Err(ParamsError::MinAngle(_))), "{bad}");
        }
        assert_eq!(p.clone().with_min_angle(30.0).unwrap().min_angle(), Some(30.0));
        let dd = p.with_method(Method::DataDependent);
        assert_eq!(dd.check_source(true), Ok(()));
        assert_eq!(dd.check_source(false), Err(ParamsError::DataDependentSource));
        let variation = dd.with_criterion(Criterion::Variation);
        assert_eq!(variation.check_source(true), Err(ParamsError::DataDependentSource));
        assert_eq!(variation.with_method(Method::SemiRecursive).check_source(false), Ok(()));
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
