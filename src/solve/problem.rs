//! The boundary value problem: the domain, the coefficient k, the load f, the boundary data g,
//! each side's condition, and the regions that override k and f.

use super::bh::Curve;
use super::polygon::{Polygon, PolygonError};
use crate::geom::{Point, Rect};
use crate::result::Geometry;
use std::sync::Arc;

/// A scalar field on the plane, evaluated at (x, y).
pub(crate) type ScalarField<'a> = Box<dyn Fn(f64, f64) -> f64 + 'a>;

/// Where a region applies: a closed rectangle or a simple polygon, boundary included.
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    /// An axis-aligned rectangle.
    Rect(Rect),
    /// A simple polygon.
    Polygon(Polygon),
}

impl Shape {
    /// The simple polygon of `corners` inside `domain`; see [`Polygon::try_new`].
    ///
    /// # Errors
    /// As [`Polygon::try_new`].
    pub fn polygon(corners: Vec<Point>, domain: Rect) -> Result<Self, PolygonError> {
        Polygon::try_new(corners, domain).map(Shape::Polygon)
    }

    /// Whether `p` is within `margin` of the box around the shape: no point outside is in it.
    fn near(&self, p: Point, margin: f64) -> bool {
        let (lo, hi) = match self {
            Shape::Rect(r) => (Point::new(r.x0(), r.y0()), Point::new(r.x1(), r.y1())),
            Shape::Polygon(polygon) => (polygon.lo, polygon.hi),
        };
        lo.x - margin <= p.x && p.x <= hi.x + margin && lo.y - margin <= p.y && p.y <= hi.y + margin
    }

    /// Whether `p` lies in the closed shape. A polygon's test is plain floating point, so a
    /// point within rounding of a slanted side may fall either way: callers ask at points well
    /// inside their triangles, or through [`Shape::holds`].
    pub fn contains(&self, p: Point) -> bool {
        match self {
            Shape::Rect(r) => r.contains(p),
            Shape::Polygon(_) if !self.near(p, 0.0) => false,
            Shape::Polygon(Polygon { corners, .. }) => {
                // Crossings of a ray to +x (W. R. Franklin's PNPOLY), then the sides themselves.
                let mut inside = false;
                let mut j = corners.len() - 1;
                for (i, &a) in corners.iter().enumerate() {
                    let b = corners[j];
                    if (a.y > p.y) != (b.y > p.y) && p.x < (b.x - a.x) * (p.y - a.y) / (b.y - a.y) + a.x {
                        inside = !inside;
                    }
                    j = i;
                }
                inside || self.sides().any(|[a, b]| distance_sq_to_segment(p, a, b) == 0.0)
            }
        }
    }

    /// Whether `p` lies in the shape or within `tolerance` of its outline: a mesh vertex that
    /// a split of a slanted side rounded a hair off it still counts as on it.
    pub fn holds(&self, p: Point, tolerance: f64) -> bool {
        self.near(p, tolerance)
            && (self.contains(p)
                || self.sides().any(|[a, b]| distance_sq_to_segment(p, a, b) <= tolerance * tolerance))
    }

    /// The sides, each from one corner to the next.
    pub fn sides(&self) -> impl Iterator<Item = [Point; 2]> + '_ {
        let rect = self.rect().map(|r| r.corners());
        let corners: &[Point] = match self {
            Shape::Rect(_) => &[],
            Shape::Polygon(polygon) => &polygon.corners,
        };
        let n = if rect.is_some() { 4 } else { corners.len() };
        let at = move |k: usize| rect.map_or_else(|| corners[k % n], |c| c[k % n]);
        (0..n).map(move |i| [at(i), at(i + 1)])
    }

    /// The area enclosed.
    pub fn area(&self) -> f64 {
        match self {
            Shape::Rect(r) => r.area(),
            Shape::Polygon(polygon) => polygon.area(),
        }
    }

    /// The rectangle, when the shape is one.
    pub fn rect(&self) -> Option<Rect> {
        match self {
            Shape::Rect(r) => Some(*r),
            Shape::Polygon(_) => None,
        }
    }
}

/// The squared distance from `p` to the segment `a`–`b`.
fn distance_sq_to_segment(p: Point, a: Point, b: Point) -> f64 {
    let (dx, dy) = (b.x - a.x, b.y - a.y);
    let len_sq = dx * dx + dy * dy;
    let t = if len_sq > 0.0 { (((p.x - a.x) * dx + (p.y - a.y) * dy) / len_sq).clamp(0.0, 1.0) } else { 0.0 };
    p.distance_sq(Point::new(a.x + t * dx, a.y + t * dy))
}

