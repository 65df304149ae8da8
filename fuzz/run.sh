#!/usr/bin/env bash
# Builds meshfit's fuzz targets and runs each for MINUTES minutes, one after another, at the
# lowest CPU priority (nice 19), so it never starves other work on the machine.
#
#   fuzz/run.sh MINUTES [TARGET...]     targets: expression request grid_file engine (default: all)
#
# Needs a nightly toolchain and cargo-fuzz (`cargo install cargo-fuzz --locked`). The seeds in
# fuzz/seeds/TARGET/ are copied into fuzz/corpus/TARGET/ first; a dictionary fuzz/dicts/TARGET.dict
# is used when there is one. Each run's output goes to fuzz/artifacts/TARGET/last-run.log, and a
# crashing input to fuzz/artifacts/TARGET/ (reproduce it with `cargo +nightly fuzz run -a TARGET
# FILE`, shrink it with `cargo +nightly fuzz tmin -a TARGET FILE`). Builds use one job unless
# CARGO_BUILD_JOBS says otherwise. Exits 1 when any target found a crash, after running them all.
set -euo pipefail

if [[ $# -lt 1 || ! $1 =~ ^[0-9]+([.][0-9]+)?$ ]]; then
    echo "usage: $0 MINUTES [TARGET...]" >&2
    exit 2
fi
minutes=$1
shift
seconds=$(awk -v m="$minutes" 'BEGIN { s = int(m * 60); print (s < 1 ? 1 : s) }')
cd "$(dirname "$0")"
targets=("$@")
if [[ ${#targets[@]} -eq 0 ]]; then
    targets=(expression request grid_file engine)
fi
export CARGO_BUILD_JOBS=${CARGO_BUILD_JOBS:-1}

# Debug assertions (and overflow checks) on: -a, for the build and every run alike.
nice -n 19 cargo +nightly fuzz build -a

# Crash, timeout, out-of-memory and leak inputs in a target's artifact directory.
findings() {
    find "artifacts/$1" -maxdepth 1 -type f \( -name 'crash-*' -o -name 'timeout-*' -o -name 'oom-*' \
        -o -name 'leak-*' \) -printf '%f\n' | sort
}

summary=()
crashed=0
for target in "${targets[@]}"; do
    mkdir -p "corpus/$target" "artifacts/$target"
    if [[ -d seeds/$target ]]; then
        find "seeds/$target" -maxdepth 1 -type f ! -name '*.py' ! -name '*.md' -exec cp -n {} "corpus/$target/" \;
    fi
    extra=()
    if [[ -f dicts/$target.dict ]]; then
        extra=("-dict=dicts/$target.dict")
    fi
    if [[ $target == engine ]]; then
        # Structured input: without this, libFuzzer keeps inputs under ~40 bytes for minutes,
        # which leaves grids to a few values repeated and domains mostly at their defaults.
        extra+=(-len_control=0 -max_len=2048)
    fi
    before=$(findings "$target")
    log="artifacts/$target/last-run.log"
    echo "== $target: ${minutes} min (log: fuzz/$log)"
    status=0
    nice -n 19 cargo +nightly fuzz run -a "$target" -- \
        -max_total_time="$seconds" -rss_limit_mb=4096 -timeout=60 -print_final_stats=1 "${extra[@]}" \
        >"$log" 2>&1 || status=$?
    # libFuzzer's final stats; the last status line if it died before printing them.
    execs=$(sed -n 's/^stat::number_of_executed_units: *\([0-9]*\).*/\1/p' "$log" | tail -n 1)
    if [[ -z $execs ]]; then
        execs=$(sed -n 's/^Done \([0-9]*\) runs.*/\1/p; s/^#\([0-9]*\)[[:space:]].*/\1/p' "$log" | tail -n 1)
    fi
    new=$(comm -13 <(echo "$before") <(findings "$target") | paste -sd ' ' -)
    if [[ $status -ne 0 || -n $new ]]; then
        crashed=1
        result="CRASH (exit $status) ${new:-see the log}"
        grep -m 3 -E '^(thread .* panicked|==[0-9]+== ?ERROR|SUMMARY:)' "$log" | sed 's/^/    /' || true
    else
        result="no crash"
    fi
    line=$(printf '%-11s %6s min  %12s executions  %s' "$target" "$minutes" "${execs:-?}" "$result")
    echo "$line"
    summary+=("$line")
done

echo "== summary"
printf '%s\n' "${summary[@]}"
exit "$crashed"
