#!/usr/bin/env bash
# Sets up what the tests need (scripts/setup.sh test), starts Redis and PostgreSQL when they are not listening,
# runs the checks (lint, format, layers, types, the web UI's lint, the docs build) and then the test suite.
# Arguments go to pytest (the main run only). A second run then puts the concurrency and integrity tests on
# PostgreSQL (CURVEFM_TEST_DATABASE=postgresql: a database per data directory, see docs/operations.md); without a
# PostgreSQL server it skips them, and under CI it fails saying why.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh test
bash scripts/services.sh
bash scripts/check.sh
# The editable install leaves src/ uncompiled, and where PYTHONDONTWRITEBYTECODE is set every API, worker and CLI
# process the tests start would compile it again.
.venv/bin/python -m compileall -q src >/dev/null
.venv/bin/python -m pytest -q "$@"

POSTGRES_TESTS=(
  tests/service/test_integrity.py
  tests/service/test_replicas.py
  tests/service/test_durability.py
  tests/queue/
)
echo "test.sh: the concurrency and integrity tests on PostgreSQL"
CURVEFM_TEST_DATABASE=postgresql .venv/bin/python -m pytest -q -p no:cacheprovider -m "not sqlite_only" \
  "${POSTGRES_TESTS[@]}"
