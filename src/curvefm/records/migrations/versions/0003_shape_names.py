"""Shapes have a name (the uploaded file's), listed by name and upload time.

Revision ID: 0003
Revises: 0002
Create Date: 2026-11-27 22:10:00
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0003"
down_revision: str | None = "0002"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


# Plain ALTER TABLE on both engines, as in 0002: a batch operation would copy the table on SQLite, and dropping the
# old copy would meet the foreign keys of the sessions and collections that use the shapes.
def upgrade() -> None:
    # names of shapes recorded before are read from their blobs by the service (Shapes.name_unnamed)
    op.add_column("shapes", sa.Column("name", sa.String(length=200), server_default=sa.text("''"), nullable=False))
    op.create_index("ix_shapes_name", "shapes", ["name", "created_at"], unique=False)


def downgrade() -> None:
    op.drop_index("ix_shapes_name", table_name="shapes")
    op.execute("ALTER TABLE shapes DROP COLUMN name")
