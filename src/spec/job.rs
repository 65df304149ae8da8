//! JobSpec: a request validated against the server's limits, in canonical form.

use super::checks::{Limits, SpecError, budget, build, domain_of, expression, grid_error, with_sizes};
use super::solution::SolveSpec;
use crate::api::{JobRequest, SolveRequest};
use crate::geom::Rect;
use crate::refine::{Criterion, Method, Params, Refinement, estimate_error};
use crate::source::{GridHints, Source, decode_grid, decode_values};
use std::sync::Arc;
use std::time::Duration;

/// A validated request: what to compute and how. Built only by the `from_*` constructors.
#[derive(Debug, Clone)]
pub struct JobSpec {
    /// A mesh or a solution.
    pub work: Work,
    /// The time limit the request named, if any. The id depends on this, never on the
    /// server's default: a result a time limit stopped is never cached, so every cached
    /// result is the same whatever limit was in force.
    pub requested_time_limit: Option<Duration>,
}

/// What a job computes.
#[derive(Debug, Clone)]
pub enum Work {
    /// A mesh of F.
    Mesh(MeshSpec),
    /// The solution of a boundary value problem on an adaptive mesh.
    Solve(Arc<SolveSpec>),
}

/// A mesh job: F, its rectangle and the engine's parameters.
#[derive(Debug, Clone)]
pub struct MeshSpec {
    /// F.
    pub source: Arc<Source>,
    /// The rectangle.
    pub domain: Rect,
    /// Method, criterion and stop rules, with the time limit already capped.
    pub params: Params,
    /// Whether the result's stats measure the final mesh against F ([`estimate_error`]).
    ///
    /// [`estimate_error`]: crate::refine::estimate_error
    pub quality: bool,
}

impl MeshSpec {
    /// Measures a finished run of this spec against F when the request asked for it.
    pub fn measure(&self, run: &mut Refinement) {
        if self.quality {
            run.stats.quality = Some(estimate_error(&run.mesh, &*self.source));
        }
    }
}

impl JobSpec {
    /// Validates a boundary value problem; see [`SolveSpec::from_request`].
    ///
    /// # Errors
    /// The first problem found, naming its field.
    pub fn from_solve_request(request: SolveRequest, limits: &Limits) -> Result<Self, SpecError> {
        let (spec, requested_time_limit) = SolveSpec::from_request(request, limits)?;
        Ok(Self { work: Work::Solve(Arc::new(spec)), requested_time_limit })
    }

    /// The mesh part, for a mesh job.
    pub fn mesh(&self) -> Option<&MeshSpec> {
        match &self.work {
            Work::Mesh(m) => Some(m),
            Work::Solve(_) => None,
        }
    }

    /// Validates `request`: fills in defaults, checks limits, parses the expression.
    ///
    /// # Errors
    /// The first problem found, in field order: source, limits, expression or grid, domain,
    /// parameters.
    pub fn from_request(request: JobRequest<'_>, limits: &Limits) -> Result<Self, SpecError> {
        Self::build(request, None, limits)
    }

    /// Validates `request` whose grid comes as a file (.npy, PNG, TIFF/GeoTIFF, raw): the
    /// request's `grid` may name only `nx`, `ny` and `dtype` for raw samples and the
    /// `encoding` of a colour PNG tile. The domain
    /// defaults to a GeoTIFF's, else to the grid's index range. The same values give the same
    /// job whichever format carried them.
    ///
    /// # Errors
    /// As [`JobSpec::from_request`], and when the file does not decode (the error names the
    /// (i, j) of a bad sample) or declares more points than the limit.
    pub fn from_upload(request: JobRequest<'_>, file: &[u8], limits: &Limits) -> Result<Self, SpecError> {
        Self::build(request, Some(file), limits)
    }

