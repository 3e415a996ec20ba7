"""The session records on disk: ``<data>/sessions/<id>.json``, one JSON file per session, and beside it
``<id>.jobs``, the ids of the refinement jobs run from it (one a line), so deleting a session finds its results.

Every write replaces the whole file atomically (:func:`curvefm.store.atomic_write`: temporary file, fsync,
rename), so a reader, another process or a restarted API, sees the previous record or the new one, never half
of one. Each write after the first increments the record's ``revision``.

Writers of one record, in any process on any machine sharing the directory, are serialised by the record's
file lock (:meth:`SessionStore.locked`: an exclusive ``flock`` on ``<data>/sessions/.locks/<id>.lock``), held
around read, check and write: every edit starts from the record as the last writer left it, whichever process
that was. (A lock on the record file itself would not do: each write replaces that file by a new one.)

:class:`RecordFiles` is that machinery for any kind of record (collections keep theirs the same way).
"""

from __future__ import annotations

import fcntl
import os
import re
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Generic, TypeVar

from pydantic import BaseModel

from curvefm.cache import LRU
from curvefm.errors import Conflict, InvalidInput, NotFound, Unavailable, shown
from curvefm.session.record import SessionRecord
from curvefm.store import atomic_write

DEFAULT_LOCK_TIMEOUT_S = 30.0
PARSED_RECORDS = 64
"""Records kept parsed with the bytes they came from (a parse is most of a read; an edit reads its record 2-3 times)."""
R = TypeVar("R", bound=BaseModel)
_RECORD_ID = re.compile(r"^[A-Za-z0-9_-]{1,64}$")


class _Revision(BaseModel):
    revision: int = 0  # as SessionRecord's


class UnknownSession(NotFound):
    """No session has this id (or the id cannot name one)."""

    def __init__(self, session_id: str):
        self.session_id = session_id
        super().__init__(f"no session with id '{shown(session_id)}'")


class RecordBusy(Unavailable):
    """A record's lock was held by another request (or process) for longer than the configured wait."""

    kind = "record"

    def __init__(self, record_id: str, timeout_s: float):
        super().__init__(
            f"{self.kind} {record_id} is busy: another request held it for more than {timeout_s:g} s "
            f"(session_lock_timeout; set CURVEFM_SESSION_LOCK_TIMEOUT to change it); try again"
        )


class SessionBusy(RecordBusy):
    kind = "session"


