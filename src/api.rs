//! Wire types of the HTTP API (serde only). Field docs here are the ones in openapi.yaml.

use crate::refine::{Criterion, Method};
use crate::result::{Geometry, Summary, Unit};
use crate::solve::{Indicator, Physics, Side};
use crate::source::{Encoding, RawType};
use serde::de::{self, Deserializer, Visitor};
use serde::{Deserialize, Serialize};
use serde_json::value::RawValue;
use std::collections::BTreeMap;
use std::fmt::{self, Write};

/// The body of `POST /v1/meshes` and `POST /v1/jobs`. Unknown fields are rejected, so a typo
/// never falls back to a default silently. A grid's values stay unparsed text borrowed from
/// the body until the spec decodes them against the server's limits.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JobRequest<'a> {
    /// F as a meval expression in x and y. Exactly one of `function` and `grid`.
    pub function: Option<String>,
    /// F sampled on a grid. Exactly one of `function` and `grid`.
    #[serde(borrow)]
    pub grid: Option<GridInput<'a>>,
    /// The rectangle; default \[0,1\]² for a function, \[0,nx−1\]×\[0,ny−1\] for a grid.
    pub domain: Option<DomainInput>,
    /// The vertex budget n (default 10000, at least 4).
    #[serde(default, deserialize_with = "optional_count")]
    pub max_vertices: Option<u64>,
    /// Stop when the worst criterion value is at most this: the largest sampled triangle error
    /// for `error`, the largest |zi − zj| over edges for `variation`.
    pub tolerance: Option<f64>,
    /// `semi-recursive` (default) or `recursive`.
    pub method: Option<Method>,
    /// `error` (default), `variation` (the paper's) or `curvature` (one evaluation a vertex,
    /// ranked by the interpolation error its gradients predict).
    pub criterion: Option<Criterion>,
    /// Criterion `error` only: repair every triangle whose smallest angle is below this many
    /// degrees (above 0, at most 30) before any error-driven split; `stats.below_min_angle`
    /// counts those a size floor, the budget or the tolerance left.
    pub min_angle: Option<f64>,
    /// Criterion `curvature` only: no edge shorter than twice this is split (a length in the
    /// domain's units).
    pub min_size: Option<f64>,
    /// Criterion `curvature` only: every edge longer than this is split first.
    pub max_size: Option<f64>,
    /// Stop after this many milliseconds; capped by the server's job time limit.
    #[serde(default, deserialize_with = "optional_count")]
    pub time_limit_ms: Option<u64>,
    /// Also measure the final mesh against F (`stats.quality`: the E_n estimate, the RMS
    /// error, the smallest angle); about 24 more evaluations of F per vertex. Default false.
    pub quality: Option<bool>,
}

/// A count: a non-negative integer. JSON has one number type, so `1000.0` and `1e3` are the
/// count 1000; `1.5` and `-1` are errors.
fn count<'de, D: Deserializer<'de>>(d: D) -> Result<u64, D::Error> {
    struct V;
    impl Visitor<'_> for V {
        type Value = u64;
        fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            f.write_str("a non-negative integer")
        }
        fn visit_u64<E>(self, v: u64) -> Result<u64, E> {
            Ok(v)
        }
        fn visit_i64<E: de::Error>(self, v: i64) -> Result<u64, E> {
            u64::try_from(v).map_err(|_| E::invalid_value(de::Unexpected::Signed(v), &self))
        }
        fn visit_f64<E: de::Error>(self, v: f64) -> Result<u64, E> {
            whole(v).ok_or_else(|| E::invalid_value(de::Unexpected::Float(v), &self))
        }
    }
    d.deserialize_any(V)
}

/// `v` as a count, when it is a whole number from 0 below 2^64.
fn whole(v: f64) -> Option<u64> {
    // 2^64 is the first float above u64::MAX; every float below it with no fraction is an
    // exact count.
    (v.fract() == 0.0 && (0.0..18_446_744_073_709_551_616.0).contains(&v)).then_some(v as u64)
}

/// A count written as text (a command-line flag) read as a request's JSON number is: `10000`,
/// `1e4` and `10000.0` are 10000; `1.5`, `-1` and words are not counts.
///
/// ```
/// assert_eq!(meshfit::api::parse_count("1e4"), Some(10_000));
/// assert_eq!(meshfit::api::parse_count("2.5"), None);
/// ```
pub fn parse_count(text: &str) -> Option<u64> {
    let text = text.trim();
    text.parse::<u64>().ok().or_else(|| text.parse::<f64>().ok().and_then(whole))
}

