"""Users and their bearer tokens, in ``<data>/access/users.json``.

The file (written whole, atomically, under an exclusive lock on ``<data>/access/.lock``)::

    {"version": 1, "users": [{"name": "alice", "admin": false, "token_sha256": "<64 hex>",
                              "created_at": "2026-01-02T03:04:05.678Z", "token_rotated_at": "..."}]}

Tokens are ``cfm_`` + ``secrets.token_urlsafe(32)`` (256 random bits): no salt or slow hash is needed for a
secret that cannot be guessed, and a plain SHA-256 lets :meth:`UserStore.authenticate` find the user by hash.
"""

from __future__ import annotations

import hashlib
import hmac
import json
import os
import re
import secrets
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

from curvefm.access.common import access_dir, locked, timestamp
from curvefm.errors import Conflict, InternalError, InvalidInput, NotFound
from curvefm.store import atomic_write

TOKEN_PREFIX = "cfm_"
NAME_PATTERN = re.compile(r"[A-Za-z0-9_.-]{1,64}")
FORMAT_VERSION = 1
# Longer than any token we make: anything longer is refused before hashing.
MAX_TOKEN_LENGTH = 128
_TOKEN = re.compile(re.escape(TOKEN_PREFIX) + r"[A-Za-z0-9_-]{20,}")
T = TypeVar("T")


@dataclass(frozen=True)
class User:
    name: str
    admin: bool
    created_at: str


@dataclass(frozen=True)
class _Snapshot:
    """The users file as last read, keyed by what ``stat`` says of it (None: there was no file)."""

    key: tuple[int, int, int] | None
    records: tuple[dict, ...]
    by_hash: dict[str, dict]
    by_name: dict[str, dict]


_EMPTY = _Snapshot(key=None, records=(), by_hash={}, by_name={})


class UserStore:
    """Users of one data directory. Safe to share between threads and between processes."""

    def __init__(self, data_dir: str | os.PathLike | None = None):
        folder = access_dir(data_dir)
        self.path = folder / "users.json"
        self._lock_path = folder / ".lock"
        self._snapshot = _EMPTY

    # -- reading --------------------------------------------------------------------------------------------
    def authenticate(self, token: str) -> User | None:
        """The user holding ``token``, or None for a wrong, rotated or removed one.

        Costs a ``stat`` and a hash: the file is parsed again only when another process changed it."""
        if not isinstance(token, str) or not token.startswith(TOKEN_PREFIX) or len(token) > MAX_TOKEN_LENGTH:
            return None
        digest = _hash(token)
        record = self._current().by_hash.get(digest)
        if record is None or not hmac.compare_digest(record["token_sha256"], digest):
            return None
        return _user(record)

    def get(self, name: str) -> User | None:
        record = self._record(name)
        return None if record is None else _user(record)

    def token_binding(self, name: str) -> str | None:
        """A digest of ``name``'s current token (None: no such user). A credential derived from the token (a
        login cookie) carries it, so rotating the token or removing the user ends it; the stored hash itself
        never leaves this module."""
        record = self._record(name)
        if record is None:
            return None
        return hashlib.sha256(("binding:" + record["token_sha256"]).encode()).hexdigest()[:32]

    def is_empty(self) -> bool:
        return not self._current().records

    def list(self) -> list[User]:
        """Every user, by name; token hashes stay inside."""
        return sorted((_user(r) for r in self._current().records), key=lambda user: user.name)

    def _record(self, name: str) -> dict | None:
        return self._current().by_name.get(name)

    def _current(self) -> _Snapshot:
        try:
            stat = os.stat(self.path)
        except FileNotFoundError:
            return _EMPTY
        snapshot = self._snapshot
        if snapshot.key != _stat_key(stat):
            snapshot = self._snapshot = _read(self.path)
        return snapshot

    # -- changing -------------------------------------------------------------------------------------------
    def add(self, name: str, admin: bool = False) -> str:
        """Create a user; returns its token, which is not stored and cannot be shown again."""
        _check_name(name)
        token = _new_token()

        def change(records: list[dict]) -> None:
            if _find(records, name) is not None:
                raise Conflict(f"user '{name}' already exists")
            records.append(_record(name, admin, token))

        self._update(change)
        return token

    def remove(self, name: str) -> None:
        def change(records: list[dict]) -> None:
            records.remove(_existing(records, name))

        self._update(change)

    def rotate(self, name: str) -> str:
        """A new token for ``name``; the old one stops working at once."""
        token = _new_token()

        def change(records: list[dict]) -> None:
            record = _existing(records, name)
            record.update(token_sha256=_hash(token), token_rotated_at=timestamp())

        self._update(change)
        return token

    def ensure_local_admin(self, name: str = "admin") -> str | None:
        """When there is no user at all, create admin ``name`` and return its token; otherwise None.

        For ``curvefm serve`` on a laptop: the check and the creation hold the lock together, so two servers
        starting at once make one admin."""
        _check_name(name)
        token = _new_token()

        def change(records: list[dict]) -> str | None:
            if records:
                return None
            records.append(_record(name, True, token))
            return token

        return self._update(change)

    def _update(self, change: Callable[[list[dict]], T]) -> T:
        """Under the lock: read the records, let ``change`` edit them in place, write them back if it did."""
        with locked(self._lock_path):
            before = list(_read(self.path).records) if self.path.exists() else []
            records = [dict(r) for r in before]
            result = change(records)
            if records != before:
                data = json.dumps({"version": FORMAT_VERSION, "users": records}, indent=1) + "\n"
                atomic_write(self.path, data.encode())
            return result


