"""The audit log in the database (both engines)."""

from __future__ import annotations

from datetime import UTC, datetime

import pytest

from curvefm.errors import InvalidInput
from curvefm.records.audit import AuditLog
from curvefm.records.users import Users


def test_record_read_filter_redact_page(db, tmp_path):
    Users(db).add("alice")
    log = AuditLog(db, data_dir=tmp_path)
    log.record("alice", "session.create", "s1", {"sharing": "private"}, at=1_000.0)
    log.record("cli", "user.add", "bob", {"admin": False}, at=2_000.0)
    log.record("alice", "shape.upload", f"{tmp_path}/meshes/x.npz", {"token": "cfm_" + "A" * 43}, at=3_000.0)
    events = log.read()
    assert [e["action"] for e in events] == ["session.create", "user.add", "shape.upload"]
    assert events[0] == {
        "time": "1970-01-01T00:16:40.000Z",
        "user": "alice",
        "action": "session.create",
        "target": "s1",
        "detail": {"sharing": "private"},
    }
    assert events[2]["target"] == "[data]/meshes/x.npz" and events[2]["detail"]["token"] == "cfm_[redacted]"
    assert [e["target"] for e in log.read(limit=1)] == [events[2]["target"]]
    assert [e["action"] for e in log.read(user="alice")] == ["session.create", "shape.upload"]
    assert [e["action"] for e in log.read(since="1970-01-01T00:33:20Z")] == ["user.add", "shape.upload"]
    assert len(log.read(since=datetime(1970, 1, 1, 0, 33, 21, tzinfo=UTC))) == 1
    page = log.page(limit=2, offset=1)
    assert page.total == 3 and [e["action"] for e in page.items] == ["user.add", "session.create"]
    with pytest.raises(InvalidInput):
        log.read(limit=0)
    with pytest.raises(InvalidInput):
        log.read(since="yesterday")