/// An optional [`count`]; `null` is no count, as for any optional field.
fn optional_count<'de, D: Deserializer<'de>>(d: D) -> Result<Option<u64>, D::Error> {
    struct Count(u64);
    impl<'de> Deserialize<'de> for Count {
        fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
            count(d).map(Count)
        }
    }
    Ok(Option::<Count>::deserialize(d)?.map(|c| c.0))
}

/// A sampled grid: `values[j*nx + i] = F(x_i, y_j)`. Sent with a grid file (multipart), it
/// holds only what the file cannot say: `nx`, `ny` and `dtype` of raw samples, and the
/// `encoding` of a colour PNG elevation tile.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GridInput<'a> {
    /// Nodes along x (at least 2).
    #[serde(default, deserialize_with = "optional_count")]
    pub nx: Option<u64>,
    /// Nodes along y (at least 2).
    #[serde(default, deserialize_with = "optional_count")]
    pub ny: Option<u64>,
    /// nx·ny numbers, row-major with x fastest, as JSON text; absent when a file carries them.
    #[serde(borrow)]
    pub values: Option<&'a RawValue>,
    /// The sample type of a raw grid file: `f32` or `f64`, little-endian.
    pub dtype: Option<RawType>,
    /// How a colour PNG tile encodes heights: `terrain-rgb` or `terrarium`.
    pub encoding: Option<Encoding>,
}

/// `{"x": [a, b], "y": [c, d]}`.
#[derive(Debug, Clone)]
pub struct DomainInput {
    /// [a, b] with a < b (a list, so a wrong length gets a clear message, not serde's).
    pub x: Vec<f64>,
    /// [c, d] with c < d.
    pub y: Vec<f64>,
}

impl<'de> Deserialize<'de> for DomainInput {
    /// The object; a list (`[a, b, c, d]` or `[[a, b], [c, d]]`, the usual slips) is refused
    /// with the object to write instead.
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct Object {
            x: Vec<f64>,
            y: Vec<f64>,
        }
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = DomainInput;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str(r#"an object {"x": [a, b], "y": [c, d]}"#)
            }
            fn visit_map<A: de::MapAccess<'de>>(self, map: A) -> Result<DomainInput, A::Error> {
                let Object { x, y } = Object::deserialize(de::value::MapAccessDeserializer::new(map))?;
                Ok(DomainInput { x, y })
            }
            fn visit_seq<A: de::SeqAccess<'de>>(self, mut seq: A) -> Result<DomainInput, A::Error> {
                let mut items = Vec::new();
                while let Some(item) = seq.next_element::<serde_json::Value>()? {
                    items.push(item);
                }
                let write = match items.as_slice() {
                    [a, b, c, d] => format!(r#"{{"x": [{a}, {b}], "y": [{c}, {d}]}}"#),
                    [x, y] => format!(r#"{{"x": {x}, "y": {y}}}"#),
                    _ => r#"{"x": [a, b], "y": [c, d]}"#.to_owned(),
                };
                Err(de::Error::custom(format!("the domain is an object, not a list: write {write}")))
            }
        }
        d.deserialize_any(V)
    }
}

/// `GET /v1/jobs/{id}` and the body of `POST /v1/jobs`.
#[derive(Debug, Clone, Serialize)]
pub struct JobStatus {
    /// The job id: the hex SHA-256 of the canonical request.
    pub id: String,
    /// `queued`, `running`, `succeeded`, `failed` or `cancelled`.
    pub status: &'static str,
    /// The latest progress report, once running.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub progress: Option<ProgressEvent>,
    /// The run's stats, once succeeded: a result's report ([`Summary`]), the
    /// same the mesh document carries, never the engine's working counters.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stats: Option<Summary>,
    /// How long the engine ran, in milliseconds, once finished (not part of the mesh: it is
    /// the one thing that differs between two runs of a request).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub elapsed_ms: Option<f64>,
    /// When the job was made here (RFC 3339, UTC); in a job list, when the client last
    /// submitted it. Absent for a result found in the cache alone.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub created_at: Option<String>,
    /// When a worker took it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub started_at: Option<String>,
    /// When it ended.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub finished_at: Option<String>,
    /// The problem document, once failed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub problem: Option<serde_json::Value>,
    /// A client job's evaluations.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub evaluations: Option<Evaluations>,
    /// Where to find the job's resources.
    pub links: Links,
}

/// A time as the API writes it: RFC 3339 in UTC, to the millisecond.
pub fn timestamp(at: std::time::SystemTime) -> String {
    humantime::format_rfc3339_millis(at).to_string()
}

