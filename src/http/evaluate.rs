//! `POST /v1/jobs/{id}/evaluate`: F_n, the mesh's piecewise linear surrogate, at given points;
//! on a magnetostatic solution also B and H there, or the flux through a polyline and H's
//! line integral along it.

use super::extract::{Body, Media, Takes, media, parse_json};
use super::jobs::finished_result;
use super::problem::ApiError;
use super::state::AppState;
use crate::api::JsonError;
use crate::geom::Point;
use crate::result::locate::Locator;
use crate::result::probe::{self, LineError};
use axum::extract::{Path, State};
use axum::http::{HeaderMap, HeaderValue, header};
use axum::response::{IntoResponse, Response};
use std::sync::Arc;

/// The binary form of points and values: little-endian f64s.
const OCTET_STREAM: &str = "application/octet-stream";

/// What to evaluate: values at points, or a polyline's flux and line integral.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct Query {
    points: Option<Vec<[f64; 2]>>,
    polyline: Option<Vec<[f64; 2]>>,
}

#[derive(serde::Serialize)]
struct Values {
    values: Vec<Option<f64>>,
    /// B at each point, on a magnetostatic solution.
    #[serde(skip_serializing_if = "Option::is_none")]
    flux_density: Option<Vec<Option<[f64; 2]>>>,
    /// H at each point, on a magnetostatic solution.
    #[serde(skip_serializing_if = "Option::is_none")]
    field_strength: Option<Vec<Option<[f64; 2]>>>,
}

/// A 422 naming the request's field at `path`.
fn invalid(path: &str, message: impl Into<String>) -> ApiError {
    ApiError::Json(JsonError::Shape { path: path.into(), message: message.into() })
}

/// `POST /v1/jobs/{id}/evaluate`: `{"points": [[x, y], ...]}` answers `{"values": [...]}`
/// with `null` outside the domain; an `application/octet-stream` body of (x, y) f64 pairs
/// answers f64 values, NaN outside.
pub async fn jobs_evaluate(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
    body: Body,
) -> Result<Response, ApiError> {
    let (result, _) = finished_result(&state, &id).await?;
    let binary = media(&headers, &body.bytes, Takes::Binary)? == Media::Binary;
    let locators = state.locators.clone();
    crate::cpu::spawn(move || {
        let locator = match locators.get(&id) {
            Some((indexed, locator)) if indexed.upgrade().is_some_and(|r| Arc::ptr_eq(&r, &result)) => {
                locator
            }
            _ => {
                let locator = Arc::new(Locator::new(&result));
                locators.insert(id, (Arc::downgrade(&result), locator.clone()));
                locator
            }
        };
        if binary {
            if !body.bytes.len().is_multiple_of(16) {
                return Err(ApiError::InvalidRequest(format!(
                    "a binary body is (x, y) pairs of little-endian f64, 16 bytes each; got {} bytes",
                    body.bytes.len()
                )));
            }
            let f64_at = |c: &[u8]| f64::from_le_bytes(c.try_into().expect("8 bytes"));
            let points: Vec<Point> = body
                .bytes
                .chunks_exact(16)
                .map(|pair| Point::new(f64_at(&pair[..8]), f64_at(&pair[8..])))
                .collect();
            let out: Vec<u8> = locator.values(&points).iter().flat_map(|v| v.to_le_bytes()).collect();
            Ok(([(header::CONTENT_TYPE, HeaderValue::from_static(OCTET_STREAM))], out).into_response())
        } else {
            let query: Query = parse_json(&body.bytes)?;
            let to_points =
                |xy: Vec<[f64; 2]>| -> Vec<Point> { xy.iter().map(|&[x, y]| Point::new(x, y)).collect() };
            match (query.points, query.polyline) {
                (Some(points), None) => {
                    let points = to_points(points);
                    let values =
                        locator.values(&points).into_iter().map(|v| (!v.is_nan()).then_some(v)).collect();
                    let (flux_density, field_strength) = probe::fields_at(&result, &locator, &points).unzip();
                    Ok(axum::Json(Values { values, flux_density, field_strength }).into_response())
                }
                (None, Some(polyline)) => {
                    if polyline.len() < 2 {
                        let detail = format!("a polyline has at least 2 points, got {}", polyline.len());
                        return Err(invalid("polyline", detail));
                    }
                    let line = probe::line(&result, &locator, &to_points(polyline)).map_err(|e| match e {
                        LineError::Outside(i) => invalid(&format!("polyline[{i}]"), e.to_string()),
                        LineError::NotMagnetic => invalid("polyline", e.to_string()),
                    })?;
                    Ok(axum::Json(line).into_response())
                }
                _ => Err(invalid("points", "give points or a polyline, one of them")),
            }
        }
    })
    .await
    .map_err(|e| ApiError::Internal(format!("evaluation panicked: {e}")))?
}
