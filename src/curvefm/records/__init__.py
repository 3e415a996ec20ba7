"""Records in a database: users, shapes' ownership, sessions and curves, jobs, collections, quotas, the audit log.

One database per data directory, through SQLAlchemy 2 with Alembic migrations: SQLite (WAL) at
``<data>/curvefm.db`` by default, PostgreSQL when ``CURVEFM_DATABASE_URL=postgresql+psycopg://...`` (the
``postgresql`` extra). Blobs (meshes, bases, display copies, results) stay content-addressed files
(:class:`curvefm.store.Store`); the database holds what points at them. Consistency comes from transactions,
foreign keys and revision checks (:mod:`.engine`), never from lock files.

The record model (:mod:`.models`; ``->`` a foreign key, with what happens when the row it points at is deleted)::

    users             id PK (stable; a name removed and added again is another user), name (unique among
                      current users), admin, token_sha256 (unique), created_at, token_rotated_at, removed_at
                      (a removed user keeps its row: what it owned keeps an owner nobody inherits)
    external_identities (issuer, subject) PK, user_id -> users CASCADE, created_at, last_login_at: who signed in
                      through an OpenID Connect provider (single sign-on) as which user
    shapes            hash PK (the blob meshes/<hash>.npz), bytes, charged_to -> users (RESTRICT; the first
                      uploader, whose byte quota pays), created_at
    shape_uploaders   (shape -> shapes CASCADE, user_id -> users RESTRICT) PK, uploaded_at, seq
    sessions          id PK, name, owner_id -> users (RESTRICT; NULL: made before users), sharing, source and
                      target -> shapes (RESTRICT: a shape in use cannot go), k, alpha, samples, energy, tracer,
                      basis_plugin, basis_params (JSON), next_curve, revision, created_at, updated_at, bytes
                      (what its curves store: the record's size cap, and the owner's byte quota)
    curves            (session_id -> sessions CASCADE, id) PK, position, spec (JSON), tracer, path_source and
                      path_target (int32 little-endian bytes)
    jobs              id PK, kind, state, progress, message, result (JSON), error_kind, error_message, worker,
                      created_at, started_at, ended_at, owner_id -> users (RESTRICT), kwargs (JSON: a retry's
                      arguments), dedupe_key, runner, session_id -> sessions (SET NULL: the session's refinement
                      jobs), result_bytes (the result files' size, for the byte quota)
    collections       id PK, name, owner_id -> users, sharing, template -> shapes (RESTRICT), the solver's
                      parameters as sessions', next_member, next_run, revision, created_at, updated_at
    template_curves   (collection_id -> collections CASCADE, id) PK, position, name, waypoints (JSON), path
    collection_members (collection_id -> collections CASCADE, id) PK, position, shape -> shapes (RESTRICT),
                      session_id -> sessions (CASCADE: deleting the session removes the member; unique),
                      basis_job -> jobs (SET NULL)
    collection_runs   (collection_id -> collections CASCADE, id) PK, converter, params (JSON), created_at
    run_members       (collection_id, run_id -> collection_runs CASCADE, member_id -> collection_members
                      CASCADE) PK, job_id -> jobs (SET NULL: an expired job), job_name (the id as given),
                      revision, carried
    collection_roles  (collection_id -> collections CASCADE, user_id -> users CASCADE) PK, role, granted_by ->
                      users (SET NULL), granted_at: who holds which role in a collection (a project)
    member_assignments (collection_id -> collections CASCADE, member_id) PK, user_id -> users CASCADE,
                      assigned_at: members assigned to annotators (a removed member's row is inert: ids are not
                      reused, reads join collection_members)
    webhooks          id PK, collection_id -> collections CASCADE, url, secret (signs the deliveries, so kept as
                      given out), events (JSON list), created_by -> users (SET NULL), created_at
    webhook_deliveries id PK, webhook_id -> webhooks CASCADE, event, event_key (an occurrence delivered once: a
                      run's end), body (the JSON posted), state (pending, delivered, failed), attempts, created_at,
                      next_attempt_at, lease_until (claimed by an API process), last_attempt_at, last_status,
                      last_error: the outbox of the webhooks and their delivery log (:mod:`.webhooks`)
    member_reviews    (collection_id -> collections CASCADE, member_id) PK, state (submitted, changes_requested,
                      accepted; no row: open), submitted_by / reviewed_by -> users (SET NULL), submitted_at,
                      reviewed_at, comment: where a member stands in review (keyed as member_assignments)
    member_annotations (collection_id -> collections CASCADE, member_id, user_id -> users CASCADE) PK,
                      session_id -> sessions (CASCADE; unique), created_at: further annotations of a member by
                      other annotators (double annotation); the repository deletes their sessions with the member
    review_comments   id PK, collection_id -> collections CASCADE, member_id, side (source: the template;
                      target: the member's shape), vertex (a file id), text, author_id -> users (SET NULL),
                      created_at, reply_to -> review_comments CASCADE (a thread's first comment), resolved_by ->
                      users (SET NULL), resolved_at: review comments pinned to a vertex (keyed as
                      member_assignments)
    audit             id PK (append order), time, actor (a name or "cli"), user_id -> users, action, target,
                      detail (JSON)
    legacy_imports    id PK, source, imported_at, counts (JSON): each import of the old JSON-file layout
    session_viewers   id PK (one per open event stream), session_id -> sessions CASCADE, user_id -> users
                      CASCADE, opened_at, expires_at (pushed on by its API process's heartbeat): who has a session
                      open, across the API processes (presence)

Indexes: every foreign key, ``sessions`` and ``collections`` by ``(updated_at, id)`` (the pages' order),
``jobs`` by state, ended_at and dedupe_key, ``audit`` by time and actor.

Usage and quotas are queries, not a ledger (:mod:`.usage`): bytes = SUM(shapes.bytes charged to the user) +
SUM(jobs.result_bytes of the user's jobs) + SUM(sessions.bytes of the user's sessions), sessions = COUNT(the
user's sessions, member sessions included), concurrent jobs = COUNT(the user's queued or started jobs), counted
in the transaction that admits the new thing.

Modules, one per concept: :mod:`.users`, :mod:`.shapes` (uploaders, and the shape-in-use check),
:mod:`.sessions`, :mod:`.collections`, :mod:`.comments` (review comments), :mod:`.jobs`, :mod:`.usage` (quotas),
:mod:`.audit`, :mod:`.webhooks`; lists are :class:`~.common.Page` s filtered in SQL for a :class:`~.common.Viewer`.
:mod:`.migrate` runs Alembic from code (``curvefm db upgrade``), :mod:`.legacy_import` imports a data directory in
the old layout (``curvefm db import``, and at first start), :mod:`.backup` copies a SQLite database (``curvefm db
backup`` / ``restore``), :mod:`.blobs` is the blob store's interface (files: :class:`~.blobs.FileBlobs`).
"""

from curvefm.records.common import SYSTEM, Page, Viewer
from curvefm.records.engine import Database, database_url, open_database

__all__ = ["SYSTEM", "Database", "Page", "Viewer", "database_url", "open_database"]
