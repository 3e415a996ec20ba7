"""Plugins through entry points: built-ins listed, a third-party package installed and used, bad names, a
plugin registered under the wrong kind."""

import json
import os
import subprocess
import sys
import textwrap

import pytest

from curvefm import registry
from curvefm.errors import CurvefmError

THIRD_PARTY_PLUGIN = """
import numpy as np
from pydantic import BaseModel, ConfigDict

from curvefm.geometry import shortest_path
from curvefm.registry import TracerPlugin


class Params(BaseModel):
    model_config = ConfigDict(extra="forbid")
    hops: int = 1


def trace(mesh, start, end, params):
    return shortest_path(mesh.edge_graph, start, end)


HOPS = TracerPlugin(name="hops", description="a lab member's tracer", Params=Params, run=trace)
"""

PYPROJECT = """
[build-system]
requires = ["setuptools"]
build-backend = "setuptools.build_meta"

[project]
name = "{name}"
version = "0.1"

[project.entry-points."curvefm.tracers"]
{entry_point}
"""


def pip_install(tmp_path, name: str, entry_point: str, module: str = "") -> dict:
    """Install the distribution ``name`` (with ``module`` as its one module, named after it, if given) that
    registers ``entry_point`` (a line ``name = "module:object"``) under ``curvefm.tracers``; returns the
    environment in which a subprocess sees it."""
    package = tmp_path / name
    package.mkdir()
    (package / "pyproject.toml").write_text(PYPROJECT.format(name=name, entry_point=entry_point))
    if module:
        (package / f"{name.replace('-', '_')}.py").write_text(module)
    site = tmp_path / f"{name}-site"
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "install",
            "-q",
            "--no-deps",
            "--no-build-isolation",
            "--target",
            str(site),
            str(package),
        ],
        check=True,
        capture_output=True,
    )
    return {**os.environ, "PYTHONPATH": str(site)}


def test_builtin_plugins_are_registered():
    assert {"geodesic", "anisotropic"} <= set(registry.names("tracer"))
    assert "laplace-beltrami" in registry.names("basis")
    assert "nearest-neighbor" in registry.names("converter")
    described = registry.describe_all()
    lb = next(p for p in described["basis"] if p["name"] == "laplace-beltrami")
    assert "laplacian" in lb["parameters"]["properties"]
    assert lb["parameters"]["properties"]["method"]["enum"] == ["auto", "exact", "multires"]


def test_unknown_plugins_and_parameters_are_named():
    with pytest.raises(CurvefmError, match="unknown tracer 'nope'; installed tracers: .*geodesic"):
        registry.get("tracer", "nope")
    with pytest.raises(CurvefmError, match="bad parameters for 'laplace-beltrami': laplacian"):
        registry.get("basis", "laplace-beltrami").parse_params({"laplacian": "magic"})
    with pytest.raises(CurvefmError, match="bad parameters for 'laplace-beltrami': method"):
        registry.get("basis", "laplace-beltrami").parse_params({"method": "guess"})
    with pytest.raises(CurvefmError, match="bad parameters for 'nearest-neighbor': colour"):
        registry.get("converter", "nearest-neighbor").parse_params({"colour": 1})


def test_a_third_party_tracer_installed_with_pip_is_listed_and_used(tmp_path):
    env = pip_install(tmp_path, "curvefm-hops", 'hops = "curvefm_hops:HOPS"', THIRD_PARTY_PLUGIN)
    listed = subprocess.run(
        [sys.executable, "-m", "curvefm.cli", "plugins", "--json"], env=env, check=True, capture_output=True, text=True
    )
    assert "hops" in [p["name"] for p in json.loads(listed.stdout)["tracer"]]
    script = textwrap.dedent("""
        import sys
        sys.path.insert(0, "tests")
        from support.shapes import ellipsoid
        from curvefm.session import trace_curve
        path = trace_curve(ellipsoid(), waypoints=[0, 600], tracer="hops", params={"hops": 2})
        print(path[0], path[-1], len(path))
    """)
    used = subprocess.run([sys.executable, "-c", script], env=env, check=True, capture_output=True, text=True)
    start, end, length = used.stdout.split()
    assert (start, end) == ("0", "600") and int(length) > 2


def test_a_plugin_of_another_kind_is_refused_naming_its_distribution_and_entry_point(tmp_path):
    value = "curvefm.plugins.converters:NEAREST_NEIGHBOR"  # a converter, registered as a tracer
    env = pip_install(tmp_path, "curvefm-mislabelled", f'nearest = "{value}"')
    script = textwrap.dedent("""
        from curvefm import registry
        from curvefm.errors import CurvefmError
        try:
            registry.get("tracer", "nearest")
        except CurvefmError as exc:
            print(exc)
    """)
    refused = subprocess.run([sys.executable, "-c", script], env=env, check=True, capture_output=True, text=True)
    message = refused.stdout.strip()
    assert message.startswith("the distribution 'curvefm-mislabelled' registers")
    assert f"'nearest = {value}'" in message and "'curvefm.tracers'" in message
    assert "ConverterPlugin, not a curvefm.registry.TracerPlugin" in message
