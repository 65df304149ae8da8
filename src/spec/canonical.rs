//! A spec's canonical encoding: the bytes its id hashes, and the bytes replicas keep so that
//! another replica can run the job again without the request.
//!
//! A spec is a run of fields in a fixed order, each (name length, name, value length, value)
//! with lengths as little-endian u64, so no two specs share an encoding. Defaults are filled
//! in, floats are written by their exact bits and names by the API's own spelling, so key
//! order, `1` versus `1.0` and omitted defaults never make a new job. The first field is the
//! engine version: a spec kept by a replica of another engine is not read as this one's.
//!
//! [`write()`] feeds the fields to a [`Sink`]: a hash for the id, or a buffer for [`encode`].
//! [`decode`] reads them back through the same domain constructors and limits as a request,
//! so a spec kept by a replica with looser limits is refused here rather than run.

use super::checks::{Limits, SpecError, domain_error, expression, grid_error};
use super::job::{JobSpec, Knobs, MeshSpec, Work};
use super::solution::{BhTable, Function, MAX_CORNERS, MAX_REGIONS, SolveSpec, Steering};
use crate::geom::{Point, Rect};
use crate::refine::Criterion;
use crate::result::Geometry;
use crate::solve::{BhCurve, Boundary, Circuit, Coil, Region, Shape};
use crate::source::{Grid, GridError, GridFileError, Source};
use serde::Serialize;
use serde::de::DeserializeOwned;
use std::sync::Arc;
use std::time::Duration;

/// Bumped whenever the engine may produce a different mesh for the same request, so that a
/// cache (in memory or on disk) never serves a mesh the current engine would not make.
pub const ENGINE_VERSION: &str = "meshfit-engine-9";

/// Where the fields of an encoding go.
pub trait Sink {
    /// Takes the next bytes of the encoding.
    fn put(&mut self, bytes: &[u8]);

    /// Marks the end of the fields a spec's family shares: those of a mesh before its
    /// budget, tolerance and time limit. Never called for a solution, which has no family.
    fn family(&mut self) {}
}

impl Sink for Vec<u8> {
    fn put(&mut self, bytes: &[u8]) {
        self.extend_from_slice(bytes);
    }
}

/// Why kept bytes are not a spec this replica runs.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DecodeError {
    /// Not the encoding of a spec of this engine: truncated, reordered, or another version's.
    #[error("not a spec of {ENGINE_VERSION}: {0}")]
    Format(String),
    /// A spec of this engine, refused by this replica's limits or the engine's rules.
    #[error(transparent)]
    Spec(#[from] SpecError),
}

/// The canonical encoding of `spec`.
pub fn encode(spec: &JobSpec) -> Vec<u8> {
    let mut bytes = Vec::new();
    write(spec, &mut bytes);
    bytes
}

/// Feeds `spec`'s fields to `sink`, in order.
pub fn write(spec: &JobSpec, sink: &mut impl Sink) {
    let mut w = Writer(sink);
    w.field("engine", ENGINE_VERSION.as_bytes());
    // The limit the client named, not the one in force: server settings never change ids.
    let ms = spec.requested_time_limit.map_or(Vec::new(), |t| (t.as_millis() as u64).to_le_bytes().to_vec());
    match &spec.work {
        Work::Mesh(mesh) => write_mesh(&mut w, mesh),
        Work::Solve(solve) => {
            w.field("kind", b"solution");
            write_solution(&mut w, solve);
        }
    }
    w.field("time_limit_ms", &ms);
}

struct Writer<'a, S>(&'a mut S);

