"""Webhooks against a real server process, with Redis and a worker (a run's end is recorded by the worker that
ends its last job), posting to a real HTTP receiver this test runs on loopback (the server is told it may post to
private addresses: CURVEFM_WEBHOOK_ALLOW_PRIVATE). The receiver checks every signature with HMAC code written
here from the documented scheme, not with curvefm's."""

from __future__ import annotations

import hashlib
import hmac
import json
import threading
import time
import typing
import uuid
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import pytest
from support.lab import CURVE, Lab
from support.processes import TEST_USER
from support.redis_servers import delete_prefix

from curvefm.client import Client
from curvefm.service.models import WebhookEventName
from curvefm.webhooks import WebhookEvent

EVERY_EVENT = [str(event) for event in WebhookEvent]
RETRIES = 2
TIMEOUT_S = 1.0
SLOW_S = 3.0
SETTINGS = {
    "CURVEFM_WEBHOOK_ALLOW_PRIVATE": "true",
    "CURVEFM_WEBHOOK_RETRIES": str(RETRIES),
    "CURVEFM_WEBHOOK_RETRY_DELAY": "0.2",
    "CURVEFM_WEBHOOK_POLL": "0.1",
    "CURVEFM_WEBHOOK_TIMEOUT": str(TIMEOUT_S),
}


class Receiver:
    """An HTTP server on loopback that keeps every POST. ``/ok`` answers 204, ``/flaky`` 500 once then 200,
    ``/down`` 503, ``/slow`` 200 after longer than the server's timeout."""

    def __init__(self):
        self.posts: list[dict] = []
        self.lock = threading.Lock()
        receiver = self

        class Handler(BaseHTTPRequestHandler):
            def do_POST(self):
                body = self.rfile.read(int(self.headers["Content-Length"]))
                with receiver.lock:
                    receiver.posts.append({"path": self.path, "headers": dict(self.headers), "body": body})
                    seen = sum(post["path"] == self.path for post in receiver.posts)
                if self.path == "/slow":
                    time.sleep(SLOW_S)
                status = {"/ok": 204, "/down": 503}.get(self.path, 500 if seen == 1 else 200)
                self.send_response(status)
                self.send_header("Content-Length", "0")
                self.end_headers()

            def log_message(self, *args):
                pass

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.server.server_address[1]}"
        threading.Thread(target=self.server.serve_forever, daemon=True).start()

    def received(self, path: str, event: str, count: int = 1, timeout: float = 60) -> list[dict]:
        """The first ``count`` posts of ``event`` to ``path``, once they arrived."""
        deadline = time.monotonic() + timeout
        while True:
            with self.lock:
                found = [p for p in self.posts if p["path"] == path and p["headers"]["X-Curvefm-Event"] == event]
            if len(found) >= count or time.monotonic() > deadline:
                assert len(found) >= count, f"{count} {event} posts to {path} expected, got {len(found)}"
                return found[:count]
            time.sleep(0.05)


def signed_by(secret: str, post: dict) -> bool:
    """The documented check: ``X-Curvefm-Signature: t=<unix time>,v1=<hex HMAC-SHA256 of "<t>.<body>">``."""
    fields = dict(part.split("=", 1) for part in post["headers"]["X-Curvefm-Signature"].split(","))
    expected = hmac.new(secret.encode(), fields["t"].encode() + b"." + post["body"], hashlib.sha256).hexdigest()
    return hmac.compare_digest(expected, fields["v1"]) and abs(time.time() - int(fields["t"])) < 300


@pytest.fixture(scope="module")
def lab(module_processes, tmp_path_factory, redis_url):
    prefix = f"cfmtest-{uuid.uuid4().hex[:10]}-"
    env = {"CURVEFM_QUEUE_PREFIX": prefix, **SETTINGS}
    api = module_processes.api(tmp_path_factory.mktemp("webhooks") / "data", redis_url=redis_url, env=env)
    module_processes.worker(redis_url, prefix, "webhooks")
    yield Lab(api)
    delete_prefix(redis_url, prefix)


