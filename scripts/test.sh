#!/usr/bin/env bash
# Runs every test graybox has: the Rust unit and integration tests (release profile, so that
# the tests, benchmarks and the Python client tests share one build), then the Python client
# tests in a pinned virtualenv when they exist.
set -euo pipefail
cd "$(dirname "$0")/.."

cargo test --release --locked "$@"

if [ -d tests/python ] && compgen -G "tests/python/test_*.py" > /dev/null; then
  venv=${GRAYBOX_VENV:-.venv}
  if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
  fi
  "$venv/bin/pip" install --quiet --disable-pip-version-check -r tests/python/requirements.txt
  "$venv/bin/pip" install --quiet --disable-pip-version-check ./clients/python
  GRAYBOX_BIN="$PWD/target/release/graybox" "$venv/bin/python" -m pytest -q tests/python
fi
