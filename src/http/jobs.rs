//! Handlers for meshes and jobs: create (synchronous or streamed), show, stream, fetch, cancel.

use super::AppState;
use super::extract::{Body, parse_json};
use super::problem::ApiError;
use crate::api::{JobRequest, JobStatus, Links, ProgressEvent};
use crate::jobs::{Finished, Found, Job, JobSpec, Outcome, Snapshot, Ticket, Waiter, job_id};
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
        let request: JobRequest = parse_json(&body.0)?;
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

fn status_body(id: &str, snapshot: Option<&Snapshot>, cached: Option<&Finished>) -> JobStatus {
    let (status, progress, stats, problem) = match snapshot {
        Some(s) => {
            let (stats, problem) = match &s.outcome {
                Some(Outcome::Succeeded(f)) => (Some(f.stats.clone()), None),
                Some(Outcome::Failed(e)) => (None, Some(ApiError::from(e.clone()).to_json())),
                Some(Outcome::Cancelled) => (None, Some(ApiError::Cancelled.to_json())),
                None => (None, None),
            };
            (s.status.as_str(), s.progress, stats, problem)
        }
        None => ("succeeded", None, cached.map(|f| f.stats.clone()), None),
    };
    JobStatus { id: id.to_owned(), status, progress, stats, problem, links: Links::of(id) }
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
        Ticket::Cached(f) if stream => Ok(finished_stream(f).into_response()),
        Ticket::Cached(f) => Ok(mesh_response(&headers, &id, &f, "hit")),
        Ticket::Job(job) if stream => Ok(job_stream(job.attach(), 0).into_response()),
        Ticket::Job(job) => {
            // Dropped with this future if the client hangs up, which cancels a job nobody
            // else waits on.
            let waiter = job.attach();
            match waiter.job().outcome().await {
                Outcome::Succeeded(f) => Ok(mesh_response(&headers, &id, &f, "miss")),
                Outcome::Failed(e) => Err(e.into()),
                Outcome::Cancelled => Err(ApiError::Cancelled),
            }
        }
    }
}

/// `POST /v1/jobs`: starts (or finds) a job that runs whether or not anyone waits.
pub async fn jobs_create(State(state): State<AppState>, body: Body) -> Result<Response, ApiError> {
    let (id, spec) = prepare(&state, body).await?;
    let (code, status) = match state.jobs.submit(id.clone(), spec, true).await? {
        Ticket::Cached(f) => (StatusCode::OK, status_body(&id, None, Some(&f))),
        Ticket::Job(job) => {
            let snapshot = job.snapshot();
            let code = if snapshot.outcome.is_some() { StatusCode::OK } else { StatusCode::ACCEPTED };
            (code, status_body(&id, Some(&snapshot), None))
        }
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
    let body = match find(&state, &id).await? {
        Found::Job(job) => status_body(&id, Some(&job.snapshot()), None),
        Found::Cached(f) => status_body(&id, None, Some(&f)),
    };
    Ok(axum::Json(body).into_response())
}

/// `GET /v1/jobs/{id}/mesh`: 200 with the mesh, 409 while it is not finished.
pub async fn jobs_mesh(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    match find(&state, &id).await? {
        Found::Cached(f) => Ok(mesh_response(&headers, &id, &f, "hit")),
        Found::Job(job) => match job.snapshot().outcome {
            Some(Outcome::Succeeded(f)) => Ok(mesh_response(&headers, &id, &f, "hit")),
            Some(Outcome::Failed(e)) => Err(e.into()),
            Some(Outcome::Cancelled) => Err(ApiError::Cancelled),
            None => Err(ApiError::NotFinished(job.snapshot().status.as_str())),
        },
    }
}

/// `GET /v1/jobs/{id}/events`: server-sent events; a finished job sends its final event at
/// once. `Last-Event-ID` skips what the client has seen.
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
    Ok(match find(&state, &id).await? {
        Found::Cached(f) if last_seen == 0 => finished_stream(f).into_response(),
        Found::Cached(_) => Sse::new(stream::empty::<Result<Event, Infallible>>()).into_response(),
        Found::Job(job) => job_stream(job.attach(), last_seen).into_response(),
    })
}

/// `DELETE /v1/jobs/{id}`: cancels the job and answers with its final status.
pub async fn jobs_cancel(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let job = match find(&state, &id).await? {
        Found::Cached(f) => return Ok(axum::Json(status_body(&id, None, Some(&f))).into_response()),
        Found::Job(job) => job,
    };
    job.cancel();
    // The worker checks the flag between insertions, so this is milliseconds.
    let _ = tokio::time::timeout(Duration::from_secs(5), job.outcome()).await;
    Ok(axum::Json(status_body(&id, Some(&job.snapshot()), None)).into_response())
}

fn progress_event(seq: u64, p: &ProgressEvent) -> Event {
    Event::default().event("progress").id(seq.to_string()).json_data(p).expect("progress serializes")
}

fn final_event(seq: u64, outcome: &Outcome) -> Event {
    let event = Event::default().id(seq.to_string());
    match outcome {
        Outcome::Succeeded(f) => event.event("result").data(String::from_utf8_lossy(&f.body)),
        Outcome::Failed(e) => event.event("error").data(ApiError::from(e.clone()).to_json().to_string()),
        Outcome::Cancelled => event.event("error").data(ApiError::Cancelled.to_json().to_string()),
    }
}

/// One `result` event for a mesh that is already cached.
fn finished_stream(f: Arc<Finished>) -> Sse<impl Stream<Item = Result<Event, Infallible>>> {
    let event = final_event(1, &Outcome::Succeeded(f));
    Sse::new(stream::iter([Ok(event)])).keep_alive(KeepAlive::default())
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
    let rx = Job::subscribe(waiter.job());
    let watch = Watch { waiter, rx, last_seen, last_progress: None, done: false };
    let events = stream::unfold(watch, |mut w| async move {
        if w.done {
            return None;
        }
        loop {
            let snapshot = w.rx.borrow_and_update().clone();
            if let Some(outcome) = &snapshot.outcome {
                w.done = true;
                return (snapshot.seq > w.last_seen).then(|| (Ok(final_event(snapshot.seq, outcome)), w));
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
