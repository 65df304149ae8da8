//! The boundary value problem: the domain, the coefficient k, the load f, the boundary data g
//! and the constant-valued regions that override k and f.

use crate::geom::{Point, Rect};

/// A scalar field on the plane, evaluated at (x, y).
pub(crate) type Field<'a> = Box<dyn Fn(f64, f64) -> f64 + 'a>;

/// An axis-aligned rectangle (closed) in which k and/or f are constants.
///
/// Regions are applied in the order they were added, so where two overlap the later one wins,
/// field by field: a later region that sets only `f` keeps an earlier region's `k`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Region {
    /// Where the region applies, boundary included.
    pub rect: Rect,
    /// The coefficient inside, or `None` to keep the value from below.
    pub k: Option<f64>,
    /// The load inside, or `None` to keep the value from below.
    pub f: Option<f64>,
}

impl Region {
    /// Whether `p` lies in the closed rectangle.
    pub fn contains(&self, p: Point) -> bool {
        let r = &self.rect;
        r.x0() <= p.x && p.x <= r.x1() && r.y0() <= p.y && p.y <= r.y1()
    }
}

/// −∇·(k ∇u) = f in the rectangle D, u = g on ∂D.
///
/// Built with [`Problem::new`] (k = 1, f = 0, g = 0) and the `with_*` builders. The fields are
/// closures, so a caller's expression, grid or exact solution can be plugged in directly.
///
/// # Example
/// ```
/// use meshfit::geom::Rect;
/// use meshfit::solve::{Problem, Region};
///
/// let inclusion = Region { rect: Rect::new(0.25, 0.5, 0.25, 0.5).unwrap(), k: Some(10.0), f: None };
/// let problem = Problem::new(Rect::unit())
///     .with_f(|_, _| 1.0)
///     .with_g(|x, y| x * y)
///     .with_region(inclusion);
/// assert_eq!(problem.regions().len(), 1);
/// ```
pub struct Problem<'a> {
    domain: Rect,
    k: Field<'a>,
    f: Field<'a>,
    g: Field<'a>,
    regions: Vec<Region>,
}

impl<'a> Problem<'a> {
    /// The Laplace problem on `domain` with zero boundary values: k = 1, f = 0, g = 0.
    pub fn new(domain: Rect) -> Self {
        Self {
            domain,
            k: Box::new(|_, _| 1.0),
            f: Box::new(|_, _| 0.0),
            g: Box::new(|_, _| 0.0),
            regions: Vec::new(),
        }
    }

    /// Sets the coefficient k(x, y); it must be finite and positive at every quadrature point.
    pub fn with_k(mut self, k: impl Fn(f64, f64) -> f64 + 'a) -> Self {
        self.k = Box::new(k);
        self
    }

    /// Sets the load f(x, y).
    pub fn with_f(mut self, f: impl Fn(f64, f64) -> f64 + 'a) -> Self {
        self.f = Box::new(f);
        self
    }

    /// Sets the boundary values g(x, y), read at the boundary vertices only.
    pub fn with_g(mut self, g: impl Fn(f64, f64) -> f64 + 'a) -> Self {
        self.g = Box::new(g);
        self
    }

    /// Adds a region on top of those already added.
    pub fn with_region(mut self, region: Region) -> Self {
        self.regions.push(region);
        self
    }

    /// The rectangle D.
    pub fn domain(&self) -> Rect {
        self.domain
    }

    /// The regions, in the order they apply.
    pub fn regions(&self) -> &[Region] {
        &self.regions
    }

    /// k and f at `p`, after the regions.
    pub(crate) fn k_and_f(&self, p: Point) -> (f64, f64) {
        let (mut k, mut f) = (None, None);
        // Walk from the top: the first region that sets a field is the last one added.
        for region in self.regions.iter().rev() {
            if region.contains(p) {
                k = k.or(region.k);
                f = f.or(region.f);
                if k.is_some() && f.is_some() {
                    break;
                }
            }
        }
        (k.unwrap_or_else(|| (self.k)(p.x, p.y)), f.unwrap_or_else(|| (self.f)(p.x, p.y)))
    }

    /// k at `p`, after the regions; f is not evaluated.
    pub(crate) fn k_at(&self, p: Point) -> f64 {
        let region = self.regions.iter().rev().find_map(|r| if r.contains(p) { r.k } else { None });
        region.unwrap_or_else(|| (self.k)(p.x, p.y))
    }

    /// g at `p`.
    pub(crate) fn g_at(&self, p: Point) -> f64 {
        (self.g)(p.x, p.y)
    }
}

impl std::fmt::Debug for Problem<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Problem")
            .field("domain", &self.domain)
            .field("regions", &self.regions)
            .finish_non_exhaustive()
    }
}