/// `POST /v1/jobs` with `"source": "client"`: a refinement of an F the caller evaluates,
/// a batch of points at a time (`GET /v1/jobs/{id}/ask`, `POST /v1/jobs/{id}/tell`).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClientJobRequest {
    /// `client`.
    pub source: ClientSource,
    /// The rectangle (default the unit square).
    pub domain: Option<DomainInput>,
    /// The vertex budget (default 10000, at least 4).
    #[serde(default, deserialize_with = "optional_count")]
    pub max_vertices: Option<u64>,
    /// Stop once the worst criterion value is at most this: the largest midpoint error the
    /// gradients predict for `curvature`, the largest |zi − zj| for `variation`.
    pub tolerance: Option<f64>,
    /// `semi-recursive` (default) or `recursive`.
    pub method: Option<Method>,
    /// `curvature` (the default) or `variation`: the criteria that need F at the vertices
    /// alone.
    pub criterion: Option<Criterion>,
    /// Criterion `curvature`: no edge shorter than twice this is split.
    pub min_size: Option<f64>,
    /// Criterion `curvature`: every edge longer than this is split first.
    pub max_size: Option<f64>,
    /// The most points one batch asks for (default 16, at most 1024).
    #[serde(default, deserialize_with = "optional_count")]
    pub batch: Option<u64>,
    /// How long a batch handed out waits for its values before it is offered again, in ms
    /// (default 60000).
    #[serde(default, deserialize_with = "optional_count")]
    pub lease_ms: Option<u64>,
    /// A client job of the same F whose values this one starts from: what it was told is not
    /// asked again, so a smaller budget finishes without asking, a larger one asks only for
    /// the points that job did not.
    pub from: Option<String>,
    /// What a failed point (a `null` value) does: `guess` (the default) keeps the
    /// criterion's guess there and goes on; `fail` fails the job.
    pub on_failure: Option<OnFailure>,
}

/// What a client job does with a point whose evaluation failed.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OnFailure {
    /// The point keeps the criterion's guess, and the refinement goes on.
    #[default]
    Guess,
    /// The job fails, naming the point.
    Fail,
}

/// Where a job's F comes from: the caller.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ClientSource {
    /// The caller evaluates F at the points it is asked for.
    Client,
}

/// A point a client job asks for.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AskedPoint {
    /// Its id, to tell its value by.
    pub id: u64,
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
}

/// The answer to `GET /v1/jobs/{id}/ask`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AskAnswer {
    /// The job's status (`running` while it asks).
    pub status: &'static str,
    /// The batch's number, from 1, when there are points.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub batch: Option<u64>,
    /// The points to evaluate: empty once the job has finished.
    pub points: Vec<AskedPoint>,
    /// How long the caller has to tell their values before they are offered again.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lease_ms: Option<u64>,
}

/// The body of `POST /v1/jobs/{id}/tell`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TellRequest {
    /// F at points asked, by id.
    pub values: Vec<TellValue>,
}

/// F at one point asked: a number, or null where F could not be had.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TellValue {
    /// The point's id.
    pub id: u64,
    /// F there, or null for a failed evaluation: present either way.
    #[serde(deserialize_with = "nullable")]
    pub value: Option<f64>,
    /// Why it failed (kept for the caller's logs, not for the mesh).
    pub reason: Option<String>,
}

/// A number or null, the field required: serde reads a missing `Option` as `None` unless a
/// field has its own `deserialize_with`.
fn nullable<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
    Option::<f64>::deserialize(d)
}

/// How many points a client job asked for, was told, waits for and saw fail.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Evaluations {
    /// Points asked for.
    pub asked: u64,
    /// Points told (a failure included).
    pub told: u64,
    /// Points of the current batch not yet told.
    pub pending: u64,
    /// Points told as failed.
    pub failed: u64,
}

/// The answer to `POST /v1/jobs/{id}/tell`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TellAnswer {
    /// The job's status after the values.
    pub status: &'static str,
    /// Values that were new (a repeat of a value told is not).
    pub accepted: u64,
    /// The job's counts.
    pub evaluations: Evaluations,
    /// With `?ask=ms`: what `GET /v1/jobs/{id}/ask?wait=ms` would answer next (`None` when
    /// nothing came within the wait), so that a caller plays one request a batch.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub next: Option<AskAnswer>,
}

/// The `result` event that ends a stream: the job's status document (its stats, times and
/// links) and the address of its mesh in each format — not the mesh, which a client fetches
/// once in the format it wants (or asks inline with `?inline=mesh`).
#[derive(Debug, Clone, Serialize)]
pub struct ResultEvent {
    /// The job as `GET /v1/jobs/{id}` shows it.
    #[serde(flatten)]
    pub status: JobStatus,
    /// `/v1/jobs/{id}/mesh?format=…` by format name.
    pub formats: std::collections::BTreeMap<&'static str, String>,
}

