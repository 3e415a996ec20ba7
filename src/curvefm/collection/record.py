"""Collection records: one template shape with its curves, and members, each a session (template -> member) that
the collection made and owns, plus the batch runs of refinement jobs over the members.

A member's curves are its session's curves: the source side is a template curve's traced path (explicit), the
target side is clicked on the member, and the session curve names the template curve it answers
(``CurveSpec.template_curve``), so edits through the normal session routes keep the count of answered curves.
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from curvefm.errors import NotFound, shown
from curvefm.fmap import DEFAULT_ALPHA, DEFAULT_K, DEFAULT_SAMPLES
from curvefm.session import EXAMPLE_PATHS, SHARING_DESCRIPTION, Alpha, MapSize, Samples, Sharing, VertexId, VertexPath
from curvefm.session.record import ENERGY_DESCRIPTION, Energy


class UnknownCollection(NotFound):
    """No collection has this id (or the id cannot name one)."""

    def __init__(self, collection_id: str):
        super().__init__(f"no collection with id '{shown(collection_id)}'")


class TemplateCurveSpec(BaseModel):
    """A template curve given directly: waypoints on the template joined by the tracer, or a whole path."""

    model_config = ConfigDict(extra="forbid")
    name: str = Field("", max_length=200)
    waypoints: list[VertexId] = Field(
        min_length=2, description="file ids on the template: waypoints, or a path", examples=[EXAMPLE_PATHS["source"]]
    )
    explicit: bool = Field(False, description="the waypoints are a whole edge-connected vertex path")
    tracer: str | None = Field(None, description="the collection's tracer when none is named")
    tracer_params: dict[str, Any] = Field(default_factory=dict)


class TemplateCurve(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    id: str = Field(description="t1, t2, ...")
    name: str = ""
    waypoints: list[int] = Field(description="what was given on the template (file ids)")
    path: VertexPath = Field(description="the traced path on the template (file ids, start first)")


class Member(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    id: str = Field(description="m1, m2, ...")
    shape: str = Field(description="shape id of the member")
    session: str = Field(description="the member's session (source: the template, target: the member)")
    basis_job: str | None = Field(None, description="the job computing the member's basis, when one was queued")


class RunMember(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    job: str = Field(description="the member's refinement job")
    revision: int = Field(description="the session revision the job refines")
    carried: bool = Field(False, description="taken over from the previous run (the member was not run again)")


class Run(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    id: str = Field(description="r1, r2, ...")
    converter: str
    params: dict[str, Any]
    created_at: float
    members: dict[str, RunMember] = Field(description="member id -> its job in this run")


class CollectionCreate(BaseModel):
    """A new collection on a template shape. Its curves come from a session on the template (``from_session``:
    its source must be the template; its curves' source sides become the template curves, its target the first
    member with its curves, and its solver parameters the collection's), or are given as ``curves``."""

    model_config = ConfigDict(extra="forbid")
    name: str = Field("", max_length=200)
    template: str = Field(description="shape id of the template")
    from_session: str | None = Field(None, description="a session whose source is the template")
    curves: list[TemplateCurveSpec] = Field(default_factory=list, description="template curves (max_curves bounds)")
    members: list[str] = Field(default_factory=list, description="shape ids of members to add now")
    k: MapSize = DEFAULT_K
    alpha: Alpha = DEFAULT_ALPHA
    samples: Samples = DEFAULT_SAMPLES
    energy: Energy = Field("combined", description=ENERGY_DESCRIPTION)
    tracer: str = "geodesic"
    basis_plugin: str = "laplace-beltrami"
    basis_params: dict[str, Any] = Field(default_factory=dict)
    sharing: Sharing = Field("private", description=SHARING_DESCRIPTION)


SOLVER_FIELDS = ("k", "alpha", "samples", "energy", "tracer", "basis_plugin", "basis_params")
"""What a collection passes on to each member session."""


class CollectionRecord(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    id: str
    name: str = ""
    owner: str = ""
    sharing: Sharing = Field("private", description=SHARING_DESCRIPTION)
    template: str = Field(description="shape id of the template (every member session's source)")
    k: MapSize
    alpha: Alpha
    samples: Samples
    energy: Energy
    tracer: str
    basis_plugin: str
    basis_params: dict[str, Any]
    curves: list[TemplateCurve] = Field(default_factory=list)
    members: list[Member] = Field(default_factory=list)
    runs: list[Run] = Field(default_factory=list)
    next_member: int = 1
    next_run: int = 1
    revision: int = 0
    created_at: float
    updated_at: float

    def member(self, member_id: str) -> Member:
        for member in self.members:
            if member.id == member_id:
                return member
        raise _unknown(self, "member", member_id, [m.id for m in self.members])

    def run(self, run_id: str) -> Run:
        for run in self.runs:
            if run.id == run_id:
                return run
        raise _unknown(self, "run", run_id, [r.id for r in self.runs])

    def template_curve(self, curve_id: str) -> TemplateCurve:
        for curve in self.curves:
            if curve.id == curve_id:
                return curve
        raise _unknown(self, "template curve", curve_id, [c.id for c in self.curves])


def _unknown(record: CollectionRecord, what: str, given: str, ids: list[str]) -> NotFound:
    return NotFound(
        f"no {what} '{shown(given)}' in collection {record.id}; its {what}s: {', '.join(ids) or 'none yet'}"
    )
