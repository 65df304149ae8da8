//! Handlers for datasets (DEMs uploaded or named in the settings) and their terrain tiles:
//! `layer.json` and each `z/x/y.terrain`, gzipped when the client takes it, with entity tags
//! known before a tile is made.

use super::extract::{Body, JobBody, Takes};
use super::negotiate::not_modified;
use super::problem::ApiError;
use super::state::AppState;
use crate::api::{DatasetInfo, DatasetLinks, DatasetList};
use crate::datasets::{Added, Dataset, DatasetError, Origin};
use crate::tiles::{TileId, Wanted};
use axum::extract::{Path, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, Uri, header};
use axum::response::{IntoResponse, Response};
use std::io::Read;
use std::sync::Arc;

/// How long a client may keep a tile of a dataset named in the settings: its file may be
/// replaced at a restart. An uploaded dataset's tiles never change (its id is its content,
/// and the URL names the engine's version).
const FILE_MAX_AGE: &str = "max-age=3600";
const UPLOAD_MAX_AGE: &str = "max-age=31536000, immutable";

/// The media type of a tile, as Cesium's servers name it.
const QUANTIZED_MESH: &str = "application/vnd.quantized-mesh";

/// `POST /v1/datasets`: a GeoTIFF as multipart (`-F grid=@dem.tif`). 201 with its
/// description and `Location` when new, 200 when the same file is already a dataset.
pub async fn datasets_create(
    State(state): State<AppState>,
    headers: HeaderMap,
    body: Body,
) -> Result<Response, ApiError> {
    let file = match JobBody::from_parts(&headers, body.bytes, Takes::Upload).await? {
        JobBody::Upload { request, grid } if request.as_ref() == b"{}" => grid,
        JobBody::Upload { .. } => {
            return Err(ApiError::InvalidRequest(
                "a dataset is its file alone: send only the `grid` part (curl -F grid=@dem.tif)".into(),
            ));
        }
        JobBody::Json(_) => {
            return Err(ApiError::UnsupportedMediaType {
                detail: "a dataset is a GeoTIFF sent as multipart/form-data: curl -F grid=@dem.tif".into(),
                accepted: &["multipart/form-data"],
            });
        }
    };
    let added = state.datasets.add(file, state.limits.max_grid_points).await.map_err(|e| match e {
        DatasetError::OverBudget(o) => ApiError::OverBudget(o.needed, o.available, state.jobs.retry_after()),
        e => e.into(),
    })?;
    let Added { dataset, created, shared } = added;
    tracing::info!(dataset = dataset.id(), created, ?shared, "dataset uploaded");
    let info = DatasetInfo { shared, ..describe(&dataset) };
    let location = HeaderValue::from_str(&info.links.this).expect("hex ids");
    let status = if created { StatusCode::CREATED } else { StatusCode::OK };
    Ok((status, [(header::LOCATION, location)], axum::Json(info)).into_response())
}

/// `GET /v1/datasets`.
pub async fn datasets_list(State(state): State<AppState>) -> axum::Json<DatasetList> {
    axum::Json(DatasetList { datasets: state.datasets.list().iter().map(|d| describe(d)).collect() })
}

