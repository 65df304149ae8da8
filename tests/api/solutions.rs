//! Boundary value problems through the API: synchronous, streamed and as background jobs,
//! with the same ids, caching and problem documents as meshes.

use crate::helpers::{read_events, spawn_app};
use serde_json::{Value, json};

/// −Δu = 2π² sin(πx) sin(πy) on the unit square, u = 0 on its boundary.
fn smooth(max_vertices: u64) -> Value {
    json!({
        "f": "2*pi^2*sin(pi*x)*sin(pi*y)",
        "exact": "sin(pi*x)*sin(pi*y)",
        "max_vertices": max_vertices,
    })
}

/// A conductor beside an iron block in a box: the README's example.
pub fn magnet() -> Value {
    json!({
        "domain": {"x": [0, 0.2], "y": [0, 0.1]},
        "physics": "magnetostatic",
        "regions": [
            {"x": [0.04, 0.07], "y": [0.035, 0.065], "current_density": 2e6},
            {"x": [0.11, 0.16], "y": [0.02, 0.08], "mu_r": 1000}
        ],
        "max_vertices": 3000
    })
}

#[tokio::test]
async fn a_solution_carries_u_at_every_vertex_and_a_history_of_every_solve() {
    let app = spawn_app().await;
    let response = app.post("/v1/solutions", &smooth(3000)).await;
    assert_eq!(response.status(), 200);
    assert_eq!(response.headers()["x-cache"], "miss");
    let body = response.bytes().await.unwrap();
    let doc: Value = serde_json::from_slice(&body).unwrap();
    let stats = &doc["stats"];
    assert_eq!((stats["physics"].as_str(), stats["stop"].as_str()), (Some("poisson"), Some("max_vertices")));
    let vertices = doc["vertices"].as_array().unwrap();
    assert_eq!(vertices.len(), 3000);
    assert_eq!(stats["triangles"].as_u64().unwrap() as usize, doc["triangles"].as_array().unwrap().len());
    // z is u_h: within the reported nodal error of the exact solution at every vertex.
    let history = stats["history"].as_array().unwrap();
    assert_eq!(history.len() as u64, stats["solves"].as_u64().unwrap());
    let last = history.last().unwrap();
    let nodal = last["max_nodal_error"].as_f64().unwrap();
    for v in vertices {
        let [x, y, z] = [0, 1, 2].map(|i| v[i].as_f64().unwrap());
        let u = (std::f64::consts::PI * x).sin() * (std::f64::consts::PI * y).sin();
        assert!((u - z).abs() <= nodal, "({x}, {y}): u_h = {z}, u = {u}, bound {nodal}");
    }
    let errors: Vec<f64> = history.iter().map(|s| s["energy_error"].as_f64().unwrap()).collect();
    assert!(errors.windows(2).all(|w| w[1] < w[0]), "the energy error falls solve by solve: {errors:?}");
    assert_eq!(stats["estimate"], last["estimate"]);

    let again = app.post("/v1/solutions", &smooth(3000)).await;
    assert_eq!(again.headers()["x-cache"], "hit");
    assert_eq!(again.bytes().await.unwrap(), body, "a cached solution is the same bytes");
    app.shutdown().await;
}

/// The events of `body` posted to /v1/solutions as a stream.
async fn stream(app: &crate::helpers::TestApp, body: &Value) -> Vec<crate::helpers::SseEvent> {
    let request = app.client.post(app.url("/v1/solutions?inline=mesh")).header("accept", "text/event-stream");
    read_events(request.json(body).send().await.unwrap()).await
}

