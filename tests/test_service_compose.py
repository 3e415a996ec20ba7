"""docker-compose.yml is valid for Debian's docker-compose 1.29 and runs the commands the other tests run."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import yaml
from conftest import unavailable

REPO = Path(__file__).resolve().parents[1]


def test_compose_file_is_valid_and_runs_the_tested_commands(processes):
    binary = shutil.which("docker-compose")
    if binary is None:
        unavailable("docker-compose is not installed (scripts/setup.sh installs Debian's)")
    result = subprocess.run(
        [binary, "-f", str(REPO / "docker-compose.yml"), "config"], capture_output=True, text=True, cwd=REPO
    )
    assert result.returncode == 0, result.stderr
    assert "WARNING" not in result.stderr, result.stderr

    services = yaml.safe_load(result.stdout)["services"]
    assert services["api"]["command"][:3] == processes.api_command
    assert services["worker"]["command"][:3] == processes.worker_command
    for name in ("api", "worker"):
        assert "data:/data:rw" in services[name]["volumes"]
        assert services[name]["environment"]["CURVEFM_REDIS_URL"].startswith("redis://redis:")
    assert "ports" not in services["worker"] and "container_name" not in services["worker"]  # --scale works