impl<S: Sink> Writer<'_, S> {
    fn header(&mut self, name: &str, len: usize) {
        self.0.put(&(name.len() as u64).to_le_bytes());
        self.0.put(name.as_bytes());
        self.0.put(&(len as u64).to_le_bytes());
    }

    fn field(&mut self, name: &str, value: &[u8]) {
        self.header(name, value.len());
        self.0.put(value);
    }

    fn u64(&mut self, name: &str, v: u64) {
        self.field(name, &v.to_le_bytes());
    }

    fn floats(&mut self, name: &str, values: &[f64]) {
        self.field(name, &values.iter().flat_map(|v| v.to_bits().to_le_bytes()).collect::<Vec<_>>());
    }

    fn optional(&mut self, name: &str, v: Option<f64>) {
        self.floats(name, v.as_slice());
    }

    fn name(&mut self, name: &str, value: &impl Serialize) {
        self.field(name, wire_name(value).as_bytes());
    }

    fn function(&mut self, name: &str, f: Option<&Function>) {
        match f {
            None => self.field(name, &[]),
            Some(Function::Constant(v)) => {
                self.field(name, &[&[0u8][..], &v.to_bits().to_le_bytes()].concat())
            }
            Some(Function::Expression(e)) => self.field(name, &[&[1u8][..], e.text().as_bytes()].concat()),
        }
    }
}

fn write_mesh<S: Sink>(w: &mut Writer<'_, S>, spec: &MeshSpec) {
    match &*spec.source {
        Source::Expression(e) => w.field("function", e.text().as_bytes()),
        Source::Grid(g) => {
            w.u64("grid.nx", g.nx() as u64);
            w.u64("grid.ny", g.ny() as u64);
            w.header("grid.values", 8 * g.nx() * g.ny());
            // Row by row: a large grid is never copied whole into a hash.
            let mut row = Vec::with_capacity(8 * g.nx());
            for j in 0..g.ny() {
                row.clear();
                row.extend(g.row(j).iter().flat_map(|v| v.to_bits().to_le_bytes()));
                w.0.put(&row);
            }
        }
    }
    let d = spec.domain;
    for (name, v) in [("domain.a", d.x0()), ("domain.b", d.x1()), ("domain.c", d.y0()), ("domain.d", d.y1())]
    {
        w.floats(name, &[v]);
    }
    let p = &spec.params;
    w.field("method", p.method().to_string().as_bytes());
    w.field("criterion", p.criterion().to_string().as_bytes());
    w.field("quality", &[u8::from(spec.quality)]);
    w.optional("min_angle", p.min_angle());
    // Only curvature has sizes: every other request keeps the bytes (and ids) it had.
    if p.criterion() == Criterion::Curvature {
        w.optional("min_size", p.min_size());
        w.optional("max_size", p.max_size());
    }
    w.0.family();
    w.u64("max_vertices", p.max_vertices() as u64);
    w.optional("tolerance", p.tolerance());
}

fn write_solution<S: Sink>(w: &mut Writer<'_, S>, spec: &SolveSpec) {
    w.name("physics", &spec.physics);
    let d = spec.domain;
    w.floats("domain", &[d.x0(), d.x1(), d.y0(), d.y1()]);
    w.function("k", Some(&spec.k));
    w.function("f", Some(&spec.f));
    w.function("g", Some(&spec.g));
    w.function("exact", spec.exact.as_ref());
    let b = spec.boundary;
    let sides = [b.left, b.right, b.bottom, b.top].map(|s| wire_name(&s));
    w.field("boundary", sides.join(",").as_bytes());
    w.u64("regions", spec.regions.len() as u64);
    for (r, table) in spec.regions.iter().zip(&spec.tables) {
        match &r.shape {
            Shape::Rect(rect) => w.floats("region.rect", &[rect.x0(), rect.x1(), rect.y0(), rect.y1()]),
            Shape::Polygon(polygon) => {
                let corners = polygon.corners().iter().flat_map(|p| [p.x, p.y]).collect::<Vec<_>>();
                w.floats("region.polygon", &corners);
            }
        }
        w.optional("region.k", r.k);
        w.optional("region.f", r.f);
        w.floats("region.bh", &table.iter().flatten().flatten().copied().collect::<Vec<_>>());
        w.floats("region.source", r.source.as_ref().map_or(&[][..], |s| &s[..]));
        // What a device adds is written only when given, so a spec without it keeps its id.
        if let Some(name) = &r.name {
            w.field("region.name", name.as_bytes());
        }
        if let Some(coil) = r.coil {
            w.u64("region.circuit", coil.circuit as u64);
            w.floats("region.turns", &[coil.turns]);
        }
        if r.torque_about != Point::new(0.0, 0.0) {
            w.floats("region.torque_about", &[r.torque_about.x, r.torque_about.y]);
        }
    }
    if !spec.circuits.is_empty() {
        w.u64("circuits", spec.circuits.len() as u64);
        for c in &spec.circuits {
            w.field("circuit.name", c.name.as_bytes());
            w.floats("circuit.current", &[c.current]);
        }
    }
    if let Some(unit) = spec.unit {
        w.name("unit", &unit);
    }
    if spec.geometry == Geometry::Axisymmetric {
        w.name("geometry", &spec.geometry);
    }
    if let Some(depth) = spec.depth {
        w.floats("depth", &[depth]);
    }
    let s = &spec.settings;
    w.field("method", s.method.to_string().as_bytes());
    w.name("criterion", &s.indicator);
    w.floats("growth", &[s.growth]);
    w.u64("max_vertices", s.max_vertices as u64);
    w.optional("tolerance", s.tolerance);
}

