//! Handlers for meshes and jobs: create (synchronous or streamed), show, stream, fetch, cancel.

use super::AppState;
use super::extract::{Body, parse_json};
use super::problem::ApiError;
use crate::api::{JobRequest, JobStatus, Links, ProgressEvent, with_grid_limit};
use crate::jobs::{
    Finished, Found, JobError, JobSpec, Outcome, Record, Snapshot, Status, Ticket, Waiter, job_id,
};
use axum::extract::{Path, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use futures_util::stream::{self, Stream};
use std::convert::Infallible;
use std::sync::Arc;
use std::time::Duration;
use tokio::time::Instant;

/// Progress events go out at most this often, however fast the engine reports.
const PROGRESS_EVERY: Duration = Duration::from_millis(100);

/// Parses, validates and hashes a body off the async workers: a large grid takes real CPU.
async fn prepare(state: &AppState, body: Body) -> Result<(String, JobSpec), ApiError> {
    let limits = state.limits;
    let (id, spec) = tokio::task::spawn_blocking(move || {
        let request: JobRequest = with_grid_limit(limits.max_grid_points, || parse_json(&body.0))?;
        let spec = JobSpec::from_request(request, &limits)?;
        Ok::<_, ApiError>((job_id(&spec), spec))
    })
    .await
    .map_err(|e| ApiError::Internal(format!("request parsing panicked: {e}")))??;
    tracing::Span::current().record("job_id", id.as_str());
    Ok((id, spec))
}

fn wants_event_stream(headers: &HeaderMap) -> bool {
    headers
        .get_all(header::ACCEPT)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .any(|v| v.split(',').any(|t| t.trim().starts_with("text/event-stream")))
}

fn etag(id: &str) -> HeaderValue {
    HeaderValue::from_str(&format!("\"{id}\"")).expect("hex is a valid header value")
}

fn not_modified(headers: &HeaderMap, id: &str) -> bool {
    let tag = format!("\"{id}\"");
    headers
        .get_all(header::IF_NONE_MATCH)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .any(|v| v.split(',').any(|t| t.trim() == tag || t.trim() == "*"))
}

/// The mesh document with its ETag, or 304 when the client has it.
fn mesh_response(headers: &HeaderMap, id: &str, finished: &Finished, cache: &'static str) -> Response {
    let mut response = if not_modified(headers, id) {
        StatusCode::NOT_MODIFIED.into_response()
    } else {
        ([(header::CONTENT_TYPE, "application/json")], finished.body.clone()).into_response()
    };
    response.headers_mut().insert(header::ETAG, etag(id));
    response.headers_mut().insert("x-cache", HeaderValue::from_static(cache));
    response
}

/// Where a job is now.
fn status_of(found: &Found) -> Status {
    match found {
        Found::Job(job) => job.snapshot().status,
        Found::Done(r) => r.status,
        Found::Cached(_) => Status::Succeeded,
    }
}

/// The status document of a job as it is now.
fn status_body(id: &str, found: &Found) -> JobStatus {
    let (status, progress, stats, problem) = match found {
        Found::Job(job) => {
            let s = job.snapshot();
            let (stats, problem) = match &s.outcome {
                Some(Outcome::Succeeded(f)) => (Some(f.stats.clone()), None),
                Some(Outcome::Failed(e)) => (None, Some(ApiError::from(e.clone()).to_json())),
                Some(Outcome::Cancelled) => (None, Some(ApiError::Cancelled.to_json())),
                None => (None, None),
            };
            (s.status, s.progress, stats, problem)
        }
        Found::Done(r) => {
            let problem = match (&r.error, r.status) {
                (Some(e), _) => Some(ApiError::from(e.clone()).to_json()),
                (None, Status::Cancelled) => Some(ApiError::Cancelled.to_json()),
                _ => None,
            };
            (r.status, r.progress, r.stats.clone(), problem)
        }
        Found::Cached(f) => (Status::Succeeded, None, Some(f.stats.clone()), None),
    };
    JobStatus { id: id.to_owned(), status: status.as_str(), progress, stats, problem, links: Links::of(id) }
}

/// `POST /v1/meshes`: the mesh, computed or cached; with `Accept: text/event-stream`, progress
/// events and then the mesh as one `result` event.
pub async fn meshes_create(
    State(state): State<AppState>,
    headers: HeaderMap,
    body: Body,
) -> Result<Response, ApiError> {
    let (id, spec) = prepare(&state, body).await?;
    let stream = wants_event_stream(&headers);
    match state.jobs.submit(id.clone(), spec, false).await? {
        Ticket::Cached(f) if stream => Ok(final_stream(&Outcome::Succeeded(f)).into_response()),
        Ticket::Cached(f) => Ok(mesh_response(&headers, &id, &f, "hit")),
        Ticket::Failed(e) if stream => Ok(final_stream(&Outcome::Failed(e)).into_response()),
        Ticket::Failed(e) => Err(e.into()),
        Ticket::Job(waiter) if stream => Ok(job_stream(waiter, 0).into_response()),
        // The waiter is dropped with this future if the client hangs up, which cancels a job
        // nobody else waits on.
        Ticket::Job(waiter) => match waiter.job().outcome().await {
            Outcome::Succeeded(f) => Ok(mesh_response(&headers, &id, &f, "miss")),
            Outcome::Failed(e) => Err(e.into()),
            Outcome::Cancelled => Err(ApiError::Cancelled),
        },
    }
}

/// `POST /v1/jobs`: starts (or finds) a job that runs whether or not anyone waits.
pub async fn jobs_create(State(state): State<AppState>, body: Body) -> Result<Response, ApiError> {
    let (id, spec) = prepare(&state, body).await?;
    let (code, status) = match state.jobs.submit(id.clone(), spec, true).await? {
        Ticket::Cached(f) => (StatusCode::OK, status_body(&id, &Found::Cached(f))),
        Ticket::Failed(e) => {
            let record = Record { status: Status::Failed, progress: None, stats: None, error: Some(e) };
            (StatusCode::OK, status_body(&id, &Found::Done(Arc::new(record))))
        }
        Ticket::Job(waiter) => (StatusCode::ACCEPTED, status_body(&id, &Found::Job(waiter.job().clone()))),
    };
    let location = HeaderValue::from_str(&status.links.this).expect("ascii path");
    Ok((code, [(header::LOCATION, location)], axum::Json(status)).into_response())
}

async fn find(state: &AppState, id: &str) -> Result<Found, ApiError> {
    tracing::Span::current().record("job_id", id);
    state.jobs.find(id).await.ok_or_else(|| ApiError::NotFound(format!("no job with id {id}")))
}

/// `GET /v1/jobs/{id}`.
pub async fn jobs_show(State(state): State<AppState>, Path(id): Path<String>) -> Result<Response, ApiError> {
    let found = find(&state, &id).await?;
    Ok(axum::Json(status_body(&id, &found)).into_response())
}

/// The outcome of a finished job, its mesh fetched back from the cache.
async fn finished_outcome(state: &AppState, id: &str, found: Found) -> Option<Outcome> {
    match found {
        Found::Cached(f) => Some(Outcome::Succeeded(f)),
        Found::Job(job) => job.snapshot().outcome,
        Found::Done(r) => Some(match (&r.error, r.status) {
            (Some(e), _) => Outcome::Failed(e.clone()),
            (None, Status::Cancelled) => Outcome::Cancelled,
            _ => match state.jobs.cached(id).await {
                Some(f) => Outcome::Succeeded(f),
                None => Outcome::Failed(JobError::Evicted),
            },
        }),
    }
}

/// `GET /v1/jobs/{id}/mesh`: 200 with the mesh, 409 while it is not finished.
pub async fn jobs_mesh(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let found = find(&state, &id).await?;
    let status = status_of(&found).as_str();
    match finished_outcome(&state, &id, found).await {
        Some(Outcome::Succeeded(f)) => Ok(mesh_response(&headers, &id, &f, "hit")),
        Some(Outcome::Failed(e)) => Err(e.into()),
        Some(Outcome::Cancelled) => Err(ApiError::Cancelled),
        None => Err(ApiError::NotFinished(status)),
    }
}

/// The id of the final event: above every progress id, the same for every run of a job, so a
/// client that reconnects with any earlier id still gets the result.
const FINAL_EVENT_ID: u64 = u64::MAX;

/// `GET /v1/jobs/{id}/events`: server-sent events; a finished job sends its final event at
/// once. `Last-Event-ID` skips what the client has seen; once it has seen the final event,
/// the answer is 204, which tells an EventSource to stop reconnecting.
pub async fn jobs_events(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let last_seen = headers
        .get("last-event-id")
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.trim().parse::<u64>().ok())
        .unwrap_or(0);
    if let Some(waiter) = state.jobs.watch(&id) {
        return Ok(job_stream(waiter, last_seen).into_response());
    }
    let found = find(&state, &id).await?;
    if last_seen == FINAL_EVENT_ID {
        return Ok(StatusCode::NO_CONTENT.into_response());
    }
    match finished_outcome(&state, &id, found).await {
        Some(outcome) => Ok(final_stream(&outcome).into_response()),
        // Finished between the two looks: the record is there now.
        None => Err(ApiError::Internal("job vanished between lookups".into())),
    }
}

