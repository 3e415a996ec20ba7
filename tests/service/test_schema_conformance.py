"""The published OpenAPI schema is the truth: schemathesis with ``--checks all`` (status codes, content types,
response bodies and headers, ``Allow`` on 405, schema-valid requests accepted and invalid ones rejected) finds
nothing against a real server with Redis and a worker, seeded with a real shape, session, curve, finished job,
result file and collection with a member. Three runs: the project's own seed with a few hundred cases, another
seed, and a third against a server whose rate limit answers most of its cases 429 (documented on every operation);
each is bounded by its count of examples, and repeatable."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest

from curvefm.access import users_of

SEED = 20261122
MAX_EXAMPLES = 20
"""Cases per operation and phase; about 500 cases in all."""
FEW_EXAMPLES = 5
REQUEST_TIMEOUT_S = 600
"""Schemathesis's default of 10 s per request, which a loaded machine's slowest requests missed (an error)."""
K = 30
RATE_LIMITED = ("--rate-limit", "1", "--rate-burst", "20")
"""A rate that a run passes after its first cases, whatever the machine's speed (a case takes far less than 1 s)."""
RUNS = {
    "own-seed": (SEED, MAX_EXAMPLES, ()),
    "another-seed": (1, FEW_EXAMPLES, ()),
    "rate-limited": (2, FEW_EXAMPLES, RATE_LIMITED),
}


SCHEMA_VALID_BUT_REFUSED = {
    "POST /shapes": "whether a file is a mesh is not a JSON schema's to say",
    "GET /sessions/{session_id}/suggestion": "moved ends given on one shape only (source and target go together)",
    "PUT /collections/{collection_id}/members/{member_id}/truth": "whether a file is a ground truth of the member's "
    "shapes (a row per template vertex, ids the member has)",
    "POST /sessions/{session_id}/refine": "converter parameters that contradict each other (k_final < k_init)",
    "POST /collections/{collection_id}/runs": "converter parameters that contradict each other (k_final < k_init)",
    "POST /collections/{collection_id}/members/upload": "a multipart body with no file, or a file that is no mesh",
    "POST /sessions/{session_id}/markups": "whether a file is Slicer markups on the session's shapes",
    "GET /sessions/{session_id}/exports/{export}": "'refinement' with a map export, or landmarks of no curves",
    "POST /collections/{collection_id}/webhooks": "a URL that is not http(s) with a host, or names an internal address",
    "GET /collections/{collection_id}/exports/{export}": "landmarks of members that lack template curves, or "
    "pseudo-landmarks without a run",
}
"""Operations that may answer 400 to a request the schema accepts, and why (their 400 says so too)."""

ACCEPTED = ["2xx", "404", "409", "413"]
"""What may answer a request the schema accepts: success, an id or state the stored data lacks, or a limit the
operator configured (413 names it and its setting)."""

CHECKS = """
[checks.positive_data_acceptance]
expected-statuses = {statuses}
"""

OPERATIONS = """
[[operations]]
include-name = "{name}"
checks.positive_data_acceptance.expected-statuses = {statuses}
"""

CURVE_OPERATIONS = """
# The seeded curve id belongs to the seeded session: a session the stateful phase creates has no curve c1, and
# schemathesis would take the configured id for one the new session handed out ("created resource not found").
[[operations]]
include-path-regex = "/curves/"
phases.stateful.enabled = false
"""


EVENT_STREAM = """
# An event stream answers for as long as the client listens (tests/service/test_live_sessions.py reads it).
[[operations]]
include-path-regex = "/events$"
enabled = false
"""


NEW_TOKEN = """
# A new token for its caller ends the token the run sends (tests/access/test_single_sign_on.py covers the route).
[[operations]]
include-name = "POST /auth/token"
enabled = false
"""


def schemathesis_config(api, session_id: str, job: dict, rate_limited: bool) -> str:
    """``schemathesis.toml``: the ids of real resources for the path parameters, so that the cases reach the
    routes' logic instead of their 404s; a rate-limited server may answer any case 429."""
    record = api.client.get(f"/sessions/{session_id}").raise_for_status().json()
    (collection,) = api.client.get("/collections").raise_for_status().json()
    parameters = {
        "path.shape_id": record["source"],
        "path.session_id": session_id,
        "path.collection_id": collection["id"],
        "path.member_id": "m1",
        "path.curve_id": record["curves"][0]["id"],
        "path.job_id": job["id"],
        "path.name": "map_target_to_source.txt",
    }
    assert parameters["path.name"] in job["links"], job["links"]
    lines = "".join(f"{json.dumps(key)} = {json.dumps(value)}\n" for key, value in parameters.items())
    accepted = [*ACCEPTED, "429"] if rate_limited else ACCEPTED
    statuses = json.dumps([*accepted, "400"])
    refused = "".join(OPERATIONS.format(name=name, statuses=statuses) for name in SCHEMA_VALID_BUT_REFUSED)
    checks = CHECKS.format(statuses=json.dumps(accepted))
    return f"[parameters]\n{lines}{checks}{refused}{CURVE_OPERATIONS}{EVENT_STREAM}{NEW_TOKEN}"