#[tokio::test]
async fn the_stream_reports_solves_and_ends_with_the_solution() {
    let app = spawn_app().await;
    let events = stream(&app, &json!({"f": "1", "max_vertices": 60_000})).await;
    let (last, progress) = events.split_last().unwrap();
    assert_eq!(last.event, "result");
    let doc: Value = serde_json::from_str(&last.data).unwrap();
    let solved: Vec<u64> =
        doc["stats"]["history"].as_array().unwrap().iter().map(|s| s["vertices"].as_u64().unwrap()).collect();
    assert!(!progress.is_empty());
    // Each progress event is one solve's: its vertex count and estimate are a history entry's.
    for event in progress {
        let p: Value = serde_json::from_str(&event.data).unwrap();
        let n = p["vertices"].as_u64().unwrap();
        let step = doc["stats"]["history"].as_array().unwrap().iter().find(|s| s["vertices"] == n);
        let step = step.unwrap_or_else(|| panic!("{n} vertices is not a solve of {solved:?}"));
        assert_eq!(step["estimate"], p["worst"]);
    }
    app.shutdown().await;
}

#[tokio::test]
async fn a_job_that_names_physics_is_a_solution_with_its_flux_density_in_every_form() {
    let app = spawn_app().await;
    let created = app.post("/v1/jobs", &magnet()).await;
    assert_eq!(created.status(), 202);
    let id = created.json::<Value>().await.unwrap()["id"].as_str().unwrap().to_owned();
    let status = app.wait_finished(&id).await;
    assert_eq!(status["status"], "succeeded", "{status}");
    assert_eq!(status["stats"]["physics"], "magnetostatic");
    assert_eq!(status["stats"]["delaunay"], true);

    let doc: Value = app.get(&format!("/v1/jobs/{id}/mesh")).await.json().await.unwrap();
    let flux = doc["flux_density"].as_array().unwrap();
    assert_eq!(flux.len(), doc["triangles"].as_array().unwrap().len());
    // The same request on the synchronous route is the same job, answered from the cache.
    let sync = app.post("/v1/solutions", &magnet()).await;
    assert_eq!(sync.headers()["x-cache"], "hit");
    assert_eq!(sync.json::<Value>().await.unwrap()["id"], id.as_str());

    let vtu = app.get(&format!("/v1/jobs/{id}/mesh?format=vtu")).await.text().await.unwrap();
    assert!(vtu.contains("Name=\"B\" NumberOfComponents=\"3\""), "VTU carries B");
    assert!(
        vtu.contains("Name=\"H\" NumberOfComponents=\"3\"") && vtu.contains("Name=\"mu_r\""),
        "VTU carries H, μr"
    );
    let msh = app.get(&format!("/v1/jobs/{id}/mesh?format=msh")).await.text().await.unwrap();
    assert!(msh.contains("$ElementData\n1\n\"B\"\n1\n0\n3\n0\n3\n"), "MSH carries B");
    assert!(msh.contains("$ElementData\n1\n\"H\"\n1\n0\n3\n0\n3\n"), "MSH carries H");
    // μr per element: the iron block's 1000 and the air's (and the conductor's) 1.
    let view = &msh[msh.find("\"mu_r\"").unwrap()..];
    let rows = view.lines().skip(7).take_while(|l| !l.starts_with('$'));
    let mut mu: Vec<f64> = rows.map(|l| l.split(' ').nth(1).unwrap().parse().unwrap()).collect();
    mu.sort_by(f64::total_cmp);
    mu.dedup_by(|a, b| (*a - *b).abs() < 1e-9 * b.abs());
    assert_eq!(mu.len(), 2, "{mu:?}");
    assert!((mu[0] - 1.0).abs() < 1e-12 && (mu[1] - 1000.0).abs() < 1e-9, "{mu:?}");
    app.shutdown().await;
}

/// The problem document of a request that must fail with 422.
pub(crate) async fn refused(app: &crate::helpers::TestApp, body: Value) -> Value {
    let response = app.post("/v1/solutions", &body).await;
    assert_eq!(response.status(), 422, "{body}");
    response.json().await.unwrap()
}

/// A change to a good request, the field its 422 must name and what its detail must say.
pub(crate) type Mistake = (fn(&mut Value), &'static str, &'static str);

/// Each mistake made to `base()` is refused naming its field and saying what it should.
pub(crate) async fn each_refused(app: &crate::helpers::TestApp, base: fn() -> Value, mistakes: &[Mistake]) {
    for (change, field, says) in mistakes {
        let mut body = base();
        change(&mut body);
        let p = refused(app, body).await;
        assert_eq!(p["field"], *field, "{p}");
        assert!(p["detail"].as_str().unwrap().contains(says), "{p}");
    }
}