/// `DELETE /v1/jobs/{id}`: cancels the job and answers with its final status.
pub async fn jobs_cancel(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let found = find(&state, &id).await?;
    if let Found::Job(job) = &found {
        job.cancel();
        // The worker checks the flag between insertions, so this is milliseconds.
        let _ = tokio::time::timeout(Duration::from_secs(5), job.outcome()).await;
    }
    Ok(axum::Json(status_body(&id, &found)).into_response())
}

fn progress_event(seq: u64, p: &ProgressEvent) -> Event {
    Event::default().event("progress").id(seq.to_string()).json_data(p).expect("progress serializes")
}

fn final_event(outcome: &Outcome) -> Event {
    let event = Event::default().id(FINAL_EVENT_ID.to_string());
    match outcome {
        Outcome::Succeeded(f) => event.event("result").data(String::from_utf8_lossy(&f.body)),
        Outcome::Failed(e) => event.event("error").data(ApiError::from(e.clone()).to_json().to_string()),
        Outcome::Cancelled => event.event("error").data(ApiError::Cancelled.to_json().to_string()),
    }
}

/// Just the final event, for a job that has finished.
fn final_stream(outcome: &Outcome) -> Sse<impl Stream<Item = Result<Event, Infallible>> + use<>> {
    Sse::new(stream::iter([Ok(final_event(outcome))])).keep_alive(KeepAlive::default())
}

