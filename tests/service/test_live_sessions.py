"""Live sessions against real API processes: a session's changes reach the event streams (Server-Sent Events, read
with httpx) of every process, with Redis (pub/sub) and without it (each process polls the shared database);
presence, the per-user stream limit, permissions, edits refused on a stale revision, and a server that stops
promptly with streams open."""

from __future__ import annotations

import json
import queue
import signal
import threading
import uuid

import httpx
import pytest
from support.errors import expect
from support.processes import add_user
from support.redis_servers import delete_prefix

K = 30
MAX_STREAMS = 3
WAIT_S = 60  # a failsafe: events come within a tick (0.2 s here) or at once
FAST_TICKS = {"CURVEFM_EVENTS_POLL": "0.2", "CURVEFM_EVENTS_KEEPALIVE": "1", "CURVEFM_MAX_EVENT_STREAMS": "3"}


class EventStream:
    """``GET /sessions/{id}/events`` read on a thread: its events (parsed JSON) and comments, in order."""

    def __init__(self, url: str, headers: dict, session_id: str):
        self.client = httpx.Client(base_url=url, headers=headers, timeout=httpx.Timeout(120, read=None))
        self.items: queue.Queue = queue.Queue()
        self.opened = threading.Event()
        self.status: int | None = None
        self.thread = threading.Thread(target=self._read, args=(session_id,), daemon=True)
        self.thread.start()
        assert self.opened.wait(WAIT_S)

    def _read(self, session_id: str) -> None:
        try:
            with self.client.stream("GET", f"/sessions/{session_id}/events") as response:
                self.status, self.response = response.status_code, response
                self.opened.set()
                if response.status_code != 200:
                    response.read()
                    return
                for line in response.iter_lines():
                    if line.startswith("data: "):
                        self.items.put(json.loads(line.removeprefix("data: ")))
                    elif line.startswith(":"):
                        self.items.put({"comment": line})
        except httpx.HTTPError:
            pass
        finally:
            self.opened.set()
            self.items.put(None)  # the stream ended

    def next(self, *kinds: str) -> dict | None:
        """The next event of one of ``kinds`` (others are skipped); None if the stream ends first."""
        while True:
            item = self.items.get(timeout=WAIT_S)
            if item is None or item.get("kind") in kinds:
                return item

    def until(self, kind: str, check) -> dict:
        """The first event of ``kind`` for which ``check(event)`` holds (presence may pass through others)."""
        while True:
            event = self.next(kind)
            assert event is not None, f"the stream ended before a {kind} event that passes"
            if check(event):
                return event

    def close(self) -> None:
        self.client.close()
        self.thread.join(WAIT_S)


@pytest.fixture(scope="module", params=["embedded", "redis"])
def deployment(request, module_processes, tmp_path_factory):
    """Two API processes on one data directory (and, for ``redis``, one Redis with a worker), the demo shapes with
    their bases, and a second user."""
    folder = tmp_path_factory.mktemp(f"live-{request.param}")
    redis_url, prefix = None, f"cfmtest-{uuid.uuid4().hex[:10]}-"
    env = {**FAST_TICKS, "CURVEFM_QUEUE_PREFIX": prefix}
    if request.param == "redis":
        redis_url = request.getfixturevalue("redis_url")
    first = module_processes.api(folder / "data", redis_url, env=env)
    if redis_url:
        module_processes.worker(redis_url, prefix, "live")
    first.shapes, _ = first.demo_pair(folder, K)
    second = module_processes.api(folder / "data", redis_url, env=env)
    bob = second.client_for("bob")
    yield request.param, first, second, bob
    if redis_url:
        delete_prefix(redis_url, prefix)


def shared_session(first, sharing: str = "edit") -> str:
    body = {"source": first.shapes[0], "target": first.shapes[1], "k": K, "sharing": sharing}
    return first.client.post("/sessions", json=body).raise_for_status().json()["id"]


def stream(api, client: httpx.Client, session_id: str) -> EventStream:
    return EventStream(api.url, dict(client.headers), session_id)