@pytest.fixture(scope="module")
def receiver():
    receiver = Receiver()
    yield receiver
    receiver.server.shutdown()


@pytest.fixture
def collection(lab) -> str:
    return lab.new_collection(lab.owner, _session_with_curve(lab))


def _session_with_curve(lab: Lab) -> str:
    session_id = lab.new_session()
    lab.add_curve(lab.owner, session_id)
    return session_id


def _register(lab: Lab, collection: str, url: str, events: list[str]) -> dict:
    response = lab.owner.post(f"/collections/{collection}/webhooks", json={"url": url, "events": events})
    assert response.status_code == 201, response.text
    return response.json()


def _ready_shape(lab: Lab) -> str:
    shape = lab.new_shape()
    lab.basis(lab.owner, shape)
    return shape


def test_the_event_names_of_the_schema_are_the_events():
    assert set(typing.get_args(WebhookEventName)) == set(EVERY_EVENT)


def test_events_are_posted_signed(lab, receiver, collection):
    hook = _register(lab, collection, f"{receiver.url}/ok", EVERY_EVENT)
    secret = hook.pop("secret")
    listed = lab.owner.get(f"/collections/{collection}/webhooks").raise_for_status()
    assert listed.json() == [hook] and secret not in listed.text

    added = lab.owner.post(f"/collections/{collection}/members", json={"shapes": [_ready_shape(lab)]})
    member = added.raise_for_status().json()["members"][-1]
    (post,) = receiver.received("/ok", "member.added")
    body = json.loads(post["body"])
    assert signed_by(secret, post) and not signed_by(secret, {**post, "body": post["body"] + b" "})
    assert post["headers"]["X-Curvefm-Delivery"] == body["id"] and post["headers"]["Content-Type"] == "application/json"
    assert (body["event"], body["collection"], body["data"]) == (
        "member.added",
        collection,
        {"member": member["id"], "shape": member["shape"], "session": member["session"]},
    )

    answer = {"template_curve": "t1", "target": CURVE["target"]}
    lab.owner.post(f"/collections/{collection}/members/{member['id']}/curves", json=answer).raise_for_status()
    (post,) = receiver.received("/ok", "member.completed")
    assert signed_by(secret, post) and json.loads(post["body"])["data"]["member"] == member["id"]

    member_path = f"/collections/{collection}/members/{member['id']}"
    lab.owner.post(f"{member_path}/submit").raise_for_status()
    (post,) = receiver.received("/ok", "member.submitted")
    assert json.loads(post["body"])["data"] == {"member": member["id"], "by": TEST_USER}
    lab.owner.post(f"{member_path}/review", json={"decision": "accept", "comment": "fine"}).raise_for_status()
    (post,) = receiver.received("/ok", "member.accepted")
    assert signed_by(secret, post) and json.loads(post["body"])["data"] == {
        "member": member["id"],
        "by": TEST_USER,
        "comment": "fine",
    }

    run = lab.finished_run(lab.owner, collection)
    (post,) = receiver.received("/ok", "run.ended")
    data = json.loads(post["body"])["data"]
    assert signed_by(secret, post) and data == {
        "run": run,
        "converter": "nearest-neighbor",
        "members": 2,
        "states": {"finished": 2},
    }

    lab.owner.delete(f"/collections/{collection}/members/{member['id']}").raise_for_status()
    (post,) = receiver.received("/ok", "member.removed")
    assert json.loads(post["body"])["data"] == {"member": member["id"], "shape": member["shape"]}
    time.sleep(1)  # nothing more arrives: each event once
    with receiver.lock:
        mine = [json.loads(p["body"]) for p in receiver.posts if p["path"] == "/ok"]
    assert sorted(b["event"] for b in mine if b["collection"] == collection) == sorted(
        ["member.added", "member.completed", "member.submitted", "member.accepted", "run.ended", "member.removed"]
    )
    log = lab.owner.get(f"/collections/{collection}/webhooks/{hook['id']}/deliveries").raise_for_status()
    assert log.headers["X-Total-Count"] == "6"
    assert {(d["state"], d["attempts"], d["last_status"]) for d in log.json()} == {("delivered", 1, 204)}


