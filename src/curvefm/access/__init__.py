"""Access control for a lab-wide service: users with bearer tokens, the audit log, the login-cookie key.

Users and the audit log are records in the data directory's database (:mod:`curvefm.records`), shared by the CLI
and every API process; :func:`users_of` and :func:`audit_of` open them for a data directory (its SQLite file, or
``CURVEFM_DATABASE_URL``):

* :class:`Users`: users with stable ids and their token hashes. Tokens are shown once, when made, and only their
  SHA-256 is stored; :meth:`Users.authenticate` is one indexed lookup.
* :class:`AuditLog`: who did what, in append order.
* :func:`signing_key`: the secret in ``<data>/access/signing.key`` that signs login cookies, made on first use
  (a file: every API process reads it at start).

No HTTP and no Redis here: the service decides how a token arrives and what a user may do.
"""

from __future__ import annotations

import os

from curvefm.access.keys import signing_key
from curvefm.records.audit import AuditLog
from curvefm.records.engine import shared_database
from curvefm.records.users import TOKEN_PREFIX, User, Users, redact_tokens


def users_of(data_dir: str | os.PathLike[str] | None = None, url: str | None = None) -> Users:
    """The users of a data directory's database (``url``, else ``$CURVEFM_DATABASE_URL``, else its SQLite file)."""
    return Users(shared_database(data_dir, url))


def audit_of(data_dir: str | os.PathLike[str] | None = None, url: str | None = None) -> AuditLog:
    """The audit log of a data directory's database; the directory's path is redacted from what it records."""
    return AuditLog(shared_database(data_dir, url), data_dir)


__all__ = [
    "AuditLog",
    "TOKEN_PREFIX",
    "User",
    "Users",
    "audit_of",
    "redact_tokens",
    "signing_key",
    "users_of",
]
