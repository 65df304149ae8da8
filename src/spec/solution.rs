//! SolveSpec: a boundary value problem request, validated and in canonical form.

use super::checks::{Limits, SpecError, budget, build, domain_of, expression};
use crate::api::{BoundaryInput, Coefficient, RegionInput, SolveRequest};
use crate::geom::{Point, Rect};
use crate::refine::Method;
use crate::solve::{
    Adapted, BhCurve, Boundary, Exact, Indicator, MU_0, Physics, Problem, Region, Settings, Shape,
    SolveError, SolveObserver, adapt,
};
use crate::source::Expression;
use std::sync::Arc;
use std::time::Duration;

/// A function of x and y as a problem's k, f, g or exact solution: a constant or a parsed
/// expression (the wire's [`crate::api::Coefficient`], checked).
#[derive(Debug, Clone)]
pub enum Function {
    /// The same value everywhere.
    Constant(f64),
    /// An expression in x and y.
    Expression(Expression),
}

impl Function {
    fn eval(&self, x: f64, y: f64) -> f64 {
        match self {
            Function::Constant(c) => *c,
            Function::Expression(e) => e.eval_xy(x, y),
        }
    }
}

/// A validated boundary value problem. Regions hold k and f already, whatever the physics.
#[derive(Debug, Clone)]
pub struct SolveSpec {
    /// What u means.
    pub physics: Physics,
    /// The rectangle.
    pub domain: Rect,
    /// k outside the regions.
    pub k: Function,
    /// f outside the regions.
    pub f: Function,
    /// u on the Dirichlet sides.
    pub g: Function,
    /// Each side's condition.
    pub boundary: Boundary,
    /// The regions, in the order they apply.
    pub regions: Vec<Region>,
    /// The B–H table of each region that has one, by region: what the cache key hashes.
    pub tables: Vec<Option<BhTable>>,
    /// The exact solution, if given.
    pub exact: Option<Function>,
    /// The loop's stop rules and method, the time limit already capped.
    pub settings: Settings,
}

/// The growth a request gets when it names none.
pub const DEFAULT_GROWTH: f64 = 1.5;

/// The largest growth: beyond it a round refines blindly far past what the last solve saw.
pub const MAX_GROWTH: f64 = 4.0;

fn invalid(field: impl Into<String>, detail: impl Into<String>) -> SpecError {
    SpecError::Problem { field: field.into(), detail: detail.into() }
}

/// A coefficient from the request, its expression parsed and its constant checked.
fn coefficient(
    field: &'static str,
    input: Option<Coefficient>,
    default: f64,
    limits: &Limits,
) -> Result<Function, SpecError> {
    match input {
        None => Ok(Function::Constant(default)),
        Some(Coefficient::Number(v)) if v.is_finite() => Ok(Function::Constant(v + 0.0)),
        Some(Coefficient::Number(v)) => Err(invalid(field, format!("must be finite, got {v}"))),
        Some(Coefficient::Expression(text)) => expression(&text, field, limits).map(Function::Expression),
    }
}

/// A positive, finite value of field `field`.
fn positive(field: &str, v: f64) -> Result<f64, SpecError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(invalid(field, format!("must be finite and > 0, got {v}")))
    }
}

/// A finite value of field `field`.
fn finite(field: &str, v: f64) -> Result<f64, SpecError> {
    if v.is_finite() { Ok(v + 0.0) } else { Err(invalid(field, format!("must be finite, got {v}"))) }
}

/// A B–H table as the request gave it: [H, B] pairs.
pub type BhTable = Vec<[f64; 2]>;

/// The most regions a problem may have: every quadrature point looks through them.
pub const MAX_REGIONS: usize = 100;

/// The most corners all regions may have together (a rectangle has 4): the first mesh holds
/// them all, and every region side is a constraint.
pub const MAX_CORNERS: usize = 10_000;

