//! What every request is checked against: the server's [`Limits`], and [`SpecError`], which
//! says which field of a request is wrong. Shared by mesh and solution specs.

use crate::api::DomainInput;
use crate::geom::Rect;
use crate::refine::{MAX_VERTICES, Params, ParamsBuilder, ParamsError};
use crate::source::{ExprError, Expression, GridFileError};
use std::time::Duration;

/// The limits a request is checked against (from the server's config).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    /// Largest `max_vertices`.
    pub max_vertices: usize,
    /// Largest nx·ny.
    pub max_grid_points: usize,
    /// Longest expression, in characters.
    pub max_expression_len: usize,
    /// Longest run; also the default time limit.
    pub job_time_limit: Duration,
}

impl Limits {
    /// No limits but the engine's own: what the command line checks a request against.
    pub const NONE: Limits = Limits {
        max_vertices: MAX_VERTICES,
        max_grid_points: usize::MAX,
        max_expression_len: usize::MAX,
        job_time_limit: Duration::MAX,
    };
}

/// The budget a request gets when it names none.
pub const DEFAULT_MAX_VERTICES: u64 = 10_000;

/// Why a request is not a valid job. Each variant says where the problem is.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SpecError {
    /// Neither or both of `function` and `grid`.
    #[error("give exactly one of `function` and `grid`{0}")]
    Source(&'static str),
    /// The expression does not parse.
    #[error("function: {0}")]
    Expression(ExprError),
    /// The grid is malformed; `index` is its (i, j) when one value is at fault.
    #[error("grid: {detail}")]
    Grid {
        /// What is wrong.
        detail: String,
        /// [i, j] of the bad value.
        index: Option<[usize; 2]>,
    },
    /// The domain is empty, reversed or not finite.
    #[error("domain: {0}")]
    Domain(String),
    /// An expression of a boundary value problem does not parse.
    #[error("{field}: {error}")]
    Coefficient {
        /// The request field: `k`, `f`, `g` or `exact`.
        field: &'static str,
        /// What is wrong, and where.
        error: ExprError,
    },
    /// A field of a boundary value problem is out of its range or not allowed.
    #[error("{field}: {detail}")]
    Problem {
        /// The request field, e.g. `regions[1].mu_r`.
        field: String,
        /// What is wrong.
        detail: String,
    },
    /// A field of another request (a client job's, a time limit) is out of its range or not
    /// allowed.
    #[error("{field}: {detail}")]
    Field {
        /// The request field, e.g. `batch`.
        field: String,
        /// What is wrong.
        detail: String,
    },
    /// A parameter out of its range.
    #[error("{0}")]
    Parameter(ParamsError),
    /// A server limit is exceeded.
    #[error("{name}{measure} is {value}, above this server's limit of {limit}")]
    Limit {
        /// The request field.
        name: &'static str,
        /// What of it is measured, as a suffix of the name (" length"); empty for a number.
        measure: &'static str,
        /// The configuration variable that sets the limit.
        setting: &'static str,
        /// The limit.
        limit: u64,
        /// What the request asked for.
        value: u64,
    },
}

/// `Err(SpecError::Limit)` when `value`, the `measure` of field `name`, is above `limit`.
pub(super) fn at_most(
    (name, measure): (&'static str, &'static str),
    setting: &'static str,
    limit: usize,
    value: u64,
) -> Result<(), SpecError> {
    if value > limit as u64 {
        return Err(SpecError::Limit { name, measure, setting, limit: limit as u64, value });
    }
    Ok(())
}

/// `text` parsed as the expression of field `field`, held to the length limit.
pub(super) fn expression(text: &str, field: &'static str, limits: &Limits) -> Result<Expression, SpecError> {
    let len = text.chars().count() as u64;
    at_most((field, " length"), "MESHFIT_MAX_EXPRESSION_LEN", limits.max_expression_len, len)?;
    Expression::parse(text).map_err(|error| match field {
        "function" => SpecError::Expression(error),
        field => SpecError::Coefficient { field, error },
    })
}