impl ResultEvent {
    /// The event of a finished job with this status, linking its mesh in `formats` (names).
    pub fn of(status: JobStatus, formats: impl IntoIterator<Item = &'static str>) -> Self {
        let formats = formats.into_iter().map(|f| (f, format!("{}?format={f}", status.links.mesh))).collect();
        Self { status, formats }
    }
}

/// `GET /v1/jobs`: a page of the jobs submitted, newest first.
#[derive(Debug, Clone, Serialize)]
pub struct JobList {
    /// The jobs, each as `GET /v1/jobs/{id}` shows it.
    pub jobs: Vec<JobStatus>,
    /// The next page's address, when older jobs are left.
    pub next: Option<String>,
}

/// Links of a job.
#[derive(Debug, Clone, Serialize)]
pub struct Links {
    /// `/v1/jobs/{id}`.
    #[serde(rename = "self")]
    pub this: String,
    /// `/v1/jobs/{id}/events` (not for a client job, which streams nothing yet).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub events: Option<String>,
    /// `/v1/jobs/{id}/mesh`.
    pub mesh: String,
    /// A client job's `/v1/jobs/{id}/ask`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ask: Option<String>,
    /// A client job's `/v1/jobs/{id}/tell`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tell: Option<String>,
}

impl Links {
    /// The links of job `id`.
    pub fn of(id: &str) -> Self {
        Self {
            this: format!("/v1/jobs/{id}"),
            events: Some(format!("/v1/jobs/{id}/events")),
            mesh: format!("/v1/jobs/{id}/mesh"),
            ask: None,
            tell: None,
        }
    }

    /// The links of client job `id`: any job's, and its ask and tell.
    pub fn of_client(id: &str) -> Self {
        Self {
            ask: Some(format!("/v1/jobs/{id}/ask")),
            tell: Some(format!("/v1/jobs/{id}/tell")),
            ..Self::of(id)
        }
    }
}

/// `GET /v1/datasets/{id}`, and the body of `POST /v1/datasets`: a DEM that terrain tiles
/// are served from.
#[derive(Debug, Clone, Serialize)]
pub struct DatasetInfo {
    /// The hex SHA-256 of the uploaded file, or the name the server's settings give a file.
    pub id: String,
    /// `upload` (deleted with `DELETE`) or `file` (named in the server's settings).
    pub source: &'static str,
    /// The size of the file, in bytes.
    pub file_bytes: u64,
    /// Samples per row and rows.
    pub size: [usize; 2],
    /// The coordinate system of the samples: `EPSG:4326`.
    pub crs: &'static str,
    /// West, south, east and north, in degrees: the outer samples' positions.
    pub bounds: [f64; 4],
    /// The finer sample spacing, in degrees.
    pub pixel_degrees: f64,
    /// The lowest and highest height, in metres (filled samples included).
    pub heights: [f64; 2],
    /// Samples that were the file's nodata value (`GDAL_NODATA`), each filled from its
    /// neighbours for meshing; a tile that holds no other sample is not available.
    pub nodata_filled: u64,
    /// The deepest level tiles are made at: where a tile's 65 samples a side reach the pixel.
    pub max_zoom: u8,
    /// Each tile of level z keeps within this times 77,067.34 m / 2^z of the DEM.
    pub error_factor: f64,
    /// In the answer to an upload, with replicas: whether the file was kept in the store, so
    /// that every replica serves it (false when larger than `MESHFIT_REDIS_MAX_BYTES`, or
    /// when Redis did not answer: then only the replica it was sent to does).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shared: Option<bool>,
    /// Where to find its resources.
    pub links: DatasetLinks,
}

/// Links of a dataset.
#[derive(Debug, Clone, Serialize)]
pub struct DatasetLinks {
    /// `/v1/datasets/{id}`.
    #[serde(rename = "self")]
    pub this: String,
    /// `/v1/tiles/{id}/layer.json`: what a terrain provider is pointed at.
    pub layer: String,
    /// `/v1/tiles/{id}/{z}/{x}/{y}.terrain`, a template.
    pub tiles: String,
}

impl DatasetLinks {
    /// The links of dataset `id`.
    pub fn of(id: &str) -> Self {
        Self {
            this: format!("/v1/datasets/{id}"),
            layer: format!("/v1/tiles/{id}/layer.json"),
            tiles: format!("/v1/tiles/{id}/{{z}}/{{x}}/{{y}}.terrain"),
        }
    }
}

/// `GET /v1/datasets`.
#[derive(Debug, Clone, Serialize)]
pub struct DatasetList {
    /// Every dataset, by id.
    pub datasets: Vec<DatasetInfo>,
}

