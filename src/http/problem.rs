//! ApiError: every failure the API reports, written as RFC 9457 `application/problem+json`.

use crate::api::{JsonError, pointer};
use crate::datasets::DatasetError;
use crate::jobs::{Cause, Failure, JobError, SubmitError};
use crate::output::Format;
use crate::spec::{SpecError, grid_error};
use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde_json::{Map, Value, json};

/// The media type of problem documents.
pub const PROBLEM_JSON: &str = "application/problem+json";

/// An API failure. Each variant's status and `type` are listed in openapi.yaml; the `type`
/// URIs are relative references (`/problems/<slug>`), as RFC 9457 allows.
#[derive(Debug)]
pub enum ApiError {
    /// 400 `malformed-json`: the body is not JSON.
    MalformedJson(String),
    /// 400 `malformed-multipart`: a `multipart/form-data` body that does not parse.
    MalformedMultipart(String),
    /// 400 `malformed-json` for a syntax error, 422 `invalid-request` (with the field's
    /// pointer) for JSON of the wrong shape: a wrong type, an unknown or a missing field.
    Json(JsonError),
    /// 422 `invalid-request`: a request of the wrong shape outside a JSON body (the query
    /// string, the multipart parts).
    InvalidRequest(String),
    /// 422 (or the variant's own): the request is well-formed but not a valid job.
    Spec(SpecError),
    /// 415 `unsupported-media-type`: a body whose content type the route does not take; the
    /// detail names the type (and how to send a grid file, for one sent raw).
    UnsupportedMediaType {
        /// What is wrong, and how to send the body instead.
        detail: String,
        /// The media types the route takes.
        accepted: &'static [&'static str],
    },
    /// 413 `limit-exceeded`: the body is larger than `MESHFIT_MAX_BODY_BYTES`.
    BodyTooLarge(usize),
    /// 414 `limit-exceeded`: the request target (path and query) is longer than this.
    TargetTooLong(usize),
    /// 431 `limit-exceeded`: the request's headers take more bytes than this.
    HeadersTooLarge(usize),
    /// 408 `body-timeout`: the body stopped arriving for `MESHFIT_BODY_TIMEOUT_MS`, or came
    /// slower than the minimum rate.
    BodyTimeout,
    /// A job's failure, on this replica or another: 422 `non-finite-value` (F is NaN or
    /// infinite at a point the refinement needs), 422 `invalid-problem` (k, f or g is invalid
    /// where the solver sampled it), or 500 `internal`.
    Failed(Failure),
    /// 404 `not-found`.
    NotFound(String),
    /// 405 `method-not-allowed`.
    MethodNotAllowed,
    /// 406 `not-acceptable`: a format (by `?format=` or `Accept`) that no encoder writes.
    NotAcceptable(String),
    /// 409 `not-finished`: the job has no mesh yet; ask again in this many seconds.
    NotFinished(&'static str, u64),
    /// 409 `job-cancelled`: the job was cancelled before it finished.
    Cancelled,
    /// 503 `queue-full`, with `Retry-After`: (jobs waiting, seconds).
    QueueFull(usize, u64),
    /// 503 `over-memory-budget`, with `Retry-After`: the request does not fit in
    /// `MESHFIT_MEMORY_BYTES` now; (bytes needed, bytes free, seconds).
    OverBudget(u64, u64, u64),
    /// 429 `share-used`, with `Retry-After`: the client holds its share of the workers and
    /// the queue; (jobs held, seconds).
    ShareUsed(usize, u64),
    /// 401 `unauthorized`: keys are configured and the request has none, or a wrong one.
    Unauthorized {
        /// Whether a bearer token was sent at all.
        presented: bool,
    },
    /// 403 `cross-origin`: a request that changes state from a web page of another origin.
    CrossOrigin,
    /// 503 `shutting-down`.
    ShuttingDown,
    /// 503 `too-many-connections`, with `Retry-After`: `MESHFIT_MAX_CONNECTIONS` are open.
    TooManyConnections,
    /// 500 `internal`: the detail is logged, never sent.
    Internal(String),
    /// 503 `redis-unavailable`, with `Retry-After`: the job runs on another replica, or may,
    /// and Redis, through which replicas reach each other, does not answer.
    Unreachable,
    /// 409 `conflicting-value`: a value told for a client job's point differs from the one told
    /// before.
    Conflict {
        /// The request field at fault, as it reads in a message (`values[2].value`).
        field: String,
        /// What differs.
        detail: String,
    },
    /// 503 `queue-full`, with `Retry-After`: this replica keeps its most client jobs.
    ClientJobsFull(usize),
    /// 409 `client-job-failed`, in a client job's status: it expired, or cannot go on.
    ClientJobFailed(String),
    /// A dataset or a tile: 422 `invalid-grid` or `limit-exceeded` for a file that does not
    /// decode, 422 `invalid-dem` for a grid that is no DEM on the globe, 404 `not-found`,
    /// 409 `dataset-configured`, 507 `datasets-full`.
    Dataset(DatasetError),
}

