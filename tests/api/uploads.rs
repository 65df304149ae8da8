//! Grid files sent as multipart/form-data: every format gives the job of the same values sent
//! as JSON, and a bad file is a 422 that says what and where.

use crate::helpers::spawn_app;
use reqwest::multipart::{Form, Part};
use serde_json::{Value, json};

const NX: usize = 9;
const NY: usize = 7;

/// The heights, as 16-bit integers so that every format carries them exactly.
fn height(i: usize, j: usize) -> u16 {
    (100 * i + 7 * j * j) as u16
}

/// The grid as the JSON API lists it: bottom row first.
fn json_values() -> Vec<f64> {
    (0..NY).flat_map(|j| (0..NX).map(move |i| f64::from(height(i, j)))).collect()
}

/// The grid as images list it: top row first.
fn image_rows() -> Vec<u16> {
    (0..NY).rev().flat_map(|j| (0..NX).map(move |i| height(i, j))).collect()
}

fn png16() -> Vec<u8> {
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, NX as u32, NY as u32);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::Sixteen);
    let data: Vec<u8> = image_rows().iter().flat_map(|v| v.to_be_bytes()).collect();
    encoder.write_header().unwrap().write_image_data(&data).unwrap();
    bytes
}

fn tiff16() -> Vec<u8> {
    let mut bytes = std::io::Cursor::new(Vec::new());
    let mut encoder = tiff::encoder::TiffEncoder::new(&mut bytes).unwrap();
    encoder.write_image::<tiff::encoder::colortype::Gray16>(NX as u32, NY as u32, &image_rows()).unwrap();
    bytes.into_inner()
}

/// A .npy of little-endian f64, written by the format's spec.
fn npy() -> Vec<u8> {
    let header = format!("{{'descr': '<f8', 'fortran_order': False, 'shape': ({NY}, {NX}), }}");
    let pad = 64 - (10 + header.len() + 1) % 64;
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&((header.len() + pad + 1) as u16).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    bytes.extend(std::iter::repeat_n(b' ', pad));
    bytes.push(b'\n');
    bytes.extend(image_rows().iter().flat_map(|&v| f64::from(v).to_le_bytes()));
    bytes
}

fn raw_f32() -> Vec<u8> {
    image_rows().iter().flat_map(|&v| f32::from(v).to_le_bytes()).collect()
}

/// The heights as an 8-bit RGBA web-map tile: Terrain-RGB's tenths of a metre above −10000 m,
/// or Terrarium's metres above −32768 m; `hole` is a pixel (i, j) left fully transparent.
fn tile(encoding: &str, hole: Option<(usize, usize)>) -> Vec<u8> {
    let data: Vec<u8> = (0..NY)
        .rev()
        .flat_map(|j| (0..NX).map(move |i| (i, j)))
        .flat_map(|(i, j)| {
            let h = u32::from(height(i, j));
            let code = if encoding == "terrain-rgb" { (h + 10_000) * 10 } else { (h + 32_768) * 256 };
            let alpha = if hole == Some((i, j)) { 0 } else { 255 };
            [(code >> 16) as u8, (code >> 8) as u8, code as u8, alpha]
        })
        .collect();
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, NX as u32, NY as u32);
    encoder.set_color(png::ColorType::Rgba);
    encoder.write_header().unwrap().write_image_data(&data).unwrap();
    bytes
}

async fn upload(app: &crate::helpers::TestApp, request: Value, file: Vec<u8>) -> reqwest::Response {
    let form =
        Form::new().text("request", request.to_string()).part("grid", Part::bytes(file).file_name("dem"));
    app.client.post(app.url("/v1/meshes")).multipart(form).send().await.unwrap()
}

#[tokio::test]
async fn every_grid_file_format_gives_the_job_of_the_same_values_sent_as_json() {
    let app = spawn_app().await;
    let json_body = json!({"grid": {"nx": NX, "ny": NY, "values": json_values()}, "max_vertices": 40});
    let reference: Value = app.post("/v1/meshes", &json_body).await.json().await.unwrap();
    let raw_request = json!({"grid": {"nx": NX, "ny": NY, "dtype": "f32"}, "max_vertices": 40});
    for (name, request, file) in [
        ("png", json!({"max_vertices": 40}), png16()),
        ("tiff", json!({"max_vertices": 40}), tiff16()),
        ("npy", json!({"max_vertices": 40}), npy()),
        ("raw", raw_request, raw_f32()),
    ] {
        let response = upload(&app, request, file).await;
        assert_eq!(response.status(), 200, "{name}");
        assert_eq!(response.headers()["x-cache"], "hit", "{name}: the same values are the same job");
        let doc: Value = response.json().await.unwrap();
        assert_eq!(doc, reference, "{name}");
    }
    app.shutdown().await;
}

