//! Client jobs over HTTP: `POST /v1/jobs` with `"source": "client"` makes one,
//! `GET /v1/jobs/{id}/ask` hands out a batch of points, `POST /v1/jobs/{id}/tell` takes their
//! values; `GET /v1/jobs/{id}/events` announces each batch as an `ask` event. The job's
//! status and mesh are served where every job's are.

use super::extract::{Body, parse_json, query};
use super::problem::ApiError;
use super::sse;
use super::state::AppState;
use crate::api::{
    AskAnswer, AskedPoint, ClientJobRequest, JobStatus, JsonError, Links, ResultEvent, TellAnswer,
    TellRequest, timestamp,
};
use crate::jobs::{
    Asked, Client, ClientError, ClientJob, ClientJobs, ClientStatus, MAX_CLIENT_JOBS, TellError,
};
use crate::output::Format;
use crate::refine::asked::Values;
use crate::spec::{ClientSpec, SpecError};
use axum::extract::{Path, State};
use axum::http::{HeaderValue, StatusCode, Uri, header};
use axum::response::{IntoResponse, Response};
use bytes::Bytes;
use futures_util::stream;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// The longest `GET /v1/jobs/{id}/ask?wait=` holds a request, in ms: under the 10 s a client
/// or a proxy commonly allows an answer; a caller asks again.
pub const MAX_WAIT_MS: u64 = 9_000;

/// `POST /v1/jobs` with `"source": "client"`: 202 with the job's status, asking for its
/// corners (or, `from` another job, for what that job was not told); `client`'s job list
/// shows it.
pub(super) async fn create(state: &AppState, body: &Body, client: &Client) -> Result<Response, ApiError> {
    let request: ClientJobRequest = parse_json(&body.bytes)?;
    // The log keeps the request as sent, for another replica to check and rebuild.
    let logged: serde_json::Value = parse_json(&body.bytes)?;
    let seeds = match &request.from {
        Some(from) => {
            let source = state.clients.get(from).await.map_err(|_| ApiError::Unreachable)?;
            let source = source.ok_or_else(|| {
                ApiError::Spec(SpecError::Field {
                    field: "from".into(),
                    detail: format!(
                        "no client job with id {from}: `from` names a client job whose values to reuse"
                    ),
                })
            })?;
            source.values()
        }
        None => Values::new(),
    };
    let spec = ClientSpec::from_request(request, &state.limits)?;
    let job = state.clients.create(logged, spec, seeds, Instant::now()).await.map_err(client_error)?;
    state.jobs.note_submission(&job.id, client);
    let status = status(&job);
    let location = HeaderValue::from_str(&status.links.this).expect("ascii path");
    let headers = [(header::LOCATION, location), (header::RETRY_AFTER, HeaderValue::from_static("0"))];
    Ok((StatusCode::ACCEPTED, headers, axum::Json(status)).into_response())
}

/// Client job `id`'s status document.
pub(super) fn status(job: &ClientJob) -> JobStatus {
    document(job, &job.status(Instant::now()))
}

/// The status document of `job` as `s` says it stands.
fn document(job: &ClientJob, s: &ClientStatus) -> JobStatus {
    let problem = s.problem.clone().map(|detail| ApiError::ClientJobFailed(detail).to_json());
    JobStatus {
        id: job.id.clone(),
        status: s.status,
        progress: None,
        stats: s.result.as_ref().map(|r| r.stats.clone()),
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
async fn find(state: &AppState, id: &str) -> Result<Arc<ClientJob>, ApiError> {
    let job = state.clients.get(id).await.map_err(|_| ApiError::Unreachable)?;
    job.ok_or_else(|| {
        ApiError::NotFound(format!(
            "no client job with id {id} (only a job made with \"source\": \"client\" asks for points)"
        ))
    })
}

/// Client job `id` if there is one, for a handler that serves any job: a store that does
/// not answer leaves the id to the other jobs' lookup, which says so.
pub(super) async fn lookup(state: &AppState, id: &str) -> Option<Arc<ClientJob>> {
    state.clients.get(id).await.ok().flatten()
}

/// The problem of a client job that was not made or not told.
fn client_error(e: ClientError) -> ApiError {
    match e {
        ClientError::TooMany => ApiError::ClientJobsFull(MAX_CLIENT_JOBS),
        ClientError::Unreachable => ApiError::Unreachable,
        ClientError::Tell(TellError::Conflict { index, id, was, told }) => ApiError::Conflict {
            field: format!("values[{index}].value"),
            detail: format!("point {id} was told {}, not {}", said(was), said(told)),
        },
        ClientError::Tell(TellError::Unknown { index, id }) => ApiError::Json(JsonError::Shape {
            path: format!("values[{index}].id"),
            message: format!("no point {id} was asked for"),
        }),
        ClientError::Tell(TellError::Finished { index }) => ApiError::Json(JsonError::Shape {
            path: format!("values[{index}].id"),
            message: "the job has finished: it takes no new values".into(),
        }),
    }
}

/// A value told, as a message says it.
fn said(value: Option<f64>) -> String {
    value.map_or("null (failed)".to_owned(), |v| v.to_string())
}

/// The query of `GET /v1/jobs/{id}/ask`.
#[derive(Debug, Default, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct AskQuery {
    wait: Option<u64>,
}

/// The query of `POST /v1/jobs/{id}/tell`.
#[derive(Debug, Default, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct TellQuery {
    ask: Option<u64>,
}

