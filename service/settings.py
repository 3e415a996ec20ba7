"""Service settings, from the environment with explicit overrides (what ``curvefm serve`` options set).

Every limit has an environment variable, and an error that hits a limit names it: the request limits of
:data:`LIMITS` are ``CURVEFM_<NAME>`` (``CURVEFM_MAX_K``); the others are in :data:`ENV`.
"""

from __future__ import annotations

import ipaddress
import os
import socket
from collections.abc import Callable
from dataclasses import dataclass, field, fields
from pathlib import Path

from curvefm.errors import InvalidInput
from curvefm.session import DEFAULT_LOCK_TIMEOUT_S, SessionLimits
from curvefm.store import default_data_dir

DEFAULT_MAX_UPLOAD_BYTES = 200 * 1024 * 1024
DEFAULT_MAX_BODY_BYTES = 4 * 1024 * 1024
SESSION_LIMITS = tuple(f.name for f in fields(SessionLimits))
LIMITS = ("max_upload_bytes", "max_body_bytes", *SESSION_LIMITS)
"""The limits: each a positive integer, read from ``CURVEFM_<NAME>`` (``CURVEFM_MAX_K``) and named in its error."""
LOOPBACK_NAMES = ("localhost", "127.0.0.1", "::1")
ANY_HOST = "*"
DAY_S = 24 * 3600
DEFAULT_LOGIN_TTL_S = 7 * 24 * 3600


@dataclass(frozen=True)
class Settings:
    data_dir: Path = field(default_factory=default_data_dir)
    redis_url: str | None = None
    """``None``: jobs run in an in-process executor."""
    max_upload_bytes: int = DEFAULT_MAX_UPLOAD_BYTES
    """The largest shape upload (``POST /shapes``), counted as the body arrives (chunked too)."""
    max_body_bytes: int = DEFAULT_MAX_BODY_BYTES
    """The largest body of any other request."""
    session_limits: SessionLimits = field(default_factory=SessionLimits)
    queue_prefix: str = ""
    job_retries: int = 1
    """How often a job whose worker died is run again before it is marked failed (RQ mode)."""
    embedded_workers: int = 2
    session_lock_timeout_s: float = DEFAULT_LOCK_TIMEOUT_S
    """How long a request waits for a session that another request or process is editing before a 503."""
    live_sessions: int = 64
    """Sessions kept live (solver built) in memory; more active sessions than this are rebuilt from disk on
    every edit, which costs tens of milliseconds each."""
    display_vertices: int = 50_000
    """A shape with more vertices is drawn in the UI as a display copy of about this many (its vertices a subset
    of the shape's; ``GET /shapes/{id}/mesh``); 0: every shape is drawn whole."""
    prior_max_vertices: int = 150_000
    """Live sessions on bigger shapes solve the combined energy without its landmark prior: it costs a few seconds
    of a core once per shape, growing with the vertices (4.5 s for a pair of 110k: its descriptors' operators over
    every vertex), and a few tenths of a second per edit whatever the size."""
    demo: bool = False
    allowed_hosts: tuple[str, ...] = LOOPBACK_NAMES
    """Host header values answered (lower case, no port); ``*`` answers any."""
    quota_bytes: int = 2 * 1024**3
    """Per user: stored bytes of the shapes they uploaded and of their jobs' results. 0: no limit."""
    quota_sessions: int = 100
    """Per user: sessions they own. 0: no limit."""
    quota_jobs: int = 4
    """Per user: jobs queued or running at once. 0: no limit."""
    rate_limit: float = 20.0
    """Requests per second per credential (token, cookie, or client address without one). 0: no limit."""
    rate_burst: int = 40
    """Requests a credential may make at once before :attr:`rate_limit` paces it."""
    job_ttl_s: float = 7 * DAY_S
    """Finished job records and their result files are deleted this long after the job ended."""
    expiry_interval_s: float = 600.0
    """How often the API looks for expired jobs and result files."""
    login_ttl_s: float = DEFAULT_LOGIN_TTL_S
    """How long a login cookie of the web page stays valid (a token rotation or removal ends it sooner)."""
    keep_alive_s: float = 75.0
    gil_switch_ms: float = 1.0
    """How long a thread may hold the interpreter lock while another waits for it (Python's default is 5 ms): the
    event loop, which reads and answers every request, waits behind the threads doing edits at most this long."""
    """How long an idle HTTP connection stays open. Longer than the idle timeout of clients and proxies (httpx
    5 s, Caddy 2 min is the exception: set it above that behind one), so that they close idle connections
    first: when the server closes one just as a request goes out on it, that request fails (the 5 s uvicorn
    default dropped requests under load in ``benchmarks/bench_soak.py``)."""

    @classmethod
    def from_env(cls, bind_host: str = LOOPBACK_NAMES[1], **overrides) -> Settings:
        """Settings from the variables of :data:`ENV` and of :data:`LIMITS`, then ``overrides`` (settings or
        limits by name; those that are ``None`` are ignored). ``bind_host``, the address the server listens on,
        chooses the default allowed hosts."""
        unknown = set(overrides) - {f.name for f in fields(cls)} - set(LIMITS)
        if unknown:
            raise TypeError(f"unknown settings: {', '.join(sorted(unknown))}")
        values = {"data_dir": default_data_dir(), "allowed_hosts": default_allowed_hosts(bind_host)}
        for name, (variable, _) in ENV.items():
            if os.environ.get(variable):
                values[name] = parsed_setting(name, os.environ[variable], variable)
        values.update({name: os.environ[limit_variable(name)] for name in LIMITS if limit_variable(name) in os.environ})
        values.update({key: value for key, value in overrides.items() if value is not None})
        for name in set(LIMITS) & set(values):
            values[name] = _positive(name, values[name])
        session_limits = {name: values.pop(name) for name in SESSION_LIMITS if name in values}
        values["session_limits"] = SessionLimits(**session_limits)
        values["data_dir"] = Path(values["data_dir"]).expanduser()
        return cls(**values)


