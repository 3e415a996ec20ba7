"""Expiry: a thread of the API deletes what an ended job leaves once it ended ``CURVEFM_JOB_TTL`` ago, its record
in the database and its result folder (``<data>/results/<job id>/``), and the partial files of writes that a
killed process left behind.

The queue forgets the job by then too (RQ's result TTL in Redis; the in-process queue's memory), so
``GET /jobs/{id}`` answers 404 and the files are gone together. A result folder whose record is gone already
is deleted by its age, its modification time, set when the job published it. A staging folder
(``.<job id>.*``, left by a worker killed while writing) is deleted only once it is also older than
:data:`STAGING_GRACE_S`, so a tiny TTL never deletes files a running job is writing; so is a partial file
(``.<name>.<random>.tmp``, which :func:`curvefm.store.atomic_write` renames into place when it is complete).
"""

from __future__ import annotations

import logging
import shutil
import threading
import time
from pathlib import Path

from curvefm.workers.interface import JobQueue

log = logging.getLogger("curvefm.service")

STAGING_GRACE_S = 6 * 3600


def remove_expired_results(results: Path, ttl_s: float, now: float | None = None) -> list[str]:
    """Delete result folders older than ``ttl_s``; returns the names of those deleted."""
    now = time.time() if now is None else now
    removed = []
    for folder in sorted(results.iterdir()) if results.is_dir() else []:
        age_limit = max(ttl_s, STAGING_GRACE_S) if folder.name.startswith(".") else ttl_s
        try:
            expired = folder.is_dir() and now - folder.stat().st_mtime > age_limit
        except FileNotFoundError:  # removed meanwhile (another API process)
            continue
        if expired:
            shutil.rmtree(folder, ignore_errors=True)
            removed.append(folder.name)
    return removed


def remove_partial_writes(data_dir: Path, now: float | None = None) -> int:
    """Delete the partial files of writes older than :data:`STAGING_GRACE_S`; returns how many."""
    now = time.time() if now is None else now
    removed = 0
    for path in data_dir.rglob(".*.tmp"):
        try:
            if path.is_file() and now - path.stat().st_mtime > STAGING_GRACE_S:
                path.unlink()
                removed += 1
        except FileNotFoundError:  # renamed into place or removed meanwhile
            continue
    return removed


def expire_jobs(queue: JobQueue, results: Path, ttl_s: float) -> list[str]:
    """Delete the records and result folders of jobs that ended more than ``ttl_s`` ago; returns their ids."""
    now = time.time()
    expired = queue.records.expire(now - ttl_s)
    for job_id in expired:
        shutil.rmtree(results / job_id, ignore_errors=True)
    return sorted({*expired, *remove_expired_results(results, ttl_s, now)})


def start_expiry(queue: JobQueue, data_dir: Path, ttl_s: float, interval_s: float) -> threading.Event:
    """Run :func:`expire_jobs` and :func:`remove_partial_writes` every ``interval_s`` in a daemon thread; set the
    event to stop."""
    stop = threading.Event()

    def loop() -> None:
        while True:
            try:
                removed = expire_jobs(queue, data_dir / "results", ttl_s)
                if removed:
                    log.info("expired %d jobs and their results: %s", len(removed), ", ".join(removed))
                partial = remove_partial_writes(data_dir)
                if partial:
                    log.info("deleted %d partial files left by interrupted writes", partial)
            except OSError:  # a full or flaky disk must not end the loop
                log.exception("expiring results failed; trying again in %.0f s", interval_s)
            if stop.wait(interval_s):
                return

    threading.Thread(target=loop, name="curvefm-expiry", daemon=True).start()
    return stop
