"""Checks that Cargo.toml's rust-version is a real minimum: no locked dependency (dev ones
included) declares a newer one. Our own code's std APIs are checked by clippy's
incompatible_msrv lint, which reads the same rust-version; edition 2024's let-chains set its
floor at 1.88."""
import json
import subprocess
import sys

meta = json.loads(subprocess.check_output(["cargo", "metadata", "--format-version", "1", "--locked"]))
# (major, minor, patch), so that "1.88" and "1.88.0" are the same version.
version = lambda v: (tuple(int(x) for x in (v or "0").split(".")) + (0, 0))[:3]
ours = next(p for p in meta["packages"] if p["name"] == "meshfit")["rust_version"]
newer = [f"{p['name']} {p['version']} needs {p['rust_version']}" for p in meta["packages"]
         if version(p.get("rust_version")) > version(ours)]
if newer:
    sys.exit(f"rust-version {ours} is below what dependencies need:\n  " + "\n  ".join(newer))
print(f"rust-version {ours}: no dependency needs a newer Rust")
