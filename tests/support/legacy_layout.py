"""A data directory in the JSON-file layout, written by the old stores themselves (so the layout is the real
one; the records whose stores are gone, by :class:`LegacyUsers`, :class:`LegacyJobs` and :func:`legacy_audit`, in
the format of curvefm 0.x): users with tokens and a removed owner, shapes with uploaders, sessions with curves and
revisions and jobs, collections with members and runs, job records in every state, results, usage ledgers, the
audit log, and one damaged session file."""

from __future__ import annotations

import contextlib
import hashlib
import json
import secrets
import time
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from support.records import curve, path


class LegacyUsers:
    """``<data>/access/users.json`` as the old ``UserStore`` wrote it (format 1)."""

    def __init__(self, data: Path):
        self.path = data / "access" / "users.json"
        self.path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
        self.records: list[dict] = []

    def add(self, name: str, admin: bool = False) -> str:
        token = "cfm_" + secrets.token_urlsafe(32)
        moment = legacy_time()
        digest = hashlib.sha256(token.encode()).hexdigest()
        self.records.append(
            {"name": name, "admin": admin, "token_sha256": digest, "created_at": moment, "token_rotated_at": moment}
        )
        self._write()
        return token

    def remove(self, name: str) -> None:
        self.records = [r for r in self.records if r["name"] != name]
        self._write()

    def _write(self) -> None:
        self.path.write_text(json.dumps({"version": 1, "users": self.records}, indent=1) + "\n")


class LegacyJobs:
    """``<data>/jobs/<id>.json`` as the old ``JobRecords`` wrote them: the job's info, its arguments, its
    deduplication key and runner."""

    def __init__(self, data: Path):
        self.folder = data / "jobs"
        self.folder.mkdir(parents=True, exist_ok=True)

    def create(self, info, kwargs: dict, dedupe_key: str | None, runner: str | None) -> None:
        self._write({"info": asdict(info), "kwargs": kwargs, "dedupe_key": dedupe_key, "runner": runner})

    def update(self, job_id: str, **changes) -> None:
        document = json.loads((self.folder / f"{job_id}.json").read_text())
        error = changes.pop("error", None)
        document["info"].update(changes, **({"error": asdict(error)} if error is not None else {}))
        self._write(document)

    def load(self, job_id: str):
        from curvefm.workers.interface import JobFailure, JobInfo
        from curvefm.workers.job_rows import StoredJob

        document = json.loads((self.folder / f"{job_id}.json").read_text())
        info = dict(document["info"])
        info["error"] = JobFailure(**info["error"]) if info.get("error") else None
        return StoredJob(JobInfo(**info), document["kwargs"], document["dedupe_key"], document["runner"])

    def lose(self, job_id: str, reason: str) -> None:
        self.update(job_id, state="lost", message=reason, ended_at=time.time())

    def _write(self, document: dict) -> None:
        (self.folder / f"{document['info']['id']}.json").write_text(json.dumps(document, indent=1))


class LegacyRecords:
    """``<folder>/<id>.json`` records as the old file stores wrote them (each write the next revision), and a
    session's ``<id>.jobs`` (the ids of the refinement jobs run from it, one a line)."""

    def __init__(self, folder: Path, model):
        self.folder, self.model = folder, model
        self.folder.mkdir(parents=True, exist_ok=True)

    def create(self, record) -> None:
        self._write(record)

    def read(self, record_id: str):
        return self.model.model_validate_json((self.folder / f"{record_id}.json").read_bytes())

    def write(self, record):
        written = record.model_copy(update={"revision": record.revision + 1, "updated_at": time.time()})
        self._write(written)
        return written

    def locked(self, record_id: str):
        return contextlib.nullcontext()

    def add_job(self, session_id: str, job_id: str) -> None:
        with open(self.folder / f"{session_id}.jobs", "a") as jobs:
            jobs.write(f"{job_id}\n")

    def _write(self, record) -> None:
        (self.folder / f"{record.id}.json").write_text(record.model_dump_json(indent=1))


