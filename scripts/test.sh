#!/usr/bin/env bash
# Runs every test graybox has: the Rust unit and integration tests (release profile, so that
# the tests, benchmarks and the Python client tests share one build), the API tests once more
# on a throwaway PostgreSQL cluster and S3 endpoint, then the Python client tests in a pinned
# virtualenv.
set -euo pipefail
cd "$(dirname "$0")/.."

# Each phase's wall time, printed as it ends and together at the end (the README's figures).
phases=()
last=$SECONDS
phase() {
  phases+=("$(printf '%-52s %5d s' "$1" $((SECONDS - last)))")
  echo "test.sh: ${phases[-1]}" >&2
  last=$SECONDS
}

# The pinned virtualenv of the Python tests (it also serves the S3 endpoint below), made
# beside the build: installing wheels waits on the disk and the registry, the build on the
# cores. Only the Python module on the inference core needs the build (below).
venv=${GRAYBOX_VENV:-.venv}
venv_log=$(mktemp)
(
  if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
  fi
  "$venv/bin/pip" install --quiet --disable-pip-version-check -r tests/python/requirements.txt
  "$venv/bin/pip" install --quiet --disable-pip-version-check ./clients/python
) > "$venv_log" 2>&1 &
venv_pid=$!

# Every member's artifacts first: `cargo test` builds only what a test links, and the Python
# module (clients/native) has no Rust tests of its own (tests/python/test_native.py tests it).
cargo build --workspace --release --locked
phase "build (the workspace, release)"
cargo test --workspace --release --locked --no-run "$@"
phase "build (the test binaries)"
cargo test --workspace --release --locked "$@"
phase "Rust tests (the API on SQLite)"

# The README's run command must reuse this build: with the dev-dependencies' and the lab's
# features declared on the service's normal dependencies (Cargo.toml), neither a plain release
# build of the workspace nor `cargo run`'s build of the service alone compiles anything.
for build in "--workspace" "-p graybox"; do
  # shellcheck disable=SC2086 # the words of $build are separate arguments
  stale=$(cargo build $build --release --locked --message-format=json 2>/dev/null | python3 -c '
import json, sys
for line in sys.stdin:
    m = json.loads(line)
    if m.get("reason") == "compiler-artifact" and not m["fresh"]:
        print(m["package_id"].rsplit("#", 1)[-1], m["target"]["name"])
')
  if [ -n "$stale" ]; then
    echo "error: after the tests, cargo build $build --release recompiled (features differ" >&2
    echo "between the builds; declare them on the service's normal dependencies):" >&2
    echo "$stale" >&2
    exit 1
  fi
done

# The virtualenv started beside the build.
if ! wait "$venv_pid"; then
  echo "error: the Python virtualenv could not be made:" >&2
  cat "$venv_log" >&2
  exit 1
fi
cat "$venv_log" >&2
rm -f "$venv_log"
# The Python module on the inference core (tests/python/test_native.py), installed as the
# README installs it: its wheel packs the workspace's build above, so the inference core must
# not compile again (a build of the module alone would, with other features).
core_rlibs() { stat -c '%n %Y' target/release/deps/libgraybox_core-*.rlib; }
before=$(core_rlibs)
"$venv/bin/pip" install --quiet --disable-pip-version-check --force-reinstall --no-deps ./clients/native
if [ "$(core_rlibs)" != "$before" ]; then
  echo "error: pip install ./clients/native compiled the inference core again:" >&2
  diff <(echo "$before") <(core_rlibs) >&2 || true
  exit 1
fi
phase "Python virtualenv and packages"
# Both packages' type stubs as a caller's type checker reads them once installed: the
# examples pass mypy's strictest mode.
"$venv/bin/python" -m mypy --strict --cache-dir=/dev/null examples/python/*.py
phase "type check of the examples (mypy --strict)"

# The service's API tests again as it runs beyond one machine: each test on a new database of
# a throwaway PostgreSQL cluster and its large bytes in an S3 endpoint (tests/api/helpers.rs
# reads GRAYBOX_TEST_POSTGRES and GRAYBOX_TEST_BLOBS). Same build, nothing recompiles.
# shellcheck source=scripts/services.sh
source scripts/services.sh
start_postgres "$venv"
start_s3 "$venv"
cargo test -p graybox --release --locked --test api
phase "API tests again (PostgreSQL and S3)"

if [ -d tests/python ] && compgen -G "tests/python/test_*.py" > /dev/null; then
  # The dashboard test drives Debian's Chromium (browsers cannot be downloaded here).
  if ! command -v chromium > /dev/null; then
    sudo=""
    if [ "$(id -u)" != 0 ]; then sudo="sudo"; fi
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq chromium > /dev/null
  fi
  GRAYBOX_BIN="$PWD/target/release/graybox" GRAYBOX_LAB_BIN="$PWD/target/release/graybox-lab" \
    "$venv/bin/python" -m pytest -q tests/python
  phase "Python, C and dashboard tests (pytest)"
fi
printf 'test.sh: wall time of each phase\n' >&2
printf '  %s\n' "${phases[@]}" >&2
printf '  %-52s %5d s\n' "total" "$SECONDS" >&2
