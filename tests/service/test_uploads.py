"""Big uploads read at once are bounded across the API processes of a deployment (``CURVEFM_MAX_CONCURRENT_UPLOADS``
slots in the queue's Redis): beyond them an upload answers 429 naming the limit, with ``Retry-After``, and stores
nothing; a slot of a process that died ends with its lease. Two real API processes on one Redis and data
directory; the test takes a slot itself as a third process reading a big upload would."""

from __future__ import annotations

import threading

import pytest

from curvefm.service.uploads import RedisSlots
from tests.support.errors import expect, snapshot
from tests.support.shapes import ellipsoid, off_bytes

BIG_BYTES = 20_000
LIMITED = {"CURVEFM_MAX_CONCURRENT_UPLOADS": "1", "CURVEFM_BIG_UPLOAD_BYTES": str(BIG_BYTES)}
LEASE_S = 600.0


@pytest.fixture
def deployment(processes, redis_url, redis_prefix, tmp_path):
    """Two API processes sharing one upload slot, and the slots as a third process sees them."""
    env = {"CURVEFM_QUEUE_PREFIX": redis_prefix, **LIMITED}
    first = processes.api(tmp_path / "data", redis_url=redis_url, env=env)
    second = processes.api(tmp_path / "data", redis_url=redis_url, env=env)
    return first, second, RedisSlots(redis_url, redis_prefix, limit=1, lease_s=LEASE_S)


def big_mesh(scale: float) -> bytes:
    content = off_bytes(ellipsoid(scale=scale))  # another scale, another shape
    assert len(content) >= BIG_BYTES
    return content


def upload(api, name: str, content: bytes):
    return api.client.post("/shapes", files={"file": (name, content)})


def shape_ids(api) -> set[str]:
    return {shape["id"] for shape in api.client.get("/shapes").raise_for_status().json()}


def test_a_big_upload_past_the_slots_of_every_process_is_a_429_and_stores_nothing(deployment, tmp_path):
    first, second, slots = deployment
    assert slots.take("a-third-process")
    before = snapshot(tmp_path / "data")
    for api in (first, second):
        refused = upload(api, "big.off", big_mesh(1.0))
        body = expect(refused, 429, "too_many", "CURVEFM_MAX_CONCURRENT_UPLOADS", "CURVEFM_BIG_UPLOAD_BYTES")
        assert body["limit"] == "CURVEFM_MAX_CONCURRENT_UPLOADS" and int(refused.headers["Retry-After"]) >= 1, body
    assert snapshot(tmp_path / "data") == before
    small = off_bytes(ellipsoid(6, 12))
    assert len(small) < BIG_BYTES
    stored_small = upload(second, "small.off", small)  # a small upload takes no slot
    assert stored_small.status_code == 201, stored_small.text
    slots.give_back("a-third-process")
    stored = [upload(api, "big.off", big_mesh(scale)) for api, scale in ((first, 1.0), (second, 1.1), (first, 1.2))]
    assert [response.status_code for response in stored] == [201, 201, 201], [r.text for r in stored]
    assert shape_ids(second) == {response.json()["id"] for response in [*stored, stored_small]}


def test_a_slot_of_a_process_that_died_ends_with_its_lease(deployment, redis_url, redis_prefix):
    first, _, slots = deployment
    assert slots.take("a-process-killed-while-parsing")
    expect(upload(first, "big.off", big_mesh(1.0)), 429, "too_many")
    slots.give_back("a-process-killed-while-parsing")
    assert RedisSlots(redis_url, redis_prefix, limit=1, lease_s=0.001).take("killed-a-millisecond-ago")
    assert upload(first, "big.off", big_mesh(1.0)).status_code == 201  # its lease ended before this upload came


def test_concurrent_big_uploads_to_two_processes_answer_201_or_429_and_store_exactly_the_201s(deployment):
    """Six distinct big uploads at once over two processes with one slot: each answer is a stored shape or a 429
    naming the limit, and the shapes stored are exactly those answered 201."""
    first, second, _ = deployment
    answers: dict[int, object] = {}

    def send(i: int) -> None:
        answers[i] = upload((first, second)[i % 2], f"big{i}.off", big_mesh(1.0 + i / 10))

    threads = [threading.Thread(target=send, args=(i,)) for i in range(6)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    statuses = sorted(response.status_code for response in answers.values())
    assert set(statuses) <= {201, 429} and 201 in statuses, statuses
    for response in answers.values():
        if response.status_code == 429:
            expect(response, 429, "too_many", "CURVEFM_MAX_CONCURRENT_UPLOADS")
    created = {response.json()["id"] for response in answers.values() if response.status_code == 201}
    assert shape_ids(first) == created
