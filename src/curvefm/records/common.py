"""What the repositories share: the viewer a list is filtered for, pages, paths as bytes, the clock."""

from __future__ import annotations

import base64
import json
import re
import time
from array import array
from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any, Generic, TypeVar

from sqlalchemy import ColumnElement, Connection, and_, or_, true
from sqlalchemy.orm import QueryableAttribute

from curvefm.errors import InvalidInput

T = TypeVar("T")
MAX_PAGE = 500
MAX_OFFSET = 2**63 - 1
"""The largest offset a page may start at: what the databases' 64-bit integers hold (beyond: 422, not an overflow)."""
DEFAULT_PAGE = 50
_RECORD_ID = re.compile(r"^[A-Za-z0-9_-]{1,64}$")


@dataclass(frozen=True)
class Viewer:
    """Who a list or a read is for: a user's stable id (None: nobody, e.g. the server itself) and whether they
    are an admin (who sees everything)."""

    user_id: int | None
    admin: bool = False


SYSTEM = Viewer(None, admin=True)
"""The server or the command line: sees every record."""


@dataclass(frozen=True)
class Page(Generic[T]):
    """One page of a list: ``total`` records match, ``items`` start at ``offset``; ``next_cursor`` continues
    after the last item (None: this is the last page)."""

    items: list[T]
    total: int
    limit: int
    offset: int = 0
    next_cursor: str | None = None
    extra: dict[str, Any] = field(default_factory=dict)


def visible(
    owner_column: QueryableAttribute[Any], sharing_column: QueryableAttribute[Any], viewer: Viewer
) -> ColumnElement[bool]:
    """The permission as a WHERE clause: an admin sees all, a user their own and what is shared with the lab."""
    if viewer.admin:
        return true()
    shared = sharing_column != "private"
    if viewer.user_id is None:
        return shared
    return or_(owner_column == viewer.user_id, shared)


def check_page(limit: int, offset: int) -> None:
    if not isinstance(limit, int) or not 1 <= limit <= MAX_PAGE:
        raise InvalidInput(f"limit must be 1 to {MAX_PAGE}, got {limit!r}")
    if not isinstance(offset, int) or not 0 <= offset <= MAX_OFFSET:
        raise InvalidInput(f"offset must be 0 to {MAX_OFFSET}, got {offset!r}")


def encode_cursor(updated_at: float, record_id: str) -> str:
    return base64.urlsafe_b64encode(json.dumps([updated_at, record_id]).encode()).decode().rstrip("=")


def after_cursor(
    updated_column: QueryableAttribute[Any], id_column: QueryableAttribute[Any], cursor: str
) -> ColumnElement[bool]:
    """Records after ``cursor`` in the order newest change first (ties by id, descending)."""
    try:
        padded = cursor + "=" * (-len(cursor) % 4)
        updated_at, record_id = json.loads(base64.urlsafe_b64decode(padded))
        updated_at, record_id = float(updated_at), str(record_id)
    except (ValueError, TypeError):
        raise InvalidInput(f"cursor {cursor[:40]!r} is not one a list gave out") from None
    return or_(updated_column < updated_at, and_(updated_column == updated_at, id_column < record_id))


def insert_new(conn: Connection, table: Any, **values: Any) -> bool:
    """``INSERT`` a row unless one with its key exists (``ON CONFLICT DO NOTHING``: two writers adding the same
    row at once both succeed, one inserts); returns whether this one inserted."""
    from sqlalchemy.dialects import postgresql, sqlite

    dialect = conn.dialect.name
    if dialect not in ("postgresql", "sqlite"):  # engine.py refuses other URLs at start; this names it if one slips by
        raise InvalidInput(f"the records' database must be SQLite or PostgreSQL, not {dialect}")
    insert = postgresql.insert if dialect == "postgresql" else sqlite.insert
    key = list(table.__table__.primary_key.columns)[0]
    statement = insert(table).values(**values).on_conflict_do_nothing().returning(key)
    return conn.execute(statement).first() is not None  # (rowcount is -1 here with psycopg)


def path_bytes(path: Sequence[int]) -> bytes:
    """A vertex path as little-endian int32 bytes."""
    values = path if isinstance(path, array) and path.typecode == "i" else array("i", path)
    return values.tobytes()  # x86 and ARM Linux are little-endian


def path_array(data: bytes) -> array[int]:
    values: array[int] = array("i")
    values.frombytes(data)
    return values


def now() -> float:
    return time.time()


def iso(seconds: float) -> str:
    """UTC ISO 8601 with milliseconds and a ``Z`` (the access module's format: fixed width, sorts as a string)."""
    moment = datetime.fromtimestamp(round(seconds, 3), UTC)
    return moment.isoformat(timespec="milliseconds").replace("+00:00", "Z")


def seconds(value: str | float | datetime | None) -> float | None:
    """An ISO 8601 time (naive: UTC), a datetime or seconds, as UNIX seconds."""
    if value is None or isinstance(value, int | float):
        return value
    if isinstance(value, str):
        try:
            value = datetime.fromisoformat(value.replace("Z", "+00:00"))
        except ValueError:
            raise InvalidInput(f"expected an ISO 8601 time, got {value!r}") from None
    if value.tzinfo is None:
        value = value.replace(tzinfo=UTC)
    return value.timestamp()


def well_formed(record_id: str) -> bool:
    """Whether ``record_id`` can name a record: 1-64 letters, digits, ``-`` or ``_``."""
    return isinstance(record_id, str) and bool(_RECORD_ID.match(record_id))
