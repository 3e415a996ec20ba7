"""The client's objects: :class:`Client` (shapes, bases, sessions, jobs), :class:`Session`, :class:`Job`."""

from __future__ import annotations

import io
import json
import os
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import httpx
import numpy as np
from tqdm.auto import tqdm

from curvefm.errors import ERROR_KINDS, CurvefmError, InternalError, InvalidInput, ResourceLimit, TooMany

ENDED = ("finished", "failed", "canceled", "lost")
DEFAULT_K = 120
SHOWN_TEXT = 500
PAGE_SIZE = 100
"""How many records :meth:`Client.iterate` asks for at a time (the server answers at most 500)."""
RETRIES = 3
"""How often a request answered 503 with ``Retry-After`` (the records' database or Redis did not answer, a session
stayed busy) is sent again by default; nothing was stored by the refused request."""
RETRY_WAIT_MAX_S = 10.0


class JobFailed(CurvefmError):
    """A job ended ``failed``, ``canceled`` or ``lost``; ``info`` is its last state (``info["error"]`` says why)."""

    code = "job_failed"

    def __init__(self, info: dict[str, Any]):
        reason = (info.get("error") or {}).get("message") or info.get("message") or ""
        super().__init__(f"job {info['id']} ({info['kind']}) ended {info['state']}: {reason}")
        self.info = info


def error_of(response: httpx.Response) -> CurvefmError:
    """The exception of an error answer: the class of its ``error`` kind, the server's ``detail`` as message."""
    try:
        body = response.json()
    except ValueError:
        body = {}
    body = body if isinstance(body, dict) else {}
    detail = body.get("detail") or response.text[:SHOWN_TEXT] or response.reason_phrase
    fallback = InternalError if response.status_code >= 500 else InvalidInput
    cls = ERROR_KINDS.get(body.get("error", ""), fallback)
    error: CurvefmError
    if issubclass(cls, TooMany):
        retry_after = response.headers.get("retry-after")
        error = cls(detail, body.get("limit"), float(retry_after) if retry_after else None)
    elif issubclass(cls, ResourceLimit):
        error = cls(detail, body.get("limit"))
    else:
        error = cls(detail)
    error.status, error.body = response.status_code, body
    return error


def retry_wait(response: httpx.Response, sent: dict[str, Any]) -> float | None:
    """Seconds to wait before sending a request again: for a 503 that says when to retry, and a body that can be
    sent twice; None otherwise."""
    retry_after = response.headers.get("retry-after", "")
    replayable = "files" not in sent and isinstance(sent.get("content", b""), bytes | str)
    if response.status_code != 503 or not replayable:
        return None
    try:
        return min(max(float(retry_after), 0.0), RETRY_WAIT_MAX_S)
    except ValueError:  # an HTTP date, or none: not ours
        return None