#[tokio::test]
async fn elevation_tiles_in_both_encodings_give_the_job_of_their_heights() {
    let app = spawn_app().await;
    let json_body = json!({"grid": {"nx": NX, "ny": NY, "values": json_values()}, "max_vertices": 40});
    let reference: Value = app.post("/v1/meshes", &json_body).await.json().await.unwrap();
    for encoding in ["terrain-rgb", "terrarium"] {
        let request = json!({"grid": {"encoding": encoding}, "max_vertices": 40});
        let response = upload(&app, request, tile(encoding, None)).await;
        assert_eq!(response.status(), 200, "{encoding}");
        assert_eq!(response.headers()["x-cache"], "hit", "{encoding}: the same heights are the same job");
        assert_eq!(response.json::<Value>().await.unwrap(), reference, "{encoding}");
    }
    // The tile without its encoding, an encoding for a greyscale PNG, and a hole.
    let cases = [
        (json!({}), tile("terrarium", None), "/detail", "encoding of an elevation tile"),
        (json!({"grid": {"encoding": "terrarium"}}), png16(), "/detail", "not a greyscale PNG"),
        (json!({"grid": {"encoding": "terrarium"}}), tile("terrarium", Some((5, 2))), "/index", ""),
    ];
    for (request, file, pointer, text) in cases {
        let response = upload(&app, request.clone(), file).await;
        assert_eq!(response.status(), 422, "{request}");
        let problem: Value = response.json().await.unwrap();
        assert_eq!(problem["type"], "/problems/invalid-grid", "{problem}");
        match pointer {
            "/index" => assert_eq!(problem["index"], json!([5, 2]), "{problem}"),
            _ => assert!(problem["detail"].as_str().unwrap().contains(text), "{problem}"),
        }
    }
    app.shutdown().await;
}

#[tokio::test]
async fn bad_grid_files_are_problems_that_say_what_and_where() {
    let app = spawn_app().await;
    let colour = {
        let mut bytes = Vec::new();
        let mut encoder = png::Encoder::new(&mut bytes, 2, 2);
        encoder.set_color(png::ColorType::Rgb);
        encoder.write_header().unwrap().write_image_data(&[0; 12]).unwrap();
        bytes
    };
    let mut nan = raw_f32();
    // Image row 0 is the top (j = NY - 1); sample 3 of it is (i, j) = (3, NY - 1).
    nan[12..16].copy_from_slice(&f32::NAN.to_le_bytes());
    let huge = {
        // A valid header claiming 100,000 × 100,000 samples, and nothing else.
        let mut bytes = Vec::new();
        let mut encoder = png::Encoder::new(&mut bytes, 100_000, 100_000);
        encoder.set_color(png::ColorType::Grayscale);
        // Dropping the writer would finish the file; the header alone is the point.
        std::mem::forget(encoder.write_header().unwrap());
        bytes
    };
    let raw_hints = json!({"grid": {"nx": NX, "ny": NY, "dtype": "f32"}});
    for (name, request, file, kind, check) in [
        ("colour png", json!({}), colour, "invalid-grid", ("/detail", "colour")),
        ("truncated png", json!({}), png16()[..60].to_vec(), "invalid-grid", ("/detail", "PNG")),
        ("raw without hints", json!({}), raw_f32(), "invalid-grid", ("/detail", "nx")),
        (
            "raw of the wrong size",
            raw_hints.clone(),
            raw_f32()[4..].to_vec(),
            "invalid-grid",
            ("/detail", "bytes"),
        ),
        ("values and a file", json!({"grid": {"values": [1]}}), png16(), "invalid-grid", ("/detail", "file")),
        ("huge header", json!({}), huge, "limit-exceeded", ("/limit/name", "MESHFIT_MAX_GRID_POINTS")),
        (
            "a function and a file",
            json!({"function": "x"}),
            png16(),
            "invalid-source",
            ("/detail", "grid file"),
        ),
    ] {
        let response = upload(&app, request, file).await;
        assert_eq!(response.status(), 422, "{name}");
        let problem: Value = response.json().await.unwrap();
        assert_eq!(problem["type"], format!("/problems/{kind}"), "{name}: {problem}");
        let (pointer, text) = check;
        let found = problem.pointer(pointer).and_then(Value::as_str).unwrap_or_default();
        assert!(found.contains(text), "{name}: {pointer} is {found:?}, wants {text:?}");
    }
    let response = upload(&app, raw_hints, nan).await;
    let problem: Value = response.json().await.unwrap();
    assert_eq!(problem["index"], json!([3, NY - 1]), "{problem}");
    let broken = app
        .client
        .post(app.url("/v1/meshes"))
        .header("content-type", "multipart/form-data; boundary=xyz")
        .body("--xyz\r\nContent-Disposition: form-data; name=\"grid\"\r\n\r\nabc")
        .send()
        .await
        .unwrap();
    assert_eq!(broken.status(), 400);
    assert_eq!(broken.json::<Value>().await.unwrap()["type"], "/problems/malformed-multipart");
    let no_grid = Form::new().text("request", "{}");
    let response = app.client.post(app.url("/v1/meshes")).multipart(no_grid).send().await.unwrap();
    assert_eq!(response.status(), 422);
    assert_eq!(app.metric("meshfit_engine_runs_total").await, 0.0);
    app.shutdown().await;
}