impl From<DatasetError> for ApiError {
    fn from(e: DatasetError) -> Self {
        match e {
            // With their Retry-After.
            DatasetError::Unreachable(_) => ApiError::Unreachable,
            DatasetError::OverBudget(o) => ApiError::OverBudget(o.needed, o.available, 1),
            // The server's fault, not the request's: logged, never sent.
            e @ DatasetError::Unreadable { .. } => ApiError::Internal(e.to_string()),
            e => ApiError::Dataset(e),
        }
    }
}

impl From<SpecError> for ApiError {
    fn from(e: SpecError) -> Self {
        ApiError::Spec(e)
    }
}

impl From<SubmitError> for ApiError {
    fn from(e: SubmitError) -> Self {
        match e {
            SubmitError::QueueFull { waiting, retry_after } => ApiError::QueueFull(waiting, retry_after),
            SubmitError::ShareUsed { held, retry_after } => ApiError::ShareUsed(held, retry_after),
            SubmitError::OverBudget { needed, available, retry_after } => {
                ApiError::OverBudget(needed, available, retry_after)
            }
            SubmitError::ShuttingDown => ApiError::ShuttingDown,
        }
    }
}

impl From<JobError> for ApiError {
    fn from(e: JobError) -> Self {
        match e {
            JobError::Evicted => ApiError::NotFound(
                "the job succeeded, but its mesh is no longer cached; submit the request again".into(),
            ),
            JobError::HandedBack => ApiError::ShuttingDown,
            // The same failure whichever replica ran the job.
            e => ApiError::Failed(e.failure()),
        }
    }
}

