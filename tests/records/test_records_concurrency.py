"""Concurrent edits of one session from threads and processes (both engines): every acknowledged edit is kept,
none overwrites another (the revision check refuses the loser, which reads again and retries)."""

from __future__ import annotations

import multiprocessing
import threading
from concurrent.futures import ProcessPoolExecutor

from support.records import add_curves, repositories, session_record, shape_id

EDITS = 15


def test_threads_and_processes_keep_every_acknowledged_edit(db, migrated_url):
    repo = repositories(db)
    a, b = shape_id(), shape_id()
    repo["shapes"].add(a, 1)
    repo["shapes"].add(b, 1)
    record = session_record(a, b)
    repo["sessions"].create(record)

    acknowledged: list[str] = []
    lock = threading.Lock()

    def in_thread(prefix: str) -> None:
        done = add_curves(migrated_url, record.id, prefix, EDITS)
        with lock:
            acknowledged.extend(done)

    with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("spawn")) as pool:
        processes = [pool.submit(add_curves, migrated_url, record.id, prefix, EDITS) for prefix in ("p", "q")]
        threads = [threading.Thread(target=in_thread, args=(prefix,)) for prefix in ("t", "u")]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        for future in processes:
            acknowledged.extend(future.result(timeout=240))

    stored = repo["sessions"].read(record.id)
    assert len(acknowledged) == 4 * EDITS
    assert sorted(c.id for c in stored.curves) == sorted(acknowledged)
    assert stored.revision == 4 * EDITS and stored.next_curve == 1 + 4 * EDITS