class Client:
    """A connection to a curvefm service at ``url``, authenticated by ``token`` (default: ``CURVEFM_TOKEN``;
    ``curvefm users add NAME`` prints one). Use it as a context manager, or :meth:`close` it."""

    def __init__(self, url: str, token: str | None = None, timeout: float = 120.0, retries: int = RETRIES):
        token = token or os.environ.get("CURVEFM_TOKEN")
        headers = {"Authorization": f"Bearer {token}"} if token else {}
        self.http = httpx.Client(base_url=url.rstrip("/"), headers=headers, timeout=timeout)
        self.retries = retries

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def close(self) -> None:
        self.http.close()

    def request(self, method: str, path: str, **kwargs: Any) -> httpx.Response:
        """Send a request; an error answer raises its :mod:`curvefm.errors` exception. A 503 with ``Retry-After``
        is sent again after that wait (at most :data:`RETRY_WAIT_MAX_S`), up to ``retries`` times, unless its body
        is a stream or files that were read once."""
        response = self.http.request(method, path, **kwargs)
        for _ in range(self.retries):
            wait = retry_wait(response, kwargs)
            if wait is None:
                break
            time.sleep(wait)
            response = self.http.request(method, path, **kwargs)
        if response.is_error:
            raise error_of(response)
        return response

    def json(self, method: str, path: str, **kwargs: Any) -> Any:
        return self.request(method, path, **kwargs).json()

    def upload(self, path: str | Path, name: str | None = None) -> str:
        """Upload a mesh file; returns its shape id (the content hash: the same mesh again gives the same id)."""
        path = Path(path)
        with open(path, "rb") as f:
            data = {"name": name} if name else None
            return self.json("POST", "/shapes", files={"file": (path.name, f)}, data=data)["id"]

    def page(
        self, path: str, limit: int | None = None, offset: int = 0, **filters: str | bool | None
    ) -> tuple[list[dict[str, Any]], int]:
        """One page of a list (``/sessions``, ``/collections``, ``/shapes``): ``limit`` records (1 to 500; None:
        all) from ``offset``, and how many the list has in all (its ``X-Total-Count``); ``filters`` (None: not
        given) as the list takes them (``/sessions``: ``q``, ``in_collection``)."""
        params: dict[str, int | str] = {"offset": offset}
        if limit is not None:
            params["limit"] = limit
        for name, value in filters.items():
            if value is not None:
                params[name] = str(value).lower() if isinstance(value, bool) else value
        response = self.request("GET", path, params=params)
        items = response.json()
        return items, int(response.headers.get("x-total-count", len(items) + offset))

    def iterate(self, path: str, page_size: int = PAGE_SIZE) -> Iterator[dict[str, Any]]:
        """Every record of a list, fetched ``page_size`` at a time as the iteration goes on (a record added or
        removed meanwhile may shift a page by one: offsets, not a snapshot)."""
        offset = 0
        while True:
            items, total = self.page(path, page_size, offset)
            yield from items
            offset += len(items)
            if not items or offset >= total:
                return

    def shapes(self, limit: int | None = None, offset: int = 0) -> list[dict[str, Any]]:
        """The stored shapes by name, then upload time: ``limit`` of them (None: all) from ``offset``."""
        return self.page("/shapes", limit, offset)[0]

    def basis(self, shape_id: str, k: int = DEFAULT_K, plugin: str = "laplace-beltrami", **params: Any) -> Job:
        """Request the first ``k`` basis functions of a shape (a job; it finishes at once if they exist)."""
        body = {"k": k, "plugin": plugin, "params": params}
        return Job(self, self.json("POST", f"/shapes/{shape_id}/bases", json=body))

    def session(self, source: str, target: str, k: int = DEFAULT_K, **options: Any) -> Session:
        """A new session of yours on two shapes whose bases are ready; ``options``: ``alpha``, ``tracer``,
        ``samples``, ``name``, ``sharing``, ``basis_plugin``, ``basis_params`` (see ``/docs``)."""
        return Session(
            self, self.json("POST", "/sessions", json={"source": source, "target": target, "k": k, **options})
        )

    def open_session(self, session_id: str) -> Session:
        """An existing session (yours, or one shared with you)."""
        return Session(self, self.json("GET", f"/sessions/{session_id}"))

    def sessions(
        self, limit: int | None = None, offset: int = 0, query: str | None = None, in_collection: bool | None = None
    ) -> list[dict[str, Any]]:
        """Summaries of the sessions you may see, the most recently changed first: ``limit`` of them (None: all)
        from ``offset``; ``query``: only those whose name or shape names contain it; ``in_collection``: False for
        sessions of their own, True for collections' member sessions (None: both). :meth:`iterate`
        (``"/sessions"``) pages through them all."""
        return self.page("/sessions", limit, offset, q=query, in_collection=in_collection)[0]

    def collections(self, limit: int | None = None, offset: int = 0) -> list[dict[str, Any]]:
        """Summaries of the collections you may see, the most recently changed first: ``limit`` of them (None:
        all) from ``offset``."""
        return self.page("/collections", limit, offset)[0]

    def collection(self, template: str, from_session: str | None = None, **options: Any) -> Collection:
        """A new collection of yours on a template shape: its curves from a session on the template
        (``from_session``) or ``curves=[{"waypoints": [i, j]}, ...]``; ``options``: ``members`` (shape ids),
        ``name``, ``k``, ``sharing``, ... (see ``/docs``)."""
        body = {"template": template, "from_session": from_session, **options}
        return Collection(self, self.json("POST", "/collections", json=body))

    def open_collection(self, collection_id: str) -> Collection:
        return Collection(self, self.json("GET", f"/collections/{collection_id}"))

    def my_work(self) -> list[dict[str, Any]]:
        """The members assigned to you in every collection you may read, those not done first (the first is
        what is next): ``collection``, ``member``, ``session``, ``curves_done`` of ``curves_total``, ``done``."""
        return self.json("GET", "/me/work")

    def job(self, job_id: str) -> Job:
        info = self.json("GET", f"/jobs/{job_id}")
        return (RefineJob if info["kind"] == "refine" else Job)(self, info)

    def plugins(self) -> dict[str, list[dict[str, Any]]]:
        return self.json("GET", "/plugins")

    def download(self, url: str) -> bytes:
        return self.request("GET", url).content