impl SpecError {
    /// The request field at fault as messages spell it (`regions[1].mu_r`); none when no one
    /// field is (neither `function` nor `grid` given, say).
    pub fn field(&self) -> Option<&str> {
        Some(match self {
            SpecError::Source(_) => return None,
            SpecError::Expression(_) => "function",
            SpecError::Grid { .. } => "grid",
            SpecError::Domain(_) => "domain",
            SpecError::Coefficient { field, .. } => field,
            SpecError::Problem { field, .. } | SpecError::Field { field, .. } => field,
            SpecError::Parameter(e) => match e {
                ParamsError::MaxVertices { .. } => "max_vertices",
                ParamsError::Tolerance(_) => "tolerance",
                ParamsError::MinAngle(_) | ParamsError::MinAngleCriterion => "min_angle",
                ParamsError::DataDependentSource => "method",
                ParamsError::Size { name, .. } | ParamsError::SizeCriterion(name) => name,
                ParamsError::SizeOrder { .. } => "max_size",
            },
            SpecError::Limit { name, .. } => name,
        })
    }
}

/// A request's time limit: none means the server's; zero would stop a job before its first
/// step, so it is refused rather than answered with the starting mesh.
pub(super) fn time_limit(ms: Option<u64>) -> Result<Option<std::time::Duration>, SpecError> {
    match ms {
        Some(0) => Err(SpecError::Field {
            field: "time_limit_ms".into(),
            detail: "must be at least 1; leave it out for the server's limit".into(),
        }),
        ms => Ok(ms.map(std::time::Duration::from_millis)),
    }
}

/// The engine's parameters for a request's vertex budget (the default when it names none),
/// checked against this server's limit rather than the engine's.
pub(super) fn budget(max_vertices: Option<u64>, limits: &Limits) -> Result<ParamsBuilder, SpecError> {
    let max_vertices = max_vertices.unwrap_or(DEFAULT_MAX_VERTICES);
    at_most(("max_vertices", ""), "MESHFIT_MAX_VERTICES", limits.max_vertices, max_vertices)?;
    Ok(Params::builder(max_vertices as usize))
}

/// `params` with a request's `[min_size, max_size]`, -0.0 taken as 0.0 (one value, one cache
/// key); the engine's checks come at [`build`].
pub(super) fn with_sizes(mut params: ParamsBuilder, [min, max]: [Option<f64>; 2]) -> ParamsBuilder {
    if let Some(length) = min {
        params = params.min_size(length + 0.0);
    }
    if let Some(length) = max {
        params = params.max_size(length + 0.0);
    }
    params
}

/// The engine's checks of `params`, with a budget below 4 told against this server's limit
/// rather than the engine's.
pub(super) fn build(params: ParamsBuilder, limits: &Limits) -> Result<Params, SpecError> {
    params.build().map_err(|e| match e {
        ParamsError::MaxVertices { got, .. } => {
            SpecError::Parameter(ParamsError::MaxVertices { got, max: limits.max_vertices as u64 })
        }
        e => SpecError::Parameter(e),
    })
}

/// A grid that does not decode: over the limit, or malformed (naming the value at fault).
pub fn grid_error(e: GridFileError) -> SpecError {
    match e {
        GridFileError::TooManyPoints { requested, allowed, .. } => SpecError::Limit {
            name: "grid",
            measure: " nx*ny",
            setting: "MESHFIT_MAX_GRID_POINTS",
            limit: allowed as u64,
            value: requested,
        },
        e => SpecError::Grid { index: e.index(), detail: e.to_string() },
    }
}

/// The two bounds of one axis, with -0.0 made 0.0 (one value, one cache key).
fn pair(axis: &str, bounds: &[f64]) -> Result<[f64; 2], SpecError> {
    match bounds {
        &[lo, hi] => Ok([lo + 0.0, hi + 0.0]),
        _ => Err(SpecError::Domain(format!("{axis} must be [low, high], got {} numbers", bounds.len()))),
    }
}

/// The rectangle a request names.
pub(super) fn domain_of(d: &DomainInput) -> Result<Rect, SpecError> {
    let ([a, b], [c, e]) = (pair("x", &d.x)?, pair("y", &d.y)?);
    Rect::new(a, b, c, e).map_err(domain_error)
}

/// A rectangle the domain type refused.
pub(super) fn domain_error(e: crate::geom::RectError) -> SpecError {
    SpecError::Domain(e.to_string())
}
