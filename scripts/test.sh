#!/usr/bin/env bash
# Sets up (scripts/setup.sh), makes sure Redis is listening on 127.0.0.1:6379, then runs the test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
if ! redis-cli -h 127.0.0.1 -p 6379 ping >/dev/null 2>&1; then
  echo "test: starting redis-server on 127.0.0.1:6379"
  redis-server --daemonize yes --bind 127.0.0.1 --port 6379 --save "" --appendonly no
  for _ in $(seq 50); do redis-cli -h 127.0.0.1 -p 6379 ping >/dev/null 2>&1 && break; sleep 0.1; done
fi
python3 -m ruff check .
npx --no-install eslint --max-warnings 0 service/static
python3 -m pytest -q "$@"
