"""docker-compose.yml is valid for Debian's docker-compose 1.29, runs the commands the other tests run, gives
Redis and PostgreSQL passwords from the env file that the API and the workers connect with, runs a worker per
queue, and publishes the API on the host's loopback only. scripts/test-deploy.sh runs the file for real."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest
import yaml
from support.ci import unavailable
from support.paths import REPO

PASSWORD = "0123456789abcdef0123456789abcdef"
POSTGRES_PASSWORD = "fedcba9876543210fedcba9876543210"
PASSWORDS = f"CURVEFM_REDIS_PASSWORD={PASSWORD}\nCURVEFM_POSTGRES_PASSWORD={POSTGRES_PASSWORD}\n"


def compose_config(env_file: Path | None) -> subprocess.CompletedProcess:
    binary = shutil.which("docker-compose")
    if binary is None:
        unavailable("docker-compose is not installed (scripts/setup.sh installs Debian's)")
    env = {k: v for k, v in os.environ.items() if not k.startswith("CURVEFM_")}  # only the env file counts
    options = ["--env-file", str(env_file)] if env_file else []
    command = [binary, *options, "-f", str(REPO / "docker-compose.yml"), "config"]
    return subprocess.run(command, capture_output=True, text=True, cwd=env_file.parent if env_file else REPO, env=env)


@pytest.fixture
def services(tmp_path) -> dict:
    """The resolved services, with .env.example copied and its passwords filled in (as the README says)."""
    example = (REPO / ".env.example").read_text()
    for name, value in (("CURVEFM_REDIS_PASSWORD", PASSWORD), ("CURVEFM_POSTGRES_PASSWORD", POSTGRES_PASSWORD)):
        assert f"\n{name}=\n" in example, f"the example must leave {name} to the admin"
        example = example.replace(f"\n{name}=\n", f"\n{name}={value}\n")
    env_file = tmp_path / ".env"
    env_file.write_text(example)
    result = compose_config(env_file)
    assert result.returncode == 0, result.stderr
    assert "WARNING" not in result.stderr, result.stderr
    return yaml.safe_load(result.stdout)["services"]


API_REPLICAS = ("api", "api-2")
WORKERS = {"worker-basis": ["curvefm-basis"], "worker-refine": ["curvefm-refine"]}
CURVEFM_SERVICES = (*API_REPLICAS, *WORKERS)


def test_compose_file_is_valid_and_runs_the_tested_commands(services, processes):
    for name in API_REPLICAS:
        assert services[name]["command"][:3] == processes.api_command
    for name, queues in WORKERS.items():
        assert services[name]["command"] == [*processes.worker_command, "--queues", *queues]
        assert "ports" not in services[name] and "container_name" not in services[name]  # --scale works
    for name in CURVEFM_SERVICES:
        assert "data:/data:rw" in services[name]["volumes"]


def test_a_worker_serves_each_queue_of_the_project_and_no_other(services):
    from curvefm.workers.rq_queue import queue_names

    served = sorted(queue for queues in WORKERS.values() for queue in queues)
    assert served == sorted(queue_names().values())


def test_redis_needs_the_password_from_the_env_file_and_the_api_and_workers_use_it(services):
    redis = services["redis"]
    assert redis["command"][redis["command"].index("--requirepass") + 1] == PASSWORD
    assert PASSWORD in redis["healthcheck"]["test"]
    assert "ports" not in redis
    assert redis["command"][redis["command"].index("--appendonly") + 1] == "yes"  # issue 12: jobs survive restarts
    # a full Redis refuses writes instead of evicting the keys of queued jobs (issue 32)
    assert redis["command"][redis["command"].index("--maxmemory-policy") + 1] == "noeviction"
    assert "redis-data:/data:rw" in redis["volumes"]
    for name in CURVEFM_SERVICES:
        assert services[name]["environment"]["CURVEFM_REDIS_URL"] == f"redis://:{PASSWORD}@redis:6379/0"


def test_the_records_are_in_postgresql_with_the_password_from_the_env_file(services):
    postgres = services["postgres"]
    assert postgres["environment"]["POSTGRES_PASSWORD"] == POSTGRES_PASSWORD
    assert "postgres-data:/var/lib/postgresql/data:rw" in postgres["volumes"] and "ports" not in postgres
    url = f"postgresql+psycopg://curvefm:{POSTGRES_PASSWORD}@postgres:5432/curvefm"
    for name in CURVEFM_SERVICES:
        assert services[name]["environment"]["CURVEFM_DATABASE_URL"] == url


def test_the_env_file_is_ignored_by_git_and_its_example_is_not():
    checks = [subprocess.run(["git", "check-ignore", "-q", name], cwd=REPO) for name in (".env", ".env.example")]
    assert [check.returncode for check in checks] == [0, 1]


@pytest.mark.parametrize("given", ["CURVEFM_REDIS_PASSWORD", "CURVEFM_POSTGRES_PASSWORD"])
def test_without_a_password_compose_refuses_to_run_and_says_which_setting(tmp_path, given):
    example = (REPO / ".env.example").read_text()
    (tmp_path / ".env").write_text(example.replace(f"\n{given}=\n", f"\n{given}={PASSWORD}\n"))
    result = compose_config(tmp_path / ".env")
    assert result.returncode != 0
    (missing,) = {"CURVEFM_REDIS_PASSWORD", "CURVEFM_POSTGRES_PASSWORD"} - {given}
    assert f"{missing} must be set" in result.stderr, result.stderr


def test_the_public_images_are_the_defaults_and_the_env_file_replaces_them(services, tmp_path):
    assert services["redis"]["image"] == "redis:7-alpine" and services["proxy"]["image"] == "caddy:2-alpine"
    assert services["postgres"]["image"].startswith("postgres:") and services["api"]["image"] == "curvefm:latest"
    env_file = tmp_path / "images.env"
    env_file.write_text(PASSWORDS + "CURVEFM_REDIS_IMAGE=localhost/redis:mine\nCURVEFM_IMAGE=localhost/curvefm:1\n")
    result = compose_config(env_file)
    assert result.returncode == 0, result.stderr
    resolved = yaml.safe_load(result.stdout)["services"]
    assert resolved["redis"]["image"] == "localhost/redis:mine"
    assert {resolved[name]["image"] for name in CURVEFM_SERVICES} == {"localhost/curvefm:1"}


def test_two_api_replicas_are_reached_only_through_the_proxy_on_the_loopback_address(services):
    assert services["proxy"]["ports"] == ["127.0.0.1:8000:8000/tcp"]
    assert "./deploy/Caddyfile:/etc/caddy/Caddyfile:ro" in [
        volume.replace(str(REPO), ".") for volume in services["proxy"]["volumes"]
    ]
    caddyfile = (REPO / "deploy/Caddyfile").read_text()
    assert "reverse_proxy api:8000 api-2:8000 {" in caddyfile and "lb_try_duration" in caddyfile
    assert all("ports" not in services[name] for name in API_REPLICAS)
    assert services["api"]["environment"] == services["api-2"]["environment"]


def test_allowed_hosts_and_limits_in_the_env_file_reach_the_api(services, tmp_path):
    assert services["api"]["environment"]["CURVEFM_ALLOWED_HOSTS"] == ""  # the example keeps the defaults
    env_file = tmp_path / "limits.env"
    env_file.write_text(PASSWORDS + "CURVEFM_ALLOWED_HOSTS=curvefm.lab.example.org\nCURVEFM_RATE_LIMIT=5\n")
    result = compose_config(env_file)
    assert result.returncode == 0, result.stderr
    for name in API_REPLICAS:
        environment = yaml.safe_load(result.stdout)["services"][name]["environment"]
        assert environment["CURVEFM_ALLOWED_HOSTS"] == "curvefm.lab.example.org"
        assert environment["CURVEFM_RATE_LIMIT"] == "5"
