"""Alembic environment for the ledger.

orthospec applies migrations itself (``db.upgrade``) and passes its open connection in
``config.attributes["connection"]``; a developer running the ``alembic`` command instead sets
``sqlalchemy.url`` in the config.
"""

from __future__ import annotations

from alembic import context
from sqlalchemy import create_engine

from orthospec.ledger.models import metadata

config = context.config
connection = config.attributes.get("connection")


def _run(conn) -> None:
    context.configure(connection=conn, target_metadata=metadata,
                      render_as_batch=conn.dialect.name == "sqlite")
    with context.begin_transaction():
        context.run_migrations()


if context.is_offline_mode():
    context.configure(url=config.get_main_option("sqlalchemy.url"), target_metadata=metadata,
                      literal_binds=True)
    with context.begin_transaction():
        context.run_migrations()
elif connection is not None:
    _run(connection)
else:
    engine = create_engine(config.get_main_option("sqlalchemy.url") or "")
    with engine.begin() as conn:
        _run(conn)