def legacy_time() -> str:
    return datetime.now(UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def legacy_audit(data: Path, events: list[tuple[str, str, str, dict]]) -> list[dict]:
    """Append ``(user, action, target, detail)`` events to ``<data>/access/audit.jsonl`` as the old ``AuditLog``
    did (one compact JSON line each); returns them as it read them back."""
    written = [
        {"time": legacy_time(), "user": user, "action": action, "target": target, "detail": detail}
        for user, action, target, detail in events
    ]
    with open(data / "access" / "audit.jsonl", "ab") as log:
        for event in written:
            log.write((json.dumps(event, separators=(",", ":")) + "\n").encode())
    return written


@dataclass
class Written:
    """What was written, as the old stores read it back."""

    tokens: dict[str, str] = field(default_factory=dict)
    shapes: list[str] = field(default_factory=list)
    sessions: dict = field(default_factory=dict)
    session_jobs: dict[str, list[str]] = field(default_factory=dict)
    collections: dict = field(default_factory=dict)
    jobs: dict = field(default_factory=dict)
    uploaders: dict[str, list[str]] = field(default_factory=dict)
    usage: dict[str, dict] = field(default_factory=dict)
    audit: list[dict] = field(default_factory=list)
    result_bytes: dict[str, int] = field(default_factory=dict)
    damaged: str = ""
    refused: str = ""


def tetrahedron(scale: float):
    from curvefm.geometry import build_mesh

    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float) * scale
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    return build_mesh(vertices, faces, name=f"tet{scale}")


