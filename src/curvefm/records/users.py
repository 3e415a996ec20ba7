"""Users and their bearer tokens on the ``users`` table (:func:`curvefm.access.users_of` opens them).

A user has a stable integer id; what it owns points at the id, never at the name. Removing a user keeps its row
(``removed_at`` set, token hash cleared): its name is free again, and a new user of that name owns nothing of the
old one's. A removed owner reads back as ``"<name> (removed)"``, which no user can be named (names allow no
space), so a check comparing names can never take one for the other.

Tokens are ``cfm_`` + ``secrets.token_urlsafe(32)``; only their SHA-256 is stored (unique, indexed: one lookup
authenticates a request).

A user may also sign in through an OpenID Connect provider (:meth:`Users.sign_in`): its identity there, the pair
(issuer, subject), is a row of ``external_identities`` pointing at the user that its first sign-in made. Such a
user has a token like any other (made with it, shown to nobody): the login cookie is bound to it, and the user
may replace it to get one for scripts.
"""

from __future__ import annotations

import hashlib
import hmac
import re
import secrets
import time
from dataclasses import dataclass
from typing import Any

from sqlalchemy import Connection, Label, Row, Select, bindparam, func, insert, select, update
from sqlalchemy.exc import IntegrityError

from curvefm.errors import Conflict, Forbidden, InvalidInput, NotFound
from curvefm.records import models as m
from curvefm.records.common import iso, now
from curvefm.records.engine import Database

TOKEN_PREFIX = "cfm_"
NAME_PATTERN = re.compile(r"[A-Za-z0-9_.-]{1,64}")
MAX_TOKEN_LENGTH = 128
REMOVED = " (removed)"
"""Appended to a removed user's name where a record shows its owner."""
_TOKEN = re.compile(re.escape(TOKEN_PREFIX) + r"[A-Za-z0-9_-]{20,}")
_NOT_IN_NAMES = re.compile(r"[^A-Za-z0-9_.-]+")
SIGN_IN_TRIES = 5
"""A first sign-in that collides with a concurrent one (same identity, or same wanted name) is tried again."""
MAX_NAME_SUFFIX = 1000
FALLBACK_NAME = "user"


@dataclass(frozen=True)
class User:
    id: int
    name: str
    admin: bool
    created_at: str


