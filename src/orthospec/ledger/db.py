"""Opening a ledger database (SQLite file or PostgreSQL URL), its schema, its write transactions.

Writes are one transaction each: the chain head row is locked first (``BEGIN IMMEDIATE`` on
SQLite, ``SELECT ... FOR UPDATE`` on PostgreSQL), so concurrent writers queue and a process
killed mid-write leaves the ledger exactly as it was. QCR rows go in by batches (COPY on
PostgreSQL, executemany on SQLite): memory stays bounded whatever the number of rows.
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from sqlalchemy import Connection, Engine, create_engine, event, select, text
from sqlalchemy.engine import make_url
from sqlalchemy.exc import ArgumentError, DBAPIError, NoSuchModuleError

from ..errors import LedgerError
from . import models as m
from .rows import QCR_COLUMNS, Row

#: the file used when neither ``--ledger`` nor ``ORTHOSPEC_LEDGER`` names one
DEFAULT_LEDGER = "orthospec-ledger.sqlite"
ENV_LEDGER = "ORTHOSPEC_LEDGER"
_PG_LOCK_KEY = 0x6F72_7468  # advisory lock serialising schema upgrades on a shared server


def default_ledger() -> str:
    """``$ORTHOSPEC_LEDGER`` if set, else ``./orthospec-ledger.sqlite``."""
    return os.environ.get(ENV_LEDGER) or DEFAULT_LEDGER


def to_url(target: str | os.PathLike[str]) -> str:
    """A SQLAlchemy URL for a path or URL; ``postgresql://`` is served by psycopg 3."""
    s = os.fspath(target)
    if "://" not in s:
        return f"sqlite:///{Path(s).expanduser().absolute().as_posix()}"
    if s.startswith(("postgresql://", "postgres://")):
        return "postgresql+psycopg://" + s.split("://", 1)[1]
    return s


def connect(target: str | os.PathLike[str] | None, *, create: bool) -> tuple[Engine, str]:
    """(engine, display name) of the ledger at a path or SQLAlchemy URL; the schema is not touched.

    ``create=False`` refuses to create a missing SQLite file (read-only commands use it so a
    typo in a path is an error, not a new empty ledger).
    """
    raw = os.fspath(target) if target is not None else default_ledger()
    try:
        url = make_url(to_url(raw))
    except ArgumentError:
        raise LedgerError(f"ledger {raw!r}: not a path or SQLAlchemy URL") from None
    display = url.render_as_string(hide_password=True) if url.drivername != "sqlite" else raw
    if url.drivername.startswith("sqlite"):
        path = Path(url.database or "")
        if not url.database or url.database == ":memory:":
            raise LedgerError(f"ledger {raw!r}: an in-memory SQLite ledger would keep nothing")
        if path.is_file() and path.stat().st_size == 0:
            raise LedgerError(
                f"ledger {raw}: empty file (0 bytes). A truncated ledger is not a new one: "
                "restore it from a backup, or remove the file to start a new ledger"
            )
        if not path.exists():
            if not create:
                raise LedgerError(
                    f"no ledger at {raw} (record a run first with "
                    f"`orthospec check ... --ledger {raw}`)"
                )
            path.parent.mkdir(parents=True, exist_ok=True)
        engine = create_engine(url, connect_args={"timeout": 60})
        _sqlite_events(engine)
    elif url.drivername.startswith("postgresql"):
        try:
            engine = create_engine(url, pool_pre_ping=True)
        except (NoSuchModuleError, ModuleNotFoundError) as exc:
            raise LedgerError(
                f"ledger {display}: PostgreSQL driver missing ({exc}); install orthospec[postgres]"
            ) from None
    else:
        raise LedgerError(
            f"ledger {display}: unsupported database {url.drivername!r}; "
            "use a SQLite path or a postgresql+psycopg:// URL"
        )
    return engine, display


def ensure_schema(engine: Engine, display: str) -> None:
    """Migrate the schema to this code's revision; a newer or unknown revision is refused."""
    with engine.connect() as conn:
        rev = current_revision(conn)
        conn.rollback()
    if rev == m.SCHEMA_REVISION:
        return
    if rev is not None and not rev.isdigit():
        raise LedgerError(f"ledger {display}: unknown schema revision {rev!r}")
    if rev is not None and int(rev) > int(m.SCHEMA_REVISION):
        raise LedgerError(
            f"ledger {display}: schema revision {rev} is newer than this "
            f"orthospec ({m.SCHEMA_REVISION}); upgrade orthospec"
        )
    with writer(engine).begin() as conn:
        if conn.dialect.name == "postgresql":
            conn.execute(text("SELECT pg_advisory_xact_lock(:k)"), {"k": _PG_LOCK_KEY})
        upgrade(conn)


