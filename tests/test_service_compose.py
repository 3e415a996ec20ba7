"""docker-compose.yml is valid for Debian's docker-compose 1.29, runs the commands the other tests run, gives
Redis a password from the env file that the API and the workers connect with, and publishes the API on the
host's loopback only."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest
import yaml
from conftest import unavailable

REPO = Path(__file__).resolve().parents[1]
PASSWORD = "0123456789abcdef0123456789abcdef"


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
    """The resolved services, with .env.example copied and its password filled in (as the README says)."""
    example = (REPO / ".env.example").read_text()
    assert "\nCURVEFM_REDIS_PASSWORD=\n" in example, "the example must leave the password to the admin"
    env_file = tmp_path / ".env"
    env_file.write_text(example.replace("\nCURVEFM_REDIS_PASSWORD=\n", f"\nCURVEFM_REDIS_PASSWORD={PASSWORD}\n"))
    result = compose_config(env_file)
    assert result.returncode == 0, result.stderr
    assert "WARNING" not in result.stderr, result.stderr
    return yaml.safe_load(result.stdout)["services"]


API_REPLICAS = ("api", "api-2")


def test_compose_file_is_valid_and_runs_the_tested_commands(services, processes):
    for name in API_REPLICAS:
        assert services[name]["command"][:3] == processes.api_command
    assert services["worker"]["command"][:3] == processes.worker_command
    for name in (*API_REPLICAS, "worker"):
        assert "data:/data:rw" in services[name]["volumes"]
    assert "ports" not in services["worker"] and "container_name" not in services["worker"]  # --scale works


def test_redis_needs_the_password_from_the_env_file_and_the_api_and_workers_use_it(services):
    redis = services["redis"]
    assert redis["command"][redis["command"].index("--requirepass") + 1] == PASSWORD
    assert PASSWORD in redis["healthcheck"]["test"]
    assert "ports" not in redis
    assert redis["command"][redis["command"].index("--appendonly") + 1] == "yes"  # issue 12: jobs survive restarts
    assert "redis-data:/data:rw" in redis["volumes"]
    for name in (*API_REPLICAS, "worker"):
        assert services[name]["environment"]["CURVEFM_REDIS_URL"] == f"redis://:{PASSWORD}@redis:6379/0"


def test_the_env_file_is_ignored_by_git_and_its_example_is_not():
    checks = [subprocess.run(["git", "check-ignore", "-q", name], cwd=REPO) for name in (".env", ".env.example")]
    assert [check.returncode for check in checks] == [0, 1]


def test_without_a_password_compose_refuses_to_run_and_says_which_setting(tmp_path):
    (tmp_path / ".env").write_text((REPO / ".env.example").read_text())
    result = compose_config(tmp_path / ".env")
    assert result.returncode != 0
    assert "CURVEFM_REDIS_PASSWORD must be set" in result.stderr, result.stderr


def test_two_api_replicas_are_reached_only_through_the_proxy_on_the_loopback_address(services):
    assert services["proxy"]["ports"] == ["127.0.0.1:8000:8000/tcp"]
    command = services["proxy"]["command"]
    assert [command[i + 1] for i, word in enumerate(command) if word == "--to"] == ["api:8000", "api-2:8000"]
    assert all("ports" not in services[name] for name in API_REPLICAS)
    assert services["api"]["environment"] == services["api-2"]["environment"]


def test_allowed_hosts_and_limits_in_the_env_file_reach_the_api(services, tmp_path):
    assert services["api"]["environment"]["CURVEFM_ALLOWED_HOSTS"] == ""  # the example keeps the defaults
    env_file = tmp_path / "limits.env"
    env_file.write_text(
        f"CURVEFM_REDIS_PASSWORD={PASSWORD}\nCURVEFM_ALLOWED_HOSTS=curvefm.lab.example.org\nCURVEFM_RATE_LIMIT=5\n"
    )
    result = compose_config(env_file)
    assert result.returncode == 0, result.stderr
    for name in API_REPLICAS:
        environment = yaml.safe_load(result.stdout)["services"][name]["environment"]
        assert environment["CURVEFM_ALLOWED_HOSTS"] == "curvefm.lab.example.org"
        assert environment["CURVEFM_RATE_LIMIT"] == "5"
