//! The deployment files under deploy/ match the server: every setting they give is one it
//! accepts, they share through Redis, and their probes name routes it serves.

use meshfit::config::{Config, RawConfig};
use serde_yaml_ng::Value;

fn config(settings: impl IntoIterator<Item = (String, String)>) -> Config {
    let raw: RawConfig = settings.into_iter().collect();
    let config = Config::try_from(raw.clone()).unwrap_or_else(|e| panic!("{raw:?}: {e}"));
    assert!(config.redis.url.is_some(), "the replicas share through Redis");
    config
}

fn text(v: &Value) -> String {
    v.as_str().map(str::to_owned).unwrap_or_else(|| panic!("not a string: {v:?}"))
}

#[test]
fn the_compose_file_gives_settings_the_server_accepts() {
    let compose: Value = serde_yaml_ng::from_str(include_str!("../deploy/compose.yaml")).unwrap();
    let service = &compose["services"]["meshfit"];
    let env = service["environment"].as_mapping().expect("an environment map");
    let config = config(env.iter().map(|(k, v)| (text(k), text(v))));
    assert_eq!(service["deploy"]["replicas"].as_u64(), Some(3));
    // compose's stop timeout covers the grace and the 5 s drain.
    let stop = text(&service["stop_grace_period"]);
    let stop: u64 = stop.trim_end_matches('s').parse().unwrap();
    assert!(config.shutdown_grace.as_secs() + 5 < stop, "{stop} s is too short");
    for name in ["redis", "lb"] {
        assert!(compose["services"][name].is_mapping(), "the {name} service");
    }
}

#[test]
fn the_kubernetes_manifest_gives_settings_the_server_accepts_and_probes_its_routes() {
    let docs: Vec<Value> = serde_yaml_ng::Deserializer::from_str(include_str!("../deploy/kubernetes.yaml"))
        .map(|doc| serde::Deserialize::deserialize(doc).unwrap())
        .collect();
    let kinds: Vec<String> = docs.iter().map(|d| text(&d["kind"])).collect();
    for kind in ["Deployment", "Service", "PodDisruptionBudget"] {
        assert!(kinds.iter().any(|k| k == kind), "a {kind} in {kinds:?}");
    }
    let deployment =
        docs.iter().find(|d| d["metadata"]["name"] == "meshfit" && d["kind"] == "Deployment").unwrap();
    let pod = &deployment["spec"]["template"]["spec"];
    let container = &pod["containers"][0];
    let env = container["env"].as_sequence().expect("an env list");
    let config = config(env.iter().map(|e| (text(&e["name"]), text(&e["value"]))));
    let grace = pod["terminationGracePeriodSeconds"].as_u64().unwrap();
    assert!(config.shutdown_grace.as_secs() + 5 < grace);
    for (probe, path) in [("readinessProbe", "/readyz"), ("livenessProbe", "/healthz")] {
        assert_eq!(container[probe]["httpGet"]["path"], path);
        assert!(meshfit::http::ROUTES.contains(&("get", path)), "{path} is served");
    }
}
