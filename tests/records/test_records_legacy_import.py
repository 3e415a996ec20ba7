"""The import of a data directory in the old JSON-file layout (both engines): every record arrives."""

from __future__ import annotations

import dataclasses

from support.legacy_layout import write_legacy

from curvefm.records import open_database
from curvefm.records.audit import AuditLog
from curvefm.records.collections import Collections
from curvefm.records.common import Viewer
from curvefm.records.jobs import Jobs
from curvefm.records.legacy_import import import_directory, import_if_needed
from curvefm.records.sessions import Sessions
from curvefm.records.shapes import Shapes
from curvefm.records.usage import Limits, Quotas
from curvefm.records.users import REMOVED, Users

ANY_REASON = "<the database's reason>"


def test_every_record_is_imported(tmp_path, db_url):
    data = tmp_path / "data"
    old = write_legacy(data)
    database = open_database(data, url=db_url)
    report = import_if_needed(database, data)
    assert report is not None
    for path, why in report.skipped:  # the database's own words vary by engine
        if why.startswith("refused: collection 'zz-duplicate'"):
            report.skipped[report.skipped.index((path, why))] = (path, why[: why.index("stored: ") + 8] + ANY_REASON)
    assert report.skipped == [
        (old.damaged, "not a session record (ValidationError)"),
        (old.refused, "refused: collection 'zz-duplicate' cannot be stored: " + ANY_REASON),
        (f"{data}/access/audit.jsonl:4", "not a whole audit event (a write cut short)"),
    ]

    users = Users(database)
    assert sorted(u.name for u in users.list()) == ["alice", "bob", "root"]
    for name, token in old.tokens.items():  # tokens keep working: the hashes came over
        assert users.authenticate(token).name == name
    assert users.get("root").admin and not users.get("alice").admin

    shapes = Shapes(database)
    assert sorted(shapes.ids()) == sorted(old.shapes)
    for shape, names in old.uploaders.items():
        assert shapes.uploaders(shape) == [n for n in names if n != "dave"]  # dave was removed

    sessions = Sessions(database)
    assert sorted(sessions.ids()) == sorted(old.sessions)
    for session_id, record in old.sessions.items():
        imported = sessions.read(session_id)
        expected = record.model_copy(update={"owner": "dave" + REMOVED}) if record.owner == "dave" else record
        assert imported == expected
    for session_id, job_ids in old.session_jobs.items():
        assert sorted(sessions.jobs(session_id)) == sorted(job_ids)

    jobs = Jobs(database)
    for job_id, stored in old.jobs.items():
        row = jobs.load(job_id)
        info = dataclasses.asdict(stored.info)
        error = info.pop("error")
        assert {k: getattr(row, k) for k in info} == info
        assert row.error == (None if error is None else (error["kind"], error["message"]))
        assert (row.kwargs, row.dedupe_key, row.runner) == (stored.kwargs, stored.dedupe_key, stored.runner)
        assert row.result_bytes == old.result_bytes.get(job_id, 0)
    orphan = next(j for j in old.session_jobs[next(iter(old.session_jobs))] if j not in old.jobs)
    assert jobs.load(orphan).state == "lost" and jobs.load(orphan).result_bytes == 77

    collections = Collections(database, sessions)
    for collection_id, record in old.collections.items():
        assert collections.read(collection_id) == record

    audit = AuditLog(database).read(limit=1000)
    assert audit == old.audit

    quotas = Quotas(database, Limits())
    alice, bob = users.get("alice"), users.get("bob")
    sizes = {shape: (data / "meshes" / f"{shape}.npz").stat().st_size for shape in old.shapes}
    used = quotas.usage(alice.id)
    assert used.shape_bytes == sizes[old.shapes[0]]
    finished = next(j for j, s in old.jobs.items() if s.info.state == "finished")
    # the results left by a job whose record had expired now count too: they are alice's, on disk
    assert used.result_bytes == old.result_bytes[finished] + 77
    assert used.sessions == 3 and used.active_jobs == 1
    assert quotas.usage(bob.id).shape_bytes == sizes[old.shapes[1]] + sizes[old.shapes[2]]

    # a re-added "dave" owns nothing of the removed one's
    users.add("dave")
    assert sessions.page(Viewer(users.get("dave").id), limit=50).total == 1  # bob's session, shared with the lab

    # once only at start; an explicit import again changes nothing
    assert import_if_needed(database, data) is None
    again = import_directory(database, data)
    assert again.counts.get("sessions", 0) == 0 and again.already["sessions"] == len(old.sessions)
    assert sorted(sessions.ids()) == sorted(old.sessions)
    database.dispose()


def test_a_directory_without_records_is_not_imported(tmp_path, db_url):
    database = open_database(tmp_path, url=db_url)
    assert import_if_needed(database, tmp_path) is None
    database.dispose()