/// Region `i`'s shape, a rectangle or a simple polygon, as a region inside `domain`: the
/// checks are the domain types' own, with their errors named by the request's fields.
fn shaped(i: usize, r: &RegionInput, domain: Rect) -> Result<Region, SpecError> {
    let here = format!("regions[{i}]");
    let shape = match (&r.x, &r.y, &r.polygon) {
        (Some(x), Some(y), None) => {
            let (x, y) = match (x.as_slice(), y.as_slice()) {
                (&[x0, x1], &[y0, y1]) => ([x0, x1], [y0, y1]),
                _ => return Err(invalid(here, "x and y must each be [low, high]")),
            };
            let rect = Rect::new(x[0] + 0.0, x[1] + 0.0, y[0] + 0.0, y[1] + 0.0)
                .map_err(|e| invalid(&here, e.to_string()))?;
            Shape::Rect(rect)
        }
        (None, None, Some(points)) => {
            let corners = points.iter().map(|&[x, y]| Point::new(x, y)).collect();
            Shape::polygon(corners, domain).map_err(|e| match e.corner() {
                Some(k) => invalid(format!("{here}.polygon[{k}]"), e.to_string()),
                None => invalid(format!("{here}.polygon"), e.to_string()),
            })?
        }
        _ => {
            return Err(invalid(
                here,
                "a region is a rectangle (x and y) or a polygon (polygon), not both or neither",
            ));
        }
    };
    Region::try_new(shape, domain).map_err(|e| invalid(here, e.to_string()))
}

/// Region `i`, inside `domain`, with k and f for `physics`, and its B–H table if it has one.
fn region(
    i: usize,
    r: RegionInput,
    domain: Rect,
    physics: Physics,
) -> Result<(Region, Option<BhTable>), SpecError> {
    let at = |name: &str| format!("regions[{i}].{name}");
    let mut region = shaped(i, &r, domain)?;
    let mut table = None;
    // Whether the region sets any of the magnetostatic fields.
    let magnetic = [r.mu_r, r.current_density, r.current].iter().any(Option::is_some)
        || r.bh.is_some()
        || r.magnetization.is_some();
    match physics {
        Physics::Poisson => {
            if magnetic {
                return Err(invalid(
                    format!("regions[{i}]"),
                    "mu_r, bh, magnetization, current_density and current are for physics magnetostatic; use k and f",
                ));
            }
            region.k = r.k.map(|k| positive(&at("k"), k)).transpose()?;
            region.f = r.f.map(|f| finite(&at("f"), f)).transpose()?;
            if region.k.is_none() && region.f.is_none() {
                return Err(invalid(format!("regions[{i}]"), "a region must set at least one value"));
            }
        }
        Physics::Magnetostatic => {
            if r.k.is_some() || r.f.is_some() {
                return Err(invalid(
                    format!("regions[{i}]"),
                    "k and f are for physics poisson; use mu_r or bh, and current_density or current",
                ));
            }
            if !magnetic {
                return Err(invalid(
                    format!("regions[{i}]"),
                    "a region must set at least one of mu_r, bh, magnetization, current_density and current",
                ));
            }
            if r.mu_r.is_some() && r.bh.is_some() {
                return Err(invalid(at("bh"), "give mu_r or bh, not both"));
            }
            if r.bh.is_some() && r.magnetization.is_some() {
                return Err(invalid(
                    at("magnetization"),
                    "a magnet takes mu_r (its recoil permeability), not bh",
                ));
            }
            if r.current_density.is_some() && r.current.is_some() {
                return Err(invalid(at("current"), "give current_density or current, not both"));
            }
            // Where regions overlap the later one's whole material wins: air (μr = 1) and no
            // current are set explicitly, never inherited.
            let mu_r = r.mu_r.map(|m| positive(&at("mu_r"), m)).transpose()?.unwrap_or(1.0);
            match r.bh {
                Some(points) => {
                    let curve = BhCurve::new(&points).map_err(|e| match e.index() {
                        Some(k) => invalid(format!("regions[{i}].bh[{k}]"), e.to_string()),
                        None => invalid(at("bh"), e.to_string()),
                    })?;
                    region.curve = Some(Arc::new(curve));
                    table = Some(points);
                }
                None => region.k = Some(1.0 / (MU_0 * mu_r)),
            }
            if let Some([mx, my]) = r.magnetization {
                // M/μr must stay finite too: μr = 1e-10 under M = 1e300 would not.
                let sx = finite(&at("magnetization[0]"), mx / mu_r)?;
                let sy = finite(&at("magnetization[1]"), my / mu_r)?;
                region.source = Some([sx, sy]);
            } else {
                region.source = Some([0.0; 2]);
            }
            let density = match (r.current_density, r.current) {
                (Some(j), _) => finite(&at("current_density"), j)?,
                (None, Some(i)) => finite(&at("current"), i)? / region.shape.area(),
                (None, None) => 0.0,
            };
            region.f = Some(density);
        }
    }
    Ok((region, table))
}

