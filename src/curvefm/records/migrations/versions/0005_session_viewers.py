"""Who has a session open: a row per open event stream, kept alive by its API process (presence).

Revision ID: 0005
Revises: 0004
Create Date: 2026-11-28 01:30:00
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0005"
down_revision: str | None = "0004"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "session_viewers",
        sa.Column("id", sa.String(32), nullable=False),
        sa.Column("session_id", sa.String(64), nullable=False),
        sa.Column("user_id", sa.Integer(), nullable=False),
        sa.Column("opened_at", sa.Double(), nullable=False),
        sa.Column("expires_at", sa.Double(), nullable=False),
        sa.ForeignKeyConstraint(
            ["session_id"],
            ["sessions.id"],
            name=op.f("fk_session_viewers_session_id_sessions"),
            ondelete="CASCADE",
        ),
        sa.ForeignKeyConstraint(
            ["user_id"], ["users.id"], name=op.f("fk_session_viewers_user_id_users"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_session_viewers")),
    )
    op.create_index(op.f("ix_session_viewers_session_id"), "session_viewers", ["session_id"])
    op.create_index(op.f("ix_session_viewers_user_id"), "session_viewers", ["user_id"])
    op.create_index(op.f("ix_session_viewers_expires_at"), "session_viewers", ["expires_at"])


def downgrade() -> None:
    op.drop_table("session_viewers")
