//! The `meshfit mesh` command, run as a user would: real process, real files, JSON on stdout.

#[path = "support/cesium.rs"]
mod support;

use serde_json::Value;
use std::path::PathBuf;
use std::process::{Command, Output};
use support::cesium;

fn meshfit(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_meshfit")).args(args).output().expect("meshfit runs")
}

fn document(args: &[&str]) -> Value {
    let out = meshfit(args);
    assert!(out.status.success(), "meshfit {args:?} failed: {}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).expect("stdout is JSON")
}

fn stderr_of_failure(args: &[&str]) -> String {
    let out = meshfit(args);
    assert!(!out.status.success(), "meshfit {args:?} should fail");
    assert!(out.stdout.is_empty(), "a failure writes nothing to stdout");
    String::from_utf8(out.stderr).unwrap()
}

fn temp_file(name: &str, contents: &str) -> PathBuf {
    let path = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    std::fs::write(&path, contents).unwrap();
    path
}

#[test]
fn mesh_writes_vertices_triangles_and_stats_for_an_expression() {
    let doc = document(&[
        "mesh",
        "--function",
        "sin(3*x)*cos(2*y)",
        "--max-vertices",
        "300",
        "--method",
        "recursive",
    ]);
    let vertices = doc["vertices"].as_array().unwrap();
    let triangles = doc["triangles"].as_array().unwrap();
    assert_eq!(vertices.len(), 300);
    assert_eq!(doc["stats"]["vertices"], 300);
    assert_eq!(doc["stats"]["triangles"].as_u64().unwrap() as usize, triangles.len());
    assert_eq!(doc["stats"]["stop"], "max_vertices");
    assert_eq!(doc["stats"]["flips"], 0, "recursive never flips");
    // The first four vertices are the corners of the default domain, with F's values.
    assert_eq!(vertices[2], serde_json::json!([1.0, 1.0, 3f64.sin() * 2f64.cos()]));
    for t in triangles {
        assert!(t.as_array().unwrap().iter().all(|i| (i.as_u64().unwrap() as usize) < vertices.len()));
    }
}

#[test]
fn mesh_reads_a_grid_file_and_accepts_negative_domain_bounds() {
    let grid = temp_file("grid_3x2.json", r#"{"nx": 3, "ny": 2, "values": [0, 1, 4, 1, 2, 5]}"#);
    let grid = grid.to_str().unwrap();
    // A leading minus is the value, not a flag, written either way.
    let doc = document(&["mesh", "--grid", grid, "--domain", "-3,3,-1,1", "--max-vertices", "40"]);
    let vertices = doc["vertices"].as_array().unwrap();
    assert_eq!(vertices[0], serde_json::json!([-3.0, -1.0, 0.0]));
    assert_eq!(vertices[2], serde_json::json!([3.0, 1.0, 5.0]));
    assert_eq!(doc["stats"]["delaunay"], true);
    assert_eq!(document(&["mesh", "--grid", grid, "--domain=-3,3,-1,1", "--max-vertices", "40"]), doc);
}

#[test]
fn a_reader_that_stops_early_ends_the_run_quietly_and_successfully() {
    use std::io::Read;
    // Far more output than a pipe buffers, so meshfit is still writing when the reader leaves.
    let mut child = Command::new(env!("CARGO_BIN_EXE_meshfit"))
        .args(["mesh", "--function", "x*y", "--max-vertices", "20000"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("meshfit runs");
    let mut head = [0u8; 16];
    child.stdout.take().unwrap().read_exact(&mut head).unwrap();
    assert_eq!(&head[..1], b"{");
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "exit {:?}", out.status);
    assert_eq!(String::from_utf8_lossy(&out.stderr), "");
}

#[test]
fn stats_flag_prints_only_the_stats_with_their_history_and_the_error_estimate() {
    let doc = document(&["mesh", "--function", "x^2 + y^2", "--max-vertices", "200", "--stats"]);
    assert!(doc.get("vertices").is_none());
    assert_eq!(doc["stats"]["vertices"], 200);
    let max_error = doc["error"]["max_error"].as_f64().unwrap();
    assert!(max_error > 0.0 && max_error < 0.1, "E_n = {max_error}");
    assert!(doc["error"]["min_angle_deg"].as_f64().unwrap() > 0.0);
    assert!(doc["elapsed_ms"].as_f64().is_some_and(|ms| ms > 0.0), "no refinement time: {doc}");
    // The convergence history: 4, 6, 8, ..., 128, then the end at 200.
    let counts: Vec<u64> =
        doc["stats"]["history"].as_array().unwrap().iter().map(|s| s["vertices"].as_u64().unwrap()).collect();
    assert_eq!(counts, [4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 200]);
}

#[test]
fn tolerance_stops_the_run_early() {
    let run = |criterion: Option<&str>| {
        let mut args = vec!["mesh", "--function", "x*y", "--max-vertices", "100000", "--tolerance", "0.05"];
        args.extend(criterion.map(|c| ["--criterion", c]).into_iter().flatten());
        args.push("--stats");
        document(&args)
    };
    // The default criterion, error: every triangle's sampled error is within the tolerance.
    let doc = run(None);
    assert_eq!(doc["stats"]["stop"], "tolerance");
    assert!(doc["stats"]["max_triangle_error"].as_f64().unwrap() <= 0.05);
    assert!(doc["error"]["max_error"].as_f64().unwrap() <= 0.05 * (1.0 + 1e-9));
    // The paper's: every edge varies by at most the tolerance.
    let doc = run(Some("variation"));
    assert_eq!(doc["stats"]["stop"], "tolerance");
    assert!(doc["stats"]["variation"].as_f64().unwrap() <= 0.05);
}

#[test]
fn the_same_command_gives_the_same_mesh_twice() {
    let args = ["mesh", "--function", "exp(-10*((x-0.3)^2+(y-0.6)^2))", "--max-vertices", "2000"];
    let (a, b) = (document(&args), document(&args));
    assert_eq!(a["vertices"], b["vertices"]);
    assert_eq!(a["triangles"], b["triangles"]);
}

#[test]
fn a_bad_expression_is_reported_with_its_column() {
    let err = stderr_of_failure(&["mesh", "--function", "sin(x) + q"]);
    assert!(err.contains("unknown variable `q`"), "{err}");
    assert!(err.contains("column 10"), "{err}");
}

#[test]
fn a_non_finite_value_of_f_names_the_point() {
    let err = stderr_of_failure(&["mesh", "--function", "ln(x)"]);
    assert!(err.contains("F is not finite at (0, 0)"), "{err}");
}

#[test]
fn bad_grids_and_domains_say_what_to_fix() {
    let short = temp_file("grid_short.json", r#"{"nx": 3, "ny": 2, "values": [0, 1, 4, 1, 2]}"#);
    let err = stderr_of_failure(&["mesh", "--grid", short.to_str().unwrap()]);
    assert!(err.contains("5 values, but nx and ny need 6"), "{err}");

    let typo = temp_file("grid_typo.json", r#"{"nx": 2, "ny": 2, "valeus": [0, 1, 2, 3]}"#);
    let err = stderr_of_failure(&["mesh", "--grid", typo.to_str().unwrap()]);
    assert!(err.contains("unknown field `valeus`"), "{err}");

    let err = stderr_of_failure(&["mesh", "--function", "x", "--domain", "0,1,1,1"]);
    assert!(err.contains("domain is empty on y"), "{err}");

    let err = stderr_of_failure(&["mesh", "--function", "x", "--max-vertices", "3"]);
    assert!(err.contains("max_vertices must be between 4"), "{err}");

    let err = stderr_of_failure(&["mesh", "--max-vertices", "10"]);
    assert!(err.contains("--function") && err.contains("--grid"), "{err}");

    let err = stderr_of_failure(&["mesh", "--function", "x", "--method", "data-dependent"]);
    assert!(err.contains("--method: method data-dependent needs a grid"), "{err}");
    let grid = temp_file("grid_dd.json", r#"{"nx": 3, "ny": 2, "values": [0, 1, 4, 1, 2, 0]}"#);
    let doc = document(&[
        "mesh",
        "--grid",
        grid.to_str().unwrap(),
        "--method",
        "data-dependent",
        "--max-vertices",
        "5",
    ]);
    assert_eq!(doc["stats"]["vertices"], 5);
}

#[test]
fn output_infers_the_format_from_the_extension_and_format_overrides_it() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"));
    let obj = dir.join("cli_mesh.obj");
    let out =
        meshfit(&["mesh", "--function", "x*y", "--max-vertices", "50", "--output", obj.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(out.stdout.is_empty(), "the mesh went to the file");
    let text = std::fs::read_to_string(&obj).unwrap();
    assert_eq!(text.lines().filter(|l| l.starts_with("v ")).count(), 50);
    // --format wins over the extension.
    let png = dir.join("cli_mesh.dat");
    let out = meshfit(&[
        "mesh",
        "--function",
        "x*y",
        "--max-vertices",
        "50",
        "--format",
        "png",
        "-o",
        png.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    assert!(std::fs::read(&png).unwrap().starts_with(b"\x89PNG"));
    let err =
        stderr_of_failure(&["mesh", "--function", "x", "--output", dir.join("mesh.xyz").to_str().unwrap()]);
    assert!(err.contains("cannot tell the format") && err.contains("--format"), "{err}");
    let err = stderr_of_failure(&["mesh", "--function", "x", "--format", "dxf"]);
    assert!(err.contains("unknown format `dxf`") && err.contains("glb"), "{err}");
}

#[test]
fn a_raw_grid_file_with_its_hints_meshes_like_the_same_json_grid() {
    let values = [0.0f64, 1.0, 4.0, 1.0, 2.0, 5.0];
    let json = temp_file("grid_same.json", r#"{"nx": 3, "ny": 2, "values": [0, 1, 4, 1, 2, 5]}"#);
    // Raw samples list the top row first, as images do.
    let raw: Vec<u8> = values[3..].iter().chain(&values[..3]).flat_map(|v| v.to_le_bytes()).collect();
    let raw_path = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("grid_same.f64");
    std::fs::write(&raw_path, raw).unwrap();
    let from_json = document(&["mesh", "--grid", json.to_str().unwrap(), "--max-vertices", "30"]);
    let raw_args = ["mesh", "--grid", raw_path.to_str().unwrap(), "--nx", "3", "--ny", "2", "--dtype", "f64"];
    let from_raw = document(&[&raw_args[..], &["--max-vertices", "30"]].concat());
    assert_eq!(from_json, from_raw);
    let err = stderr_of_failure(&["mesh", "--grid", raw_path.to_str().unwrap()]);
    assert!(err.contains("nx"), "{err}");
}

#[test]
fn solve_prints_the_solution_document_the_api_serves() {
    let request =
        r#"{"f": "1", "regions": [{"x": [0.25, 0.5], "y": [0.25, 0.5], "k": 10}], "max_vertices": 800}"#;
    let path = temp_file("solve_inclusion.json", request);
    let doc = document(&["solve", path.to_str().unwrap()]);
    // The document the API encodes for the same request, without its id.
    let limits = meshfit::spec::Limits {
        max_vertices: 1 << 20,
        max_grid_points: 1 << 20,
        max_expression_len: 4096,
        job_time_limit: std::time::Duration::from_secs(600),
    };
    let (spec, _) =
        meshfit::spec::SolveSpec::from_request(serde_json::from_str(request).unwrap(), &limits).unwrap();
    let adapted = spec.solve(&mut ()).unwrap();
    let result = std::sync::Arc::new(adapted.into_result(spec.physics));
    let encoded =
        meshfit::output::encode(&result, meshfit::output::Format::Json, &Default::default()).to_vec();
    assert_eq!(doc, serde_json::from_slice::<Value>(&encoded).unwrap());
    assert_eq!(doc["vertices"].as_array().unwrap().len(), 800);
    assert!(doc.get("flux_density").is_none(), "poisson has no flux density");
}

#[test]
fn solve_reads_stdin_and_stats_give_the_time_of_each_solve() {
    let request = r#"{"physics": "magnetostatic", "regions": [{"x": [0.4, 0.6], "y": [0.4, 0.6], "current_density": 1e6}], "max_vertices": 500}"#;
    let mut child = Command::new(env!("CARGO_BIN_EXE_meshfit"))
        .args(["solve", "-", "--stats"])
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    use std::io::Write;
    child.stdin.take().unwrap().write_all(request.as_bytes()).unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success());
    let doc: Value = serde_json::from_slice(&out.stdout).unwrap();
    let solves = doc["stats"]["solves"].as_u64().unwrap() as usize;
    assert_eq!(doc["stats"]["physics"], "magnetostatic");
    let times: Vec<f64> = serde_json::from_value(doc["solve_times_ms"].clone()).unwrap();
    assert_eq!(times.len(), solves);
    assert!(times.windows(2).all(|w| w[0] <= w[1]), "times are cumulative: {times:?}");
}

#[test]
fn solve_names_the_field_and_column_of_a_bad_expression() {
    let path = temp_file("solve_bad.json", r#"{"g": "x +* y"}"#);
    let err = stderr_of_failure(&["solve", path.to_str().unwrap()]);
    assert!(err.contains("g:") && err.contains("column 4"), "{err}");
}

#[test]
fn solve_names_the_field_of_a_value_of_the_wrong_type() {
    let path = temp_file("solve_wrong_type.json", r#"{"domain": {"x": [0, 1], "y": [0, "1"]}}"#);
    let err = stderr_of_failure(&["solve", path.to_str().unwrap()]);
    assert!(err.contains("domain.y[1]: invalid type") && !err.contains("column"), "{err}");
}

#[test]
fn a_run_larger_than_the_memory_available_is_refused_before_it_starts() {
    // 4·10^8 vertices (the engine's limit) need about 90 GB: more than any test machine has.
    let err = stderr_of_failure(&["mesh", "--function", "x", "--max-vertices", "400000000"]);
    assert!(err.contains("needs about") && err.contains("224 bytes a vertex"), "{err}");
    assert!(err.contains("of memory available; lower the budget"), "{err}");
}

#[test]
fn serve_names_the_flag_of_a_bad_setting_and_the_variable_it_sets() {
    let out = Command::new(env!("CARGO_BIN_EXE_meshfit"))
        .args(["serve", "--workers", "0"])
        .env("MESHFIT_QUEUE", "lots")
        .output()
        .expect("meshfit runs");
    assert!(!out.status.success());
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(stderr.contains(r#"--workers "0" (MESHFIT_WORKERS): must be at least 1"#), "{stderr}");
    assert!(stderr.contains(r#"MESHFIT_QUEUE="lots": expected a whole number"#), "{stderr}");
}

#[test]
fn serve_help_has_a_flag_for_every_setting_but_the_secrets_with_its_variable_and_default() {
    let out =
        Command::new(env!("CARGO_BIN_EXE_meshfit")).args(["serve", "--help"]).output().expect("meshfit runs");
    let help = String::from_utf8(out.stdout).unwrap();
    let mut flags = 0;
    for setting in meshfit::config::SETTINGS {
        let Some(flag) = setting.flag else {
            assert!(!help.contains(&format!("{}:", setting.name)), "{} is not a flag", setting.name);
            continue;
        };
        let line =
            help.lines().find(|l| l.trim_start().starts_with(&format!("--{flag} <"))).unwrap_or_else(|| {
                panic!("no --{flag} in:\n{help}");
            });
        assert!(line.contains(&format!("<{}>", setting.value_name)) && line.contains(setting.name), "{line}");
        assert!(line.contains(&format!("[default: {}]", setting.default)), "{line}");
        flags += 1;
    }
    assert!(flags >= 25, "{flags}");
    // A flag given twice, or one that does not exist, is clap's error, not a start.
    let out = Command::new(env!("CARGO_BIN_EXE_meshfit")).args(["serve", "--wokers", "2"]).output().unwrap();
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("--workers"));
    let out = Command::new(env!("CARGO_BIN_EXE_meshfit"))
        .args(["serve", "--workers", "2", "--workers", "3"])
        .output()
        .unwrap();
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("--workers"));
}

/// A port that was free a moment ago.
fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

/// Runs `meshfit health` with `args`.
fn health(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_meshfit")).arg("health").args(args).output().expect("meshfit runs")
}

#[test]
fn health_answers_for_a_server_at_the_configured_address_and_fails_without_one() {
    let port = free_port();
    let addr = format!("localhost:{port}");
    let down = health(&["--addr", &addr]);
    assert!(!down.status.success());
    let stderr = String::from_utf8_lossy(&down.stderr);
    assert!(stderr.contains("no server answers at"), "{stderr}");

    // MESHFIT_ADDR with a host name, as a container sets it; the start-up line names the page.
    let mut server = Command::new(env!("CARGO_BIN_EXE_meshfit"))
        .arg("serve")
        .env("MESHFIT_ADDR", &addr)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("meshfit serves");
    let mut lines = std::io::BufRead::lines(std::io::BufReader::new(server.stderr.take().unwrap()));
    let started = lines.next().expect("a start-up line").unwrap();
    let up = Command::new(env!("CARGO_BIN_EXE_meshfit"))
        .arg("health")
        .env("MESHFIT_ADDR", &addr)
        .output()
        .expect("meshfit runs");
    server.kill().unwrap();
    server.wait().unwrap();
    assert!(up.status.success(), "{}", String::from_utf8_lossy(&up.stderr));
    // localhost is 127.0.0.1 or ::1, as the resolver lists it.
    let opened = [format!("open=http://127.0.0.1:{port}/"), format!("open=http://[::1]:{port}/")];
    assert!(opened.iter().any(|url| started.contains(url)), "{started}");
    assert!(started.contains("api_keys=\"off: the API is open\""), "{started}");
    assert!(
        started.contains("memory_budget=") && started.contains("cache_dir=\"none: memory only\""),
        "{started}"
    );
}

#[test]
fn health_of_a_wildcard_address_asks_on_loopback_and_a_bad_address_is_named() {
    // Nothing listens on a fresh port: the question went to 127.0.0.1, not to 0.0.0.0.
    let port = free_port();
    let out = health(&["--addr", &format!("0.0.0.0:{port}")]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.contains(&format!("127.0.0.1:{port}")), "{stderr}");
    let out = health(&["--addr", "8080"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains(r#"--addr "8080": expected host:port"#), "{stderr}");
}

#[test]
fn serve_stops_at_start_up_naming_a_cache_directory_it_cannot_use() {
    // A regular file where the directory should be: it can be neither created nor listed.
    let file = temp_file("not-a-directory", "x");
    let out = Command::new(env!("CARGO_BIN_EXE_meshfit"))
        .arg("serve")
        .env("MESHFIT_ADDR", "127.0.0.1:0")
        .env("MESHFIT_CACHE_DIR", &file)
        .output()
        .expect("meshfit runs");
    assert!(!out.status.success());
    let stderr = String::from_utf8(out.stderr).unwrap();
    let named = format!("MESHFIT_CACHE_DIR={}", file.display());
    assert!(stderr.contains(&named) && stderr.contains("cannot use it"), "{stderr}");
}

#[test]
fn the_quick_starts_sample_grids_hold_the_tiles_heights() {
    use meshfit::source::{Encoding, GridHints, RawType, decode_grid};
    let examples = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("examples");
    let read = |name: &str| std::fs::read(examples.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
    let decode = |name: &str, hints: GridHints| decode_grid(&read(name), &hints, usize::MAX).unwrap();
    let terrarium = GridHints { encoding: Some(Encoding::Terrarium), ..GridHints::default() };
    let tile = decode("tiles/jacksboro-terrarium.png", terrarium).grid;
    let raw = GridHints { nx: Some(256), ny: Some(256), dtype: Some(RawType::F32), ..GridHints::default() };
    for (name, hints) in [
        ("grids/dem.tif", GridHints::default()),
        ("grids/dem-4326.tif", GridHints::default()),
        ("grids/heightmap.png", GridHints::default()),
        ("grids/heights.npy", GridHints::default()),
        ("grids/heights.f32", raw),
    ] {
        let decoded = decode(name, hints);
        assert_eq!((decoded.grid.nx(), decoded.grid.ny()), (256, 256), "{name}");
        let same = (0..256).all(|j| decoded.grid.row(j) == tile.row(j));
        assert!(same, "{name} holds other heights than the tile, or holds them in another order");
    }
    // The GeoTIFF places its pixel centres: 30 m pixels, the first one's corner at (500000, 4000000).
    let domain = decode("grids/dem.tif", GridHints::default()).domain.expect("a georeferenced file");
    let bounds = (domain.x0(), domain.x1(), domain.y0(), domain.y1());
    assert_eq!(bounds, (500_015.0, 507_665.0, 3_992_335.0, 3_999_985.0));
    // Its twin for `meshfit tiles` is in EPSG:4326, one arc-second pixels.
    let decoded = decode("grids/dem-4326.tif", GridHints::default());
    assert_eq!(decoded.crs, Some(meshfit::source::Crs::Geographic(Some(4326))));
    let domain = decoded.domain.expect("a georeferenced file");
    assert!(
        (domain.x0() - (-98.25 + 0.5 / 3600.0)).abs() < 1e-12
            && (domain.y1() - (33.3 - 0.5 / 3600.0)).abs() < 1e-12
    );
}

/// A GeoTIFF in EPSG:4326 of `nx` × `ny` f32 heights, its top-left pixel's corner at
/// (`west`, `north`), `pixel` degrees a side.
fn geotiff_4326(
    name: &str,
    (nx, ny): (u32, u32),
    (west, north, pixel): (f64, f64, f64),
    keys: &[u16],
) -> PathBuf {
    use tiff::encoder::{TiffEncoder, colortype};
    use tiff::tags::Tag;
    let data: Vec<f32> = (0..ny)
        .flat_map(|row| (0..nx).map(move |column| (column, row)))
        .map(|(i, j)| {
            500.0 + 300.0 * ((i as f32) * 0.05).sin() * ((j as f32) * 0.07).cos() + (i * j % 13) as f32
        })
        .collect();
    let mut bytes = Vec::new();
    let mut encoder = TiffEncoder::new(std::io::Cursor::new(&mut bytes)).unwrap();
    let mut image = encoder.new_image::<colortype::Gray32Float>(nx, ny).unwrap();
    image.encoder().write_tag(Tag::ModelPixelScaleTag, &[pixel, pixel, 0.0][..]).unwrap();
    image.encoder().write_tag(Tag::ModelTiepointTag, &[0.0, 0.0, 0.0, west, north, 0.0][..]).unwrap();
    image.encoder().write_tag(Tag::GeoKeyDirectoryTag, keys).unwrap();
    image.write_data(&data).unwrap();
    let path = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

const WGS84_KEYS: [u16; 12] = [1, 1, 0, 2, 1024, 0, 1, 2, 2048, 0, 1, 4326];

#[test]
fn tiles_writes_a_crack_free_pyramid_and_its_layer_json() {
    // 0.6° × 0.4° at 9 arc-seconds, near 10.2°E 45.6°N: level 11 reaches the pixel.
    let dem = geotiff_4326("alps.tif", (241, 161), (10.2, 45.6, 0.0025), &WGS84_KEYS);
    let out = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("alps-tiles");
    let _ = std::fs::remove_dir_all(&out);
    let run = meshfit(&["tiles", dem.to_str().unwrap(), "--out", out.to_str().unwrap(), "--max-zoom", "9"]);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let layer: Value = serde_json::from_slice(&std::fs::read(out.join("layer.json")).unwrap()).unwrap();
    assert_eq!(layer["format"], "quantized-mesh-1.0");
    assert_eq!((layer["scheme"].as_str(), layer["projection"].as_str()), (Some("tms"), Some("EPSG:4326")));
    assert_eq!(layer["maxzoom"], 9);
    assert_eq!(layer["extensions"], serde_json::json!(["octvertexnormals", "metadata"]));
    let available = layer["available"].as_array().unwrap();
    assert_eq!(available.len(), 10);
    assert_eq!(available[0], serde_json::json!([{"startX": 0, "startY": 0, "endX": 1, "endY": 0}]));
    // Every tile layer.json lists is on disk and decodes; neighbours at the deepest level
    // agree on every vertex of their common side.
    let mut written = 0;
    let mut deepest = std::collections::BTreeMap::new();
    for (z, ranges) in available.iter().enumerate() {
        for range in ranges.as_array().unwrap() {
            let n = |k: &str| range[k].as_u64().unwrap();
            for y in n("startY")..=n("endY") {
                for x in n("startX")..=n("endX") {
                    let bytes = std::fs::read(out.join(format!("{z}/{x}/{y}.terrain"))).unwrap();
                    let mesh = quantized_mesh::DecodedMesh::decode(&bytes).unwrap();
                    assert!(!mesh.indices.is_empty());
                    written += 1;
                    if z == 9 {
                        deepest.insert((x, y), mesh);
                    }
                }
            }
        }
    }
    assert!(written > 12, "{written} tiles");
    let height = |m: &quantized_mesh::DecodedMesh, k: u32| {
        let (lo, hi) = (f64::from(m.header.min_height), f64::from(m.header.max_height));
        lo + f64::from(m.vertices.height[k as usize]) / 32767.0 * (hi - lo)
    };
    let mut sides = 0;
    for (&(x, y), mesh) in &deepest {
        if let Some(east) = deepest.get(&(x + 1, y)) {
            let ours: Vec<u16> =
                mesh.edge_indices.east.iter().map(|&k| mesh.vertices.v[k as usize]).collect();
            let theirs: Vec<u16> =
                east.edge_indices.west.iter().map(|&k| east.vertices.v[k as usize]).collect();
            assert_eq!(ours, theirs, "tiles {x}/{y} and {}/{y} disagree on their side", x + 1);
            // Normals come from the DEM around each vertex: the same on both sides.
            let normal =
                |m: &quantized_mesh::DecodedMesh, k: u32| m.extensions.normals.as_ref().unwrap()[k as usize];
            for (&a, &b) in mesh.edge_indices.east.iter().zip(&east.edge_indices.west) {
                assert_eq!(normal(mesh, a), normal(east, b));
            }
            for (&a, &b) in mesh.edge_indices.east.iter().zip(&east.edge_indices.west) {
                // Each tile quantizes heights over its own range: equal within both quanta.
                let quanta = (mesh.header.max_height - mesh.header.min_height + east.header.max_height
                    - east.header.min_height) as f64
                    / 32767.0;
                assert!((height(mesh, a) - height(east, b)).abs() <= quanta);
            }
            sides += 1;
        }
    }
    assert!(sides > 0, "some tiles at level 9 have an east neighbour");
}

#[test]
fn tiles_refuses_a_projected_or_unreferenced_dem_naming_why() {
    let utm = geotiff_4326(
        "utm.tif",
        (20, 20),
        (500_000.0, 5_000_000.0, 30.0),
        &[1, 1, 0, 2, 1024, 0, 1, 1, 3072, 0, 1, 32632],
    );
    let out = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("utm-tiles");
    let refused = |dem: &PathBuf, extra: &[&str]| {
        stderr_of_failure(
            &[&["tiles", dem.to_str().unwrap(), "--out", out.to_str().unwrap()], extra].concat(),
        )
    };
    let err = refused(&utm, &[]);
    assert!(err.contains("EPSG:32632") && err.contains("projected") && err.contains("EPSG:4326"), "{err}");
    let plain = temp_file("plain.json", r#"{"nx": 2, "ny": 2, "values": [1, 2, 3, 4]}"#);
    let err = refused(&plain, &[]);
    assert!(err.contains("not georeferenced"), "{err}");
    let dem = geotiff_4326("small.tif", (20, 20), (10.0, 46.0, 0.01), &WGS84_KEYS);
    let err = refused(&dem, &["--min-zoom", "5", "--max-zoom", "3"]);
    assert!(err.contains("levels 5..=3"), "{err}");
    let err = refused(&dem, &["--max-zoom", "30"]);
    assert!(err.contains("more than 10000000") && err.contains("lower max level"), "{err}");
}

#[test]
fn cesium_reads_every_tile_as_written_and_sees_no_crack() {
    let Some(cesium) = cesium() else { return };
    let dem = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("examples/grids/dem-4326.tif");
    let out = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("cesium-tiles");
    let _ = std::fs::remove_dir_all(&out);
    let run = meshfit(&["tiles", dem.to_str().unwrap(), "--out", out.to_str().unwrap(), "--max-zoom", "12"]);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let check = Command::new("node").arg(cesium.join("check.mjs")).arg(&out).output().expect("node runs");
    assert!(check.status.success(), "CesiumJS failed: {}", String::from_utf8_lossy(&check.stderr));
    let lines: Vec<Value> =
        String::from_utf8(check.stdout).unwrap().lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    let (summary, tiles) = lines.split_last().unwrap();
    // Every tile layer.json lists: available to Cesium, and read as the quantized-mesh crate
    // reads it, down to the edge lists.
    let mut quantum = 0.0f64;
    for tile in tiles {
        let at = |k: &str| tile[k].as_u64().unwrap();
        let bytes = std::fs::read(out.join(format!("{}/{}/{}.terrain", at("z"), at("x"), at("y")))).unwrap();
        let ours = quantized_mesh::DecodedMesh::decode(&bytes).unwrap();
        assert_eq!(tile["available"], true, "{tile}");
        assert_eq!(at("vertices") as usize, ours.vertices.u.len(), "{tile}");
        assert_eq!(at("triangles") as usize, ours.indices.len() / 3, "{tile}");
        assert_eq!(at("normals") as usize, ours.vertices.u.len(), "Cesium reads a normal a vertex: {tile}");
        let e = &ours.edge_indices;
        assert_eq!(
            tile["edges"],
            serde_json::json!([e.west.len(), e.south.len(), e.east.len(), e.north.len()])
        );
        if at("z") == 12 {
            quantum = quantum.max(f64::from(ours.header.max_height - ours.header.min_height) / 32767.0);
        }
    }
    assert_eq!(tiles.len(), 17, "levels 0..=12 of the DEM: 2 roots, 1 tile a level to 11, 4 at 12");
    // Across each common side Cesium's heights differ by quantization alone (each tile
    // quantizes over its own range): no crack.
    assert!(summary["sides"].as_u64().unwrap() > 0, "{summary}");
    assert!(summary["gap"].as_f64().unwrap() <= quantum + 1e-9, "{summary}, a quantum is {quantum}");
}

#[test]
fn counts_read_as_the_api_reads_them_and_a_grid_comes_from_stdin() {
    use std::io::Write;
    let a = document(&["mesh", "--function", "x*y", "--max-vertices", "1e2", "--stats"]);
    let b = document(&["mesh", "--function", "x*y", "--max-vertices", "100", "--stats"]);
    assert_eq!(a["stats"]["vertices"], 100);
    assert_eq!(a["stats"], b["stats"]);
    let err = stderr_of_failure(&["mesh", "--function", "x*y", "--max-vertices", "1.5"]);
    assert!(err.contains("`1.5` is not a whole number"), "{err}");
    // The same grid from a file and from stdin.
    let grid = r#"{"nx": 3, "ny": 2, "values": [0, 1, 4, 1, 2, 9]}"#;
    let path = temp_file("stdin-grid.json", grid);
    let from_file = document(&["mesh", "--grid", path.to_str().unwrap(), "--max-vertices", "6"]);
    let mut child = Command::new(env!("CARGO_BIN_EXE_meshfit"))
        .args(["mesh", "--grid", "-", "--max-vertices", "6"])
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(grid.as_bytes()).unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let from_stdin: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(from_stdin["vertices"], from_file["vertices"]);
    assert_eq!(from_stdin["stats"]["vertices"], 6);
}

#[test]
fn an_output_option_the_format_does_not_take_is_refused() {
    let err = stderr_of_failure(&["mesh", "--function", "x*y", "--z-scale", "2"]);
    assert!(err.contains("--z-scale does not apply to format json"), "{err}");
    let err = stderr_of_failure(&["mesh", "--function", "x*y", "--format", "svg", "--size", "100"]);
    assert!(err.contains("--size does not apply to format svg"), "{err}");
    let out =
        meshfit(&["mesh", "--function", "x*y", "--max-vertices", "9", "--format", "obj", "--z-scale", "2"]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    let z: Vec<f64> = text
        .lines()
        .filter_map(|l| l.strip_prefix("v "))
        .map(|l| l.split(' ').nth(2).unwrap().parse().unwrap())
        .collect();
    // x*y on [0,1]²: the far corner is 1, doubled.
    assert!(z.contains(&2.0), "{z:?}");
}