/// A value's name on the wire: how the API spells an enum's variant.
fn wire_name(value: &impl Serialize) -> String {
    match serde_json::to_value(value) {
        Ok(serde_json::Value::String(name)) => name,
        other => unreachable!("a unit variant serializes as its name, not {other:?}"),
    }
}

/// Reads a spec from its canonical encoding, checked against `limits`.
///
/// # Errors
/// [`DecodeError::Format`] when `bytes` are not the encoding of a spec of this engine;
/// [`DecodeError::Spec`] when the spec breaks `limits` or the engine's rules.
pub fn decode(bytes: &[u8], limits: &Limits) -> Result<JobSpec, DecodeError> {
    let mut r = Reader { bytes, at: 0 };
    let engine = r.text("engine")?;
    if engine != ENGINE_VERSION {
        return Err(DecodeError::Format(format!("kept by {engine}")));
    }
    let spec = if r.next_is("kind") {
        match r.text("kind")? {
            "solution" => read_solution(&mut r, limits)?,
            kind => return Err(DecodeError::Format(format!("unknown kind {kind:?}"))),
        }
    } else {
        read_mesh(&mut r, limits)?
    };
    if r.at != bytes.len() {
        return Err(DecodeError::Format(format!("{} bytes past the last field", bytes.len() - r.at)));
    }
    Ok(spec)
}

struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn malformed(&self, what: impl std::fmt::Display) -> DecodeError {
        DecodeError::Format(format!("{what} at byte {}", self.at))
    }

    fn take(&mut self, len: u64) -> Result<&'a [u8], DecodeError> {
        let len = usize::try_from(len).ok().filter(|&n| n <= self.bytes.len() - self.at);
        let len = len.ok_or_else(|| self.malformed("truncated"))?;
        let taken = &self.bytes[self.at..self.at + len];
        self.at += len;
        Ok(taken)
    }

    fn len(&mut self) -> Result<u64, DecodeError> {
        let bytes = self.take(8)?;
        Ok(u64::from_le_bytes(bytes.try_into().expect("8 bytes")))
    }

    /// The name of the next field, without reading it.
    fn next_is(&self, name: &str) -> bool {
        let mut ahead = Reader { bytes: self.bytes, at: self.at };
        ahead.len().and_then(|n| ahead.take(n)).is_ok_and(|n| n == name.as_bytes())
    }

    /// The value of field `name`, which must come next.
    fn field(&mut self, name: &str) -> Result<&'a [u8], DecodeError> {
        let n = self.len()?;
        let found = self.take(n)?;
        if found != name.as_bytes() {
            let found = String::from_utf8_lossy(found);
            return Err(self.malformed(format!("field {found:?} where {name:?} belongs")));
        }
        let n = self.len()?;
        self.take(n)
    }

    fn text(&mut self, name: &str) -> Result<&'a str, DecodeError> {
        let value = self.field(name)?;
        std::str::from_utf8(value).map_err(|_| self.malformed(format!("{name} is not UTF-8")))
    }

    fn u64(&mut self, name: &str) -> Result<u64, DecodeError> {
        let value = self.field(name)?;
        let bytes = value.try_into().map_err(|_| self.malformed(format!("{name} is not 8 bytes")))?;
        Ok(u64::from_le_bytes(bytes))
    }

    fn floats(&mut self, name: &str) -> Result<Vec<f64>, DecodeError> {
        let value = self.field(name)?;
        if value.len() % 8 != 0 {
            return Err(self.malformed(format!("{name} is not a run of 8-byte floats")));
        }
        Ok(value
            .chunks_exact(8)
            .map(|b| f64::from_bits(u64::from_le_bytes(b.try_into().expect("8"))))
            .collect())
    }

    fn exactly<const N: usize>(&mut self, name: &str) -> Result<[f64; N], DecodeError> {
        let values = self.floats(name)?;
        values.try_into().map_err(|_| self.malformed(format!("{name} is not {N} numbers")))
    }

    fn optional(&mut self, name: &str) -> Result<Option<f64>, DecodeError> {
        match *self.floats(name)? {
            [] => Ok(None),
            [v] => Ok(Some(v)),
            _ => Err(self.malformed(format!("{name} is more than one number"))),
        }
    }

    fn name<T: DeserializeOwned>(&mut self, name: &str) -> Result<T, DecodeError> {
        let text = self.text(name)?;
        from_wire_name(text).ok_or_else(|| self.malformed(format!("{name} {text:?} is unknown")))
    }

    fn parsed<T: std::str::FromStr>(&mut self, name: &str) -> Result<T, DecodeError> {
        let text = self.text(name)?;
        text.parse().map_err(|_| self.malformed(format!("{name} {text:?} is unknown")))
    }

    /// A function field of a problem, its expression held to this replica's limit.
    fn function(&mut self, name: &'static str, limits: &Limits) -> Result<Option<Function>, DecodeError> {
        let value = self.field(name)?;
        Ok(Some(match value.split_first() {
            None => return Ok(None),
            Some((0, bits)) => {
                let bits = bits.try_into().map_err(|_| self.malformed(format!("{name} is not 8 bytes")))?;
                Function::Constant(f64::from_bits(u64::from_le_bytes(bits)))
            }
            Some((1, text)) => {
                let text =
                    std::str::from_utf8(text).map_err(|_| self.malformed(format!("{name} is not UTF-8")))?;
                Function::Expression(expression(text, name, limits)?)
            }
            Some((tag, _)) => return Err(self.malformed(format!("{name} has unknown tag {tag}"))),
        }))
    }

    /// A function field that a problem always has.
    fn given(&mut self, name: &'static str, limits: &Limits) -> Result<Function, DecodeError> {
        self.function(name, limits)?.ok_or_else(|| self.malformed(format!("{name} is empty")))
    }
}

fn from_wire_name<T: DeserializeOwned>(name: &str) -> Option<T> {
    serde_json::from_value(serde_json::Value::String(name.to_owned())).ok()
}

