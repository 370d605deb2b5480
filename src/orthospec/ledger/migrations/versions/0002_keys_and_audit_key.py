"""Keys and audit continuity: signatures on runs and sign-offs, the run's audit key.

Revision ID: 0002
Revises: 0001
Create Date: 2026-11-28

Runs and sign-offs get the SSH signature of the person who made them (issue 29 item 5) and runs
the audit key their Normal/Tightened state and §12.8 rounds are kept under and the earlier run
whose content they continue (issue 25 item 6).
Every new column is nullable and enters an entry's chain hash only when set (chain.ADDED_COLUMNS):
entries recorded before this revision keep their hash and verify as before; they show as
unsigned, and their audit key is their manifest project id.
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("runs") as batch:
        batch.add_column(sa.Column("audit_key", sa.String(200), nullable=True))
        batch.add_column(sa.Column("continues_run", sa.Integer, nullable=True))
        batch.add_column(sa.Column("signer", sa.String(200), nullable=True))
        batch.add_column(sa.Column("key_fingerprint", sa.String(100), nullable=True))
        batch.add_column(sa.Column("signature", sa.Text, nullable=True))
        batch.create_index("ix_runs_audit_key_seq", ["audit_key", "seq"])
    op.create_index("ix_run_files_sha256", "run_files", ["sha256"])
    with op.batch_alter_table("signoffs") as batch:
        batch.add_column(sa.Column("key_fingerprint", sa.String(100), nullable=True))
        batch.add_column(sa.Column("signature", sa.Text, nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("signoffs") as batch:
        batch.drop_column("signature")
        batch.drop_column("key_fingerprint")
    with op.batch_alter_table("runs") as batch:
        batch.drop_index("ix_runs_audit_key_seq")
        batch.drop_column("signature")
        batch.drop_column("key_fingerprint")
        batch.drop_column("signer")
        batch.drop_column("continues_run")
        batch.drop_column("audit_key")
    op.drop_index("ix_run_files_sha256", table_name="run_files")
