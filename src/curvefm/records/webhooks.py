"""Webhooks of collections (``webhooks``) and the outbox of their deliveries (``webhook_deliveries``).

:meth:`Webhooks.notify` writes one delivery per webhook subscribed to the event, in the caller's transaction when
given one (so an event is announced exactly when its change commits). An API process claims due deliveries
(:meth:`Webhooks.claim`: a lease, so two processes never post the same one at once), posts them
(:mod:`curvefm.webhooks.delivery`) and records each attempt (:meth:`Webhooks.attempted`). A webhook keeps its
newest ``log_size`` deliveries.

:func:`announce_run_end` is called by :mod:`.jobs` in the transaction that ends a job: when it was the last job of
a run to end, the run's end is announced (once, whichever process ends the last job).
"""

from __future__ import annotations

import secrets
import time
from collections import Counter
from dataclasses import dataclass
from typing import Any

from sqlalchemy import Connection, Row, Select, delete, func, insert, select, update

from curvefm.errors import LimitExceeded, NotFound, shown
from curvefm.records import models as m
from curvefm.records.common import Page, check_page, well_formed
from curvefm.records.engine import Database
from curvefm.webhooks.events import WebhookEvent, event_body
from curvefm.webhooks.signing import new_secret

DEFAULT_LOG_SIZE = 100
EXPIRED = "expired"
"""A run member whose job record is gone (it ended long ago)."""


@dataclass(frozen=True)
class WebhookRow:
    id: str
    collection_id: str
    url: str
    events: list[str]
    created_by: str | None
    created_at: float
    last_delivery: DeliveryRow | None = None


@dataclass(frozen=True)
class DeliveryRow:
    id: str
    webhook_id: str
    event: str
    state: str
    attempts: int
    created_at: float
    next_attempt_at: float
    last_attempt_at: float | None
    last_status: int | None
    last_error: str | None


@dataclass(frozen=True)
class Due:
    """A delivery to attempt now: where, with which secret, what body, and how many attempts came before."""

    id: str
    webhook_id: str
    event: str
    url: str
    secret: str
    body: str
    attempts: int


