"""Webhooks in the database (both engines): registered and listed without their secret, events written to the
outbox for the webhooks subscribed to them, a run's end announced once by the job that ended it last, deliveries
claimed once, retried and logged, cascades."""

from __future__ import annotations

import json
import threading

import pytest
from support.records import collection_record, curve, job_row, repositories, session_record, shape_id

from curvefm.collection.record import Member, Run, RunMember
from curvefm.errors import LimitExceeded, NotFound
from curvefm.records.webhooks import Webhooks
from curvefm.webhooks import WebhookEvent

RUN_AND_MEMBERS = [WebhookEvent.RUN_ENDED, WebhookEvent.MEMBER_ADDED]


@pytest.fixture
def repo(db):
    repo = repositories(db)
    repo["users"].add("alice")
    alice = repo["users"].get("alice")
    template, shapes = shape_id(), [shape_id(), shape_id()]
    for shape in (template, *shapes):
        repo["shapes"].add(shape, 10, alice.id)
    record = collection_record(template, owner="alice")
    repo["collections"].create(record)
    added = []
    for i, shape in enumerate(shapes, 1):
        session = session_record(template, shape, owner="alice", curves=[curve("c1", template_curve="t1")])
        added.append((Member(id=f"m{i}", shape=shape, session=session.id), session))
    repo["record"] = repo["collections"].add_members(record.id, record.revision, added)
    repo["alice"], repo["hooks"] = alice, Webhooks(db, log_size=3)
    return repo


def _run(repo, states=("started", "started")) -> tuple[str, list[str]]:
    """A run r1 of both members, its jobs in ``states``."""
    jobs = [job_row(owner="alice", state=state) for state in states]
    for job in jobs:
        repo["jobs"].create(job)
    record = repo["collections"].read(repo["record"].id)
    members = {f"m{i}": RunMember(job=job.id, revision=1) for i, job in enumerate(jobs, 1)}
    run = Run(id="r1", converter="nearest-neighbor", params={}, created_at=1.0, members=members)
    repo["collections"].write(record.model_copy(update={"runs": [run], "next_run": 2}))
    return record.id, [job.id for job in jobs]


def _bodies(repo, now: float = 1e12) -> list[dict]:
    return [json.loads(due.body) for due in repo["hooks"].claim(now, lease_s=30, limit=100)]


def test_a_webhook_is_listed_without_its_secret_and_deleted(repo):
    hooks, collection = repo["hooks"], repo["record"].id
    row, secret = hooks.create(collection, "https://lab.example/h", RUN_AND_MEMBERS, repo["alice"].id, limit=2)
    assert secret.startswith("whsec_") and len(secret) > 40
    assert row.events == ["member.added", "run.ended"] and row.created_by == "alice" and row.last_delivery is None
    assert hooks.of_collection(collection) == [row] and secret not in repr(hooks.of_collection(collection))
    hooks.create(collection, "https://lab.example/g", RUN_AND_MEMBERS, None, limit=2)
    with pytest.raises(LimitExceeded, match="CURVEFM_MAX_WEBHOOKS"):
        hooks.create(collection, "https://lab.example/f", RUN_AND_MEMBERS, None, limit=2)
    hooks.delete(collection, row.id)
    with pytest.raises(NotFound):
        hooks.delete(collection, row.id)
    with pytest.raises(NotFound):
        hooks.get(
            "another", hooks.of_collection(collection)[0].id
        )  # a webhook is found through its own collection only


def test_an_event_reaches_the_webhooks_subscribed_to_it(repo):
    hooks, collection = repo["hooks"], repo["record"].id
    runs, _ = hooks.create(collection, "https://lab.example/runs", [WebhookEvent.RUN_ENDED], None, limit=5)
    members, _ = hooks.create(collection, "https://lab.example/m", [WebhookEvent.MEMBER_ADDED], None, limit=5)
    assert hooks.subscribed(collection, WebhookEvent.RUN_ENDED)
    assert not hooks.subscribed(collection, WebhookEvent.MEMBER_REMOVED)
    assert hooks.notify(collection, WebhookEvent.MEMBER_REMOVED, {"member": "m3"}) == []
    (delivery,) = hooks.notify(collection, WebhookEvent.MEMBER_ADDED, {"member": "m3"})
    (body,) = _bodies(repo)
    assert body == {**body, "id": delivery, "event": "member.added", "collection": collection, "data": {"member": "m3"}}
    assert hooks.get(collection, members.id).last_delivery.id == delivery
    assert hooks.get(collection, runs.id).last_delivery is None


