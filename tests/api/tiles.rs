//! Datasets and their terrain tiles over HTTP: a GeoTIFF uploaded by multipart (or named in
//! the settings) is served as layer.json and quantized-mesh tiles, which an independent
//! decoder (the `quantized-mesh` crate) reads, neighbours agreeing on their sides; the tiles
//! are the library's bytes, gzipped when asked, revalidated by entity tag; and every bad
//! request is a problem naming what is wrong.

#[path = "../support/cesium.rs"]
mod support;

use crate::helpers::{configured, spawn_with};

use meshfit::tiles::{Dem, Pyramid, TileId, Wanted};
use quantized_mesh::DecodedMesh;
use reqwest::multipart::{Form, Part};
use reqwest::{Response, StatusCode};
use serde_json::Value;
use std::collections::BTreeMap;
use std::io::Read;
use std::path::PathBuf;
use support::cesium;

/// The quick start's 256 × 256 DEM at one arc-second, in EPSG:4326: levels 0..=14.
fn dem_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("examples/grids/dem-4326.tif")
}

fn dem_file() -> Vec<u8> {
    std::fs::read(dem_path()).unwrap()
}

/// A server whose grids may be as large as the DEM.
async fn app(change: impl FnOnce(&mut meshfit::config::Config)) -> crate::helpers::TestApp {
    spawn_with(configured(|c| {
        c.limits.max_grid_points = 1 << 20;
        change(c);
    }))
    .await
}

async fn upload(app: &crate::helpers::TestApp, file: Vec<u8>) -> Response {
    let form = Form::new().part("grid", Part::bytes(file).file_name("dem.tif"));
    app.client.post(app.url("/v1/datasets")).multipart(form).send().await.unwrap()
}

async fn problem(response: Response, status: StatusCode) -> Value {
    assert_eq!(response.status(), status);
    assert_eq!(response.headers()["content-type"], "application/problem+json");
    response.json().await.unwrap()
}

fn gunzip(bytes: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    flate2::read::GzDecoder::new(bytes).read_to_end(&mut out).unwrap();
    out
}

/// The tile's bytes as a client that takes gzip gets them, unzipped.
async fn tile(app: &crate::helpers::TestApp, path: &str, extensions: &str) -> Vec<u8> {
    let url = app.url(&format!("{path}?extensions={extensions}"));
    let response = app.client.get(url).header("accept-encoding", "gzip").send().await.unwrap();
    assert_eq!(response.status(), StatusCode::OK, "{path}");
    assert_eq!(response.headers()["content-encoding"], "gzip");
    gunzip(&response.bytes().await.unwrap())
}

