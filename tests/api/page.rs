//! The page at `/`, driven in headless Chromium through chromedriver (WebDriver, fantoccini).
//!
//! Needs Debian's `chromium` and `chromium-driver` (`.ci/run` installs them). Without them the
//! test says so and passes, unless `BROWSER_TESTS=required` (set by `.ci/run`), which
//! makes a missing browser a failure. `UPDATE_SCREENSHOT=1` also writes the screenshot
//! to docs/page.png, the one in the README.

use crate::helpers::{TestApp, spawn_with};
use fantoccini::{Client, ClientBuilder, Locator};
use futures_util::FutureExt;
use serde_json::{Value, json};
use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

/// How long the page may take to finish a job: a bound on a wait, never an assertion.
const PATIENCE: Duration = Duration::from_secs(120);

/// chromedriver on a loopback port, killed when dropped.
struct Driver {
    child: Child,
    url: String,
}

impl Drop for Driver {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn find_program(name: &str, variable: &str) -> Option<PathBuf> {
    if let Some(path) = std::env::var_os(variable) {
        return Some(PathBuf::from(path));
    }
    std::env::split_paths(&std::env::var_os("PATH")?).map(|dir| dir.join(name)).find(|p| p.is_file())
}

/// chromedriver and the browser, or `None` (with the reason printed) when this machine has none
/// and they are not required.
async fn browser() -> Option<(Driver, Client)> {
    let required = std::env::var("BROWSER_TESTS").is_ok_and(|v| v == "required");
    let driver = find_program("chromedriver", "CHROMEDRIVER");
    let chromium = find_program("chromium", "CHROMIUM");
    let (Some(driver), Some(chromium)) = (driver, chromium) else {
        assert!(!required, "BROWSER_TESTS=required, but chromium or chromedriver is missing");
        eprintln!("skipped: no chromium and chromedriver (apt-get install chromium chromium-driver)");
        return None;
    };
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let child = Command::new(driver)
        .arg(format!("--port={port}"))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("chromedriver starts");
    let driver = Driver { child, url: format!("http://127.0.0.1:{port}") };
    let capabilities = json!({
        "goog:chromeOptions": {
            "binary": chromium,
            "args": ["--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--window-size=1280,1000",
                     "--enable-unsafe-swiftshader", "--hide-scrollbars"],
        }
    });
    let Value::Object(capabilities) = capabilities else { unreachable!() };
    let connector = hyper_util::client::legacy::connect::HttpConnector::new();
    // chromedriver takes a moment to listen.
    for _ in 0..100 {
        let session = ClientBuilder::new(connector.clone())
            .capabilities(capabilities.clone())
            .connect(&driver.url)
            .await;
        match session {
            Ok(client) => return Some((driver, client)),
            Err(_) => tokio::time::sleep(Duration::from_millis(100)).await,
        }
    }
    panic!("chromedriver did not start a session at {}", driver.url);
}

/// Waits for the page's job to end (`body[data-state=done]`) or for an error to show.
async fn wait_until(client: &Client, css: &str) {
    client
        .wait()
        .at_most(PATIENCE)
        .for_element(Locator::Css(css))
        .await
        .unwrap_or_else(|e| panic!("{css} never appeared: {e}"));
}

/// Of the canvas `id`: pixels that are not the white background, and distinct colours.
async fn canvas_ink(client: &Client, id: &str) -> (u64, u64) {
    let script = r#"
        const c = document.getElementById(arguments[0]);
        const d = c.getContext("2d").getImageData(0, 0, c.width, c.height).data;
        let ink = 0; const colours = new Set();
        for (let i = 0; i < d.length; i += 4) {
            if (d[i] < 250 || d[i + 1] < 250 || d[i + 2] < 250) { ink++; colours.add((d[i] << 16) | (d[i + 1] << 8) | d[i + 2]); }
        }
        return [ink, colours.size, c.width * c.height];
    "#;
    let out = client.execute(script, vec![json!(id)]).await.unwrap();
    (out[0].as_u64().unwrap(), out[1].as_u64().unwrap())
}

/// The stats table as the page shows it: `data-stat` name → the exact value.
async fn page_stats(client: &Client) -> serde_json::Map<String, Value> {
    let script = r##"
        const out = {};
        for (const td of document.querySelectorAll("#stats td[data-stat]")) out[td.dataset.stat] = JSON.parse(td.dataset.value);
        return out;
    "##;
    match client.execute(script, vec![]).await.unwrap() {
        Value::Object(map) => map,
        other => panic!("stats: {other}"),
    }
}

/// The job id of the page's result, from its download links.
async fn page_job(client: &Client) -> String {
    let href = client.find(Locator::Css("#download-links a[data-format=obj]")).await.unwrap();
    let href = href.attr("href").await.unwrap().expect("a link");
    href.strip_prefix("/v1/jobs/").and_then(|s| s.split('/').next()).expect("a job link").to_owned()
}

/// Saves what the browser shows as the test artifact `name`.png under the target directory,
/// and returns the PNG.
async fn screenshot(client: &Client, name: &str) -> Vec<u8> {
    let png = client.screenshot().await.unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    let path = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("browser/{name}.png"));
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(&path, &png).unwrap();
    eprintln!("screenshot: {}", path.display());
    png
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_page_runs_a_shared_address_draws_the_mesh_and_shows_the_apis_stats() {
    let Some((_driver, client)) = browser().await else { return };
    // Grids as large as the example DEM, which the terrain tab uploads.
    let app = spawn_with(crate::helpers::configured(|c| c.limits.max_grid_points = 1 << 20)).await;
    let mut keys = meshfit::config::ApiKeys::default();
    keys.insert(KEY);
    let keyed = spawn_with(crate::helpers::configured(|c| c.callers.api_keys = keys)).await;
    // A failed assertion must still end the browser session, so it is caught and re-raised.
    let outcome = AssertUnwindSafe(async {
        shared_address(&app, &client).await;
        bad_expression(&app, &client).await;
        grid_file(&app, &client).await;
        boundary_value_problem(&app, &client).await;
        device(&app, &client).await;
        terrain(&app, &client).await;
        client_job(&app, &client).await;
        api_key(&keyed, &client).await;
    })
    .catch_unwind()
    .await;
    let _ = client.close().await;
    app.shutdown().await;
    keyed.shutdown().await;
    if let Err(panic) = outcome {
        std::panic::resume_unwind(panic);
    }
}

async fn shared_address(app: &TestApp, client: &Client) {
    client.goto(&app.url("/?function=sin(5*x)*y&max_vertices=3000&x=0,2&y=0,1")).await.unwrap();
    wait_until(client, "body[data-state=done]").await;

    // The address filled the form and ran the job: the mesh is drawn filled by value.
    let (ink, colours) = canvas_ink(client, "flat").await;
    assert!(ink > 200_000, "the 800×800 canvas has {ink} drawn pixels");
    assert!(colours > 40, "a mesh filled by value has many colours, got {colours}");
    // Its axes tick the domain [0, 2] × [0, 1] at round numbers.
    let flat = client.find(Locator::Id("flat")).await.unwrap();
    assert_eq!(flat.attr("data-x-ticks").await.unwrap().as_deref(), Some("0.0 0.5 1.0 1.5 2.0"));
    assert_eq!(flat.attr("data-y-ticks").await.unwrap().as_deref(), Some("0.0 0.2 0.4 0.6 0.8 1.0"));
    let (plot, _) = canvas_ink(client, "convergence").await;
    assert!(plot > 2_000, "the convergence plot drew {plot} pixels");

    // The stats on the page are the API's, bit for bit.
    let id = page_job(client).await;
    let status: Value = app.get(&format!("/v1/jobs/{id}")).await.json().await.unwrap();
    let api = &status["stats"];
    assert_eq!(api["vertices"], 3000);
    let shown = page_stats(client).await;
    let expected = [
        ("vertices", &api["vertices"]),
        ("triangles", &api["triangles"]),
        ("variation", &api["variation"]),
        ("max_triangle_error", &api["max_triangle_error"]),
        ("max_error", &api["quality"]["max_error"]),
        ("rms_error", &api["quality"]["rms_error"]),
        ("min_angle_deg", &api["quality"]["min_angle_deg"]),
        ("evaluations", &api["evaluations"]),
        ("stop", &api["stop"]),
    ];
    for (name, value) in expected {
        assert!(!value.is_null(), "the API reports {name}");
        assert_eq!(shown.get(name), Some(value), "{name} on the page");
    }

    // Every format is offered, and the OBJ and PNG links download what they say.
    let formats: Value = client
        .execute(
            "return [...document.querySelectorAll('#download-links a')].map(a => a.dataset.format)",
            vec![],
        )
        .await
        .unwrap();
    assert_eq!(formats, json!(["json", "obj", "ply", "stl", "vtu", "msh", "glb", "svg", "png"]));
    let obj = app.get(&format!("/v1/jobs/{id}/mesh?format=obj")).await;
    assert_eq!(obj.headers()["content-type"], "model/obj");
    assert_eq!(obj.text().await.unwrap().lines().filter(|l| l.starts_with("v ")).count(), 3000);
    let png = app.get(&format!("/v1/jobs/{id}/mesh?format=png")).await.bytes().await.unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");

    // The curl line reproduces the job: the same request gives the same id.
    let curl = client.find(Locator::Id("curl")).await.unwrap().text().await.unwrap();
    let body = curl.split(" -d '").nth(1).and_then(|s| s.strip_suffix('\'')).expect("a -d body");
    let again = app.post("/v1/meshes", &serde_json::from_str(body).unwrap()).await;
    assert_eq!(again.headers()["etag"], format!("\"{id}\"").as_str());

    // The share link is the address that reproduces this view.
    let share = client.find(Locator::Id("share")).await.unwrap().attr("href").await.unwrap().unwrap();
    assert!(share.contains("function=sin%285*x%29*y") && share.contains("max_vertices=3000"), "{share}");

    let png = screenshot(client, "page").await;
    if std::env::var_os("UPDATE_SCREENSHOT").is_some() {
        std::fs::write(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/page.png"), small_png(&png)).unwrap();
    }

    // The 3-D view draws the surface.
    client.find(Locator::Css("button[data-view=surface]")).await.unwrap().click().await.unwrap();
    let drawn: Value = client
        .execute(
            r#"const c = document.getElementById("surface");
               const g = c.getContext("webgl", {preserveDrawingBuffer: true});
               if (!g) return -1;
               const px = new Uint8Array(4 * c.width * c.height);
               g.readPixels(0, 0, c.width, c.height, g.RGBA, g.UNSIGNED_BYTE, px);
               let ink = 0; for (let i = 0; i < px.length; i += 4) if (px[i] < 250 || px[i+1] < 250 || px[i+2] < 250) ink++;
               return ink;"#,
            vec![],
        )
        .await
        .unwrap();
    // A browser without WebGL says so on the page instead (-1); one with it draws the surface.
    let drawn = drawn.as_i64().unwrap();
    assert!(drawn == -1 || drawn > 50_000, "the surface drew {drawn} pixels");
    screenshot(client, "page-surface").await;

    // The error view colours each triangle by its error, read from the PLY.
    client.find(Locator::Css("button[data-view=error]")).await.unwrap().click().await.unwrap();
    wait_until(client, "#legend[data-mode=error]").await;
    let legend = client.find(Locator::Id("legend")).await.unwrap().text().await.unwrap();
    assert!(legend.starts_with("log10 error per triangle"), "{legend}");
    // Its colour bar runs over the errors themselves, smallest first.
    let bar: Value = client
        .execute(
            r#"const b = document.getElementById("colourbar");
               return [b.hidden, ...[".what", ".lo", ".hi"].map(c => b.querySelector(c).textContent)];"#,
            vec![],
        )
        .await
        .unwrap();
    assert_eq!(bar[0], false, "{bar}");
    assert_eq!(bar[1], "error per triangle (log scale)");
    let (lo, hi): (f64, f64) =
        (bar[2].as_str().unwrap().parse().unwrap(), bar[3].as_str().unwrap().parse().unwrap());
    assert!(0.0 < lo && lo < hi, "{bar}");
    let (ink, colours) = canvas_ink(client, "flat").await;
    assert!(ink > 200_000 && colours > 40, "error view: {ink} pixels, {colours} colours");
    screenshot(client, "page-error").await;
    client.find(Locator::Css("button[data-view=flat]")).await.unwrap().click().await.unwrap();
}

/// `png` again with a palette of 256 colours (NeuQuant), which keeps the README's copy small.
fn small_png(png: &[u8]) -> Vec<u8> {
    let mut reader = png::Decoder::new(std::io::Cursor::new(png)).read_info().unwrap();
    let mut pixels = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut pixels).unwrap();
    let channels = info.color_type.samples();
    let rgba: Vec<u8> =
        pixels[..info.buffer_size()].chunks(channels).flat_map(|p| [p[0], p[1], p[2], 255]).collect();
    let quant = color_quant::NeuQuant::new(10, 256, &rgba);
    let indices: Vec<u8> = rgba.chunks(4).map(|p| quant.index_of(p) as u8).collect();
    let palette: Vec<u8> = quant.color_map_rgb();
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, info.width, info.height);
    encoder.set_color(png::ColorType::Indexed);
    encoder.set_palette(palette);
    encoder.set_compression(png::Compression::High);
    encoder.write_header().unwrap().write_image_data(&indices).unwrap();
    out
}