/// Each side's condition; at least one must be Dirichlet, or u is fixed only up to a constant.
fn boundary(input: Option<BoundaryInput>) -> Result<Boundary, SpecError> {
    let input = input.unwrap_or_default();
    let boundary = Boundary {
        left: input.left.unwrap_or_default(),
        right: input.right.unwrap_or_default(),
        bottom: input.bottom.unwrap_or_default(),
        top: input.top.unwrap_or_default(),
    };
    for (a, b, pair) in
        [(boundary.left, boundary.right, "left and right"), (boundary.bottom, boundary.top, "bottom and top")]
    {
        if (a.sign().is_some() || b.sign().is_some()) && a != b {
            return Err(invalid(
                "boundary",
                format!("{pair} are a pair: periodic and antiperiodic sides must say the same on both"),
            ));
        }
    }
    if !boundary.has_dirichlet() {
        return Err(invalid(
            "boundary",
            "at least one side must be dirichlet: with every side neumann, u is fixed only up to a constant",
        ));
    }
    Ok(boundary)
}

/// How a problem's adaptive loop runs, as a request or a kept spec names it, defaults
/// filled in.
pub(super) struct Steering {
    pub(super) max_vertices: Option<u64>,
    pub(super) tolerance: Option<f64>,
    pub(super) method: Method,
    pub(super) indicator: Indicator,
    pub(super) growth: f64,
    pub(super) requested_time_limit: Option<Duration>,
}

impl Steering {
    /// The loop's settings, checked as a mesh's budget and tolerance are, against `limits`.
    pub(super) fn settings(self, limits: &Limits) -> Result<Settings, SpecError> {
        let mut params = budget(self.max_vertices, limits)?;
        if let Some(t) = self.tolerance {
            params = params.tolerance(t + 0.0);
        }
        let params = build(params, limits)?;
        if self.method == Method::DataDependent {
            let detail = "data-dependent is for meshes of a grid; use semi-recursive or recursive";
            return Err(invalid("method", detail));
        }
        let growth = self.growth;
        if !(growth > 1.0 && growth <= MAX_GROWTH) {
            return Err(invalid("growth", format!("must be in (1, {MAX_GROWTH}], got {growth}")));
        }
        Ok(Settings {
            max_vertices: params.max_vertices(),
            tolerance: params.tolerance(),
            method: self.method,
            indicator: self.indicator,
            growth,
            time_limit: Some(
                self.requested_time_limit.map_or(limits.job_time_limit, |t| t.min(limits.job_time_limit)),
            ),
        })
    }
}

