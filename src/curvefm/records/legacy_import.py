"""The import of a data directory in the JSON-file layout the records had before the database::

    access/users.json              users and token hashes          -> users
    access/usage/<user>.json       what each quota was charged for -> shapes.charged_to (the rest is counted)
    access/audit.jsonl             the audit log                   -> audit
    meshes/<hash>.npz, .uploaders  stored shapes and uploaders     -> shapes, shape_uploaders
    sessions/<id>.json, <id>.jobs  sessions and their jobs         -> sessions, curves, jobs.session_id
    collections/<id>.json          collections                     -> collections and their children
    jobs/<id>.json                 job records                     -> jobs
    results/<job id>/              result files (stay)             -> jobs.result_bytes

One transaction: all of it or nothing. Nothing is deleted or moved (the files stay as a backup; the blobs stay
where the blob store finds them). Records already in the database (same id) are kept as they are and counted as
``already``, so an import can run again. What cannot be imported is reported, never fatal:

* a damaged file (not valid JSON, or not a valid record) is skipped;
* a name that owns records but is no current user (removed) becomes a removed user: its records keep their
  owner, and a user added later under that name owns none of them;
* a collection member whose session is gone (deleted before this import) is dropped from the collection;
* a job id listed by a session whose job record is gone gets a ``lost`` record when its results still exist
  (so deleting the session finds them), else is dropped (nothing is left of it);
* a member's basis job or a run's job whose record expired: the member shows none, the run keeps its id.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

from pydantic import ValidationError
from sqlalchemy import Connection, insert, select, update
from sqlalchemy.exc import IntegrityError

from curvefm.collection.record import CollectionRecord
from curvefm.errors import CurvefmError
from curvefm.records import models as m
from curvefm.records.collections import Collections
from curvefm.records.common import seconds, well_formed
from curvefm.records.engine import Database
from curvefm.records.jobs import JobRow, Jobs
from curvefm.records.sessions import Sessions
from curvefm.session.record import SessionRecord

AUDIT_BATCH = 2000
JOB_FIELDS = {
    "id",
    "kind",
    "state",
    "progress",
    "message",
    "result",
    "worker",
    "created_at",
    "started_at",
    "ended_at",
    "owner",
}


@dataclass
class ImportReport:
    counts: dict[str, int] = field(default_factory=dict)
    already: dict[str, int] = field(default_factory=dict)
    skipped: list[tuple[str, str]] = field(default_factory=list)
    """(file, why) for each record that could not be imported."""
    notes: list[str] = field(default_factory=list)

    def count(self, what: str, n: int = 1) -> None:
        self.counts[what] = self.counts.get(what, 0) + n

    def lines(self) -> list[str]:
        out = [f"imported {n} {what}" for what, n in sorted(self.counts.items())]
        out += [f"already in the database: {n} {what}" for what, n in sorted(self.already.items())]
        out += [f"skipped {path}: {why}" for path, why in self.skipped]
        return out + self.notes


def has_legacy_records(data_dir: str | os.PathLike[str]) -> bool:
    root = Path(data_dir)
    return (root / "access" / "users.json").is_file() or any(
        any((root / folder).glob("*.json")) for folder in ("sessions", "collections", "jobs")
    )


def import_if_needed(
    database: Database, data_dir: str | os.PathLike[str], mark_fresh: bool = False
) -> ImportReport | None:
    """At a first start on a data directory in the old layout: import it (once; None when there was nothing to
    do). ``mark_fresh`` (the service's start): a first start with nothing to import is noted as an empty import,
    so that files the old layout's names are later given (collections' records, still files) are never imported."""
    with database.read() as conn:
        done = conn.execute(select(m.LegacyImport.id).limit(1)).first() is not None
    if done:
        return None
    if not has_legacy_records(data_dir):
        if mark_fresh:
            with database.write() as conn:
                source = str(Path(data_dir).absolute())
                conn.execute(insert(m.LegacyImport).values(source=source, imported_at=time.time(), counts={}))
        return None
    return import_directory(database, data_dir)


def import_directory(database: Database, data_dir: str | os.PathLike[str]) -> ImportReport:
    root = Path(data_dir)
    report = ImportReport()
    with database.write() as conn:
        run = _Import(database, conn, root, report)
        run.users()
        run.shapes()
        run.jobs()
        run.sessions()
        run.collections()
        run.usage()
        run.audit()
        conn.execute(
            insert(m.LegacyImport).values(source=str(root.absolute()), imported_at=time.time(), counts=report.counts)
        )
    return report


class _Import:
    def __init__(self, database: Database, conn: Connection, root: Path, report: ImportReport):
        self.db, self.conn, self.root, self.report = database, conn, root, report
        self.sessions_repo = Sessions(database, max_curves=10**9, max_curve_bytes=2**62, max_session_bytes=2**62)
        self.user_ids: dict[str, int] = {
            row.name: row.id for row in conn.execute(select(m.User.id, m.User.name).where(m.User.removed_at.is_(None)))
        }
        self.job_ids: set[str] = set(conn.execute(select(m.Job.id)).scalars())
        self.shape_ids: set[str] = set(conn.execute(select(m.Shape.hash)).scalars())

    def saved(self, path: Path, store: Callable[[], object]) -> bool:
        """Run ``store`` in a savepoint: a record the database refuses is skipped and reported, the rest of the
        import goes on (on PostgreSQL a refused statement would otherwise abort the whole transaction)."""
        try:
            with self.conn.begin_nested():
                store()
        except (CurvefmError, IntegrityError) as exc:
            reason = exc.message if isinstance(exc, CurvefmError) else " ".join(str(exc.orig).split())[:200]
            self.report.skipped.append((str(path), f"refused: {reason}"))
            return False
        return True

    # -- owners ---------------------------------------------------------------------------------------------
    def owner(self, name: str | None) -> int | None:
        """The id of ``name``: a user of the users file, or a removed user made now for a name owning records."""
        if not name:
            return None
        if name not in self.user_ids:
            moment = time.time()
            self.user_ids[name] = self.conn.execute(
                insert(m.User)
                .values(
                    name=name[:64],
                    admin=False,
                    token_sha256=None,
                    created_at=moment,
                    token_rotated_at=moment,
                    removed_at=moment,
                )
                .returning(m.User.id)
            ).scalar_one()
            self.report.count("removed users (names owning records)")
        return self.user_ids[name]

    # -- each kind ------------------------------------------------------------------------------------------
    def users(self) -> None:
        path = self.root / "access" / "users.json"
        if not path.is_file():
            return
        try:
            document = json.loads(path.read_bytes())
            users = list(document["users"])
        except (ValueError, KeyError, TypeError) as exc:
            self.report.skipped.append((str(path), f"not a users file ({type(exc).__name__})"))
            return
        for user in users:
            if user["name"] in self.user_ids:
                self.report.already["users"] = self.report.already.get("users", 0) + 1
                continue
            self.user_ids[user["name"]] = self.conn.execute(
                insert(m.User)
                .values(
                    name=user["name"],
                    admin=bool(user.get("admin")),
                    token_sha256=user["token_sha256"],
                    created_at=seconds(user["created_at"]),
                    token_rotated_at=seconds(user.get("token_rotated_at") or user["created_at"]),
                )
                .returning(m.User.id)
            ).scalar_one()
            self.report.count("users")

    def shape(self, shape: str, size: int | None = None) -> None:
        if shape in self.shape_ids:
            return
        blob = self.root / "meshes" / f"{shape}.npz"
        if size is None:
            size = blob.stat().st_size if blob.is_file() else 0
            if not blob.is_file():
                self.report.notes.append(f"shape {shape} is used but its mesh file is missing")
        created = blob.stat().st_mtime if blob.is_file() else time.time()
        self.conn.execute(insert(m.Shape).values(hash=shape, bytes=size, charged_to=None, created_at=created))
        self.shape_ids.add(shape)
        self.report.count("shapes")

    def shapes(self) -> None:
        for blob in sorted((self.root / "meshes").glob("*.npz")):
            shape = blob.stem
            self.shape(shape, blob.stat().st_size)
            uploaders = blob.with_suffix(".uploaders")
            if not uploaders.is_file():
                continue
            known = set(
                self.conn.execute(select(m.ShapeUploader.user_id).where(m.ShapeUploader.shape == shape)).scalars()
            )
            for seq, name in enumerate(dict.fromkeys(uploaders.read_text().split())):
                user_id = self.owner(name)
                if user_id in known:
                    continue
                self.conn.execute(
                    insert(m.ShapeUploader).values(
                        shape=shape, user_id=user_id, uploaded_at=uploaders.stat().st_mtime, seq=seq
                    )
                )
                self.conn.execute(
                    update(m.Shape)
                    .where(m.Shape.hash == shape, m.Shape.charged_to.is_(None))
                    .values(charged_to=user_id)
                )
                self.report.count("shape uploaders")

    def jobs(self) -> None:
        repo = Jobs(self.db)
        for path in sorted((self.root / "jobs").glob("*.json")):
            if path.stem in self.job_ids:
                self.report.already["jobs"] = self.report.already.get("jobs", 0) + 1
                continue
            try:
                document = json.loads(path.read_bytes())
                info = {k: v for k, v in document["info"].items() if k in JOB_FIELDS}
                error = document["info"].get("error")
                job = JobRow(
                    **info,
                    error=(error["kind"], error["message"]) if error else None,
                    kwargs=document["kwargs"],
                    dedupe_key=document.get("dedupe_key"),
                    runner=document.get("runner"),
                    result_bytes=self.result_bytes(info["id"]),
                )
            except (ValueError, KeyError, TypeError) as exc:
                self.report.skipped.append((str(path), f"not a job record ({type(exc).__name__})"))
                continue
            if not self.saved(path, partial(repo.create, job, self.conn, owner=self.owner)):
                continue
            self.job_ids.add(job.id)
            self.report.count("jobs")

    def result_bytes(self, job_id: str) -> int:
        folder = self.root / "results" / job_id
        if not well_formed(job_id) or not folder.is_dir():
            return 0
        return sum(p.stat().st_size for p in folder.iterdir() if p.is_file())

    def sessions(self) -> None:
        existing = set(self.conn.execute(select(m.Session.id)).scalars())
        for path in sorted((self.root / "sessions").glob("*.json")):
            try:
                record = SessionRecord.model_validate_json(path.read_bytes())
            except (ValidationError, ValueError) as exc:
                self.report.skipped.append((str(path), f"not a session record ({type(exc).__name__})"))
                continue
            if record.id in existing:
                self.report.already["sessions"] = self.report.already.get("sessions", 0) + 1
                continue
            self.shape(record.source)
            self.shape(record.target)
            if not self.saved(path, partial(self.sessions_repo.create, record, self.conn, owner=self.owner)):
                continue
            self.report.count("sessions")
            self.report.count("curves", len(record.curves))
            self.session_jobs(record)

    def session_jobs(self, record: SessionRecord) -> None:
        listed = self.root / "sessions" / f"{record.id}.jobs"
        if not listed.is_file():
            return
        for job_id in dict.fromkeys(listed.read_text().split()):
            if job_id not in self.job_ids:
                if not (well_formed(job_id) and (self.root / "results" / job_id).is_dir()):
                    continue  # expired with its results: nothing is left to find
                lost = JobRow(
                    id=job_id,
                    kind="refine",
                    state="lost",
                    message="imported: the job's record was gone, its results were not",
                    ended_at=time.time(),
                    owner=record.owner or None,
                    result_bytes=self.result_bytes(job_id),
                )
                Jobs(self.db).create(lost, self.conn, owner=self.owner)
                self.job_ids.add(job_id)
                self.report.count("jobs (results without a record)")
            self.conn.execute(update(m.Job).where(m.Job.id == job_id).values(session_id=record.id))
            self.report.count("session jobs")

    def collections(self) -> None:
        repo = Collections(self.db, self.sessions_repo)
        existing = set(self.conn.execute(select(m.Collection.id)).scalars())
        sessions = set(self.conn.execute(select(m.Session.id)).scalars())
        for path in sorted((self.root / "collections").glob("*.json")):
            try:
                record = CollectionRecord.model_validate_json(path.read_bytes())
            except (ValidationError, ValueError) as exc:
                self.report.skipped.append((str(path), f"not a collection record ({type(exc).__name__})"))
                continue
            if record.id in existing:
                self.report.already["collections"] = self.report.already.get("collections", 0) + 1
                continue
            kept = [member for member in record.members if member.session in sessions]
            for member in record.members:
                if member.session not in sessions:
                    self.report.notes.append(
                        f"collection {record.id}: member {member.id} dropped, its session {member.session} is gone"
                    )
            for shape in [record.template, *(member.shape for member in kept)]:
                self.shape(shape)
            kept_record = record.model_copy(update={"members": kept})
            if not self.saved(path, partial(repo.create, kept_record, self.conn, owner=self.owner)):
                continue
            self.report.count("collections")
            self.report.count("collection members", len(kept))
            self.report.count("collection runs", len(record.runs))

    def usage(self) -> None:
        for path in sorted((self.root / "access" / "usage").glob("*.json")):
            try:
                ids = json.loads(path.read_bytes())
                shapes = [str(shape) for shape in ids.get("shapes", [])]
            except (ValueError, AttributeError, TypeError) as exc:
                self.report.skipped.append((str(path), f"not a usage file ({type(exc).__name__})"))
                continue
            user_id = self.owner(path.stem)
            for shape in shapes:
                if shape in self.shape_ids:
                    self.conn.execute(update(m.Shape).where(m.Shape.hash == shape).values(charged_to=user_id))
            self.report.count("usage ledgers")

    def audit(self) -> None:
        path = self.root / "access" / "audit.jsonl"
        if not path.is_file():
            return
        if self.conn.execute(select(m.AuditEvent.id).limit(1)).first() is not None:
            self.report.notes.append("the audit log was not imported: the database has events already")
            return
        rows: list[dict[str, Any]] = []
        with open(path, "rb") as lines:
            for number, line in enumerate(lines, 1):
                try:
                    event = json.loads(line)
                    user = str(event["user"])
                    rows.append(
                        {
                            "time": seconds(event["time"]),
                            "actor": user[:64],
                            "user_id": self.user_ids.get(user),  # a removed user's events stay linked to it
                            "action": str(event["action"])[:64],
                            "target": str(event["target"])[:200],
                            "detail": event.get("detail") or {},
                        }
                    )
                except (ValueError, KeyError, TypeError, AttributeError, CurvefmError):
                    self.report.skipped.append((f"{path}:{number}", "not a whole audit event (a write cut short)"))
                    continue
                if len(rows) == AUDIT_BATCH:
                    self.conn.execute(insert(m.AuditEvent), rows)
                    self.report.count("audit events", len(rows))
                    rows = []
        if rows:
            self.conn.execute(insert(m.AuditEvent), rows)
            self.report.count("audit events", len(rows))
