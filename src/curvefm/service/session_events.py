"""Live sessions: every page showing a session follows its changes over Server-Sent Events
(``GET /sessions/{id}/events``), whichever API process made them.

An event is a hint, never the data: its ``kind`` and the session's new ``revision``; the page reloads what it needs
through the other routes. Delivery across processes:

* with Redis, the process that commits a change (and the worker that ends a refinement) publishes the event on the
  session's channel (:mod:`curvefm.workers.session_events`), and every API process follows its deployment's
  channels and hands each event to its streams of that session;
* without Redis (several processes may serve one SQLite file), each process hands its own changes to its streams
  at once, and one poller per process reads, every ``events_poll_s``, the revisions, the last refinement's end and
  a mark of the member's review comments (:meth:`curvefm.records.viewers.Viewers.comment_marks`) of the sessions
  it has streams of (one query each, whatever the number of streams): another process's change arrives as
  ``changed`` (``refined``, ``comments``). A comment made on the stream's own process is heard twice then (at once,
  and from the poller's mark): a hint, harmless.

Presence: each stream is a row of ``session_viewers`` (:class:`curvefm.records.viewers.Viewers`) that its process
keeps alive at every tick; the same tick reads who has each followed session open, and a change of that is a
``viewers`` event. The rows also bound a user's streams across the processes (``max_event_streams``).

A stream says ``hello`` first (the session's revision and viewers: a page that reconnects compares revisions),
then the events, with a keep-alive comment every ``events_keepalive_s``; it ends after ``deleted``, after a
``sharing`` change that takes the user's access away (``forbidden``), and when the server shuts down
(``closing``: the browser reconnects to another process, or to this one once it is back).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import secrets
import time
from collections.abc import AsyncIterator, Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

from starlette.concurrency import run_in_threadpool

from curvefm.access import User
from curvefm.errors import CurvefmError
from curvefm.records.viewers import Viewers
from curvefm.service.deps import Services
from curvefm.service.permissions import session_for
from curvefm.service.settings import env_name
from curvefm.session import SessionRecord
from curvefm.workers.session_events import SessionChannels

log = logging.getLogger(__name__)

RETRY_MS = 2000
"""How long a browser waits before it reconnects a stream that ended (the SSE ``retry`` field)."""
QUEUE_SIZE = 64
"""Events a stream holds for a page that reads slowly; beyond, the oldest go (each says: reload)."""
PRESENCE_GRACE_S = 5.0
CHANGES = frozenset({"curve-added", "curve-removed", "curve-replaced", "renamed", "sharing", "changed"})
"""The kinds whose ``revision`` is the session's new one."""
ACCESS_CHANGES = frozenset({"sharing", "changed"})
"""The kinds after which a stream checks that its user may still read the session."""
CommentMark = tuple[Any, ...]
"""What changes with any change of a member's review comments (:meth:`Viewers.comment_marks`)."""
NO_COMMENTS: CommentMark = (0, None, 0, None)


@dataclass(eq=False)
class Stream:
    session_id: str
    user: User
    credential: Callable[[], User | None]
    """The user the stream's credential belongs to now (None once it was ended: a logout, a rotated token)."""
    queue: asyncio.Queue[dict] = field(default_factory=lambda: asyncio.Queue(QUEUE_SIZE))
    id: str = field(default_factory=lambda: secrets.token_hex(16))


@dataclass(frozen=True)
class Observed:
    """What one tick read: who has each followed session open; without Redis also their revisions (sessions
    gone left out), when their last refinement ended and the marks of their member's review comments."""

    present: dict[str, tuple[str, ...]]
    revisions: dict[str, int] | None = None
    refined: dict[str, float] | None = None
    comments: dict[str, CommentMark] | None = None