/// A `progress` server-sent event.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ProgressEvent {
    /// Vertices so far.
    pub vertices: usize,
    /// Triangles so far.
    pub triangles: usize,
    /// The current worst criterion value: the largest e(T) for error, V_n for variation; for a
    /// solution, the estimate after the latest solve. It may rise between events (a split
    /// measures its new triangles afresh, a solve changes every value): `fraction` is what
    /// never falls.
    pub worst: f64,
    /// Milliseconds since the job started running.
    pub elapsed_ms: f64,
    /// Where the job stops: the first of its targets it reaches.
    #[serde(default)]
    pub target: Target,
    /// How far the job is toward its nearest target, in [0, 1], never falling from one event
    /// to the next: the largest of vertices / `max_vertices`, the error's way down to
    /// `tolerance` on a log scale (from the first event's `worst`), and the time over
    /// `time_limit_ms`.
    #[serde(default)]
    pub fraction: f64,
    /// A nonlinear solution's Newton steps in its latest solve.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub newton_iterations: Option<u32>,
    /// Newton's final relative residual in that solve.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub newton_residual: Option<f64>,
}

/// The targets a job stops at, the first it reaches.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Target {
    /// The vertex budget.
    pub max_vertices: usize,
    /// The worst criterion value to reach, when asked for.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub tolerance: Option<f64>,
    /// The time limit in force (the request's, or the server's).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub time_limit_ms: Option<u64>,
}

impl Target {
    /// How far `worst` at `elapsed_ms` with `vertices` is toward the nearest target, in
    /// [0, 1]: the error's progress measured on a log scale from `first_worst`.
    pub fn fraction(&self, vertices: usize, worst: f64, elapsed_ms: f64, first_worst: f64) -> f64 {
        let by_vertices = vertices as f64 / self.max_vertices.max(1) as f64;
        let by_error = self.tolerance.map_or(0.0, |tolerance| {
            if worst <= tolerance {
                1.0
            } else if first_worst > tolerance && tolerance > 0.0 {
                (first_worst / worst).ln() / (first_worst / tolerance).ln()
            } else {
                0.0
            }
        });
        let by_time = self.time_limit_ms.map_or(0.0, |limit| elapsed_ms / limit.max(1) as f64);
        let fraction = by_vertices.max(by_error).max(by_time);
        if fraction.is_nan() { 0.0 } else { fraction.clamp(0.0, 1.0) }
    }
}

/// The body of `POST /v1/solutions` (and of `POST /v1/jobs` when it names `physics`): the
/// boundary value problem −∇·(k ∇u) = f in the rectangle, u = g on its boundary.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SolveRequest {
    /// The rectangle; default \[0,1\]².
    pub domain: Option<DomainInput>,
    /// `poisson` (default) or `magnetostatic` (u is A_z; regions give `mu_r` and
    /// `current_density`).
    pub physics: Option<Physics>,
    /// The coefficient k > 0: a number or an expression in x and y (default 1; poisson only).
    pub k: Option<Coefficient>,
    /// The load f (default 0; poisson only).
    pub f: Option<Coefficient>,
    /// The boundary values g (default 0) on the Dirichlet sides; A there for magnetostatics.
    pub g: Option<Coefficient>,
    /// The unit of every length in the request and the answer: `m` (default), `cm` or `mm`
    /// (magnetostatic). Field values stay SI.
    pub unit: Option<Unit>,
    /// A planar device's depth, in `unit`: forces, torques, energies and inductances are then
    /// totals rather than per metre (magnetostatic).
    pub depth: Option<f64>,
    /// Materials by name, for regions' `material` (magnetostatic); a name not here is looked
    /// up in the built-in library (`GET /v1/materials`).
    #[serde(default)]
    pub materials: BTreeMap<String, MaterialInput>,
    /// Circuits by name, each a current through coil regions in series (magnetostatic).
    #[serde(default)]
    pub circuits: BTreeMap<String, CircuitInput>,
    /// Each side's condition: `dirichlet` (u = g, the default), `neumann` (zero normal flux),
    /// `periodic`, `antiperiodic` or `open` (magnetostatic); one name for every side, or an
    /// object by side.
    pub boundary: Option<BoundaryField>,
    /// `planar` (default) or `axisymmetric`: x is r ≥ 0 and y is z, u is A_φ (magnetostatic).
    pub geometry: Option<Geometry>,
    /// Rectangles and polygons inside the domain, later entries winning, that override k and
    /// f (or the material and current).
    #[serde(default)]
    pub regions: Vec<RegionInput>,
    /// The exact solution, to measure the errors against.
    pub exact: Option<Coefficient>,
    /// The vertex budget (default 10000, at least 4).
    #[serde(default, deserialize_with = "optional_count")]
    pub max_vertices: Option<u64>,
    /// Stop once the estimate is at most this.
    pub tolerance: Option<f64>,
    /// `semi-recursive` (default) or `recursive`.
    pub method: Option<Method>,
    /// `residual` (default) or `variation` (the paper's).
    pub criterion: Option<Indicator>,
    /// The factor each round grows the vertex count by (default 1.5, in (1, 4]).
    pub growth: Option<f64>,
    /// Stop after this many milliseconds; capped by the server's job time limit.
    #[serde(default, deserialize_with = "optional_count")]
    pub time_limit_ms: Option<u64>,
}

