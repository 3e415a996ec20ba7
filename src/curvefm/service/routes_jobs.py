"""``/jobs``, ``/plugins`` and ``/health`` (the one route that needs no credentials)."""

from __future__ import annotations

import re

from fastapi import APIRouter
from fastapi.responses import FileResponse

from curvefm import registry
from curvefm.errors import Conflict, NotFound, shown
from curvefm.service.auth import AUTHENTICATED, CurrentUser
from curvefm.service.deps import JOB_ERRORS, ServicesDep, job_admission, job_model, refined_session, results_dir
from curvefm.service.errors import error_responses
from curvefm.service.filenames import download_name
from curvefm.service.models import JobInfoModel
from curvefm.service.openapi import SchemaRoute
from curvefm.service.permissions import job_for

router = APIRouter(route_class=SchemaRoute, dependencies=AUTHENTICATED, responses=error_responses(401, 403, 507))
public = APIRouter(route_class=SchemaRoute)
ERRORS = {**error_responses(404, 409, 422), **JOB_ERRORS}
_SAFE_NAME = re.compile(r"^[A-Za-z0-9_-][A-Za-z0-9_.-]{0,127}$")
FILE_TYPES = {".txt": "text/plain", ".obj": "model/obj", ".mat": "application/x-matlab-data", ".zip": "application/zip"}
"""Media types of the result files by suffix; any other file (``.npy``) is ``application/octet-stream``."""
BINARY = "application/octet-stream"
FILE_CONTENT = {media_type: {"schema": {"type": "string"}} for media_type in FILE_TYPES.values()}
FILE_CONTENT[BINARY] = {"schema": {"type": "string", "format": "binary"}}


@router.get("/jobs/{job_id}", response_model=JobInfoModel, responses=ERRORS, tags=["jobs"])
def get_job(job_id: str, services: ServicesDep, user: CurrentUser) -> JobInfoModel:
    """State, progress (0..1 with a message), links to results, or why the job failed (a kind and one line).
    ``lost``: the queue lost the job (its Redis restarted empty, or the service restarted while running it
    in-process); ``message`` says so, and ``POST /jobs/{id}/retry`` runs it again."""
    return job_model(job_for(services, user, job_id))


@router.post(
    "/jobs/{job_id}/retry",
    status_code=202,
    response_model=JobInfoModel,
    responses={**ERRORS, **error_responses(413, 429)},
    tags=["jobs"],
)
def retry_job(job_id: str, services: ServicesDep, user: CurrentUser) -> JobInfoModel:
    """Run a lost, failed or canceled job again (same kind, arguments and owner: the user who started it, or an
    admin) and answer the new job; any other state answers 409. Retrying again while the new job is queued or
    running answers that job. A refinement whose session was deleted is not run again (409). The new job counts in
    your concurrent-jobs quota as any (429 at it)."""
    job_for(services, user, job_id, act=True)
    session_id = refined_session(services, job_id)
    if session_id is not None and not services.records.exists(session_id):
        raise Conflict(f"job {job_id} refined session {session_id}, which was deleted; there is nothing to retry")
    return job_model(services.queue.retry(job_id, job_admission(services, user)))


@router.delete("/jobs/{job_id}", response_model=JobInfoModel, responses=ERRORS, tags=["jobs"])
def cancel_job(job_id: str, services: ServicesDep, user: CurrentUser) -> JobInfoModel:
    """Cancel a queued job, or stop a running one (the user who started it, or an admin); a job that already
    ended answers 409."""
    job_for(services, user, job_id, act=True)
    return job_model(services.queue.cancel(job_id))


@router.get(
    "/jobs/{job_id}/files/{name}",
    response_class=FileResponse,
    responses={200: {"content": FILE_CONTENT}, **error_responses(404, 422)},
    tags=["jobs"],
)
def get_job_file(job_id: str, name: str, services: ServicesDep, user: CurrentUser) -> FileResponse:
    """A file a refinement job wrote (listed in its ``links``): maps as text (``.txt``), numpy arrays
    (``.npy``), both kinds of maps for MATLAB (``maps.mat``), the textured target (``.obj``, and with its material
    and texture image as ``target_textured.zip``); whoever may see the job may fetch it. It is saved as
    ``<session name>_<session id>_<converter>_r<revision>_<name>`` (Content-Disposition), so that results of other
    converters or revisions do not overwrite it."""
    info = job_for(services, user, job_id)
    path = results_dir(services, job_id) / name
    if not (_SAFE_NAME.match(job_id) and _SAFE_NAME.match(name) and path.is_file()):
        raise NotFound(f"job {shown(job_id)} has no result file '{shown(name)}'")
    return FileResponse(
        path, filename=_saved_as(info.result or {}, name), media_type=FILE_TYPES.get(path.suffix, BINARY)
    )


def _saved_as(result: dict, name: str) -> str:
    """A refinement's file is saved under its session, converter and revision (:mod:`curvefm.service.filenames`);
    jobs stored before results named their session's name say its id only."""
    if "session" not in result:
        return name
    return download_name(
        result["session"], result.get("session_name", ""), result["converter"], result["revision"], name
    )


@router.get("/plugins", tags=["plugins"])
def list_plugins() -> dict[str, list[dict]]:
    """Installed tracers, bases and converters, each with its parameters' JSON schema."""
    return registry.describe_all()


@public.get("/health", tags=["service"], responses=JOB_ERRORS)
def health(services: ServicesDep) -> dict:
    """``ok``, how jobs run (``embedded`` or ``redis``) and the records' database (``sqlite`` or ``postgresql``);
    503 while the job queue's Redis or the database does not answer."""
    services.queue.check()
    return {"status": "ok", "jobs": services.queue.mode, "database": services.database.check()}
