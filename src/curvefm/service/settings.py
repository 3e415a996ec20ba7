"""Service settings: a pydantic-settings model read from ``CURVEFM_<NAME>`` environment variables, with explicit
overrides (what ``curvefm serve`` options set) winning over the environment.

Every setting is a typed field with bounds and a description (the documentation lists them from
``Settings.model_fields``); :func:`env_name` gives its variable. Every limit has a variable, and an error that hits
a limit names it: the request limits of :data:`LIMITS` are ``CURVEFM_<NAME>`` (``CURVEFM_MAX_K``). Adding a
setting is adding a field.
"""

from __future__ import annotations

import ipaddress
import socket
from dataclasses import fields
from pathlib import Path
from typing import Annotated, Any

from pydantic import AfterValidator, BeforeValidator, Field, SecretStr, ValidationError, model_validator
from pydantic_settings import NoDecode

from curvefm.errors import InvalidInput
from curvefm.morphometrics import DEFAULT_SNAP_TOLERANCE, MAX_PSEUDO_LANDMARKS
from curvefm.records.sessions import MAX_SESSION_BYTES
from curvefm.session import DEFAULT_LOCK_TIMEOUT_S, SessionLimits
from curvefm.store import default_data_dir
from curvefm.workers.settings import ENV_PREFIX, QueueSettings

DEFAULT_MAX_UPLOAD_BYTES = 200 * 1024 * 1024
DEFAULT_MAX_BODY_BYTES = 4 * 1024 * 1024
DEFAULT_MAX_JSON_DEPTH = 32  # the published bodies nest at most 5 deep; Python's parser fails near 1,000
SESSION_LIMITS = tuple(f.name for f in fields(SessionLimits))
LIMITS = (
    "max_upload_bytes",
    "max_body_bytes",
    "max_json_depth",
    "max_session_bytes",
    *SESSION_LIMITS,
    "max_webhooks",
    "max_pseudo_landmarks",
    "max_review_comments",
    "max_comment_chars",
)
"""The limits: each a positive integer, read from ``CURVEFM_<NAME>`` (``CURVEFM_MAX_K``) and named in its error."""
LOOPBACK_NAMES = ("localhost", "127.0.0.1", "::1")
ANY_HOST = "*"
DAY_S = 24 * 3600
DEFAULT_LOGIN_TTL_S = 7 * 24 * 3600
OIDC_SETTINGS = ("oidc_issuer", "oidc_client_id", "oidc_client_secret")
"""Single sign-on is on when all three are set."""


def normal_host(host: str) -> str:
    """Lower case, without brackets around an IPv6 address or a trailing dot."""
    return host.strip().lower().removeprefix("[").removesuffix("]").rstrip(".")


def host_list(text: str) -> tuple[str, ...]:
    """``"a.example, B.example"`` -> ``("a.example", "b.example")``; ``*`` allows any host."""
    hosts = tuple(normal_host(part) for part in text.split(",") if part.strip())
    if not hosts:
        raise ValueError("no host name in the list")
    return hosts


Positive = Annotated[int, Field(gt=0)]
Count = Annotated[int, Field(ge=0)]
NonNegative = Annotated[float, Field(ge=0)]  # also refuses nan
Seconds = NonNegative  # inf: never
Timeout = Annotated[float, Field(gt=0)]  # inf: never
Hosts = Annotated[tuple[str, ...], NoDecode, BeforeValidator(lambda v: host_list(v) if isinstance(v, str) else v)]


def http_url(text: str) -> str:
    if not text.startswith(("https://", "http://")) or len(text) > 512:
        raise ValueError("an http:// or https:// URL of at most 512 characters")
    return text


IssuerUrl = Annotated[str, AfterValidator(http_url)]


def _session_limit(name: str) -> Any:
    """The field of the request limit ``name`` of :class:`SessionLimits`, with its default and help."""
    limit = next(f for f in fields(SessionLimits) if f.name == name)
    return Field(limit.default, description=f"The most {limit.metadata['help']} a request may ask for.")