/// A part of the domain in which k, f and the material are constants.
///
/// Regions are applied in the order they were added, so where two overlap the later one wins,
/// field by field: a later region that sets only `f` keeps an earlier region's `k`. The
/// material (`k` or `curve`, with `source`) is one field.
#[derive(Debug, Clone)]
pub struct Region {
    /// Where the region applies, boundary included.
    pub shape: Shape,
    /// The coefficient inside, or `None` to keep the value from below.
    pub k: Option<f64>,
    /// The load inside, or `None` to keep the value from below.
    pub f: Option<f64>,
    /// A nonlinear coefficient instead of `k`: k = ν(|∇u|) = H(B)/B with B = |∇u|, for a
    /// magnetostatic problem's iron.
    pub curve: Option<Arc<dyn Curve>>,
    /// A vector source s inside, the weak form gaining ∫ s · (∂φ/∂y, −∂φ/∂x): a permanent
    /// magnet's M/μr in A/m. Goes with the material: it applies where `k` or `curve` does.
    pub source: Option<[f64; 2]>,
    /// The name its figures carry.
    pub name: Option<String>,
    /// The circuit whose turns it holds, when it is a coil side: its `f` is then that
    /// circuit's current times `turns` over its area.
    pub coil: Option<Coil>,
    /// The point its torque is taken about.
    pub torque_about: Point,
}

/// A coil side: `turns` turns of a circuit, signed by their direction (+ out of the plane).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Coil {
    /// The circuit's index in [`Problem::circuits`].
    pub circuit: usize,
    /// The turns, negative where they return into the plane.
    pub turns: f64,
}

/// A circuit: coil sides in series, each turn carrying `current`.
#[derive(Debug, Clone, PartialEq)]
pub struct Circuit {
    /// The name its figures carry.
    pub name: String,
    /// The current in every turn, in A.
    pub current: f64,
}

/// A region's shape reaches outside the problem's domain.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("the region must lie inside the domain")]
pub struct OutsideDomain;

impl Region {
    /// A region of `shape` that sets nothing yet. [`Region::try_new`] also checks that it
    /// lies inside the domain, which a problem's regions must.
    pub fn new(shape: Shape) -> Self {
        let torque_about = Point::new(0.0, 0.0);
        Self { shape, k: None, f: None, curve: None, source: None, name: None, coil: None, torque_about }
    }

    /// A region of `shape`, which must lie inside `domain` (boundary included), that sets
    /// nothing yet.
    ///
    /// # Errors
    /// [`OutsideDomain`] when a corner of the shape lies outside `domain`.
    pub fn try_new(shape: Shape, domain: Rect) -> Result<Self, OutsideDomain> {
        if shape.sides().all(|[a, _]| domain.contains(a)) { Ok(Self::new(shape)) } else { Err(OutsideDomain) }
    }

    /// A rectangle with k and/or f.
    pub fn rect(rect: Rect, k: Option<f64>, f: Option<f64>) -> Self {
        Self { k, f, ..Self::new(Shape::Rect(rect)) }
    }

    /// Whether `p` lies in the closed region.
    pub fn contains(&self, p: Point) -> bool {
        self.shape.contains(p)
    }

    /// Whether the region sets the material (`k` or `curve`).
    fn sets_material(&self) -> bool {
        self.k.is_some() || self.curve.is_some()
    }
}

/// What a side of the rectangle prescribes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Side {
    /// u = g.
    #[default]
    Dirichlet,
    /// Zero normal flux, k ∂u/∂n = 0: u is free there (in magnetostatics the field crosses
    /// the side at right angles).
    Neumann,
    /// u on this side equals u at the matching point of the opposite side, which says the same:
    /// a repeating structure. The mesh gets a vertex on each side wherever the other has one.
    Periodic,
    /// As `periodic`, with u opposite: a motor slice over one pole.
    Antiperiodic,
    /// Unbounded space beyond the side: an asymptotic (Robin) condition, k ∂u/∂n + k c u = k h,
    /// that a field decaying as a dipole's meets exactly, with a net current's logarithm as data.
    Open,
}

impl Side {
    /// u at the point matched across a periodic pair, for u here: ±1; `None` when not a pair.
    pub fn sign(self) -> Option<f64> {
        match self {
            Side::Periodic => Some(1.0),
            Side::Antiperiodic => Some(-1.0),
            Side::Dirichlet | Side::Neumann | Side::Open => None,
        }
    }
}

/// The condition on each side of the rectangle: x = x0, x = x1, y = y0, y = y1.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Boundary {
    /// x = x0.
    pub left: Side,
    /// x = x1.
    pub right: Side,
    /// y = y0.
    pub bottom: Side,
    /// y = y1.
    pub top: Side,
}