class Users:
    """The users of one database. Safe to share between threads; every process sees every change at once."""

    def __init__(self, database: Database):
        self.db = database

    # -- reading --------------------------------------------------------------------------------------------
    def authenticate(self, token: str) -> User | None:
        """The user holding ``token``, or None for a wrong, rotated or removed one."""
        if not isinstance(token, str) or not token.startswith(TOKEN_PREFIX) or len(token) > MAX_TOKEN_LENGTH:
            return None
        digest = token_hash(token)
        with self.db.read() as conn:
            row = conn.execute(_BY_TOKEN, {"digest": digest}).first()
        if row is None or not hmac.compare_digest(row.token_sha256 or "", digest):
            return None
        return _user(row)

    def get(self, name: str, conn: Connection | None = None) -> User | None:
        """The current user of that name (removed users are not found)."""
        query = _select().where(m.User.name == name, m.User.removed_at.is_(None))
        if conn is not None:
            row = conn.execute(query).first()
        else:
            with self.db.read() as fresh:
                row = fresh.execute(query).first()
        return None if row is None else _user(row)

    def by_id(self, user_id: int) -> User | None:
        with self.db.read() as conn:
            row = conn.execute(_select().where(m.User.id == user_id, m.User.removed_at.is_(None))).first()
        return None if row is None else _user(row)

    def require(self, name: str, conn: Connection | None = None) -> User:
        user = self.get(name, conn)
        if user is None:
            raise NotFound(f"no user '{name}'; 'curvefm users list' shows them")
        return user

    def token_binding(self, name: str) -> str | None:
        """A digest of ``name``'s current token and of when their logins last ended (None: no such user), for
        credentials derived from them: a rotation or a logout changes it."""
        with self.db.read() as conn:
            row = conn.execute(
                select(m.User.token_sha256, m.User.logins_ended_at).where(
                    m.User.name == name, m.User.removed_at.is_(None)
                )
            ).first()
        if row is None or row.token_sha256 is None:
            return None
        ended = "" if row.logins_ended_at is None else f":{row.logins_ended_at!r}"  # cookies made before stay good
        return hashlib.sha256(f"binding:{row.token_sha256}{ended}".encode()).hexdigest()[:32]

    def end_logins(self, name: str) -> None:
        """End every login (web page cookie) of ``name`` made until now; their token stays good."""
        with self.db.write() as conn:
            conn.execute(
                update(m.User)
                .where(m.User.name == name, m.User.removed_at.is_(None))
                .values(logins_ended_at=time.time())
            )

    def is_empty(self) -> bool:
        with self.db.read() as conn:
            return not conn.execute(select(func.count()).where(m.User.removed_at.is_(None))).scalar()

    def list(self) -> list[User]:
        """Every current user, by name."""
        with self.db.read() as conn:
            rows = conn.execute(_select().where(m.User.removed_at.is_(None)).order_by(m.User.name)).all()
        return [_user(r) for r in rows]

    # -- changing -------------------------------------------------------------------------------------------
    def add(self, name: str, admin: bool = False, conn: Connection | None = None) -> str:
        """Create a user; returns its token, which is not stored and cannot be shown again."""
        check_name(name)
        token = new_token()
        try:
            with self.db.joined(conn) as tx:
                if self.get(name, tx) is not None:
                    raise Conflict(f"user '{name}' already exists")
                tx.execute(insert(m.User).values(**_new_user(name, admin, token)))
        except IntegrityError:  # another process added the name between the check and the insert (PostgreSQL)
            raise Conflict(f"user '{name}' already exists") from None
        return token

    def remove(self, name: str) -> None:
        with self.db.write() as conn:
            user = self.require(name, conn)
            conn.execute(update(m.User).where(m.User.id == user.id).values(removed_at=now(), token_sha256=None))

    def set_admin(self, name: str, admin: bool) -> bool:
        """Make ``name`` an admin or take it away (a user made at a single sign-on too); returns whether they were
        one. Takes effect at their next request: every request reads the user afresh."""
        with self.db.write() as conn:
            user = self.require(name, conn)
            conn.execute(update(m.User).where(m.User.id == user.id).values(admin=admin))
        return user.admin

    def rotate(self, name: str) -> str:
        """A new token for ``name``; the old one stops working at once."""
        token = new_token()
        with self.db.write() as conn:
            user = self.require(name, conn)
            conn.execute(
                update(m.User)
                .where(m.User.id == user.id)
                .values(token_sha256=token_hash(token), token_rotated_at=now())
            )
        return token

    def sign_in(self, issuer: str, subject: str, name: str) -> tuple[User, bool]:
        """The user that ``subject`` of the OpenID Connect provider ``issuer`` signs in as, and whether it was made
        now. The identity's first sign-in makes a user (not an admin) named after ``name`` (:func:`usable_name`),
        or ``NAME-2``, ``NAME-3``... when a current user has that name: a sign-in never takes over a user it did
        not make. :class:`Forbidden` when an admin removed the identity's user."""
        for _ in range(SIGN_IN_TRIES):
            try:
                with self.db.write() as conn:
                    return self._sign_in(conn, issuer, subject, usable_name(name))
            except IntegrityError:  # a concurrent first sign-in made this identity, or took the name: look again
                continue
        raise Conflict("signing in collided with other sign-ins repeatedly; try again")

    def _sign_in(self, conn: Connection, issuer: str, subject: str, name: str) -> tuple[User, bool]:
        identity = (m.ExternalIdentity.issuer == issuer, m.ExternalIdentity.subject == subject)
        user_id = conn.execute(select(m.ExternalIdentity.user_id).where(*identity)).scalar()
        moment = now()
        if user_id is not None:
            row = conn.execute(_select().where(m.User.id == user_id, m.User.removed_at.is_(None))).first()
            if row is None:
                raise Forbidden("an admin removed the curvefm user of this sign-in; ask an admin of curvefm")
            conn.execute(update(m.ExternalIdentity).where(*identity).values(last_login_at=moment))
            return _user(row), False
        values = _new_user(self._free_name(conn, name), False, new_token())
        user_id = conn.execute(insert(m.User).values(**values).returning(m.User.id)).scalar_one()
        conn.execute(
            insert(m.ExternalIdentity).values(
                issuer=issuer, subject=subject, user_id=user_id, created_at=moment, last_login_at=moment
            )
        )
        return _user(conn.execute(_select().where(m.User.id == user_id)).one()), True

    def _free_name(self, conn: Connection, name: str) -> str:
        for number in range(1, MAX_NAME_SUFFIX + 1):
            candidate = name if number == 1 else f"{name}-{number}"
            if self.get(candidate, conn) is None:
                return candidate
        raise Conflict(f"the names {name}, {name}-2 ... {name}-{MAX_NAME_SUFFIX} are all taken")

    def ensure_local_admin(self, name: str = "admin") -> str | None:
        """When there is no user at all, create admin ``name`` and return its token; otherwise None (two
        servers starting at once make one admin: the second finds the first's, or loses on the name)."""
        check_name(name)
        token = new_token()
        try:
            with self.db.write() as conn:
                if conn.execute(select(func.count()).where(m.User.removed_at.is_(None))).scalar():
                    return None
                conn.execute(insert(m.User).values(**_new_user(name, True, token)))
        except IntegrityError:
            return None
        return token