class Settings(QueueSettings):
    """What ``curvefm serve`` runs with; :meth:`from_env` also takes ``serve``'s options. Built directly (tests,
    benchmarks), the environment still fills the fields not given."""

    data_dir: Annotated[Path, AfterValidator(Path.expanduser)] = Field(
        default_factory=default_data_dir,
        validation_alias="CURVEFM_DATA",
        description="The data directory: shapes, bases, sessions, results, users (default ~/.local/share/curvefm).",
    )
    max_upload_bytes: Positive = Field(
        DEFAULT_MAX_UPLOAD_BYTES,
        description="The largest shape upload (POST /shapes), counted as the body arrives (chunked too).",
    )
    max_concurrent_uploads: Count = Field(
        2,
        description="Uploads of big_upload_bytes or more parsed at once, by all API processes that share the job "
        "queue's Redis (without Redis: by each process); more answer 429. Reading one takes up to about 5x its size "
        "in memory. 0: no limit.",
    )
    big_upload_bytes: Positive = Field(
        8 * 1024 * 1024, description="The size from which an upload counts towards max_concurrent_uploads."
    )
    upload_lease_s: Annotated[float, Field(gt=0, allow_inf_nan=False)] = Field(
        600.0,
        description="Seconds after which an upload slot of an API process that died while parsing is given back "
        "(with Redis; longer than the slowest big upload's parse).",
    )
    max_body_bytes: Positive = Field(DEFAULT_MAX_BODY_BYTES, description="The largest body of any other request.")
    max_json_depth: Positive = Field(
        DEFAULT_MAX_JSON_DEPTH, description="The deepest nesting of arrays and objects a JSON body may have."
    )
    max_session_bytes: Positive = Field(
        MAX_SESSION_BYTES,
        description="The most a session's curves may store, counted as 4 bytes a vertex id of their traced paths "
        "and of the waypoints or paths given (long explicit paths make big records); it counts in the owner's "
        "quota_bytes.",
    )
    max_waypoints: Positive = _session_limit("max_waypoints")
    max_path_vertices: Positive = _session_limit("max_path_vertices")
    max_curves: Positive = _session_limit("max_curves")
    max_k: Positive = _session_limit("max_k")
    max_members: Positive = _session_limit("max_members")
    max_webhooks: Positive = Field(10, description="The most webhooks one collection may have.")
    max_pseudo_landmarks: Positive = Field(
        MAX_PSEUDO_LANDMARKS,
        description="The most pseudo-landmarks a collection's morphometrics export may ask for (each is mapped to "
        "every member, so the work grows with both).",
    )
    max_review_comments: Positive = Field(200, description="The most review comments one collection member may hold.")
    max_comment_chars: Positive = Field(2000, description="The longest review comment, in characters.")
    webhook_allow_private: bool = Field(
        False,
        description="Let webhooks post to loopback, private, link-local and other internal addresses. Off, a "
        "webhook's URL may not name one, and a delivery whose host resolves to one fails: users cannot make the "
        "server reach what only it can reach (SSRF).",
    )
    webhook_timeout_s: Timeout = Field(
        10.0, description="Seconds a webhook delivery may take (connecting, sending, the answer) before it fails."
    )
    webhook_retries: Count = Field(
        5,
        description="How often a failed webhook delivery (no answer, or not 2xx) is tried again before it is marked "
        "failed; the waits between tries start at webhook_retry_delay_s and double.",
    )
    webhook_retry_delay_s: Timeout = Field(
        10.0, description="Seconds before the first retry of a failed webhook delivery (then doubling)."
    )
    webhook_poll_s: Timeout = Field(
        1.0, description="Seconds between two looks of an API process for webhook deliveries that are due."
    )
    webhook_log_size: Positive = Field(
        100, description="Deliveries kept per webhook (GET /collections/{id}/webhooks/{webhook}/deliveries)."
    )
    job_retries: Count = Field(
        1, description="How often a job whose worker died is run again before it is marked failed (with Redis)."
    )
    embedded_workers: Positive = Field(2, description="Threads that run jobs in-process when there is no Redis.")
    session_lock_timeout_s: Seconds = Field(
        DEFAULT_LOCK_TIMEOUT_S,
        description="Seconds a request waits for a session that another request or process is editing before a 503.",
    )
    agreement_points: Positive = Field(
        1000,
        description="At how many template vertices (spread by farthest-point sampling) two annotators' maps of a "
        "member are compared (GET /collections/{id}/agreement); the cost grows with it.",
    )
    agreement_threshold: NonNegative = Field(
        0.05,
        description="The mean geodesic distance between two annotators' maps of a member (units of its "
        "sqrt(area)) above which the agreement report flags the member for review.",
    )
    markup_snap_tolerance: NonNegative = Field(
        DEFAULT_SNAP_TOLERANCE,
        description="How far a point of imported Slicer markups (POST /sessions/{id}/markups) may be from the "
        "nearest vertex it is snapped to, in units of the mesh's sqrt(area); farther points are refused by name.",
    )
    live_sessions: Count = Field(
        64,
        description="Sessions kept live (solver built) in memory; more active sessions than this are rebuilt from "
        "disk on every edit, which costs tens of milliseconds each.",
    )
    display_vertices: Count = Field(
        50_000,
        description="A shape with more vertices is drawn in the UI as a display copy of about this many (its "
        "vertices a subset of the shape's; GET /shapes/{id}/mesh); 0: every shape is drawn whole.",
    )
    guided_trace_vertices: Count = Field(
        300_000,
        description="Curves on a shape of at least this many vertices whose display copy is stored (its basis job "
        "makes it) are traced in a corridor around the display copy's path instead of over the whole mesh: still a "
        "path of the shape's own edges between the same vertices, on average 0.01-0.14% longer than the shortest "
        "one as measured (at worst 1.1%), and several times faster at a million vertices (docs/performance.md).",
    )
    prior_max_vertices: Count = Field(
        150_000,
        description="Live sessions on bigger shapes solve the combined energy without its landmark prior: it costs "
        "a few seconds of a core once per shape, growing with the vertices (4.5 s for a pair of 110k: its "
        "descriptors' operators over every vertex), and a few tenths of a second per edit whatever the size.",
    )
    demo: bool = Field(False, description="Add two generated shapes and a ready session 'demo' at startup.")
    allowed_hosts: Hosts = Field(
        LOOPBACK_NAMES,
        description="Host header values answered, comma-separated (lower case, no port); * answers any. Default: "
        "the loopback names, plus this machine's names and the bound address when bound elsewhere.",
    )
    quota_bytes: Count = Field(
        2 * 1024**3,
        description="Per user: stored bytes of the shapes they uploaded, of their jobs' results and of their "
        "sessions' curves. 0: no limit.",
    )
    quota_sessions: Count = Field(100, description="Per user: sessions they own. 0: no limit.")
    quota_jobs: Count = Field(4, description="Per user: jobs queued or running at once. 0: no limit.")
    rate_limit: NonNegative = Field(
        20.0,
        description="Requests per second per credential (token, cookie, or client address without one). 0: no limit.",
    )
    rate_burst: Count = Field(40, description="Requests a credential may make at once before rate_limit paces it.")
    job_ttl_s: Seconds = Field(
        7 * DAY_S,
        description="Seconds after a job ended that its record and result files are deleted.",
    )
    expiry_interval_s: Seconds = Field(
        600.0,
        description="How often (seconds) the API looks for expired jobs and result files.",
    )
    login_ttl_s: Seconds = Field(
        DEFAULT_LOGIN_TTL_S,
        description="Seconds a login cookie of the web page stays valid (a token rotation or removal ends it sooner).",
    )
    keep_alive_s: Seconds = Field(
        75.0,
        description="Seconds an idle HTTP connection stays open. Longer than the idle timeout of clients and "
        "proxies (httpx 5 s, Caddy 2 min is the exception: set it above that behind one), so that they close idle "
        "connections first: when the server closes one just as a request goes out on it, that request fails (the "
        "5 s uvicorn default dropped requests under load in benchmarks/bench_soak.py).",
    )
    header_timeout_s: Timeout = Field(
        10.0, description="Seconds a new connection may take to send its first request's headers (slow clients)."
    )
    body_timeout_s: Timeout = Field(
        30.0, description="Seconds a request body may pause between two reads before the request answers 408."
    )
    max_event_streams: Positive = Field(
        4,
        description="Per user: session pages that may follow their sessions' changes at once (event streams, GET "
        "/sessions/{id}/events), counted across the API processes; one more is refused with 429 (and shows without "
        "live updates). Over plain HTTP/1.1 a browser opens at most 6 connections to a server for all its tabs: each "
        "stream holds one, so more than 4 would leave a user's pages too few for their requests.",
    )
    events_poll_s: Timeout = Field(
        1.0,
        description="Seconds between two looks of an API process at the sessions its pages follow: who has them "
        "open (presence; a page that closed without a word counts out after three of these plus 5 s) and, without "
        "Redis, their revisions and refinements (Redis delivers those at once).",
    )
    events_keepalive_s: Timeout = Field(
        15.0,
        description="Seconds between two keep-alive comments on an idle event stream, so that proxies keep it open.",
    )
    gil_switch_ms: Annotated[float, Field(gt=0, allow_inf_nan=False)] = Field(
        1.0,
        description="Milliseconds a thread may hold the interpreter lock while another waits for it (Python's "
        "default is 5 ms): the event loop, which reads and answers every request, waits behind the threads doing "
        "edits at most this long.",
    )

    oidc_issuer: IssuerUrl | None = Field(
        None,
        description="Single sign-on: the OpenID Connect provider's issuer URL, exactly as its ID tokens state it "
        "(e.g. https://login.uni.example/realms/lab); its ISSUER/.well-known/openid-configuration is read at the "
        "first sign-in. With oidc_client_id and oidc_client_secret, the login page offers to sign in there.",
    )
    oidc_client_id: str | None = Field(None, description="Single sign-on: curvefm's client id at the provider.")
    oidc_client_secret: SecretStr | None = Field(
        None, description="Single sign-on: curvefm's client secret at the provider (never logged or shown)."
    )
    oidc_scopes: str = Field(
        "openid profile email",
        description="Single sign-on: the scopes asked for, space-separated (openid is added when missing).",
    )
    oidc_name_claim: str = Field(
        "preferred_username",
        description="Single sign-on: the claim (of the ID token, else of the provider's userinfo) that names a user "
        "made at their first sign-in; without it, the e-mail address, else the subject. A name already taken gets "
        "a -2, -3... suffix.",
    )
    oidc_label: str = Field(
        "single sign-on",
        max_length=60,
        description="Single sign-on: the provider's name on the login page's button ('Sign in with ...').",
    )
    oidc_timeout_s: Timeout = Field(
        10.0, description="Single sign-on: seconds to wait for an answer of the provider before a 503."
    )
    oidc_login_timeout_s: Timeout = Field(
        600.0, description="Single sign-on: seconds a person has to sign in at the provider and come back."
    )

    @model_validator(mode="after")
    def _sso_complete(self) -> Settings:
        given = [name for name in OIDC_SETTINGS if getattr(self, name) is not None]
        if given and len(given) < len(OIDC_SETTINGS):
            missing = ", ".join(env_name(name) for name in OIDC_SETTINGS if name not in given)
            raise ValueError(f"single sign-on needs {missing} too")
        return self

    @property
    def sso(self) -> bool:
        """Whether single sign-on is configured."""
        return self.oidc_issuer is not None

    @property
    def session_limits(self) -> SessionLimits:
        """The request limits that sessions and collections check."""
        return SessionLimits(**{name: getattr(self, name) for name in SESSION_LIMITS})

    @classmethod
    def from_env(cls, bind_host: str = LOOPBACK_NAMES[1], **overrides: Any) -> Settings:
        """Settings from the ``CURVEFM_*`` variables, then ``overrides`` (settings by name; those that are ``None``
        are ignored). ``bind_host``, the address the server listens on, chooses the default allowed hosts. A bad
        value is an :class:`InvalidInput` naming its variable (or, for an override, its ``serve`` option)."""
        unknown = set(overrides) - set(cls.model_fields)
        if unknown:
            raise TypeError(f"unknown settings: {', '.join(sorted(unknown))}")
        given = {name: value for name, value in overrides.items() if value is not None}
        try:
            settings = cls(**given)
        except ValidationError as error:
            raise InvalidInput(_invalid(error, given)) from None
        if "allowed_hosts" not in settings.model_fields_set:
            settings = settings.model_copy(update={"allowed_hosts": default_allowed_hosts(bind_host)})
        return settings