impl ApiError {
    /// Status, `type` slug, title, detail and extension members.
    fn parts(&self) -> (StatusCode, &'static str, &'static str, String, Map<String, Value>) {
        let mut ext = Map::new();
        let unprocessable = StatusCode::UNPROCESSABLE_ENTITY;
        let (status, slug, title, detail) = match self {
            ApiError::MalformedJson(d) => {
                (StatusCode::BAD_REQUEST, "malformed-json", "Body is not valid JSON", d.clone())
            }
            ApiError::MalformedMultipart(d) => (
                StatusCode::BAD_REQUEST,
                "malformed-multipart",
                "Body is not valid multipart/form-data",
                d.clone(),
            ),
            ApiError::Json(e @ JsonError::Syntax { .. }) => {
                (StatusCode::BAD_REQUEST, "malformed-json", "Body is not valid JSON", e.to_string())
            }
            ApiError::Json(e @ JsonError::Shape { .. }) => {
                ext.insert("field".into(), json!(e.pointer()));
                (unprocessable, "invalid-request", "Request does not match the schema", e.to_string())
            }
            ApiError::InvalidRequest(d) => {
                (unprocessable, "invalid-request", "Request does not match the schema", d.clone())
            }
            ApiError::UnsupportedMediaType { detail, accepted } => {
                ext.insert("accepted".into(), json!(accepted));
                let status = StatusCode::UNSUPPORTED_MEDIA_TYPE;
                (status, "unsupported-media-type", "Content type not supported", detail.clone())
            }
            ApiError::BodyTooLarge(limit) => {
                ext.insert("limit".into(), json!({"name": "MESHFIT_MAX_BODY_BYTES", "value": limit}));
                let detail = format!("the body is larger than this server's limit of {limit} bytes");
                (StatusCode::PAYLOAD_TOO_LARGE, "limit-exceeded", "Request exceeds a limit", detail)
            }
            ApiError::TargetTooLong(limit) => {
                let detail = format!("the path and query are longer than this server's limit of {limit} bytes");
                (StatusCode::URI_TOO_LONG, "limit-exceeded", "Request exceeds a limit", detail)
            }
            ApiError::HeadersTooLarge(limit) => {
                let detail = format!("the headers take more than this server's limit of {limit} bytes");
                let status = StatusCode::REQUEST_HEADER_FIELDS_TOO_LARGE;
                (status, "limit-exceeded", "Request exceeds a limit", detail)
            }
            ApiError::BodyTimeout => (
                StatusCode::REQUEST_TIMEOUT,
                "body-timeout",
                "Request body stopped arriving",
                "the body paused longer than this server's body timeout (MESHFIT_BODY_TIMEOUT_MS), or arrived \
                 slower than 64 KiB/s beyond it"
                    .into(),
            ),
            ApiError::Spec(e) => {
                if let Some(field) = e.field() {
                    ext.insert("field".into(), json!(pointer(field)));
                }
                let (slug, title) = match e {
                    SpecError::Source(_) => ("invalid-source", "Give exactly one of function and grid"),
                    SpecError::Expression(x) => {
                        ext.insert("column".into(), json!(x.column));
                        ("invalid-expression", "Expression does not parse")
                    }
                    SpecError::Grid { index, .. } => {
                        if let Some(index) = index {
                            ext.insert("index".into(), json!(index));
                        }
                        ("invalid-grid", "Grid is malformed")
                    }
                    SpecError::Domain(_) => ("invalid-domain", "Domain is not a rectangle"),
                    SpecError::Coefficient { error, .. } => {
                        ext.insert("column".into(), json!(error.column));
                        ("invalid-expression", "Expression does not parse")
                    }
                    SpecError::Problem { .. } => ("invalid-problem", "Boundary value problem is invalid"),
                    SpecError::Field { .. } => ("invalid-request", "Request field is invalid"),
                    SpecError::Parameter(_) => ("invalid-parameter", "Parameter out of range"),
                    SpecError::Limit { setting, limit, .. } => {
                        ext.insert("limit".into(), json!({"name": setting, "value": limit}));
                        ("limit-exceeded", "Request exceeds a limit")
                    }
                };
                (unprocessable, slug, title, e.to_string())
            }
            ApiError::Failed(f) => {
                let (slug, title) = match f.cause {
                    Cause::NonFiniteValue => ("non-finite-value", "F is not finite where the mesh needs it"),
                    Cause::InvalidProblem => ("invalid-problem", "Boundary value problem is invalid"),
                    // Its message is for the logs only.
                    Cause::Internal => return ApiError::Internal(f.message.clone()).parts(),
                };
                if let Some(field) = &f.field {
                    ext.insert("field".into(), json!(pointer(field)));
                }
                if let Some(point) = f.point {
                    ext.insert("point".into(), json!(point));
                }
                (unprocessable, slug, title, f.message.clone())
            }
            ApiError::NotFound(d) => (StatusCode::NOT_FOUND, "not-found", "Not found", d.clone()),
            ApiError::MethodNotAllowed => (
                StatusCode::METHOD_NOT_ALLOWED,
                "method-not-allowed",
                "Method not allowed",
                "this resource does not support that method".into(),
            ),
            ApiError::NotAcceptable(asked) => {
                let formats: Vec<&str> = Format::ALL.iter().map(|f| f.name()).collect();
                ext.insert("formats".into(), json!(formats));
                let detail = format!("no format matches `{asked}`; known formats: {}", Format::names());
                (StatusCode::NOT_ACCEPTABLE, "not-acceptable", "Format not available", detail)
            }
            ApiError::NotFinished(status, _) => {
                ext.insert("job_status".into(), json!(status));
                (StatusCode::CONFLICT, "not-finished", "Job has no mesh yet", format!("the job is {status}"))
            }
            ApiError::Cancelled => {
                let detail = "the job was cancelled before it finished; submit it again to rerun it".into();
                (StatusCode::CONFLICT, "job-cancelled", "Job was cancelled", detail)
            }
            ApiError::QueueFull(waiting, _) => {
                let detail = format!("{waiting} jobs are already waiting for a worker; retry shortly");
                (StatusCode::SERVICE_UNAVAILABLE, "queue-full", "Server is busy", detail)
            }
            ApiError::OverBudget(needed, available, _) => {
                ext.insert("limit".into(), json!({"name": "MESHFIT_MEMORY_BYTES"}));
                let detail = format!(
                    "this request needs {needed} bytes of memory and {available} are free now; retry shortly, \
                     or ask for fewer vertices or a smaller grid"
                );
                (StatusCode::SERVICE_UNAVAILABLE, "over-memory-budget", "Server memory is committed", detail)
            }
            ApiError::ShareUsed(held, _) => {
                let detail = format!(
                    "you have {held} jobs running or queued, your share of this server (MESHFIT_CLIENT_SHARE); \
                     retry when one has finished"
                );
                (StatusCode::TOO_MANY_REQUESTS, "share-used", "Too many jobs from this client", detail)
            }
            ApiError::Unauthorized { presented } => {
                let detail = if *presented {
                    "the bearer token is not one of this server's API keys"
                } else {
                    "this server needs an API key: send `Authorization: Bearer <key>`"
                };
                (StatusCode::UNAUTHORIZED, "unauthorized", "API key missing or wrong", detail.into())
            }
            ApiError::CrossOrigin => (
                StatusCode::FORBIDDEN,
                "cross-origin",
                "Origin not allowed",
                "requests that change state are taken from this server's own pages and from the \
                 origins in MESHFIT_CORS_ORIGINS only"
                    .into(),
            ),
            ApiError::ShuttingDown => (
                StatusCode::SERVICE_UNAVAILABLE,
                "shutting-down",
                "Server is shutting down",
                "the server takes no new jobs while it shuts down".into(),
            ),
            ApiError::TooManyConnections => (
                StatusCode::SERVICE_UNAVAILABLE,
                "too-many-connections",
                "Server has too many open connections",
                "this server has as many open connections as it serves (MESHFIT_MAX_CONNECTIONS); retry shortly".into(),
            ),
            ApiError::Conflict { field, detail } => {
                ext.insert("field".into(), json!(pointer(field)));
                (StatusCode::CONFLICT, "conflicting-value", "Value differs from the one told", detail.clone())
            }
            ApiError::ClientJobsFull(most) => {
                ext.insert("limit".into(), json!({"name": "client jobs", "value": most}));
                let detail = format!(
                    "this replica keeps {most} client jobs, its most: finish one, or retry once one expires"
                );
                (StatusCode::SERVICE_UNAVAILABLE, "queue-full", "Server is busy", detail)
            }
            ApiError::ClientJobFailed(detail) => {
                (StatusCode::CONFLICT, "client-job-failed", "Client job failed", detail.clone())
            }
            ApiError::Unreachable => (
                StatusCode::SERVICE_UNAVAILABLE,
                "redis-unavailable",
                "The job's replica cannot be reached",
                "the job or dataset is not known here and may be on another replica (or the job runs on another replica), and Redis, through which replicas reach each other, does not answer now; retry shortly".into(),
            ),
            ApiError::Dataset(e) => match e {
                DatasetError::File(file) => return ApiError::Spec(grid_error(file.clone())).parts(),
                DatasetError::Dem(_) | DatasetError::Pyramid(_) => {
                    (unprocessable, "invalid-dem", "Not a DEM terrain tiles can be made of", e.to_string())
                }
                DatasetError::Unreachable(_) => return ApiError::Unreachable.parts(),
                DatasetError::NotFound { .. } | DatasetError::NoTile(_) => {
                    (StatusCode::NOT_FOUND, "not-found", "Not found", e.to_string())
                }
                DatasetError::Configured(_) => {
                    (StatusCode::CONFLICT, "dataset-configured", "Dataset is named in the settings", e.to_string())
                }
                DatasetError::Full { limit, .. } => {
                    ext.insert("limit".into(), json!({"name": "MESHFIT_DATASET_BYTES", "value": limit}));
                    (StatusCode::INSUFFICIENT_STORAGE, "datasets-full", "Datasets take their whole allowance", e.to_string())
                }
                // Made the variants above by `From`, which sets their Retry-After.
                DatasetError::OverBudget(o) => return ApiError::OverBudget(o.needed, o.available, 1).parts(),
                DatasetError::Unreadable { .. } => return ApiError::Internal(e.to_string()).parts(),
            },
            ApiError::Internal(_) => (
                StatusCode::INTERNAL_SERVER_ERROR,
                "internal",
                "Internal server error",
                "an internal error occurred; it has been logged with this request's id".into(),
            ),
        };
        (status, slug, title, detail, ext)
    }

