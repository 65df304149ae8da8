//! Handlers for meshes and jobs: create (synchronous or streamed), show, stream, fetch, cancel.

use super::extract::{Body, JobBody, Takes, names, parse_json};
use super::negotiate::{self, Wanted};
use super::problem::ApiError;
use super::sse;
use super::state::AppState;
use crate::api::{JobList, JobRequest, JobStatus, JsonError, Links, ResultEvent, SolveRequest, timestamp};
use crate::jobs::{Client, Found, JobError, Lifetime, Outcome, Record, Snapshot, Status, Ticket, Waiter};
use crate::output::Format;
use crate::refine::StopReason;
use crate::result::RunResult;
use crate::result::Stop;
use crate::spec::{JobKeys, JobSpec, Limits, job_keys};
use axum::Extension;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, Uri, header};
use axum::response::{IntoResponse, Response};
use bytes::Bytes;
use futures_util::stream;
use std::sync::Arc;
use std::time::Duration;

/// The most vertices one progress event carries (about 4 MB of JSON): a client that joins a
/// large job late, or stops reading, holds at most this much in its stream; the rest comes
/// with the next events, or in the result.
const POINTS_PER_EVENT: usize = 1 << 16;

/// What a route takes.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    /// A mesh request.
    Mesh,
    /// A boundary value problem.
    Solution,
    /// Either: a JSON body that names `physics` is a boundary value problem.
    Any,
}

impl Kind {
    /// The media types a route of this kind takes: a boundary value problem is JSON only.
    fn takes(self) -> Takes {
        match self {
            Kind::Solution => Takes::Json,
            Kind::Mesh | Kind::Any => Takes::Upload,
        }
    }
}

/// A mesh request; one that names `physics` (which only problems have) is pointed to the
/// route for problems. Looked at only when the parse fails, so a mesh body is read once.
fn mesh_request(json: &[u8]) -> Result<JobRequest<'_>, ApiError> {
    parse_json(json).map_err(|e| match e {
        ApiError::Json(JsonError::Shape { path, .. }) if path == "physics" => {
            let message = "`physics` names a boundary value problem: send it to POST /v1/solutions \
                           (or POST /v1/jobs); this route meshes a function or a grid";
            ApiError::Json(JsonError::Shape { path, message: message.into() })
        }
        e => e,
    })
}

/// JSON bodies up to this size are parsed on the async worker that read them.
const INLINE_BODY_BYTES: usize = 16 << 10;

/// Parses and validates a body read as `kind`, and hashes it: CPU work for a large grid.
fn parse_body(body: JobBody, kind: Kind, limits: &Limits) -> Result<(JobKeys, JobSpec), ApiError> {
    let spec = match body {
        JobBody::Json(json) if kind == Kind::Solution || (kind == Kind::Any && names(&json, "physics")) => {
            JobSpec::from_solve_request(parse_json::<SolveRequest>(&json)?, limits)?
        }
        JobBody::Json(json) => JobSpec::from_request(mesh_request(&json)?, limits)?,
        JobBody::Upload { request, grid } => JobSpec::from_upload(mesh_request(&request)?, &grid, limits)?,
    };
    Ok((job_keys(&spec), spec))
}

/// Parses, validates and hashes a body, off the async workers when it is large.
async fn prepare(
    state: &AppState,
    headers: &HeaderMap,
    body: Body,
    kind: Kind,
) -> Result<(JobKeys, JobSpec), ApiError> {
    let limits = state.limits;
    let body = JobBody::from_parts(headers, body.bytes, kind.takes()).await?;
    let inline = matches!(&body, JobBody::Json(json) if json.len() <= INLINE_BODY_BYTES);
    // A small JSON body parses in microseconds, less than a trip to the blocking pool; a grid
    // takes real CPU and goes there.
    let (keys, spec) = if inline {
        parse_body(body, kind, &limits)?
    } else {
        let _permit = state.parsers.acquire().await.map_err(|e| ApiError::Internal(e.to_string()))?;
        crate::cpu::spawn(move || parse_body(body, kind, &limits))
            .await
            .map_err(|e| ApiError::Internal(format!("request parsing panicked: {e}")))??
    };
    tracing::Span::current().record("job_id", keys.id.as_str());
    Ok((keys, spec))
}

fn wants_event_stream(headers: &HeaderMap) -> bool {
    headers
        .get_all(header::ACCEPT)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .any(|v| v.split(',').any(|t| t.trim().starts_with("text/event-stream")))
}