def writer(engine: Engine) -> Engine:
    """The engine whose transactions take the write lock up front (SQLite ``BEGIN IMMEDIATE``)."""
    return engine.execution_options(ledger_write=True)


@contextmanager
def write_transaction(engine: Engine, display: str) -> Iterator[tuple[Connection, int, str]]:
    """A write transaction holding the chain head: yields (conn, head seq, head hash)."""
    try:
        with writer(engine).begin() as conn:
            row = conn.execute(
                select(m.head.c.seq, m.head.c.hash).where(m.head.c.id == 1).with_for_update()
            ).one_or_none()
            if row is None:
                raise LedgerError(
                    f"{display}: the chain head row is missing; run `orthospec ledger verify`"
                )
            yield conn, int(row.seq), str(row.hash)
    except DBAPIError as exc:
        raise LedgerError(
            f"{display}: write failed, nothing recorded: {str(exc.orig).strip()}"
        ) from None


def _sqlite_events(engine: Engine) -> None:
    """Own the transactions: BEGIN IMMEDIATE for writes (takes the write lock up front)."""

    @event.listens_for(engine, "connect")
    def _connect(dbapi_conn: Any, _rec: Any) -> None:
        dbapi_conn.isolation_level = None
        cur = dbapi_conn.cursor()
        cur.execute("PRAGMA foreign_keys=ON")
        cur.close()

    @event.listens_for(engine, "begin")
    def _begin(conn: Connection) -> None:
        write = conn.get_execution_options().get("ledger_write", False)
        conn.exec_driver_sql("BEGIN IMMEDIATE" if write else "BEGIN")


def upgrade(conn: Connection) -> None:
    """Apply the package's Alembic migrations up to head on an open connection."""
    from alembic import command
    from alembic.config import Config

    cfg = Config()
    cfg.set_main_option("script_location", str(Path(__file__).with_name("migrations")))
    cfg.attributes["connection"] = conn
    command.upgrade(cfg, "head")


def current_revision(conn: Connection) -> str | None:
    from alembic.runtime.migration import MigrationContext

    return MigrationContext.configure(conn).get_current_revision()


#: QCR rows per executemany and per hash update (a few MB of rows at a time)
BATCH = 5000


def next_batch(rows: Iterator[Row]) -> list[Row]:
    """The next rows of ``rows_with_text`` (empty at the end); a malformed document is a LedgerError."""
    try:
        return list(itertools.islice(rows, BATCH))
    except (KeyError, TypeError, AttributeError) as exc:
        raise LedgerError(
            f"not a QCR document (missing {exc}); expected qcr.json structure"
        ) from None


def qcr_writer(
    conn: Connection, run_id: int, display: str
) -> Callable[[list[tuple[Any, ...]]], None]:
    """Writes a batch of QCR rows (value tuples in :data:`QCR_COLUMNS` order) of run ``run_id`` in
    the open transaction: PostgreSQL by COPY (one stream, not a statement per row), SQLite by
    executemany of one INSERT with positional parameters (they bind faster than named ones)."""
    q = conn.dialect.identifier_preparer.quote
    columns = f"{q('run_id')}, {', '.join(q(c) for c in QCR_COLUMNS)}"
    if conn.dialect.name == "postgresql":
        import psycopg

        copy = f"COPY {q(m.qcrs.name)} ({columns}) FROM STDIN"
        dbapi: Any = conn.connection.dbapi_connection  # the transaction's own connection

        def write_pg(batch: list[tuple[Any, ...]]) -> None:
            try:
                with dbapi.cursor() as cur, cur.copy(copy) as out:
                    for values in batch:
                        out.write_row((run_id, *values))
            except psycopg.Error as exc:
                raise LedgerError(
                    f"{display}: write failed, nothing recorded: {str(exc).strip()}"
                ) from None

        return write_pg
    insert = f"INSERT INTO {q(m.qcrs.name)} ({columns}) VALUES ({int(run_id)}, {', '.join('?' for _ in QCR_COLUMNS)})"

    def write_sqlite(batch: list[tuple[Any, ...]]) -> None:
        conn.exec_driver_sql(insert, batch)

    return write_sqlite