/// A wait of `ms` (named `name` in the query), checked against [`MAX_WAIT_MS`].
fn wait_of(name: &str, ms: u64) -> Result<Duration, ApiError> {
    if ms > MAX_WAIT_MS {
        return Err(ApiError::InvalidRequest(format!("{name} must be from 0 to {MAX_WAIT_MS} ms, got {ms}")));
    }
    Ok(Duration::from_millis(ms))
}

/// What an asker is given.
enum Given {
    /// Points, or none once the job has finished.
    Answer(AskAnswer),
    /// Nothing within the wait: ask again after this many seconds.
    Nothing(u64),
}

/// The current batch's untold points, leased to the caller, waiting up to `wait` for them
/// while another caller holds them or the next batch is being chosen.
async fn hand_out(state: &AppState, job: &Arc<ClientJob>, wait: Duration) -> Given {
    let deadline = tokio::time::Instant::now() + wait;
    loop {
        // Listen before looking, so a change between the two is not missed.
        let changed = job.changed();
        tokio::pin!(changed);
        changed.as_mut().enable();
        match job.ask(Instant::now()) {
            Asked::Batch { number, points, lease } => {
                return Given::Answer(batch_answer(number, points, lease));
            }
            Asked::Finished => {
                let status = job.status(Instant::now()).status;
                return Given::Answer(AskAnswer { status, batch: None, points: vec![], lease_ms: None });
            }
            Asked::Wait { until } => {
                let now = tokio::time::Instant::now();
                if now >= deadline {
                    // A lease's end is when the batch comes round again.
                    let seconds =
                        until.map_or(1, |t| t.saturating_duration_since(Instant::now()).as_secs().max(1));
                    return Given::Nothing(seconds);
                }
                let lease_end = until.map_or(deadline, |t| now + t.saturating_duration_since(Instant::now()));
                state.clients.wait(job, changed, deadline.min(lease_end)).await;
            }
        }
    }
}

/// `GET /v1/jobs/{id}/ask?wait=ms`: the current batch's untold points, leased to the caller;
/// 204 with `Retry-After` when another caller holds them or the next batch is being chosen
/// and nothing changed within `wait`; once finished, the status and no points.
pub async fn jobs_ask(
    State(state): State<AppState>,
    Path(id): Path<String>,
    uri: Uri,
) -> Result<Response, ApiError> {
    let job = find(&state, &id).await?;
    let query: AskQuery = query(&uri)?;
    let wait = wait_of("wait", query.wait.unwrap_or(0))?;
    Ok(match hand_out(&state, &job, wait).await {
        Given::Answer(answer) => axum::Json(answer).into_response(),
        Given::Nothing(seconds) => {
            let mut response = StatusCode::NO_CONTENT.into_response();
            response.headers_mut().insert(header::RETRY_AFTER, HeaderValue::from(seconds));
            response
        }
    })
}

/// `POST /v1/jobs/{id}/tell?ask=ms`: values for points asked, all or none. A value told again
/// is a no-op; a different one is a 409 naming the entry; an id never asked is a 422 naming
/// it. The value completing a batch sets the next one choosing on the blocking pool; with
/// `ask`, the answer carries what `ask?wait=ms` would give next.
pub async fn jobs_tell(
    State(state): State<AppState>,
    Path(id): Path<String>,
    uri: Uri,
    body: Body,
) -> Result<Response, ApiError> {
    let job = find(&state, &id).await?;
    let query: TellQuery = query(&uri)?;
    let ask = query.ask.map(|ms| wait_of("ask", ms)).transpose()?;
    let request: TellRequest = parse_json(&body.bytes)?;
    let values: Vec<(u64, Option<f64>)> = request.values.iter().map(|v| (v.id, v.value)).collect();
    let accepted = state.clients.tell(&job, &values, Instant::now()).await.map_err(client_error)?;
    let next = match ask {
        Some(wait) => match hand_out(&state, &job, wait).await {
            Given::Answer(answer) => Some(answer),
            Given::Nothing(_) => None,
        },
        None => None,
    };
    let s = job.status(Instant::now());
    Ok(axum::Json(TellAnswer { status: s.status, accepted, evaluations: s.evaluations, next })
        .into_response())
}