#[tokio::test]
async fn an_uploaded_dem_serves_layer_json_and_tiles_whose_neighbours_share_their_sides() {
    let app = app(|_| {}).await;
    let created = upload(&app, dem_file()).await;
    assert_eq!(created.status(), StatusCode::CREATED);
    let location = created.headers()["location"].to_str().unwrap().to_owned();
    let info: Value = created.json().await.unwrap();
    let id = info["id"].as_str().unwrap().to_owned();
    assert_eq!(id, meshfit::datasets::digest(&dem_file()), "the id is the file's hash");
    assert_eq!(location, format!("/v1/datasets/{id}"));
    assert_eq!(
        (info["size"].clone(), info["crs"].as_str()),
        (serde_json::json!([256, 256]), Some("EPSG:4326"))
    );
    assert_eq!((info["max_zoom"].as_u64(), info["source"].as_str()), (Some(14), Some("upload")));
    let heights = info["heights"].as_array().unwrap();
    assert!(heights[0].as_f64() < heights[1].as_f64());

    // The same file again is the same dataset.
    let again = upload(&app, dem_file()).await;
    assert_eq!(again.status(), StatusCode::OK);
    assert_eq!(again.json::<Value>().await.unwrap()["id"], id.as_str());
    let listed: Value = app.get("/v1/datasets").await.json().await.unwrap();
    assert_eq!(listed["datasets"].as_array().unwrap().len(), 1);
    assert_eq!(app.get(&location).await.json::<Value>().await.unwrap(), info);

    let layer: Value = app.get(&format!("/v1/tiles/{id}/layer.json")).await.json().await.unwrap();
    assert_eq!(
        (layer["format"].as_str(), layer["scheme"].as_str()),
        (Some("quantized-mesh-1.0"), Some("tms"))
    );
    assert_eq!(layer["extensions"], serde_json::json!(["octvertexnormals", "metadata"]));
    assert_eq!((layer["maxzoom"].as_u64(), layer["metadataAvailability"].as_u64()), (Some(14), Some(10)));
    let available = layer["available"].as_array().unwrap();
    assert_eq!(available[0], serde_json::json!([{"startX": 0, "startY": 0, "endX": 1, "endY": 0}]));

    // Every tile of the deepest level decodes, and each pair of neighbours has the same
    // vertices on its common side.
    let range = &available[14][0];
    let n = |k: &str| range[k].as_u64().unwrap() as u32;
    let mut deepest = BTreeMap::new();
    for y in n("startY")..=n("endY") {
        for x in n("startX")..=n("endX") {
            let bytes = tile(&app, &format!("/v1/tiles/{id}/14/{x}/{y}.terrain"), "octvertexnormals").await;
            let mesh = DecodedMesh::decode(&bytes).unwrap();
            assert!(!mesh.indices.is_empty() && mesh.extensions.normals.is_some());
            deepest.insert((x, y), mesh);
        }
    }
    // Each side's vertices by their quantized position along it: v on an east or west side,
    // u on a north or south one.
    let along = |side: &[u32], at: &[u16]| side.iter().map(|&k| at[k as usize]).collect::<Vec<_>>();
    let mut sides = 0;
    for (&(x, y), mesh) in &deepest {
        let (e, n) = (&mesh.edge_indices, &mesh.vertices);
        if let Some(east) = deepest.get(&(x + 1, y)) {
            let theirs = along(&east.edge_indices.west, &east.vertices.v);
            assert_eq!(along(&e.east, &n.v), theirs, "{x}/{y} east side");
            sides += 1;
        }
        if let Some(north) = deepest.get(&(x, y + 1)) {
            let theirs = along(&north.edge_indices.south, &north.vertices.u);
            assert_eq!(along(&e.north, &n.u), theirs, "{x}/{y} north side");
            sides += 1;
        }
    }
    assert!(sides >= 4, "{sides} sides compared");
    app.shutdown().await;
}

#[tokio::test]
async fn a_tile_is_the_library_s_bytes_with_the_extensions_asked_for() {
    let app = app(|_| {}).await;
    let id = upload(&app, dem_file()).await.json::<Value>().await.unwrap()["id"].as_str().unwrap().to_owned();
    let dem = Dem::open(Box::new(std::io::Cursor::new(dem_file())), usize::MAX).unwrap();
    let pyramid = Pyramid::new(&dem, 0, None, 1.0).unwrap();
    // The DEM is in Texas, under the western root.
    let root = TileId { z: 0, x: 0, y: 0 };
    let path = format!("/v1/tiles/{id}/0/0/0.terrain");
    for (extensions, wanted) in [
        ("octvertexnormals-metadata", Wanted::ALL),
        ("octvertexnormals", Wanted { normals: true, metadata: false }),
        ("", Wanted::default()),
    ] {
        assert_eq!(
            tile(&app, &path, extensions).await,
            pyramid.tile(root, wanted).unwrap().unwrap(),
            "{extensions}"
        );
    }
    // CesiumJS asks in Accept; a root tile's metadata lists the tiles of the levels below.
    let accept = "application/vnd.quantized-mesh;extensions=octvertexnormals-watermask-metadata,*/*;q=0.01";
    let response = app.client.get(app.url(&path)).header("accept", accept).send().await.unwrap();
    assert_eq!(
        response.headers()["content-type"],
        "application/vnd.quantized-mesh;extensions=octvertexnormals-metadata"
    );
    assert!(response.headers().get("content-encoding").is_none(), "no gzip unless accepted");
    let mesh = DecodedMesh::decode(&response.bytes().await.unwrap()).unwrap();
    let metadata = mesh.extensions.metadata.expect("level 0 carries metadata");
    assert_eq!(metadata.available.len(), 10);
    let layer: Value = app.get(&format!("/v1/tiles/{id}/layer.json")).await.json().await.unwrap();
    for (k, ranges) in metadata.available.iter().enumerate() {
        // The western root's subtree holds every tile of the level.
        let listed = &layer["available"][k + 1][0];
        assert_eq!(ranges.len(), 1);
        assert_eq!(
            [ranges[0].start_x, ranges[0].end_x, ranges[0].start_y, ranges[0].end_y],
            ["startX", "endX", "startY", "endY"].map(|key| listed[key].as_u64().unwrap() as u32),
        );
    }
    app.shutdown().await;
}

