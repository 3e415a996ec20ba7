"""A user's logins end when they log out: the login cookies issued before ``logins_ended_at`` are refused.

Revision ID: 0004
Revises: 0003
Create Date: 2026-11-27 23:10:00
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0004"
down_revision: str | None = "0003"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


# Plain ALTER TABLE on both engines, as in 0002 (a batch operation would copy the table on SQLite).
def upgrade() -> None:
    op.add_column("users", sa.Column("logins_ended_at", sa.Double(), nullable=True))


def downgrade() -> None:
    op.execute("ALTER TABLE users DROP COLUMN logins_ended_at")
