//! SolveSpec: a boundary value problem request, validated and in canonical form.

use super::checks::{Limits, SpecError, budget, build, domain_of, expression};
use crate::api::{
    ArcInput, BoundaryField, CircuitInput, Coefficient, MaterialInput, PolygonEntry, RegionInput,
    SolveRequest,
};
use crate::geom::{Point, Rect};
use crate::refine::Method;
use crate::result::{Geometry, RunResult, Summary, Unit};
use crate::solve::{
    Adapted, BhCurve, Boundary, Circuit, Coil, Exact, Indicator, MAX_POLYGON_POINTS, MU_0, Physics, Problem,
    Region, Settings, Shape, Side, SolveError, SolveObserver, adapt, arc_points, materials,
};
use crate::source::Expression;
use std::collections::BTreeMap;
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
    /// How the plane is read: planar, or (r, z) about the axis.
    pub geometry: Geometry,
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
    /// The circuits coil regions name, by index (in the order of their names).
    pub circuits: Vec<Circuit>,
    /// The unit the request's and the answer's lengths are in, when it named one; the spec
    /// itself holds metres.
    pub unit: Option<Unit>,
    /// The planar device's depth in metres, when given.
    pub depth: Option<f64>,
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
fn shaped(i: usize, r: &RegionInput, domain: Rect, per_metre: f64) -> Result<Region, SpecError> {
    let here = format!("regions[{i}]");
    let m = |v: f64| v / per_metre + 0.0;
    let shape = match (&r.x, &r.y, &r.polygon) {
        (Some(x), Some(y), None) => {
            let (x, y) = match (x.as_slice(), y.as_slice()) {
                (&[x0, x1], &[y0, y1]) => ([x0, x1], [y0, y1]),
                _ => return Err(invalid(here, "x and y must each be [low, high]")),
            };
            let rect =
                Rect::new(m(x[0]), m(x[1]), m(y[0]), m(y[1])).map_err(|e| invalid(&here, e.to_string()))?;
            Shape::Rect(rect)
        }
        (None, None, Some(entries)) => {
            let (corners, entry_of) = outline(&here, entries, m)?;
            Shape::polygon(corners, domain).map_err(|e| match e.corner() {
                Some(k) => invalid(format!("{here}.polygon[{}]", entry_of[k]), e.to_string()),
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

/// The degrees one straight segment of an arc sweeps unless the request says otherwise: a
/// circle of 72 sides, whose area is 0.13% short of the disc's.
pub const ARC_SEGMENT_ANGLE: f64 = 5.0;

/// How many corners `entries` make once each arc is drawn (a bad arc counts one, and is
/// named when it is drawn).
fn drawn_corners(entries: &[PolygonEntry]) -> usize {
    let drawn = |arc: &ArcInput| {
        let n = segments(arc.arc, arc.max_segment_angle.unwrap_or(ARC_SEGMENT_ANGLE));
        // Beyond a polygon's corners the count need not be exact; NaN counts 1.
        if n >= 1.0 { n.min(MAX_POLYGON_POINTS as f64 + 1.0) as usize } else { 1 }
    };
    entries.iter().map(|e| if let PolygonEntry::Arc(arc) = e { drawn(arc) - 1 } else { 1 }).sum()
}

/// The straight segments an arc of `degrees` is drawn with, each sweeping at most `most`.
fn segments(degrees: f64, most: f64) -> f64 {
    (degrees.abs() / most).ceil()
}

/// The corners of region `here`'s polygon `entries`, in metres (`m`), each arc drawn as
/// straight segments, and for each corner the index of the entry it came from, so that a
/// fault is named where the request put it.
fn outline(
    here: &str,
    entries: &[PolygonEntry],
    m: impl Fn(f64) -> f64,
) -> Result<(Vec<Point>, Vec<usize>), SpecError> {
    let n = entries.len();
    let corner = |k: usize| entries[k % n].corner().map(|[x, y]| Point::new(m(x), m(y)));
    let (mut corners, mut entry_of) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for (k, entry) in entries.iter().enumerate() {
        let PolygonEntry::Arc(arc) = *entry else {
            corners.extend(corner(k));
            entry_of.push(k);
            continue;
        };
        let field = format!("{here}.polygon[{k}]");
        let (Some(from), Some(to)) = (corner(k + n - 1), corner(k + 1)) else {
            return Err(invalid(field, "an arc stands between two corners (the first follows the last)"));
        };
        if from == to {
            return Err(invalid(
                field,
                "an arc needs two different corners: the one before it and the one after",
            ));
        }
        let degrees = arc.arc;
        if !(degrees.is_finite() && degrees != 0.0 && degrees.abs() < 360.0) {
            return Err(invalid(
                format!("{field}.arc"),
                format!("must be in (-360, 360) and not 0, got {degrees}"),
            ));
        }
        let most = arc.max_segment_angle.unwrap_or(ARC_SEGMENT_ANGLE);
        if !(most.is_finite() && most > 0.0 && most <= 90.0) {
            return Err(invalid(
                format!("{field}.max_segment_angle"),
                format!("must be in (0, 90], got {most}"),
            ));
        }
        let segments = segments(degrees, most);
        if segments > MAX_POLYGON_POINTS as f64 {
            return Err(invalid(
                format!("{field}.max_segment_angle"),
                format!(
                    "draws the arc as {segments} segments, more than a polygon's {MAX_POLYGON_POINTS} corners"
                ),
            ));
        }
        if corners.len() + segments as usize > MAX_POLYGON_POINTS + 1 {
            return Err(invalid(
                format!("{here}.polygon"),
                format!("has more than {MAX_POLYGON_POINTS} corners once its arcs are drawn"),
            ));
        }
        for p in arc_points(from, to, degrees, segments as usize) {
            corners.push(p);
            entry_of.push(k);
        }
    }
    Ok((corners, entry_of))
}

/// What the regions of a request read besides their own fields: the request's materials
/// and circuits, and its unit.
struct Device<'r> {
    physics: Physics,
    domain: Rect,
    per_metre: f64,
    /// The request's own materials, each law checked once.
    materials: &'r BTreeMap<String, Named>,
    circuits: &'r [Circuit],
}

/// A material's law, checked: μr (a magnet's recoil permeability), or a B–H table and its
/// curve, and a magnet's magnetization M = Br/μ0 with its direction.
#[derive(Clone)]
struct Named {
    mu_r: f64,
    bh: Option<(BhTable, Arc<BhCurve>)>,
    /// M in A/m, and the direction in degrees when the material names one.
    magnet: Option<(f64, Option<f64>)>,
}

/// The law of a material as the request's `materials` or the library gives it, its fields
/// named under `at`.
fn law(at: &str, m: &MaterialInput) -> Result<Named, SpecError> {
    let field = |name: &str| format!("{at}.{name}");
    let mu_r = m.mu_r.map(|v| positive(&field("mu_r"), v)).transpose()?;
    let br = m.br.map(|v| positive(&field("br"), v)).transpose()?;
    let hc = m.hc.map(|v| positive(&field("hc"), v)).transpose()?;
    if let Some(c) = m.conductivity
        && !(c.is_finite() && c >= 0.0)
    {
        return Err(invalid(field("conductivity"), format!("must be finite and >= 0, got {c}")));
    }
    let angle = m.angle.map(|a| finite(&field("angle"), a)).transpose()?;
    if let Some(bh) = &m.bh {
        if mu_r.is_some() || br.is_some() || hc.is_some() {
            return Err(invalid(
                field("bh"),
                "a B–H table is the whole law: give bh, or mu_r, or a magnet's br, hc and mu_r",
            ));
        }
        return Ok(Named { mu_r: 1.0, bh: Some((bh.clone(), curve(at, bh)?)), magnet: None });
    }
    let magnet = match (br, hc, mu_r) {
        (None, None, _) => None,
        (Some(br), _, Some(mu_r)) => Some((br, mu_r)),
        (Some(br), Some(hc), None) => Some((br, positive(&field("hc"), br / (MU_0 * hc))?)),
        (None, Some(hc), Some(mu_r)) => Some((finite(&field("hc"), MU_0 * mu_r * hc)?, mu_r)),
        _ => return Err(invalid(at, "a magnet needs two of br, hc and mu_r")),
    };
    if angle.is_some() && magnet.is_none() {
        return Err(invalid(field("angle"), "an angle is a magnet's direction: give br, hc or both"));
    }
    Ok(match magnet {
        Some((br, mu_r)) => Named { mu_r, bh: None, magnet: Some((br / MU_0, angle)) },
        None => Named { mu_r: mu_r.unwrap_or(1.0), bh: None, magnet: None },
    })
}

/// The B–H curve of `table`, a bad point named as `at`'s entry (`at.bh[k]`).
fn curve(at: &str, table: &BhTable) -> Result<Arc<BhCurve>, SpecError> {
    BhCurve::new(table).map(Arc::new).map_err(|e| match e.index() {
        Some(k) => invalid(format!("{at}.bh[{k}]"), e.to_string()),
        None => invalid(format!("{at}.bh"), e.to_string()),
    })
}

/// The unit vector `degrees` counter-clockwise from +x: exact at multiples of 90°, and
/// otherwise libm's sine and cosine, the same bits on every machine.
fn direction(degrees: f64) -> [f64; 2] {
    match degrees.rem_euclid(360.0) {
        0.0 => [1.0, 0.0],
        90.0 => [0.0, 1.0],
        180.0 => [-1.0, 0.0],
        270.0 => [0.0, -1.0],
        d => {
            let t = d.to_radians();
            [libm::cos(t), libm::sin(t)]
        }
    }
}

impl Device<'_> {
    /// Region `i`, inside the domain, with k and f for the physics, and its B–H table if it
    /// has one.
    fn region(&self, i: usize, r: RegionInput) -> Result<(Region, Option<BhTable>), SpecError> {
        let at = |name: &str| format!("regions[{i}].{name}");
        let mut region = shaped(i, &r, self.domain, self.per_metre)?;
        region.name = r.name.clone();
        if let Some([x, y]) = r.torque_about {
            let (x, y) = (finite(&at("torque_about[0]"), x)?, finite(&at("torque_about[1]"), y)?);
            region.torque_about = Point::new(x / self.per_metre + 0.0, y / self.per_metre + 0.0);
        }
        let mut table = None;
        // Whether the region sets any of the magnetostatic fields.
        let magnetic = [r.mu_r, r.current_density, r.current, r.turns, r.angle].iter().any(Option::is_some)
            || r.bh.is_some()
            || r.magnetization.is_some()
            || r.material.is_some()
            || r.circuit.is_some()
            || r.direction.is_some();
        match self.physics {
            Physics::Poisson => {
                if magnetic {
                    return Err(invalid(
                        format!("regions[{i}]"),
                        "mu_r, bh, magnetization, material, current_density, current and coils are for physics magnetostatic; use k and f",
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
                        "k and f are for physics poisson; use a material (or mu_r, bh), and a circuit or current",
                    ));
                }
                if !magnetic {
                    return Err(invalid(
                        format!("regions[{i}]"),
                        "a region must set at least one of material, mu_r, bh, magnetization, circuit, current_density and current",
                    ));
                }
                let law = self.law(i, &r)?;
                // Where regions overlap the later one's whole material wins: air (μr = 1) and no
                // current are set explicitly, never inherited.
                match law.bh {
                    Some((points, curve)) => {
                        region.curve = Some(curve);
                        table = Some(points);
                    }
                    None => region.k = Some(1.0 / (MU_0 * law.mu_r)),
                }
                region.source = Some(match law.magnet {
                    // M/μr must stay finite too: μr = 1e-10 under M = 1e300 would not.
                    Some([mx, my]) => [
                        finite(&at("magnetization[0]"), mx / law.mu_r)?,
                        finite(&at("magnetization[1]"), my / law.mu_r)?,
                    ],
                    None => [0.0; 2],
                });
                region.coil = self.coil(i, &r)?;
                let density = match (region.coil, r.current_density, r.current) {
                    (Some(_), Some(_), _) | (Some(_), _, Some(_)) => {
                        return Err(invalid(
                            at("circuit"),
                            "a coil's current is its circuit's: drop current and current_density",
                        ));
                    }
                    (_, Some(_), Some(_)) => {
                        return Err(invalid(at("current"), "give current_density or current, not both"));
                    }
                    (Some(coil), None, None) => {
                        let current = self.circuits[coil.circuit].current * coil.turns;
                        finite(&at("turns"), current / region.shape.area())?
                    }
                    (None, Some(j), None) => finite(&at("current_density"), j)?,
                    (None, None, Some(i)) => finite(&at("current"), i)? / region.shape.area(),
                    (None, None, None) => 0.0,
                };
                region.f = Some(density);
            }
        }
        Ok((region, table))
    }

    /// Region `i`'s material: named, or given by its own `mu_r`, `bh` and `magnetization`,
    /// as magnetization [Mx, My] for a magnet.
    fn law(&self, i: usize, r: &RegionInput) -> Result<Material, SpecError> {
        let at = |name: &str| format!("regions[{i}].{name}");
        let direct = r.mu_r.is_some() || r.bh.is_some() || r.magnetization.is_some();
        let Some(name) = &r.material else {
            if r.mu_r.is_some() && r.bh.is_some() {
                return Err(invalid(at("bh"), "give mu_r or bh, not both"));
            }
            if r.bh.is_some() && r.magnetization.is_some() {
                return Err(invalid(
                    at("magnetization"),
                    "a magnet takes mu_r (its recoil permeability), not bh",
                ));
            }
            if r.angle.is_some() {
                return Err(invalid(
                    at("angle"),
                    "an angle turns a named magnet material; give magnetization [Mx, My] here",
                ));
            }
            let mu_r = r.mu_r.map(|m| positive(&at("mu_r"), m)).transpose()?.unwrap_or(1.0);
            let bh = match &r.bh {
                Some(points) => Some((points.clone(), curve(&format!("regions[{i}]"), points)?)),
                None => None,
            };
            return Ok(Material { mu_r, bh, magnet: r.magnetization });
        };
        if direct {
            return Err(invalid(at("material"), "give material, or mu_r, bh and magnetization, not both"));
        }
        let law = match (self.materials.get(name), materials::find(name)) {
            (Some(own), _) => own.clone(),
            (None, Some(built_in)) => {
                let input = MaterialInput {
                    mu_r: built_in.mu_r,
                    bh: built_in.bh.clone(),
                    br: built_in.br,
                    hc: built_in.hc,
                    angle: None,
                    conductivity: built_in.conductivity,
                };
                law(&format!("materials.{name}"), &input)?
            }
            (None, None) => {
                return Err(invalid(
                    at("material"),
                    format!(
                        "no material {name:?} in materials or the built-in library (GET /v1/materials lists it)"
                    ),
                ));
            }
        };
        let magnet = match law.magnet {
            Some((m, angle)) => {
                let degrees = r.angle.map(|a| finite(&at("angle"), a)).transpose()?.or(angle).unwrap_or(0.0);
                let [c, s] = direction(degrees);
                Some([m * c, m * s])
            }
            None if r.angle.is_some() => {
                return Err(invalid(at("angle"), format!("material {name:?} is not a magnet")));
            }
            None => None,
        };
        Ok(Material { mu_r: law.mu_r, bh: law.bh, magnet })
    }

    /// Region `i`'s coil: the circuit it names, its turns signed by its direction.
    fn coil(&self, i: usize, r: &RegionInput) -> Result<Option<Coil>, SpecError> {
        let at = |name: &str| format!("regions[{i}].{name}");
        let Some(name) = &r.circuit else {
            if r.turns.is_some() || r.direction.is_some() {
                return Err(invalid(
                    at("circuit"),
                    "a coil (turns, direction) needs a circuit: a key of circuits",
                ));
            }
            return Ok(None);
        };
        let Some(circuit) = self.circuits.iter().position(|c| &c.name == name) else {
            let known: Vec<&str> = self.circuits.iter().map(|c| c.name.as_str()).collect();
            return Err(invalid(
                at("circuit"),
                format!(
                    "no circuit {name:?} in circuits (it has {})",
                    if known.is_empty() { "none".into() } else { known.join(", ") }
                ),
            ));
        };
        let turns = r.turns.map(|t| positive(&at("turns"), t)).transpose()?.unwrap_or(1.0);
        let sign = match r.direction {
            None | Some(1) => 1.0,
            Some(-1) => -1.0,
            Some(d) => return Err(invalid(at("direction"), format!("must be 1 or -1, got {d}"))),
        };
        Ok(Some(Coil { circuit, turns: sign * turns }))
    }
}

/// A region's material, resolved: μr, or a B–H table and its curve, and a magnet's
/// magnetization [Mx, My].
struct Material {
    mu_r: f64,
    bh: Option<(BhTable, Arc<BhCurve>)>,
    magnet: Option<[f64; 2]>,
}

/// The longest name of a region, a material or a circuit.
pub const MAX_NAME: usize = 100;

/// A key of `map` (materials or circuits): a name that errors can point at, so without the
/// `.` and `[` that separate a field's parts.
fn key(map: &str, name: &str) -> Result<(), SpecError> {
    if name.is_empty() || name.chars().count() > MAX_NAME || name.contains(['.', '[', ']']) {
        let detail = format!("{name:?}: a name is 1 to {MAX_NAME} characters, without '.', '[' or ']'");
        return Err(invalid(map, detail));
    }
    Ok(())
}

/// The circuits, checked, in the order of their names.
fn circuits(input: BTreeMap<String, CircuitInput>) -> Result<Vec<Circuit>, SpecError> {
    input
        .into_iter()
        .map(|(name, c)| {
            let current = finite(&format!("circuits.{name}.current"), c.current)?;
            Ok(Circuit { name, current })
        })
        .collect()
}

/// Each side's condition, checked against the physics, the geometry and the regions.
///
/// At least one side must fix u: a Dirichlet or an open side (or the axis), or u is fixed only
/// up to a constant. An open side is magnetostatics' and must lie in air: no region may touch
/// it. Axisymmetric, the axis (x = 0) holds A_φ = 0 whatever a side's name for all four says,
/// and no other condition may be named for it.
fn boundary(
    field: Option<BoundaryField>,
    physics: Physics,
    geometry: Geometry,
    domain: Rect,
    regions: &[Region],
) -> Result<Boundary, SpecError> {
    let input = field.map(|b| b.0).unwrap_or_default();
    let mut boundary = Boundary {
        left: input.left.unwrap_or_default(),
        right: input.right.unwrap_or_default(),
        bottom: input.bottom.unwrap_or_default(),
        top: input.top.unwrap_or_default(),
    };
    let axis = geometry == Geometry::Axisymmetric && domain.x0() == 0.0;
    if axis {
        if !input.every_side && boundary.left != Side::Dirichlet {
            return Err(invalid(
                "boundary.left",
                "the left side is the axis r = 0, where A_φ = 0: leave it out",
            ));
        }
        boundary.left = Side::Dirichlet;
    }
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
    if geometry == Geometry::Axisymmetric && boundary.across_x().is_some() {
        return Err(invalid("boundary", "left and right cannot be periodic about an axis"));
    }
    let sides = [
        ("left", boundary.left),
        ("right", boundary.right),
        ("bottom", boundary.bottom),
        ("top", boundary.top),
    ];
    for (name, side) in sides {
        if side != Side::Open {
            continue;
        }
        if physics != Physics::Magnetostatic {
            return Err(invalid(format!("boundary.{name}"), "open sides are for physics magnetostatic"));
        }
        let on = |p: Point| match name {
            "left" => p.x == domain.x0(),
            "right" => p.x == domain.x1(),
            "bottom" => p.y == domain.y0(),
            _ => p.y == domain.y1(),
        };
        if let Some(i) = regions.iter().position(|r| r.shape.sides().any(|[a, _]| on(a))) {
            return Err(invalid(
                format!("boundary.{name}"),
                format!(
                    "regions[{i}] touches this open side: an open side must lie in air, with room around the device"
                ),
            ));
        }
    }
    if !boundary.has_dirichlet() && !boundary.has_open() {
        return Err(invalid(
            "boundary",
            "at least one side must be dirichlet or open: with every side neumann, u is fixed only up to a constant",
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
        let physics = request.physics.unwrap_or_default();
        let geometry = request.geometry.unwrap_or_default();
        if physics == Physics::Poisson {
            let device = [
                ("geometry", request.geometry.is_some()),
                ("unit", request.unit.is_some()),
                ("depth", request.depth.is_some()),
                ("materials", !request.materials.is_empty()),
                ("circuits", !request.circuits.is_empty()),
            ];
            if let Some((field, _)) = device.iter().find(|(_, given)| *given) {
                return Err(invalid(
                    *field,
                    "is for physics magnetostatic: a poisson problem has no units or devices",
                ));
            }
        }
        if geometry == Geometry::Axisymmetric {
            let planar = [
                ("depth", request.depth.is_some(), "an axisymmetric device is the whole turn about its axis"),
                (
                    "exact",
                    request.exact.is_some(),
                    "errors against an exact solution are measured planar only",
                ),
            ];
            if let Some((field, _, why)) = planar.iter().find(|(_, given, _)| *given) {
                return Err(invalid(*field, format!("not allowed with geometry axisymmetric: {why}")));
            }
            if let Some(i) = request.regions.iter().position(|r| r.torque_about.is_some()) {
                let detail = "nothing turns about the axis: an axisymmetric force is axial";
                return Err(invalid(format!("regions[{i}].torque_about"), detail));
            }
        }
        let per_metre = request.unit.unwrap_or_default().per_metre();
        let depth = match request.depth {
            Some(d) => Some(positive("depth", d)? / per_metre),
            None => None,
        };
        let domain = match request.domain {
            None => Rect::unit(),
            Some(d) => {
                let r = domain_of(&d)?;
                let m = |v: f64| v / per_metre;
                Rect::new(m(r.x0()), m(r.x1()), m(r.y0()), m(r.y1())).map_err(super::checks::domain_error)?
            }
        };
        if geometry == Geometry::Axisymmetric && domain.x0() < 0.0 {
            // Name the region that crosses the axis, if one does, as what to move.
            let below = |r: &crate::api::RegionInput| {
                let xs =
                    r.x.iter()
                        .flatten()
                        .copied()
                        .chain(r.polygon.iter().flatten().filter_map(PolygonEntry::corner).map(|p| p[0]));
                xs.fold(f64::INFINITY, f64::min) < 0.0
            };
            let field = request
                .regions
                .iter()
                .position(below)
                .map_or("domain.x".to_owned(), |i| format!("regions[{i}]"));
            return Err(invalid(field, "crosses the axis: an axisymmetric problem lives in r = x >= 0"));
        }
        // Without a source or boundary values the answer is u = 0 (A = 0), whatever the mesh:
        // a request that forgot them is told so rather than answered. A coil counts at any
        // current: its inductance at zero current is an answer.
        let sourced = request.f.is_some()
            || request.g.is_some()
            || request.regions.iter().any(|r| {
                r.f.is_some()
                    || r.magnetization.is_some()
                    || r.current_density.is_some()
                    || r.current.is_some()
                    || r.circuit.is_some()
                    || r.material.as_ref().is_some_and(|name| {
                        let own = request.materials.get(name);
                        own.map_or_else(
                            || materials::find(name).is_some_and(|m| m.br.is_some()),
                            |m| m.br.is_some() || m.hc.is_some(),
                        )
                    })
            });
        let (k, f) = match physics {
            Physics::Poisson => {
                (coefficient("k", request.k, 1.0, limits)?, coefficient("f", request.f, 0.0, limits)?)
            }
            Physics::Magnetostatic => {
                for (field, given) in [("k", request.k.is_some()), ("f", request.f.is_some())] {
                    if given {
                        return Err(invalid(
                            field,
                            "not allowed with physics magnetostatic: regions give materials and currents",
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
        let mut own = BTreeMap::new();
        for (name, m) in &request.materials {
            key("materials", name)?;
            own.insert(name.clone(), law(&format!("materials.{name}"), m)?);
        }
        for name in request.circuits.keys() {
            key("circuits", name)?;
        }
        for (i, r) in request.regions.iter().enumerate() {
            if let Some(name) = &r.name
                && name.chars().count() > MAX_NAME
            {
                return Err(invalid(
                    format!("regions[{i}].name"),
                    format!("longer than {MAX_NAME} characters"),
                ));
            }
        }
        let circuits = circuits(request.circuits)?;
        if request.regions.len() > MAX_REGIONS {
            return Err(invalid(
                "regions",
                format!("{} regions, more than {MAX_REGIONS}", request.regions.len()),
            ));
        }
        // Counted as drawn before anything is drawn or checked: the simplicity check takes
        // time growing with the square of a polygon's corners.
        let corners: usize =
            request.regions.iter().map(|r| r.polygon.as_deref().map_or(4, drawn_corners)).sum();
        if corners > MAX_CORNERS {
            return Err(invalid("regions", format!("{corners} corners in all, more than {MAX_CORNERS}")));
        }
        let device = Device { physics, domain, per_metre, materials: &own, circuits: &circuits };
        let (regions, tables) = (request.regions.into_iter().enumerate())
            .map(|(i, r)| device.region(i, r))
            .collect::<Result<(Vec<_>, Vec<_>), _>>()?;
        let boundary = boundary(request.boundary, physics, geometry, domain, &regions)?;
        if let Some(unused) = circuits
            .iter()
            .enumerate()
            .find(|(c, _)| !regions.iter().any(|r| r.coil.is_some_and(|coil| coil.circuit == *c)))
        {
            return Err(invalid(
                format!("circuits.{}", unused.1.name),
                "no region is a coil of this circuit",
            ));
        }
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
                    ("regions", "a region with a circuit, a current_density, a current or a magnet")
                }
            };
            return Err(invalid(
                field,
                format!("nothing to solve: the solution is 0 everywhere without {what}"),
            ));
        }
        let unit = request.unit;
        let spec = Self {
            physics,
            geometry,
            domain,
            k,
            f,
            g,
            boundary,
            regions,
            tables,
            exact,
            settings,
            circuits,
            unit,
            depth,
        };
        Ok((spec, requested_time_limit))
    }

    /// The problem to solve, its fields reading this spec.
    pub fn problem(&self) -> Problem<'_> {
        // The expressions read x and y in the request's unit; the problem is in metres.
        let per = self.per_metre();
        let mut problem = Problem::new(self.domain)
            .with_k(move |x, y| self.k.eval(x * per, y * per))
            .with_f(move |x, y| self.f.eval(x * per, y * per))
            .with_g(move |x, y| self.g.eval(x * per, y * per))
            .with_boundary(self.boundary)
            .with_geometry(self.geometry);
        for circuit in &self.circuits {
            problem = problem.with_circuit(circuit.clone());
        }
        for region in &self.regions {
            problem = problem.with_region(region.clone());
        }
        problem
    }

    /// How many of the request's unit make a metre.
    fn per_metre(&self) -> f64 {
        self.unit.unwrap_or_default().per_metre()
    }

    /// The result of a finished loop as the request asked for it: lengths back in its unit
    /// (vertices, areas), and per-metre figures times the depth when it gave one.
    pub fn result(&self, adapted: Adapted) -> RunResult {
        let mut result = adapted.into_result(self.physics);
        let per = self.per_metre();
        if per != 1.0 {
            for v in &mut result.vertices {
                v.x *= per;
                v.y *= per;
            }
        }
        if let Summary::Solution(stats) = &mut result.stats {
            stats.unit = self.unit;
            stats.depth = self.depth.map(|d| d * per);
            let run = &mut stats.run;
            for region in &mut run.regions {
                region.area *= per * per;
            }
            // Per metre of depth planar, per radian axisymmetric: the device's totals are the
            // depth's, or the whole turn's.
            let whole = match self.geometry {
                Geometry::Planar => self.depth,
                Geometry::Axisymmetric => Some(2.0 * std::f64::consts::PI),
            };
            if let Some(depth) = whole {
                run.energy *= depth;
                run.coenergy *= depth;
                for step in &mut run.history {
                    step.energy *= depth;
                }
                for region in &mut run.regions {
                    region.force = region.force.map(|f| f * depth);
                    region.torque *= depth;
                }
                for circuit in run.circuits.values_mut() {
                    circuit.flux_linkage *= depth;
                    circuit.inductance = circuit.inductance.map(|l| l * depth);
                    circuit.incremental_inductance *= depth;
                }
            }
        }
        result
    }

    /// Runs the adaptive loop on this problem, measuring against `exact` when given; what
    /// the worker and `meshfit solve` both run.
    ///
    /// # Errors
    /// As [`adapt`].
    pub fn solve<O: SolveObserver>(&self, observer: &mut O) -> Result<Adapted, SolveError> {
        let per = self.per_metre();
        let exact = self.exact.as_ref().map(|e| move |x: f64, y: f64| e.eval(x * per, y * per));
        adapt(&self.problem(), exact.as_ref().map(|u| u as Exact<'_>), &self.settings, observer)
    }
}
