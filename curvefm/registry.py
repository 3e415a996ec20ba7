"""Plugins found through Python entry points.

Four entry-point groups, one per kind of plugin. Each entry point names a :class:`Plugin` object:

* ``curvefm.tracers``:    ``run(mesh, start, end, params) -> path``, a vertex path (internal ids) from start
  to end whose consecutive entries share an edge.
* ``curvefm.bases``:      ``run(mesh, k, params, progress) -> Basis``.
* ``curvefm.converters``: ``run(problem: MapProblem, params, progress) -> PointwiseMaps``.
* ``curvefm.methods``:    ``run(inputs: MapInputs, params, progress) -> FunctionalMaps``, functional maps
  from curves or landmarks (``curvefm reproduce`` compares them).

Our own built-ins are registered in ``pyproject.toml`` exactly as a third-party package registers its own.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from importlib.metadata import entry_points

from pydantic import BaseModel, ValidationError

from curvefm.errors import CurvefmError

GROUPS = {
    "tracer": "curvefm.tracers",
    "basis": "curvefm.bases",
    "converter": "curvefm.converters",
    "method": "curvefm.methods",
}


@dataclass(frozen=True)
class Plugin:
    name: str
    description: str
    Params: type[BaseModel]
    run: Callable

    def parse_params(self, params: dict | BaseModel | None) -> BaseModel:
        """Validate user parameters, raising :class:`CurvefmError` that names each bad field."""
        if isinstance(params, self.Params):
            return params
        try:
            return self.Params.model_validate(params or {})
        except ValidationError as exc:
            problems = "; ".join(
                f"{'.'.join(str(p) for p in e['loc']) or 'params'}: {e['msg']}" for e in exc.errors()
            )
            raise CurvefmError(f"bad parameters for '{self.name}': {problems}") from None

    def describe(self) -> dict:
        return {"name": self.name, "description": self.description, "parameters": self.Params.model_json_schema()}


def _group(kind: str) -> str:
    if kind not in GROUPS:
        raise CurvefmError(f"unknown plugin kind '{kind}'; kinds are {', '.join(GROUPS)}")
    return GROUPS[kind]


@cache
def _entry_points(group: str) -> tuple:
    # scanning installed distributions costs ~50 ms; plugins are installed before a process starts
    return tuple(entry_points(group=group))


def names(kind: str) -> list[str]:
    """Names of the installed plugins of one kind."""
    return sorted({ep.name for ep in _entry_points(_group(kind))})


@cache
def get(kind: str, name: str) -> Plugin:
    """Load a plugin by name; an unknown name raises an error listing what is installed."""
    matches = [ep for ep in _entry_points(_group(kind)) if ep.name == name]
    if not matches:
        raise CurvefmError(
            f"unknown {kind} '{name}'; installed {kind}s: {', '.join(names(kind)) or 'none'}", kind="invalid"
        )
    plugin = matches[0].load()
    if not isinstance(plugin, Plugin) and not all(hasattr(plugin, a) for a in ("name", "Params", "run")):
        raise CurvefmError(f"{kind} plugin '{name}' ({matches[0].value}) is not a curvefm Plugin object")
    return plugin


def describe_all() -> dict[str, list[dict]]:
    """Every installed plugin with its parameter schema, by kind (what ``curvefm plugins`` prints)."""
    return {kind: [get(kind, name).describe() for name in names(kind)] for kind in GROUPS}