class RecordFiles(Generic[R]):
    """Records of one kind, one JSON file each under ``<data>/<folder>/``: read, created, written atomically with
    the next revision, and locked across processes (see the module doc). A subclass names its folder, record
    model and errors (``unknown``: no such record; ``busy``: its lock was held too long).

    ``lock_timeout_s``: how long a request waits for a record another request (or process) holds before the
    busy error; a stuck holder then costs each waiter that long, not a thread forever."""

    kind: str
    """What a record is, for messages ("session")."""
    folder_name: str
    model: type[R]
    unknown: type[NotFound]
    """Raised with the record's id when there is no such record."""
    busy: type[RecordBusy]

    def __init__(self, data_dir: str | Path, lock_timeout_s: float = DEFAULT_LOCK_TIMEOUT_S):
        self.folder = Path(data_dir) / self.folder_name
        self.lock_timeout_s = lock_timeout_s
        self._parsed: LRU[tuple[bytes, R]] = LRU(PARSED_RECORDS)

    def exists(self, record_id: str) -> bool:
        return well_formed(record_id) and self._path(record_id).is_file()

    def read(self, record_id: str) -> R:
        """The stored record, always read from disk; parsed again only when its bytes changed since the last read."""
        data = self._bytes(record_id)
        parsed = self._parsed.peek(record_id)
        if parsed is not None and parsed[0] == data:
            return parsed[1]
        record = self.model.model_validate_json(data)
        self._parsed.put(record_id, (data, record))
        return record

    def list(self) -> list[R]:
        """All records, the most recently changed first."""
        records = [self.model.model_validate_json(p.read_bytes()) for p in self.folder.glob("*.json")]
        return sorted(records, key=lambda r: r.updated_at, reverse=True)

    def create(self, record: R) -> None:
        """Write a new record as it is; an id in use is a conflict."""
        if not well_formed(record.id):
            raise InvalidInput(f"a {self.kind} id is 1-64 letters, digits, '-' or '_', got '{record.id}'")
        with self.locked(record.id, new=True):
            if self._path(record.id).exists():
                raise Conflict(f"{self.kind} '{record.id}' already exists")
            self._write(record)

    @contextmanager
    def locked(self, record_id: str, new: bool = False) -> Iterator[None]:
        """Hold the record's file lock, waiting for any other holder in this or another process. Only a ``new``
        record's lock may be taken before it exists (so a request naming no record creates no file)."""
        if not (self.exists(record_id) or (new and well_formed(record_id))):
            raise self.unknown(record_id)
        folder = self.folder / ".locks"
        folder.mkdir(parents=True, exist_ok=True)
        descriptor = os.open(folder / f"{record_id}.lock", os.O_RDWR | os.O_CREAT, 0o600)
        try:
            self._flock(descriptor, record_id)
            yield
        finally:
            os.close(descriptor)  # releases the lock

    def _flock(self, descriptor: int, record_id: str) -> None:
        """An exclusive flock, polled (flock itself cannot time out) with waits growing from 1 to 50 ms."""
        deadline, pause = time.monotonic() + self.lock_timeout_s, 0.001
        while True:
            try:
                fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
                return
            except BlockingIOError:
                if time.monotonic() >= deadline:
                    raise self.busy(record_id, self.lock_timeout_s) from None
                time.sleep(pause)
                pause = min(2 * pause, 0.05)

    def remove(self, record_id: str) -> None:
        if not self.exists(record_id):
            raise self.unknown(record_id)
        self._path(record_id).unlink()
        self._parsed.pop(record_id)

    def write(self, record: R) -> R:
        """Replace the stored record by ``record`` with the next revision and the current time; returns what
        was written."""
        written = record.model_copy(update={"revision": record.revision + 1, "updated_at": time.time()})
        self._write(written)
        return written

    def _bytes(self, record_id: str) -> bytes:
        if not self.exists(record_id):
            raise self.unknown(record_id)
        return self._path(record_id).read_bytes()

    def _write(self, record: R) -> None:
        atomic_write(self._path(record.id), record.model_dump_json(indent=1).encode())

    def _path(self, record_id: str) -> Path:
        return self.folder / f"{record_id}.json"


class SessionStore(RecordFiles[SessionRecord]):
    """Session records under ``<data>/sessions/``, with the ids of the refinement jobs run from each."""

    kind, folder_name, model = "session", "sessions", SessionRecord
    unknown, busy = UnknownSession, SessionBusy

    def read_changed(self, session_id: str, revision: int) -> SessionRecord | None:
        """The stored record if its revision is not ``revision``, else ``None``: then only the revision is parsed
        (0.2 ms instead of 0.8 for a record of 45 curves)."""
        data = self._bytes(session_id)
        if _Revision.model_validate_json(data).revision == revision:
            return None
        return SessionRecord.model_validate_json(data)

    def delete(self, session_id: str) -> list[str]:
        """Remove the record; returns the ids of the refinement jobs run from it (their results are the
        caller's to delete)."""
        jobs = self.jobs(session_id)
        self.remove(session_id)
        self._jobs_path(session_id).unlink(missing_ok=True)
        return jobs

    def add_job(self, session_id: str, job_id: str) -> None:
        """Note a refinement job run from the session (one appended line: writers never interleave)."""
        fd = os.open(self._jobs_path(session_id), os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            os.write(fd, f"{job_id}\n".encode())
        finally:
            os.close(fd)

    def jobs(self, session_id: str) -> list[str]:
        try:
            return self._jobs_path(session_id).read_text().split()
        except FileNotFoundError:
            return []

    def _jobs_path(self, session_id: str) -> Path:
        return self.folder / f"{session_id}.jobs"


def well_formed(record_id: str) -> bool:
    """Whether ``record_id`` can name a record (and a file): 1-64 letters, digits, ``-`` or ``_``."""
    return bool(_RECORD_ID.match(record_id))
