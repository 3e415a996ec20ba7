#!/usr/bin/env bash
# Sets up curvefm in a virtual environment, .venv/ in the checkout (never the system Python: stock Debian 12 and
# Ubuntu 24.04 refuse that, PEP 668). `scripts/setup.sh demo` installs what the service and its web UI need;
# `scripts/setup.sh test` (the default) adds what the tests, lint, type and docs checks need.
#
# Debian packages, installed when missing (with sudo unless root):
#   both:  python3 (3.11+), python3-venv and python3-dev, nodejs and npm (three.js for the UI comes from the npm
#          registry), libusb-1.0-0, libgomp1, libgl1 and libegl1 (open3d-cpu 0.20 loads them at import time; a
#          stock Debian has none of them)
#   test:  build-essential and libsuitesparse-dev (scikit-sparse's CHOLMOD builds against it), chromium (the
#          browser tests), redis-server and postgresql (real services for the tests), docker-compose (checks the
#          compose file), podman (copies the image's build context, tests/deploy/test_image_sources.py), and for
#          the deployment test (scripts/test-deploy.sh) podman-compose, runc, netavark, aardvark-dns, debootstrap
#          and iptables (netavark sets up the containers' network with it; Debian only recommends it)
set -euo pipefail
cd "$(dirname "$0")/.."
purpose="${1:-test}"
case "$purpose" in demo|test) ;; *) echo "usage: scripts/setup.sh [demo|test]" >&2; exit 2 ;; esac

# A Python from elsewhere (pyenv, a distribution's newer python3.x) with venv (and headers, for the tests' one C
# extension) works as well: then no python3 packages are installed.
python_ready() {
  command -v python3 >/dev/null && python3 - "$purpose" 2>/dev/null <<'PY'
import os, sys, sysconfig
import ensurepip, venv  # Debian ships ensurepip in python3-venv
assert sys.version_info >= (3, 11)
assert sys.argv[1] == "demo" or os.path.exists(os.path.join(sysconfig.get_paths()["include"], "Python.h"))
PY
}
packages=(libusb-1.0-0 libgomp1 libgl1 libegl1 ca-certificates)
python_ready || packages+=(python3 python3-venv python3-dev)
{ command -v node && command -v npm; } >/dev/null || packages+=(nodejs npm)
if [ "$purpose" = test ]; then
  packages+=(build-essential libsuitesparse-dev chromium redis-server postgresql docker-compose podman git
    podman-compose runc netavark aardvark-dns debootstrap iptables)
fi
missing=()
for package in "${packages[@]}"; do
  # installed, not merely known to dpkg (a removed package keeps its configuration and a status)
  [ "$(dpkg-query -W -f='${db:Status-Status}' "$package" 2>/dev/null)" = installed ] || missing+=("$package")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing Debian packages: ${missing[*]}"
  SUDO=""
  if [ "$(id -u)" != 0 ]; then
    command -v sudo >/dev/null || { echo "setup: as root, run: apt-get install ${missing[*]}; then run this again" >&2; exit 1; }
    SUDO="sudo"
  fi
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

if [ ! -x .venv/bin/python ]; then
  echo "setup: creating the virtual environment .venv (activate it with: source .venv/bin/activate)"
  python3 -m venv .venv
fi
.venv/bin/python -c 'import sys; assert sys.version_info >= (3, 11)' 2>/dev/null || {
  echo "setup: .venv has $(.venv/bin/python -V 2>&1), curvefm needs Python 3.11 or newer: remove .venv, put a" \
    "python3 >= 3.11 first on PATH (pyenv, or your distribution's python3.11) and run this again" >&2
  exit 1
}
echo "setup: installing curvefm and its Python packages into .venv (a few minutes the first time)"
extras="service"
[ "$purpose" = test ] && extras="service,test"
.venv/bin/python -m pip install -q --disable-pip-version-check --upgrade pip
.venv/bin/python -m pip install -q --disable-pip-version-check -e ".[$extras]"
if [ "$purpose" = demo ]; then
  npm ci --omit=dev --ignore-scripts --no-audit --no-fund --silent  # three.js, Swagger UI, ReDoc; no install scripts
else
  npm ci --ignore-scripts --no-audit --no-fund --silent  # and eslint
fi
# open3d reads and writes PLY, OFF and STL: a shared library it lacks only shows when a shape is loaded, so say it now
.venv/bin/python -c 'import open3d' >/dev/null 2>&1 || {
  echo "setup: open3d does not load; install the Debian package that has the library it names:" >&2
  .venv/bin/python -c 'import open3d' 2>&1 | tail -1 >&2
  exit 1
}
echo "setup: done; the command line is .venv/bin/curvefm"
