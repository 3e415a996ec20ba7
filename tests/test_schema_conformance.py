"""The published OpenAPI schema is the truth: schemathesis with ``--checks all`` (status codes, content types,
response bodies and headers, ``Allow`` on 405, schema-valid requests accepted and invalid ones rejected) finds
nothing against a real server with Redis and a worker, seeded with a real shape, session, curve, finished job
and result file. A fixed seed and a few hundred cases keep it short and repeatable."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from collections import Counter
from pathlib import Path

from curvefm.access import UserStore

SEED = 20261122
MAX_EXAMPLES = 20
"""Cases per operation and phase; about 500 cases in all."""
K = 30


SCHEMA_VALID_BUT_REFUSED = {
    "POST /shapes": "whether a file is a mesh is not a JSON schema's to say",
    "POST /sessions/{session_id}/refine": "converter parameters that contradict each other (k_final < k_init)",
    "POST /collections/{collection_id}/runs": "converter parameters that contradict each other (k_final < k_init)",
    "POST /collections/{collection_id}/members/upload": "a multipart body with no file, or a file that is no mesh",
}
"""Operations that may answer 400 to a request the schema accepts, and why (their 400 says so too)."""

ACCEPTED = ["2xx", "404", "409", "413"]
"""What may answer a request the schema accepts: success, an id or state the stored data lacks, or a limit the
operator configured (413 names it and its setting)."""

CHECKS = f"""
[checks.positive_data_acceptance]
expected-statuses = {json.dumps(ACCEPTED)}
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


def schemathesis_config(api, session_id: str, job: dict) -> str:
    """``schemathesis.toml``: the ids of real resources for the path parameters, so that the cases reach the
    routes' logic instead of their 404s."""
    record = api.client.get(f"/sessions/{session_id}").raise_for_status().json()
    parameters = {
        "path.shape_id": record["source"],
        "path.session_id": session_id,
        "path.curve_id": record["curves"][0]["id"],
        "path.job_id": job["id"],
        "path.name": "map_target_to_source.txt",
    }
    assert parameters["path.name"] in job["links"], job["links"]
    lines = "".join(f"{json.dumps(key)} = {json.dumps(value)}\n" for key, value in parameters.items())
    statuses = json.dumps([*ACCEPTED, "400"])
    refused = "".join(OPERATIONS.format(name=name, statuses=statuses) for name in SCHEMA_VALID_BUT_REFUSED)
    return f"[parameters]\n{lines}{CHECKS}{refused}{CURVE_OPERATIONS}"


def schemathesis_command(url: str, config: Path, report: Path, token: str | None = None) -> list[str]:
    command = [sys.executable, "-m", "schemathesis.cli", "--config-file", str(config), "--no-color", "run"]
    command += [f"{url}/openapi.json", "--checks", "all", "-n", str(MAX_EXAMPLES), "--seed", str(SEED)]
    command += ["--workers", "1", "--generation-database", "none", "--suppress-health-check", "all"]
    command += ["--report", "ndjson", "--report-ndjson-path", str(report)]
    if token:
        command += ["-H", f"Authorization: Bearer {token}"]
    return command


UNLIMITED = {"CURVEFM_QUOTA_SESSIONS": "0", "CURVEFM_QUOTA_JOBS": "0", "CURVEFM_QUOTA_BYTES": "0"}
"""Quotas off (and the rate limit, with ``--rate-limit 0``): the cases test the schema, not the limits."""


def seeded_server(processes, redis_url: str, redis_prefix: str, folder: Path):
    """An API and a worker on Redis, with the demo pair, a session with one curve and a finished refinement;
    the API has an admin, whose token is ``api.token``."""
    token = UserStore(folder / "data").add("schemathesis", admin=True)
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


def test_schemathesis_finds_nothing(processes, redis_url, redis_prefix, tmp_path):
    api, session_id, job = seeded_server(processes, redis_url, redis_prefix, tmp_path)
    config = tmp_path / "schemathesis.toml"
    config.write_text(schemathesis_config(api, session_id, job))
    report = tmp_path / "schemathesis.ndjson"
    run = subprocess.run(
        schemathesis_command(api.url, config, report, api.token),
        capture_output=True,
        text=True,
        timeout=300,
        cwd=tmp_path,
    )
    summary = run.stdout[run.stdout.find("=== FAILURES") :] or run.stdout[-4000:]
    assert run.returncode == 0, f"schemathesis found problems:\n{summary}\n{run.stderr[-2000:]}"
    generated, passed = map(int, re.search(r"(\d+) generated, (\d+) passed", run.stdout).groups())
    statuses = response_statuses(report)
    assert passed == generated == statuses.total() >= 300, (generated, passed, statuses)
    assert not [status for status in statuses if status is None or status >= 500], statuses
    assert sum(count for status, count in statuses.items() if status < 300) >= 100, statuses  # not all refused
    assert api.client.get("/health").status_code == 200