#[tokio::test]
async fn bad_problems_are_422_naming_the_field_and_the_column_or_point() {
    let app = spawn_app().await;
    let p = refused(&app, json!({"f": "sin(x) + * y"})).await;
    assert_eq!(
        (p["type"].as_str().unwrap().rsplit('/').next(), p["field"].as_str()),
        (Some("invalid-expression"), Some("/f"))
    );
    assert_eq!(p["column"], 10);

    let p = refused(&app, json!({"physics": "magnetostatic", "k": 2})).await;
    assert_eq!(p["field"], "/k", "{p}");
    let p = refused(&app, json!({"regions": [{"x": [0.5, 1.5], "y": [0, 1], "k": 2}]})).await;
    assert_eq!(p["field"], "/regions/0", "{p}");
    let p = refused(&app, json!({"regions": [{"x": [0, 1], "y": [0, 1], "mu_r": 2}]})).await;
    assert_eq!(p["field"], "/regions/0", "{p}");
    let p = refused(
        &app,
        json!({"physics": "magnetostatic", "regions": [{"x": [0, 1], "y": [0, 1], "mu_r": 0}]}),
    )
    .await;
    assert_eq!(p["field"], "/regions/0/mu_r", "{p}");
    let p = refused(&app, json!({"k": -1})).await;
    assert_eq!(p["field"], "/k", "{p}");
    let p = refused(&app, json!({"growth": 1})).await;
    assert_eq!(p["field"], "/growth", "{p}");
    let p = refused(&app, json!({"method": "data-dependent"})).await;
    assert_eq!(p["field"], "/method", "{p}");

    // k is an expression that turns negative: found where the solver samples it.
    let p = refused(&app, json!({"k": "x - 0.5", "f": 1, "max_vertices": 100})).await;
    assert_eq!(
        (p["field"].as_str(), p["type"].as_str().unwrap().rsplit('/').next()),
        (Some("/k"), Some("invalid-problem"))
    );
    let x = p["point"][0].as_f64().unwrap();
    assert!(x <= 0.5, "k(x, y) = x − 0.5 ≤ 0 at x = {x}");
    app.shutdown().await;
}

/// The issue's device: a triangular coil, a steel block with a B–H curve and a magnet, in a
/// box with Neumann top and bottom.
fn device(max_vertices: u64) -> Value {
    json!({
        "physics": "magnetostatic",
        "domain": {"x": [0, 0.2], "y": [0, 0.1]},
        "boundary": {"left": "dirichlet", "right": "dirichlet", "bottom": "neumann", "top": "neumann"},
        "regions": [
            {"polygon": [[0.03, 0.03], [0.07, 0.03], [0.05, 0.07]], "current_density": 2e6},
            {"x": [0.11, 0.16], "y": [0.02, 0.08], "bh": [[0, 0], [100, 0.6], [300, 1.1], [1000, 1.45], [10000, 1.8]]},
            {"x": [0.17, 0.19], "y": [0.03, 0.07], "magnetization": [0, 8.8e5], "mu_r": 1.05}
        ],
        "max_vertices": max_vertices
    })
}