/// Where a job is now.
fn status_of(found: &Found) -> Status {
    found.record().status
}

/// The status document of a job as it is now.
fn status_body(id: &str, found: &Found) -> JobStatus {
    status_document(id, found.record())
}

/// The status document of job `id` whose state is `r`: the one mapping of [`Record`] to the
/// wire.
fn status_document(id: &str, r: Record) -> JobStatus {
    let problem = match (&r.error, r.status) {
        (Some(e), _) => Some(ApiError::from(e.clone()).to_json()),
        (None, Status::Cancelled) => Some(ApiError::Cancelled.to_json()),
        _ => None,
    };
    JobStatus {
        id: id.to_owned(),
        status: r.status.as_str(),
        progress: r.progress,
        stats: r.stats,
        elapsed_ms: r.elapsed.map(|d| d.as_secs_f64() * 1e3),
        created_at: r.times.map(|t| timestamp(t.created)),
        started_at: r.times.and_then(|t| t.started).map(timestamp),
        finished_at: r.times.and_then(|t| t.finished).map(timestamp),
        problem,
        evaluations: None,
        links: Links::of(id),
    }
}

/// Where `result` is served from: `otherwise`, unless a time limit stopped its run, which
/// makes it a partial answer whatever found it.
fn served(result: &RunResult, otherwise: negotiate::Provenance) -> negotiate::Provenance {
    match result.stats.stop() {
        Stop::Mesh(StopReason::TimeLimit) => negotiate::Provenance::Partial,
        _ => otherwise,
    }
}

/// `POST /v1/meshes`: the mesh, computed or cached, in the format asked for; with
/// `Accept: text/event-stream`, progress events and then the mesh document as one `result`
/// event.
pub async fn meshes_create(
    State(state): State<AppState>,
    Extension(client): Extension<Client>,
    uri: Uri,
    headers: HeaderMap,
    body: Body,
) -> Result<Response, ApiError> {
    create(state, &client, uri, headers, body, Kind::Mesh).await
}

/// `POST /v1/solutions`: as `POST /v1/meshes`, for a boundary value problem; the events are
/// one per solve.
pub async fn solutions_create(
    State(state): State<AppState>,
    Extension(client): Extension<Client>,
    uri: Uri,
    headers: HeaderMap,
    body: Body,
) -> Result<Response, ApiError> {
    create(state, &client, uri, headers, body, Kind::Solution).await
}

async fn create(
    state: AppState,
    client: &Client,
    uri: Uri,
    headers: HeaderMap,
    body: Body,
    kind: Kind,
) -> Result<Response, ApiError> {
    let stream = wants_event_stream(&headers);
    // A format nobody writes is refused before any work is done; a stream takes `inline`.
    let (wanted, options) = match stream {
        true => (None, StreamOptions::of(&uri, false)?),
        false => (Some(Wanted::from_request(&uri, &headers)?), StreamOptions::default()),
    };
    let (keys, spec) = prepare(&state, &headers, body, kind).await?;
    let id = keys.id.clone();
    let ticket = state.jobs.submit(keys, spec, Lifetime::WhileWaited, client).await?;
    let Some(wanted) = wanted else {
        // An answer at once is the stream's one event, id 1.
        let mut response = match ticket {
            Ticket::Cached(r) | Ticket::Prefix(r) => {
                let status = status_document(&id, Record::cached(&r));
                final_stream(&status, &Outcome::Succeeded(r), 1, options.inline)
            }
            Ticket::Failed(e) => final_stream(
                &status_body(&id, &Found::Done(failed(e.clone()))),
                &Outcome::Failed(e),
                1,
                options.inline,
            ),
            Ticket::Job(waiter) => job_stream(waiter, 0, options),
        };
        // The job the stream's links name, for a client that reads headers.
        let location = HeaderValue::from_str(&format!("/v1/jobs/{id}")).expect("ascii path");
        response.headers_mut().insert(header::CONTENT_LOCATION, location);
        return Ok(response);
    };
    match ticket {
        Ticket::Cached(r) => {
            negotiate::result_response(&headers, &wanted, &id, r, negotiate::Provenance::Hit, None).await
        }
        Ticket::Prefix(r) => {
            negotiate::result_response(&headers, &wanted, &id, r, negotiate::Provenance::Prefix, None).await
        }
        Ticket::Failed(e) => Err(e.into()),
        // The waiter is dropped with this future if the client hangs up, which cancels a job
        // nobody else waits on.
        Ticket::Job(waiter) => match waiter.job().outcome().await {
            Outcome::Succeeded(r) => {
                let elapsed = waiter.job().snapshot().elapsed;
                let provenance = served(&r, negotiate::Provenance::Miss);
                negotiate::result_response(&headers, &wanted, &id, r, provenance, elapsed).await
            }
            Outcome::Failed(e) => Err(e.into()),
            Outcome::Cancelled => Err(ApiError::Cancelled),
        },
    }
}

