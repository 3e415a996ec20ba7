#!/usr/bin/env bash
# Sets up what the demo needs (scripts/setup.sh demo) and starts the service with its web UI on the embedded
# defaults: no Redis, data in ~/.local/share/curvefm, two generated demo shapes with a ready session. On its first
# start on that data directory the service makes an admin user and prints its login URL,
# http://127.0.0.1:8000/?token=...: open it.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh demo
exec .venv/bin/curvefm serve --demo --host "${CURVEFM_HOST:-127.0.0.1}" --port "${CURVEFM_PORT:-8000}"