#[tokio::test]
async fn a_device_with_a_polygon_coil_nonlinear_iron_a_magnet_and_neumann_sides_is_solved() {
    let app = spawn_app().await;
    let response = app.post("/v1/solutions", &device(4000)).await;
    assert_eq!(response.status(), 200);
    let doc: Value = response.json().await.unwrap();
    let stats = &doc["stats"];
    assert_eq!((stats["stop"].as_str(), stats["delaunay"].as_bool()), (Some("max_vertices"), Some(true)));
    assert!(stats["constrained_edges"].as_u64().unwrap() > 12, "{stats}");
    for step in stats["history"].as_array().unwrap() {
        assert!(step["newton_iterations"].as_u64().unwrap() >= 1, "{step}");
        assert!(step["newton_residual"].as_f64().unwrap() <= 1e-10, "{step}");
    }
    let regions = stats["regions"].as_array().unwrap();
    assert_eq!(regions.len(), 3);
    // The coil: a triangle of 0.04 × 0.04 / 2 at 2 MA/m².
    let coil = &regions[0];
    assert!((coil["area"].as_f64().unwrap() - 8e-4).abs() < 1e-15);
    assert!((coil["current"].as_f64().unwrap() - 1600.0).abs() < 1e-9);
    assert!(regions.iter().all(|r| r["force"].as_array().unwrap().len() == 2 && r["torque"].is_f64()));
    // Iron attracts both the coil on its left and the magnet on its right.
    let fx = |i: usize| regions[i]["force"][0].as_f64().unwrap();
    assert!(fx(0) > 0.0 && fx(2) < 0.0, "coil {} magnet {}", fx(0), fx(2));
    assert!(stats["coenergy"].is_f64() && stats["energy"].as_f64().unwrap() > 0.0, "{stats}");
    // A = 0 on the Dirichlet sides; free on the Neumann ones.
    let vertices = doc["vertices"].as_array().unwrap();
    let values = |test: fn(f64, f64) -> bool| -> Vec<f64> {
        let xyz = vertices.iter().map(|v| [0, 1, 2].map(|i| v[i].as_f64().unwrap()));
        xyz.filter(|&[x, y, _]| test(x, y)).map(|[_, _, a]| a).collect()
    };
    assert!(values(|x, _| x == 0.0 || x == 0.2).iter().all(|&a| a == 0.0));
    let bottom = values(|x, y| y == 0.0 && x > 0.0 && x < 0.2);
    assert!(bottom.iter().any(|a| a.abs() > 1e-6), "A is held at 0 on a Neumann side");
    app.shutdown().await;
}

#[tokio::test]
async fn a_nonlinear_solution_streams_progress_with_newtons_steps() {
    let app = spawn_app().await;
    let events = stream(&app, &device(3000)).await;
    let (last, progress) = events.split_last().unwrap();
    assert_eq!(last.event, "result");
    assert!(!progress.is_empty());
    for event in progress {
        let p: Value = serde_json::from_str(&event.data).unwrap();
        assert!(
            p["newton_iterations"].as_u64().unwrap() >= 1 && p["newton_residual"].as_f64().unwrap() <= 1e-10,
            "{p}"
        );
    }
    app.shutdown().await;
}

#[tokio::test]
async fn bad_materials_shapes_and_sides_are_422_naming_the_entry() {
    let app = spawn_app().await;
    let mut body = device(100);
    body["regions"][1]["bh"] = json!([[0, 0], [100, 0.6], [90, 1.1]]);
    let p = refused(&app, body).await;
    assert_eq!(p["field"], "/regions/1/bh/2", "{p}");
    assert!(p["detail"].as_str().unwrap().contains("increase"), "{p}");

    let mut body = device(100);
    body["regions"][0]["polygon"] = json!([[0.03, 0.03], [0.07, 0.07], [0.07, 0.03], [0.03, 0.07]]);
    let p = refused(&app, body).await;
    assert_eq!(p["field"], "/regions/0/polygon/2", "a bow tie's first side crosses its third: {p}");

    let mut body = device(100);
    body["regions"][0]["polygon"] = json!([[0.03, 0.03], [0.3, 0.03], [0.05, 0.07]]);
    assert_eq!(refused(&app, body).await["field"], "/regions/0/polygon/1");

    let mut body = device(100);
    body["regions"][1]["mu_r"] = json!(1000);
    assert_eq!(refused(&app, body).await["field"], "/regions/1/bh");

    let mut body = device(100);
    body["boundary"] = json!({"left": "neumann", "right": "neumann", "bottom": "neumann", "top": "neumann"});
    assert_eq!(refused(&app, body).await["field"], "/boundary");

    let mut body = device(100);
    body["boundary"] = json!({"left": "periodic", "right": "antiperiodic"});
    let p = refused(&app, body).await;
    assert_eq!(p["field"], "/boundary", "{p}");
    assert!(p["detail"].as_str().unwrap().contains("left and right"), "{p}");

    let mut body = device(100);
    body["regions"] = json!(vec![json!({"x": [0.01, 0.02], "y": [0.01, 0.02], "mu_r": 2}); 101]);
    let p = refused(&app, body).await;
    assert_eq!(p["field"], "/regions", "{p}");

    // The outlines alone are more vertices than the budget.
    let p = refused(&app, device(8)).await;
    assert_eq!(p["field"], "/regions", "{p}");
    assert!(p["detail"].as_str().unwrap().contains("vertex budget"), "{p}");

    let mut body = device(100);
    body["regions"][2]["mu_r"] = json!(1e-10);
    body["regions"][2]["magnetization"] = json!([1e300, 0]);
    assert_eq!(refused(&app, body).await["field"], "/regions/2/magnetization/0");

    let mut body = device(100);
    body["boundary"]["left"] = json!("robin");
    let p = refused(&app, body).await;
    assert_eq!(p["field"], "/boundary/left", "{p}");
    app.shutdown().await;
}