/// The record of a job that failed before it ran (a replay that failed).
fn failed(e: JobError) -> Arc<Record> {
    Arc::new(Record {
        status: Status::Failed,
        progress: None,
        stats: None,
        error: Some(e),
        elapsed: None,
        last_event: 0,
        times: None,
    })
}

/// `POST /v1/jobs`: starts (or finds) a job that runs whether or not anyone waits; a body
/// that names `physics` is a boundary value problem.
pub async fn jobs_create(
    State(state): State<AppState>,
    Extension(client): Extension<Client>,
    headers: HeaderMap,
    body: Body,
) -> Result<Response, ApiError> {
    if names(&body.bytes, "source") {
        return super::client::create(&state, &body, &client).await;
    }
    let (keys, spec) = prepare(&state, &headers, body, Kind::Any).await?;
    let id = keys.id.clone();
    let (code, status) = match state.jobs.submit(keys, spec, Lifetime::Detached, &client).await? {
        Ticket::Cached(f) | Ticket::Prefix(f) => (StatusCode::OK, status_body(&id, &Found::Cached(f))),
        Ticket::Failed(e) => (StatusCode::OK, status_body(&id, &Found::Done(failed(e)))),
        Ticket::Job(waiter) => (StatusCode::ACCEPTED, status_body(&id, &Found::Job(waiter.job().clone()))),
    };
    let location = HeaderValue::from_str(&status.links.this).expect("ascii path");
    let mut response = (code, [(header::LOCATION, location)], axum::Json(status)).into_response();
    if code == StatusCode::ACCEPTED {
        // When to look again: about when a worker is likely to have news.
        response.headers_mut().insert(header::RETRY_AFTER, HeaderValue::from(state.jobs.retry_after()));
    }
    Ok(response)
}

async fn find(state: &AppState, id: &str) -> Result<Found, ApiError> {
    tracing::Span::current().record("job_id", id);
    match state.jobs.find(id).await {
        Some(found) => Ok(found),
        // Another replica may run it: only Redis would say.
        None if state.jobs.redis() == Some(false) => Err(ApiError::Unreachable),
        None => Err(ApiError::NotFound(format!("no job with id {id}"))),
    }
}

/// The query of `GET /v1/jobs`.
#[derive(Debug, Default, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct ListQuery {
    status: Option<String>,
    limit: Option<u64>,
    cursor: Option<String>,
}

/// The jobs a page lists when the query does not say.
const DEFAULT_LIST_LIMIT: u64 = 20;
/// The most a page lists.
const MAX_LIST_LIMIT: u64 = 100;

/// `GET /v1/jobs?status=&limit=&cursor=`: the jobs the caller submitted to this replica (by
/// its key, or its address without keys), newest first. `next` is the address of the page of
/// older ones.
pub async fn jobs_list(
    State(state): State<AppState>,
    Extension(client): Extension<Client>,
    uri: Uri,
) -> Result<Response, ApiError> {
    let query: ListQuery = super::extract::query(&uri)?;
    let status = match query.status.as_deref() {
        None => None,
        Some(name) => Some(Status::parse(name).ok_or_else(|| {
            ApiError::InvalidRequest(format!(
                "status `{name}` is not one of queued, running, succeeded, failed, cancelled"
            ))
        })?),
    };
    let limit = query.limit.unwrap_or(DEFAULT_LIST_LIMIT);
    if !(1..=MAX_LIST_LIMIT).contains(&limit) {
        return Err(ApiError::InvalidRequest(format!(
            "limit must be from 1 to {MAX_LIST_LIMIT}, got {limit}"
        )));
    }
    let before = match query.cursor.as_deref() {
        None => None,
        Some(text) => Some(text.parse::<u64>().map_err(|_| {
            ApiError::InvalidRequest(format!("cursor `{text}` is not one a job list gave (its `next`)"))
        })?),
    };
    // A caller's own: its key's, or without keys its address's. Job ids are not guessable;
    // a list of everyone's would hand them out.
    let client_status = |id: &str| state.clients.local(id).map(|job| super::client::status(&job));
    let elsewhere = |id: &str| client_status(id).and_then(|s| Status::parse(s.status));
    let (page, next) = state.jobs.list(Some(&client), status, before, limit as usize, elsewhere);
    let jobs = page
        .into_iter()
        .filter_map(|(submission, record)| {
            let mut status = match record {
                Some(record) => status_document(&submission.id, record),
                // A client job: its own status document, as GET /v1/jobs/{id} shows it.
                None => client_status(&submission.id)?,
            };
            status.created_at = Some(timestamp(submission.at));
            Some(status)
        })
        .collect();
    let next = next.map(|cursor| {
        let status = query.status.as_deref().map_or_else(String::new, |s| format!("&status={s}"));
        format!("/v1/jobs?limit={limit}{status}&cursor={cursor}")
    });
    Ok(axum::Json(JobList { jobs, next }).into_response())
}

