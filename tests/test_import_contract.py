"""The layering contract, read from the source (every import statement, function-level ones included).

Import names differ from folder names (``service/`` installs as ``curvefm.service``): the folders come from
``pyproject.toml``'s package-dir table, so the check reads both.

* the core (``curvefm/``) imports nothing above it; only the CLI, the entry point, starts the service and workers
* plugins import the core's public API (a package such as ``curvefm.fmap``, not its modules) and other plugins
* workers import the core and plugins, never the service
* the service imports the core, plugins and, of the workers, only the queue interface and the factory of queues
* the client (of the HTTP API) imports the core's public API only: never the service, workers or plugins
"""

from __future__ import annotations

import ast
import tomllib
from functools import cache
from pathlib import Path

import pytest
from conftest import REPO

QUEUE_INTERFACE = {"curvefm.workers.interface", "curvefm.workers.factory"}
CORE_PACKAGES = {"geometry", "spectral", "fmap", "pointwise", "session", "evaluation"}
ABOVE_CORE = ("curvefm.plugins", "curvefm.service", "curvefm.workers", "curvefm.client")


@cache
def package_dirs() -> dict[str, Path]:
    table = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["package-dir"]
    return {name: REPO / folder for name, folder in table.items()}


def module_name(path: Path, dirs: dict[str, Path]) -> str:
    """The import name of a source file: the longest package-dir folder that contains it decides."""
    package, folder = max(
        ((p, f) for p, f in dirs.items() if path.is_relative_to(f)), key=lambda item: len(item[1].parts)
    )
    parts = list(path.relative_to(folder).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join([package, *parts])


def imports_of(path: Path, module: str) -> set[str]:
    """Every curvefm module ``path`` imports (``from a import b`` counts as a.b when b is a module)."""
    found = set()
    is_package = path.name == "__init__.py"
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = module.split(".")[: len(module.split(".")) - node.level + (1 if is_package else 0)]
                base = ".".join([*anchor, *([base] if base else [])])
            found.add(base)
            found |= {f"{base}.{alias.name}" for alias in node.names}
    return {name for name in found if name == "curvefm" or name.startswith("curvefm.")}


@cache
def all_imports() -> dict[str, set[str]]:
    dirs = package_dirs()
    files = {path for folder in set(dirs.values()) for path in folder.rglob("*.py")}
    return {module_name(path, dirs): imports_of(path, module_name(path, dirs)) for path in sorted(files)}


def is_module(name: str) -> bool:
    """Whether an imported name is a module of ours (``from curvefm.fmap import solve_columns`` is not)."""
    dirs = package_dirs()
    for package, folder in sorted(dirs.items(), key=lambda item: -len(item[0])):
        if name == package or name.startswith(package + "."):
            rest = name[len(package) :].lstrip(".").split(".") if name != package else []
            target = folder.joinpath(*rest)
            return target.with_suffix(".py").is_file() or (target / "__init__.py").is_file()
    return False


def violations(module: str, imported: set[str]) -> list[str]:
    modules = {name for name in imported if is_module(name)}
    if module.startswith("curvefm.plugins"):
        private = {m for m in modules if _inside_core_package(m)}
        return sorted(_under(modules, "curvefm.service", "curvefm.workers") | private)
    if module.startswith("curvefm.client"):
        private = {m for m in modules if _inside_core_package(m)}
        return sorted(_under(modules, "curvefm.service", "curvefm.workers", "curvefm.plugins") | private)
    if module.startswith("curvefm.workers"):
        return sorted(_under(modules, "curvefm.service"))
    if module.startswith("curvefm.service"):
        return sorted(_under(modules, "curvefm.workers") - QUEUE_INTERFACE - {"curvefm.workers"})
    if module == "curvefm.cli":
        return []
    return sorted(_under(modules, *ABOVE_CORE))


def _under(modules: set[str], *packages: str) -> set[str]:
    return {m for m in modules if any(m == p or m.startswith(p + ".") for p in packages)}


def _inside_core_package(module: str) -> bool:
    parts = module.split(".")
    return len(parts) > 2 and parts[1] in CORE_PACKAGES


def test_the_contract_reads_every_source_folder():
    modules = all_imports()
    for expected in ("curvefm.cli", "curvefm.plugins.tracers", "curvefm.service.app", "curvefm.workers.jobs",
                     "curvefm.client.api"):
        assert expected in modules
    assert len(modules) > 60


@pytest.mark.parametrize("module", sorted(all_imports()))
def test_module_respects_the_layers(module):
    assert violations(module, all_imports()[module]) == [], f"{module} breaks the import contract"


def test_a_core_module_importing_the_service_is_caught():
    assert violations("curvefm.fmap.solver", {"curvefm.service.app"}) == ["curvefm.service.app"]
    assert violations("curvefm.plugins.icp", {"curvefm.fmap.solver"}) == ["curvefm.fmap.solver"]
    assert violations("curvefm.service.deps", {"curvefm.workers.jobs"}) == ["curvefm.workers.jobs"]
    assert violations("curvefm.service.deps", {"curvefm.workers.rq_queue"}) == ["curvefm.workers.rq_queue"]
    assert violations("curvefm.workers.jobs", {"curvefm.service.models"}) == ["curvefm.service.models"]
    assert violations("curvefm.client.api", {"curvefm.service.models"}) == ["curvefm.service.models"]
    assert violations("curvefm.fmap.solver", {"curvefm.client.api"}) == ["curvefm.client.api"]