def _read(path: Path) -> _Snapshot:
    """Parse the file; the key comes from the descriptor that was read, so it always matches the content."""
    with open(path, "rb") as f:
        key = _stat_key(os.fstat(f.fileno()))
        try:
            document = json.loads(f.read())
        except json.JSONDecodeError:  # fail closed: nobody is let in through a broken file
            raise InternalError("the users file is not valid JSON; restore it or re-add the users") from None
    if document.get("version") != FORMAT_VERSION:
        raise InternalError(f"users file format {document.get('version')!r} is not {FORMAT_VERSION}; upgrade curvefm")
    records = tuple(document["users"])
    by_hash, by_name = {r["token_sha256"]: r for r in records}, {r["name"]: r for r in records}
    return _Snapshot(key=key, records=records, by_hash=by_hash, by_name=by_name)


def _stat_key(stat: os.stat_result) -> tuple[int, int, int]:
    # Every write renames a new file into place, so the inode changes even when size and mtime would not.
    return stat.st_mtime_ns, stat.st_size, stat.st_ino


def _check_name(name: str) -> None:
    if not isinstance(name, str) or not NAME_PATTERN.fullmatch(name) or set(name) == {"."}:
        raise InvalidInput(f"bad user name {name!r}: use 1 to 64 letters, digits, '_', '.' or '-'")


def _find(records: list[dict], name: str) -> dict | None:
    return next((r for r in records if r["name"] == name), None)


def _existing(records: list[dict], name: str) -> dict:
    record = _find(records, name)
    if record is None:
        raise NotFound(f"no user '{name}'; 'curvefm users list' shows them")
    return record


def _record(name: str, admin: bool, token: str) -> dict:
    now = timestamp()
    return {"name": name, "admin": bool(admin), "token_sha256": _hash(token), "created_at": now,
            "token_rotated_at": now}


def redact_tokens(text: str) -> str:
    """``text`` with every token in it replaced by ``cfm_[redacted]``."""
    return _TOKEN.sub(TOKEN_PREFIX + "[redacted]", text)


def _new_token() -> str:
    return TOKEN_PREFIX + secrets.token_urlsafe(32)


def _hash(token: str) -> str:
    return hashlib.sha256(token.encode()).hexdigest()


def _user(record: dict) -> User:
    return User(name=record["name"], admin=record["admin"], created_at=record["created_at"])
