use super::*;
use crate::api::{JobRequest, SolveRequest};
use crate::spec::job_keys;
use proptest::prelude::*;

const LIMITS: Limits = Limits {
    max_vertices: 1 << 20,
    max_grid_points: 1 << 16,
    max_expression_len: 200,
    job_time_limit: Duration::from_secs(60),
};

fn mesh(body: &str) -> JobSpec {
    JobSpec::from_request(serde_json::from_str::<JobRequest>(body).unwrap(), &LIMITS).unwrap()
}

fn solution(body: &str) -> JobSpec {
    JobSpec::from_solve_request(serde_json::from_str::<SolveRequest>(body).unwrap(), &LIMITS).unwrap()
}

/// Decoding gives back a spec with the same encoding, hence the same id and family, and the
/// same limits in force.
fn round_trips(spec: &JobSpec) {
    let bytes = encode(spec);
    let back = decode(&bytes, &LIMITS).unwrap();
    assert_eq!(encode(&back), bytes);
    assert_eq!(job_keys(&back), job_keys(spec));
    assert_eq!(back.requested_time_limit, spec.requested_time_limit);
    match (&back.work, &spec.work) {
        (Work::Mesh(a), Work::Mesh(b)) => assert_eq!(a.params, b.params),
        (Work::Solve(a), Work::Solve(b)) => {
            assert_eq!(a.settings, b.settings);
            let curves = |s: &SolveSpec| s.regions.iter().map(|r| r.curve.is_some()).collect::<Vec<_>>();
            assert_eq!(curves(a), curves(b));
            let device = |s: &SolveSpec| {
                let regions: Vec<_> =
                    s.regions.iter().map(|r| (r.name.clone(), r.coil, r.torque_about)).collect();
                (regions, s.circuits.clone(), s.unit, s.depth)
            };
            assert_eq!(device(a), device(b));
        }
        _ => panic!("a mesh came back as a solution, or the other way round"),
    }
}

const PROBLEMS: [&str; 6] = [
    r#"{"f": "sin(x)*y", "exact": "x*x", "boundary": {"left": "neumann"}, "tolerance": 0.01}"#,
    r#"{"k": 2.5, "g": 1, "regions": [{"x": [0, 0.5], "y": [0, 0.5], "k": 3},
        {"polygon": [[0.6, 0.6], [0.9, 0.6], [0.7, 0.9]], "f": -1}],
        "boundary": {"left": "periodic", "right": "periodic"}, "growth": 2, "time_limit_ms": 900}"#,
    r#"{"physics": "magnetostatic", "domain": {"x": [-1, 1], "y": [-1, 1]}, "criterion": "variation",
        "regions": [{"x": [-0.5, 0.5], "y": [-0.2, 0.2], "bh": [[0, 0], [100, 0.5], [1000, 1.2]]},
        {"x": [-0.9, -0.6], "y": [-0.9, 0.9], "current": 10},
        {"x": [0.6, 0.9], "y": [-0.9, 0.9], "mu_r": 1.05, "magnetization": [0, 8e5]}]}"#,
    r#"{"f": 1, "max_vertices": 400, "method": "recursive"}"#,
    r#"{"physics": "magnetostatic", "unit": "mm", "depth": 40, "domain": {"x": [-60, 60], "y": [-60, 60]},
        "materials": {"my-steel": {"bh": [[0, 0], [100, 0.5], [1000, 1.3]]}, "my-magnet": {"br": 1.2, "hc": 9e5, "angle": 30}},
        "circuits": {"main": {"current": 2.5}, "aux": {"current": -1}},
        "regions": [{"name": "core", "material": "M400-50A", "x": [-20, 20], "y": [-20, 20], "torque_about": [1, 2]},
        {"material": "my-magnet", "x": [-50, -40], "y": [-5, 5]},
        {"name": "a", "circuit": "aux", "x": [40, 50], "y": [-5, 5]},
        {"name": "coil+", "material": "copper", "turns": 200, "circuit": "main", "x": [22, 30], "y": [-10, 10]},
        {"name": "coil-", "material": "my-steel", "turns": 200, "circuit": "main", "direction": -1, "x": [-30, -22], "y": [-10, 10]}]}"#,
    r#"{"physics": "magnetostatic", "geometry": "axisymmetric", "unit": "cm", "boundary": "open",
        "domain": {"x": [0, 6], "y": [-6, 6]}, "circuits": {"coil": {"current": 1}},
        "regions": [{"name": "plunger", "material": "M-19", "x": [0, 0.5], "y": [-1, 3]},
        {"circuit": "coil", "turns": 500, "x": [0.8, 2], "y": [-1.4, 1.4]}]}"#,
];