/// `GET /v1/jobs/{id}`.
pub async fn jobs_show(State(state): State<AppState>, Path(id): Path<String>) -> Result<Response, ApiError> {
    if let Some(job) = super::client::lookup(&state, &id).await {
        return Ok(axum::Json(super::client::status(&job)).into_response());
    }
    let found = find(&state, &id).await?;
    Ok(axum::Json(status_body(&id, &found)).into_response())
}

/// The outcome of a finished job, its result fetched back from the cache (or, for a run its
/// time limit stopped, from the partial results), with how long the engine ran.
async fn finished_outcome(state: &AppState, id: &str, found: Found) -> Option<(Outcome, Option<Duration>)> {
    match found {
        Found::Cached(r) => Some((Outcome::Succeeded(r), None)),
        Found::Remote(_) => None,
        Found::Job(job) => {
            let s = job.snapshot();
            s.outcome.map(|o| (o, s.elapsed))
        }
        Found::Done(r) => Some(match (&r.error, r.status) {
            (Some(e), _) => (Outcome::Failed(e.clone()), r.elapsed),
            (None, Status::Cancelled) => (Outcome::Cancelled, r.elapsed),
            _ => {
                let stopped_by_time =
                    r.stats.as_ref().is_some_and(|s| s.stop() == Stop::Mesh(StopReason::TimeLimit));
                let result = match stopped_by_time {
                    true => state.jobs.partial(id).await,
                    false => state.jobs.cached(id).await,
                };
                (result.map_or(Outcome::Failed(JobError::Evicted), Outcome::Succeeded), r.elapsed)
            }
        }),
    }
}

/// The result of finished job `id` and how long its engine ran: 404 for an unknown job, 409
/// for one not finished (or cancelled), the job's problem for one that failed.
pub(super) async fn finished_result(
    state: &AppState,
    id: &str,
) -> Result<(Arc<RunResult>, Option<Duration>), ApiError> {
    if let Some(job) = super::client::lookup(state, id).await {
        let s = job.status(std::time::Instant::now());
        return s.result.map(|r| (r, None)).ok_or(ApiError::NotFinished(s.status, 1));
    }
    let found = find(state, id).await?;
    let status = status_of(&found).as_str();
    match finished_outcome(state, id, found).await {
        Some((Outcome::Succeeded(r), elapsed)) => Ok((r, elapsed)),
        Some((Outcome::Failed(e), _)) => Err(e.into()),
        Some((Outcome::Cancelled, _)) => Err(ApiError::Cancelled),
        None => Err(ApiError::NotFinished(status, state.jobs.retry_after())),
    }
}

/// `GET /v1/jobs/{id}/mesh`: 200 with the mesh in the format asked for, 409 while it is not
/// finished.
pub async fn jobs_mesh(
    State(state): State<AppState>,
    Path(id): Path<String>,
    uri: Uri,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let wanted = Wanted::from_request(&uri, &headers)?;
    let (result, elapsed) = finished_result(&state, &id).await?;
    let provenance = served(&result, negotiate::Provenance::Hit);
    negotiate::result_response(&headers, &wanted, &id, result, provenance, elapsed).await
}

/// The id of a finished job's final event for a client that has seen `last_seen`, or `None`
/// when the client has seen it. The final event's id is one more than the job's last progress
/// event's; for a result found in the cache alone, whose events are not known, it is the one
/// after the client's.
fn final_event_id(found: &Found, last_seen: u64) -> Option<u64> {
    let known = match found {
        Found::Job(job) => Some(job.snapshot()).filter(|s| s.outcome.is_some()).map_or(0, |s| s.seq),
        Found::Done(record) => record.last_event,
        // Not finished (the caller looks again), or finished with no events known.
        Found::Remote(_) | Found::Cached(_) => 0,
    };
    match known {
        0 => Some(last_seen + 1),
        id => (last_seen < id).then_some(id),
    }
}

