"""Requests per second per credential: a token bucket (GCRA), in Redis when configured, else in this process.

A credential is the bearer token, else the cookie header, else (no credential) the client's address; the bucket
is keyed by a SHA-256 of it, so no token is stored. With Redis, every API process of a deployment shares one
bucket per credential: the check is one Lua script, atomic, on Redis's clock. ``/health`` and the UI's static
files are not limited (``exempt``).

GCRA ("generic cell rate algorithm") keeps one number per bucket, the theoretical arrival time ``tat`` of the
next request: at ``rate`` requests per second each request moves it ``1 / rate`` later, and a request is
allowed while ``tat`` is less than ``burst / rate`` ahead of now. So ``burst`` requests pass at once, then
``rate`` per second.
"""

from __future__ import annotations

import hashlib
import logging
import math
import time
from collections.abc import Callable

from curvefm.errors import TooMany
from curvefm.service.errors import error_response
from curvefm.service.settings import Settings, env_name

log = logging.getLogger("curvefm.service")

# KEYS[1]: the bucket; ARGV[1]: microseconds per request; ARGV[2]: burst. Returns microseconds to wait (0: go).
GCRA_LUA = """
local clock = redis.call('TIME')
local now = tonumber(clock[1]) * 1000000 + tonumber(clock[2])
local interval = tonumber(ARGV[1])
local tat = math.max(tonumber(redis.call('GET', KEYS[1]) or now), now)
local wait = tat - interval * (tonumber(ARGV[2]) - 1) - now
if wait > 0 then
  return math.ceil(wait)
end
local next_tat = tat + interval
redis.call('SET', KEYS[1], string.format('%.0f', next_tat), 'PX', math.ceil((next_tat - now) / 1000) + 1)
return 0
"""
MEMORY_BUCKETS_PRUNED_AT = 10_000
REDIS_ERROR_LOG_INTERVAL_S = 60.0


class MemoryBuckets:
    """GCRA buckets in this process (one API process without Redis)."""

    def __init__(self) -> None:
        self._tat: dict[str, float] = {}

    async def wait_s(self, key: str, interval: float, burst: int) -> float:
        now = time.monotonic()
        tat = max(self._tat.get(key, now), now)
        wait = tat - interval * (burst - 1) - now
        if wait > 0:
            return wait
        self._tat[key] = tat + interval
        if len(self._tat) > MEMORY_BUCKETS_PRUNED_AT:
            self._tat = {k: t for k, t in self._tat.items() if t > now}
        return 0.0

    async def close(self) -> None:
        pass


class RedisBuckets:
    """GCRA buckets in Redis, shared by every API process that uses the same Redis and key prefix."""

    def __init__(self, redis_url: str, prefix: str):
        from redis.asyncio import Redis

        self._redis = Redis.from_url(redis_url)
        self._script = self._redis.register_script(GCRA_LUA)
        self._prefix = f"curvefm:{prefix}rate:"

    async def wait_s(self, key: str, interval: float, burst: int) -> float:
        micros = await self._script(keys=[self._prefix + key], args=[max(1, round(interval * 1e6)), burst])
        return int(micros) / 1e6

    async def close(self) -> None:
        await self._redis.aclose()


class RateLimit:
    """ASGI middleware: a request over its credential's rate answers 429 with ``Retry-After``."""

    def __init__(self, app, settings: Settings, buckets: MemoryBuckets | RedisBuckets, exempt: Callable[[str], bool]):
        self.app, self.buckets, self.exempt = app, buckets, exempt
        self.interval, self.burst = 1.0 / settings.rate_limit, max(1, settings.rate_burst)
        self.rate = settings.rate_limit
        self._last_error_log = -math.inf

    async def __call__(self, scope, receive, send) -> None:
        if scope["type"] == "http" and not self.exempt(scope["path"]):
            wait = await self._wait_s(credential_key(scope))
            if wait > 0:
                await error_response(self._limited(wait))(scope, receive, send)
                return
        await self.app(scope, receive, send)

    async def _wait_s(self, key: str) -> float:
        try:
            return await self.buckets.wait_s(key, self.interval, self.burst)
        except Exception:  # Redis unreachable: serve rather than refuse everyone; say so in the log
            if time.monotonic() - self._last_error_log > REDIS_ERROR_LOG_INTERVAL_S:
                self._last_error_log = time.monotonic()
                log.warning("rate limit not applied: its Redis does not answer", exc_info=True)
            return 0.0

    def _limited(self, wait: float) -> TooMany:
        rate, burst = env_name("rate_limit"), env_name("rate_burst")
        return TooMany(
            f"more than {self.rate:g} requests per second (bursts of {self.burst}) with this credential; retry in "
            f"{math.ceil(wait * 1000)} ms (the limits are {rate} and {burst})",
            setting=rate,
            retry_after=wait,
        )


def make_buckets(settings: Settings) -> MemoryBuckets | RedisBuckets:
    if settings.redis_url:
        return RedisBuckets(settings.redis_url, settings.queue_prefix)
    return MemoryBuckets()


def credential_key(scope) -> str:
    """A hash of what identifies the caller: bearer token, else cookies, else the client's address."""
    headers = dict(scope["headers"])
    authorization = headers.get(b"authorization", b"")
    if authorization[:7].lower() == b"bearer ":
        credential = b"bearer:" + authorization[7:].strip()
    elif b"cookie" in headers:
        credential = b"cookie:" + headers[b"cookie"]
    else:
        credential = b"address:" + (scope.get("client") or ("?",))[0].encode()
    return hashlib.sha256(credential).hexdigest()[:32]