/// A number, or a meval expression in x and y.
#[derive(Debug, Clone, PartialEq)]
pub enum Coefficient {
    /// A constant.
    Number(f64),
    /// An expression.
    Expression(String),
}

impl<'de> Deserialize<'de> for Coefficient {
    /// By hand rather than `untagged`, whose error names neither what was sent nor what fits.
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl Visitor<'_> for V {
            type Value = Coefficient;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a number or an expression in x and y (a string)")
            }
            fn visit_f64<E>(self, v: f64) -> Result<Coefficient, E> {
                Ok(Coefficient::Number(v))
            }
            fn visit_i64<E>(self, v: i64) -> Result<Coefficient, E> {
                Ok(Coefficient::Number(v as f64))
            }
            fn visit_u64<E>(self, v: u64) -> Result<Coefficient, E> {
                Ok(Coefficient::Number(v as f64))
            }
            fn visit_str<E>(self, v: &str) -> Result<Coefficient, E> {
                Ok(Coefficient::Expression(v.to_owned()))
            }
        }
        d.deserialize_any(V)
    }
}

/// A region of a boundary value problem: a rectangle (`x`, `y`) or a simple polygon
/// (`polygon`), with constant values. The mesh follows its sides.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegionInput {
    /// [x0, x1], with `y`.
    pub x: Option<Vec<f64>>,
    /// [y0, y1], with `x`.
    pub y: Option<Vec<f64>>,
    /// A simple polygon's corners [[x, y], …], either orientation, instead of `x` and `y`;
    /// an arc (`{"arc": degrees}`) between two corners makes that side a circular arc.
    pub polygon: Option<Vec<PolygonEntry>>,
    /// k inside (poisson).
    pub k: Option<f64>,
    /// f inside (poisson).
    pub f: Option<f64>,
    /// Relative permeability inside (magnetostatic; default 1).
    pub mu_r: Option<f64>,
    /// A B–H curve [[H in A/m, B in T], …] from [0, 0], both strictly increasing, instead of
    /// `mu_r` (magnetostatic).
    pub bh: Option<Vec<[f64; 2]>>,
    /// A permanent magnet's magnetization [Mx, My] in A/m: B = μ0 (μr H + M) (magnetostatic).
    pub magnetization: Option<[f64; 2]>,
    /// Current density J_z inside, in A/m² (magnetostatic; default 0).
    pub current_density: Option<f64>,
    /// The current through the region in A, spread evenly over its area, instead of
    /// `current_density` (magnetostatic).
    pub current: Option<f64>,
    /// The name its figures carry in the answer.
    pub name: Option<String>,
    /// A material by name, from `materials` or the built-in library, instead of `mu_r`, `bh`
    /// and `magnetization` (magnetostatic).
    pub material: Option<String>,
    /// A magnet's direction of magnetization in degrees counter-clockwise from +x (default
    /// the material's, else 0).
    pub angle: Option<f64>,
    /// The turns of a coil side (default 1 when it names a `circuit`).
    pub turns: Option<f64>,
    /// The circuit whose current its turns carry: a key of `circuits`.
    pub circuit: Option<String>,
    /// +1 (the default) where the turns carry the current out of the plane, −1 into it.
    pub direction: Option<i8>,
    /// The point its torque is taken about, [x, y] (default the origin).
    pub torque_about: Option<[f64; 2]>,
}

/// One entry of a region's `polygon`: a corner [x, y], or an arc that bends the side from
/// the corner before it to the corner after it (the first after the last).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PolygonEntry {
    /// A corner.
    Corner([f64; 2]),
    /// A circular arc between its neighbours.
    Arc(ArcInput),
}

impl PolygonEntry {
    /// The corner, when the entry is one.
    pub fn corner(&self) -> Option<[f64; 2]> {
        match *self {
            Self::Corner(p) => Some(p),
            Self::Arc(_) => None,
        }
    }
}

