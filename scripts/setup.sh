#!/usr/bin/env bash
# Installs everything curvefm needs on a Debian-like machine with Python 3.11+: system libraries
# (open3d needs libusb; scikit-sparse's CHOLMOD builds against libsuitesparse-dev; the browser tests need
# Chromium; docker-compose checks the compose file), the Python package with its service, test, reproduce,
# bench (pyFM, to compare baselines) and cholmod extras, and three.js for the web UI.
set -euo pipefail
cd "$(dirname "$0")/.."

missing=()
dpkg -s libusb-1.0-0 >/dev/null 2>&1 || missing+=(libusb-1.0-0)
dpkg -s libsuitesparse-dev >/dev/null 2>&1 || missing+=(libsuitesparse-dev)
[ -n "${CURVEFM_SKIP_BROWSER:-}" ] || command -v chromium >/dev/null || missing+=(chromium)
command -v docker-compose >/dev/null || missing+=(docker-compose)
command -v redis-server >/dev/null || missing+=(redis-server)
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing system packages: ${missing[*]}"
  if [ "$(id -u)" = 0 ]; then SUDO=""; else SUDO="sudo"; fi
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${missing[@]}" >/dev/null
fi

python3 -m pip install -q --disable-pip-version-check -e ".[service,test,reproduce,bench,cholmod]"
if [ -f package.json ]; then
  npm install --ignore-scripts --no-audit --no-fund --silent  # no install scripts: the UI needs none
fi
