"""Curve specs as users give them (file vertex ids) and tracing them into vertex paths."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from curvefm import registry
from curvefm.errors import Conflict, InvalidInput, NotFound
from curvefm.geometry import DisplayMesh, Mesh, check_edge_path

MAX_VERTEX_ID = 2**31 - 1
"""No mesh has more vertices (paths are stored as int32). Also a bound that survives the OpenAPI schema, whose
numbers FastAPI writes as floats: 2**63 - 1 would read there as 2**63."""
VertexId = Annotated[
    int,
    Field(
        ge=0,
        le=MAX_VERTEX_ID,
        description="a vertex id in the mesh file (0-based); the mesh bounds it further",
        examples=[19],  # else Swagger UI fills its example requests with the bound, 2147483647
    ),
]
EXAMPLE_PATHS = {"source": [19, 432], "target": [19, 432]}
"""Waypoints that exist on every shape of a thousand vertices or more (the demo's have 4098): the examples of the
API schema, which Swagger UI puts in the requests it offers to send."""
"""A file vertex id as a request may give it: the bounds keep ids beyond int64 out of the numeric code."""


MAX_CURVE_WEIGHT = 1e6
CurveWeight = Annotated[
    float,
    Field(
        gt=0,
        le=MAX_CURVE_WEIGHT,
        allow_inf_nan=False,
        description="how much the curve counts relative to the others (1: as much)",
    ),
]
"""A curve's weight: bounded, so no sum of weights overflows the solver's matrices."""


class CurveSpec(BaseModel):
    """One pair of corresponding curves, in file vertex ids (0-based).

    ``source`` and ``target`` are endpoints or waypoints joined by the tracer, or, with ``explicit``, whole
    edge-connected vertex paths (``explicit="source"``: only the source is a path, as in a collection, whose
    member curves answer a template curve traced once; ``"target"`` likewise).
    """

    model_config = ConfigDict(extra="forbid")
    source: list[VertexId] = Field(
        min_length=2, description="waypoints (at least start and end) or a path", examples=[EXAMPLE_PATHS["source"]]
    )
    target: list[VertexId] = Field(
        min_length=2, description="waypoints (at least start and end) or a path", examples=[EXAMPLE_PATHS["target"]]
    )
    explicit: bool | Literal["source", "target"] = Field(
        False, description="true: both sides are whole vertex paths; 'source' or 'target': only that side is"
    )
    tracer: str | None = Field(None, description="the session's tracer when none is named")
    tracer_params: dict[str, Any] = Field(
        default_factory=dict, description="parameters of the tracer named in 'tracer'"
    )
    weight: CurveWeight = 1.0
    template_curve: str | None = Field(
        None, max_length=64, description="in a collection's member session: the template curve this curve answers"
    )

    @model_validator(mode="after")
    def _params_need_their_tracer(self) -> CurveSpec:
        if self.tracer_params and self.tracer is None:
            raise ValueError("tracer_params need the tracer they are for: name it in 'tracer'")
        return self

    def is_path(self, side: str) -> bool:
        """Whether the ``side`` (``source`` or ``target``) is given as a whole vertex path."""
        return self.explicit is True or self.explicit == side

    @property
    def traced(self) -> bool:
        """Whether a tracer joins the waypoints of at least one side."""
        return self.explicit is not True


class CurvesFile(BaseModel):
    model_config = ConfigDict(extra="forbid")
    curves: list[CurveSpec]


def read_curves(path: str | Path) -> list[CurveSpec]:
    try:
        return CurvesFile.model_validate(json.loads(Path(path).read_text())).curves
    except FileNotFoundError:
        raise NotFound(f"curves file not found: {path}") from None
    except json.JSONDecodeError as exc:
        raise InvalidInput(f"curves file {path} is not valid JSON: {exc}") from None
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first["loc"])
        raise InvalidInput(f"curves file {path}: {where}: {first['msg']}") from None


def trace_curve(
    mesh: Mesh,
    waypoints: Sequence[int] | None = None,
    path: Sequence[int] | None = None,
    tracer: str = "geodesic",
    params: dict[str, Any] | None = None,
    guide: DisplayMesh | None = None,
) -> np.ndarray:
    """Return a vertex path (internal ids) from user input in **file** ids.

    Give either ``waypoints`` (two endpoints, or more points the curve must pass in order; consecutive
    points are joined by the tracer) or an explicit ``path`` (checked to be edge-connected). ``guide``: the
    mesh's display copy, for a tracer that can search near it (``run_guided``) instead of on the whole mesh.
    """
    if (waypoints is None) == (path is None):
        raise InvalidInput("give a curve either as waypoints (endpoints) or as an explicit vertex path")
    if path is not None:
        internal = mesh.internal_ids(path, "path vertex")
        check_edge_path(mesh.edge_graph, internal)
        return internal
    assert waypoints is not None  # exactly one of waypoints and path was given
    points = mesh.internal_ids(waypoints, "waypoint")
    if len(points) < 2:
        raise InvalidInput(f"a curve needs at least two waypoints (start and end), got {len(points)}")
    plugin, parsed = registry.load("tracer", tracer, params)

    def piece(a: int, b: int) -> np.ndarray:
        if guide is None or plugin.run_guided is None:
            return plugin.run(mesh, a, b, parsed)
        return plugin.run_guided(mesh, a, b, parsed, guide)

    pieces = [piece(int(a), int(b)) for a, b in zip(points[:-1], points[1:], strict=True)]
    traced = np.concatenate([pieces[0]] + [p[1:] for p in pieces[1:]])
    if len(traced) < 2:
        raise Conflict("the curve's waypoints are all the same vertex of the mesh; pick two different points")
    return traced


def pinned_pieces(
    mesh_M: Mesh, mesh_N: Mesh, spec: CurveSpec, path_M: np.ndarray, path_N: np.ndarray
) -> list[tuple[np.ndarray, np.ndarray]]:
    """The traced pair ``(path_M, path_N)`` (internal ids) as the refiners pin it: cut at its waypoints, so that
    every point the user gave ends a piece (the refiners pin the ends of a piece) and the traced stretches between
    them correspond by arc length stretch by stretch. A curve of two points, or given as a whole path on a side,
    stays one piece."""
    if spec.explicit or len(spec.source) == 2 or len(spec.source) != len(spec.target):
        return [(path_M, path_N)]
    cuts_M = _positions(path_M, mesh_M.internal_ids(spec.source, "waypoint"))
    cuts_N = _positions(path_N, mesh_N.internal_ids(spec.target, "waypoint"))
    if cuts_M is None or cuts_N is None:
        return [(path_M, path_N)]
    return [
        (path_M[a : b + 1], path_N[c : d + 1])
        for a, b, c, d in zip(cuts_M, cuts_M[1:], cuts_N, cuts_N[1:], strict=False)
    ]


def _positions(path: np.ndarray, waypoints: np.ndarray) -> list[int] | None:
    """Where the path passes each waypoint, in order (None if it does not: a tracer that moved one)."""
    positions, start = [], 0
    for waypoint in waypoints:
        found = np.flatnonzero(path[start:] == waypoint)
        if not len(found):
            return None
        start += int(found[0])
        positions.append(start)
    return positions


def trace_pair(
    mesh_M: Mesh,
    mesh_N: Mesh,
    spec: CurveSpec,
    default_tracer: str,
    guides: tuple[DisplayMesh | None, DisplayMesh | None] = (None, None),
) -> tuple[np.ndarray, np.ndarray]:
    """Both paths of a curve pair (internal ids); ``guides``: display copies to trace near (:func:`trace_curve`)."""
    tracer = spec.tracer or default_tracer
    paths = []
    for side, mesh, ids, guide in (
        ("source", mesh_M, spec.source, guides[0]),
        ("target", mesh_N, spec.target, guides[1]),
    ):
        if spec.is_path(side):
            paths.append(trace_curve(mesh, path=ids))
        else:
            paths.append(trace_curve(mesh, waypoints=ids, tracer=tracer, params=spec.tracer_params, guide=guide))
    return paths[0], paths[1]