def test_failed_deliveries_are_retried_then_given_up_and_logged(lab, receiver, collection):
    hooks = {
        path: _register(lab, collection, f"{receiver.url}{path}", ["member.added"])
        for path in ("/flaky", "/down", "/slow")
    }
    lab.owner.post(f"/collections/{collection}/members", json={"shapes": [lab.new_shape()]}).raise_for_status()
    flaky = receiver.received("/flaky", "member.added", count=2)
    assert flaky[0]["headers"]["X-Curvefm-Delivery"] == flaky[1]["headers"]["X-Curvefm-Delivery"]
    receiver.received("/down", "member.added", count=1 + RETRIES)
    receiver.received("/slow", "member.added", count=1 + RETRIES, timeout=60 + 3 * SLOW_S)
    expected = {
        "/flaky": ("delivered", 2, 200),
        "/down": ("failed", 1 + RETRIES, 503),
        "/slow": ("failed", 1 + RETRIES, None),
    }
    deadline = time.monotonic() + 30
    while True:
        listed = {
            hook["url"]: hook["last_delivery"] for hook in lab.owner.get(f"/collections/{collection}/webhooks").json()
        }
        got = {
            path: tuple(listed[f"{receiver.url}{path}"][k] for k in ("state", "attempts", "last_status"))
            for path in hooks
        }
        if got == expected or time.monotonic() > deadline:
            break
        time.sleep(0.2)
    assert got == expected
    assert "Timeout" in listed[f"{receiver.url}/slow"]["last_error"]
    assert listed[f"{receiver.url}/down"]["last_error"] == "the receiver answered 503"
    time.sleep(1)  # no attempt past the last
    with receiver.lock:
        assert sum(p["path"] == "/down" for p in receiver.posts) == 1 + RETRIES


def test_who_may_register_and_what_is_refused(lab, receiver, collection):
    hooks = f"/collections/{collection}/webhooks"
    body = {"url": f"{receiver.url}/ok", "events": ["run.ended"]}
    assert lab.other.post(hooks, json=body).status_code == 404  # they cannot see the collection
    lab.owner.put(f"/collections/{collection}/roles/oscar", json={"role": "annotator"}).raise_for_status()
    refused = lab.other.post(hooks, json=body)
    assert refused.status_code == 403 and "manager" in refused.json()["detail"]
    assert lab.other.get(hooks).status_code == 403
    lab.owner.put(f"/collections/{collection}/roles/oscar", json={"role": "manager"}).raise_for_status()
    hook = lab.other.post(hooks, json=body)
    assert hook.status_code == 201, hook.text
    with Client(lab.api.url, token=lab.api.token) as client:
        mine = client.open_collection(collection)
        added = mine.add_webhook(f"{receiver.url}/ok", ["member.removed"])
        assert [h["id"] for h in mine.webhooks()] == [hook.json()["id"], added["id"]]
        mine.remove_webhook(added["id"])
    for url, words in (
        ("ftp://lab.example/x", "http:// or https://"),
        ("https://user:pw@lab.example/x", "no user name"),
        ("https://lab.example:99999/x", "port"),
    ):
        response = lab.owner.post(hooks, json={**body, "url": url})
        assert response.status_code == 400 and words in response.json()["detail"], response.text
    assert lab.owner.post(hooks, json={**body, "events": ["member.eaten"]}).status_code == 422
    lab.owner.delete(f"{hooks}/{hook.json()['id']}").raise_for_status()
    assert lab.owner.get(hooks).json() == []
    assert lab.owner.delete(f"{hooks}/{hook.json()['id']}").status_code == 404
    assert lab.owner.get(f"{hooks}/{hook.json()['id']}/deliveries").status_code == 404