def test_the_last_job_to_end_announces_the_run_once(repo):
    hooks = repo["hooks"]
    hook, _ = hooks.create(repo["record"].id, "https://lab.example/h", RUN_AND_MEMBERS, None, limit=5)
    collection, (job1, job2) = _run(repo)
    repo["jobs"].update(job1, state="finished", ended_at=10.0)
    assert _bodies(repo) == []  # one job of two ended
    repo["jobs"].update(job2, state="failed", ended_at=11.0, error=("invalid", "no"))
    repo["jobs"].update(job2, state="failed", ended_at=11.0)  # an end changed to another end: not a new end
    repo["jobs"].lose(job2, "gone")
    (body,) = _bodies(repo)
    assert body["event"] == "run.ended" and body["data"] == {
        "run": "r1",
        "converter": "nearest-neighbor",
        "members": 2,
        "states": {"failed": 1, "finished": 1},
    }
    hooks.run_recorded(collection, "r1")  # the route's check after recording the run finds it announced
    assert _bodies(repo) == []
    assert hooks.deliveries(collection, hook.id, limit=10).total == 1


def test_a_run_whose_jobs_ended_before_it_was_recorded_is_announced_when_recorded(repo):
    hooks = repo["hooks"]
    hooks.create(repo["record"].id, "https://lab.example/h", [WebhookEvent.RUN_ENDED], None, limit=5)
    collection, _ = _run(repo, states=("finished", "canceled"))
    hooks.run_recorded(collection, "r1")
    hooks.run_recorded(collection, "r1")
    assert [b["data"]["states"] for b in _bodies(repo)] == [{"canceled": 1, "finished": 1}]


def test_two_last_jobs_ending_at_once_announce_the_run_once(repo):
    """Each end in its own transaction, in two threads: whichever commits second sees both ends."""
    hooks = repo["hooks"]
    hooks.create(repo["record"].id, "https://lab.example/h", [WebhookEvent.RUN_ENDED], None, limit=5)
    _, jobs = _run(repo)
    threads = [
        threading.Thread(target=repo["jobs"].update, args=(job,), kwargs={"state": "finished", "ended_at": 5.0})
        for job in jobs
    ]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert [b["data"]["states"] for b in _bodies(repo)] == [{"finished": 2}]


def test_deliveries_are_claimed_once_retried_and_logged(repo):
    hooks, collection = repo["hooks"], repo["record"].id
    hook, _ = hooks.create(collection, "https://lab.example/h", [WebhookEvent.MEMBER_ADDED], None, limit=5)
    (delivery,) = hooks.notify(collection, WebhookEvent.MEMBER_ADDED, {"member": "m3"})
    (due,) = hooks.claim(1e12, lease_s=30, limit=5)
    assert (due.id, due.url, due.attempts) == (delivery, "https://lab.example/h", 0) and due.secret.startswith("whsec_")
    assert hooks.claim(1e12, lease_s=30, limit=5) == []  # leased
    hooks.attempted(delivery, 100.0, 500, "the receiver answered 500", retry_at=200.0)
    assert hooks.claim(150.0, lease_s=30, limit=5) == []  # not due yet
    (again,) = hooks.claim(250.0, lease_s=30, limit=5)
    assert again.attempts == 1
    hooks.attempted(delivery, 260.0, 204, None, retry_at=None)
    last = hooks.get(collection, hook.id).last_delivery
    assert (last.state, last.attempts, last.last_status, last.last_error) == ("delivered", 2, 204, None)
    assert hooks.claim(1e12, lease_s=30, limit=5) == []
    for i in range(5):  # the log keeps the newest 3 that are not pending
        (done,) = hooks.notify(collection, WebhookEvent.MEMBER_ADDED, {"member": f"x{i}"})
        hooks.attempted(done, 300.0 + i, None, "ConnectError: refused", retry_at=None)
    page = hooks.deliveries(collection, hook.id, limit=10)
    assert page.total == 3 and {d.state for d in page.items} == {"failed"}


def test_deleting_the_collection_deletes_its_webhooks_and_deliveries(repo):
    hooks, collection = repo["hooks"], repo["record"].id
    hooks.create(collection, "https://lab.example/h", [WebhookEvent.MEMBER_ADDED], None, limit=5)
    hooks.notify(collection, WebhookEvent.MEMBER_ADDED, {"member": "m3"})
    repo["collections"].delete(collection)
    assert hooks.of_collection(collection) == [] and hooks.claim(1e12, lease_s=30, limit=5) == []
