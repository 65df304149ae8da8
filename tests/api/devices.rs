//! Round parts drawn with arcs, checked against exact answers through the API.

use crate::helpers::spawn_app;
use crate::solutions::{Mistake, each_refused, refused};
use serde_json::{Value, json};

const MU_0: f64 = 1.25663706212e-6;

/// A coaxial line in mm: a copper core of radius 1 inside a return conductor from 3 to 4,
/// drawn with arcs of 2° segments, 10 A on one circuit. The return conductor is two half
/// rings side by side, each half a turn: the current divides between them.
fn coax(max_vertices: u64) -> Value {
    let arc = |degrees: i32| json!({"arc": degrees, "max_segment_angle": 2});
    json!({
        "physics": "magnetostatic", "unit": "mm",
        "domain": {"x": [-8, 8], "y": [-8, 8]},
        "circuits": {"line": {"current": 10}},
        "regions": [
            {"name": "core", "material": "copper", "circuit": "line",
             "polygon": [[1, 0], arc(180), [-1, 0], arc(180)]},
            {"name": "upper return", "material": "copper", "circuit": "line", "direction": -1, "turns": 0.5,
             "polygon": [[3, 0], [4, 0], arc(180), [-4, 0], [-3, 0], arc(-180)]},
            {"name": "lower return", "material": "copper", "circuit": "line", "direction": -1, "turns": 0.5,
             "polygon": [[-3, 0], [-4, 0], arc(180), [4, 0], [3, 0], arc(-180)]}
        ],
        "max_vertices": max_vertices
    })
}

/// A coaxial line's inductance per metre at direct current: the gap's μ0/2π ln(b/a), the
/// core's μ0/8π and the return conductor's own share (radii a < b < c).
fn coax_inductance(a: f64, b: f64, c: f64) -> f64 {
    let (b2, c2) = (b * b, c * c);
    let outer = c2 * c2 / (c2 - b2).powi(2) * (c / b).ln() - (3.0 * c2 - b2) / (4.0 * (c2 - b2));
    MU_0 / (2.0 * std::f64::consts::PI) * ((b / a).ln() + 0.25 + outer)
}

#[tokio::test]
async fn a_coaxial_line_drawn_with_arcs_has_the_inductance_of_its_formula() {
    let app = spawn_app().await;
    let response = app.post("/v1/solutions", &coax(10_000)).await;
    assert_eq!(response.status(), 200);
    let doc: Value = response.json().await.unwrap();
    let stats = &doc["stats"];
    // Each half circle is 90 segments of 2°: the core is a 180-gon.
    let area = |i: usize| stats["regions"][i]["area"].as_f64().unwrap();
    let gon = |r: f64| 90.0 * r * r * (2f64).to_radians().sin();
    assert!((area(0) - gon(1.0)).abs() < 1e-12, "{} against {}", area(0), gon(1.0));
    assert!((area(1) - (gon(4.0) - gon(3.0)) / 2.0).abs() < 1e-12, "{}", area(1));
    assert!((area(1) - area(2)).abs() < 1e-12, "mirror images: {} and {}", area(1), area(2));
    // Every arc point is a vertex, on its circle.
    let on = |r: f64| {
        (doc["vertices"].as_array().unwrap().iter())
            .filter(|v| (v[0].as_f64().unwrap().hypot(v[1].as_f64().unwrap()) - r).abs() < 1e-12)
            .count()
    };
    assert_eq!([on(1.0), on(3.0), on(4.0)], [180, 180, 180]);
    let line = &stats["circuits"]["line"];
    let inductance = line["inductance"].as_f64().unwrap();
    let exact = coax_inductance(1.0, 3.0, 4.0);
    assert!((inductance - exact).abs() < 2e-3 * exact, "{line} against {exact} H/m");
    // Linear: the incremental inductance is the apparent one.
    let incremental = line["incremental_inductance"].as_f64().unwrap();
    assert!((incremental - inductance).abs() < 1e-6 * inductance, "{line}");
    app.shutdown().await;
}