/// `GET /v1/datasets/{id}`.
pub async fn datasets_show(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<axum::Json<DatasetInfo>, ApiError> {
    Ok(axum::Json(describe(&*find(&state, &id).await?)))
}

/// `DELETE /v1/datasets/{id}`: an uploaded dataset and its cached tiles, on every replica.
pub async fn datasets_delete(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<StatusCode, ApiError> {
    state.datasets.delete(&id).await?;
    Ok(StatusCode::NO_CONTENT)
}

/// `GET /v1/tiles/{id}/layer.json`: what a terrain provider is pointed at.
pub async fn tiles_layer(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let dataset = find(&state, &id).await?;
    let tag = HeaderValue::from_str(&dataset.layer_etag()).expect("hex tags");
    let mut response = if not_modified(&headers, &tag) {
        StatusCode::NOT_MODIFIED.into_response()
    } else {
        axum::Json(dataset.pyramid().layer_json(dataset.id(), &dataset.version())).into_response()
    };
    let h = response.headers_mut();
    h.insert(header::ETAG, tag);
    let scope = if state.keyed { "private, max-age=60" } else { "public, max-age=60" };
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static(scope));
    Ok(response)
}

/// `GET /v1/tiles/{id}/{z}/{x}/{y}.terrain`: the quantized-mesh-1.0 tile with the extensions
/// asked for (`?extensions=` or `Accept`), gzipped when the client accepts gzip.
pub async fn tiles_tile(
    State(state): State<AppState>,
    Path((id, z, x, file)): Path<(String, String, String, String)>,
    uri: Uri,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let dataset = find(&state, &id).await?;
    let tile = tile_id(&z, &x, &file)?;
    state.datasets.check(&dataset, tile)?;
    let wanted = extensions(&uri, &headers)?;
    // A strong tag names the bytes sent: the gzip its own.
    let gzip = takes_gzip(&headers);
    let etag = dataset.etag(tile, wanted);
    let etag = if gzip { format!("{}-gz\"", etag.trim_end_matches('"')) } else { etag };
    let tag = HeaderValue::from_str(&etag).expect("hex tags");
    let mut response = if not_modified(&headers, &tag) {
        StatusCode::NOT_MODIFIED.into_response()
    } else {
        let (bytes, made) = state.datasets.tile(&dataset, tile, wanted).await?;
        let mut response = if gzip {
            ([(header::CONTENT_ENCODING, "gzip")], bytes).into_response()
        } else {
            gunzip(&bytes)?.into_response()
        };
        response.headers_mut().insert(header::CONTENT_TYPE, media_type(wanted));
        response.headers_mut().insert("x-cache", HeaderValue::from_static(made.name()));
        response
    };
    let h = response.headers_mut();
    h.insert(header::ETAG, tag);
    h.insert(header::CACHE_CONTROL, cache_control(&state, &dataset));
    h.insert(header::VARY, HeaderValue::from_static("accept, accept-encoding"));
    Ok(response)
}

/// How long a client may keep a tile: the URL names the version, so an upload's tiles never
/// change under it; a file named in the settings may be replaced at a restart. Behind API
/// keys, only the client's own cache may keep them.
fn cache_control(state: &AppState, dataset: &Dataset) -> HeaderValue {
    let age = if *dataset.origin() == Origin::Upload { UPLOAD_MAX_AGE } else { FILE_MAX_AGE };
    let scope = if state.keyed { "private" } else { "public" };
    HeaderValue::from_str(&format!("{scope}, {age}")).expect("ascii")
}

async fn find(state: &AppState, id: &str) -> Result<Arc<Dataset>, ApiError> {
    Ok(state.datasets.find(id).await?)
}

/// The tile a path names: `{z}/{x}/{y}.terrain`, each a whole number.
fn tile_id(z: &str, x: &str, file: &str) -> Result<TileId, ApiError> {
    let bad = || {
        ApiError::NotFound(format!(
            "`{z}/{x}/{file}` is not a tile: tiles are {{z}}/{{x}}/{{y}}.terrain with whole numbers (TMS rows, from the south)"
        ))
    };
    let y = file.strip_suffix(".terrain").ok_or_else(bad)?;
    Ok(TileId {
        z: z.parse().map_err(|_| bad())?,
        x: x.parse().map_err(|_| bad())?,
        y: y.parse().map_err(|_| bad())?,
    })
}

/// The extensions a client asks for: `?extensions=octvertexnormals-metadata` (an unknown
/// one is refused), else the `extensions` parameter of an `Accept` for a quantized mesh, as
/// CesiumJS sends it (an unknown one, such as `watermask`, is left out).
fn extensions(uri: &Uri, headers: &HeaderMap) -> Result<Wanted, ApiError> {
    #[derive(serde::Deserialize)]
    struct Query {
        extensions: Option<String>,
    }
    let query: Query = super::extract::query(uri)?;
    if let Some(list) = query.extensions {
        let mut wanted = Wanted::default();
        for name in list.split(['-', ',']).filter(|n| !n.is_empty()) {
            match name {
                "octvertexnormals" => wanted.normals = true,
                "metadata" => wanted.metadata = true,
                _ => {
                    return Err(ApiError::InvalidRequest(format!(
                        "query string: extension `{name}` is not served; the extensions are octvertexnormals and metadata"
                    )));
                }
            }
        }
        return Ok(wanted);
    }
    let mut wanted = Wanted::default();
    let accepts = headers.get_all(header::ACCEPT).iter().filter_map(|v| v.to_str().ok());
    for media in accepts.flat_map(|v| v.split(',')) {
        let mut params = media.split(';').map(str::trim);
        if !params.next().is_some_and(|t| t.eq_ignore_ascii_case(QUANTIZED_MESH)) {
            continue;
        }
        for list in params.filter_map(|p| p.strip_prefix("extensions=")) {
            for name in list.trim_matches('"').split('-') {
                wanted.normals |= name == "octvertexnormals";
                wanted.metadata |= name == "metadata";
            }
        }
    }
    Ok(wanted)
}

/// The tile's media type, naming the extensions it carries.
fn media_type(wanted: Wanted) -> HeaderValue {
    let names: Vec<&str> = [(wanted.normals, "octvertexnormals"), (wanted.metadata, "metadata")]
        .into_iter()
        .filter_map(|(on, name)| on.then_some(name))
        .collect();
    let media = if names.is_empty() {
        QUANTIZED_MESH.to_owned()
    } else {
        format!("{QUANTIZED_MESH};extensions={}", names.join("-"))
    };
    HeaderValue::from_str(&media).expect("ascii")
}

/// Whether `Accept-Encoding` takes gzip (not refused with `q=0`).
fn takes_gzip(headers: &HeaderMap) -> bool {
    let codings = headers.get_all(header::ACCEPT_ENCODING).iter().filter_map(|v| v.to_str().ok());
    // The weight of `gzip` if named, else of `*`: an explicit `gzip;q=0` wins over `*`.
    let (mut gzip, mut any) = (None, None);
    for coding in codings.flat_map(|v| v.split(',')) {
        let mut parts = coding.split(';').map(str::trim);
        let name = parts.next().unwrap_or_default();
        let q = parts
            .find_map(|p| p.replace(' ', "").strip_prefix("q=").and_then(|q| q.parse::<f64>().ok()))
            .unwrap_or(1.0);
        if name.eq_ignore_ascii_case("gzip") {
            gzip = Some(q);
        } else if name == "*" {
            any = Some(q);
        }
    }
    gzip.or(any).is_some_and(|q| q > 0.0)
}

/// The tile for a client that does not take gzip.
fn gunzip(gzip: &[u8]) -> Result<Vec<u8>, ApiError> {
    let mut bytes = Vec::with_capacity(gzip.len() * 2);
    flate2::read::GzDecoder::new(gzip)
        .read_to_end(&mut bytes)
        .map_err(|e| ApiError::Internal(format!("a cached tile does not gunzip: {e}")))?;
    Ok(bytes)
}

/// What a client is told of a dataset.
fn describe(dataset: &Dataset) -> DatasetInfo {
    let dem = dataset.dem();
    let b = dem.bounds();
    DatasetInfo {
        id: dataset.id().to_owned(),
        source: match dataset.origin() {
            Origin::Upload => "upload",
            Origin::File(_) => "file",
        },
        file_bytes: dataset.file_bytes(),
        size: dem.size(),
        crs: "EPSG:4326",
        bounds: [b.west, b.south, b.east, b.north],
        pixel_degrees: dem.pixel(),
        heights: dataset.heights(),
        nodata_filled: dem.filled(),
        max_zoom: dataset.max_level(),
        error_factor: dataset.error_factor(),
        shared: None,
        links: DatasetLinks::of(dataset.id()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn headers(name: header::HeaderName, value: &str) -> HeaderMap {
        let mut h = HeaderMap::new();
        h.insert(name, HeaderValue::from_str(value).unwrap());
        h
    }

    #[test]
    fn cesium_s_accept_header_asks_for_its_extensions_and_the_query_wins() {
        let accept = "application/vnd.quantized-mesh;extensions=octvertexnormals-watermask-metadata,application/octet-stream;q=0.9,*/*;q=0.01";
        let h = headers(header::ACCEPT, accept);
        assert_eq!(extensions(&"/t".parse().unwrap(), &h).unwrap(), Wanted::ALL);
        let only = extensions(&"/t?extensions=metadata".parse().unwrap(), &h).unwrap();
        assert_eq!(only, Wanted { normals: false, metadata: true });
        assert_eq!(extensions(&"/t".parse().unwrap(), &HeaderMap::new()).unwrap(), Wanted::default());
        let err = extensions(&"/t?extensions=watermask".parse().unwrap(), &HeaderMap::new()).unwrap_err();
        assert!(err.detail().contains("`watermask`"), "{}", err.detail());
    }

    #[test]
    fn gzip_is_taken_unless_refused() {
        assert!(takes_gzip(&headers(header::ACCEPT_ENCODING, "gzip, deflate, br")));
        assert!(takes_gzip(&headers(header::ACCEPT_ENCODING, "br;q=1.0, *;q=0.5")));
        assert!(!takes_gzip(&headers(header::ACCEPT_ENCODING, "gzip;q=0, br")));
        assert!(!takes_gzip(&headers(header::ACCEPT_ENCODING, "gzip; q=0.000")));
        assert!(!takes_gzip(&headers(header::ACCEPT_ENCODING, "identity")));
        assert!(!takes_gzip(&headers(header::ACCEPT_ENCODING, "gzip;q=0, *")));
        assert!(!takes_gzip(&HeaderMap::new()));
    }

    #[test]
    fn a_tile_path_is_three_whole_numbers_and_terrain() {
        assert_eq!(tile_id("3", "5", "2.terrain").unwrap(), TileId { z: 3, x: 5, y: 2 });
        for (z, x, y) in
            [("3", "5", "2"), ("3", "-5", "2.terrain"), ("z", "5", "2.terrain"), ("300", "0", "0.terrain")]
        {
            assert!(matches!(tile_id(z, x, y), Err(ApiError::NotFound(_))), "{z}/{x}/{y}");
        }
    }
}