    /// The problem's `detail`: what went wrong, in a sentence.
    pub fn detail(&self) -> String {
        self.parts().3
    }

    /// The problem document.
    pub fn to_json(&self) -> Value {
        self.document().1
    }

    /// The HTTP status and the problem document, from one pass over the variant.
    fn document(&self) -> (StatusCode, Value) {
        let (status, slug, title, detail, ext) = self.parts();
        let mut doc = Map::new();
        doc.insert("type".into(), json!(format!("/problems/{slug}")));
        doc.insert("title".into(), json!(title));
        doc.insert("status".into(), json!(status.as_u16()));
        doc.insert("detail".into(), json!(detail));
        doc.extend(ext);
        (status, Value::Object(doc))
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        if let ApiError::Internal(detail)
        | ApiError::Failed(Failure { cause: Cause::Internal, message: detail, .. }) = &self
        {
            // Inside the request's span, so the log line carries its id.
            tracing::error!(%detail, "internal error");
        }
        let (status, doc) = self.document();
        let mut response = (status, doc.to_string()).into_response();
        let headers = response.headers_mut();
        headers.insert(header::CONTENT_TYPE, HeaderValue::from_static(PROBLEM_JSON));
        match self {
            ApiError::QueueFull(_, seconds)
            | ApiError::ShareUsed(_, seconds)
            | ApiError::NotFinished(_, seconds)
            | ApiError::OverBudget(_, _, seconds) => {
                headers.insert(header::RETRY_AFTER, HeaderValue::from(seconds));
            }
            ApiError::ShuttingDown | ApiError::TooManyConnections | ApiError::Unreachable => {
                headers.insert(header::RETRY_AFTER, HeaderValue::from_static("1"));
            }
            ApiError::ClientJobsFull(_) => {
                headers.insert(header::RETRY_AFTER, HeaderValue::from_static("60"));
            }
            ApiError::Unauthorized { .. } => {
                headers.insert(header::WWW_AUTHENTICATE, HeaderValue::from_static("Bearer"));
            }
            _ => {}
        }
        response
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Point;
    use crate::refine::RefineError;
    use crate::solve::SolveError;

    fn rendered(e: JobError) -> (StatusCode, Value) {
        ApiError::from(e).document()
    }

    /// A job's failure reads the same to clients of the replica that ran it and of any other,
    /// which gets it from the store.
    #[test]
    fn a_relayed_failure_is_answered_as_the_failure_itself() {
        let errors = [
            JobError::Refine(RefineError::NonFinite { point: Point::new(0.5, 0.25), value: f64::INFINITY }),
            JobError::Solve(SolveError::InvalidK { x: 0.5, y: 1.0, value: -1.0, triangle: 7 }),
            JobError::Solve(SolveError::NotPositiveDefinite { pivot: 3, unknowns: 10 }),
            JobError::Internal("the refinement panicked".into()),
        ];
        for error in errors {
            let stored = serde_json::to_vec(&error.failure()).unwrap();
            let relayed = JobError::Relayed(serde_json::from_slice(&stored).unwrap());
            assert_eq!(rendered(relayed), rendered(error));
        }
    }

    #[test]
    fn failures_on_the_input_name_where_and_internal_ones_say_nothing() {
        let (status, doc) = rendered(JobError::Refine(RefineError::NonFinite {
            point: Point::new(0.5, 0.25),
            value: f64::NAN,
        }));
        assert_eq!(status, StatusCode::UNPROCESSABLE_ENTITY);
        assert_eq!(
            (&doc["type"], &doc["point"]),
            (&json!("/problems/non-finite-value"), &json!([0.5, 0.25]))
        );
        assert!(doc.get("field").is_none());
        let (status, doc) =
            rendered(JobError::Solve(SolveError::NonFiniteG { x: 1.0, y: 0.0, value: f64::NAN, vertex: 2 }));
        assert_eq!(status, StatusCode::UNPROCESSABLE_ENTITY);
        assert_eq!((&doc["type"], &doc["field"]), (&json!("/problems/invalid-problem"), &json!("/g")));
        let (status, doc) = rendered(JobError::Internal("secret detail".into()));
        assert_eq!(status, StatusCode::INTERNAL_SERVER_ERROR);
        assert!(!doc.to_string().contains("secret"), "{doc}");
    }
}
