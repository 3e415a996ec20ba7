"""What every route needs, created once per app at startup and found through ``request.app.state``."""

from __future__ import annotations

import threading
from dataclasses import asdict, dataclass, field
from functools import partial
from pathlib import Path
from typing import Annotated

from fastapi import Depends, Request

from curvefm.access import AuditLog, User, Users, signing_key
from curvefm.collection import CollectionEditor, JobView
from curvefm.errors import NotFound
from curvefm.records import SYSTEM, Database, Viewer
from curvefm.records.collections import Collections
from curvefm.records.comments import ReviewComments
from curvefm.records.engine import shared_database
from curvefm.records.legacy_import import ImportReport, import_if_needed
from curvefm.records.sessions import Sessions
from curvefm.records.sessions import blob_bytes as stored_mesh_bytes
from curvefm.records.shapes import Shapes
from curvefm.records.usage import Quotas
from curvefm.records.webhooks import Webhooks
from curvefm.service.errors import error_responses, require_plugin
from curvefm.service.expiry import start_expiry
from curvefm.service.login import LoginCookies
from curvefm.service.models import JobInfoModel
from curvefm.service.oidc import SingleSignOn
from curvefm.service.quotas import quotas as make_quotas
from curvefm.service.settings import Settings, env_name
from curvefm.service.uploads import UploadSlots
from curvefm.session import LiveSessions, SessionEditor, SessionRecord
from curvefm.store import Store, params_key
from curvefm.webhooks.delivery import DeliveryPolicy, start_delivery
from curvefm.workers.factory import make_queue
from curvefm.workers.interface import Admission, JobInfo, JobQueue

JOB_ERRORS = error_responses(503, 507)
"""What every route that reaches the job queue may answer besides its own errors: its Redis does not answer, the
disk of its records is full."""


@dataclass
class Services:
    settings: Settings
    store: Store
    queue: JobQueue
    records: Sessions
    live: LiveSessions
    sessions: SessionEditor
    users: Users
    audit: AuditLog
    quotas: Quotas
    logins: LoginCookies
    collections: CollectionEditor
    database: Database
    shapes: Shapes
    uploads: UploadSlots
    webhooks: Webhooks
    """The collections' webhooks: ``services.webhooks.notify(collection_id, WebhookEvent.X, data)`` announces an
    event (posted by this process's delivery loop, or another API process's)."""
    comments: ReviewComments
    """The collection members' review comments, pinned to vertices."""
    sso: SingleSignOn | None = None  # single sign-on, when configured
    stop_events: list[threading.Event] = field(default_factory=list)

    def close(self) -> None:
        for event in self.stop_events:
            event.set()
        self.queue.close()
        self.live.close()


def open_records(settings: Settings) -> tuple[Database, ImportReport | None]:
    """The records' database of the service (migrated to this version's schema; a database that is not
    curvefm's is a clear error), with the data directory in the old JSON-file layout imported at its first start
    (the report; None when there was nothing to import)."""
    database = shared_database(settings.data_dir, settings.database_url)
    return database, import_if_needed(database, settings.data_dir, mark_fresh=True)


