"""Request and response models of the HTTP API (they are its OpenAPI schema at ``/docs``).

Vertex ids in requests and responses are **file** ids (0-based, as in the uploaded file), except in the
binary mesh and transfer payloads, whose rows follow the mesh's internal vertex order (``file_ids`` in the
mesh payload translates).
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from curvefm.fmap import DEFAULT_ALPHA, DEFAULT_K, DEFAULT_SAMPLES
from curvefm.session import CurveRecord

JobStateName = Literal["queued", "started", "finished", "failed", "canceled"]


class ErrorBody(BaseModel):
    error: str = Field(description="invalid, not_found, conflict or too_large")
    detail: str = Field(description="what was wrong and what to do")
    available: list[str] | None = Field(None, description="installed plugins of the kind asked for")


class BasisInfo(BaseModel):
    plugin: str
    k: int
    params_key: str


class ShapeInfo(BaseModel):
    id: str = Field(description="content hash of the validated mesh")
    name: str
    n_vertices: int = Field(description="vertices used by faces (internal ids 0..n_vertices-1)")
    n_faces: int
    n_file_vertices: int = Field(description="vertices in the file; file ids are 0..n_file_vertices-1")
    has_uv: bool
    report: dict = Field(description="what validation changed or noticed")
    bases: list[BasisInfo]


class BasisRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")
    k: int = Field(DEFAULT_K, ge=1, description="number of basis functions")
    plugin: str = "laplace-beltrami"
    params: dict = Field(default_factory=dict, description="the basis plugin's parameters (GET /plugins)")


class JobInfoModel(BaseModel):
    id: str
    kind: str = Field(description="basis or refine")
    state: JobStateName
    progress: float = Field(description="0..1")
    message: str
    result: dict | None = None
    links: dict[str, str] = Field(default_factory=dict, description="where to fetch what the job produced")
    error: str | None = Field(None, description="one readable line when the job failed")
    traceback: str | None = None
    worker: str | None = None
    created_at: float | None = None
    started_at: float | None = None
    ended_at: float | None = None


class SessionCreate(BaseModel):
    model_config = ConfigDict(extra="forbid")
    source: str = Field(description="shape id of M")
    target: str = Field(description="shape id of N")
    k: int = Field(DEFAULT_K, ge=1)
    alpha: float = Field(DEFAULT_ALPHA, ge=0)
    tracer: str = Field("geodesic", description="default tracer for curves that name none")
    samples: int = Field(DEFAULT_SAMPLES, ge=2, le=10_000, description="samples per curve")
    basis_plugin: str = "laplace-beltrami"
    basis_params: dict = Field(default_factory=dict)
    name: str = Field("", max_length=200)


class SessionSummary(BaseModel):
    id: str
    name: str
    source: str
    target: str
    k: int
    n_curves: int
    revision: int
    updated_at: float


class MapSummary(BaseModel):
    revision: int = Field(description="increases with every change of the session")
    n_curves: int
    k: int
    solve_ms: float = Field(description="time to update both maps for this edit")


class CurveEdit(BaseModel):
    curve: CurveRecord | None = Field(None, description="the stored curve with its traced paths (file ids)")
    map: MapSummary


class MapResponse(BaseModel):
    revision: int
    k: int
    C_source_to_target: list[list[float]] = Field(description="C_MN: coefficients on M -> coefficients on N")
    C_target_to_source: list[list[float]] = Field(description="C_NM")


class RefineRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")
    converter: str = "nearest-neighbor"
    params: dict = Field(default_factory=dict)