/// The issue's device, as an engineer writes it: lengths in mm, 40 mm deep, a steel of their
/// own and one from the library, a coil of two named sides on one circuit.
fn engineered(max_vertices: u64) -> Value {
    json!({
        "physics": "magnetostatic", "unit": "mm", "depth": 40,
        "domain": {"x": [-60, 60], "y": [-60, 60]},
        "materials": {"my-steel": {"bh": [[0, 0], [100, 0.5], [1000, 1.3]]}},
        "circuits": {"main": {"current": 2.5}},
        "regions": [
            {"name": "core", "material": "M400-50A", "polygon": [[-20, -20], [20, -20], [20, 20], [-20, 20]]},
            {"name": "keeper", "material": "my-steel", "x": [-20, 20], "y": [24, 30]},
            {"name": "coil+", "material": "copper", "turns": 200, "circuit": "main", "direction": 1,
             "x": [22, 30], "y": [-10, 10]},
            {"name": "coil-", "material": "copper", "turns": 200, "circuit": "main", "direction": -1,
             "x": [-30, -22], "y": [-10, 10]}
        ],
        "max_vertices": max_vertices
    })
}

#[tokio::test]
async fn the_material_library_lists_every_law_with_its_source() {
    let app = spawn_app().await;
    let response = app.get("/v1/materials").await;
    assert_eq!(response.status(), 200);
    assert!(response.headers()["cache-control"].to_str().unwrap().contains("max-age"));
    let doc: Value = response.json().await.unwrap();
    let materials = doc["materials"].as_array().unwrap();
    let by_name =
        |name: &str| materials.iter().find(|m| m["name"] == name).unwrap_or_else(|| panic!("{name}"));
    assert_eq!(by_name("M400-50A")["bh"].as_array().unwrap().len(), 44);
    assert_eq!(by_name("M400-50A")["kind"], "steel");
    assert!(by_name("N52")["br"].as_f64().unwrap() > 1.3);
    assert_eq!(by_name("copper")["mu_r"], 1.0);
    assert!(materials.iter().all(|m| !m["source"].as_str().unwrap().is_empty()), "{doc}");
    app.shutdown().await;
}