class Job:
    """A basis or refinement job. ``info`` is its state as last fetched; :attr:`state` fetches it again."""

    def __init__(self, client: Client, info: dict[str, Any]):
        self.client, self.info = client, info

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.id} {self.info['kind']} {self.info['state']}>"

    @property
    def id(self) -> str:
        return self.info["id"]

    @property
    def state(self) -> str:
        """``queued``, ``started``, ``finished``, ``failed``, ``canceled`` or ``lost``, asked now."""
        return self.refresh()["state"]

    def refresh(self) -> dict[str, Any]:
        self.info = self.client.json("GET", f"/jobs/{self.id}")
        return self.info

    def cancel(self) -> Job:
        """Cancel the job (queued) or stop it (running); a job that ended already raises ``Conflict``."""
        self.info = self.client.json("DELETE", f"/jobs/{self.id}")
        return self

    def wait(self, timeout: float | None = None, progress: bool = True, poll_s: float = 0.2) -> Job:
        """Wait until the job ends, showing a progress bar (``progress=False``: none); raises :class:`JobFailed`
        unless it finished, ``TimeoutError`` after ``timeout`` seconds."""
        deadline = None if timeout is None else time.monotonic() + timeout
        with tqdm(total=1.0, disable=not progress, desc=self.info["kind"], bar_format="{l_bar}{bar}| {elapsed}") as bar:
            while self.info["state"] not in ENDED:
                if deadline is not None and time.monotonic() > deadline:
                    raise TimeoutError(f"job {self.id} is still {self.info['state']} after {timeout} s")
                time.sleep(poll_s)
                self.refresh()
                bar.update(self.info["progress"] - bar.n)
                bar.set_postfix_str(self.info["message"][:60], refresh=True)
        if self.info["state"] != "finished":
            raise JobFailed(self.info)
        return self


@dataclass(frozen=True)
class Refinement:
    """What a finished refinement job made. Maps are in file vertex ids (0-based); -1 for a vertex of no face.

    ``map_target_to_source[j]`` is the source vertex for target vertex j (``p2p_NM``), ``map_source_to_target[i]``
    the target vertex for source vertex i. ``C_source_to_target`` / ``C_target_to_source`` are the functional maps
    written with them: a refinement's at its final size (ZoomOut's k_final), those its pointwise maps induce
    (``result["functional_maps"]`` says which). ``files`` maps each result file's name to its URL
    (``Client.download``); ``result`` is the job's whole result (quality figures, ``solve``: how the session's maps
    were solved).
    """

    job_id: str
    revision: int
    converter: str
    map_target_to_source: np.ndarray
    map_source_to_target: np.ndarray
    C_source_to_target: np.ndarray
    C_target_to_source: np.ndarray
    files: dict[str, str]
    result: dict[str, Any]


class RefineJob(Job):
    """A refinement job: :meth:`wait` answers the :class:`Refinement`."""

    # answers the refinement's maps rather than the job (the documented client API), hence the narrower override
    def wait(  # type: ignore[override]
        self, timeout: float | None = None, progress: bool = True, poll_s: float = 0.2
    ) -> Refinement:
        super().wait(timeout, progress, poll_s)
        links, result = self.info["links"], self.info["result"]
        return Refinement(
            job_id=self.id,
            revision=result["revision"],
            converter=result["converter"],
            map_target_to_source=self._array(links["p2p_target_to_source.npy"]),
            map_source_to_target=self._array(links["p2p_source_to_target.npy"]),
            C_source_to_target=self._array(links["C_source_to_target.npy"]),
            C_target_to_source=self._array(links["C_target_to_source.npy"]),
            files={name: url for name, url in links.items() if name != "self"},
            result=result,
        )

    def _array(self, url: str) -> np.ndarray:
        return np.load(io.BytesIO(self.client.download(url)), allow_pickle=False)


