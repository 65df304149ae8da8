//! Malformed requests: each gets its own status, problem type and the fields that say where.

use crate::helpers::spawn_app;
use serde_json::{Value, json};

struct Case {
    name: &'static str,
    body: String,
    status: u16,
    kind: &'static str,
    /// JSON pointers into the problem and the values they must hold.
    fields: Vec<(&'static str, Value)>,
    /// Text the detail must contain.
    detail: &'static str,
}

fn case(name: &'static str, body: impl Into<String>, status: u16, kind: &'static str) -> Case {
    Case { name, body: body.into(), status, kind, fields: Vec::new(), detail: "" }
}

impl Case {
    fn field(mut self, pointer: &'static str, value: Value) -> Self {
        self.fields.push((pointer, value));
        self
    }
    fn detail(mut self, text: &'static str) -> Self {
        self.detail = text;
        self
    }
}

fn cases() -> Vec<Case> {
    let long = format!(r#"{{"function": "{}"}}"#, "x+".repeat(100) + "x");
    vec![
        case("not json", "function=x", 400, "malformed-json"),
        case("empty body", "", 400, "malformed-json").detail("empty"),
        case("truncated", r#"{"function": "x""#, 400, "malformed-json").detail("line 1"),
        case("an array", "[1, 2]", 422, "invalid-request"),
        case("an array that fits the fields in order", r#"["x"]"#, 422, "invalid-request").detail("object"),
        case("a string", r#""x""#, 422, "invalid-request").detail("object"),
        case("a fractional budget", r#"{"function": "x", "max_vertices": 100.5}"#, 422, "invalid-request")
            .detail("100.5"),
        case(
            "a fractional grid size",
            r#"{"grid": {"nx": 2.5, "ny": 2, "values": [1, 2, 3, 4]}}"#,
            422,
            "invalid-request",
        ),
        case("no source", "{}", 422, "invalid-source").detail("none given"),
        case(
            "both sources",
            r#"{"function": "x", "grid": {"nx": 2, "ny": 2, "values": [1, 2, 3, 4]}}"#,
            422,
            "invalid-source",
        )
        .detail("not both"),
        case("function of the wrong type", r#"{"function": 5}"#, 422, "invalid-request")
            .detail("expected a string"),
        case("unknown field", r#"{"function": "x", "max_vertcies": 10}"#, 422, "invalid-request")
            .detail("max_vertcies"),
        case(
            "a budget sent as a string",
            r#"{"function": "x", "max_vertices": "100"}"#,
            422,
            "invalid-request",
        )
        .field("/field", json!("/max_vertices")),
        case(
            "a domain sent as a list",
            r#"{"function": "x", "domain": [0, 1, 0, 1]}"#,
            422,
            "invalid-request",
        )
        .field("/field", json!("/domain"))
        .detail(r#"write {"x": [0, 1], "y": [0, 1]}"#),
        case(
            "a wrong domain bound",
            r#"{"function": "x", "domain": {"x": [0, 1], "y": [0, "1"]}}"#,
            422,
            "invalid-request",
        )
        .field("/field", json!("/domain/y/1")),
        case(
            "an unknown grid field",
            r#"{"grid": {"nx": 2, "ny": 2, "values": [1, 2, 3, 4], "nz": 1}}"#,
            422,
            "invalid-request",
        )
        .field("/field", json!("/grid/nz")),
        case("a problem sent to meshes", r#"{"physics": "poisson", "f": 1}"#, 422, "invalid-request")
            .field("/field", json!("/physics"))
            .detail("POST /v1/solutions"),
        case(
            "a budget below the corners",
            r#"{"function": "x", "max_vertices": 3}"#,
            422,
            "invalid-parameter",
        )
        .field("/field", json!("/max_vertices"))
        .detail("between 4 and 2000000"),
        case("implicit multiplication", r#"{"function": "2x + y"}"#, 422, "invalid-expression")
            .field("/field", json!("/function"))
            .detail("write `2*x`"),
        case(
            "grid values nested as rows",
            r#"{"grid": {"nx": 2, "ny": 2, "values": [[1, 2], [3, 4]]}}"#,
            422,
            "invalid-grid",
        )
        .detail("one flat list"),
        case(
            "grid value beyond f64",
            r#"{"grid": {"nx": 2, "ny": 2, "values": [1, 2, 1e400, 4]}}"#,
            422,
            "invalid-grid",
        )
        .field("/index", json!([0, 1]))
        .detail("beyond the range of a 64-bit float"),
        case("unknown variable", r#"{"function": "x + z"}"#, 422, "invalid-expression")
            .field("/column", json!(5)),
        case("unclosed parenthesis", r#"{"function": "sin(x"}"#, 422, "invalid-expression")
            .field("/column", json!(6)),
        case("stray character", r#"{"function": "x $ y"}"#, 422, "invalid-expression")
            .field("/column", json!(3)),
        case("unknown function", r#"{"function": "1 + foo(x)"}"#, 422, "invalid-expression")
            .field("/column", json!(5))
            .detail("unknown function `foo`"),
        case("wrong arity", r#"{"function": "atan2(x)"}"#, 422, "invalid-expression").detail("takes 2"),
        case("empty expression", r#"{"function": " "}"#, 422, "invalid-expression")
            .field("/column", json!(1)),
        case("expression too long", long, 422, "limit-exceeded")
            .field("/limit/name", json!("MESHFIT_MAX_EXPRESSION_LEN"))
            .field("/limit/value", json!(200)),
        case(
            "grid too short",
            r#"{"grid": {"nx": 3, "ny": 2, "values": [1, 2, 3, 4, 5]}}"#,
            422,
            "invalid-grid",
        )
        .detail("5 values, but nx and ny need 6"),
        case("grid too narrow", r#"{"grid": {"nx": 1, "ny": 2, "values": [1, 2]}}"#, 422, "invalid-grid"),
        case(
            "grid null value",
            r#"{"grid": {"nx": 3, "ny": 2, "values": [1, 2, 3, 4, null, 6]}}"#,
            422,
            "invalid-grid",
        )
        .field("/index", json!([1, 1])),
        case(
            "grid string value",
            r#"{"grid": {"nx": 2, "ny": 2, "values": [1, "a", 3, 4]}}"#,
            422,
            "invalid-grid",
        )
        .field("/index", json!([1, 0])),
        case(
            "grid over the limit",
            r#"{"grid": {"nx": 200, "ny": 200, "values": []}}"#,
            422,
            "limit-exceeded",
        )
        .field("/limit/name", json!("MESHFIT_MAX_GRID_POINTS"))
        .field("/limit/value", json!(10000)),
        case(
            "grid with more values than the limit",
            format!(r#"{{"grid": {{"nx": 2, "ny": 2, "values": [{}0]}}}}"#, "1,".repeat(20_000)),
            422,
            "invalid-grid",
        )
        .detail("20001 values, but nx and ny need 4"),
        case("grid without values", r#"{"grid": {"nx": 2, "ny": 2}}"#, 422, "invalid-grid").detail("values"),
        case(
            "grid with a dtype",
            r#"{"grid": {"nx": 2, "ny": 2, "values": [1, 2, 3, 4], "dtype": "f32"}}"#,
            422,
            "invalid-grid",
        )
        .detail("raw grid files"),
        case(
            "reversed domain",
            r#"{"function": "x", "domain": {"x": [1, 0], "y": [0, 1]}}"#,
            422,
            "invalid-domain",
        )
        .detail("empty on x"),
        case(
            "empty domain",
            r#"{"function": "x", "domain": {"x": [0, 1], "y": [2, 2]}}"#,
            422,
            "invalid-domain",
        )
        .detail("empty on y"),
        case("domain without y", r#"{"function": "x", "domain": {"x": [0, 1]}}"#, 422, "invalid-request"),
        case(
            "domain with three bounds",
            r#"{"function": "x", "domain": {"x": [0, 1, 2], "y": [0, 1]}}"#,
            422,
            "invalid-domain",
        )
        .detail("x must be [low, high], got 3 numbers"),
        case("budget below four", r#"{"function": "x", "max_vertices": 3}"#, 422, "invalid-parameter"),
        case("budget over the limit", r#"{"function": "x", "max_vertices": 3000000}"#, 422, "limit-exceeded")
            .field("/limit/name", json!("MESHFIT_MAX_VERTICES"))
            .field("/limit/value", json!(2_000_000)),
        case("negative budget", r#"{"function": "x", "max_vertices": -5}"#, 422, "invalid-request"),
        case("negative tolerance", r#"{"function": "x", "tolerance": -1}"#, 422, "invalid-parameter"),
        case("min_angle above 30", r#"{"function": "x", "min_angle": 31}"#, 422, "invalid-parameter")
            .detail("at most 30 degrees, got 31"),
        case(
            "min_angle with the paper's criterion",
            r#"{"function": "x", "min_angle": 20, "criterion": "variation"}"#,
            422,
            "invalid-parameter",
        )
        .detail("needs criterion error"),
        case(
            "data-dependent on an expression",
            r#"{"function": "x", "method": "data-dependent"}"#,
            422,
            "invalid-parameter",
        )
        .detail("needs a grid and criterion error")
        .field("/field", json!("/method")),
        case(
            "data-dependent with the paper's criterion",
            r#"{"grid": {"nx": 2, "ny": 2, "values": [1, 2, 3, 4]}, "method": "data-dependent", "criterion": "variation"}"#,
            422,
            "invalid-parameter",
        )
        .field("/field", json!("/method")),
        case("unknown method", r#"{"function": "x", "method": "semi"}"#, 422, "invalid-request")
            .detail("semi-recursive"),
        case("unknown criterion", r#"{"function": "x", "criterion": "hessian"}"#, 422, "invalid-request")
            .detail("curvature"),
        case("min_size with criterion error", r#"{"function": "x", "min_size": 0.01}"#, 422, "invalid-parameter")
            .detail("needs criterion curvature")
            .field("/field", json!("/min_size")),
        case(
            "max_size below twice min_size",
            r#"{"function": "x", "criterion": "curvature", "min_size": 0.1, "max_size": 0.15}"#,
            422,
            "invalid-parameter",
        )
        .detail("at least twice min_size")
        .field("/field", json!("/max_size")),
        case("time limit as text", r#"{"function": "x", "time_limit_ms": "soon"}"#, 422, "invalid-request"),
    ]
}

#[tokio::test]
async fn each_malformed_request_gets_its_own_problem() {
    let app = spawn_app().await;
    let table = cases();
    assert!(table.len() >= 25);
    for case in table {
        let response = app.post_raw("/v1/meshes", case.body.clone()).await;
        let status = response.status().as_u16();
        let content_type = response.headers()["content-type"].to_str().unwrap().to_owned();
        let problem: Value =
            response.json().await.unwrap_or_else(|e| panic!("{}: body is not JSON: {e}", case.name));
        let name = case.name;
        assert_eq!(status, case.status, "{name}: {problem}");
        assert_eq!(content_type, "application/problem+json", "{name}");
        assert_eq!(problem["type"], format!("/problems/{}", case.kind), "{name}: {problem}");
        assert_eq!(problem["status"], case.status, "{name}");
        assert!(problem["title"].as_str().is_some_and(|t| !t.is_empty()), "{name}: {problem}");
        let detail = problem["detail"].as_str().unwrap_or_default();
        assert!(detail.contains(case.detail), "{name}: detail {detail:?} lacks {:?}", case.detail);
        for (pointer, value) in &case.fields {
            assert_eq!(problem.pointer(pointer), Some(value), "{name}: {pointer} in {problem}");
        }
    }
    // The same validation guards the jobs endpoint.
    let response = app.post_raw("/v1/jobs", r#"{"function": "x + z"}"#).await;
    assert_eq!(response.status(), 422);
    app.shutdown().await;
}

#[tokio::test]
async fn a_body_over_the_limit_is_413_naming_the_limit() {
    let app = spawn_app().await;
    let huge = format!(r#"{{"grid": {{"nx": 2, "ny": 2, "values": [{}0]}}}}"#, "0,".repeat(600_000));
    let response = app.post_raw("/v1/meshes", huge).await;
    assert_eq!(response.status(), 413);
    let problem: Value = response.json().await.unwrap();
    assert_eq!(problem["type"], "/problems/limit-exceeded");
    assert_eq!(problem["limit"], json!({"name": "MESHFIT_MAX_BODY_BYTES", "value": 1 << 20}));
    app.shutdown().await;
}

#[tokio::test]
async fn wrong_methods_and_routes_get_problems_too() {
    let app = spawn_app().await;
    let response = app.get("/v1/meshes").await;
    assert_eq!(response.status(), 405);
    assert_eq!(response.headers()["content-type"], "application/problem+json");
    let response = app.get("/v2/anything").await;
    assert_eq!(response.status(), 404);
    let problem: Value = response.json().await.unwrap();
    assert_eq!(problem["type"], "/problems/not-found");
    app.shutdown().await;
}

#[tokio::test]
async fn a_body_of_a_type_the_route_does_not_take_is_415_naming_the_ones_it_does() {
    let app = spawn_app().await;
    let body = r#"{"function": "x*y", "max_vertices": 10}"#;
    let send = |path: &'static str, content_type: &'static str, body: Vec<u8>| {
        app.client.post(app.url(path)).header("content-type", content_type).body(body).send()
    };
    for content_type in ["text/plain", "application/xml"] {
        let r = send("/v1/meshes", content_type, body.into()).await.unwrap();
        assert_eq!(r.status(), 415, "{content_type}");
        let p: Value = r.json().await.unwrap();
        assert_eq!(p["type"], "/problems/unsupported-media-type");
        assert_eq!(p["accepted"], json!(["application/json", "multipart/form-data"]), "{p}");
    }
    // curl's -d names form data whatever it sends: a JSON object under it is read as JSON.
    let r = send("/v1/meshes", "application/x-www-form-urlencoded", body.into()).await.unwrap();
    assert_eq!(r.status(), 200);
    // A grid file sent raw is told how to send it.
    let png = std::fs::read("examples/tiles/jacksboro-terrarium.png").unwrap();
    let r = send("/v1/meshes", "application/x-www-form-urlencoded", png.clone()).await.unwrap();
    assert_eq!(r.status(), 415);
    assert!(r.text().await.unwrap().contains("-F grid=@"));
    let r = send("/v1/meshes", "application/json", png).await.unwrap();
    assert_eq!(r.status(), 400);
    assert!(r.text().await.unwrap().contains("PNG file, not JSON"));
    // A boundary value problem is JSON only.
    let r = send("/v1/solutions", "multipart/form-data; boundary=x", b"--x--".to_vec()).await.unwrap();
    assert_eq!(r.status(), 415);
    assert_eq!(r.json::<Value>().await.unwrap()["accepted"], json!(["application/json"]));
    app.shutdown().await;
}
