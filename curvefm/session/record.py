"""Session records: what a session stores on disk (:func:`curvefm.session.pair.build_solver` rebuilds its solver).

A record holds the shape pair, the parameters and every curve with its traced paths in **file** vertex ids
(the ids a user reads off the mesh files). The API writes it atomically on every change; the refinement job
receives a copy of it, so both rebuild exactly the same ``CurveMapSolver``.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from curvefm.session.curves import CurveSpec


class CurveRecord(BaseModel):
    """One stored curve pair: the user's input and the traced paths (file vertex ids, start first)."""

    model_config = ConfigDict(extra="forbid")
    id: str
    spec: CurveSpec
    tracer: str = Field(description="tracer actually used (the session default when the spec names none)")
    path_source: list[int]
    path_target: list[int]


class SessionRecord(BaseModel):
    model_config = ConfigDict(extra="forbid")
    id: str
    name: str = ""
    source: str = Field(description="shape id of M, the source")
    target: str = Field(description="shape id of N, the target")
    k: int
    alpha: float
    samples: int
    tracer: str
    basis_plugin: str
    basis_params: dict
    curves: list[CurveRecord] = Field(default_factory=list)
    next_curve: int = 1
    revision: int = 0
    created_at: float
    updated_at: float
