"""Requests per second per user: a token bucket (GCRA), in Redis when configured, else in this process.

A request is counted against its user when its credential (the bearer token, else the login cookie) authenticates
(looked up once a minute per process, off the event loop); a request whose credential does not, against the
client's address. So a stream of made-up tokens or cookies shares one address's allowance instead of getting a
fresh one each. A request with no credential at all is not counted: it can only be answered 401 (or 404 for a
path that is no route), which costs no more than a 429, and a client without credentials is told it needs them.
Buckets are keyed by a SHA-256, so no token is stored. With Redis, every API process of a deployment shares one
bucket per key: the check is one Lua script, atomic, on Redis's clock. ``/health`` and the UI's static files are
not limited (``exempt``).

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

import anyio
from starlette.requests import Request

from curvefm.errors import TooMany
from curvefm.service.auth import cookie_name, identify
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
KNOWN_CREDENTIALS_KEPT = 10_000
KNOWN_CREDENTIAL_S = 60.0  # a rotated token is refused by the routes at once; this only picks its bucket
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
        self.known = KnownCredentials()
        self._last_error_log = -math.inf

    async def __call__(self, scope, receive, send) -> None:
        if scope["type"] == "http" and not self.exempt(scope["path"]):
            request = Request(scope)
            credential = credential_hash(request)
            wait = 0.0 if credential is None else await self._wait_s(await self._bucket(request, credential))
            if wait > 0:
                await error_response(self._limited(wait))(scope, receive, send)
                return
        await self.app(scope, receive, send)

    async def _bucket(self, request: Request, credential: str) -> str:
        """``user:ID`` for a credential that authenticates (looked up once a minute per process), else the
        client's address."""
        user_id = self.known.get(credential)
        if user_id is None:
            user = await anyio.to_thread.run_sync(identify, request)
            if user is not None:
                user_id = self.known.add(credential, user.id)
        if user_id is not None:
            return f"user:{user_id}"
        return "address:" + hashlib.sha256((request.client.host if request.client else "?").encode()).hexdigest()[:32]

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


class KnownCredentials:
    """The credentials that authenticated in this process lately, each with its user's id."""

    def __init__(self) -> None:
        self._users: dict[str, tuple[int, float]] = {}

    def get(self, credential: str | None) -> int | None:
        known = self._users.get(credential or "")
        return known[0] if known is not None and known[1] > time.monotonic() else None

    def add(self, credential: str, user_id: int) -> int:
        now = time.monotonic()
        if len(self._users) >= KNOWN_CREDENTIALS_KEPT:
            self._users = {key: known for key, known in self._users.items() if known[1] > now}
        self._users[credential] = (user_id, now + KNOWN_CREDENTIAL_S)
        return user_id


def credential_hash(request: Request) -> str | None:
    """A hash of the request's credential: its bearer token, else its login cookie (None: neither)."""
    authorization = request.headers.get("authorization", "")
    if authorization[:7].lower() == "bearer ":
        credential = "bearer:" + authorization[7:].strip()
    else:
        cookie = request.cookies.get(cookie_name(request))
        if cookie is None:
            return None
        credential = "cookie:" + cookie
    return hashlib.sha256(credential.encode()).hexdigest()[:32]