def limit_variable(name: str) -> str:
    return f"CURVEFM_{name.upper()}"


def _positive(name: str, value: int | str) -> int:
    try:
        number = int(value)
    except ValueError:
        number = 0
    if number < 1:
        raise ValueError(f"{name} ({limit_variable(name)}) must be a positive integer, got {value!r}")
    return number


def _non_negative(kind: Callable[[str], float | int]) -> Callable[[str], float | int]:
    def parse(text: str) -> float | int:
        value = kind(text)
        if not value >= 0:  # also refuses nan
            raise ValueError(text)
        return value

    return parse


def _positive_float(text: str) -> float:
    value = float(text)
    if not 0 < value < float("inf"):
        raise ValueError(text)
    return value


def host_list(text: str) -> tuple[str, ...]:
    """``"a.example, B.example"`` -> ``("a.example", "b.example")``; ``*`` allows any host."""
    hosts = tuple(normal_host(part) for part in text.split(",") if part.strip())
    if not hosts:
        raise ValueError(text)
    return hosts


def normal_host(host: str) -> str:
    """Lower case, without brackets around an IPv6 address or a trailing dot."""
    return host.strip().lower().removeprefix("[").removesuffix("]").rstrip(".")


ENV: dict[str, tuple[str, Callable[[str], object]]] = {
    "redis_url": ("CURVEFM_REDIS_URL", str),
    "queue_prefix": ("CURVEFM_QUEUE_PREFIX", str),
    "job_retries": ("CURVEFM_JOB_RETRIES", _non_negative(int)),
    "live_sessions": ("CURVEFM_LIVE_SESSIONS", _non_negative(int)),
    "display_vertices": ("CURVEFM_DISPLAY_VERTICES", _non_negative(int)),
    "prior_max_vertices": ("CURVEFM_PRIOR_MAX_VERTICES", _non_negative(int)),
    "session_lock_timeout_s": ("CURVEFM_SESSION_LOCK_TIMEOUT", _non_negative(float)),
    "allowed_hosts": ("CURVEFM_ALLOWED_HOSTS", host_list),
    "quota_bytes": ("CURVEFM_QUOTA_BYTES", _non_negative(int)),
    "quota_sessions": ("CURVEFM_QUOTA_SESSIONS", _non_negative(int)),
    "quota_jobs": ("CURVEFM_QUOTA_JOBS", _non_negative(int)),
    "rate_limit": ("CURVEFM_RATE_LIMIT", _non_negative(float)),
    "rate_burst": ("CURVEFM_RATE_BURST", _non_negative(int)),
    "job_ttl_s": ("CURVEFM_JOB_TTL", _non_negative(float)),
    "expiry_interval_s": ("CURVEFM_EXPIRY_INTERVAL", _non_negative(float)),
    "login_ttl_s": ("CURVEFM_LOGIN_TTL", _non_negative(float)),
    "keep_alive_s": ("CURVEFM_KEEP_ALIVE", _non_negative(float)),
    "gil_switch_ms": ("CURVEFM_GIL_SWITCH_MS", _positive_float),
}
"""Setting -> (environment variable, parser), for the settings that are not request limits (:data:`LIMITS`)."""


def env_name(setting: str) -> str:
    """The environment variable of a setting, for messages that name a limit."""
    return ENV[setting][0]


def parsed_setting(name: str, text: str, source: str) -> object:
    """The value of setting ``name`` written as ``text`` in ``source`` (a variable or an option, for the error)."""
    try:
        return ENV[name][1](text)
    except ValueError:
        raise InvalidInput(f"{source}={text!r} is not valid; see `curvefm serve --help`") from None


def default_allowed_hosts(bind_host: str) -> tuple[str, ...]:
    """The loopback names; bound elsewhere, also the bound address and this machine's names and addresses.

    A browser sends the name it was pointed at as Host, so a page on an attacker's domain that resolves to this
    machine (DNS rebinding) is refused, and loopback names are always safe to answer."""
    if _is_loopback(bind_host):
        return LOOPBACK_NAMES
    names = [socket.gethostname(), socket.getfqdn()]
    if bind_host not in ("", "0.0.0.0", "::"):
        names.append(bind_host)
    else:
        names += _addresses(socket.gethostname())
    return tuple(dict.fromkeys(normal_host(name) for name in (*LOOPBACK_NAMES, *names) if name))


def _is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _addresses(hostname: str) -> list[str]:
    try:
        return sorted({info[4][0] for info in socket.getaddrinfo(hostname, None)})
    except OSError:
        return []