class SessionEvents:
    """The event streams of one API process, and how their events reach them."""

    def __init__(self, services: Services):
        settings = services.settings
        self.services, self.viewers = services, Viewers(services.database)
        self.poll_s, self.keepalive_s = settings.events_poll_s, settings.events_keepalive_s
        self.ttl_s = 3 * settings.events_poll_s + PRESENCE_GRACE_S
        self.max_streams = settings.max_event_streams
        self.channels = SessionChannels(settings.redis_url, settings.queue_prefix) if settings.redis_url else None
        self.publisher = ThreadPoolExecutor(1, thread_name_prefix="curvefm-events")
        self.streams: dict[str, dict[str, Stream]] = {}  # session id -> stream id -> stream
        self.revisions: dict[str, int] = {}  # per followed session: the newest revision its streams were told of
        self.refined: dict[str, float] = {}  # without Redis: when its last refinement ended, as last read
        self.comments: dict[str, CommentMark] = {}  # without Redis: the mark of its member's comments, as last read
        self.present: dict[str, tuple[str, ...]] = {}
        self.stopping = asyncio.Event()
        self.loop: asyncio.AbstractEventLoop | None = None
        self.tasks: list[asyncio.Task] = []

    async def start(self) -> None:
        self.loop = asyncio.get_running_loop()
        self.tasks.append(asyncio.create_task(self._tick()))
        if self.channels is not None:
            self.tasks.append(asyncio.create_task(self._follow_channels()))

    def stop(self) -> None:
        """End every stream now (the server is shutting down; uvicorn waits for open responses). Safe from any
        thread and from a signal handler."""
        if self.loop is not None and not self.loop.is_closed():
            self.loop.call_soon_threadsafe(self.stopping.set)

    async def close(self) -> None:
        self.stopping.set()
        for task in self.tasks:
            task.cancel()
        await asyncio.gather(*self.tasks, return_exceptions=True)
        open_ids = [stream_id for streams in self.streams.values() for stream_id in streams]
        with contextlib.suppress(Exception):  # the rows expire by themselves
            await run_in_threadpool(self.viewers.close, open_ids)
        self.publisher.shutdown()
        if self.channels is not None:
            self.channels.close()

    # -- changes, from any thread ---------------------------------------------------------------------------
    def notify(self, session_id: str, event: dict) -> None:
        """A change of the session was committed: tell every page that shows it, in every process. Called by
        the edit holding the session's lock: Redis is reached from a thread of its own, in order, so that an
        edit never waits for it."""
        if self.channels is None:
            self._hand_over(session_id, event)
        else:
            self.publisher.submit(self._publish, session_id, event)

    def _publish(self, session_id: str, event: dict) -> None:
        assert self.channels is not None
        if not self.channels.publish(session_id, event):  # Redis does not answer: this process's pages still hear
            self._hand_over(session_id, event)

    def _hand_over(self, session_id: str, event: dict) -> None:
        if self.loop is not None and not self.loop.is_closed():
            self.loop.call_soon_threadsafe(self._deliver, session_id, event)

    def _deliver(self, session_id: str, event: dict) -> None:
        """Give ``event`` to this process's streams of the session (all of them for ``""``)."""
        if event["kind"] in CHANGES and session_id in self.revisions:
            self.revisions[session_id] = max(self.revisions[session_id], event["revision"])
        targets = self.streams.get(session_id, {}).values() if session_id else self._all_streams()
        for stream in list(targets):
            if stream.queue.full():
                stream.queue.get_nowait()
            stream.queue.put_nowait(event)

    def _all_streams(self) -> list[Stream]:
        return [stream for streams in self.streams.values() for stream in streams.values()]

    # -- streams ----------------------------------------------------------------------------------------------
    async def open(self, user: User, record: SessionRecord, credential: Callable[[], User | None]) -> Stream:
        """A stream of the session for ``user`` (who may read it, by the ``credential`` that answers who the
        request's credential belongs to now), its ``hello`` queued; 429 when the user has ``max_event_streams``
        open."""
        stream = Stream(record.id, user, credential)
        following = record.id in self.streams
        self.streams.setdefault(record.id, {})[stream.id] = stream  # before reading: no change falls in between
        try:
            revision, viewers, polled = await run_in_threadpool(self._enter, stream)
        except BaseException:
            self._forget(stream)
            raise
        if not following:
            self.revisions.setdefault(record.id, revision)
            self.present.setdefault(record.id, viewers)
            if polled is not None:
                self.refined.setdefault(record.id, polled[0])
                self.comments.setdefault(record.id, polled[1])
        stream.queue.put_nowait({"kind": "hello", "revision": revision, "viewers": list(viewers)})
        return stream

    def _enter(self, stream: Stream) -> tuple[int, tuple[str, ...], tuple[float, CommentMark] | None]:
        """Record the stream (counted against the user's limit); the session's revision, viewers and (without
        Redis) its last refinement's end and its member's comment mark."""
        now = time.time()
        setting = env_name("max_event_streams")
        self.viewers.open(
            stream.id, stream.session_id, stream.user.id, now, now + self.ttl_s, self.max_streams, setting
        )
        sessions = [stream.session_id]
        revision = self.viewers.revisions(sessions).get(stream.session_id, -1)
        polled = None
        if self.channels is None:
            refined = self.viewers.refinements_ended(sessions).get(stream.session_id, 0.0)
            polled = refined, self.viewers.comment_marks(sessions).get(stream.session_id, NO_COMMENTS)
        return revision, self.viewers.present(sessions, now)[stream.session_id], polled

    def _forget(self, stream: Stream) -> None:
        streams = self.streams.get(stream.session_id, {})
        streams.pop(stream.id, None)
        if not streams:
            for known in (self.streams, self.revisions, self.refined, self.comments, self.present):
                known.pop(stream.session_id, None)
        if self.loop is not None and not self.loop.is_closed():  # not awaited: the stream may be being canceled
            self.loop.run_in_executor(None, self._close_row, stream.id)

    def _close_row(self, stream_id: str) -> None:
        try:
            self.viewers.close([stream_id])
        except Exception as exc:  # the row expires by itself
            log.warning("an event stream's presence row stays until it expires: %s", type(exc).__name__)

    async def feed(self, stream: Stream) -> AsyncIterator[str]:
        """The stream's text/event-stream body."""
        try:
            yield f"retry: {RETRY_MS}\n\n"
            while not self.stopping.is_set():
                event = await self._next(stream)
                if event is None:  # idle: does the stream's credential still let it read the session?
                    ended = await run_in_threadpool(self._access_ended, stream)
                    if ended is not None:
                        yield _sse({"kind": ended, "revision": self.revisions.get(stream.session_id)})
                        return
                    yield ": keep-alive\n\n"
                    continue
                if event["kind"] in ACCESS_CHANGES and not await run_in_threadpool(self._may_read, stream):
                    yield _sse({"kind": "forbidden", "revision": event["revision"]})
                    return
                yield _sse(event)
                if event["kind"] == "deleted":
                    return
            yield _sse({"kind": "closing", "revision": self.revisions.get(stream.session_id)})
        finally:
            self._forget(stream)

    async def _next(self, stream: Stream) -> dict | None:
        """The stream's next event; None after ``keepalive_s`` without one, or when the server stops."""
        if not stream.queue.empty():
            return stream.queue.get_nowait()
        event, stop = asyncio.ensure_future(stream.queue.get()), asyncio.ensure_future(self.stopping.wait())
        try:
            done, _ = await asyncio.wait((event, stop), timeout=self.keepalive_s, return_when=asyncio.FIRST_COMPLETED)
        finally:
            event.cancel()
            stop.cancel()
        return event.result() if event in done else None

    def _access_ended(self, stream: Stream) -> str | None:
        """``logged-out`` when the stream's credential no longer authenticates (its login ended, its token was
        rotated, its user removed), ``forbidden`` when it may no longer read the session (a role taken away);
        None while it may go on, or when the records do not answer (the next keep-alive asks again)."""
        try:
            if stream.credential() is None:
                return "logged-out"
            return None if self._may_read(stream) else "forbidden"
        except Exception as exc:
            log.warning("session events: a stream's access could not be checked (%s)", type(exc).__name__)
            return None

    def _may_read(self, stream: Stream) -> bool:
        try:
            self.services.sessions.record(stream.session_id)
        except CurvefmError:  # deleted meanwhile: its own event follows
            return True
        try:
            session_for(self.services, stream.user, stream.session_id, "read")  # (a role in its collection counts)
        except CurvefmError:
            return False
        return True

    # -- the tick: presence (and without Redis, other processes' changes) -----------------------------------
    async def _tick(self) -> None:
        while not self.stopping.is_set():
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self.stopping.wait(), self.poll_s)
                return
            stream_ids = [stream_id for streams in self.streams.values() for stream_id in streams]
            if not stream_ids:  # nothing to look at: an idle process writes nothing
                continue
            try:
                observed = await run_in_threadpool(self._observe, stream_ids, list(self.streams))
            except Exception as exc:  # the database did not answer: the next tick tries again
                log.warning("session events: the records could not be read (%s)", type(exc).__name__)
                continue
            self._compare(observed)

    def _observe(self, stream_ids: list[str], session_ids: list[str]) -> Observed:
        now = time.time()
        self.viewers.heartbeat(stream_ids, now, now + self.ttl_s)
        present = self.viewers.present(session_ids, now)
        if self.channels is not None:
            return Observed(present)
        return Observed(
            present,
            self.viewers.revisions(session_ids),
            self.viewers.refinements_ended(session_ids),
            self.viewers.comment_marks(session_ids),
        )

    def _compare(self, observed: Observed) -> None:
        """Deliver what changed since the last tick, for the sessions still followed."""
        for session_id, viewers in observed.present.items():
            if session_id in self.streams and viewers != self.present.get(session_id):
                self.present[session_id] = viewers
                self._deliver(session_id, {"kind": "viewers", "viewers": list(viewers)})
        if observed.revisions is None or observed.refined is None or observed.comments is None:
            return
        for session_id in list(self.revisions):
            revision = observed.revisions.get(session_id)
            if revision is None:
                self._deliver(session_id, {"kind": "deleted", "revision": None})
            elif revision > self.revisions[session_id]:
                self._deliver(session_id, {"kind": "changed", "revision": revision})
            ended = observed.refined.get(session_id, 0.0)
            if ended > self.refined.get(session_id, ended):
                self._deliver(session_id, {"kind": "refined", "revision": revision})
            if session_id in self.refined:
                self.refined[session_id] = max(self.refined[session_id], ended)
            mark = observed.comments.get(session_id, NO_COMMENTS)
            if revision is not None and session_id in self.comments and mark != self.comments[session_id]:
                self.comments[session_id] = mark
                self._deliver(session_id, {"kind": "comments", "revision": revision})

    async def _follow_channels(self) -> None:
        assert self.channels is not None
        async for session_id, event in self.channels.follow(self.stopping):
            self._deliver(session_id, event)


def _sse(event: dict) -> str:
    return f"data: {json.dumps(event, separators=(',', ':'))}\n\n"