def schemathesis_command(
    url: str,
    config: Path,
    report: Path,
    token: str | None = None,
    seed: int = SEED,
    examples: int = MAX_EXAMPLES,
) -> list[str]:
    command = [sys.executable, "-m", "schemathesis.cli", "--config-file", str(config), "--no-color", "run"]
    command += [f"{url}/openapi.json", "--checks", "all", "-n", str(examples), "--seed", str(seed)]
    command += ["--workers", "1", "--generation-database", "none", "--suppress-health-check", "all"]
    # `--checks all` also fails a response slower than 10 s, which a loaded CI machine can miss: the cases test the
    # schema, so a slow answer fails only where the request itself times out.
    command += ["--request-timeout", str(REQUEST_TIMEOUT_S), "--max-response-time", str(REQUEST_TIMEOUT_S)]
    command += ["--report", "ndjson", "--report-ndjson-path", str(report)]
    if token:
        command += ["-H", f"Authorization: Bearer {token}"]
    return command


UNLIMITED = {"CURVEFM_QUOTA_SESSIONS": "0", "CURVEFM_QUOTA_JOBS": "0", "CURVEFM_QUOTA_BYTES": "0"}
"""Quotas off (and the rate limit, with ``--rate-limit 0``): the cases test the schema, not the limits."""


def seeded_server(processes, redis_url: str, redis_prefix: str, folder: Path):
    """An API and a worker on Redis, with the demo pair, a session with one curve and a finished refinement, and
    a collection made from the session (its member m1 answered); the API has an admin, whose token is
    ``api.token``."""
    token = users_of(folder / "data").add("schemathesis", admin=True)
    env = {"CURVEFM_QUEUE_PREFIX": redis_prefix, **UNLIMITED}
    api = processes.api(folder / "data", redis_url=redis_url, env=env, args=["--rate-limit", "0"])
    api.token = token
    processes.worker(redis_url, redis_prefix, "schema")
    _, session_id = api.demo_pair(folder, K)
    curve = {"source": [0, 100], "target": [0, 100]}
    api.client.post(f"/sessions/{session_id}/curves", json=curve).raise_for_status()
    job = api.client.post(f"/sessions/{session_id}/refine", json={}).raise_for_status().json()
    job = api.wait_job(job["id"])
    assert job["state"] == "finished", job
    source = api.client.get(f"/sessions/{session_id}").raise_for_status().json()["source"]
    api.client.post("/collections", json={"template": source, "from_session": session_id}).raise_for_status()
    return api, session_id, job


def response_statuses(report: Path) -> Counter:
    """The status of every response schemathesis recorded in its NDJSON report."""
    statuses = Counter()
    for line in report.read_text().splitlines():
        scenario = json.loads(line).get("ScenarioFinished")
        for recorded in (scenario or {}).get("recorder", {}).values():
            for entry in recorded.values() if isinstance(recorded, dict) else ():
                if isinstance(entry, dict) and "response" in entry:  # an interaction: a request and its response
                    statuses[(entry["response"] or {}).get("status_code")] += 1
    return statuses


@pytest.mark.parametrize(("seed", "examples", "limits"), RUNS.values(), ids=RUNS)
def test_schemathesis_finds_nothing(processes, redis_url, redis_prefix, tmp_path, seed, examples, limits):
    api, session_id, job = seeded_server(processes, redis_url, redis_prefix, tmp_path)
    if limits:  # another API process on the seeded records, with the limits (seeding at that rate would take long)
        env = {"CURVEFM_QUEUE_PREFIX": redis_prefix, **UNLIMITED}
        checked = processes.api(tmp_path / "data", redis_url=redis_url, env=env, args=list(limits))
    else:
        checked = api
    config = tmp_path / "schemathesis.toml"
    config.write_text(schemathesis_config(api, session_id, job, rate_limited=bool(limits)))
    report = tmp_path / "schemathesis.ndjson"
    run = subprocess.run(
        schemathesis_command(checked.url, config, report, api.token, seed, examples),
        capture_output=True,
        text=True,
        cwd=tmp_path,  # no wall-clock limit: the run is bounded by its number of examples
    )
    sections = [run.stdout.find(title) for title in ("=== ERRORS", "=== FAILURES")]
    summary = run.stdout[min([at for at in sections if at >= 0], default=-4000) :]
    assert run.returncode == 0, f"schemathesis found problems:\n{summary}\n{run.stderr[-2000:]}"
    generated, passed = map(int, re.search(r"(\d+) generated, (\d+) passed", run.stdout).groups())
    statuses = response_statuses(report)
    assert passed == generated == statuses.total() >= 15 * examples, (generated, passed, statuses)
    assert not [status for status in statuses if status is None or status >= 500], statuses
    successes = sum(count for status, count in statuses.items() if status < 300)
    if limits:
        assert statuses[429] >= statuses.total() / 2 and successes, statuses
    else:
        assert successes >= 5 * examples, statuses  # not all refused
    assert checked.client.get("/health").status_code == 200