class Webhooks:
    def __init__(self, database: Database, log_size: int = DEFAULT_LOG_SIZE):
        self.db = database
        self.log_size = log_size

    def create(
        self, collection_id: str, url: str, events: list[WebhookEvent], user_id: int | None, limit: int
    ) -> tuple[WebhookRow, str]:
        """A new webhook and its secret (given out once: only the deliveries' signatures show it again); 413
        (``max_webhooks``) when the collection has ``limit`` already."""
        secret, webhook_id = new_secret(), "wh" + secrets.token_hex(8)
        with self.db.write() as conn:
            count = conn.execute(
                select(func.count()).select_from(m.Webhook).where(m.Webhook.collection_id == collection_id)
            ).scalar_one()
            if count >= limit:
                raise LimitExceeded("max_webhooks", limit, f"{count + 1} webhooks in collection {collection_id}")
            names = sorted({str(event) for event in events})
            values = {"url": url, "secret": secret, "events": names, "created_by": user_id, "created_at": time.time()}
            conn.execute(insert(m.Webhook).values(id=webhook_id, collection_id=collection_id, **values))
        return self.get(collection_id, webhook_id), secret

    def of_collection(self, collection_id: str) -> list[WebhookRow]:
        """The collection's webhooks, oldest first, each with its newest delivery."""
        with self.db.read() as conn:
            rows = conn.execute(_webhooks().where(m.Webhook.collection_id == collection_id)).all()
            return [_webhook(row, _last_delivery(conn, row.id)) for row in rows]

    def get(self, collection_id: str, webhook_id: str) -> WebhookRow:
        with self.db.read() as conn:
            row = conn.execute(_webhooks().where(*_named(collection_id, webhook_id))).first()
            if row is None:
                raise _unknown(collection_id, webhook_id)
            return _webhook(row, _last_delivery(conn, webhook_id))

    def delete(self, collection_id: str, webhook_id: str) -> None:
        """Delete the webhook and its deliveries (pending ones are not posted)."""
        with self.db.write() as conn:
            if conn.execute(delete(m.Webhook).where(*_named(collection_id, webhook_id))).rowcount == 0:
                raise _unknown(collection_id, webhook_id)

    def deliveries(self, collection_id: str, webhook_id: str, limit: int, offset: int = 0) -> Page[DeliveryRow]:
        """The webhook's deliveries, the newest first."""
        check_page(limit, offset)
        self.get(collection_id, webhook_id)
        where = m.WebhookDelivery.webhook_id == webhook_id
        with self.db.read() as conn:
            total = conn.execute(select(func.count()).select_from(m.WebhookDelivery).where(where)).scalar_one()
            query = _deliveries().where(where).order_by(*_newest_first()).offset(offset).limit(limit)
            items = [_delivery(row) for row in conn.execute(query)]
        return Page(items, total, limit, offset)

    def subscribed(self, collection_id: str, event: WebhookEvent) -> bool:
        """Whether a webhook of the collection wants ``event`` (to skip the work of finding out whether it
        happened)."""
        with self.db.read() as conn:
            rows = conn.execute(select(m.Webhook.events).where(m.Webhook.collection_id == collection_id))
            return any(str(event) in events for (events,) in rows)

    def notify(
        self,
        collection_id: str,
        event: WebhookEvent,
        data: dict[str, Any],
        conn: Connection | None = None,
        key: str | None = None,
    ) -> list[str]:
        """Announce ``event`` with ``data`` (JSON-able) to the collection's webhooks subscribed to it; returns the
        deliveries' ids. In ``conn``'s transaction when given. ``key`` names an occurrence that several processes
        may see: a webhook that has a delivery with that key gets no second one."""
        with self.db.joined(conn) as tx:
            return notify(tx, collection_id, event, data, key, self.log_size)

    def run_recorded(self, collection_id: str, run_id: str) -> None:
        """A run was just recorded: announce its end if its jobs all ended before it was (quick jobs)."""
        with self.db.write() as conn:
            announce_if_ended(conn, collection_id, run_id, self.log_size)

    def claim(self, now: float, lease_s: float, limit: int) -> list[Due]:
        """Up to ``limit`` pending deliveries that are due, leased to the caller until ``now + lease_s`` (another
        process claims them again only once the lease ran out: a process that died mid-delivery)."""
        due = (
            (m.WebhookDelivery.state == "pending")
            & (m.WebhookDelivery.next_attempt_at <= now)
            & ((m.WebhookDelivery.lease_until.is_(None)) | (m.WebhookDelivery.lease_until <= now))
        )
        candidates = select(m.WebhookDelivery.id).where(due).order_by(m.WebhookDelivery.next_attempt_at).limit(limit)
        with self.db.read() as conn:  # most looks find nothing: they take no write lock
            ids = list(conn.execute(candidates).scalars())
        if not ids:
            return []
        with self.db.write() as conn:
            claimed = [
                delivery_id
                for delivery_id in ids
                if conn.execute(
                    update(m.WebhookDelivery)
                    .where(m.WebhookDelivery.id == delivery_id, due)
                    .values(lease_until=now + lease_s)
                ).rowcount
                == 1
            ]
            if not claimed:
                return []
            rows = conn.execute(
                select(
                    m.WebhookDelivery.id,
                    m.WebhookDelivery.webhook_id,
                    m.WebhookDelivery.event,
                    m.Webhook.url,
                    m.Webhook.secret,
                    m.WebhookDelivery.body,
                    m.WebhookDelivery.attempts,
                )
                .join(m.Webhook, m.Webhook.id == m.WebhookDelivery.webhook_id)
                .where(m.WebhookDelivery.id.in_(claimed))
                .order_by(m.WebhookDelivery.next_attempt_at)
            ).all()
        return [Due(*row) for row in rows]

    def attempted(
        self, delivery_id: str, at: float, status: int | None, error: str | None, retry_at: float | None
    ) -> None:
        """Record an attempt: delivered (a 2xx ``status``), to be tried again at ``retry_at``, or failed for good
        (``retry_at`` None)."""
        delivered = status is not None and 200 <= status < 300
        state = "delivered" if delivered else "pending" if retry_at is not None else "failed"
        with self.db.write() as conn:
            conn.execute(
                update(m.WebhookDelivery)
                .where(m.WebhookDelivery.id == delivery_id)
                .values(
                    state=state,
                    attempts=m.WebhookDelivery.attempts + 1,
                    last_attempt_at=at,
                    last_status=status,
                    last_error=error,
                    lease_until=None,
                    next_attempt_at=retry_at if retry_at is not None else at,
                )
            )


def notify(
    conn: Connection,
    collection_id: str,
    event: WebhookEvent,
    data: dict[str, Any],
    key: str | None = None,
    log_size: int = DEFAULT_LOG_SIZE,
) -> list[str]:
    """As :meth:`Webhooks.notify`, in ``conn``'s transaction."""
    event = WebhookEvent(event)
    hooks = list(
        conn.execute(select(m.Webhook.id, m.Webhook.events).where(m.Webhook.collection_id == collection_id)).all()
    )
    created, ids = time.time(), []
    for webhook_id, events in hooks:
        if str(event) not in events or (key is not None and _has_key(conn, webhook_id, key)):
            continue
        delivery_id = "dl" + secrets.token_hex(8)
        body = event_body(delivery_id, event, collection_id, created, data)
        conn.execute(
            insert(m.WebhookDelivery).values(
                id=delivery_id,
                webhook_id=webhook_id,
                event=str(event),
                event_key=key,
                body=body,
                state="pending",
                attempts=0,
                created_at=created,
                next_attempt_at=created,
            )
        )
        _keep_newest(conn, webhook_id, log_size)
        ids.append(delivery_id)
    return ids