/// `GET /v1/jobs/{id}/events`: server-sent events; a finished job sends its final event at
/// once. `Last-Event-ID` skips what the client has seen; once it has seen the final event,
/// the answer is 204, which tells an EventSource to stop reconnecting.
pub async fn jobs_events(
    State(state): State<AppState>,
    Path(id): Path<String>,
    uri: Uri,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let options = StreamOptions::of(&uri, true)?;
    let last_seen = headers
        .get("last-event-id")
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.trim().parse::<u64>().ok())
        .unwrap_or(0);
    if let Some(job) = super::client::lookup(&state, &id).await {
        return Ok(super::client::events(state.clients.clone(), job, last_seen, options.inline));
    }
    let found = find(&state, &id).await?;
    if let Found::Job(_) | Found::Remote(_) = &found
        && let Some(waiter) = state.jobs.watch(&id).await
    {
        return Ok(job_stream(waiter, last_seen, options));
    }
    if let Some(response) = final_response(&state, &id, found, last_seen, options.inline).await {
        return Ok(response);
    }
    // Finished between the two looks (its record is there now), or Redis stopped answering.
    let found = find(&state, &id).await?;
    final_response(&state, &id, found, last_seen, options.inline).await.ok_or(ApiError::Unreachable)
}

/// The stream of a finished job's final event, or 204 for a client that has seen it; `None`
/// when `found` is not finished.
async fn final_response(
    state: &AppState,
    id: &str,
    found: Found,
    last_seen: u64,
    inline: bool,
) -> Option<Response> {
    let Some(event_id) = final_event_id(&found, last_seen) else {
        return Some(StatusCode::NO_CONTENT.into_response());
    };
    let status = status_body(id, &found);
    let (outcome, _) = finished_outcome(state, id, found).await?;
    Some(final_stream(&status, &outcome, event_id, inline))
}

/// What a client asks of a stream: `?vertices=true` (progress events carry the new
/// vertices) and `?inline=mesh` (the result event carries the mesh document).
#[derive(Debug, Clone, Copy, Default)]
struct StreamOptions {
    points: bool,
    inline: bool,
}

impl StreamOptions {
    /// The options `uri` asks for; `vertices` only where `points` are sent (the events route).
    fn of(uri: &Uri, points: bool) -> Result<Self, ApiError> {
        #[derive(serde::Deserialize)]
        #[serde(deny_unknown_fields)]
        struct Query {
            vertices: Option<bool>,
            inline: Option<String>,
        }
        let query: Query = super::extract::query(uri)?;
        if query.vertices.is_some() && !points {
            let detail =
                "vertices applies to GET /v1/jobs/{id}/events (a stream's id is in Content-Location)";
            return Err(ApiError::InvalidRequest(detail.into()));
        }
        let inline = match query.inline.as_deref() {
            None => false,
            Some("mesh") => true,
            Some(other) => {
                return Err(ApiError::InvalidRequest(format!(
                    "inline `{other}` is not known; `inline=mesh` is"
                )));
            }
        };
        Ok(Self { points: query.vertices.unwrap_or(false), inline })
    }
}

/// `DELETE /v1/jobs/{id}`: cancels the job, wherever it runs, and answers with its status
/// once it has stopped (or after 5 s, as it is then).
pub async fn jobs_cancel(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    if let Some(job) = super::client::lookup(&state, &id).await {
        state.clients.cancel(&job, std::time::Instant::now()).await.map_err(|_| ApiError::Unreachable)?;
        return Ok(axum::Json(super::client::status(&job)).into_response());
    }
    let found = find(&state, &id).await?;
    // Waiting on the job (here, or a mirror of it) until it has stopped.
    let waiter = match found {
        Found::Job(_) | Found::Remote(_) => state.jobs.watch(&id).await,
        _ => None,
    };
    let Some(waiter) = waiter else {
        // Another replica runs it, and it could not be reached to be told.
        if let Found::Remote(_) = found {
            return Err(ApiError::Unreachable);
        }
        return Ok(axum::Json(status_body(&id, &found)).into_response());
    };
    let job = waiter.job().clone();
    state.jobs.cancel(&job).await.map_err(|_| ApiError::Unreachable)?;
    // The worker checks the flag between insertions, so this is milliseconds (and a renewal
    // on another replica).
    let _ = tokio::time::timeout(Duration::from_secs(5), job.outcome()).await;
    Ok(axum::Json(status_body(&id, &Found::Job(job))).into_response())
}