def test_a_member_whose_session_is_deleted_directly_is_announced_removed(lab, receiver, collection):
    """Deleting a member's session (DELETE /sessions/{id}) removes the member: announced as DELETE .../members/{m}
    announces it, once, its delivery recorded with the deletion (listed as soon as the deletion answered)."""
    hook = _register(lab, collection, f"{receiver.url}/ok", ["member.removed"])
    (member,) = lab.owner.get(f"/collections/{collection}").raise_for_status().json()["members"]
    lab.owner.delete(f"/sessions/{member['session']}").raise_for_status()
    log = lab.owner.get(f"/collections/{collection}/webhooks/{hook['id']}/deliveries").raise_for_status()
    assert [d["event"] for d in log.json()] == ["member.removed"]
    assert lab.owner.get(f"/collections/{collection}").json()["members"] == []

    deadline = time.monotonic() + 60
    while not _posts_of(receiver, collection) and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(1)  # nothing more arrives: the event once
    (body,) = _posts_of(receiver, collection)
    assert (body["event"], body["data"]) == ("member.removed", {"member": member["id"], "shape": member["shape"]})


def _posts_of(receiver: Receiver, collection: str) -> list[dict]:
    """The bodies of the posts to ``/ok`` about ``collection``."""
    with receiver.lock:
        bodies = [json.loads(p["body"]) for p in receiver.posts if p["path"] == "/ok"]
    return [body for body in bodies if body["collection"] == collection]


@pytest.mark.parametrize("queue", ["embedded", "redis"])
def test_events_of_the_records_layer_keep_the_configured_delivery_log(queue, processes, tmp_path, receiver, redis_url):
    """``run.ended`` (recorded with the run's last job's end: by the API's in-process executor, or by the worker,
    whose environment does not set the size) and ``member.removed`` (a member's session deleted directly) keep each
    webhook's newest ``CURVEFM_WEBHOOK_LOG_SIZE`` deliveries, as the service's own events do."""
    prefix = f"cfmtest-{uuid.uuid4().hex[:10]}-"
    env = {**SETTINGS, "CURVEFM_WEBHOOK_LOG_SIZE": "1", "CURVEFM_QUEUE_PREFIX": prefix}
    try:
        if queue == "redis":
            api = processes.api(tmp_path / "data", redis_url=redis_url, env=env)
            processes.worker(redis_url, prefix, "log-size")
        else:
            api = processes.api(tmp_path / "data", env=env)
        _records_layer_events_keep_one_delivery(Lab(api), receiver)
    finally:
        delete_prefix(redis_url, prefix)


def _records_layer_events_keep_one_delivery(lab: Lab, receiver: Receiver) -> None:
    collection = lab.new_collection(lab.owner, _session_with_curve(lab))
    hook = _register(lab, collection, f"{receiver.url}/ok", ["run.ended", "member.removed"])
    log = f"/collections/{collection}/webhooks/{hook['id']}/deliveries"
    for _ in range(2):
        lab.finished_run(lab.owner, collection)
        (delivery,) = _delivered(lab, log)
        assert delivery["event"] == "run.ended"  # the one before, delivered, forgotten
    (member,) = lab.owner.get(f"/collections/{collection}").raise_for_status().json()["members"]
    lab.owner.delete(f"/sessions/{member['session']}").raise_for_status()
    assert [d["event"] for d in _delivered(lab, log)] == ["member.removed"]


def _delivered(lab: Lab, log: str, timeout: float = 60) -> list[dict]:
    """The webhook's delivery log once every delivery in it was delivered."""
    deadline = time.monotonic() + timeout
    while True:
        deliveries = lab.owner.get(log).raise_for_status().json()
        if all(d["state"] == "delivered" for d in deliveries):
            return deliveries
        assert time.monotonic() < deadline, deliveries
        time.sleep(0.05)