async fn bad_expression(app: &TestApp, client: &Client) {
    // `q` is not a variable: the API names column 8, and the page shows it under the field. The
    // `+` typed in the address is a plus, not the space a query string would make of it.
    client.goto(&app.url("/?function=sin(x)+q")).await.unwrap();
    wait_until(client, "body[data-state=failed]").await;
    let text =
        client.find(Locator::Css(".field-error[data-for=function]")).await.unwrap().text().await.unwrap();
    assert!(text.contains("unknown variable") && text.contains("column 8"), "{text}");
    let at: Value = client
        .execute(
            "const f = document.getElementById('function'); return [f.selectionStart, f.selectionEnd, f.classList.contains('invalid')]",
            vec![],
        )
        .await
        .unwrap();
    assert_eq!(at, json!([7, 8, true]), "the input selects the character at column 8");
}

async fn grid_file(app: &TestApp, client: &Client) {
    // A 16-bit greyscale heightmap, picked in the file input.
    let (w, h) = (40u32, 30u32);
    let heights: Vec<u8> = (0..w * h)
        .flat_map(|k| {
            let (i, j) = (f64::from(k % w), f64::from(k / w));
            let v = 30_000.0 + 20_000.0 * (i / 6.0).sin() * (j / 5.0).cos();
            (v as u16).to_be_bytes()
        })
        .collect();
    let path = Path::new(env!("CARGO_TARGET_TMPDIR")).join("browser/heightmap.png");
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    let mut encoder = png::Encoder::new(std::fs::File::create(&path).unwrap(), w, h);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::Sixteen);
    encoder.write_header().unwrap().write_image_data(&heights).unwrap();

    // A first visit runs the example; the file's job replaces it.
    client.goto(&app.url("/")).await.unwrap();
    wait_until(client, "body[data-state=done]").await;
    let input = client.find(Locator::Id("grid-file")).await.unwrap();
    input.send_keys(path.to_str().unwrap()).await.unwrap();
    let disabled = client.find(Locator::Id("function")).await.unwrap().attr("disabled").await.unwrap();
    assert!(disabled.is_some(), "a picked file replaces the function");
    let budget = client.find(Locator::Id("max_vertices")).await.unwrap();
    budget.clear().await.unwrap();
    budget.send_keys("500").await.unwrap();
    client.find(Locator::Id("run")).await.unwrap().click().await.unwrap();
    wait_until(client, r#"body[data-state=done] #stats td[data-stat=vertices][data-value="500"]"#).await;
    let id = page_job(client).await;
    let status: Value = app.get(&format!("/v1/jobs/{id}")).await.json().await.unwrap();
    assert_eq!(status["stats"]["vertices"], 500);
    let mesh: Value = app.get(&format!("/v1/jobs/{id}/mesh")).await.json().await.unwrap();
    // The default domain of a grid: [0, nx-1] x [0, ny-1].
    assert_eq!(mesh["vertices"][2], json!([39.0, 29.0, mesh["vertices"][2][2]]));
    let shown = page_stats(client).await;
    // Compared as numbers: a max error on a grid's nodes may be whole, which the page prints
    // as 270 where the API writes 270.0.
    let max_error = shown.get("max_error").and_then(Value::as_f64);
    assert_eq!(max_error, status["stats"]["quality"]["max_error"].as_f64());
    let curl = client.find(Locator::Id("curl")).await.unwrap().text().await.unwrap();
    assert!(curl.contains("-F grid=@'heightmap.png'"), "{curl}");

    // A file cannot travel in an address, so the link names the job, and opens it.
    let share = client.find(Locator::Id("share")).await.unwrap().attr("href").await.unwrap().unwrap();
    assert_eq!(share, format!("/?job={id}"));
    client.goto(&app.url(&share)).await.unwrap();
    wait_until(client, "body[data-state=done]").await;
    assert_eq!(page_stats(client).await.get("vertices"), Some(&json!(500)));
    // The page says that the form is not the job's request, and offers a fresh one.
    let notice = client.find(Locator::Id("job-notice")).await.unwrap();
    assert!(notice.is_displayed().await.unwrap());
    assert!(notice.text().await.unwrap().contains(&id), "the notice names the job");
    let (ink, _) = canvas_ink(client, "flat").await;
    assert!(ink > 100_000, "the shared job is drawn: {ink} pixels");
}