def write_legacy(data: Path) -> Written:
    from curvefm.collection.record import CollectionRecord, Member, Run, RunMember, TemplateCurve
    from curvefm.session.record import SessionRecord
    from curvefm.store import Store
    from curvefm.workers.interface import JobFailure, JobInfo

    out = Written()
    users, store = LegacyUsers(data), Store(data)
    for name, admin in (("alice", False), ("bob", False), ("root", True), ("dave", False)):
        out.tokens[name] = users.add(name, admin=admin)

    shapes = [store.put_mesh(tetrahedron(1.0 + i)) for i in range(4)]
    out.shapes = shapes
    for shape, names in zip(shapes, (["alice"], ["alice", "bob"], ["bob"], ["dave"]), strict=True):
        for name in names:
            with open(data / "meshes" / f"{shape}.uploaders", "a") as uploaders:  # as curvefm 0.x appended them
                uploaders.write(f"{name}\n")
        out.uploaders[shape] = names

    jobs = LegacyJobs(data)
    now = time.time()

    def job(owner: str | None, state: str, **changes) -> str:
        job_id = secrets.token_hex(8)
        info = JobInfo(id=job_id, kind=changes.pop("kind", "refine"), state="queued", created_at=now, owner=owner)
        jobs.create(info, {"data_dir": str(data), "n": 1}, changes.pop("dedupe_key", None), "rq")
        if state != "queued":
            jobs.update(job_id, state=state, **changes)
        return job_id

    finished = job("alice", "finished", started_at=now, ended_at=now + 1, progress=1.0, result={"session": "x"})
    failed = job("bob", "failed", ended_at=now + 2, error=JobFailure("internal", "it broke"))
    running = job("alice", "started", started_at=now, worker="w1", progress=0.4, message="refining")
    queued = job(None, "queued", dedupe_key="basis:abc", kind="basis")
    lost = job("alice", "queued")
    jobs.lose(lost, "Redis restarted without it")
    for job_id, files in ((finished, 3), (failed, 0)):
        folder = data / "results" / job_id
        folder.mkdir(parents=True)
        for i in range(files):
            (folder / f"part{i}.npz").write_bytes(b"x" * (100 * (i + 1)))
        out.result_bytes[job_id] = sum(100 * (i + 1) for i in range(files))
    orphan = secrets.token_hex(8)  # a job listed by a session whose record expired but whose results remain
    (data / "results" / orphan).mkdir(parents=True)
    (data / "results" / orphan / "map.npz").write_bytes(b"y" * 77)
    out.result_bytes[orphan] = 77

    sessions = LegacyRecords(data / "sessions", SessionRecord)

    def session(owner: str, source: str, target: str, n_curves: int, sharing: str = "private") -> SessionRecord:
        record = SessionRecord(
            id=secrets.token_hex(8),
            name=f"{owner}'s",
            owner=owner,
            sharing=sharing,
            source=source,
            target=target,
            k=20,
            alpha=0.001,
            samples=50,
            energy="curves",
            tracer="geodesic",
            basis_plugin="laplace-beltrami",
            basis_params={"normalized": True},
            curves=[curve(f"c{i}", n=3 + i) for i in range(1, n_curves + 1)],
            next_curve=n_curves + 1,
            created_at=now,
            updated_at=now,
        )
        sessions.create(record)
        for _ in range(2):  # revisions as edits leave them
            with sessions.locked(record.id):
                record = sessions.write(sessions.read(record.id))
        return record

    s_alice = session("alice", shapes[0], shapes[1], 3)
    s_bob = session("bob", shapes[1], shapes[2], 1, sharing="read")
    s_dave = session("dave", shapes[3], shapes[0], 2)  # dave is removed below: the session keeps its owner
    s_old = session("", shapes[0], shapes[2], 0)  # made before users existed
    for job_id in (finished, running, orphan, secrets.token_hex(8)):  # the last: expired with its results
        sessions.add_job(s_alice.id, job_id)
    sessions.add_job(s_bob.id, failed)
    out.session_jobs = {s_alice.id: [finished, running, orphan], s_bob.id: [failed]}

    members = [session("alice", shapes[0], shape, 1) for shape in (shapes[1], shapes[2])]
    collections = LegacyRecords(data / "collections", CollectionRecord)
    collection = CollectionRecord(
        id=secrets.token_hex(8),
        name="teeth",
        owner="alice",
        sharing="read",
        template=shapes[0],
        k=20,
        alpha=0.001,
        samples=50,
        energy="combined",
        tracer="geodesic",
        basis_plugin="laplace-beltrami",
        basis_params={},
        curves=[
            TemplateCurve(id="t1", name="rim", waypoints=[0, 2], path=path(0, 1, 2)),
            TemplateCurve(id="t2", name="", waypoints=[], path=path(3, 1)),
        ],
        members=[
            Member(id="m1", shape=shapes[1], session=members[0].id, basis_job=queued),
            Member(id="m2", shape=shapes[2], session=members[1].id),
        ],
        runs=[
            Run(
                id="r1",
                converter="zoomout",
                params={"k_final": 40},
                created_at=now,
                members={"m1": RunMember(job=finished, revision=2), "m2": RunMember(job=failed, revision=2)},
            )
        ],
        next_member=3,
        next_run=2,
        created_at=now,
        updated_at=now,
    )
    collections.create(collection)
    with collections.locked(collection.id):
        collections.write(collections.read(collection.id))

    users.remove("dave")
    out.tokens.pop("dave")
    kinds = ("shapes", "sessions", "jobs", "results")
    out.usage = {  # the old per-user ledgers, access/usage/<user>.json
        "alice": dict.fromkeys(kinds, [])
        | {
            "shapes": [shapes[0]],
            "sessions": [s_alice.id, *(m.id for m in members)],
            "results": [finished],
        },
        "bob": dict.fromkeys(kinds, []) | {"shapes": [shapes[1], shapes[2]]},  # charged for 1 (first: alice)
    }
    (data / "access" / "usage").mkdir(mode=0o700, exist_ok=True)
    for name, ids in out.usage.items():
        (data / "access" / "usage" / f"{name}.json").write_text(json.dumps(ids))

    out.audit = legacy_audit(
        data,
        [
            ("alice", "session.create", s_alice.id, {"sharing": "private"}),
            ("cli", "user.remove", "dave", {}),
            ("bob", "shape.upload", shapes[2], {"note": "café ✓"}),
        ],
    )
    with open(data / "access" / "audit.jsonl", "ab") as log:
        log.write(b'{"time": "2026-01-01T00:00:00.000Z", "user": "cut sh')  # a write cut short

    damaged = data / "sessions" / "broken.json"
    damaged.write_text('{"id": "broken", "curves": [')
    out.damaged = str(damaged)
    # a collection claiming another's member session: the database refuses it (a session is one member's)
    duplicate = collection.model_copy(update={"id": "zz-duplicate", "runs": [], "members": collection.members[:1]})
    collections.create(duplicate)
    out.refused = str(data / "collections" / "zz-duplicate.json")

    out.sessions = {r.id: sessions.read(r.id) for r in (s_alice, s_bob, s_dave, s_old, *members)}
    out.collections = {collection.id: collections.read(collection.id)}
    out.jobs = {job_id: jobs.load(job_id) for job_id in (finished, failed, running, queued, lost)}
    return out
