"""Curve specs as users give them (file vertex ids) and tracing them into vertex paths."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from curvefm import registry
from curvefm.errors import Conflict, InvalidInput, NotFound
from curvefm.geometry import Mesh, check_edge_path

MAX_VERTEX_ID = 2**31 - 1
"""No mesh has more vertices (paths are stored as int32). Also a bound that survives the OpenAPI schema, whose
numbers FastAPI writes as floats: 2**63 - 1 would read there as 2**63."""
VertexId = Annotated[
    int, Field(ge=0, le=MAX_VERTEX_ID, description="a vertex id in the mesh file (0-based); the mesh bounds it further")
]
"""A file vertex id as a request may give it: the bounds keep ids beyond int64 out of the numeric code."""


class CurveSpec(BaseModel):
    """One pair of corresponding curves, in file vertex ids (0-based).

    ``source`` and ``target`` are endpoints or waypoints joined by the tracer, or, with ``explicit``, whole
    edge-connected vertex paths (``explicit="source"``: only the source is a path, as in a collection, whose
    member curves answer a template curve traced once; ``"target"`` likewise).
    """

    model_config = ConfigDict(extra="forbid")
    source: list[VertexId] = Field(min_length=2, description="waypoints (at least start and end) or a path")
    target: list[VertexId] = Field(min_length=2, description="waypoints (at least start and end) or a path")
    explicit: bool | Literal["source", "target"] = Field(
        False, description="true: both sides are whole vertex paths; 'source' or 'target': only that side is"
    )
    tracer: str | None = Field(None, description="the session's tracer when none is named")
    tracer_params: dict = Field(default_factory=dict, description="parameters of the tracer named in 'tracer'")
    weight: float = Field(1.0, gt=0)
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
    params: dict | None = None,
) -> np.ndarray:
    """Return a vertex path (internal ids) from user input in **file** ids.

    Give either ``waypoints`` (two endpoints, or more points the curve must pass in order; consecutive
    points are joined by the tracer) or an explicit ``path`` (checked to be edge-connected).
    """
    if (waypoints is None) == (path is None):
        raise InvalidInput("give a curve either as waypoints (endpoints) or as an explicit vertex path")
    if path is not None:
        internal = mesh.internal_ids(path, "path vertex")
        check_edge_path(mesh.edge_graph, internal)
        return internal
    points = mesh.internal_ids(waypoints, "waypoint")
    if len(points) < 2:
        raise InvalidInput(f"a curve needs at least two waypoints (start and end), got {len(points)}")
    plugin, parsed = registry.load("tracer", tracer, params)
    pieces = [plugin.run(mesh, int(a), int(b), parsed) for a, b in zip(points[:-1], points[1:], strict=True)]
    traced = np.concatenate([pieces[0]] + [p[1:] for p in pieces[1:]])
    if len(traced) < 2:
        raise Conflict("the curve's waypoints are all the same vertex of the mesh; pick two different points")
    return traced


def trace_pair(mesh_M: Mesh, mesh_N: Mesh, spec: CurveSpec, default_tracer: str) -> tuple[np.ndarray, np.ndarray]:
    tracer = spec.tracer or default_tracer
    paths = []
    for side, mesh, ids in (("source", mesh_M, spec.source), ("target", mesh_N, spec.target)):
        if spec.is_path(side):
            paths.append(trace_curve(mesh, path=ids))
        else:
            paths.append(trace_curve(mesh, waypoints=ids, tracer=tracer, params=spec.tracer_params))
    return paths[0], paths[1]
