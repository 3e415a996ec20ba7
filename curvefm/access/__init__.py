"""Access control for a lab-wide service: users with bearer tokens, and an audit log.

Both live under ``<data>/access/`` and are plain files, so the CLI and every API process share them without a
server of their own:

* :class:`UserStore`: users and their token hashes in ``users.json``. Tokens are shown once, when made, and only
  their SHA-256 is stored. Changes are atomic and serialized by a lock file; :meth:`UserStore.authenticate`
  rereads the file only when it changed, so it is cheap enough for every request and sees users added or
  removed by another process at once.
* :class:`AuditLog`: who did what, as append-only JSON lines in ``audit.jsonl``.
* :class:`Usage`: what each user's quotas are charged for, one file per user under ``usage/``.
* :func:`signing_key`: the secret in ``signing.key`` that signs login cookies, made on first use.

No HTTP and no Redis here: the service decides how a token arrives and what a user may do.
"""

from curvefm.access.audit import AuditLog
from curvefm.access.keys import signing_key
from curvefm.access.usage import Usage
from curvefm.access.users import TOKEN_PREFIX, User, UserStore, redact_tokens

__all__ = ["AuditLog", "TOKEN_PREFIX", "Usage", "User", "UserStore", "redact_tokens", "signing_key"]