def owner_id(conn: Connection, name: str | None) -> int | None:
    """The id of the current user ``name`` (None for no name: a record made before users existed)."""
    if not name:
        return None
    found = conn.execute(select(m.User.id).where(m.User.name == name, m.User.removed_at.is_(None))).scalar()
    if found is None:
        raise NotFound(f"no user '{name}'")
    return found


def owner_name() -> Label[str]:
    """The owner's name as a record shows it: ``""`` for none, marked for a removed user (outer-join ``users``)."""
    from sqlalchemy import case

    return case(
        (m.User.id.is_(None), ""),
        (m.User.removed_at.is_not(None), m.User.name + REMOVED),
        else_=m.User.name,
    ).label("owner")


def check_name(name: str) -> None:
    if not isinstance(name, str) or not NAME_PATTERN.fullmatch(name) or set(name) == {"."}:
        raise InvalidInput(f"bad user name {name!r}: use 1 to 64 letters, digits, '_', '.' or '-'")


def usable_name(text: str) -> str:
    """A user name made from a provider's claim (``preferred_username``, an e-mail address): each run of other
    characters becomes ``-``, cut to leave room for a ``-N`` suffix; ``user`` when nothing usable is left."""
    name = _NOT_IN_NAMES.sub("-", text)[: 64 - len(f"-{MAX_NAME_SUFFIX}")].strip("-")
    return name if name and set(name) != {"."} else FALLBACK_NAME


def redact_tokens(text: str) -> str:
    """``text`` with every token in it replaced by ``cfm_[redacted]``."""
    return _TOKEN.sub(TOKEN_PREFIX + "[redacted]", text)


def new_token() -> str:
    return TOKEN_PREFIX + secrets.token_urlsafe(32)


def token_hash(token: str) -> str:
    return hashlib.sha256(token.encode()).hexdigest()


def _new_user(name: str, admin: bool, token: str) -> dict[str, Any]:
    moment = now()
    return {
        "name": name,
        "admin": bool(admin),
        "token_sha256": token_hash(token),
        "created_at": moment,
        "token_rotated_at": moment,
    }


def _select() -> Select[int, str, bool, float, str | None]:
    return select(m.User.id, m.User.name, m.User.admin, m.User.created_at, m.User.token_sha256)


_BY_TOKEN = _select().where(m.User.token_sha256 == bindparam("digest"))
"""Every request's lookup, built once: SQLAlchemy keys its compiled-statement cache by a traversal of the
statement, which costs a new statement object 3x what the query does (about 200 us of 270)."""


def _user(row: Row[int, str, bool, float, str | None]) -> User:
    return User(id=row.id, name=row.name, admin=row.admin, created_at=iso(row.created_at))