@dataclass(frozen=True)
class Curve:
    """A stored curve pair: ``source`` / ``target`` as given (waypoints or paths), ``path_source`` /
    ``path_target`` as traced (file vertex ids)."""

    id: str
    source: list[int]
    target: list[int]
    tracer: str
    path_source: list[int]
    path_target: list[int]

    @classmethod
    def of(cls, record: dict[str, Any]) -> Curve:
        spec = record["spec"]
        return cls(
            record["id"], spec["source"], spec["target"], record["tracer"], record["path_source"], record["path_target"]
        )


class Session:
    """A session on a shape pair: its curves, the functional maps both ways, refinements. ``record`` is the
    session as last fetched; :attr:`curves` fetches it again."""

    def __init__(self, client: Client, record: dict[str, Any]):
        self.client, self.record = client, record

    def __repr__(self) -> str:
        return f"<Session {self.id} {self.record['source'][:8]} -> {self.record['target'][:8]} k={self.record['k']}>"

    @property
    def id(self) -> str:
        return self.record["id"]

    @property
    def path(self) -> str:
        return f"/sessions/{self.id}"

    def refresh(self) -> dict[str, Any]:
        self.record = self.client.json("GET", self.path)
        return self.record

    @property
    def curves(self) -> list[Curve]:
        """The session's curves now, in the order they were added."""
        return [Curve.of(record) for record in self.refresh()["curves"]]

    def add_curve(self, source: list[int], target: list[int], if_revision: int | None = None, **options: Any) -> Curve:
        """Add a curve pair: waypoints joined by the tracer, or with ``explicit=True`` whole vertex paths (file
        ids); ``options``: ``tracer``, ``tracer_params``, ``weight``. Both maps are updated before it answers.
        ``if_revision`` (here and in the other edits): apply it only if the session is still at that revision,
        else :class:`~curvefm.errors.Conflict` (someone else changed it since)."""
        body = {"source": list(source), "target": list(target), **options}
        answer = self.client.json("POST", f"{self.path}/curves", json=body, headers=_if_match(if_revision))
        return Curve.of(answer["curve"])

    def replace_curve(
        self, curve_id: str, source: list[int], target: list[int], if_revision: int | None = None, **options: Any
    ) -> Curve:
        body = {"source": list(source), "target": list(target), **options}
        path, headers = f"{self.path}/curves/{curve_id}", _if_match(if_revision)
        return Curve.of(self.client.json("PUT", path, json=body, headers=headers)["curve"])

    def remove_curve(self, curve: str | Curve, if_revision: int | None = None) -> None:
        curve_id = curve.id if isinstance(curve, Curve) else curve
        self.client.request("DELETE", f"{self.path}/curves/{curve_id}", headers=_if_match(if_revision))

    def events(self) -> Iterator[dict[str, Any]]:
        """The session's changes as they happen, made by anyone (``GET /sessions/{id}/events``): dicts with
        ``kind`` (``hello`` first, then ``curve-added``, ``prior``, ``refined``, ``viewers``...) and the session's
        ``revision``. It ends when the session is deleted, is no longer shared with you, or the server stops."""
        timeout = httpx.Timeout(None, connect=self.client.http.timeout.connect)
        with self.client.http.stream("GET", f"{self.path}/events", timeout=timeout) as response:
            if response.is_error:
                response.read()
                raise error_of(response)
            for line in response.iter_lines():
                if line.startswith("data:"):
                    yield json.loads(line.removeprefix("data:"))

    def map(self, direction: Literal["source_to_target", "target_to_source"] = "source_to_target") -> np.ndarray:
        """The functional map now: ``C_source_to_target`` takes coefficients of a function on the source to
        coefficients on the target. It is :meth:`solve`'s ``size`` square, which may be less than the session's k
        (the combined energy hands out 50 x 50 below 20 curves; :meth:`solve` says why)."""
        return np.array(self.client.json("GET", f"{self.path}/map")[f"C_{direction}"])

    def solve(self) -> dict[str, Any]:
        """What the maps are now and why: ``energy`` (combined, or curves where the combined energy gave way),
        ``weights`` as applied (``alpha``, ...), ``size`` (the maps are size x size), ``summary`` (e.g. "combined;
        50 x 50 until curves totalling 6.2 sqrt(area)") and ``reason``."""
        return self.client.json("GET", f"{self.path}/solve")

    def suggestion(self, paths: bool = False) -> dict[str, Any]:
        """The next curve to draw: ``source`` (its start and end where the maps are least certain) and ``target``
        (their images through the maps), file ids, with the ``revision`` whose maps made it and ``prior_pending``;
        ``paths``: with the curve traced on both shapes (``path_source``, ``path_target``).
        ``add_curve(s["source"], s["target"])`` adds it; move an end first where its image is wrong."""
        return self.client.json("GET", f"{self.path}/suggestion", params={"paths": "true"} if paths else None)

    def refine(self, converter: str = "nearest-neighbor", **params: Any) -> RefineJob:
        """Start pointwise maps both ways from the curves as they are now (a job; ``.wait()`` answers them)."""
        body = {"converter": converter, "params": params}
        return RefineJob(self.client, self.client.json("POST", f"{self.path}/refine", json=body))

    def landmarks(
        self,
        file: str,
        out: str | Path,
        semilandmarks: int = 20,
        pseudo: int = 0,
        refinement: str | None = None,
    ) -> Path:
        """Download one landmark export (``source.mrk.json``, ``target.mrk.json``, ``source.fcsv``,
        ``target.fcsv``, ``landmarks.tps``, ``morphologika.txt``, ``curveslide.csv``) to ``out``: the curves'
        endpoints, ``semilandmarks`` per curve and ``pseudo`` pseudo-landmarks, by the live maps or a finished
        ``refinement`` job's."""
        params: dict[str, Any] = {"semilandmarks": semilandmarks, "pseudo": pseudo}
        if refinement is not None:
            params["refinement"] = refinement
        Path(out).write_bytes(self.client.request("GET", f"{self.path}/exports/{file}", params=params).content)
        return Path(out)

    def import_markups(
        self, source: str | Path, target: str | Path, join_landmarks: bool = False, if_revision: int | None = None
    ) -> dict[str, Any]:
        """Add curves from 3D Slicer markups (``.mrk.json`` or ``.fcsv``) placed on the source and on the target;
        answers the curves added and every point's snap (vertex and distance)."""
        files = {
            side: (Path(path).name, Path(path).read_bytes()) for side, path in (("source", source), ("target", target))
        }
        params = {"join_landmarks": join_landmarks}
        answer: dict[str, Any] = self.client.json(
            "POST", f"{self.path}/markups", files=files, params=params, headers=_if_match(if_revision)
        )
        return answer

    def rename(self, name: str, if_revision: int | None = None) -> Session:
        """Give the session another name (yours, or one shared editable with you)."""
        self.record = self.client.json("PATCH", self.path, json={"name": name}, headers=_if_match(if_revision))
        return self

    def delete(self) -> None:
        """Delete the session and its refinement results."""
        self.client.request("DELETE", self.path)


