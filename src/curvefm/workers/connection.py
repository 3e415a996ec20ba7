"""Connecting to Redis: RQ's JSON serializer (no pickle crosses Redis), timeouts, and errors that name the
problem (a password missing or refused, a server that does not answer) without the password a URL holds."""

from __future__ import annotations

from redis import Redis
from redis.backoff import NoBackoff
from redis.exceptions import AuthenticationError
from redis.exceptions import ConnectionError as RedisConnectionError
from redis.exceptions import TimeoutError as RedisTimeoutError
from redis.retry import Retry
from rq.serializers import JSONSerializer

from curvefm.errors import InvalidInput, Unavailable
from curvefm.workers.interface import one_line

SERIALIZER = JSONSerializer
"""Every Queue, Job fetch and Worker of the project uses it: job arguments, metadata and results are JSON."""
CONNECT_TIMEOUT_S = 3.0
COMMAND_TIMEOUT_S = 10.0
UNREACHABLE = (RedisConnectionError, RedisTimeoutError)
"""What a Redis that is down, restarting, loading its data or refusing our password raises."""


def connect(url: str, worker: bool = False) -> Redis:
    """A connection to the Redis at ``url`` that has answered a ping. The API's fails fast (a request must not
    hang on a Redis that is down); a worker's has no command timeout, as RQ blocks on its queues."""
    # one immediate retry: a pooled connection that a Redis restart broke is replaced by a fresh one
    fail_fast = {"socket_timeout": COMMAND_TIMEOUT_S, "retry": Retry(NoBackoff(), 1)}
    options = {} if worker else fail_fast
    connection = Redis.from_url(url, socket_connect_timeout=CONNECT_TIMEOUT_S, **options)
    try:
        connection.ping()
    except AuthenticationError:
        raise InvalidInput(password_problem(connection)) from None
    except UNREACHABLE as exc:
        raise Unavailable(f"cannot reach Redis at {location(connection)}: {one_line(str(exc))}") from None
    return connection


def password_problem(connection: Redis) -> str:
    where = location(connection)
    if connection.connection_pool.connection_kwargs.get("password"):
        return (
            f"Redis at {where} refused the password in the Redis URL; check --redis-url or CURVEFM_REDIS_URL "
            "(docker-compose: CURVEFM_REDIS_PASSWORD in .env)"
        )
    return (
        f"Redis at {where} requires a password; put it in the Redis URL (redis://:PASSWORD@{where}) given by "
        "--redis-url or CURVEFM_REDIS_URL"
    )


def location(connection: Redis) -> str:
    """Where Redis is, without the password a URL may hold."""
    kwargs = connection.connection_pool.connection_kwargs
    if "path" in kwargs:
        return f"unix:{kwargs['path']}"
    return f"{kwargs.get('host', '?')}:{kwargs.get('port', '?')}/{kwargs.get('db', 0)}"