/// The data of an `ask` event and of `GET /v1/jobs/{id}/ask`'s answer while points are out.
fn batch_answer(number: u64, points: Vec<(u64, crate::geom::Point)>, lease: Duration) -> AskAnswer {
    let points = points.into_iter().map(|(id, p)| AskedPoint { id, x: p.x, y: p.y }).collect();
    AskAnswer { status: "running", batch: Some(number), points, lease_ms: Some(lease.as_millis() as u64) }
}

/// `GET /v1/jobs/{id}/events` of a client job: an `ask` event for each batch (its number as
/// the event id, its untold points as data, leased to nobody: any listener may evaluate and
/// tell them, or lease them through `ask`), then the final event as any job's, with the id
/// after the last batch's. A listener that falls behind skips to the newest batch; the stream
/// ends after [`sse::KEEP_ALIVE`] without news, and `Last-Event-ID` resumes it (a 204 once
/// the listener has seen the end).
pub(super) fn events(clients: ClientJobs, job: Arc<ClientJob>, last_seen: u64, inline: bool) -> Response {
    let (number, _) = job.current(Instant::now());
    if job.is_finished(Instant::now()) && last_seen > number {
        return StatusCode::NO_CONTENT.into_response();
    }
    struct Listener {
        clients: ClientJobs,
        job: Arc<ClientJob>,
        last_seen: u64,
        inline: bool,
        rest: Option<Box<dyn Iterator<Item = Bytes> + Send>>,
        /// When the stream ends if nothing more comes.
        quiet: tokio::time::Instant,
    }
    // A caller may take hours between batches: rather than hold the stream (and a proxy's
    // connection) open, it ends after a quiet spell, and the listener comes back with
    // Last-Event-ID, as an EventSource does by itself.
    let quiet = tokio::time::Instant::now() + sse::KEEP_ALIVE;
    let listener = Listener { clients, job, last_seen, inline, rest: None, quiet };
    let events = stream::unfold(listener, |mut l| async move {
        loop {
            if let Some(rest) = &mut l.rest {
                return rest.next().map(|chunk| (chunk, l));
            }
            let job = l.job.clone();
            // Listen before looking, so a change between the two is not missed.
            let changed = job.changed();
            tokio::pin!(changed);
            changed.as_mut().enable();
            let (number, points) = job.current(Instant::now());
            if let Some(points) = points.filter(|_| number > l.last_seen) {
                l.last_seen = number;
                l.quiet = tokio::time::Instant::now() + sse::KEEP_ALIVE;
                let data =
                    serde_json::to_string(&batch_answer(number, points, job.lease())).expect("serializes");
                return Some((Bytes::from(format!("event: ask\nid: {number}\ndata: {data}\n\n")), l));
            }
            if job.is_finished(Instant::now()) {
                if l.last_seen > number {
                    return None;
                }
                l.last_seen = number + 1;
                l.rest = Some(final_event(&job, number + 1, l.inline));
                continue;
            }
            if tokio::time::Instant::now() >= l.quiet {
                return None;
            }
            l.clients.wait(&job, changed, l.quiet).await;
        }
    });
    sse::response(events)
}

/// A finished client job's final event with id `id`: `result` (with the mesh when `inline`),
/// or `error` with the problem.
fn final_event(job: &ClientJob, id: u64, inline: bool) -> Box<dyn Iterator<Item = Bytes> + Send> {
    let s = job.status(Instant::now());
    match &s.result {
        Some(result) if inline => Box::new(sse::result(id, &job.id, result)),
        Some(_) => {
            let formats = Format::ALL.iter().map(|f| f.name());
            Box::new(std::iter::once(sse::finished(id, &ResultEvent::of(document(job, &s), formats))))
        }
        None => {
            let problem = match s.problem {
                Some(detail) => ApiError::ClientJobFailed(detail),
                None => ApiError::Cancelled,
            };
            Box::new(std::iter::once(sse::error(id, &problem.to_json())))
        }
    }
}
