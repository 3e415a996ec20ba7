#!/usr/bin/env bash
# The deployment test (docs/operations.md, "The deployment test"): builds the image from this source tree and runs
# docker-compose.yml for real with podman and podman-compose, then tests/deploy/compose_topology.py drives it
# through the proxy only (log in, upload, session, curves, basis and refinement on the workers, a result file,
# restarts of one API replica and one worker in the middle).
#
# No registry of images is needed: a Debian 12 base is made with debootstrap and imported, and Redis, PostgreSQL,
# Caddy and Node.js images are built on it from Debian's packages (tests/deploy/images/). Everything podman keeps
# (base, images, build cache) lives in its own store under $CURVEFM_DEPLOY_CACHE (default
# ~/.cache/curvefm-deploy), never in the machine's podman store nor in the checkout; unchanged inputs reuse their
# cached layers, so a second run skips the builds. Needs root (rootful podman) and podman, podman-compose, runc,
# netavark, aardvark-dns and debootstrap (Debian packages). Without them it says what is missing and exits 0, or
# 1 when CI is set. CURVEFM_DEPLOY_KEEP=1 leaves the deployment running afterwards (podman-compose -p
# curvefm-deploytest down -v removes it); --build-only stops once the images are built.
set -euo pipefail
cd "$(dirname "$0")/.."
REPO=$PWD
CACHE=${CURVEFM_DEPLOY_CACHE:-$HOME/.cache/curvefm-deploy}
PROJECT=curvefm-deploytest
PORT=${CURVEFM_DEPLOY_PORT:-18000}
BASE=localhost/curvefm-deploy/debian:bookworm
started=$(date +%s)

say() { echo "test-deploy: $*" >&2; }
missing() {
  if [ -n "${CI:-}" ] && [ "${CI}" != 0 ] && [ "${CI,,}" != false ]; then
    say "FAILED: $* [CI is set: a missing requirement fails the deployment test]"
    exit 1
  fi
  say "skipped: $*"
  exit 0
}