def env_name(setting: str) -> str:
    """The environment variable of a setting (``max_k`` -> ``CURVEFM_MAX_K``), for messages that name it."""
    return str(Settings.model_fields[setting].validation_alias)


def option_name(setting: str) -> str:
    """The ``curvefm serve`` option of a setting (``job_ttl_s`` -> ``--job-ttl``, ``data_dir`` -> ``--data``)."""
    return "--" + env_name(setting).removeprefix(ENV_PREFIX).lower().replace("_", "-")


def _invalid(error: ValidationError, given: dict[str, Any]) -> str:
    """One line per bad value, naming where it came from: an override's option, else its variable."""
    by_variable = {env_name(name): name for name in Settings.model_fields}
    problems = []
    for problem in error.errors():
        reason = problem["msg"].removeprefix("Value error, ")
        if not problem["loc"]:  # about settings together (their values unshown: one may be a secret)
            problems.append(reason)
            continue
        name = by_variable.get(str(problem["loc"][0]), str(problem["loc"][0]))
        source = option_name(name) if name in given else env_name(name) if name in Settings.model_fields else name
        problems.append(f"{source}={problem['input']!r} is not valid: {reason[:1].lower()}{reason[1:]}")
    return "; ".join(problems) + "; see `curvefm serve --help`"


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
        return sorted({str(info[4][0]) for info in socket.getaddrinfo(hostname, None)})
    except OSError:
        return []