#[tokio::test]
async fn tiles_are_cached_revalidated_by_tag_and_kept_long_by_clients() {
    let app = app(|_| {}).await;
    let id = upload(&app, dem_file()).await.json::<Value>().await.unwrap()["id"].as_str().unwrap().to_owned();
    let layer: Value = app.get(&format!("/v1/tiles/{id}/layer.json")).await.json().await.unwrap();
    let range = &layer["available"][12][0];
    let url = app.url(&format!("/v1/tiles/{id}/12/{}/{}.terrain", range["startX"], range["startY"]));
    let first = app.client.get(&url).send().await.unwrap();
    assert_eq!(first.status(), StatusCode::OK);
    assert_eq!(first.headers()["x-cache"], "miss");
    assert_eq!(first.headers()["cache-control"], "public, max-age=31536000, immutable");
    let etag = first.headers()["etag"].clone();
    let body = first.bytes().await.unwrap();
    let second = app.client.get(&url).send().await.unwrap();
    assert_eq!((second.headers()["x-cache"].to_str().unwrap(), &second.headers()["etag"]), ("hit", &etag));
    assert_eq!(second.bytes().await.unwrap(), body);
    let revalidated = app.client.get(&url).header("if-none-match", etag.clone()).send().await.unwrap();
    assert_eq!(revalidated.status(), StatusCode::NOT_MODIFIED);
    // Another set of extensions, or gzip, is another representation, with its own tag.
    let normals = app.client.get(format!("{url}?extensions=octvertexnormals")).send().await.unwrap();
    assert_ne!(normals.headers()["etag"], etag);
    let zipped = app.client.get(&url).header("accept-encoding", "gzip").send().await.unwrap();
    let zipped_tag = zipped.headers()["etag"].to_str().unwrap().to_owned();
    assert_eq!(zipped_tag, format!("{}-gz\"", etag.to_str().unwrap().trim_end_matches('"')));
    assert_eq!(gunzip(&zipped.bytes().await.unwrap()), body);
    // The tiles' URLs name the version of their bytes (clients fill in `{version}` from the
    // layer), so a year's caching never mixes two.
    assert_eq!(layer["tiles"][0], "{z}/{x}/{y}.terrain?v={version}");
    let version = layer["version"].as_str().unwrap();
    assert!(version.len() == 16 && version.bytes().all(|b| b.is_ascii_hexdigit()), "{version}");
    app.shutdown().await;
}

#[tokio::test]
async fn a_dataset_named_in_the_settings_is_served_and_cannot_be_deleted() {
    let app = app(|c| c.datasets.files = vec![("alps".into(), dem_path())]).await;
    let info: Value = app.get("/v1/datasets/alps").await.json().await.unwrap();
    assert_eq!((info["source"].as_str(), info["max_zoom"].as_u64()), (Some("file"), Some(14)));
    let root = app.get("/v1/tiles/alps/0/0/0.terrain").await;
    assert_eq!(root.status(), StatusCode::OK, "both roots answer, the DEM in one of them");
    assert_eq!(root.headers()["cache-control"], "public, max-age=3600");
    let doc = problem(app.delete("/v1/datasets/alps").await, StatusCode::CONFLICT).await;
    assert_eq!(doc["type"], "/problems/dataset-configured");
    assert_eq!(app.get("/v1/datasets/alps").await.status(), StatusCode::OK);
    app.shutdown().await;
}

