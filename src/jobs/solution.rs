//! SolveSpec: a boundary value problem request, validated and in canonical form.

use super::spec::{Limits, SpecError, at_most, budget, domain_of};
use crate::api::{Coefficient, RegionInput, SolveRequest};
use crate::geom::Rect;
use crate::refine::Observer;
use crate::solve::{Adapted, Exact, MU_0, Physics, Problem, Region, Settings, SolveError, adapt};
use crate::source::Expression;
use std::time::Duration;

/// A coefficient: a constant or a parsed expression.
#[derive(Debug, Clone)]
pub enum Coef {
    /// The same value everywhere.
    Constant(f64),
    /// An expression in x and y.
    Expression(Expression),
}

impl Coef {
    fn eval(&self, x: f64, y: f64) -> f64 {
        match self {
            Coef::Constant(c) => *c,
            Coef::Expression(e) => e.eval_xy(x, y),
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
    pub k: Coef,
    /// f outside the regions.
    pub f: Coef,
    /// u on the boundary.
    pub g: Coef,
    /// The regions, in the order they apply.
    pub regions: Vec<Region>,
    /// The exact solution, if given.
    pub exact: Option<Coef>,
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
) -> Result<Coef, SpecError> {
    match input {
        None => Ok(Coef::Constant(default)),
        Some(Coefficient::Number(v)) if v.is_finite() => Ok(Coef::Constant(v + 0.0)),
        Some(Coefficient::Number(v)) => Err(invalid(field, format!("must be finite, got {v}"))),
        Some(Coefficient::Expression(text)) => {
            let len = text.chars().count() as u64;
            at_most((field, " length"), "MESHFIT_MAX_EXPRESSION_LEN", limits.max_expression_len, len)?;
            Expression::parse(&text)
                .map(Coef::Expression)
                .map_err(|error| SpecError::Coefficient { field, error })
        }
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

/// Region `i`, inside `domain`, with k and f for `physics`.
fn region(i: usize, r: RegionInput, domain: Rect, physics: Physics) -> Result<Region, SpecError> {
    let at = |name: &str| format!("regions[{i}].{name}");
    let (x, y) = match (r.x.as_slice(), r.y.as_slice()) {
        (&[x0, x1], &[y0, y1]) => ([x0, x1], [y0, y1]),
        _ => return Err(invalid(format!("regions[{i}]"), "x and y must each be [low, high]")),
    };
    let rect = Rect::new(x[0] + 0.0, x[1] + 0.0, y[0] + 0.0, y[1] + 0.0)
        .map_err(|e| invalid(format!("regions[{i}]"), e.to_string()))?;
    let inside = domain.x0() <= rect.x0()
        && rect.x1() <= domain.x1()
        && domain.y0() <= rect.y0()
        && rect.y1() <= domain.y1();
    if !inside {
        return Err(invalid(format!("regions[{i}]"), "the region must lie inside the domain"));
    }
    let (k, f) = match physics {
        Physics::Poisson => {
            if r.mu_r.is_some() || r.current_density.is_some() {
                return Err(invalid(
                    format!("regions[{i}]"),
                    "mu_r and current_density are for physics magnetostatic; use k and f",
                ));
            }
            (r.k.map(|k| positive(&at("k"), k)).transpose()?, r.f.map(|f| finite(&at("f"), f)).transpose()?)
        }
        Physics::Magnetostatic => {
            if r.k.is_some() || r.f.is_some() {
                return Err(invalid(
                    format!("regions[{i}]"),
                    "k and f are for physics poisson; use mu_r and current_density",
                ));
            }
            let mu_r = r.mu_r.map(|m| positive(&at("mu_r"), m)).transpose()?;
            (
                mu_r.map(|m| 1.0 / (MU_0 * m)),
                r.current_density.map(|j| finite(&at("current_density"), j)).transpose()?,
            )
        }
    };
    if k.is_none() && f.is_none() {
        return Err(invalid(format!("regions[{i}]"), "a region must set at least one value"));
    }
    Ok(Region { rect, k, f })
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
                (Coef::Constant(1.0 / MU_0), Coef::Constant(0.0))
            }
        };
        if let Coef::Constant(k) = k {
            positive("k", k)?;
        }
        let g = coefficient("g", request.g, 0.0, limits)?;
        let exact = match request.exact {
            None => None,
            Some(e) => Some(coefficient("exact", Some(e), 0.0, limits)?),
        };
        let regions = (request.regions.into_iter().enumerate())
            .map(|(i, r)| region(i, r, domain, physics))
            .collect::<Result<Vec<_>, _>>()?;
        // The checks of the budget and the tolerance, as for a mesh.
        let mut params = budget(request.max_vertices, limits)?;
        if let Some(t) = request.tolerance {
            params = params.with_tolerance(t + 0.0).map_err(SpecError::Parameter)?;
        }
        let growth = request.growth.unwrap_or(DEFAULT_GROWTH);
        if !(growth > 1.0 && growth <= MAX_GROWTH) {
            return Err(invalid("growth", format!("must be in (1, {MAX_GROWTH}], got {growth}")));
        }
        let requested_time_limit = request.time_limit_ms.map(Duration::from_millis);
        let settings = Settings {
            max_vertices: params.max_vertices(),
            tolerance: params.tolerance(),
            method: request.method.unwrap_or_default(),
            indicator: request.criterion.unwrap_or_default(),
            growth,
            time_limit: Some(
                requested_time_limit.map_or(limits.job_time_limit, |t| t.min(limits.job_time_limit)),
            ),
        };
        let spec = Self { physics, domain, k, f, g, regions, exact, settings };
        Ok((spec, requested_time_limit))
    }

    /// The problem to solve, its fields reading this spec.
    pub fn problem(&self) -> Problem<'_> {
        let mut problem = Problem::new(self.domain)
            .with_k(|x, y| self.k.eval(x, y))
            .with_f(|x, y| self.f.eval(x, y))
            .with_g(|x, y| self.g.eval(x, y));
        for &region in &self.regions {
            problem = problem.with_region(region);
        }
        problem
    }

    /// Runs the adaptive loop on this problem, measuring against `exact` when given; what
    /// the worker and `meshfit solve` both run.
    ///
    /// # Errors
    /// As [`adapt`].
    pub fn solve<O: Observer>(&self, observer: &mut O) -> Result<Adapted, SolveError> {
        let exact = self.exact.as_ref().map(|e| move |x: f64, y: f64| e.eval(x, y));
        adapt(&self.problem(), exact.as_ref().map(|u| u as Exact<'_>), &self.settings, observer)
    }
}
