//! Whether CesiumJS can be run, shared by the test crates that check tiles with it.

use std::path::PathBuf;
use std::process::Command;

/// CesiumJS's own terrain provider, in Node (`npm ci --prefix tests/cesium`): the directory
/// of its `check.mjs`, or `None` to skip; `CESIUM_TESTS=required` (as in `.ci/run`) makes its
/// absence a failure.
pub fn cesium() -> Option<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/cesium");
    let installed = dir.join("node_modules/@cesium/engine").is_dir()
        && Command::new("node").arg("--version").output().is_ok_and(|o| o.status.success());
    if !installed {
        let required = std::env::var("CESIUM_TESTS").is_ok_and(|v| v == "required");
        assert!(!required, "CESIUM_TESTS=required, but node or tests/cesium/node_modules is missing");
        eprintln!("skipped: CesiumJS is not installed (npm ci --prefix tests/cesium)");
        return None;
    }
    Some(dir)
}