def start_services(settings: Settings) -> Services:
    store = Store(settings.data_dir)
    database, _ = open_records(settings)
    queue = make_queue(
        settings.redis_url,
        store.root,
        settings.queue_prefix,
        settings.job_retries,
        settings.embedded_workers,
        settings.job_ttl_s,
        settings.sizing,
        None if settings.redis_url else settings.memory_budget(),
        settings.webhook_log_size,
    )
    records = Sessions(
        database,
        max_curves=settings.max_curves,
        max_curve_bytes=8 * settings.max_path_vertices,
        lock_timeout_s=settings.session_lock_timeout_s,
        stored_shape=partial(stored_mesh_bytes, store),
        max_session_bytes=settings.max_session_bytes,
        webhook_log_size=settings.webhook_log_size,
    )
    live = LiveSessions(
        store,
        records,
        size=settings.live_sessions,
        display_vertices=settings.display_vertices,
        prior_max_vertices=settings.prior_max_vertices,
        guided_trace_vertices=settings.guided_trace_vertices,
    )
    # require_plugin's errors list the installed plugins
    sessions = SessionEditor(records, live, find_plugin=require_plugin, limits=settings.session_limits)
    quotas = make_quotas(settings, database)
    users, audit = Users(database), AuditLog(database, store.root)
    logins = LoginCookies(signing_key(store.root), users, settings.login_ttl_s)
    collections = CollectionEditor(Collections(database, records), sessions)
    services = Services(
        settings,
        store,
        queue,
        records,
        live,
        sessions,
        users,
        audit,
        quotas,
        logins,
        collections,
        database,
        Shapes(database),
        UploadSlots(settings),
        Webhooks(database, settings.webhook_log_size),
        ReviewComments(database),
        SingleSignOn(settings) if settings.sso else None,
    )
    expiry = start_expiry(queue, store.root, settings.job_ttl_s, settings.expiry_interval_s)
    services.stop_events.append(expiry)
    services.stop_events.append(start_delivery(services.webhooks, delivery_policy(settings), settings.webhook_poll_s))
    return services


def delivery_policy(settings: Settings) -> DeliveryPolicy:
    return DeliveryPolicy(
        settings.webhook_timeout_s,
        settings.webhook_retries,
        settings.webhook_retry_delay_s,
        settings.webhook_allow_private,
        env_name("webhook_allow_private"),
    )


def viewer(user: User | None) -> Viewer:
    """Whom a database list or check is for."""
    return SYSTEM if user is None else Viewer(user.id, user.admin)


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
    """The job as the API answers it; a lost job's reason is its ``error`` too, as a failed job's is."""
    fields = asdict(info)
    if info.state == "lost" and info.error is None:
        fields["error"] = {"kind": "lost", "message": info.message}
    return JobInfoModel(**fields, links=job_links(info))


def job_view(services: Services, job_id: str) -> JobView:
    """A job as the collection domain sees it (``lost`` when the queue forgot it, or its record expired)."""
    try:
        info = services.queue.get(job_id)
    except NotFound:
        return JobView("lost", message=EXPIRED)
    error = info.error.message if info.error else None
    return JobView(info.state, info.progress, info.message, error, info.result)


EXPIRED = (
    "the job's record expired (ended jobs and their results are kept CURVEFM_JOB_TTL seconds); start a new run of "
    "the members to have their maps again"
)


def job_admission(services: Services, user: User) -> Admission:
    """The user's concurrent-jobs quota (429) and byte quota (413), checked in the transaction that writes the
    job's record: a user's parallel submissions cannot pass the quota together."""
    return partial(services.quotas.admit, user, "jobs")


def submit_refine(
    services: Services, record: SessionRecord, converter: str, params: dict, owner: str, admit: Admission | None
) -> JobInfo:
    """Queue a refinement of a snapshot of a session (``params`` canonical), noted on the session, admitted by
    ``admit``."""
    kwargs = {
        "data_dir": str(services.store.root),
        "session": record.model_dump(mode="json"),
        "converter": converter,
        "params": params,
    }
    return services.queue.submit("refine", kwargs, owner=owner, admit=admit, session_id=record.id)


def submit_basis(
    services: Services, mesh_id: str, k: int, plugin: str, params: dict, owner: str, admit: Admission | None = None
) -> JobInfo:
    """Queue a basis job of ``owner`` (``params`` canonical), deduplicated by (shape, plugin, k, parameters),
    admitted by ``admit``."""
    kwargs = {
        "data_dir": str(services.store.root),
        "mesh_id": mesh_id,
        "k": k,
        "plugin": plugin,
        "params": params,
        "display_vertices": services.settings.display_vertices,
    }
    dedupe_key = f"basis:{mesh_id}:{plugin}:{k}:{params_key(params)}"
    return services.queue.submit("basis", kwargs, dedupe_key=dedupe_key, owner=owner, admit=admit)
