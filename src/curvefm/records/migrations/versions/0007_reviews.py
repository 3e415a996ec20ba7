"""Review of members (submitted / changes requested / accepted) and further annotations of a member by other
annotators (double annotation, for agreement between annotators).

Revision ID: 0007
Revises: 0006
Create Date: 2026-11-28 05:00:00
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0007"
down_revision: str | None = "0006"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "member_reviews",
        sa.Column("collection_id", sa.String(64), nullable=False),
        sa.Column("member_id", sa.String(16), nullable=False),
        sa.Column("state", sa.String(20), nullable=False),
        sa.Column("submitted_by", sa.Integer(), nullable=True),
        sa.Column("submitted_at", sa.Double(), nullable=True),
        sa.Column("reviewed_by", sa.Integer(), nullable=True),
        sa.Column("reviewed_at", sa.Double(), nullable=True),
        sa.Column("comment", sa.Text(), nullable=False),
        sa.ForeignKeyConstraint(
            ["collection_id"],
            ["collections.id"],
            name=op.f("fk_member_reviews_collection_id_collections"),
            ondelete="CASCADE",
        ),
        sa.ForeignKeyConstraint(
            ["submitted_by"], ["users.id"], name=op.f("fk_member_reviews_submitted_by_users"), ondelete="SET NULL"
        ),
        sa.ForeignKeyConstraint(
            ["reviewed_by"], ["users.id"], name=op.f("fk_member_reviews_reviewed_by_users"), ondelete="SET NULL"
        ),
        sa.PrimaryKeyConstraint("collection_id", "member_id", name=op.f("pk_member_reviews")),
    )
    op.create_table(
        "member_annotations",
        sa.Column("collection_id", sa.String(64), nullable=False),
        sa.Column("member_id", sa.String(16), nullable=False),
        sa.Column("user_id", sa.Integer(), nullable=False),
        sa.Column("session_id", sa.String(64), nullable=False),
        sa.Column("created_at", sa.Double(), nullable=False),
        sa.ForeignKeyConstraint(
            ["collection_id"],
            ["collections.id"],
            name=op.f("fk_member_annotations_collection_id_collections"),
            ondelete="CASCADE",
        ),
        sa.ForeignKeyConstraint(
            ["user_id"], ["users.id"], name=op.f("fk_member_annotations_user_id_users"), ondelete="CASCADE"
        ),
        sa.ForeignKeyConstraint(
            ["session_id"], ["sessions.id"], name=op.f("fk_member_annotations_session_id_sessions"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("collection_id", "member_id", "user_id", name=op.f("pk_member_annotations")),
        sa.UniqueConstraint("session_id", name=op.f("uq_member_annotations_session_id")),
    )
    op.create_index(op.f("ix_member_annotations_user_id"), "member_annotations", ["user_id"])


def downgrade() -> None:
    op.drop_table("member_annotations")
    op.drop_table("member_reviews")