def _if_match(revision: int | None) -> dict[str, str]:
    return {} if revision is None else {"If-Match": str(revision)}


class Collection:
    """A collection on the server: a template with curves and member shapes (``info``: the last
    ``GET /collections/{id}`` answer, members with their progress)."""

    def __init__(self, client: Client, info: dict[str, Any]):
        self.client, self.info = client, info

    def __repr__(self) -> str:
        return f"Collection({self.id!r}, members={len(self.info['members'])})"

    @property
    def id(self) -> str:
        return self.info["collection"]["id"]

    @property
    def path(self) -> str:
        return f"/collections/{self.id}"

    def refresh(self) -> dict[str, Any]:
        self.info = self.client.json("GET", self.path)
        return self.info

    def add(self, shapes: list[str]) -> list[dict[str, Any]]:
        """Add stored shapes as members; returns every member's status."""
        self.info = self.client.json("POST", f"{self.path}/members", json={"shapes": list(shapes)})
        return self.info["members"]

    def upload(self, paths: list[str | Path]) -> list[dict[str, Any]]:
        """Upload mesh files at once as new members; returns every member's status."""
        handles = [open(path, "rb") for path in paths]  # noqa: SIM115  (closed below)
        try:
            files = [("files", (Path(path).name, handle)) for path, handle in zip(paths, handles, strict=True)]
            self.info = self.client.json("POST", f"{self.path}/members/upload", files=files)
        finally:
            for handle in handles:
                handle.close()
        return self.info["members"]

    def wait_bases(self, timeout: float | None = None, poll_s: float = 0.5) -> list[dict[str, Any]]:
        """Wait until every member's basis is ready (a failed basis job raises)."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while not all(m["basis"] == "ready" for m in self.refresh()["members"]):
            failed = [m["id"] for m in self.info["members"] if m["basis"] in ENDED]
            if failed or (deadline is not None and time.monotonic() > deadline):
                raise TimeoutError(f"collection {self.id}: bases not ready (failed: {failed or 'none'})")
            time.sleep(poll_s)
        return self.info["members"]

    def answer(
        self,
        member: str,
        template_curve: str,
        target: list[int],
        if_revision: int | None = None,
        annotator: str | None = None,
        **options: Any,
    ) -> Curve:
        """Answer a template curve on a member with ``target`` (waypoints on the member); ``if_revision``: only
        while the member's session is at that revision (as :meth:`Session.add_curve`); ``annotator``: in that
        annotator's further annotation of the member (:meth:`annotate`)."""
        body = {"template_curve": template_curve, "target": list(target), **options}
        path, headers = f"{self.path}/members/{member}/curves", _if_match(if_revision)
        params = {"annotator": annotator} if annotator else None
        return Curve.of(self.client.json("POST", path, json=body, headers=headers, params=params)["curve"])

    def submit(self, member: str) -> dict[str, Any]:
        """Submit a member for review (every template curve answered); returns its review (``state``,
        ``submitted_by``, ``submitted_at``, ``reviewed_by``, ``reviewed_at``, ``comment``)."""
        return self.client.json("POST", f"{self.path}/members/{member}/submit")

    def accept(self, member: str, comment: str = "") -> dict[str, Any]:
        """Accept a submitted member (a reviewer, manager or owner); returns its review."""
        return self._review(member, "accept", comment)

    def request_changes(self, member: str, comment: str) -> dict[str, Any]:
        """Send a submitted or accepted member back to its annotator with ``comment``; returns its review."""
        return self._review(member, "request_changes", comment)

    def _review(self, member: str, decision: str, comment: str) -> dict[str, Any]:
        body = {"decision": decision, "comment": comment}
        return self.client.json("POST", f"{self.path}/members/{member}/review", json=body)

    def reviews(self) -> list[dict[str, Any]]:
        """Every member's review, members in order."""
        return self.client.json("GET", f"{self.path}/reviews")

    def comments(self, member: str) -> list[dict[str, Any]]:
        """The member's review comments, oldest first (``id``, ``side``, ``vertex``, ``text``, ``author``,
        ``created_at``, ``reply_to``: a reply's thread, ``resolved_by``, ``resolved_at``: on a thread's first)."""
        return self.client.json("GET", self._comments(member))

    def comment(self, member: str, text: str, side: Literal["source", "target"], vertex: int) -> dict[str, Any]:
        """Start a thread pinned to ``vertex`` (a file id) of the template (``source``) or of the member's shape
        (``target``): a reviewer, manager or owner. Returns the comment."""
        return self.client.json("POST", self._comments(member), json={"text": text, "side": side, "vertex": vertex})

    def reply(self, member: str, comment: str, text: str) -> dict[str, Any]:
        """Reply to ``comment`` (any comment of its thread): reviewers, and the member's annotators (its assignee,
        those of its further annotations). Returns the reply."""
        return self.client.json("POST", self._comments(member), json={"text": text, "reply_to": comment})

    def resolve(self, member: str, comment: str, resolved: bool = True) -> dict[str, Any]:
        """Resolve the thread of ``comment`` (``resolved=False``: reopen it), as whoever may reply; returns its
        first comment."""
        return self.client.json("PATCH", f"{self._comments(member)}/{comment}", json={"resolved": resolved})

    def delete_comment(self, member: str, comment: str) -> None:
        """Delete a comment of yours (a thread's first comment: with its replies)."""
        self.client.request("DELETE", f"{self._comments(member)}/{comment}")

    def _comments(self, member: str) -> str:
        return f"{self.path}/members/{member}/comments"

    def annotate(self, member: str, user: str) -> dict[str, Any]:
        """Ask the annotator named ``user`` for a further, independent annotation of ``member`` (double
        annotation); returns it (``session``: where they answer, or :meth:`answer` with ``annotator=user``)."""
        return self.client.json("POST", f"{self.path}/members/{member}/annotations", json={"user": user})

    def annotate_many(self, user: str, members: list[str] | None = None) -> list[dict[str, Any]]:
        """Ask the annotator named ``user`` for further annotations of ``members`` (default: every member), but
        those they annotate already or are the assignee of; returns the annotations made."""
        body: dict[str, Any] = {"user": user} | ({"members": members} if members is not None else {})
        return self.client.json("POST", f"{self.path}/annotations", json=body)

    def annotations(self) -> list[dict[str, Any]]:
        """Every member's annotations (its own session first, then the further ones)."""
        return self.client.json("GET", f"{self.path}/annotations")

    def agreement(self) -> dict[str, Any]:
        """Agreement between annotators per member annotated twice or more and for the collection (map and
        endpoint distances by sqrt(area), members flagged above the threshold); for managers, ``checks``: each
        annotator's error on the check members (:meth:`set_truth`)."""
        return self.client.json("GET", f"{self.path}/agreement")

    def set_truth(self, member: str, path: str | os.PathLike[str]) -> dict[str, Any]:
        """Make ``member`` a check member: its ground truth from a file (per template vertex the member vertex:
        ``.npy``, ``.vts`` 1-based, or text with one 0-based id per line; -1: unknown); a manager's. Returns its
        summary (``rows``, ``known``, ``set_by``, ``set_at``)."""
        path = Path(path)
        with open(path, "rb") as f:
            return self.client.json("PUT", f"{self.path}/members/{member}/truth", files={"file": (path.name, f)})

    def truth(self, member: str) -> dict[str, Any]:
        """The check member's ground truth (``truth``: the member vertex of each template vertex, -1: unknown)."""
        return self.client.json("GET", f"{self.path}/members/{member}/truth")

    def remove_truth(self, member: str) -> None:
        """Take the member's ground truth away: it is no check member any more."""
        self.client.request("DELETE", f"{self.path}/members/{member}/truth")

    def roles(self) -> list[dict[str, Any]]:
        """Who holds which role (``user``, ``user_id``, ``role``, ``granted_by``, ``granted_at``), its creator
        first."""
        return self.client.json("GET", f"{self.path}/roles")

    def grant(self, user: str, role: str) -> dict[str, Any]:
        """Give the user named ``user`` a role: ``owner``, ``manager``, ``annotator``, ``reviewer`` or ``viewer``
        (replacing the one they held)."""
        return self.client.json("PUT", f"{self.path}/roles/{user}", json={"role": role})

    def revoke(self, user: str) -> None:
        """Take the user's role away (they keep what the collection's sharing gives every user)."""
        self.client.request("DELETE", f"{self.path}/roles/{user}")

    def assign(self, annotators: list[str] | None = None, member: str | None = None, user: str | None = None) -> Any:
        """Spread the members assigned to no one evenly over ``annotators`` (a list of names), or assign one
        ``member`` to ``user`` (None: to no one). Returns the progress (:meth:`assignments`, or the member's)."""
        if member is not None:
            return self.client.json("PUT", f"{self.path}/members/{member}/assignee", json={"user": user})
        return self.client.json("POST", f"{self.path}/assign", json={"annotators": list(annotators or [])})

    def assignments(self) -> dict[str, Any]:
        """Progress per member (``assignee``, curves answered, ``done``) and per annotator (``assigned``,
        ``done``, ``next``)."""
        return self.client.json("GET", f"{self.path}/assignments")

    def remove(self, member: str) -> None:
        """Remove a member with its session, curves and refinement results."""
        self.client.request("DELETE", f"{self.path}/members/{member}")
        self.refresh()

    def run(
        self,
        converter: str = "nearest-neighbor",
        members: list[str] | None = None,
        only_ready: bool = False,
        only_accepted: bool = False,
        **params: Any,
    ) -> dict[str, Any]:
        """Refine every member (or ``members``; ``only_ready``: those of them that have curves; ``only_accepted``:
        those a reviewer accepted) as jobs; returns the run's status (``id``, per member ``state``)."""
        body = {"converter": converter, "params": params, "members": members, "only_ready": only_ready}
        body["only_accepted"] = only_accepted
        return self.client.json("POST", f"{self.path}/runs", json=body)

    def wait_run(self, run_id: str, timeout: float | None = None, poll_s: float = 0.5) -> dict[str, Any]:
        """Wait until the run ended for every member; a run that ended unfinished for some raises."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while (run := self.client.json("GET", f"{self.path}/runs/{run_id}"))["state"] not in ("finished", "failed"):
            if deadline is not None and time.monotonic() > deadline:
                raise TimeoutError(f"run {run_id} of collection {self.id} still {run['state']}")
            time.sleep(poll_s)
        if run["state"] == "failed":
            failed = [f"{m['member']}: {m['error'] or m['state']}" for m in run["members"] if m["state"] != "finished"]
            raise InvalidInput(f"run {run_id} of collection {self.id} failed for {'; '.join(failed)}")
        return run

    def archive(self, run_id: str, out: str | Path, kind: Literal["npz", "zip"] = "npz") -> Path:
        """Download a finished run's archive to ``out``."""
        Path(out).write_bytes(self.client.download(f"{self.path}/runs/{run_id}/archive.{kind}"))
        return Path(out)

    def landmarks(
        self,
        file: str,
        out: str | Path,
        semilandmarks: int = 20,
        pseudo: int = 0,
        run: str | None = None,
        complete_only: bool = False,
        template: bool = False,
    ) -> Path:
        """Download one of the collection's landmark exports (``landmarks.tps``, ``morphologika.txt``,
        ``curveslide.csv``, ``pseudo_landmarks.csv``), one specimen per member (``template``: the template first):
        the template curves' endpoints, ``semilandmarks`` per curve and ``pseudo`` pseudo-landmarks, by the
        members' live maps or a finished ``run``'s; ``complete_only`` leaves out the members that do not answer
        every template curve."""
        params: dict[str, Any] = {"semilandmarks": semilandmarks, "pseudo": pseudo}
        params |= {"complete_only": complete_only, "template": template}
        if run is not None:
            params["run"] = run
        Path(out).write_bytes(self.client.request("GET", f"{self.path}/exports/{file}", params=params).content)
        return Path(out)

    def add_webhook(self, url: str, events: list[str]) -> dict[str, Any]:
        """Register ``url`` to receive a signed POST on each of ``events`` (``run.ended``, ``member.added``, ...);
        the answer's ``secret`` (shown this once) checks the signatures (:func:`curvefm.webhooks.verify`)."""
        return self.client.json("POST", f"{self.path}/webhooks", json={"url": url, "events": list(events)})

    def webhooks(self) -> list[dict[str, Any]]:
        """The collection's webhooks, each with its newest delivery."""
        return self.client.json("GET", f"{self.path}/webhooks")

    def remove_webhook(self, webhook_id: str) -> None:
        self.client.request("DELETE", f"{self.path}/webhooks/{webhook_id}")

    def composed(self, run_id: str, a: str, b: str) -> tuple[np.ndarray, np.ndarray]:
        """``(map_a_to_b, C_a_to_b)``: member a to member b through the template."""
        data = self.client.download(f"{self.path}/runs/{run_id}/members/{a}/to/{b}?format=npz")
        with np.load(io.BytesIO(data)) as arrays:
            return arrays["map_a_to_b"], arrays["C_a_to_b"]
