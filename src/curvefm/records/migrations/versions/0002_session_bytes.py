"""Sessions keep what their curves store (``sessions.bytes``), for the record's size cap and the byte quota.

Existing sessions are measured as :func:`curvefm.records.sessions.stored_bytes` measures them: 4 bytes a vertex
id of the traced paths (their stored bytes) and of the waypoints or paths given (the spec's ``source`` and
``target`` lists).

Revision ID: 0002
Revises: 0001
Create Date: 2026-11-27 22:10:00
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0002"
down_revision: str | None = "0001"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

SPEC_IDS = {
    "sqlite": "json_array_length(spec, '$.source') + json_array_length(spec, '$.target')",
    "postgresql": "jsonb_array_length(spec -> 'source') + jsonb_array_length(spec -> 'target')",
}


# Plain ALTER TABLE on both engines (SQLite 3.35+ drops a column too): a batch operation would copy the table on
# SQLite, and dropping the old copy would cascade to the sessions' curves and members.
def upgrade() -> None:
    op.add_column("sessions", sa.Column("bytes", sa.Integer(), server_default=sa.text("0"), nullable=False))
    spec_ids = SPEC_IDS[op.get_bind().dialect.name]
    curves = f"SELECT SUM(length(path_source) + length(path_target) + 4 * ({spec_ids})) FROM curves"
    op.execute(f"UPDATE sessions SET bytes = COALESCE(({curves} WHERE curves.session_id = sessions.id), 0)")


def downgrade() -> None:
    op.execute("ALTER TABLE sessions DROP COLUMN bytes")
