"""The ledger's tables (SQLAlchemy Core), the one description migrations are checked against.

Every column that enters a chain hash holds text, integers or booleans only: floats would not
round-trip identically through SQLite and PostgreSQL, so measured values are stored as JSON text.
"""

from __future__ import annotations

from sqlalchemy import (
    BigInteger,
    Boolean,
    Column,
    ForeignKey,
    Index,
    Integer,
    MetaData,
    String,
    Table,
    Text,
)

#: Alembic revision the current code expects (the newest file in migrations/versions).
SCHEMA_REVISION = "0002"

#: prev_hash of the first entry of every chain.
GENESIS = "0" * 64

metadata = MetaData(naming_convention={
    "ix": "ix_%(table_name)s_%(column_0_N_name)s",
    "uq": "uq_%(table_name)s_%(column_0_N_name)s",
    "fk": "fk_%(table_name)s_%(column_0_name)s_%(referred_table_name)s",
    "pk": "pk_%(table_name)s",
})

#: One row (id = 1): the last entry of the chain. Deleting the newest run changes nothing in
#: the chain itself; the head row still remembers it, so `verify` sees the truncation.
head = Table(
    "ledger_head", metadata,
    Column("id", Integer, primary_key=True, autoincrement=False),
    Column("seq", Integer, nullable=False),
    Column("hash", String(64), nullable=False),
)

runs = Table(
    "runs", metadata,
    Column("id", Integer, primary_key=True, autoincrement=False),
    Column("seq", Integer, nullable=False, unique=True),
    Column("recorded_at", String(32), nullable=False),
    Column("date", String(10), nullable=False),
    Column("project_id", String(200), nullable=False),
    Column("delivery_id", String(200), nullable=False),
    Column("delivery_path", Text, nullable=True),
    Column("manifest_sha256", String(64), nullable=False),
    Column("profile_id", String(200), nullable=False),
    Column("profile_version", String(64), nullable=False),
    Column("profile_sha256", String(64), nullable=False),
    Column("verdict", String(16), nullable=False),
    Column("fail_on", String(8), nullable=False),
    Column("operator", Text, nullable=True),
    Column("n_records", Integer, nullable=False),
    Column("summary", Text, nullable=False),
    Column("document", Text, nullable=False),
    Column("document_sha256", String(64), nullable=False),
    Column("prev_hash", String(64), nullable=False),
    Column("hash", String(64), nullable=False),
    # 0002: the key the audit state and rounds are kept under (what the checker states, else
    # content continuity, else the manifest's project id); the checker's SSH signature
    Column("audit_key", String(200), nullable=True),
    Column("continues_run", Integer, nullable=True),
    Column("signer", String(200), nullable=True),
    Column("key_fingerprint", String(100), nullable=True),
    Column("signature", Text, nullable=True),
    Index(None, "project_id", "seq"),
    Index(None, "audit_key", "seq"),
)

run_files = Table(
    "run_files", metadata,
    Column("run_id", Integer, ForeignKey("runs.id"), primary_key=True),
    Column("path", String(1000), primary_key=True),
    Column("sha256", String(64), nullable=False),
    Column("bytes", BigInteger, nullable=True),
    Index(None, "sha256"),   # 0002: content continuity (which earlier run a delivery continues)
)

qcrs = Table(
    "qcrs", metadata,
    Column("run_id", Integer, ForeignKey("runs.id"), primary_key=True),
    Column("ordinal", Integer, primary_key=True, autoincrement=False),
    Column("rule", String(200), nullable=False),
    Column("scope", String(32), nullable=False),
    Column("item", String(500), nullable=False),
    Column("verdict", String(16), nullable=False),
    Column("family", String(200), nullable=False),
    Column("level", String(16), nullable=True),
    Column("consequence", String(32), nullable=True),
    Column("manual", Boolean, nullable=False),
    Column("measure", String(300), nullable=True),
    Column("measured", Text, nullable=False),
    Column("unit", String(32), nullable=True),
    Column("requirement", Text, nullable=False),
    Column("requirement_text", Text, nullable=True),
    Column("clause_document", String(200), nullable=True),
    Column("clause_section", String(64), nullable=True),
    Column("clause_table", String(64), nullable=True),
    Column("clause_row", String(64), nullable=True),
    Column("message", Text, nullable=True),
    Index(None, "run_id", "rule"),
)

signoffs = Table(
    "signoffs", metadata,
    Column("id", Integer, primary_key=True, autoincrement=False),
    Column("seq", Integer, nullable=False, unique=True),
    Column("run_id", Integer, ForeignKey("runs.id"), nullable=False, index=True),
    Column("run_hash", String(64), nullable=False),
    Column("recorded_at", String(32), nullable=False),
    Column("date", String(10), nullable=False),
    Column("by_name", String(200), nullable=False),
    Column("role", String(64), nullable=False),
    Column("note", Text, nullable=True),
    Column("manual", Text, nullable=False),
    Column("prev_hash", String(64), nullable=False),
    Column("hash", String(64), nullable=False),
    # 0002: the countersigner's SSH signature (by_name is then the allowed-signers principal)
    Column("key_fingerprint", String(100), nullable=True),
    Column("signature", Text, nullable=True),
)

TABLES = ("ledger_head", "runs", "run_files", "qcrs", "signoffs")
