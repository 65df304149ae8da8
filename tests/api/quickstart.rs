//! The README's quick start, run as written: its shell block, with `localhost:8080` pointed at
//! a test server, in a scratch directory that sees the repository's `examples/`. So the README
//! cannot drift from the service: a command that fails, a sample file that is missing or an
//! answer that changed shape fails this test.
//!
//! Needs `bash`, `curl` and `jq` (`.ci/run` installs both); without them the test says so and
//! passes.

use crate::helpers::{spawn_with, temp_dir, test_config};
use std::path::Path;
use std::process::Command;

/// The shell block under the README's "Quick start with curl" heading.
fn quick_start(readme: &str) -> &str {
    let section = &readme[readme.find("## Quick start with curl").expect("the README has a quick start")..];
    let block = &section[section.find("```sh\n").expect("a sh block") + "```sh\n".len()..];
    &block[..block.find("```").expect("the block ends")]
}

#[tokio::test]
async fn the_readme_quick_start_runs_as_written_and_says_what_the_readme_says() {
    if ["curl", "jq"].iter().any(|tool| Command::new(tool).arg("--version").output().is_err()) {
        eprintln!("skipped: no curl or no jq (apt-get install curl jq)");
        return;
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    // The server's own defaults for what the quick start sends: a 256 × 256 grid file.
    let mut config = test_config();
    (config.limits.max_grid_points, config.body.max_bytes) = (4097 * 4097, 16 << 20);
    let app = spawn_with(config).await;
    let dir = temp_dir("quickstart");
    std::os::unix::fs::symlink(root.join("examples"), dir.join("examples")).unwrap();
    // curl fails on an error status (and says so on stderr) while still printing the body.
    let script = format!(
        "curl() {{ command curl -S --fail-with-body \"$@\"; }}\nset -e\n{}",
        quick_start(&readme).replace("localhost:8080", &app.addr.to_string())
    );
    let cwd = dir.clone();
    let out = tokio::task::spawn_blocking(move || {
        Command::new("bash").arg("-c").arg(script).current_dir(cwd).output().expect("bash runs")
    })
    .await
    .unwrap();
    let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "the quick start stopped:\n{stderr}\n{stdout}");
    // A pipe cut short (`| head`) is curl error 23, which is fine; an HTTP error is 22.
    assert!(!stderr.contains("curl: (22)"), "a command got an error status:\n{stderr}");

    for said in [
        "x-cache: hit",
        "x-cache: prefix",
        "event: progress",
        "event: result",
        r#",null]}"#,
        r#""status":"cancelled""#,
        r#"{"status":"succeeded","evaluations":{"asked":"#,
        r#"{"status":"ok"}"#,
        "openapi: 3.1",
        "HTTP/1.1 202 Accepted",
        r#""source":"upload","file_bytes":93240,"size":[256,256]"#,
        r#""format":"quantized-mesh-1.0""#,
    ] {
        assert!(stdout.contains(said), "the quick start no longer prints {said:?}:\n{stdout}");
    }
    // The electromagnet's four forces, one a line; the armature's is the second, as it says.
    let forces: Vec<f64> = (stdout.lines())
        .filter_map(|l| l.strip_prefix(r#""force":["#))
        .map(|l| l.split(',').next().unwrap().parse().unwrap())
        .collect();
    assert_eq!(forces.len(), 4, "{stdout}");
    assert!((-85.0..-78.0).contains(&forces[1]), "the armature's force is {} N", forces[1]);
    // Its regions by name, in order, and its circuit with the apparent inductance it says.
    let names: Vec<&str> =
        (stdout.lines()).filter_map(|l| l.strip_prefix(r#""name":""#)?.strip_suffix(r#"","area"#)).collect();
    assert_eq!(names, ["core", "armature", "coil+", "coil-"], "{stdout}");
    let circuits: Vec<serde_json::Value> = (stdout.lines())
        .filter_map(|l| serde_json::from_str(l.strip_prefix(r#""circuits":"#)?).ok())
        .collect();
    assert_eq!(circuits.len(), 2, "the electromagnet's and the actuator's: {stdout}");
    let inductance = |i: usize| circuits[i]["coil"]["inductance"].as_f64().unwrap();
    assert!((5.0e-3..5.6e-3).contains(&inductance(0)), "{}", circuits[0]);
    assert!((0.019..0.022).contains(&inductance(1)), "{}", circuits[1]);
    // The actuator's plunger, pulled axially into its pot.
    let plunger = stdout.lines().find(|l| l.starts_with(r#""name":"plunger""#)).expect("the plunger's line");
    let force = plunger.rsplit(r#""force":["#).next().unwrap().trim_end_matches(']');
    let [fr, fz] = [0, 1].map(|i| force.split(',').nth(i).unwrap().parse::<f64>().unwrap());
    assert!(fr == 0.0 && (-1.2..-0.95).contains(&fz), "{plunger}");
    let file = |name: &str| std::fs::read(dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
    for (name, starts) in [
        ("mesh.ply", &b"ply\n"[..]),
        ("mesh.glb", b"glTF"),
        ("mesh.png", b"\x89PNG"),
        ("electromagnet.png", b"\x89PNG"),
        ("mesh.msh", b"$MeshFormat"),
        ("heights.ply", b"ply\n"),
    ] {
        assert!(file(name).starts_with(starts), "{name}");
    }
    // The terrain tile, unzipped by curl, with the normals and no metadata (level 14).
    let tile = quantized_mesh::DecodedMesh::decode(&file("tile.terrain")).expect("a quantized-mesh tile");
    assert!(tile.extensions.normals.is_some() && tile.extensions.metadata.is_none());
    for (name, holds) in [
        ("mesh.obj", "\nf "),
        ("heightmap.obj", "\nf "),
        ("tile.obj", "\nf "),
        ("mesh.vtu", "<VTKFile"),
        ("magnet.vtu", "<VTKFile"),
        ("mesh.svg", "<svg"),
    ] {
        assert!(String::from_utf8_lossy(&file(name)).contains(holds), "{name}");
    }
    for (name, vertices) in [("mesh.json", 2000), ("dem.json", 20_000), ("job.json", 1_000_000)] {
        let doc: serde_json::Value = serde_json::from_slice(&file(name)).unwrap();
        assert_eq!(doc["stats"]["vertices"], vertices, "{name}");
    }
    // The GeoTIFF placed the mesh on its own rectangle: 30 m pixels from (500000, 4000000).
    let dem: serde_json::Value = serde_json::from_slice(&file("dem.json")).unwrap();
    let xs: Vec<f64> = dem["vertices"].as_array().unwrap().iter().map(|v| v[0].as_f64().unwrap()).collect();
    assert_eq!(xs.iter().copied().fold(f64::INFINITY, f64::min), 500_015.0);
    app.shutdown().await;
}
