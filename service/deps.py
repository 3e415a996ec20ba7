"""What every route needs, created once per app at startup and found through ``request.app.state``."""

from __future__ import annotations

import threading
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Annotated

from fastapi import Depends, Request

from curvefm.access import AuditLog, Usage, UserStore, signing_key
from curvefm.collection import CollectionEditor, CollectionStore, JobView
from curvefm.service.errors import error_responses, require_plugin
from curvefm.service.expiry import start_expiry
from curvefm.service.login import LoginCookies
from curvefm.service.models import JobInfoModel
from curvefm.service.quotas import Quotas
from curvefm.service.settings import Settings
from curvefm.session import LiveSessions, SessionEditor, SessionRecord, SessionStore
from curvefm.store import Store, params_key
from curvefm.workers.factory import make_queue
from curvefm.workers.interface import JobInfo, JobQueue

JOB_ERRORS = error_responses(503)
"""What every route that reaches the job queue may answer besides its own errors: its Redis does not answer."""


@dataclass
class Services:
    settings: Settings
    store: Store
    queue: JobQueue
    records: SessionStore
    live: LiveSessions
    sessions: SessionEditor
    users: UserStore
    audit: AuditLog
    quotas: Quotas
    logins: LoginCookies
    collections: CollectionEditor
    stop_events: list[threading.Event] = field(default_factory=list)

    def close(self) -> None:
        for event in self.stop_events:
            event.set()
        self.queue.close()
        self.live.close()


def start_services(settings: Settings) -> Services:
    store = Store(settings.data_dir)
    queue = make_queue(
        settings.redis_url,
        store.root,
        settings.queue_prefix,
        settings.job_retries,
        settings.embedded_workers,
        settings.job_ttl_s,
    )
    records = SessionStore(store.root, lock_timeout_s=settings.session_lock_timeout_s)
    live = LiveSessions(
        store,
        records,
        size=settings.live_sessions,
        display_vertices=settings.display_vertices,
        prior_max_vertices=settings.prior_max_vertices,
    )
    # require_plugin's errors list the installed plugins
    sessions = SessionEditor(records, live, find_plugin=require_plugin, limits=settings.session_limits)
    quotas = Quotas(settings, Usage(store.root), store, records, queue)
    users, audit = UserStore(store.root), AuditLog(store.root)
    logins = LoginCookies(signing_key(store.root), users, settings.login_ttl_s)
    collections = CollectionEditor(CollectionStore(store.root, settings.session_lock_timeout_s), sessions)
    services = Services(settings, store, queue, records, live, sessions, users, audit, quotas, logins, collections)
    expiry = start_expiry(queue, store.root / "results", settings.job_ttl_s, settings.expiry_interval_s)
    services.stop_events.append(expiry)
    return services


async def get_services(request: Request) -> Services:
    # async: FastAPI runs a plain function dependency in a worker thread, a hand-off per dependency per request
    return request.app.state.services


ServicesDep = Annotated[Services, Depends(get_services)]


def results_dir(services: Services, job_id: str) -> Path:
    """Where a refinement job's files are (``curvefm.workers.jobs.refine`` writes them)."""
    return services.store.root / "results" / job_id


def refined_session(services: Services, job_id: str) -> str | None:
    """The session a refinement job was run from (None for other jobs, or one without a stored record)."""
    stored = services.queue.records.load(job_id)
    return stored.kwargs["session"]["id"] if stored is not None and stored.info.kind == "refine" else None


def job_links(info: JobInfo) -> dict[str, str]:
    """Where to fetch what a finished job produced."""
    if info.state != "finished" or not info.result:
        return {}
    if info.kind == "basis":
        return {"shape": f"/shapes/{info.result['shape']}"}
    return {name: f"/jobs/{info.id}/files/{name}" for name in info.result.get("files", [])}


def job_model(info: JobInfo) -> JobInfoModel:
    return JobInfoModel(**asdict(info), links=job_links(info))


def job_view(services: Services, job_id: str) -> JobView:
    """A job as the collection domain sees it (``lost`` when the queue forgot it)."""
    info = services.queue.get(job_id)
    error = info.error.message if info.error else None
    return JobView(info.state, info.progress, info.message, error, info.result)


def submit_refine(services: Services, record: SessionRecord, converter: str, params: dict, owner: str) -> JobInfo:
    """Queue a refinement of a snapshot of a session (``params`` canonical) and note it on the session."""
    kwargs = {
        "data_dir": str(services.store.root),
        "session": record.model_dump(mode="json"),
        "converter": converter,
        "params": params,
    }
    info = services.queue.submit("refine", kwargs, owner=owner)
    services.records.add_job(record.id, info.id)
    return info


def submit_basis(services: Services, mesh_id: str, k: int, plugin: str, params: dict, owner: str) -> JobInfo:
    """Queue a basis job of ``owner`` (``params`` canonical), deduplicated by (shape, plugin, k, parameters)."""
    kwargs = {
        "data_dir": str(services.store.root),
        "mesh_id": mesh_id,
        "k": k,
        "plugin": plugin,
        "params": params,
    }
    dedupe_key = f"basis:{mesh_id}:{plugin}:{k}:{params_key(params)}"
    return services.queue.submit("basis", kwargs, dedupe_key=dedupe_key, owner=owner)