fn read_mesh(r: &mut Reader<'_>, limits: &Limits) -> Result<JobSpec, DecodeError> {
    let source = if r.next_is("function") {
        Source::Expression(expression(r.text("function")?, "function", limits)?)
    } else {
        let (nx, ny) = (r.u64("grid.nx")?, r.u64("grid.ny")?);
        let allowed = limits.max_grid_points;
        let requested = nx.saturating_mul(ny);
        if requested > allowed as u64 {
            return Err(grid_error(GridFileError::TooManyPoints { nx, ny, requested, allowed }).into());
        }
        let values = r.floats("grid.values")?;
        let grid = Grid::new(nx as usize, ny as usize, values).map_err(|e| {
            let index = match e {
                GridError::NonFinite { i, j, .. } => Some([i, j]),
                _ => None,
            };
            SpecError::Grid { detail: e.to_string(), index }
        })?;
        Source::Grid(grid)
    };
    let [a] = r.exactly("domain.a")?;
    let [b] = r.exactly("domain.b")?;
    let [c] = r.exactly("domain.c")?;
    let [d] = r.exactly("domain.d")?;
    let domain = Rect::new(a, b, c, d).map_err(domain_error)?;
    let method = r.parsed("method")?;
    let criterion = r.parsed("criterion")?;
    let quality = match r.field("quality")? {
        [0] => false,
        [1] => true,
        _ => return Err(r.malformed("quality is not 0 or 1")),
    };
    let min_angle = r.optional("min_angle")?;
    let sizes = match criterion {
        Criterion::Curvature => [r.optional("min_size")?, r.optional("max_size")?],
        _ => [None, None],
    };
    let max_vertices = Some(r.u64("max_vertices")?);
    let tolerance = r.optional("tolerance")?;
    let requested_time_limit = time_limit(r)?;
    let knobs =
        Knobs { max_vertices, method, criterion, tolerance, min_angle, sizes, quality, requested_time_limit };
    Ok(JobSpec::mesh_from(source.with_domain(domain), domain, knobs, limits)?)
}

fn time_limit(r: &mut Reader<'_>) -> Result<Option<Duration>, DecodeError> {
    let value = r.field("time_limit_ms")?;
    match value.try_into() {
        Ok(bytes) => Ok(Some(Duration::from_millis(u64::from_le_bytes(bytes)))),
        Err(_) if value.is_empty() => Ok(None),
        Err(_) => Err(r.malformed("time_limit_ms is not 8 bytes")),
    }
}