#[tokio::test]
async fn arc_mistakes_are_422_naming_the_entry() {
    let app = spawn_app().await;
    let mistakes: [Mistake; 9] = [
        (|b| b["regions"][0]["polygon"][1] = json!({"arc": 0}), "/regions/0/polygon/1/arc", "not 0"),
        (|b| b["regions"][0]["polygon"][1] = json!({"arc": -360}), "/regions/0/polygon/1/arc", "(-360, 360)"),
        (
            |b| b["regions"][0]["polygon"][1] = json!({"arc": 180, "max_segment_angle": 0}),
            "/regions/0/polygon/1/max_segment_angle",
            "(0, 90]",
        ),
        (
            |b| b["regions"][0]["polygon"][1] = json!({"arc": 180, "max_segment_angle": 0.1}),
            "/regions/0/polygon/1/max_segment_angle",
            "1800 segments",
        ),
        (
            |b| b["regions"][0]["polygon"][0] = json!({"arc": 90}),
            "/regions/0/polygon/0",
            "between two corners",
        ),
        // Both halves bend the same way: the second arc runs over the first.
        (|b| b["regions"][0]["polygon"][3] = json!({"arc": -180}), "/regions/0/polygon/3", "simple"),
        // Nearly a whole turn about a far centre leaves the domain.
        (
            |b| b["regions"][0]["polygon"][1] = json!({"arc": 350}),
            "/regions/0/polygon/1",
            "inside the domain",
        ),
        (
            |b| b["regions"][0]["polygon"][1] = json!({"arc": 90, "radius": 1}),
            "/regions/0/polygon/1/radius",
            "unknown field",
        ),
        // Two arcs of 995 segments each: refused before the second is drawn.
        (
            |b| {
                let fine = json!({"arc": 179, "max_segment_angle": 0.18});
                b["regions"][0]["polygon"] = json!([[1, 0], fine, [-1, 0], fine]);
            },
            "/regions/0/polygon",
            "more than 1000 corners once its arcs are drawn",
        ),
    ];
    each_refused(&app, || coax(100), &mistakes).await;
    let mut body = coax(100);
    body["regions"][0]["polygon"][2] = json!([1, 0]);
    let p = refused(&app, body).await;
    assert_eq!(p["field"], "/regions/0/polygon/1", "an arc from a corner to itself: {p}");
    assert!(p["detail"].as_str().unwrap().contains("two different corners"), "{p}");
    app.shutdown().await;
}

/// A round core of μr 10⁴ from r = 10 to 15 mm, 10 mm deep, and a coil of 50 turns at 1 A
/// with one side in its hole and the other outside: two discs of arcs, the hole's drawn over
/// the core's, later regions winning.
fn ring_core(max_vertices: u64) -> Value {
    let disc = |r: f64| json!([[r, 0], {"arc": 180, "max_segment_angle": 2}, [-r, 0], {"arc": 180, "max_segment_angle": 2}]);
    json!({
        "physics": "magnetostatic", "unit": "mm", "depth": 10,
        "domain": {"x": [-40, 40], "y": [-40, 40]},
        "materials": {"core": {"mu_r": 10000}},
        "circuits": {"winding": {"current": 1}},
        "regions": [
            {"name": "core", "material": "core", "polygon": disc(15.0)},
            {"name": "hole", "material": "air", "polygon": disc(10.0)},
            {"name": "in", "material": "copper", "circuit": "winding", "turns": 50, "x": [-2, 2], "y": [-2, 2]},
            {"name": "out", "material": "copper", "circuit": "winding", "turns": 50, "direction": -1,
             "x": [17, 21], "y": [-2, 2]}
        ],
        "max_vertices": max_vertices
    })
}

#[tokio::test]
async fn a_ring_cores_inductance_is_the_magnetic_circuits() {
    // Every circle in the core holds the 50 ampere-turns of the side in its hole, so as μr grows
    // H → NI/2πr there and L → N² μ0 μr ln(r2/r1)/2π times the depth; the flux that stays in
    // the air adds about 1/(μr ln(r2/r1)/2π) of that.
    let app = spawn_app().await;
    let response = app.post("/v1/solutions", &ring_core(10_000)).await;
    assert_eq!(response.status(), 200);
    let doc: Value = response.json().await.unwrap();
    let winding = &doc["stats"]["circuits"]["winding"];
    let inductance = winding["inductance"].as_f64().unwrap();
    let circuit = 0.01 * 50f64.powi(2) * MU_0 * 1e4 * 1.5f64.ln() / (2.0 * std::f64::consts::PI);
    assert!((inductance - circuit).abs() < 2e-3 * circuit, "{winding} against {circuit} H");
    app.shutdown().await;
}