    fn build(request: JobRequest<'_>, file: Option<&[u8]>, limits: &Limits) -> Result<Self, SpecError> {
        let mut file_domain = None;
        let source = match (request.function, request.grid, file) {
            (Some(_), _, Some(_)) => return Err(SpecError::Source(", not a function and a grid file")),
            (None, grid, Some(file)) => {
                let grid = grid.unwrap_or_default();
                if grid.values.is_some() {
                    let detail = "values come from the grid file; the request's grid may give only nx, ny, dtype and encoding";
                    return Err(SpecError::Grid { detail: detail.into(), index: None });
                }
                let hints = GridHints {
                    nx: grid.nx.map(|n| n.try_into().unwrap_or(usize::MAX)),
                    ny: grid.ny.map(|n| n.try_into().unwrap_or(usize::MAX)),
                    dtype: grid.dtype,
                    encoding: grid.encoding,
                };
                let decoded = decode_grid(file, &hints, limits.max_grid_points).map_err(grid_error)?;
                file_domain = decoded.domain;
                Source::Grid(decoded.grid)
            }
            (None, None, None) => return Err(SpecError::Source(", none given")),
            (Some(_), Some(_), None) => return Err(SpecError::Source(", not both")),
            (Some(text), None, None) => Source::Expression(expression(&text, "function", limits)?),
            (None, Some(grid), None) => {
                let (Some(nx), Some(ny), Some(values)) = (grid.nx, grid.ny, grid.values) else {
                    let detail = "a grid needs nx, ny and values (or send it as a file, multipart)";
                    return Err(SpecError::Grid { detail: detail.into(), index: None });
                };
                if grid.dtype.is_some() || grid.encoding.is_some() {
                    let detail = match grid.dtype {
                        Some(_) => "dtype is for raw grid files; JSON values are numbers",
                        None => "encoding is for colour PNG tiles sent as a file; JSON values are heights",
                    };
                    return Err(SpecError::Grid { detail: detail.into(), index: None });
                }
                // One decoder for every grid, with the limit passed in: nx·ny is checked before
                // the values are parsed, and a bad element is named by its (i, j).
                let grid = decode_values(values.get(), nx, ny, limits.max_grid_points).map_err(grid_error)?;
                Source::Grid(grid)
            }
        };
        let domain = match request.domain {
            None => file_domain.unwrap_or_else(|| source.default_domain()),
            Some(d) => domain_of(&d)?,
        };
        let knobs = Knobs {
            max_vertices: request.max_vertices,
            method: request.method.unwrap_or_default(),
            criterion: request.criterion.unwrap_or_default(),
            tolerance: request.tolerance,
            min_angle: request.min_angle,
            sizes: [request.min_size, request.max_size],
            quality: request.quality.unwrap_or(false),
            requested_time_limit: super::checks::time_limit(request.time_limit_ms)?,
        };
        Self::mesh_from(source.with_domain(domain), domain, knobs, limits)
    }

    /// A mesh job of `source` on `domain`, its knobs checked against `limits`: the one
    /// mapping to the engine's parameters, for a request and for a kept spec alike.
    pub(super) fn mesh_from(
        source: Source,
        domain: Rect,
        knobs: Knobs,
        limits: &Limits,
    ) -> Result<Self, SpecError> {
        let Knobs {
            max_vertices,
            method,
            criterion,
            tolerance,
            min_angle,
            sizes,
            quality,
            requested_time_limit,
        } = knobs;
        let time_limit = requested_time_limit.map_or(limits.job_time_limit, |t| t.min(limits.job_time_limit));
        let mut params = budget(max_vertices, limits)?
            .method(method)
            .criterion(criterion)
            .time_limit(time_limit)
            .on_grid(matches!(source, Source::Grid(_)));
        // + 0.0: -0.0 is 0.0, one value and one cache key.
        if let Some(t) = tolerance {
            params = params.tolerance(t + 0.0);
        }
        if let Some(degrees) = min_angle {
            params = params.min_angle(degrees + 0.0);
        }
        let params = build(with_sizes(params, sizes), limits)?;
        let mesh = MeshSpec { source: Arc::new(source), domain, params, quality };
        Ok(Self { work: Work::Mesh(mesh), requested_time_limit })
    }
}

/// A mesh request's settings past F and its rectangle, defaults filled in.
pub(super) struct Knobs {
    pub(super) max_vertices: Option<u64>,
    pub(super) method: Method,
    pub(super) criterion: Criterion,
    pub(super) tolerance: Option<f64>,
    pub(super) min_angle: Option<f64>,
    /// `min_size` and `max_size`.
    pub(super) sizes: [Option<f64>; 2],
    pub(super) quality: bool,
    pub(super) requested_time_limit: Option<Duration>,
}