def test_changes_made_on_one_process_reach_the_streams_of_the_other(deployment):
    mode, first, second, bob = deployment
    session = shared_session(first)
    bobs = stream(second, bob, session)
    try:
        hello = bobs.next("hello")
        assert hello["revision"] == 0 and "bob" in hello["viewers"]
        added = first.client.post(f"/sessions/{session}/curves", json={"source": [0, 2000], "target": [0, 2000]})
        assert added.status_code == 201, added.text
        # without Redis another process's change is seen by the poller, which knows the revision, not the kind
        change_kinds = ("curve-added", "changed") if mode == "embedded" else ("curve-added",)
        event = bobs.next(*change_kinds)
        assert event["revision"] == added.json()["map"]["revision"] == 1
        first.client.patch(f"/sessions/{session}", json={"name": "live one"}).raise_for_status()
        assert bobs.next("renamed", "changed")["revision"] == 2
        # an edit on bob's own process reaches his stream at once, with its kind
        removed = bob.delete(f"/sessions/{session}/curves/c1")
        assert removed.status_code == 200, removed.text
        assert bobs.next("curve-removed") == {"kind": "curve-removed", "curve": "c1", "revision": 3}
    finally:
        bobs.close()


def test_the_streams_show_who_has_the_session_open_across_processes(deployment):
    _, first, second, bob = deployment
    session = shared_session(first)
    bobs = stream(second, bob, session)
    try:
        assert bobs.next("hello")["viewers"] == ["bob"]
        owners = stream(first, first.client, session)
        try:
            assert owners.next("hello")["viewers"] == ["bob", "tester"]
            bobs.until("viewers", lambda event: event["viewers"] == ["bob", "tester"])
        finally:
            owners.close()
        bobs.until("viewers", lambda event: event["viewers"] == ["bob"])  # the owner closed the page
    finally:
        bobs.close()


def test_an_idle_stream_gets_keep_alive_comments(deployment):
    _, first, _, _ = deployment
    session = shared_session(first)
    owners = stream(first, first.client, session)
    try:
        comments = 0
        while comments < 2:
            item = owners.items.get(timeout=WAIT_S)
            assert item is not None
            comments += "comment" in item
    finally:
        owners.close()


def test_an_edit_based_on_an_old_revision_is_refused_with_the_current_revision(deployment):
    _, first, second, bob = deployment
    session = shared_session(first)
    curve = {"source": [0, 2000], "target": [0, 2000]}
    read = first.client.get(f"/sessions/{session}")
    assert read.headers["ETag"] == '"0"'
    assert bob.post(f"/sessions/{session}/curves", json=curve).status_code == 201  # on the other process
    stale = first.client.post(f"/sessions/{session}/curves", json=curve, headers={"If-Match": read.headers["ETag"]})
    body = expect(stale, 409, "conflict", "revision 1", "not 0", "reload")
    assert body["revision"] == 1
    for method, path in (("PUT", "/curves/c1"), ("DELETE", "/curves/c1"), ("PATCH", "")):
        json_body = {"name": "x"} if method == "PATCH" else curve if method == "PUT" else None
        refused = second.client.request(method, f"/sessions/{session}{path}", json=json_body, headers={"If-Match": "0"})
        assert expect(refused, 409, "conflict")["revision"] == 1
    assert first.client.get(f"/sessions/{session}").json()["revision"] == 1  # nothing changed
    fresh = first.client.post(f"/sessions/{session}/curves", json=curve, headers={"If-Match": "1"})
    assert fresh.status_code == 201 and fresh.json()["map"]["revision"] == 2
    expect(first.client.post(f"/sessions/{session}/curves", json=curve, headers={"If-Match": "two"}), 422, "invalid")


def test_a_user_may_have_a_bounded_number_of_streams_across_processes(deployment):
    _, first, second, _ = deployment
    session = shared_session(first)
    carol = first.client_for("carol")
    streams = [stream(api, carol, session) for api in (first, second, first)]
    try:
        assert all(s.next("hello") for s in streams)
        extra = carol.get(f"/sessions/{session}/events")
        body = expect(extra, 429, "too_many", "CURVEFM_MAX_EVENT_STREAMS")
        assert body["limit"] == "CURVEFM_MAX_EVENT_STREAMS"
    finally:
        for s in streams:
            s.close()
    again = stream(second, carol, session)  # closed streams no longer count
    try:
        assert again.status == 200 and again.next("hello")
    finally:
        again.close()


def test_only_readers_get_a_stream_and_one_losing_access_is_told_and_ended(deployment):
    _, first, second, bob = deployment
    private = shared_session(first, "private")
    expect(bob.get(f"/sessions/{private}/events"), 404, "not_found", private)
    anonymous = httpx.get(f"{second.url}/sessions/{private}/events", timeout=30)
    expect(anonymous, 401, "unauthenticated")
    expect(bob.get("/sessions/nosuchsession/events"), 404, "not_found")

    readable = shared_session(first, "read")
    bobs = stream(second, bob, readable)
    try:
        assert bobs.next("hello")["revision"] == 0
        first.client.patch(f"/sessions/{readable}", json={"sharing": "private"}).raise_for_status()
        assert bobs.next("forbidden", "changed", "sharing") == {"kind": "forbidden", "revision": 1}
        assert bobs.next("any") is None  # the stream ended
    finally:
        bobs.close()