#[tokio::test]
async fn a_device_in_mm_with_a_depth_answers_in_its_units_with_named_regions_and_its_circuit() {
    let app = spawn_app().await;
    let response = app.post("/v1/solutions", &engineered(3000)).await;
    assert_eq!(response.status(), 200);
    let doc: Value = response.json().await.unwrap();
    let stats = &doc["stats"];
    assert_eq!((stats["unit"].as_str(), stats["depth"].as_f64()), (Some("mm"), Some(40.0)), "{stats}");
    // Vertices in mm: the domain's corners are there as the request wrote them.
    let xy: Vec<[f64; 2]> = (doc["vertices"].as_array().unwrap().iter())
        .map(|v| [v[0].as_f64().unwrap(), v[1].as_f64().unwrap()])
        .collect();
    for corner in [[-60.0, -60.0], [60.0, -60.0], [60.0, 60.0], [-60.0, 60.0]] {
        assert!(xy.contains(&corner), "no corner {corner:?}");
    }
    assert!(xy.iter().all(|&[x, y]| x.abs() <= 60.0 && y.abs() <= 60.0));
    let regions = stats["regions"].as_array().unwrap();
    let names: Vec<&str> = regions.iter().map(|r| r["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["core", "keeper", "coil+", "coil-"]);
    // Areas in mm², currents in ampere-turns.
    assert!((regions[0]["area"].as_f64().unwrap() - 1600.0).abs() < 1e-9, "{}", regions[0]);
    assert!((regions[2]["current"].as_f64().unwrap() - 500.0).abs() < 1e-9, "{}", regions[2]);
    assert!((regions[3]["current"].as_f64().unwrap() + 500.0).abs() < 1e-9, "{}", regions[3]);
    // λ is the turns times the sides' mean A, times the depth in metres.
    let circuit = &stats["circuits"]["main"];
    let mean = |i: usize| regions[i]["mean_a"].as_f64().unwrap();
    let flux_linkage = 0.04 * 200.0 * (mean(2) - mean(3));
    assert!(
        (circuit["flux_linkage"].as_f64().unwrap() - flux_linkage).abs() < 1e-9 * flux_linkage,
        "{circuit}"
    );
    let inductance = circuit["inductance"].as_f64().unwrap();
    assert!((inductance - flux_linkage / 2.5).abs() < 1e-9 * inductance, "{circuit}");
    assert!(circuit["incremental_inductance"].as_f64().unwrap() > 0.0, "{circuit}");

    // The same device in metres, per metre of depth: the same mesh and solution, and every
    // total is the per-metre figure times the depth.
    let mut metres = engineered(3000);
    fn m(v: &Value) -> Value {
        match v {
            Value::Number(n) => json!(n.as_f64().unwrap() / 1000.0),
            Value::Array(items) => Value::Array(items.iter().map(m).collect()),
            other => other.clone(),
        }
    }
    metres["domain"] = json!({"x": m(&metres["domain"]["x"]), "y": m(&metres["domain"]["y"])});
    for region in metres["regions"].as_array_mut().unwrap() {
        for field in ["x", "y", "polygon"] {
            if region.get(field).is_some() {
                region[field] = m(&region[field]);
            }
        }
    }
    let object = metres.as_object_mut().unwrap();
    object.remove("unit");
    object.remove("depth");
    let per_metre: Value = app.post("/v1/solutions", &metres).await.json().await.unwrap();
    let per = &per_metre["stats"];
    assert!(per.get("unit").is_none() && per.get("depth").is_none(), "{per}");
    assert_eq!(per["regions"][2]["mean_a"], regions[2]["mean_a"], "the same solution");
    let force = |s: &Value, i: usize| s["regions"][i]["force"][0].as_f64().unwrap();
    assert!((force(stats, 1) - 0.04 * force(per, 1)).abs() < 1e-12 * force(per, 1).abs());
    let energy = |s: &Value| s["energy"].as_f64().unwrap();
    assert!((energy(stats) - 0.04 * energy(per)).abs() < 1e-12 * energy(per));
    let l = per["circuits"]["main"]["inductance"].as_f64().unwrap();
    assert!((inductance - 0.04 * l).abs() < 1e-12 * l, "{inductance} against {l} H/m");
    app.shutdown().await;
}

#[tokio::test]
async fn a_device_with_unknown_names_or_loose_coils_is_422_naming_the_field() {
    let app = spawn_app().await;
    let mistakes: [Mistake; 9] = [
        (|b| b["regions"][0]["material"] = json!("unobtainium"), "/regions/0/material", "unobtainium"),
        (|b| b["regions"][2]["circuit"] = json!("spare"), "/regions/2/circuit", "main"),
        (
            |b| {
                b["regions"][2].as_object_mut().unwrap().remove("circuit");
            },
            "/regions/2/circuit",
            "needs a circuit",
        ),
        (|b| b["regions"][3]["direction"] = json!(2), "/regions/3/direction", "1 or -1"),
        (|b| b["circuits"]["spare"] = json!({"current": 1}), "/circuits/spare", "no region"),
        (|b| b["materials"]["my-steel"]["bh"][2] = json!([90, 1.3]), "/materials/my-steel/bh/2", "increas"),
        (|b| b["regions"][0]["mu_r"] = json!(1000), "/regions/0/material", "not both"),
        (|b| b["regions"][1]["angle"] = json!(90), "/regions/1/angle", "not a magnet"),
        (|b| b["materials"]["a.b"] = json!({"mu_r": 2}), "/materials", "without"),
    ];
    each_refused(&app, || engineered(100), &mistakes).await;
    // Units and devices are magnetostatics'.
    let p = refused(&app, json!({"f": 1, "unit": "mm"})).await;
    assert_eq!(p["field"], "/unit", "{p}");
    app.shutdown().await;
}

/// The round actuator of examples/requests: a plunger in a pot core, turned about its axis,
/// in a small open box.
fn actuator() -> Value {
    let text =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/examples/requests/actuator.json"));
    let mut body: Value = serde_json::from_str(&text.unwrap()).unwrap();
    body["max_vertices"] = json!(4000);
    body
}

#[tokio::test]
async fn a_round_actuator_in_an_open_box_answers_its_axial_force_and_inductance_for_the_whole_turn() {
    let app = spawn_app().await;
    let response = app.post("/v1/solutions", &actuator()).await;
    assert_eq!(response.status(), 200);
    let doc: Value = response.json().await.unwrap();
    let stats = &doc["stats"];
    assert_eq!(
        (stats["geometry"].as_str(), stats["unit"].as_str()),
        (Some("axisymmetric"), Some("mm")),
        "{stats}"
    );
    // A_φ = 0 on the axis, and nowhere is r negative.
    let vertices = doc["vertices"].as_array().unwrap();
    let xyz = |v: &Value| [0, 1, 2].map(|i| v[i].as_f64().unwrap());
    assert!(vertices.iter().map(xyz).all(|[r, _, a]| r >= 0.0 && (r > 0.0 || a == 0.0)));
    // The plunger is pulled down into the pot, axially; the forces on everything balance.
    let regions = stats["regions"].as_array().unwrap();
    let force = |i: usize| [0, 1].map(|k| regions[i]["force"][k].as_f64().unwrap());
    assert_eq!(regions[1]["name"], "plunger");
    let [fr, fz] = force(1);
    assert!(fr == 0.0 && fz < -0.5, "{:?}", force(1));
    let sum: f64 = (0..3).map(|i| force(i)[1]).sum();
    assert!(sum.abs() < 0.05 * fz.abs(), "forces sum to {sum}");
    // The whole turn's energy and inductance: L = 2W/I² (nearly linear iron at 1 A), in mH.
    let coil = &stats["circuits"]["coil"];
    let inductance = coil["inductance"].as_f64().unwrap();
    let energy = stats["energy"].as_f64().unwrap();
    assert!((inductance - 2.0 * energy).abs() < 1e-2 * inductance, "{coil} against W = {energy}");
    assert!((0.015..0.03).contains(&inductance), "{coil}");
    app.shutdown().await;
}

#[tokio::test]
async fn axisymmetric_and_open_mistakes_are_422_naming_the_field() {
    let app = spawn_app().await;
    let mistakes: [Mistake; 7] = [
        (|b| b["domain"]["x"] = json!([-60, 60]), "/domain/x", "axis"),
        (
            |b| {
                b["domain"]["x"] = json!([-60, 60]);
                b["regions"][2]["x"] = json!([-8, 20]);
            },
            "/regions/2",
            "axis",
        ),
        (|b| b["depth"] = json!(10), "/depth", "whole turn"),
        (|b| b["regions"][1]["torque_about"] = json!([0, 0]), "/regions/1/torque_about", "axial"),
        (|b| b["boundary"] = json!({"left": "open", "right": "open"}), "/boundary/left", "axis"),
        (|b| b["regions"][0]["polygon"][1] = json!([60, -20]), "/boundary/right", "regions[0]"),
        (|b| b["boundary"] = json!("robin"), "/boundary", "unknown variant"),
    ];
    each_refused(&app, actuator, &mistakes).await;
    let p = refused(&app, json!({"f": 1, "boundary": "open"})).await;
    assert_eq!(p["field"], "/boundary/left", "{p}");
    app.shutdown().await;
}

#[tokio::test]
async fn a_solution_answers_b_and_h_at_points_and_a_polylines_flux_and_ampere_turns() {
    let app = spawn_app().await;
    let response = app.post("/v1/jobs", &engineered(6000)).await;
    let id = response.json::<Value>().await.unwrap()["id"].as_str().unwrap().to_owned();
    assert_eq!(app.wait_finished(&id).await["status"], "succeeded");
    let evaluate = |body: Value| {
        let app = &app;
        let id = id.clone();
        async move { app.post(&format!("/v1/jobs/{id}/evaluate"), &body).await }
    };
    // B and H at points (mm), null outside; in air H = B/μ0.
    let doc: Value = evaluate(json!({"points": [[40, 0], [26, 0], [100, 0]]})).await.json().await.unwrap();
    let b = &doc["flux_density"];
    let h = &doc["field_strength"];
    assert!(b[2].is_null() && h[2].is_null() && doc["values"][2].is_null(), "{doc}");
    let mu0 = 1.25663706212e-6;
    for k in 0..2 {
        let (bx, hx) = (b[0][k].as_f64().unwrap(), h[0][k].as_f64().unwrap());
        assert!((bx - mu0 * hx).abs() <= 1e-9 * bx.abs().max(1e-12), "B {bx} against μ0 H {}", mu0 * hx);
    }
    // Flux through a polyline: the change of A along it, times the depth (40 mm).
    let doc: Value = evaluate(json!({"points": [[-45, 0], [45, 0]]})).await.json().await.unwrap();
    let a = [0, 1].map(|i| doc["values"][i].as_f64().unwrap());
    let line: Value = evaluate(json!({"polyline": [[-45, 0], [0, 30], [45, 0]]})).await.json().await.unwrap();
    let flux = line["flux"].as_f64().unwrap();
    assert!((flux - 0.04 * (a[1] - a[0])).abs() <= 1e-12 * flux.abs().max(1e-15), "{line}");
    assert_eq!(line["closed"], false);
    // Ampère: around coil+ the line integral of H is its 200 turns × 2.5 A; around both
    // sides, or around nothing, it is 0.
    let around =
        |x0: f64, x1: f64| json!({"polyline": [[x0, -14], [x1, -14], [x1, 14], [x0, 14], [x0, -14]]});
    let mmf = |line: Value| line["mmf"].as_f64().unwrap();
    let coil: Value = evaluate(around(20.0, 33.0)).await.json().await.unwrap();
    assert_eq!(coil["closed"], true);
    assert!((mmf(coil.clone()) - 500.0).abs() < 0.03 * 500.0, "{coil}");
    let both: Value = evaluate(json!({"polyline": [[-35, -45], [35, -45], [35, 45], [-35, 45], [-35, -45]]}))
        .await
        .json()
        .await
        .unwrap();
    assert!(mmf(both.clone()).abs() < 0.03 * 500.0, "{both}");
    // Mistakes name the field.
    for (body, field) in [
        (json!({"polyline": [[0, 0]]}), "/polyline"),
        (json!({"polyline": [[0, 0], [100, 0]]}), "/polyline/1"),
        (json!({"points": [[0, 0]], "polyline": [[0, 0], [1, 1]]}), "/points"),
    ] {
        let response = evaluate(body.clone()).await;
        assert_eq!(response.status(), 422, "{body}");
        let p: Value = response.json().await.unwrap();
        assert_eq!(p["field"], field, "{p}");
    }
    app.shutdown().await;
}
