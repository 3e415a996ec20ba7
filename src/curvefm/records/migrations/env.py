"""Alembic's environment for curvefm's records: a connection handed over by :mod:`curvefm.records.migrate`."""

from alembic import context
from sqlalchemy import Connection, create_engine

from curvefm.records.models import Base

config = context.config
target_metadata = Base.metadata


def run(connection: Connection) -> None:
    context.configure(
        connection=connection,
        target_metadata=target_metadata,
        render_as_batch=connection.dialect.name == "sqlite",  # SQLite alters a table by copying it
        compare_type=True,
    )
    with context.begin_transaction():
        context.run_migrations()


connection = config.attributes.get("connection")
if connection is not None:
    run(connection)
else:
    with create_engine(config.get_main_option("sqlalchemy.url") or "").connect() as fresh:
        run(fresh)
        fresh.commit()