impl<'de> Deserialize<'de> for PolygonEntry {
    /// By hand rather than `untagged`, so that a fault inside an arc is named by its path.
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = PolygonEntry;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a corner [x, y] or an arc {\"arc\": degrees}")
            }
            fn visit_seq<S: de::SeqAccess<'de>>(self, seq: S) -> Result<PolygonEntry, S::Error> {
                <[f64; 2]>::deserialize(de::value::SeqAccessDeserializer::new(seq)).map(PolygonEntry::Corner)
            }
            fn visit_map<M: de::MapAccess<'de>>(self, map: M) -> Result<PolygonEntry, M::Error> {
                ArcInput::deserialize(de::value::MapAccessDeserializer::new(map)).map(PolygonEntry::Arc)
            }
        }
        d.deserialize_any(V)
    }
}

/// A polygon side bent into a circular arc, drawn as straight segments.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArcInput {
    /// The angle it sweeps about its centre in degrees, 0 < |arc| < 360: counter-clockwise
    /// from the corner before to the corner after when positive, clockwise when negative.
    pub arc: f64,
    /// The most degrees one of its straight segments may sweep (default 5, at most 90).
    pub max_segment_angle: Option<f64>,
}

/// A material's law, as a request's `materials` names it: linear (`mu_r`), a B–H table
/// (`bh`), or a magnet (two of `br`, `hc`, `mu_r`).
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialInput {
    /// Relative permeability (a magnet's recoil permeability).
    pub mu_r: Option<f64>,
    /// A B–H curve [[H in A/m, B in T], …] from [0, 0], both strictly increasing.
    pub bh: Option<Vec<[f64; 2]>>,
    /// A magnet's remanence in T.
    pub br: Option<f64>,
    /// A magnet's coercivity H_cB in A/m.
    pub hc: Option<f64>,
    /// A magnet's direction in degrees counter-clockwise from +x (default 0; a region's
    /// `angle` overrides it).
    pub angle: Option<f64>,
    /// Electrical conductivity in S/m (kept for eddy currents; magnetostatics ignores it).
    pub conductivity: Option<f64>,
}

/// A circuit: its current flows through every turn of the coil regions that name it.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CircuitInput {
    /// The current in A.
    pub current: f64,
}

/// The condition on each side of the domain; a side left out is `dirichlet`. On the wire an
/// object by side, or one name for every side (`"boundary": "open"`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoundaryInput {
    /// x = a.
    pub left: Option<Side>,
    /// x = b.
    pub right: Option<Side>,
    /// y = c.
    pub bottom: Option<Side>,
    /// y = d.
    pub top: Option<Side>,
    /// Whether the request named one condition for every side.
    #[serde(skip)]
    pub every_side: bool,
}

/// The request's `boundary`: one side's name for all four, or an object by side.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct BoundaryField(pub BoundaryInput);

impl<'de> Deserialize<'de> for BoundaryField {
    /// By hand rather than `untagged`, so that a bad side inside the object is still named
    /// by its path (`boundary.left`).
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = BoundaryField;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str(
                    "a side's condition for every side, or an object by side (left, right, bottom, top)",
                )
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<BoundaryField, E> {
                let side = Side::deserialize(de::value::StrDeserializer::<E>::new(v))?;
                let s = Some(side);
                Ok(BoundaryField(BoundaryInput { left: s, right: s, bottom: s, top: s, every_side: true }))
            }
            fn visit_map<M: de::MapAccess<'de>>(self, map: M) -> Result<BoundaryField, M::Error> {
                BoundaryInput::deserialize(de::value::MapAccessDeserializer::new(map)).map(BoundaryField)
            }
        }
        d.deserialize_any(V)
    }
}

/// Why a JSON body is not the request it should be, and where.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum JsonError {
    /// Not JSON at all: a syntax error at a line and column of the body.
    #[error("{message} at line {line} column {column}")]
    Syntax {
        /// serde_json's message, without the position.
        message: String,
        /// 1-based line.
        line: usize,
        /// 1-based column, in bytes.
        column: usize,
    },
    /// JSON of the wrong shape: a wrong type, an unknown or a missing field.
    #[error("{}{message}", if path.is_empty() { String::new() } else { format!("{path}: ") })]
    Shape {
        /// The value at fault as it reads in a message (`domain.x[1]`); empty for the body.
        path: String,
        /// What is wrong with it.
        message: String,
    },
}

impl JsonError {
    /// The value at fault as an RFC 6901 JSON pointer (`/domain/x/1`; `""` for the whole
    /// body); none for a syntax error.
    pub fn pointer(&self) -> Option<String> {
        match self {
            JsonError::Syntax { .. } => None,
            JsonError::Shape { path, .. } => Some(pointer(path)),
        }
    }
}

