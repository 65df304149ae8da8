//! The Python client (clients/python) against this build's server: its pytest suite, run by
//! the interpreter `PYTHON_CLIENT` names (one with the client and pytest installed; `.ci/run`
//! makes one), else `python3` if it has them. Without one the test says so and passes, unless
//! `PYTHON_CLIENT_TESTS=required` (set by `.ci/run`).

use std::path::Path;
use std::process::Command;

#[test]
fn the_python_clients_tests_pass_against_the_real_server() {
    let required = std::env::var("PYTHON_CLIENT_TESTS").is_ok_and(|v| v == "required");
    let python = std::env::var("PYTHON_CLIENT").unwrap_or_else(|_| "python3".into());
    let ready = Command::new(&python)
        .args(["-c", "import meshfit, pytest"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !ready {
        assert!(!required, "PYTHON_CLIENT_TESTS=required, but {python} cannot import meshfit and pytest");
        eprintln!("skipped: {python} has no meshfit client and pytest (pip install ./clients/python pytest)");
        return;
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = Command::new(&python)
        .args(["-m", "pytest", "-q", "-p", "no:cacheprovider", "clients/python/tests"])
        .current_dir(root)
        .env("SERVER_BINARY", env!("CARGO_BIN_EXE_meshfit"))
        .output()
        .expect("pytest runs");
    let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "the Python client's tests failed:\n{stdout}\n{stderr}");
    assert!(stdout.contains(" passed"), "{stdout}");
}
