"""Plugins found through Python entry points, one entry-point group and one contract per kind.

A plugin is a small frozen object: a ``name``, a ``description``, a pydantic parameter model ``Params`` and
one function of the work, ``run``. Each kind has its own contract class; an entry point must name an
instance of its group's class (a converter listed under ``curvefm.tracers`` is refused when loaded):

* ``curvefm.tracers``, :class:`TracerPlugin`: ``run(mesh, start, end, params) -> path``, a vertex path
  (internal ids) from start to end whose consecutive entries share an edge. Optional hook ``run_guided(mesh,
  start, end, params, guide)``: the same path sought near the mesh's display copy ``guide``
  (:class:`~curvefm.geometry.DisplayMesh`), which live sessions call on shapes of millions of vertices.
* ``curvefm.bases``, :class:`BasisPlugin`: ``run(mesh, k, params, progress) -> Basis``.
* ``curvefm.converters``, :class:`ConverterPlugin`: ``run(pair, maps, params, progress) -> PointwiseMaps``,
  pointwise maps both ways from a :class:`~curvefm.spectral.ShapePair` and its functional maps. Optional
  hook ``basis_size(params) -> int``: the basis functions per shape the converter works with, so that callers
  holding stored bases can pass bases that large (0, the default: the maps' own size is enough). Optional
  flag ``takes_curves``: ``run`` also accepts the keyword ``curves``, the user's corresponding curves as
  ``(path_M, path_N)`` internal vertex paths (refiners keep them as constraints); callers use
  :meth:`ConverterPlugin.convert`, which passes them only to a converter that takes them, so converters
  written before the flag existed keep working. ``refines`` (default true): the converter improves on the
  nearest-neighbour maps, and callers check that it did.
* ``curvefm.methods``, :class:`MethodPlugin`: ``run(pair, hints, params, progress) -> FunctionalMaps``,
  functional maps from curves or landmarks (``curvefm reproduce`` compares them).

Parameters are parsed once, here (:func:`load`, or :meth:`Plugin.parse_params` on a plugin already at hand):
``run`` receives the plugin's own ``Params`` model, never a dict. Our own built-ins are registered in
``pyproject.toml`` exactly as a third-party package registers its own.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from functools import cache
from importlib.metadata import EntryPoint, entry_points
from typing import TYPE_CHECKING, Any, Generic, Literal, TypeVar, overload

from pydantic import BaseModel, ValidationError

from curvefm.errors import InvalidInput

if TYPE_CHECKING:
    import numpy as np

    from curvefm.fmap import FunctionalMaps, Hints
    from curvefm.geometry import DisplayMesh, Mesh
    from curvefm.pointwise import PointwiseMaps
    from curvefm.progress import Progress
    from curvefm.spectral import Basis, ShapePair

P = TypeVar("P", bound=BaseModel)


def parse_params(name: str, model: type[P], params: dict[str, Any] | BaseModel | None) -> P:
    """``params`` validated by ``model``, raising :class:`CurvefmError` that names ``name`` and each bad field (what
    :meth:`Plugin.parse_params` does; the core calls it for the default basis, which it computes without a plugin)."""
    if isinstance(params, model):
        return params
    try:
        return model.model_validate(params or {})
    except ValidationError as exc:
        problems = "; ".join(f"{'.'.join(str(p) for p in e['loc']) or 'params'}: {e['msg']}" for e in exc.errors())
        raise InvalidInput(f"bad parameters for '{name}': {problems}") from None


@dataclass(frozen=True)
class Plugin(Generic[P]):
    """What every kind has: a name, a description and the parameter model its ``run`` receives."""

    name: str
    description: str
    Params: type[P]

    def parse_params(self, params: dict[str, Any] | BaseModel | None) -> P:
        """Validate user parameters, raising :class:`CurvefmError` that names each bad field."""
        return parse_params(self.name, self.Params, params)

    def describe(self) -> dict[str, Any]:
        return {"name": self.name, "description": self.description, "parameters": self.Params.model_json_schema()}


@dataclass(frozen=True)
class TracerPlugin(Plugin[P]):
    run: Callable[[Mesh, int, int, P], np.ndarray]
    run_guided: Callable[[Mesh, int, int, P, DisplayMesh], np.ndarray] | None = None


@dataclass(frozen=True)
class BasisPlugin(Plugin[P]):
    run: Callable[[Mesh, int, P, Progress], Basis]
    storage_params: Callable[[P], dict[str, Any]] = lambda params: params.model_dump()
    """The parameters a stored basis is filed under (:meth:`curvefm.store.Store.ensure_basis`): all of them, unless
    the plugin leaves out one that only chooses how to compute it, so that adding such a parameter keeps finding
    the bases stored before it existed."""


def no_basis_size(params: BaseModel) -> int:
    """A converter that works in the functional maps' own bases."""
    return 0