/// The JSON pointer of a field as messages spell it: `regions[1].bh[2]` is `/regions/1/bh/2`.
/// Request fields are plain names, so `.` and `[` only ever separate.
pub fn pointer(path: &str) -> String {
    let mut out = String::with_capacity(path.len() + 4);
    for part in path.split(['.', '[']).filter(|p| !p.is_empty()) {
        out.push('/');
        out.push_str(&part.trim_end_matches(']').replace('~', "~0").replace('/', "~1"));
    }
    out
}

/// Reads a request of type `T` from JSON, saying where a value does not fit: the path to it,
/// and serde's message without a body position, which the path replaces.
///
/// # Errors
/// [`JsonError::Syntax`] when the bytes are not JSON, [`JsonError::Shape`] when they are not
/// a `T` (an array or a scalar where the request is an object, too).
pub fn from_json<'a, T: Deserialize<'a>>(bytes: &'a [u8]) -> Result<T, JsonError> {
    let syntax = |e: &serde_json::Error| JsonError::Syntax {
        message: strip_position(e),
        line: e.line(),
        column: e.column(),
    };
    // serde's derived structs also take arrays (as tuples); a request is an object.
    if bytes.iter().find(|b| !b.is_ascii_whitespace()) != Some(&b'{') {
        return Err(match serde_json::from_slice::<de::IgnoredAny>(bytes) {
            Err(e) if e.classify() != serde_json::error::Category::Data => syntax(&e),
            _ => JsonError::Shape { path: String::new(), message: "the body must be a JSON object".into() },
        });
    }
    let mut de = serde_json::Deserializer::from_slice(bytes);
    let value = serde_path_to_error::deserialize(&mut de).map_err(|e| {
        let inner = e.inner();
        if inner.classify() != serde_json::error::Category::Data {
            return syntax(inner);
        }
        // Rust's type names mean nothing to a caller.
        let message = strip_position(inner).replace("expected f64", "expected a number");
        JsonError::Shape { path: readable(e.path()), message }
    })?;
    de.end().map_err(|e| syntax(&e))?;
    Ok(value)
}

/// `domain.x[1]` for serde_path_to_error's path (which writes `.` for the whole body).
fn readable(path: &serde_path_to_error::Path) -> String {
    use serde_path_to_error::Segment;
    let mut out = String::new();
    for segment in path {
        match segment {
            Segment::Seq { index } => write!(out, "[{index}]").expect("a String takes every write"),
            Segment::Map { key } | Segment::Enum { variant: key } => {
                if !out.is_empty() {
                    out.push('.');
                }
                out.push_str(key);
            }
            Segment::Unknown => {}
        }
    }
    out
}

/// serde_json's message without the " at line L column C" it appends.
fn strip_position(e: &serde_json::Error) -> String {
    let mut message = e.to_string();
    let suffix = format!(" at line {} column {}", e.line(), e.column());
    if let Some(kept) = message.strip_suffix(&suffix).map(str::len) {
        message.truncate(kept);
    }
    message
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fraction_is_the_nearest_targets_and_stays_in_range() {
        let budget = Target { max_vertices: 1000, tolerance: None, time_limit_ms: None };
        assert_eq!(budget.fraction(250, 3.0, 10.0, 5.0), 0.25);
        assert_eq!(budget.fraction(5000, 3.0, 10.0, 5.0), 1.0);
        // From an error of 1 down to 0.001: three decades, one of them done.
        let tolerance = Target { tolerance: Some(1e-3), ..budget };
        assert!((tolerance.fraction(10, 1e-1, 0.0, 1.0) - 1.0 / 3.0).abs() < 1e-12);
        assert_eq!(tolerance.fraction(10, 1e-4, 0.0, 1.0), 1.0);
        // A worst that rose above the first: no progress by error, but never below 0.
        assert_eq!(tolerance.fraction(0, 2.0, 0.0, 1.0), 0.0);
        let time = Target { time_limit_ms: Some(2000), ..budget };
        assert_eq!(time.fraction(10, 1.0, 1500.0, 1.0), 0.75);
        assert_eq!(Target::default().fraction(0, f64::NAN, 0.0, f64::NAN), 0.0);
    }

    #[test]
    fn a_count_reads_as_json_counts_do() {
        assert_eq!(parse_count("1e4"), Some(10_000));
        assert_eq!(parse_count(" 250 "), Some(250));
        assert_eq!(parse_count("10000.0"), Some(10_000));
        for bad in ["1.5", "-1", "inf", "NaN", "ten", "1e30"] {
            assert_eq!(parse_count(bad), None, "{bad}");
        }
    }
}
