"""Check members: a member's ground truth (template vertex -> member vertex), given by a manager, against which
each annotator's map of it is scored.

Revision ID: 0011
Revises: 0010
Create Date: 2026-11-28 08:00:00
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0011"
down_revision: str | None = "0010"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "member_truths",
        sa.Column("collection_id", sa.String(64), nullable=False),
        sa.Column("member_id", sa.String(16), nullable=False),
        sa.Column("truth", sa.LargeBinary(), nullable=False),
        sa.Column("set_by", sa.Integer(), nullable=True),
        sa.Column("set_at", sa.Double(), nullable=False),
        sa.ForeignKeyConstraint(
            ["collection_id"],
            ["collections.id"],
            name=op.f("fk_member_truths_collection_id_collections"),
            ondelete="CASCADE",
        ),
        sa.ForeignKeyConstraint(
            ["set_by"], ["users.id"], name=op.f("fk_member_truths_set_by_users"), ondelete="SET NULL"
        ),
        sa.PrimaryKeyConstraint("collection_id", "member_id", name=op.f("pk_member_truths")),
    )


def downgrade() -> None:
    op.drop_table("member_truths")
