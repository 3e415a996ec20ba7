"""``curvefm db``: upgrade, current, import, backup, restore (SQLite in the data directory)."""

from __future__ import annotations

from support.legacy_layout import write_legacy

from curvefm.cli import main
from curvefm.records import open_database
from curvefm.records.sessions import Sessions


def test_db_commands(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("CURVEFM_DATABASE_URL", raising=False)
    data = tmp_path / "data"
    old = write_legacy(data)
    assert main(["db", "current", "--data", str(data)]) == 0
    assert "revision none" in capsys.readouterr().out
    assert main(["db", "upgrade", "--data", str(data)]) == 0
    assert main(["db", "current", "--data", str(data)]) == 0
    assert "up to date" in capsys.readouterr().out
    assert main(["db", "import", str(data)]) == 0
    out = capsys.readouterr().out
    assert f"imported {len(old.sessions)} sessions" in out and "skipped" in out
    backup = tmp_path / "records.db"
    assert main(["db", "backup", "--data", str(data), str(backup)]) == 0
    database = open_database(data)
    sessions = Sessions(database)
    gone = next(iter(old.sessions))
    sessions.delete(gone)
    assert main(["db", "restore", "--data", str(data), str(backup)]) == 0
    assert sessions.exists(gone)
    database.dispose()
    assert main(["db", "backup", "--data", str(data), str(backup)]) == 2  # never over an existing file