[ "$(id -u)" = 0 ] || missing "rootful podman is needed: run as root"
for tool in podman podman-compose debootstrap runc netavark:/usr/lib/podman/netavark \
  aardvark-dns:/usr/lib/podman/aardvark-dns iptables; do
  name=${tool%%:*} path=${tool#*:}
  if [ "$name" = "$path" ]; then command -v "$name" >/dev/null && continue; else [ -x "$path" ] && continue; fi
  missing "$name is not installed (Debian: apt-get install podman podman-compose runc netavark aardvark-dns debootstrap iptables)"
done

# podman's own settings, in the cache: a private store; no default ulimits (podman's exceed the hard limits of
# some machines: "error setting rlimit"); runc (crun refuses hybrid cgroup v1/v2 hosts); netavark and
# aardvark-dns, so that containers find each other by service name
mkdir -p "$CACHE"
cat >"$CACHE/containers.conf" <<CONF
[containers]
default_ulimits = []
[network]
network_backend = "netavark"
[engine]
runtime = "runc"
events_logger = "file"
cgroup_manager = "cgroupfs"
CONF
cat >"$CACHE/storage.conf" <<CONF
[storage]
driver = "overlay"
graphroot = "$CACHE/storage"
runroot = "$CACHE/run"
CONF
export CONTAINERS_CONF=$CACHE/containers.conf CONTAINERS_STORAGE_CONF=$CACHE/storage.conf

# builds reach the package registries with the host's CA bundle (a proxy's certificate may be in it), mounted
# beside the image's own (where Debian's ca-certificates package, which npm pulls in, writes its bundle)
CA_BUNDLE=/etc/ssl/certs/ca-certificates.crt
[ -f "$CA_BUNDLE" ] || missing "the host's CA bundle $CA_BUNDLE is absent (Debian: apt-get install ca-certificates)"
printf '[global]\ncert = /run/host-ca.crt\n' >"$CACHE/pip.conf"
printf 'cafile=/run/host-ca.crt\n' >"$CACHE/npmrc"
BUILD_MOUNTS=(-v "$CA_BUNDLE:/run/host-ca.crt:ro" -v "$CACHE/pip.conf:/etc/pip.conf:ro" -v "$CACHE/npmrc:/root/.npmrc:ro")

base_image() {
  podman image exists "$BASE" && return
  say "making the Debian 12 base with debootstrap (about a minute, once)"
  local root
  root=$(mktemp -d "$CACHE/rootfs.XXXXXX")
  debootstrap --variant=minbase bookworm "$root" http://deb.debian.org/debian >"$CACHE/debootstrap.log" 2>&1 \
    || { say "FAILED: debootstrap (see $CACHE/debootstrap.log)"; exit 1; }
  tar -C "$root" -c . | podman import -q - "$BASE" >/dev/null
  rm -rf "$root"
}

build() {  # build IMAGE CONTEXT [podman build options]: the cached layers make an unchanged build take seconds
  local image=$1 context=$2
  shift 2
  say "building $image"
  podman build -q --pull=never --build-arg "BASE_IMAGE=$BASE" "${BUILD_MOUNTS[@]}" -t "$image" "$@" "$context" \
    >"$CACHE/build.log" 2>&1 || { tail -40 "$CACHE/build.log" >&2; say "FAILED: building $image"; exit 1; }
}

build_images() {
  base_image
  for name in node redis postgres caddy; do
    build "localhost/curvefm-deploy/$name:bookworm" "tests/deploy/images/$name"
  done
  build localhost/curvefm-deploy/curvefm:test "$REPO" --build-arg NODE_IMAGE=localhost/curvefm-deploy/node:bookworm
}

build_images
# what earlier builds of other sources left (untagged layers), once a day old: the store stays a few GB
podman image prune -f --filter until=24h >/dev/null
say "images ready after $(($(date +%s) - started)) s"
[ "${1:-}" = --build-only ] && exit 0

# The compose project in a folder of its own, as an operator sets it up: docker-compose.yml, the Caddyfile it
# mounts and a .env with fresh passwords (podman-compose reads .env beside the compose file, so a developer's own
# .env in the checkout is never used), the local images in place of the public ones.
project_dir=$(mktemp -d "${TMPDIR:-/tmp}/curvefm-deploy.XXXXXX")
mkdir "$project_dir/deploy"
cp docker-compose.yml "$project_dir/"
cp deploy/Caddyfile "$project_dir/deploy/"
REDIS_PASSWORD=$(od -An -N16 -tx1 /dev/urandom | tr -d ' \n')
cat >"$project_dir/.env" <<ENV
CURVEFM_REDIS_PASSWORD=$REDIS_PASSWORD
CURVEFM_POSTGRES_PASSWORD=$(od -An -N16 -tx1 /dev/urandom | tr -d ' \n')
CURVEFM_PORT=$PORT
CURVEFM_IMAGE=localhost/curvefm-deploy/curvefm:test
CURVEFM_POSTGRES_IMAGE=localhost/curvefm-deploy/postgres:bookworm
CURVEFM_REDIS_IMAGE=localhost/curvefm-deploy/redis:bookworm
CURVEFM_CADDY_IMAGE=localhost/curvefm-deploy/caddy:bookworm
ENV
compose() { podman-compose --no-ansi -p "$PROJECT" -f "$project_dir/docker-compose.yml" "$@"; }
down() { compose down -v >"$CACHE/down.log" 2>&1 || true; }
finish() {
  local status=$?
  if [ $status != 0 ]; then
    say "logs of the deployment (last 30 lines each):"
    for name in $(podman ps -a --filter "label=io.podman.compose.project=$PROJECT" --format '{{.Names}}'); do
      echo "----- $name" >&2
      podman logs --tail 30 "$name" 2>&1 | sed 's/token=[A-Za-z0-9_-]*/token=.../' >&2
    done
  fi
  if [ -n "${CURVEFM_DEPLOY_KEEP:-}" ]; then say "left running: $project_dir"; else down; rm -rf "$project_dir"; fi
  say "$([ $status = 0 ] && echo passed || echo FAILED) in $(($(date +%s) - started)) s"
}
trap finish EXIT
down  # what a run that was killed may have left

# podman runs healthchecks from systemd timers, which this machine may lack: run each container's own check
# (the compose file's healthcheck) until it passes, then wait for the proxy
healthy() {
  local name=$1 deadline=$(($(date +%s) + 180))
  until podman healthcheck run "$name" >/dev/null 2>&1; do
    [ "$(date +%s)" -lt "$deadline" ] || { say "FAILED: $name is not healthy after 180 s"; exit 1; }
    sleep 2
  done
}
wait_until_up() {
  for service in postgres redis api api-2; do healthy "${PROJECT}_${service}_1"; done
  local deadline=$(($(date +%s) + 60))
  until curl -fsS "http://127.0.0.1:$PORT/health" >/dev/null 2>&1; do
    [ "$(date +%s)" -lt "$deadline" ] || { say "FAILED: the proxy does not answer /health after 60 s"; exit 1; }
    sleep 1
  done
}
up() {
  compose up -d >"$CACHE/up.log" 2>&1 || { tail -30 "$CACHE/up.log" >&2; say "FAILED: podman-compose up"; exit 1; }
  wait_until_up
}

say "starting the compose project $PROJECT (proxy on 127.0.0.1:$PORT)"
up
say "deployment up after $(($(date +%s) - started)) s"

# the login URL that the API replica which made the admin printed
TOKEN=$(podman logs "${PROJECT}_api_1" "${PROJECT}_api-2_1" 2>&1 | grep -o '/?token=[A-Za-z0-9_-]*' |
  grep -v YOUR_TOKEN | head -1 | cut -d= -f2)
[ -n "$TOKEN" ] || { say "FAILED: neither API replica printed a login URL"; exit 1; }

CURVEFM_DEPLOY_URL="http://127.0.0.1:$PORT" CURVEFM_DEPLOY_TOKEN=$TOKEN CURVEFM_DEPLOY_PROJECT=$PROJECT \
  CURVEFM_DEPLOY_IMAGE=localhost/curvefm-deploy/curvefm:test CURVEFM_DEPLOY_REDIS_PASSWORD=$REDIS_PASSWORD \
  PYTHONPATH="$REPO/src${PYTHONPATH:+:$PYTHONPATH}" .venv/bin/python -m pytest -q -p no:cacheprovider \
  tests/deploy/compose_topology.py

# Backup and restore as docs/operations.md says, with podman itself where a command's output is piped
# (podman-compose 1.0.3 prints the commands it runs on stdout): back up, wipe the deployment with its volumes,
# start it afresh, restore; the sessions are back as they were, the token from before still logs in, and a map
# needs the restored bases
say "backup, wipe, restore"
get() { curl -fsS -H "Authorization: Bearer $TOKEN" "http://127.0.0.1:$PORT$1"; }
WRITERS=("${PROJECT}_api_1" "${PROJECT}_api-2_1" "${PROJECT}_worker-basis_1" "${PROJECT}_worker-refine_1")
before=$(get /sessions)
podman exec -i "${PROJECT}_postgres_1" pg_dump -U curvefm -Fc curvefm >"$project_dir/curvefm.dump"
podman exec -i "${PROJECT}_api_1" tar -C /data -cz . >"$project_dir/curvefm-data.tar.gz"
down
up
podman stop -t 10 "${WRITERS[@]}" >/dev/null
podman run --rm -i -v "${PROJECT}_data:/data" localhost/curvefm-deploy/curvefm:test tar -C /data -xz \
  <"$project_dir/curvefm-data.tar.gz"
podman exec -i "${PROJECT}_postgres_1" pg_restore -U curvefm -d curvefm --clean --if-exists <"$project_dir/curvefm.dump"
podman start "${WRITERS[@]}" >/dev/null
wait_until_up
after=$(get /sessions) || { say "FAILED: the token from before the backup does not log in after the restore"; exit 1; }
[ "$after" = "$before" ] || { say "FAILED: after backup, wipe and restore the sessions are $after, not $before"; exit 1; }
session=$(printf '%s' "$after" | .venv/bin/python -c 'import json, sys; print(json.load(sys.stdin)[0]["id"])')
get "/sessions/$session/map" >/dev/null || { say "FAILED: the restored session has no map"; exit 1; }