fn read_solution(r: &mut Reader<'_>, limits: &Limits) -> Result<JobSpec, DecodeError> {
    let physics = r.name("physics")?;
    let [a, b, c, d] = r.exactly("domain")?;
    let domain = Rect::new(a, b, c, d).map_err(domain_error)?;
    let (k, f, g) = (r.given("k", limits)?, r.given("f", limits)?, r.given("g", limits)?);
    let exact = r.function("exact", limits)?;
    let sides = r.text("boundary")?.split(',').map(from_wire_name).collect::<Option<Vec<_>>>();
    let Some([left, right, bottom, top]) = sides.and_then(|s| <[_; 4]>::try_from(s).ok()) else {
        return Err(r.malformed("boundary is not four sides"));
    };
    let boundary = Boundary { left, right, bottom, top };
    let count = r.u64("regions")?;
    if count > MAX_REGIONS as u64 {
        return Err(r.malformed(format!("{count} regions, more than {MAX_REGIONS}")));
    }
    let (mut regions, mut tables, mut corners) = (Vec::new(), Vec::new(), 0);
    for i in 0..count as usize {
        let (region, table) = read_region(r, i, domain, &mut corners)?;
        regions.push(region);
        tables.push(table);
    }
    let mut circuits = Vec::new();
    if r.next_is("circuits") {
        let count = r.u64("circuits")?;
        if count > MAX_REGIONS as u64 {
            return Err(r.malformed(format!("{count} circuits, more than the regions may name")));
        }
        for _ in 0..count {
            let name = r.text("circuit.name")?.to_owned();
            let [current] = r.exactly("circuit.current")?;
            if !current.is_finite() {
                return Err(r.malformed(format!("circuit {name}'s current is not finite")));
            }
            circuits.push(Circuit { name, current });
        }
    }
    if let Some(i) = regions.iter().position(|g| g.coil.is_some_and(|c| c.circuit >= circuits.len())) {
        return Err(r.malformed(format!("region {i} names a circuit past the {} given", circuits.len())));
    }
    let unit = if r.next_is("unit") { Some(r.name("unit")?) } else { None };
    let geometry = if r.next_is("geometry") { r.name("geometry")? } else { Geometry::Planar };
    if geometry == Geometry::Axisymmetric && domain.x0() < 0.0 {
        return Err(r.malformed("an axisymmetric domain crosses the axis"));
    }
    let depth = if r.next_is("depth") {
        let [depth] = r.exactly("depth")?;
        if !(depth.is_finite() && depth > 0.0) {
            return Err(r.malformed("depth is not finite and positive"));
        }
        Some(depth)
    } else {
        None
    };
    let method = r.parsed("method")?;
    let indicator = r.name("criterion")?;
    let [growth] = r.exactly("growth")?;
    let max_vertices = Some(r.u64("max_vertices")?);
    let tolerance = r.optional("tolerance")?;
    let requested_time_limit = time_limit(r)?;
    let steering = Steering { max_vertices, tolerance, method, indicator, growth, requested_time_limit };
    let settings = steering.settings(limits)?;
    let spec = SolveSpec {
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
    Ok(JobSpec { work: Work::Solve(Arc::new(spec)), requested_time_limit })
}

/// Region `i` and its B–H table, through the domain types' own checks.
fn read_region(
    r: &mut Reader<'_>,
    i: usize,
    domain: Rect,
    corners: &mut usize,
) -> Result<(Region, Option<BhTable>), DecodeError> {
    let invalid = |detail: String| SpecError::Problem { field: format!("regions[{i}]"), detail };
    let shape = if r.next_is("region.rect") {
        *corners += 4;
        let [x0, x1, y0, y1] = r.exactly("region.rect")?;
        Shape::Rect(Rect::new(x0, x1, y0, y1).map_err(|e| invalid(e.to_string()))?)
    } else {
        let xy = r.floats("region.polygon")?;
        *corners += xy.len() / 2;
        if *corners > MAX_CORNERS || xy.len() % 2 != 0 {
            return Err(r.malformed(format!("region {i}'s corners are odd or past {MAX_CORNERS}")));
        }
        let points = xy.chunks_exact(2).map(|p| Point::new(p[0], p[1])).collect();
        Shape::polygon(points, domain).map_err(|e| invalid(e.to_string()))?
    };
    let mut region = Region::try_new(shape, domain).map_err(|e| invalid(e.to_string()))?;
    region.k = r.optional("region.k")?;
    region.f = r.optional("region.f")?;
    let bh = r.floats("region.bh")?;
    let table = match bh.as_slice() {
        [] => None,
        _ if bh.len() % 2 != 0 => return Err(r.malformed(format!("region {i}'s B–H table is odd"))),
        _ => {
            let table: BhTable = bh.chunks_exact(2).map(|p| [p[0], p[1]]).collect();
            region.curve = Some(Arc::new(BhCurve::new(&table).map_err(|e| invalid(e.to_string()))?));
            Some(table)
        }
    };
    region.source = match *r.floats("region.source")? {
        [] => None,
        [x, y] => Some([x, y]),
        _ => return Err(r.malformed(format!("region {i}'s source is not two numbers"))),
    };
    if r.next_is("region.name") {
        region.name = Some(r.text("region.name")?.to_owned());
    }
    if r.next_is("region.circuit") {
        let circuit = r.u64("region.circuit")? as usize;
        let [turns] = r.exactly("region.turns")?;
        if !(turns.is_finite() && turns != 0.0) {
            return Err(r.malformed(format!("region {i}'s turns are not finite and nonzero")));
        }
        region.coil = Some(Coil { circuit, turns });
    }
    if r.next_is("region.torque_about") {
        let [x, y] = r.exactly("region.torque_about")?;
        if !(x.is_finite() && y.is_finite()) {
            return Err(r.malformed(format!("region {i}'s torque point is not finite")));
        }
        region.torque_about = Point::new(x, y);
    }
    let finite = region.f.iter().chain(region.source.iter().flatten()).all(|v| v.is_finite());
    if !finite || region.k.is_some_and(|k| !(k.is_finite() && k > 0.0)) {
        return Err(invalid("k must be finite and > 0, f and the source finite".into()).into());
    }
    Ok((region, table))
}

#[cfg(test)]
mod tests;
