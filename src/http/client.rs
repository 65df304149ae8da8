//! Client jobs over HTTP: `POST /v1/jobs` with `"source": "client"` makes one,
//! `GET /v1/jobs/{id}/ask` hands out a batch of points, `POST /v1/jobs/{id}/tell` takes their
//! values; the job's status and mesh are served where every job's are.

use super::extract::{Body, parse_json, query};
use super::problem::ApiError;
use super::state::AppState;
use crate::api::{
    AskAnswer, AskedPoint, ClientJobRequest, JobStatus, JsonError, Links, TellAnswer, TellRequest, timestamp,
};
use crate::jobs::{Asked, ClientJob, MAX_CLIENT_JOBS, TellError};
use crate::spec::ClientSpec;
use axum::extract::{Path, State};
use axum::http::{HeaderValue, StatusCode, Uri, header};
use axum::response::{IntoResponse, Response};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// The longest `GET /v1/jobs/{id}/ask?wait=` holds a request, in ms: under the 10 s a client
/// or a proxy commonly allows an answer; a caller asks again.
pub const MAX_WAIT_MS: u64 = 9_000;

/// `POST /v1/jobs` with `"source": "client"`: 202 with the job's status, asking for its corners.
pub(super) fn create(state: &AppState, body: &Body) -> Result<Response, ApiError> {
    let request: ClientJobRequest = parse_json(&body.bytes)?;
    let spec = ClientSpec::from_request(request, &state.limits)?;
    let job =
        state.clients.create(spec, Instant::now()).map_err(|_| ApiError::ClientJobsFull(MAX_CLIENT_JOBS))?;
    let status = status(&job);
    let location = HeaderValue::from_str(&status.links.this).expect("ascii path");
    let headers = [(header::LOCATION, location), (header::RETRY_AFTER, HeaderValue::from_static("0"))];
    Ok((StatusCode::ACCEPTED, headers, axum::Json(status)).into_response())
}

/// Client job `id`'s status document.
pub(super) fn status(job: &ClientJob) -> JobStatus {
    let s = job.status(Instant::now());
    let problem = s.problem.map(|detail| ApiError::ClientJobFailed(detail).to_json());
    JobStatus {
        id: job.id.clone(),
        status: s.status,
        progress: None,
        stats: s.result.map(|r| r.stats.clone()),
        elapsed_ms: None,
        created_at: Some(timestamp(job.created)),
        started_at: Some(timestamp(job.created)),
        finished_at: s.finished.map(timestamp),
        problem,
        evaluations: Some(s.evaluations),
        links: Links::of_client(&job.id),
    }
}

/// Client job `id`, or a 404 that says what the id is not.
fn find(state: &AppState, id: &str) -> Result<Arc<ClientJob>, ApiError> {
    state.clients.get(id).ok_or_else(|| {
        ApiError::NotFound(format!("no client job with id {id} on this replica (only a job made with \"source\": \"client\" asks for points)"))
    })
}

/// The query of `GET /v1/jobs/{id}/ask`.
#[derive(Debug, Default, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct AskQuery {
    wait: Option<u64>,
}

/// `GET /v1/jobs/{id}/ask?wait=ms`: the current batch's untold points, leased to the caller;
/// 204 with `Retry-After` when another caller holds them or the next batch is being chosen
/// and nothing changed within `wait`; once finished, the status and no points.
pub async fn jobs_ask(
    State(state): State<AppState>,
    Path(id): Path<String>,
    uri: Uri,
) -> Result<Response, ApiError> {
    let job = find(&state, &id)?;
    let query: AskQuery = query(&uri)?;
    let wait = query.wait.unwrap_or(0);
    if wait > MAX_WAIT_MS {
        return Err(ApiError::InvalidRequest(format!("wait must be from 0 to {MAX_WAIT_MS} ms, got {wait}")));
    }
    let deadline = tokio::time::Instant::now() + Duration::from_millis(wait);
    loop {
        // Listen before looking, so a change between the two is not missed.
        let changed = job.changed();
        tokio::pin!(changed);
        changed.as_mut().enable();
        match job.ask(Instant::now()) {
            Asked::Batch { number, points, lease } => {
                let points = points.into_iter().map(|(id, p)| AskedPoint { id, x: p.x, y: p.y }).collect();
                let lease_ms = Some(lease.as_millis() as u64);
                let answer = AskAnswer { status: "running", batch: Some(number), points, lease_ms };
                return Ok(axum::Json(answer).into_response());
            }
            Asked::Finished => {
                let answer = AskAnswer {
                    status: job.status(Instant::now()).status,
                    batch: None,
                    points: vec![],
                    lease_ms: None,
                };
                return Ok(axum::Json(answer).into_response());
            }
            Asked::Wait { until } => {
                let now = tokio::time::Instant::now();
                if now >= deadline {
                    // A lease's end is when the batch comes round again.
                    let seconds =
                        until.map_or(1, |t| t.saturating_duration_since(Instant::now()).as_secs().max(1));
                    let mut response = StatusCode::NO_CONTENT.into_response();
                    response.headers_mut().insert(header::RETRY_AFTER, HeaderValue::from(seconds));
                    return Ok(response);
                }
                let lease_end = until.map_or(deadline, |t| now + t.saturating_duration_since(Instant::now()));
                let _ = tokio::time::timeout_at(deadline.min(lease_end), changed).await;
            }
        }
    }
}

/// `POST /v1/jobs/{id}/tell`: values for points asked, all or none. A value told again is a
/// no-op; a different one is a 409 naming the entry; an id never asked is a 422 naming it.
/// The value completing a batch sets the next one choosing on the blocking pool.
pub async fn jobs_tell(
    State(state): State<AppState>,
    Path(id): Path<String>,
    body: Body,
) -> Result<Response, ApiError> {
    let job = find(&state, &id)?;
    let request: TellRequest = parse_json(&body.bytes)?;
    let values: Vec<(u64, Option<f64>)> = request.values.iter().map(|v| (v.id, v.value)).collect();
    let (accepted, complete) = job.tell(&values, Instant::now()).map_err(|e| match e {
        TellError::Unknown { index, id } => ApiError::Json(JsonError::Shape {
            path: format!("values[{index}].id"),
            message: format!("no point {id} was asked for"),
        }),
        TellError::Conflict { index, id, was } => ApiError::Conflict {
            field: format!("values[{index}].value"),
            detail: format!(
                "point {id} was told {}, not {}",
                was.map_or("null (failed)".to_owned(), |v| v.to_string()),
                request.values[index].value.map_or("null".to_owned(), |v| v.to_string())
            ),
        },
        TellError::Finished { index } => ApiError::Json(JsonError::Shape {
            path: format!("values[{index}].id"),
            message: "the job has finished: it takes no new values".into(),
        }),
    })?;
    if complete {
        let chooser = job.clone();
        tokio::spawn(async move {
            if let Err(e) = crate::cpu::spawn(move || chooser.choose()).await {
                tracing::error!(error = %e, "choosing a client job's next batch panicked");
            }
        });
    }
    let s = job.status(Instant::now());
    Ok(axum::Json(TellAnswer { status: s.status, accepted, evaluations: s.evaluations }).into_response())
}