@dataclass(frozen=True)
class ConverterPlugin(Plugin[P]):
    run: Callable[..., PointwiseMaps]
    basis_size: Callable[[P], int] = no_basis_size
    takes_curves: bool = False
    refines: bool = True
    """Whether ``run`` refines the nearest-neighbour maps (then :func:`curvefm.matching.convert` keeps them
    only where refinement made no intrinsic quality figure worse)."""
    stages: Callable[..., Iterator[tuple[str, PointwiseMaps]]] | None = None
    """Optional, with ``run``'s arguments: ``(label, maps)`` with ``run``'s maps first, then the refinement
    stopped earlier and earlier, each computed only when asked for; the guard returns the first stage that made no
    intrinsic figure worse."""

    def convert_in_stages(
        self,
        pair: ShapePair,
        maps: FunctionalMaps,
        params: P,
        progress: Progress,
        curves: Sequence[tuple[np.ndarray, np.ndarray]] = (),
    ) -> Iterator[tuple[str, PointwiseMaps]]:
        """``stages`` where the converter has them, else ``run``'s maps as the one stage; with the user's curves
        where the converter takes them. The first stage is always ``run``'s maps."""
        arguments = {"curves": tuple(curves)} if self.takes_curves else {}
        if self.stages is None:
            yield "", self.run(pair, maps, params, progress, **arguments)
        else:
            yield from self.stages(pair, maps, params, progress, **arguments)


@dataclass(frozen=True)
class MethodPlugin(Plugin[P]):
    run: Callable[[ShapePair, Hints, P, Progress], FunctionalMaps]


#: kind -> (entry-point group, contract class)
KINDS: dict[str, tuple[str, type[Plugin[Any]]]] = {
    "tracer": ("curvefm.tracers", TracerPlugin),
    "basis": ("curvefm.bases", BasisPlugin),
    "converter": ("curvefm.converters", ConverterPlugin),
    "method": ("curvefm.methods", MethodPlugin),
}


def _kind(kind: str) -> tuple[str, type[Plugin[Any]]]:
    if kind not in KINDS:
        raise InvalidInput(f"unknown plugin kind '{kind}'; kinds are {', '.join(KINDS)}")
    return KINDS[kind]


@cache
def _entry_points(group: str) -> tuple[EntryPoint, ...]:
    # scanning installed distributions costs ~50 ms; plugins are installed before a process starts
    return tuple(entry_points(group=group))


def names(kind: str) -> list[str]:
    """Names of the installed plugins of one kind."""
    return sorted({ep.name for ep in _entry_points(_kind(kind)[0])})


# The kinds' names as literals, so that `get("converter", ...)` is typed as a ConverterPlugin; any other string
# (a kind read at run time) gives a Plugin, and an unknown kind is refused when called.
@overload
def get(kind: Literal["tracer"], name: str) -> TracerPlugin[Any]: ...
@overload
def get(kind: Literal["basis"], name: str) -> BasisPlugin[Any]: ...
@overload
def get(kind: Literal["converter"], name: str) -> ConverterPlugin[Any]: ...
@overload
def get(kind: Literal["method"], name: str) -> MethodPlugin[Any]: ...
@overload
def get(kind: str, name: str) -> Plugin[Any]: ...
@cache
def get(kind: str, name: str) -> Plugin[Any]:
    """Load a plugin by name; an unknown name raises an error listing what is installed, an entry point whose
    object is not the kind's contract an error naming the distribution and the entry point."""
    group, contract = _kind(kind)
    matches = [ep for ep in _entry_points(group) if ep.name == name]
    if not matches:
        raise InvalidInput(f"unknown {kind} '{name}'; installed {kind}s: {', '.join(names(kind)) or 'none'}")
    plugin = matches[0].load()
    if not isinstance(plugin, contract):
        ep = matches[0]
        distribution = ep.dist.name if ep.dist is not None else "?"
        raise InvalidInput(
            f"the distribution '{distribution}' registers '{ep.name} = {ep.value}' in the entry-point group "
            f"'{group}', but that object is a {type(plugin).__name__}, not a curvefm.registry.{contract.__name__}"
        )
    return plugin


@overload
def load(
    kind: Literal["tracer"], name: str, params: dict[str, Any] | BaseModel | None = None
) -> tuple[TracerPlugin[Any], BaseModel]: ...
@overload
def load(
    kind: Literal["basis"], name: str, params: dict[str, Any] | BaseModel | None = None
) -> tuple[BasisPlugin[Any], BaseModel]: ...
@overload
def load(
    kind: Literal["converter"], name: str, params: dict[str, Any] | BaseModel | None = None
) -> tuple[ConverterPlugin[Any], BaseModel]: ...
@overload
def load(
    kind: Literal["method"], name: str, params: dict[str, Any] | BaseModel | None = None
) -> tuple[MethodPlugin[Any], BaseModel]: ...
@overload
def load(kind: str, name: str, params: dict[str, Any] | BaseModel | None = None) -> tuple[Plugin[Any], BaseModel]: ...
def load(kind: str, name: str, params: dict[str, Any] | BaseModel | None = None) -> tuple[Plugin[Any], BaseModel]:
    """The plugin and its parsed parameters, ready for ``plugin.run(..., params, ...)``."""
    plugin = get(kind, name)
    return plugin, plugin.parse_params(params)


def describe_all() -> dict[str, list[dict[str, Any]]]:
    """Every installed plugin with its parameter schema, by kind (what ``curvefm plugins`` prints)."""
    return {kind: [get(kind, name).describe() for name in names(kind)] for kind in KINDS}