#[test]
fn every_kind_of_spec_comes_back_with_the_same_encoding() {
    for body in [
        r#"{"function": "x*y - sin(3*x)", "max_vertices": 700, "quality": true}"#,
        r#"{"function": "x", "domain": {"x": [-2, 2], "y": [1e-3, 5]}, "tolerance": 0.2, "time_limit_ms": 5}"#,
        r#"{"function": "y", "method": "recursive", "criterion": "variation"}"#,
        r#"{"function": "x*x", "min_angle": 25}"#,
        r#"{"grid": {"nx": 3, "ny": 2, "values": [1, -2.5, 3e10, 0, -0.0, 7]}, "method": "data-dependent"}"#,
    ] {
        round_trips(&mesh(body));
    }
    for body in PROBLEMS {
        round_trips(&solution(body));
    }
}

#[test]
fn a_device_in_another_unit_or_with_other_names_is_another_job_and_a_named_magnet_points_its_way() {
    let id = |body: &str| crate::spec::job_id(&solution(body));
    let device = PROBLEMS[4];
    assert_ne!(id(device), id(&device.replace(r#""name": "core", "#, "")));
    assert_ne!(id(device), id(&device.replace(r#""unit": "mm", "#, r#""unit": "cm", "#)));
    assert_ne!(id(device), id(&device.replace(r#""depth": 40, "#, "")));
    assert_ne!(id(device), id(&device.replace(r#""torque_about": [1, 2]"#, r#""torque_about": [0, 0]"#)));
    let round = PROBLEMS[5];
    let closed = round.replace(r#""boundary": "open","#, "");
    assert_ne!(id(round), id(&closed));
    assert_ne!(id(&closed), id(&closed.replace(r#""geometry": "axisymmetric", "#, "")));
    // A built-in magnet along +y holds its Br / (μ0 μr) exactly, with no rounding from a sine.
    let magnet = |angle: f64| {
        let body = format!(
            r#"{{"physics": "magnetostatic", "regions": [{{"material": "N45", "angle": {angle}, "x": [0.2, 0.4], "y": [0.2, 0.4]}}]}}"#
        );
        match solution(&body).work {
            Work::Solve(s) => s.regions[0].source.unwrap(),
            Work::Mesh(_) => unreachable!(),
        }
    };
    let n45 = crate::solve::materials::find("N45").unwrap();
    let strength = n45.br.unwrap() / crate::solve::MU_0 / n45.mu_r.unwrap();
    assert_eq!(magnet(90.0), [0.0, strength]);
    assert_eq!(magnet(-180.0), [-strength, 0.0]);
    let [x, y] = magnet(30.0);
    assert!(
        (x - strength * 3f64.sqrt() / 2.0).abs() < 1e-12 * strength
            && (y - strength / 2.0).abs() < 1e-12 * strength
    );
}

#[test]
fn regions_that_set_only_k_or_only_f_are_different_jobs() {
    // Once both were 8 bytes in one field: two problems shared an id, and a cache answered
    // one with the other's solution.
    let k = solution(r#"{"g": 1, "regions": [{"x": [0, 0.5], "y": [0, 0.5], "k": 2}]}"#);
    let f = solution(r#"{"g": 1, "regions": [{"x": [0, 0.5], "y": [0, 0.5], "f": 2}]}"#);
    assert_ne!(job_keys(&k).id, job_keys(&f).id);
}

#[test]
fn a_spec_of_another_engine_or_with_bytes_past_its_end_is_refused() {
    let bytes = encode(&mesh(r#"{"function": "x"}"#));
    let mut other = bytes.clone();
    let at = other.windows(ENGINE_VERSION.len()).position(|w| w == ENGINE_VERSION.as_bytes()).unwrap();
    *other[at..at + ENGINE_VERSION.len()].last_mut().unwrap() = b'0';
    assert!(
        matches!(decode(&other, &LIMITS), Err(DecodeError::Format(m)) if m.contains("kept by meshfit-engine-0"))
    );
    let mut longer = bytes;
    longer.push(0);
    assert!(matches!(decode(&longer, &LIMITS), Err(DecodeError::Format(m)) if m.contains("1 bytes past")));
}

#[test]
fn every_proper_prefix_of_an_encoding_is_refused() {
    for spec in [mesh(r#"{"grid": {"nx": 2, "ny": 2, "values": [1, 2, 3, 4]}}"#), solution(PROBLEMS[2])] {
        let bytes = encode(&spec);
        for end in 0..bytes.len() {
            assert!(
                matches!(decode(&bytes[..end], &LIMITS), Err(DecodeError::Format(_))),
                "prefix of {end} bytes"
            );
        }
    }
}

#[test]
fn a_kept_spec_is_held_to_this_replicas_limits() {
    let spec = mesh(r#"{"function": "x*y", "max_vertices": 5000, "time_limit_ms": 90000}"#);
    let tight = Limits { max_vertices: 4000, ..LIMITS };
    match decode(&encode(&spec), &tight) {
        Err(DecodeError::Spec(SpecError::Limit {
            name: "max_vertices", limit: 4000, value: 5000, ..
        })) => {}
        other => panic!("{other:?}"),
    }
    let short = Limits { job_time_limit: Duration::from_secs(2), ..LIMITS };
    let Work::Mesh(m) = decode(&encode(&spec), &short).unwrap().work else { panic!("a mesh") };
    assert_eq!(m.params.time_limit(), Some(Duration::from_secs(2)), "the limit in force is this replica's");
    let values = vec!["1"; 200 * 200].join(",");
    let grid = mesh(&format!(r#"{{"grid": {{"nx": 200, "ny": 200, "values": [{values}]}}}}"#));
    let few = Limits { max_grid_points: 1000, ..LIMITS };
    assert!(matches!(
        decode(&encode(&grid), &few),
        Err(DecodeError::Spec(SpecError::Limit { name: "grid", .. }))
    ));
    let long = Limits { max_expression_len: 3, ..LIMITS };
    let expression = solution(r#"{"f": "x*y*x"}"#);
    assert!(matches!(
        decode(&encode(&expression), &long),
        Err(DecodeError::Spec(SpecError::Limit { name: "f", .. }))
    ));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// Any mesh request's spec comes back whole.
    #[test]
    fn mesh_specs_round_trip(
        function in prop::sample::select(vec!["x", "x*y", "sin(5*x)*exp(-y)", "abs(x-0.3)"]),
        a in -10.0f64..10.0, width in 0.01f64..100.0, c in -10.0f64..10.0, height in 0.01f64..100.0,
        max_vertices in 4u64..100_000,
        method in prop::sample::select(vec!["recursive", "semi-recursive"]),
        variation in any::<bool>(),
        tolerance in prop::option::of(0.0f64..10.0),
        quality in any::<bool>(),
        time_limit_ms in prop::option::of(1u64..1_000_000),
    ) {
        let mut body = serde_json::json!({
            "function": function,
            "domain": {"x": [a, a + width], "y": [c, c + height]},
            "max_vertices": max_vertices, "method": method, "quality": quality,
            "criterion": if variation { "variation" } else { "error" },
        });
        if let Some(t) = tolerance { body["tolerance"] = t.into(); }
        if let Some(t) = time_limit_ms { body["time_limit_ms"] = t.into(); }
        round_trips(&mesh(&body.to_string()));
    }

    /// Whatever a kept spec's bytes turn into, decoding answers rather than panics.
    #[test]
    fn damaged_encodings_never_panic(which in 0..PROBLEMS.len() + 1, at in any::<prop::sample::Index>(), byte in any::<u8>()) {
        let spec = match PROBLEMS.get(which) {
            Some(body) => solution(body),
            None => mesh(r#"{"grid": {"nx": 3, "ny": 2, "values": [1, 2, 3, 4, 5, 6]}, "min_angle": 20}"#),
        };
        let mut bytes = encode(&spec);
        let i = at.index(bytes.len());
        bytes[i] = byte;
        let _ = decode(&bytes, &LIMITS);
    }
}