impl SolveSpec {
    /// Validates `request`: fills in defaults, checks limits, parses the expressions.
    ///
    /// # Errors
    /// The first problem found, in field order, naming the field.
    pub fn from_request(
        request: SolveRequest,
        limits: &Limits,
    ) -> Result<(Self, Option<Duration>), SpecError> {
        // Without a source or boundary values the answer is u = 0 (A = 0), whatever the mesh:
        // a request that forgot them is told so rather than answered.
        let sourced = request.f.is_some()
            || request.g.is_some()
            || request.regions.iter().any(|r| {
                r.f.is_some()
                    || r.magnetization.is_some()
                    || r.current_density.is_some()
                    || r.current.is_some()
            });
        let physics = request.physics.unwrap_or_default();
        let domain = match request.domain {
            None => Rect::unit(),
            Some(d) => domain_of(&d)?,
        };
        let (k, f) = match physics {
            Physics::Poisson => {
                (coefficient("k", request.k, 1.0, limits)?, coefficient("f", request.f, 0.0, limits)?)
            }
            Physics::Magnetostatic => {
                for (field, given) in [("k", request.k.is_some()), ("f", request.f.is_some())] {
                    if given {
                        return Err(invalid(
                            field,
                            "not allowed with physics magnetostatic: regions give mu_r and current_density",
                        ));
                    }
                }
                (Function::Constant(1.0 / MU_0), Function::Constant(0.0))
            }
        };
        if let Function::Constant(k) = k {
            positive("k", k)?;
        }
        let g = coefficient("g", request.g, 0.0, limits)?;
        let exact = match request.exact {
            None => None,
            Some(e) => Some(coefficient("exact", Some(e), 0.0, limits)?),
        };
        let boundary = boundary(request.boundary)?;
        if request.regions.len() > MAX_REGIONS {
            return Err(invalid(
                "regions",
                format!("{} regions, more than {MAX_REGIONS}", request.regions.len()),
            ));
        }
        let corners: usize = request.regions.iter().map(|r| r.polygon.as_ref().map_or(4, Vec::len)).sum();
        if corners > MAX_CORNERS {
            return Err(invalid("regions", format!("{corners} corners in all, more than {MAX_CORNERS}")));
        }
        let (regions, tables) = (request.regions.into_iter().enumerate())
            .map(|(i, r)| region(i, r, domain, physics))
            .collect::<Result<(Vec<_>, Vec<_>), _>>()?;
        let requested_time_limit = super::checks::time_limit(request.time_limit_ms)?;
        let steering = Steering {
            max_vertices: request.max_vertices,
            tolerance: request.tolerance,
            method: request.method.unwrap_or_default(),
            indicator: request.criterion.unwrap_or_default(),
            growth: request.growth.unwrap_or(DEFAULT_GROWTH),
            requested_time_limit,
        };
        let settings = steering.settings(limits)?;
        // Last, so that a more particular error is named first.
        if !sourced {
            let (field, what) = match physics {
                Physics::Poisson => ("f", "f (a source), g (boundary values) or a region's f"),
                Physics::Magnetostatic => {
                    ("regions", "a region with a current_density, a current or a magnetization")
                }
            };
            return Err(invalid(
                field,
                format!("nothing to solve: the solution is 0 everywhere without {what}"),
            ));
        }
        let spec = Self { physics, domain, k, f, g, boundary, regions, tables, exact, settings };
        Ok((spec, requested_time_limit))
    }

    /// The problem to solve, its fields reading this spec.
    pub fn problem(&self) -> Problem<'_> {
        let mut problem = Problem::new(self.domain)
            .with_k(|x, y| self.k.eval(x, y))
            .with_f(|x, y| self.f.eval(x, y))
            .with_g(|x, y| self.g.eval(x, y))
            .with_boundary(self.boundary);
        for region in &self.regions {
            problem = problem.with_region(region.clone());
        }
        problem
    }

    /// Runs the adaptive loop on this problem, measuring against `exact` when given; what
    /// the worker and `meshfit solve` both run.
    ///
    /// # Errors
    /// As [`adapt`].
    pub fn solve<O: SolveObserver>(&self, observer: &mut O) -> Result<Adapted, SolveError> {
        let exact = self.exact.as_ref().map(|e| move |x: f64, y: f64| e.eval(x, y));
        adapt(&self.problem(), exact.as_ref().map(|u| u as Exact<'_>), &self.settings, observer)
    }
}
