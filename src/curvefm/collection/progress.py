"""Where a collection stands: per member its basis, its answered curves and its job in a run; a run's maps once
every member's job finished. Jobs are seen through :class:`JobView` (the caller reads its queue)."""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import BaseModel, Field

from curvefm.collection.archive import MemberMaps, load_member_maps
from curvefm.collection.record import CollectionRecord, Member, Run
from curvefm.errors import Conflict
from curvefm.session import SessionRecord


@dataclass(frozen=True)
class JobView:
    state: str
    progress: float = 0.0
    message: str = ""
    error: str | None = None
    result: dict[str, Any] | None = None


JobOf = Callable[[str], JobView]


class MemberRunState(BaseModel):
    member: str
    job: str
    state: str = Field(description="the job's state: queued, started, finished, failed, canceled or lost")
    progress: float
    message: str
    error: str | None = Field(None, description="why the job failed")
    revision: int = Field(description="the session revision the job refines")
    carried: bool = Field(description="taken over from the previous run")


class RunStatus(BaseModel):
    id: str
    converter: str
    params: dict[str, Any]
    created_at: float
    state: str = Field(
        description="finished (all members), failed (some ended unfinished, none pending), running or queued"
    )
    counts: dict[str, int] = Field(description="members per job state")
    members: list[MemberRunState]


class MemberStatus(BaseModel):
    id: str
    shape: str
    shape_name: str = Field("", description="the shape's name (its file's)")
    session: str
    basis: str = Field(description="ready, or the basis job's state (queued, started, failed, ...)")
    basis_job: str | None
    curves_done: int = Field(description="template curves answered on the member")
    curves_total: int = Field(description="template curves of the collection")
    extra_curves: int = Field(description="the member's curves that answer no template curve")
    revision: int = Field(description="the member session's revision")
    last_run: MemberRunState | None = Field(None, description="the member's job in the newest run that has it")


def member_status(
    record: CollectionRecord, member: Member, session: SessionRecord, basis: str, job_of: JobOf, shape_name: str = ""
) -> MemberStatus:
    templates = {c.id for c in record.curves}
    answered = {c.spec.template_curve for c in session.curves} & templates
    extra = sum(c.spec.template_curve not in templates for c in session.curves)
    last = next((run for run in reversed(record.runs) if member.id in run.members), None)
    return MemberStatus(
        id=member.id,
        shape=member.shape,
        shape_name=shape_name,
        session=member.session,
        basis=basis,
        basis_job=member.basis_job,
        curves_done=len(answered),
        curves_total=len(templates),
        extra_curves=extra,
        revision=session.revision,
        last_run=_member_run(last, member.id, job_of) if last else None,
    )


def run_status(run: Run, job_of: JobOf) -> RunStatus:
    members = [_member_run(run, member_id, job_of) for member_id in run.members]
    counts = Counter(m.state for m in members)
    pending = counts["queued"] + counts["started"]
    if counts["finished"] == len(members):
        state = "finished"
    elif not pending:
        state = "failed"
    else:
        state = "running" if counts["started"] or counts["finished"] else "queued"
    fields = run.model_dump(include={"id", "converter", "params", "created_at"})
    return RunStatus(**fields, state=state, counts=dict(counts), members=members)


def run_maps(
    record: CollectionRecord, run: Run, job_of: JobOf, results: Path, only: list[str] | None = None
) -> list[MemberMaps]:
    """The maps of the run's members (``only`` these), read from their jobs' results; 409 naming the members that
    are pending or ended unfinished."""
    wanted = only or list(run.members)
    status = {m.member: m for m in run_status(run, job_of).members if m.member in wanted}
    unfinished = [
        f"{m.member} {m.state}" + (f" ({m.error})" if m.error else "") for m in status.values() if m.state != "finished"
    ]
    if unfinished:
        raise Conflict(
            f"run {run.id} of collection {record.id} is not finished for every member asked: "
            f"{'; '.join(unfinished)}; wait for pending members, or re-run failed ones"
        )
    maps = []
    for member_id in wanted:
        member, job = record.member(member_id), run.members[member_id].job
        maps.append(
            load_member_maps(results / job, member_id, member.shape, member.session, job, job_of(job).result or {})
        )
    return maps


def archive_summary(
    record: CollectionRecord, run: Run, maps: list[MemberMaps], agreement: dict[str, Any] | None = None
) -> dict[str, Any]:
    """The archive's ``summary.json``; with ``agreement`` (the agreement report, given when the collection has
    double annotations) under that key."""
    return {
        "collection": record.id,
        "name": record.name,
        "template": record.template,
        "k": record.k,
        "run": run.id,
        "converter": run.converter,
        "params": run.params,
        "template_curves": [c.id for c in record.curves],
        "members": [m.summary() for m in maps],
        "directions": "map_member_to_template[i] is the template vertex of member vertex i (0-based file ids, -1: a "
        "vertex of no face); C_template_to_member takes template coefficients to member coefficients",
        **({"agreement": agreement} if agreement is not None else {}),
    }


def _member_run(run: Run, member_id: str, job_of: JobOf) -> MemberRunState:
    entry = run.members[member_id]
    job = job_of(entry.job)
    return MemberRunState(
        member=member_id,
        job=entry.job,
        state=job.state,
        progress=job.progress,
        message=job.message,
        error=job.error,
        revision=entry.revision,
        carried=entry.carried,
    )
