"""Checks of the API's answers to bad requests: an error body of the published schema, and a data directory
left as it was."""

import contextlib
import sqlite3
from pathlib import Path

from curvefm.service.models import ErrorBody

DATABASE = "curvefm.db"


def snapshot(folder: Path, ignored: tuple[str, ...] = ()) -> dict[str, object]:
    """The files of a data directory (size and time) and the rows of its database's tables (``curvefm.db/<table>``),
    less the paths (and tables) starting with one of ``ignored``. The database's own files change when it is only
    read (SQLite's shared-memory index), so its rows are compared instead."""
    paths = (
        p
        for p in folder.rglob("*")
        if not p.name.startswith(DATABASE) and not str(p.relative_to(folder)).startswith(ignored)
    )
    files: dict[str, object] = {str(p.relative_to(folder)): (p.stat().st_size, p.stat().st_mtime_ns) for p in paths}
    if (folder / DATABASE).exists():
        with contextlib.closing(sqlite3.connect(f"file:{folder / DATABASE}?mode=ro", uri=True)) as conn:
            tables = [row[0] for row in conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'")]
            for table in tables:
                key = f"{DATABASE}/{table}"
                if not key.startswith(ignored):
                    files[key] = sorted(map(repr, conn.execute(f'SELECT * FROM "{table}"')))
    return files


def expect(response, status: int, kind: str, *words: str) -> dict:
    """The body of an error answer, once it has ``status``, matches ``ErrorBody``, is of ``kind`` and names every
    one of ``words`` in its detail."""
    assert response.status_code == status, response.text
    body = response.json()
    assert set(body) <= set(ErrorBody.model_fields) and ErrorBody.model_validate(body), body
    assert body["error"] == kind, body
    for word in words:
        assert word in body["detail"], body
    return body