struct Watch {
    /// Keeps the job alive for this client; dropped with the stream when it disconnects.
    waiter: Waiter,
    rx: tokio::sync::watch::Receiver<Snapshot>,
    last_seen: u64,
    last_progress: Option<Instant>,
    done: bool,
}

/// Progress events (throttled) and the final event of a job, skipping ids ≤ `last_seen`.
fn job_stream(waiter: Waiter, last_seen: u64) -> Sse<impl Stream<Item = Result<Event, Infallible>>> {
    let rx = waiter.job().subscribe();
    let watch = Watch { waiter, rx, last_seen, last_progress: None, done: false };
    let events = stream::unfold(watch, |mut w| async move {
        if w.done {
            return None;
        }
        loop {
            let snapshot = w.rx.borrow_and_update().clone();
            if let Some(outcome) = &snapshot.outcome {
                w.done = true;
                return (w.last_seen < FINAL_EVENT_ID).then(|| (Ok(final_event(outcome)), w));
            }
            if let Some(progress) = snapshot.progress.filter(|_| snapshot.seq > w.last_seen) {
                let due = w.last_progress.map(|t| t + PROGRESS_EVERY);
                if let Some(due) = due.filter(|&due| Instant::now() < due) {
                    // Too soon: wait, then send the newest snapshot instead of this one.
                    tokio::select! {
                        () = tokio::time::sleep_until(due) => {}
                        _ = w.rx.changed() => {}
                    }
                    continue;
                }
                w.last_seen = snapshot.seq;
                w.last_progress = Some(Instant::now());
                return Some((Ok(progress_event(snapshot.seq, &progress)), w));
            }
            if w.rx.changed().await.is_err() {
                tracing::warn!(job = %w.waiter.job().id(), "job state closed without an outcome");
                return None;
            }
        }
    });
    Sse::new(events).keep_alive(KeepAlive::default())
}
