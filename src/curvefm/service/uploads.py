"""Big uploads parsed at once: at most ``max_concurrent_uploads`` of at least ``big_upload_bytes``, counted across
every API process that shares the Redis of the job queue (in each process on its own without one); more answer
429 naming the limit, with ``Retry-After``.

Reading an upload (parsing and validating the mesh) peaks at about 4-5x its file's size in memory (docs:
performance, bench_uploads), so this bounds what uploads can take of an API host's memory. A slot is taken once
the body has arrived (it is spooled to disk on the way, which costs no memory), so a slow client holds none. In
Redis a slot is a member of a sorted set scored by its lease's end: a process killed while parsing leaves a slot
that the next admission drops once ``upload_lease_s`` has passed. When the Redis does not answer, each process
counts its own uploads rather than refuse them all (a warning says so).
"""

from __future__ import annotations

import logging
import threading
import uuid
from collections.abc import Iterator
from contextlib import contextmanager

from curvefm.errors import TooMany
from curvefm.service.settings import Settings, env_name

log = logging.getLogger("curvefm.service")

RETRY_AFTER_S = 5
"""What a refused upload is asked to wait: about the time a big upload takes to parse."""
REDIS_TIMEOUT_S = 2.0

# KEYS[1]: the slots; ARGV[1]: how many; ARGV[2]: the lease (seconds); ARGV[3]: this slot. Returns 1 if taken.
TAKE_LUA = """
local clock = redis.call('TIME')
local now = tonumber(clock[1]) + tonumber(clock[2]) / 1000000
redis.call('ZREMRANGEBYSCORE', KEYS[1], '-inf', now)
if redis.call('ZCARD', KEYS[1]) >= tonumber(ARGV[1]) then
  return 0
end
redis.call('ZADD', KEYS[1], now + tonumber(ARGV[2]), ARGV[3])
redis.call('EXPIRE', KEYS[1], math.ceil(tonumber(ARGV[2])) + 1)
return 1
"""


class LocalSlots:
    """The slots of this process."""

    def __init__(self, limit: int):
        self.limit, self.taken, self._lock = limit, 0, threading.Lock()

    def take(self, slot: str) -> bool:
        with self._lock:
            if self.taken >= self.limit:
                return False
            self.taken += 1
            return True

    def give_back(self, slot: str) -> None:
        with self._lock:
            self.taken -= 1


class RedisSlots:
    """The slots of every API process on one Redis and queue prefix."""

    def __init__(self, redis_url: str, prefix: str, limit: int, lease_s: float):
        from redis import Redis

        self.limit, self.lease_s = limit, lease_s
        self.key = f"curvefm:{prefix}uploads"
        self._redis = Redis.from_url(redis_url, socket_timeout=REDIS_TIMEOUT_S, socket_connect_timeout=REDIS_TIMEOUT_S)
        self._take = self._redis.register_script(TAKE_LUA)

    def take(self, slot: str) -> bool:
        return bool(self._take(keys=[self.key], args=[self.limit, self.lease_s, slot]))

    def give_back(self, slot: str) -> None:
        self._redis.zrem(self.key, slot)


class UploadSlots:
    def __init__(self, settings: Settings):
        self.limit, self.big = settings.max_concurrent_uploads, settings.big_upload_bytes
        self.local = LocalSlots(self.limit)
        self.shared = (
            RedisSlots(settings.redis_url, settings.queue_prefix, self.limit, settings.upload_lease_s)
            if settings.redis_url
            else None
        )

    @contextmanager
    def admit(self, size: int) -> Iterator[None]:
        """Hold a slot while an upload of ``size`` bytes is parsed (none for a small one, or without a limit);
        :class:`TooMany` if every slot is taken."""
        if not self.limit or size < self.big:
            yield
            return
        slot = uuid.uuid4().hex
        slots = self._take(slot)
        if slots is None:
            raise TooMany(
                f"{self.limit} uploads of {self.big} bytes or more are being read already; retry in "
                f"{RETRY_AFTER_S} s (the limit is {env_name('max_concurrent_uploads')}, the size "
                f"{env_name('big_upload_bytes')})",
                setting=env_name("max_concurrent_uploads"),
                retry_after=RETRY_AFTER_S,
            )
        try:
            yield
        finally:
            _give_back(slots, slot)

    def _take(self, slot: str) -> LocalSlots | RedisSlots | None:
        """Where ``slot`` was taken: the shared slots, or this process's own while their Redis does not answer;
        None when every slot is taken."""
        if self.shared is not None:
            try:
                return self.shared if self.shared.take(slot) else None
            except Exception as exc:  # RedisError, or an OSError of its connection
                why = type(exc).__name__
                log.warning("upload slots counted in this process alone: their Redis does not answer (%s)", why)
        return self.local if self.local.take(slot) else None


def _give_back(slots: LocalSlots | RedisSlots, slot: str) -> None:
    try:
        slots.give_back(slot)
    except Exception as exc:  # Redis went away: the slot's lease ends it
        log.warning("an upload slot is left to its lease: its Redis does not answer (%s)", type(exc).__name__)