impl Boundary {
    /// Whether any side is Dirichlet: otherwise u is fixed only up to a constant.
    pub fn has_dirichlet(&self) -> bool {
        [self.left, self.right, self.bottom, self.top].contains(&Side::Dirichlet)
    }

    /// Whether any side is open: its condition fixes u too.
    pub fn has_open(&self) -> bool {
        [self.left, self.right, self.bottom, self.top].contains(&Side::Open)
    }

    /// The sign of the left–right pair (u right = sign · u left), when the pair is periodic.
    pub fn across_x(&self) -> Option<f64> {
        if self.left == self.right { self.left.sign() } else { None }
    }

    /// The sign of the bottom–top pair, when it is periodic.
    pub fn across_y(&self) -> Option<f64> {
        if self.bottom == self.top { self.bottom.sign() } else { None }
    }
}

/// −∇·(k ∇u) = f in the rectangle D; u = g on its Dirichlet sides, k ∂u/∂n = 0 on its
/// Neumann sides.
///
/// Built with [`Problem::new`] (k = 1, f = 0, g = 0) and the `with_*` builders. The fields are
/// closures, so a caller's expression, grid or exact solution can be plugged in directly.
///
/// # Example
/// ```
/// use meshfit::geom::Rect;
/// use meshfit::solve::{Problem, Region};
///
/// let inclusion = Region::rect(Rect::new(0.25, 0.5, 0.25, 0.5).unwrap(), Some(10.0), None);
/// let problem = Problem::new(Rect::unit())
///     .with_f(|_, _| 1.0)
///     .with_g(|x, y| x * y)
///     .with_region(inclusion);
/// assert_eq!(problem.regions().len(), 1);
/// ```
pub struct Problem<'a> {
    domain: Rect,
    k: ScalarField<'a>,
    f: ScalarField<'a>,
    g: ScalarField<'a>,
    regions: Vec<Region>,
    circuits: Vec<Circuit>,
    boundary: Boundary,
    geometry: Geometry,
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
            circuits: Vec::new(),
            boundary: Boundary::default(),
            geometry: Geometry::Planar,
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

    /// Adds a circuit, which coil regions name by its index in [`Problem::circuits`].
    pub fn with_circuit(mut self, circuit: Circuit) -> Self {
        self.circuits.push(circuit);
        self
    }

    /// The circuits, in the order they were added.
    pub fn circuits(&self) -> &[Circuit] {
        &self.circuits
    }

    /// Sets each side's condition (every side Dirichlet by default).
    pub fn with_boundary(mut self, boundary: Boundary) -> Self {
        self.boundary = boundary;
        self
    }

    /// Reads the plane as (r, z) about the axis x = 0 (x ≥ 0 everywhere): the equation is
    /// then the axisymmetric one for A_φ, and A_φ = 0 on the axis, whatever the left side
    /// says. Planar by default.
    pub fn with_geometry(mut self, geometry: Geometry) -> Self {
        self.geometry = geometry;
        self
    }

    /// How the plane is read.
    pub fn geometry(&self) -> Geometry {
        self.geometry
    }

    /// Whether `p` lies on the axis of an axisymmetric problem.
    fn on_axis(&self, p: Point) -> bool {
        self.geometry == Geometry::Axisymmetric && p.x == 0.0
    }

    /// Each side's condition.
    pub fn boundary(&self) -> Boundary {
        self.boundary
    }

    /// Whether `p` is on a Dirichlet side (exactly: its coordinate equals the side's); a
    /// corner between a Dirichlet and a Neumann side is Dirichlet.
    pub(crate) fn is_dirichlet(&self, p: Point) -> bool {
        let (d, b) = (self.domain, self.boundary);
        self.on_axis(p)
            || (p.x == d.x0() && b.left == Side::Dirichlet)
            || (p.x == d.x1() && b.right == Side::Dirichlet)
            || (p.y == d.y0() && b.bottom == Side::Dirichlet)
            || (p.y == d.y1() && b.top == Side::Dirichlet)
    }

    /// Whether the segment `a`–`b` lies on a Neumann side.
    pub(crate) fn is_neumann_edge(&self, a: Point, b: Point) -> bool {
        let (d, s) = (self.domain, self.boundary);
        (a.x == b.x
            && ((a.x == d.x0() && s.left == Side::Neumann) || (a.x == d.x1() && s.right == Side::Neumann)))
            || (a.y == b.y
                && ((a.y == d.y0() && s.bottom == Side::Neumann)
                    || (a.y == d.y1() && s.top == Side::Neumann)))
    }

    /// The outward normal of the open side the segment `a`–`b` lies on, if it lies on one.
    pub(crate) fn open_normal(&self, a: Point, b: Point) -> Option<[f64; 2]> {
        let (d, s) = (self.domain, self.boundary);
        if self.on_axis(a) && self.on_axis(b) {
            None
        } else if a.x == b.x && a.x == d.x0() && s.left == Side::Open {
            Some([-1.0, 0.0])
        } else if a.x == b.x && a.x == d.x1() && s.right == Side::Open {
            Some([1.0, 0.0])
        } else if a.y == b.y && a.y == d.y0() && s.bottom == Side::Open {
            Some([0.0, -1.0])
        } else if a.y == b.y && a.y == d.y1() && s.top == Side::Open {
            Some([0.0, 1.0])
        } else {
            None
        }
    }

    /// The open boundary's condition at `p` of a side with outward normal `n`: ∂u/∂n + c u = h,
    /// as (c, h) for a net source `net` (∫ f) in a medium of coefficient `k`.
    ///
    /// Far from the sources u is a multipole expansion about the domain's centre o (planar;
    /// axisymmetric, the axis's point at the height of the domain's middle). Planar, u =
    /// −net/(2πk) ln(ρ/ρ₀) + a dipole ∝ cos θ/ρ + …; the condition ∂u/∂ρ = −u/ρ is the
    /// dipole's, and h carries the logarithm's remainder, so a device with a net current and
    /// one without both meet it to the quadrupole's order. Axisymmetric, A_φ of a dipole falls
    /// as sin θ/R², so ∂A/∂R = −2A/R, and there is no net term. On a side, ∂/∂n = (ρ̂·n) ∂/∂ρ.
    /// ρ₀ is half the domain's diagonal, where the logarithm's u is 0.
    pub(crate) fn open(&self, p: Point, n: [f64; 2], net: f64, k: f64) -> (f64, f64) {
        let d = self.domain;
        let centre = match self.geometry {
            Geometry::Planar => Point::new((d.x0() + d.x1()) / 2.0, (d.y0() + d.y1()) / 2.0),
            Geometry::Axisymmetric => Point::new(0.0, (d.y0() + d.y1()) / 2.0),
        };
        let (rx, ry) = (p.x - centre.x, p.y - centre.y);
        let rho_sq = rx * rx + ry * ry;
        let along = (rx * n[0] + ry * n[1]) / rho_sq;
        match self.geometry {
            Geometry::Planar => {
                let log = 0.5 * (rho_sq / (0.25 * d.diagonal() * d.diagonal())).ln();
                (along, -along * net / (2.0 * std::f64::consts::PI * k) * (1.0 + log))
            }
            Geometry::Axisymmetric => (2.0 * along, 0.0),
        }
    }

    /// Every region side, for a mesh that follows them.
    pub(crate) fn sides(&self) -> Vec<[Point; 2]> {
        self.regions.iter().flat_map(|r| r.shape.sides()).collect()
    }

    /// The material at `p`: the index of the topmost region that sets it with a curve, and
    /// its source (0 where none).
    pub(crate) fn material_at(&self, p: Point) -> (Option<u32>, [f64; 2]) {
        match self.regions.iter().enumerate().rev().find(|(_, r)| r.sets_material() && r.contains(p)) {
            Some((i, r)) => (r.curve.is_some().then_some(i as u32), r.source.unwrap_or([0.0; 2])),
            None => (None, [0.0; 2]),
        }
    }

    /// Whether a region sets a curve or a source: each triangle then records its material.
    pub(crate) fn has_materials(&self) -> bool {
        self.regions.iter().any(|r| r.curve.is_some() || r.source.is_some())
    }

    /// Whether a region's k is a curve: the problem is nonlinear.
    pub fn is_nonlinear(&self) -> bool {
        self.regions.iter().any(|r| r.curve.is_some())
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
                k = k.or(region.k).or_else(|| region.curve.as_ref().map(|c| c.nu(0.0).0));
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
        let region = self.regions.iter().rev().find_map(|r| {
            if r.contains(p) { r.k.or_else(|| r.curve.as_ref().map(|c| c.nu(0.0).0)) } else { None }
        });
        region.unwrap_or_else(|| (self.k)(p.x, p.y))
    }

    /// g at `p`; 0 on the axis.
    pub(crate) fn g_at(&self, p: Point) -> f64 {
        if self.on_axis(p) { 0.0 } else { (self.g)(p.x, p.y) }
    }
}

impl std::fmt::Debug for Problem<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Problem")
            .field("domain", &self.domain)
            .field("regions", &self.regions)
            .field("circuits", &self.circuits)
            .field("boundary", &self.boundary)
            .field("geometry", &self.geometry)
            .finish_non_exhaustive()
    }
}