/// The final event of the job `status` shows, with id `event_id`: its status and links (with
/// `inline`, its mesh document), or the problem that ended it; none for a job handed to
/// another replica at shutdown, so that the client reconnects (with its last event's id) and
/// follows the job there.
fn final_event(
    status: &JobStatus,
    outcome: &Outcome,
    event_id: u64,
    inline: bool,
) -> Box<dyn Iterator<Item = Bytes> + Send> {
    match outcome {
        Outcome::Failed(JobError::HandedBack) => Box::new(std::iter::empty()),
        Outcome::Succeeded(r) if inline => Box::new(sse::result(event_id, &status.id, r)),
        Outcome::Succeeded(_) => {
            let formats = Format::ALL.iter().map(|f| f.name());
            Box::new(std::iter::once(sse::finished(event_id, &ResultEvent::of(status.clone(), formats))))
        }
        Outcome::Failed(e) => {
            Box::new(std::iter::once(sse::error(event_id, &ApiError::from(e.clone()).to_json())))
        }
        Outcome::Cancelled => Box::new(std::iter::once(sse::error(event_id, &ApiError::Cancelled.to_json()))),
    }
}

/// Just the final event, for a job that has finished.
fn final_stream(status: &JobStatus, outcome: &Outcome, event_id: u64, inline: bool) -> Response {
    sse::response(stream::iter(final_event(status, outcome, event_id, inline)))
}

struct Watch {
    /// Keeps the job alive for this client; dropped with the stream when it disconnects.
    waiter: Waiter,
    rx: tokio::sync::watch::Receiver<Snapshot>,
    last_seen: u64,
    /// With `?vertices=true`: the vertices this client has been sent.
    points_sent: Option<usize>,
    /// With `?inline=mesh`: the result event carries the mesh.
    inline: bool,
    /// The rest of the final event, once the job has finished.
    rest: Option<Box<dyn Iterator<Item = Bytes> + Send>>,
}

/// Progress events (as often as the job publishes them, a slow client skipping to the newest)
/// and the final event of a job, skipping ids ≤ `last_seen`, with a keep-alive comment
/// whenever the job is silent for [`sse::KEEP_ALIVE`]. With `points`, each progress event
/// carries the vertices added since the last one this client was sent, at most
/// [`POINTS_PER_EVENT`] (from the first: a reconnecting client starts again at 0).
fn job_stream(waiter: Waiter, last_seen: u64, options: StreamOptions) -> Response {
    let rx = waiter.job().subscribe();
    let points_sent = options.points.then_some(0);
    let watch = Watch { waiter, rx, last_seen, points_sent, inline: options.inline, rest: None };
    let events = stream::unfold(watch, |mut w| async move {
        loop {
            if let Some(rest) = &mut w.rest {
                return rest.next().map(|chunk| (chunk, w));
            }
            let snapshot = w.rx.borrow_and_update().clone();
            if let Some(outcome) = &snapshot.outcome {
                if w.last_seen >= snapshot.seq {
                    return None;
                }
                let status = status_document(w.waiter.job().id(), Record::of(&snapshot));
                w.rest = Some(final_event(&status, outcome, snapshot.seq, w.inline));
                continue;
            }
            if let Some(progress) = snapshot.progress.filter(|_| snapshot.seq > w.last_seen) {
                w.last_seen = snapshot.seq;
                let Some(sent) = w.points_sent else {
                    return Some((sse::progress(snapshot.seq, &progress, None), w));
                };
                let points = w.waiter.job().points(sent, progress.vertices.min(sent + POINTS_PER_EVENT));
                w.points_sent = Some(sent + points.len());
                return Some((sse::progress(snapshot.seq, &progress, Some((sent, &points))), w));
            }
            match tokio::time::timeout(sse::KEEP_ALIVE, w.rx.changed()).await {
                Err(_) => return Some((sse::keep_alive(), w)),
                Ok(Ok(())) => {}
                Ok(Err(_)) => {
                    tracing::warn!(job = %w.waiter.job().id(), "job state closed without an outcome");
                    return None;
                }
            }
        }
    });
    sse::response(events)
}