def announce_member_removed(conn: Connection, session_id: str, log_size: int) -> None:
    """The session is being deleted (in ``conn``'s transaction, before its row goes): when it is a collection's
    member, the member goes with it; announce ``member.removed``, whether the member was removed as such or its
    session was deleted directly (each webhook keeping its newest ``log_size`` deliveries)."""
    members = conn.execute(
        select(m.Member.collection_id, m.Member.id, m.Member.shape).where(m.Member.session_id == session_id)
    ).all()
    for collection_id, member_id, shape in members:
        data = {"member": member_id, "shape": shape}
        notify(conn, collection_id, WebhookEvent.MEMBER_REMOVED, data, log_size=log_size)


def announce_run_end(conn: Connection, job_id: str, log_size: int) -> None:
    """The job just ended (in ``conn``'s transaction): announce the end of each run of which it was the last job
    to end. The run's row is locked first, so of two last jobs ending at once the second sees the first's end."""
    runs = conn.execute(
        select(m.RunMember.collection_id, m.RunMember.run_id).where(m.RunMember.job_id == job_id).distinct()
    ).all()
    for collection_id, run_id in runs:
        announce_if_ended(conn, collection_id, run_id, log_size)


def announce_if_ended(conn: Connection, collection_id: str, run_id: str, log_size: int) -> bool:
    """Announce ``run.ended`` when every job of the run has ended (each end of a run once: a job retried and
    ended again ends the run again); whether it has ended."""
    run = conn.execute(
        select(m.Run.id, m.Run.converter)
        .where(m.Run.collection_id == collection_id, m.Run.id == run_id)
        .with_for_update()
    ).first()
    if run is None:
        return False
    states = conn.execute(
        select(m.RunMember.member_id, m.Job.state, m.Job.ended_at)
        .outerjoin(m.Job, m.Job.id == m.RunMember.job_id)
        .where(m.RunMember.collection_id == collection_id, m.RunMember.run_id == run_id)
    ).all()
    if any(state is not None and state not in m.ENDED_STATES for _, state, _ in states):
        return False
    last_end = max((ended_at or 0.0 for _, _, ended_at in states), default=0.0)
    counts = Counter(state or EXPIRED for _, state, _ in states)
    data = {"run": run_id, "converter": run.converter, "members": len(states), "states": dict(sorted(counts.items()))}
    key = f"run.ended:{collection_id}:{run_id}:{last_end!r}"
    notify(conn, collection_id, WebhookEvent.RUN_ENDED, data, key, log_size)
    return True


def _has_key(conn: Connection, webhook_id: str, key: str) -> bool:
    found = select(m.WebhookDelivery.id).where(
        m.WebhookDelivery.webhook_id == webhook_id, m.WebhookDelivery.event_key == key
    )
    return conn.execute(found.limit(1)).first() is not None


def _keep_newest(conn: Connection, webhook_id: str, log_size: int) -> None:
    """Forget the deliveries past the newest ``log_size``, unless they are still to be posted."""
    older = (
        select(m.WebhookDelivery.id, m.WebhookDelivery.state)
        .where(m.WebhookDelivery.webhook_id == webhook_id)
        .order_by(*_newest_first())
        .offset(log_size)
    )
    stale = [delivery_id for delivery_id, state in conn.execute(older) if state != "pending"]
    if stale:
        conn.execute(delete(m.WebhookDelivery).where(m.WebhookDelivery.id.in_(stale)))


def _newest_first() -> tuple[Any, Any]:
    return m.WebhookDelivery.created_at.desc(), m.WebhookDelivery.id.desc()


def _named(collection_id: str, webhook_id: str) -> tuple[Any, Any]:
    return m.Webhook.collection_id == collection_id, m.Webhook.id == webhook_id


def _unknown(collection_id: str, webhook_id: str) -> NotFound:
    shown_id = webhook_id if well_formed(webhook_id) else shown(webhook_id)
    return NotFound(f"collection {collection_id} has no webhook '{shown_id}'")


def _webhooks() -> Select[Any]:
    columns = [c for c in m.Webhook.__table__.c if c.name not in ("secret", "created_by")]
    return (
        select(*columns, m.User.name.label("creator"))
        .outerjoin(m.User, m.User.id == m.Webhook.created_by)
        .order_by(m.Webhook.created_at, m.Webhook.id)
    )


def _webhook(row: Row[Any], last: DeliveryRow | None) -> WebhookRow:
    return WebhookRow(row.id, row.collection_id, row.url, list(row.events), row.creator, row.created_at, last)


def _deliveries() -> Select[Any]:
    return select(*[c for c in m.WebhookDelivery.__table__.c if c.name not in ("body", "event_key", "lease_until")])


def _delivery(row: Row[Any]) -> DeliveryRow:
    return DeliveryRow(**row._asdict())


def _last_delivery(conn: Connection, webhook_id: str) -> DeliveryRow | None:
    query = _deliveries().where(m.WebhookDelivery.webhook_id == webhook_id).order_by(*_newest_first()).limit(1)
    row = conn.execute(query).first()
    return None if row is None else _delivery(row)