#[tokio::test]
async fn bad_uploads_and_tile_addresses_are_problems_naming_what_is_wrong() {
    // An allowance of one DEM (its file and its blocks' cache), with room for a few bytes more.
    let dem = Dem::open(Box::new(std::io::Cursor::new(dem_file())), usize::MAX).unwrap();
    let one = dem.resident_bytes() + dem_file().len() as u64;
    let app = app(|c| c.datasets.max_bytes = one + 64).await;
    // A projected GeoTIFF (the quick start's, in UTM) names its system.
    let utm =
        std::fs::read(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("examples/grids/dem.tif")).unwrap();
    let doc = problem(upload(&app, utm).await, StatusCode::UNPROCESSABLE_ENTITY).await;
    assert_eq!(doc["type"], "/problems/invalid-dem");
    assert!(doc["detail"].as_str().unwrap().contains("EPSG:"), "{doc}");
    // A truncated file.
    let file = dem_file();
    let doc =
        problem(upload(&app, file[..file.len() / 2].to_vec()).await, StatusCode::UNPROCESSABLE_ENTITY).await;
    assert_eq!(doc["type"], "/problems/invalid-grid");
    // JSON is not a dataset.
    let doc =
        problem(app.post("/v1/datasets", &serde_json::json!({})).await, StatusCode::UNSUPPORTED_MEDIA_TYPE)
            .await;
    assert!(doc["detail"].as_str().unwrap().contains("-F grid=@"), "{doc}");
    // Unknown datasets and tiles outside the pyramid.
    let doc = problem(app.get("/v1/tiles/nope/layer.json").await, StatusCode::NOT_FOUND).await;
    assert!(doc["detail"].as_str().unwrap().contains("`nope`"), "{doc}");
    let id = upload(&app, dem_file()).await.json::<Value>().await.unwrap()["id"].as_str().unwrap().to_owned();
    let doc = problem(app.get(&format!("/v1/tiles/{id}/3/0/0.terrain")).await, StatusCode::NOT_FOUND).await;
    assert!(doc["detail"].as_str().unwrap().contains("level 3 of dataset"), "{doc}");
    let doc = problem(app.get(&format!("/v1/tiles/{id}/15/0/0.terrain")).await, StatusCode::NOT_FOUND).await;
    assert!(doc["detail"].as_str().unwrap().contains("levels 0..=14"), "{doc}");
    let doc = problem(app.get(&format!("/v1/tiles/{id}/1/0/x.terrain")).await, StatusCode::NOT_FOUND).await;
    assert!(doc["detail"].as_str().unwrap().contains("whole numbers"), "{doc}");
    let doc = problem(
        app.get(&format!("/v1/tiles/{id}/0/0/0.terrain?extensions=watermask")).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert!(doc["detail"].as_str().unwrap().contains("`watermask`"), "{doc}");
    // The allowance holds one such DEM: another is refused until it is deleted.
    let mut other = dem_file();
    other.extend_from_slice(b"another file, the same DEM");
    let doc = problem(upload(&app, other.clone()).await, StatusCode::INSUFFICIENT_STORAGE).await;
    assert_eq!(doc["limit"]["name"], "MESHFIT_DATASET_BYTES");
    assert_eq!(app.delete(&format!("/v1/datasets/{id}")).await.status(), StatusCode::NO_CONTENT);
    assert_eq!(app.get(&format!("/v1/datasets/{id}")).await.status(), StatusCode::NOT_FOUND);
    assert_eq!(upload(&app, other).await.status(), StatusCode::CREATED);
    app.shutdown().await;
}

#[tokio::test]
async fn cesium_loads_every_tile_of_an_uploaded_dataset_from_the_server_and_sees_no_crack() {
    let Some(cesium) = cesium() else { return };
    let app = app(|_| {}).await;
    let info: Value = upload(&app, dem_file()).await.json().await.unwrap();
    let layer = app.url(info["links"]["layer"].as_str().unwrap());
    let base = layer.strip_suffix("layer.json").unwrap().to_owned();
    let check = tokio::task::spawn_blocking(move || {
        std::process::Command::new("node")
            .arg(cesium.join("check.mjs"))
            .arg(base)
            .output()
            .expect("node runs")
    })
    .await
    .unwrap();
    assert!(check.status.success(), "CesiumJS failed: {}", String::from_utf8_lossy(&check.stderr));
    let lines: Vec<Value> =
        String::from_utf8(check.stdout).unwrap().lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    let (summary, tiles) = lines.split_last().unwrap();
    let layer: Value = app.client.get(&layer).send().await.unwrap().json().await.unwrap();
    let listed: u64 = layer["available"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|ranges| ranges.as_array().unwrap())
        .map(|r| {
            let n = |k: &str| r[k].as_u64().unwrap();
            (n("endX") - n("startX") + 1) * (n("endY") - n("startY") + 1)
        })
        .sum();
    assert_eq!(tiles.len() as u64, listed, "one line a tile layer.json lists");
    for tile in tiles {
        // Known available from the tiles' metadata (metadataAvailability), normals read.
        assert_eq!(tile["available"], true, "{tile}");
        assert_eq!(tile["normals"], tile["vertices"], "{tile}");
    }
    assert!(summary["sides"].as_u64().unwrap() > 0, "{summary}");
    // Each tile quantizes its heights over its own range: a gap of a few quanta, no crack.
    let range = info["heights"][1].as_f64().unwrap() - info["heights"][0].as_f64().unwrap();
    assert!(summary["gap"].as_f64().unwrap() <= range / 32767.0 + 1e-9, "{summary}");
    app.shutdown().await;
}

/// A GeoTIFF in EPSG:4326 of 1/256° pixels from 10°E, 46°N (its first row the north), whose
/// southern half (the file's last rows) is the nodata value −9999.
fn half_nodata_geotiff() -> Vec<u8> {
    use tiff::encoder::{TiffEncoder, colortype};
    use tiff::tags::Tag;
    let (nx, ny) = (512u32, 256u32);
    let data: Vec<f32> = (0..ny)
        .flat_map(|j| (0..nx).map(move |i| (i, j)))
        .map(|(i, row)| {
            if row >= ny / 2 {
                -9999.0
            } else {
                400.0 + 200.0 * (i as f32 * 0.03).sin() * (row as f32 * 0.05).cos()
            }
        })
        .collect();
    let mut bytes = Vec::new();
    let mut encoder = TiffEncoder::new(std::io::Cursor::new(&mut bytes)).unwrap();
    let mut image = encoder.new_image::<colortype::Gray32Float>(nx, ny).unwrap();
    let pixel = 1.0 / 256.0;
    image.encoder().write_tag(Tag::ModelPixelScaleTag, &[pixel, pixel, 0.0][..]).unwrap();
    image.encoder().write_tag(Tag::ModelTiepointTag, &[0.0, 0.0, 0.0, 10.0, 46.0, 0.0][..]).unwrap();
    let keys: [u16; 12] = [1, 1, 0, 2, 1024, 0, 1, 2, 2048, 0, 1, 4326];
    image.encoder().write_tag(Tag::GeoKeyDirectoryTag, &keys[..]).unwrap();
    image.encoder().write_tag(Tag::GdalNodata, "-9999").unwrap();
    image.write_data(&data).unwrap();
    bytes
}

#[tokio::test]
async fn nodata_is_filled_for_meshing_and_a_tile_of_nodata_alone_is_not_available() {
    let app = app(|_| {}).await;
    let created = upload(&app, half_nodata_geotiff()).await;
    assert_eq!(created.status(), StatusCode::CREATED);
    let info: Value = created.json().await.unwrap();
    assert_eq!(info["nodata_filled"], 512 * 128, "the southern half");
    // Filled from the data: no height near −9999.
    assert!(info["heights"][0].as_f64().unwrap() > 100.0, "{info}");
    let id = info["id"].as_str().unwrap().to_owned();
    let layer: Value = app.get(&format!("/v1/tiles/{id}/layer.json")).await.json().await.unwrap();
    // Level 10 tiles are 45/256° high: rows of the DEM's southern half-degree hold no data.
    let level = &layer["available"][10];
    let listed: Vec<(u64, u64)> = level
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|r| {
            let n = |k: &str| r[k].as_u64().unwrap();
            (n("startY")..=n("endY")).flat_map(move |y| (n("startX")..=n("endX")).map(move |x| (x, y)))
        })
        .collect();
    let south_of_data = |y: u64| -90.0 + (y + 1) as f64 * 180.0 / 1024.0 < 45.5;
    assert!(!listed.is_empty() && listed.iter().all(|&(_, y)| !south_of_data(y)), "{level}");
    // A tile of the southern half answers 404 saying why; its northern neighbours decode.
    let covering = |lat: f64| ((lat + 90.0) / (180.0 / 1024.0)).floor() as u64;
    let x = listed[0].0;
    let doc = problem(
        app.get(&format!("/v1/tiles/{id}/10/{x}/{}.terrain", covering(45.1))).await,
        StatusCode::NOT_FOUND,
    )
    .await;
    assert!(doc["detail"].as_str().unwrap().contains("only nodata"), "{doc}");
    for &(x, y) in &listed {
        let bytes = tile(&app, &format!("/v1/tiles/{id}/10/{x}/{y}.terrain"), "").await;
        let mesh = DecodedMesh::decode(&bytes).unwrap();
        assert!(mesh.header.min_height > 100.0, "tile 10/{x}/{y} dips to {}", mesh.header.min_height);
    }
    app.shutdown().await;
}