def test_a_stream_whose_credential_ended_ends_at_its_next_keep_alive(deployment):
    _, first, second, _ = deployment
    carol = second.client_for(f"carol-{uuid.uuid4().hex[:6]}")
    name = carol.get("/auth/me").raise_for_status().json()["name"]
    readable = shared_session(first, "read")
    carols = stream(second, carol, readable)
    try:
        assert carols.next("hello")["revision"] == 0
        while "comment" not in (item := carols.items.get(timeout=WAIT_S)):  # kept alive while her token holds
            assert item is not None, "the stream ended while its credential held"
        add_user(second.data_dir, name)  # an admin rotates her token: the stream's credential ends
        assert carols.next("logged-out", "forbidden")["kind"] == "logged-out"
        assert carols.next("any") is None  # the stream ended
    finally:
        carols.close()


def test_deleting_the_session_ends_its_streams(deployment):
    _, first, second, bob = deployment
    session = shared_session(first)
    bobs = stream(second, bob, session)
    try:
        bobs.next("hello")
        assert first.client.delete(f"/sessions/{session}").status_code == 204
        assert bobs.next("deleted")["kind"] == "deleted"
        assert bobs.next("any") is None
    finally:
        bobs.close()


def test_a_finished_refinement_is_an_event(deployment):
    _, first, second, bob = deployment
    session = shared_session(first)
    first.client.post(f"/sessions/{session}/curves", json={"source": [0, 2000], "target": [0, 2000]})
    bobs = stream(second, bob, session)
    try:
        bobs.next("hello")
        job = first.client.post(f"/sessions/{session}/refine", json={"converter": "nearest-neighbor"})
        assert job.status_code == 202, job.text
        assert first.wait_job(job.json()["id"])["state"] == "finished"
        assert bobs.next("refined")["kind"] == "refined"
    finally:
        bobs.close()


def test_review_comments_reach_the_streams_of_the_members_sessions_across_processes(deployment):
    _, first, second, bob = deployment
    session = shared_session(first)
    first.client.post(f"/sessions/{session}/curves", json={"source": [0, 2000], "target": [0, 2000]})
    made = first.client.post("/collections", json={"template": first.shapes[0], "from_session": session})
    collection = made.raise_for_status().json()["collection"]
    base = f"/collections/{collection['id']}"
    first.client.put(f"{base}/roles/bob", json={"role": "annotator"}).raise_for_status()
    further = first.client.post(f"{base}/members/m1/annotations", json={"user": "bob"}).raise_for_status().json()
    own = next(member["session"] for member in collection["members"] if member["id"] == "m1")
    streams = [stream(second, bob, own), stream(second, bob, further["session"])]
    comments = f"{base}/members/m1/comments"
    try:
        assert all(s.next("hello") for s in streams)
        pinned = first.client.post(comments, json={"text": "too low", "side": "source", "vertex": 60})
        assert pinned.status_code == 201, pinned.text
        changes = [
            lambda: bob.post(comments, json={"text": "moved", "reply_to": pinned.json()["id"]}),
            lambda: first.client.patch(f"{comments}/{pinned.json()['id']}", json={"resolved": True}),
            lambda: first.client.delete(f"{comments}/{pinned.json()['id']}"),
        ]
        for change in [None, *changes]:  # each change once the previous one was heard, on both pages
            if change is not None:
                assert change().status_code in (200, 201, 204)
            for s in streams:
                assert s.next("comments")["kind"] == "comments"
        assert bob.get(comments).json() == []
    finally:
        for s in streams:
            s.close()


def test_a_server_with_open_streams_stops_promptly(deployment, module_processes):
    _, first, _, _ = deployment
    extra = module_processes.api(first.data_dir, env=FAST_TICKS)
    session = shared_session(first)
    streams = [stream(extra, extra.client, session) for _ in range(2)]
    try:
        assert all(s.next("hello") for s in streams)
        extra.process.send_signal(signal.SIGINT)
        # uvicorn waits for every open response before it shuts down: for ever, had the streams not ended
        assert extra.process.wait(timeout=30) in (0, -signal.SIGINT)  # (uvicorn raises the signal again at its end)
        assert "Application shutdown complete" in extra.log.read_text()  # a graceful stop, not a forced one
        for s in streams:
            assert s.next("closing")["kind"] == "closing"
            assert s.next("any") is None
    finally:
        for s in streams:
            s.close()
    assert first.client.get(f"/sessions/{session}").status_code == 200  # the other processes go on
