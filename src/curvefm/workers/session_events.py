"""Session events on Redis pub/sub: a small JSON message on the session's channel after each committed change
(published by the API process that made it, and by the worker that ended a refinement of it). Every API process
listens to the channels of its deployment (:func:`pattern`) and hands each message to the pages that follow the
session. A message is a hint to reload, never the data: one lost while Redis restarts costs a page its update
until the next change or its reconnect, which compares revisions."""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
from collections.abc import AsyncIterator

from redis import Redis
from redis.exceptions import RedisError
from rq.job import Job

from curvefm.workers.connection import CONNECT_TIMEOUT_S, UNREACHABLE, connect
from curvefm.workers.interface import one_line

log = logging.getLogger(__name__)
RECONNECT_S = 1.0


def channel(prefix: str, session_id: str) -> str:
    """The channel of a session's events, within the deployment that ``prefix`` (its queue prefix) names."""
    return f"curvefm:{prefix}session-events:{session_id}"


def pattern(prefix: str) -> str:
    """The channels of every session of the deployment."""
    return channel(prefix, "*")


def session_of(prefix: str, channel_name: str) -> str:
    return channel_name.removeprefix(channel(prefix, ""))


def publish(connection: Redis, prefix: str, session_id: str, event: dict) -> bool:
    """Publish ``event`` on the session's channel; whether Redis took it. A Redis that does not answer is logged,
    not raised: the change it announces is committed, and the pages catch up on their next change or reconnect."""
    try:
        connection.publish(channel(prefix, session_id), json.dumps(event))
    except UNREACHABLE as exc:
        log.warning("a session event was not published (Redis does not answer): %s", one_line(str(exc)))
        return False
    return True


def announce_refinement_end(job: Job, connection: Redis, state: str) -> None:
    """A worker ended a refinement job (finished, failed for good, or canceled): tell its session's pages."""
    kind = "refine"
    if not job.origin.endswith(f"curvefm-{kind}"):
        return
    session = (job.kwargs.get("session") or {}).get("id")
    if session:
        prefix = job.origin.removesuffix(f"curvefm-{kind}")
        revision = (job.kwargs.get("session") or {}).get("revision")
        publish(connection, prefix, session, {"kind": "refined", "job": job.id, "state": state, "revision": revision})


class SessionChannels:
    """The session channels of one deployment (``prefix``) on the Redis at ``redis_url``: publish to them, and
    follow them all."""

    def __init__(self, redis_url: str, prefix: str):
        self.url, self.prefix = redis_url, prefix
        self.connection = connect(redis_url)

    def publish(self, session_id: str, event: dict) -> bool:
        """Whether Redis took the event (:func:`publish`)."""
        return publish(self.connection, self.prefix, session_id, event)

    async def follow(self, stopping: asyncio.Event) -> AsyncIterator[tuple[str, dict]]:
        """Every event published on the deployment's channels, as (session id, event), until ``stopping``. When
        Redis stopped answering and answers again, ``("", {"kind": "reconnected"})`` first: events may have been
        lost meanwhile."""
        from redis.asyncio import Redis as AsyncRedis

        lost = False
        while not stopping.is_set():
            client = AsyncRedis.from_url(self.url, socket_connect_timeout=CONNECT_TIMEOUT_S)
            try:
                async with client.pubsub() as pubsub:
                    await pubsub.psubscribe(pattern(self.prefix))
                    if lost:
                        lost = False
                        yield "", {"kind": "reconnected"}
                    while not stopping.is_set():
                        message = await pubsub.get_message(ignore_subscribe_messages=True, timeout=1.0)
                        if message is not None and message["type"] == "pmessage":
                            yield session_of(self.prefix, message["channel"].decode()), json.loads(message["data"])
            except (RedisError, OSError) as exc:
                if not lost:
                    log.warning("session events: Redis does not answer (%s); trying again", one_line(str(exc)))
                lost = True
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(stopping.wait(), RECONNECT_S)
            finally:
                await client.aclose()

    def close(self) -> None:
        self.connection.close()