async fn terrain(app: &TestApp, client: &Client) {
    client.goto(&app.url("/")).await.unwrap();
    wait_until(client, "body[data-state=done]").await;
    client.find(Locator::Id("tab-terrain")).await.unwrap().click().await.unwrap();
    // A projected GeoTIFF is refused where the file is picked, naming its system.
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/grids");
    let input = client.find(Locator::Id("dem-file")).await.unwrap();
    input.send_keys(examples.join("dem.tif").to_str().unwrap()).await.unwrap();
    client.find(Locator::Id("dem-upload")).await.unwrap().click().await.unwrap();
    wait_until(client, "body[data-state=failed]").await;
    let error = client.find(Locator::Css(r#".field-error[data-for="dem"]"#)).await.unwrap();
    assert!(error.text().await.unwrap().contains("EPSG:"), "the problem is shown by the file input");
    // A DEM in EPSG:4326 becomes a dataset: its layer's address and the lines to paste.
    input.clear().await.unwrap();
    input.send_keys(examples.join("dem-4326.tif").to_str().unwrap()).await.unwrap();
    client.find(Locator::Id("dem-upload")).await.unwrap().click().await.unwrap();
    wait_until(client, "body[data-state=done] #terrain-result:not([hidden])").await;
    let listed: Value = app.get("/v1/datasets").await.json().await.unwrap();
    let id = listed["datasets"][0]["id"].as_str().unwrap().to_owned();
    let layer = app.url(&format!("/v1/tiles/{id}/layer.json"));
    let link = client.find(Locator::Id("layer-url")).await.unwrap();
    assert_eq!(link.attr("href").await.unwrap().as_deref(), Some(layer.as_str()));
    let snippet = client.find(Locator::Id("cesium-snippet")).await.unwrap().text().await.unwrap();
    assert!(snippet.contains(&format!("CesiumTerrainProvider.fromUrl(\"{layer}\"")), "{snippet}");
    let curl = client.find(Locator::Id("terrain-curl")).await.unwrap().text().await.unwrap();
    assert!(curl.contains("-F grid=@'dem-4326.tif'"), "{curl}");
    let levels = client.find(Locator::Css("#dataset tr[data-stat=levels] td:last-child")).await.unwrap();
    assert_eq!(levels.text().await.unwrap(), "0 to 14");
}

/// A client job opened by its address: the page says each batch waits for its caller, then
/// shows the mesh its caller's values made.
async fn client_job(app: &TestApp, client: &Client) {
    let body = json!({"source": "client", "max_vertices": 50, "batch": 8});
    let created: Value = app.post("/v1/jobs", &body).await.json().await.unwrap();
    let id = created["id"].as_str().unwrap().to_owned();
    client.goto(&app.url(&format!("/?job={id}"))).await.unwrap();
    let status = client.find(Locator::Id("status")).await.unwrap();
    let shown = tokio::time::timeout(PATIENCE, async {
        loop {
            let text = status.text().await.unwrap();
            if text.contains("waiting for the caller") {
                return text;
            }
            tokio::time::sleep(std::time::Duration::from_millis(50)).await;
        }
    })
    .await
    .expect("the page says the job waits for its caller");
    assert_eq!(shown, "waiting for the caller: batch 1, 4 points to tell");
    // Plays the caller: F = x·y + y.
    loop {
        let ask: Value =
            app.get(&format!("/v1/jobs/{id}/ask?wait=9000")).await.json().await.unwrap_or(Value::Null);
        if ask.is_null() {
            continue; // 204: the next batch is being chosen
        }
        if ask["status"] != "running" {
            break;
        }
        let values: Vec<Value> = (ask["points"].as_array().unwrap().iter())
            .map(|p| {
                let (x, y) = (p["x"].as_f64().unwrap(), p["y"].as_f64().unwrap());
                json!({"id": p["id"], "value": x * y + y})
            })
            .collect();
        assert_eq!(app.post(&format!("/v1/jobs/{id}/tell"), &json!({"values": values})).await.status(), 200);
    }
    wait_until(client, "body[data-state=done]").await;
    assert_eq!(page_stats(client).await["vertices"], json!(50));
    assert_eq!(page_job(client).await, id);
}

async fn boundary_value_problem(app: &TestApp, client: &Client) {
    let problem = crate::solutions::magnet();
    let address = reqwest::Url::parse_with_params(&app.url("/"), [("problem", problem.to_string())]).unwrap();
    client.goto(address.as_str()).await.unwrap();
    wait_until(client, "body[data-state=done]").await;
    let (ink, colours) = canvas_ink(client, "flat").await;
    assert!(ink > 100_000 && colours > 40, "solution: {ink} pixels, {colours} colours");
    let id = page_job(client).await;
    let status: Value = app.get(&format!("/v1/jobs/{id}")).await.json().await.unwrap();
    let shown = page_stats(client).await;
    for name in ["vertices", "unknowns", "solves", "estimate", "energy", "stop"] {
        assert_eq!(shown.get(name), Some(&status["stats"][name]), "{name} on the page");
    }
    // Each region's force, as the stats give it.
    for (i, region) in status["stats"]["regions"].as_array().unwrap().iter().enumerate() {
        assert_eq!(
            shown.get(&format!("force_{i}")),
            Some(&region["force"]),
            "region {i}'s force on the page"
        );
    }
    // A magnetostatic problem opens as a device, on |B|; u is a different picture.
    wait_until(client, "#tab-device[aria-selected=true]").await;
    wait_until(client, "#legend[data-label='|B| (T)']").await;
    let before = canvas_ink(client, "flat").await;
    client.execute("const s = document.getElementById('solve-colour'); s.value = 'u'; s.dispatchEvent(new Event('change'));", vec![]).await.unwrap();
    wait_until(client, "#legend[data-label='u']").await;
    assert_ne!(canvas_ink(client, "flat").await, before, "u repaints the picture");
    screenshot(client, "page-solution").await;
}

/// The problem in the page's editor, parsed.
async fn page_problem(client: &Client) -> Value {
    let text = client.execute("return document.getElementById('problem').value", vec![]).await.unwrap();
    serde_json::from_str(text.as_str().unwrap()).unwrap()
}

async fn device(app: &TestApp, client: &Client) {
    client.goto(&app.url("/")).await.unwrap();
    wait_until(client, "body[data-state=done]").await;
    client.find(Locator::Id("tab-device")).await.unwrap().click().await.unwrap();
    wait_until(client, "#legend[data-label='|B| (T)']").await;
    wait_until(client, "body[data-state=done]").await;
    // The example device, its circuit's inductance as the API gives it.
    let id = page_job(client).await;
    let status: Value = app.get(&format!("/v1/jobs/{id}")).await.json().await.unwrap();
    let coil = &status["stats"]["circuits"]["coil"];
    let shown = page_stats(client).await;
    assert_eq!(shown.get("circuit_coil"), Some(&json!([coil["inductance"], coil["incremental_inductance"]])));
    // One row a region, by name, its material chosen from the library.
    let library: Value = app.get("/v1/materials").await.json().await.unwrap();
    let names: Vec<&str> =
        library["materials"].as_array().unwrap().iter().map(|m| m["name"].as_str().unwrap()).collect();
    wait_until(client, "#device-regions option[value='N52']").await;
    let script = r#"
        return [...document.querySelectorAll('#device-regions tr')].map((tr) => {
            const [name, material, circuit] = tr.querySelectorAll('input, select');
            return [name.value, material.value, circuit.value, material.querySelectorAll('option').length];
        });
    "#;
    let rows = client.execute(script, vec![]).await.unwrap();
    let rows = rows.as_array().unwrap();
    let row = |i: usize, k: usize| rows[i][k].as_str().unwrap().to_owned();
    assert_eq!((0..4).map(|i| row(i, 0)).collect::<Vec<_>>(), ["core", "armature", "coil+", "coil-"]);
    assert_eq!((row(0, 1), row(0, 2), row(2, 2)), ("M400-50A".into(), "—".into(), "coil".into()));
    assert_eq!(rows[0][3].as_u64(), Some(names.len() as u64), "every library material is offered");
    // The steel's B–H table, plotted point by point.
    let steel = library["materials"].as_array().unwrap().iter().find(|m| m["name"] == "M400-50A").unwrap();
    let points = steel["bh"].as_array().unwrap().len().to_string();
    wait_until(client, &format!("#bh-plot[data-points='{points}']")).await;
    assert!(canvas_ink(client, "bh-plot").await.0 > 500, "the B–H plot is drawn");
    // Choosing a material, a circuit's current and a new circuit writes the request.
    let set = r#"
        const [selector, value] = arguments;
        const el = document.querySelector(selector);
        el.value = value;
        el.dispatchEvent(new Event('change'));
    "#;
    client
        .execute(
            set,
            vec![json!("#device-regions tr[data-region='1'] td:nth-child(2) select"), json!("M-19")],
        )
        .await
        .unwrap();
    client.execute(set, vec![json!("#device-circuits input"), json!("2.5")]).await.unwrap();
    client.find(Locator::Id("add-circuit")).await.unwrap().click().await.unwrap();
    client
        .execute(set, vec![json!("#device-regions tr[data-region='0'] td:nth-child(3) select"), json!("c1")])
        .await
        .unwrap();
    let problem = page_problem(client).await;
    assert_eq!(problem["regions"][1]["material"], "M-19", "{problem}");
    assert_eq!(problem["circuits"], json!({"coil": {"current": 2.5}, "c1": {"current": 1}}), "{problem}");
    assert_eq!(
        (
            &problem["regions"][0]["circuit"],
            &problem["regions"][0]["turns"],
            &problem["regions"][0]["direction"]
        ),
        (&json!("c1"), &json!(1), &json!(1)),
        "{problem}"
    );
    // The edited device solves.
    client.find(Locator::Id("solve-run")).await.unwrap().click().await.unwrap();
    wait_until(client, "body[data-state=done] #stats td[data-stat=circuit_c1]").await;
    screenshot(client, "page-device").await;
}

const KEY: &str = "page-key-0123456789abcdef";

async fn api_key(app: &TestApp, client: &Client) {
    // Without a key the first visit's job is refused, and the key field opens.
    client.goto(&app.url("/?function=x*y&max_vertices=300")).await.unwrap();
    wait_until(client, "body[data-state=failed] #key-settings[open]").await;
    let text = client.find(Locator::Id("general-error")).await.unwrap().text().await.unwrap();
    assert!(!text.is_empty(), "the 401 is shown");
    let field = client.find(Locator::Id("api-key")).await.unwrap();
    field.send_keys(KEY).await.unwrap();
    client
        .execute("document.getElementById('api-key').dispatchEvent(new Event('change'))", vec![])
        .await
        .unwrap();
    client.find(Locator::Id("run")).await.unwrap().click().await.unwrap();
    wait_until(client, "body[data-state=done]").await;
    // The page's job exists on the server, which only a keyed request could have made.
    let id = page_job(client).await;
    let status = app.client.get(app.url(&format!("/v1/jobs/{id}"))).bearer_auth(KEY).send().await.unwrap();
    let status: Value = status.json().await.unwrap();
    assert_eq!(status["stats"]["vertices"], 300);
    let (ink, _) = canvas_ink(client, "flat").await;
    assert!(ink > 100_000, "drawn with the key: {ink} pixels");
    // The key stays in this browser only; the test leaves none behind.
    client.execute("localStorage.clear()", vec![]).await.unwrap();
}
