"""Who created, changed, shared or deleted what: append-only JSON lines in ``<data>/access/audit.jsonl``.

One line per event::

    {"time": "2026-01-02T03:04:05.678Z", "user": "alice", "action": "session.share", "target": "a1b2c3",
     "detail": {"sharing": "read"}}

Each event is one ``os.write`` of one whole line on an ``O_APPEND`` descriptor, so lines from several processes
never interleave. Lines are in append order, which is time order up to the processes' clocks.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path

from curvefm.access.common import access_dir, timestamp
from curvefm.access.users import redact_tokens
from curvefm.errors import InvalidInput

# Reading goes backwards from the end in blocks of this many bytes, so a short tail of a long log is cheap.
BLOCK_BYTES = 64 * 1024


class AuditLog:
    def __init__(self, data_dir: str | os.PathLike | None = None):
        self.path = access_dir(data_dir) / "audit.jsonl"
        # Callers pass ids, not paths or secrets; as a guard, tokens and this data directory are redacted.
        root = self.path.parent.parent
        self._paths = sorted({str(root.absolute()), str(root.resolve())}, key=len, reverse=True)

    def record(self, user: str, action: str, target: str, detail: dict | None = None) -> None:
        """Append one event: ``user`` did ``action`` (e.g. ``user.add``) to ``target`` (an id or a name)."""
        event = {"time": timestamp(), "user": user, "action": action, "target": target, "detail": detail or {}}
        line = (self._redact(json.dumps(event, separators=(",", ":"))) + "\n").encode()
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o600)
        try:
            written = os.write(fd, line)
        finally:
            os.close(fd)
        if written != len(line):
            raise OSError(f"audit log: wrote {written} of {len(line)} bytes (disk full?)")

    def read(self, limit: int = 100, since: datetime | str | None = None, user: str | None = None) -> list[dict]:
        """The last ``limit`` events (of ``user``, at or after ``since``), oldest first.

        Reads the file backwards and stops as soon as it has them. A naive ``since`` is taken as UTC."""
        if not isinstance(limit, int) or limit < 1:
            raise InvalidInput(f"limit must be a positive integer, got {limit!r}")
        earliest = _since(since)
        events: list[dict] = []
        for event in _events_backwards(self.path):
            if earliest is not None and event.get("time", "") < earliest:
                break
            if user is None or event.get("user") == user:
                events.append(event)
                if len(events) == limit:
                    break
        return events[::-1]

    def _redact(self, text: str) -> str:
        text = redact_tokens(text)
        for path in self._paths:
            text = text.replace(json.dumps(path)[1:-1], "[data]")
        return text


def _since(since: datetime | str | None) -> str | None:
    """``since`` as a timestamp string of the log's own format, which compares as a string."""
    if since is None:
        return None
    if isinstance(since, str):
        try:
            since = datetime.fromisoformat(since)
        except ValueError:
            raise InvalidInput(f"since must be an ISO 8601 time, got {since!r}") from None
    if since.tzinfo is None:
        since = since.replace(tzinfo=UTC)
    return timestamp(since)


def _events_backwards(path: Path) -> Iterator[dict]:
    """The log's events, last first; a line that is not a whole JSON object (a write cut short) is skipped."""
    for line in _lines_backwards(path):
        try:
            event = json.loads(line)
        except ValueError:
            continue
        if isinstance(event, dict):
            yield event


def _lines_backwards(path: Path) -> Iterator[bytes]:
    try:
        f = open(path, "rb")
    except FileNotFoundError:
        return
    with f:
        end = f.seek(0, os.SEEK_END)
        head = b""  # the start of a line whose beginning lies in a block not yet read
        while end > 0:
            start = max(0, end - BLOCK_BYTES)
            f.seek(start)
            lines = (f.read(end - start) + head).split(b"\n")
            head = lines.pop(0)
            end = start
            yield from (line for line in reversed(lines) if line)
        if head:
            yield head
