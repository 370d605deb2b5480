"""Initial ledger schema: chain head, runs, their files and QCRs, sign-offs.

Revision ID: 0001
Revises:
Create Date: 2026-11-21
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None

GENESIS = "0" * 64


def upgrade() -> None:
    head = op.create_table(
        "ledger_head",
        sa.Column("id", sa.Integer, autoincrement=False, nullable=False),
        sa.Column("seq", sa.Integer, nullable=False),
        sa.Column("hash", sa.String(64), nullable=False),
        sa.PrimaryKeyConstraint("id", name="pk_ledger_head"),
    )
    op.bulk_insert(head, [{"id": 1, "seq": 0, "hash": GENESIS}])
    op.create_table(
        "runs",
        sa.Column("id", sa.Integer, autoincrement=False, nullable=False),
        sa.Column("seq", sa.Integer, nullable=False),
        sa.Column("recorded_at", sa.String(32), nullable=False),
        sa.Column("date", sa.String(10), nullable=False),
        sa.Column("project_id", sa.String(200), nullable=False),
        sa.Column("delivery_id", sa.String(200), nullable=False),
        sa.Column("delivery_path", sa.Text, nullable=True),
        sa.Column("manifest_sha256", sa.String(64), nullable=False),
        sa.Column("profile_id", sa.String(200), nullable=False),
        sa.Column("profile_version", sa.String(64), nullable=False),
        sa.Column("profile_sha256", sa.String(64), nullable=False),
        sa.Column("verdict", sa.String(16), nullable=False),
        sa.Column("fail_on", sa.String(8), nullable=False),
        sa.Column("operator", sa.Text, nullable=True),
        sa.Column("n_records", sa.Integer, nullable=False),
        sa.Column("summary", sa.Text, nullable=False),
        sa.Column("document", sa.Text, nullable=False),
        sa.Column("document_sha256", sa.String(64), nullable=False),
        sa.Column("prev_hash", sa.String(64), nullable=False),
        sa.Column("hash", sa.String(64), nullable=False),
        sa.PrimaryKeyConstraint("id", name="pk_runs"),
        sa.UniqueConstraint("seq", name="uq_runs_seq"),
    )
    op.create_index("ix_runs_project_id_seq", "runs", ["project_id", "seq"])
    op.create_table(
        "run_files",
        sa.Column("run_id", sa.Integer, nullable=False),
        sa.Column("path", sa.String(1000), nullable=False),
        sa.Column("sha256", sa.String(64), nullable=False),
        sa.Column("bytes", sa.BigInteger, nullable=True),
        sa.ForeignKeyConstraint(["run_id"], ["runs.id"], name="fk_run_files_run_id_runs"),
        sa.PrimaryKeyConstraint("run_id", "path", name="pk_run_files"),
    )
    op.create_table(
        "qcrs",
        sa.Column("run_id", sa.Integer, nullable=False),
        sa.Column("ordinal", sa.Integer, autoincrement=False, nullable=False),
        sa.Column("rule", sa.String(200), nullable=False),
        sa.Column("scope", sa.String(32), nullable=False),
        sa.Column("item", sa.String(500), nullable=False),
        sa.Column("verdict", sa.String(16), nullable=False),
        sa.Column("family", sa.String(200), nullable=False),
        sa.Column("level", sa.String(16), nullable=True),
        sa.Column("consequence", sa.String(32), nullable=True),
        sa.Column("manual", sa.Boolean, nullable=False),
        sa.Column("measure", sa.String(300), nullable=True),
        sa.Column("measured", sa.Text, nullable=False),
        sa.Column("unit", sa.String(32), nullable=True),
        sa.Column("requirement", sa.Text, nullable=False),
        sa.Column("requirement_text", sa.Text, nullable=True),
        sa.Column("clause_document", sa.String(200), nullable=True),
        sa.Column("clause_section", sa.String(64), nullable=True),
        sa.Column("clause_table", sa.String(64), nullable=True),
        sa.Column("clause_row", sa.String(64), nullable=True),
        sa.Column("message", sa.Text, nullable=True),
        sa.ForeignKeyConstraint(["run_id"], ["runs.id"], name="fk_qcrs_run_id_runs"),
        sa.PrimaryKeyConstraint("run_id", "ordinal", name="pk_qcrs"),
    )
    op.create_index("ix_qcrs_run_id_rule", "qcrs", ["run_id", "rule"])
    op.create_table(
        "signoffs",
        sa.Column("id", sa.Integer, autoincrement=False, nullable=False),
        sa.Column("seq", sa.Integer, nullable=False),
        sa.Column("run_id", sa.Integer, nullable=False),
        sa.Column("run_hash", sa.String(64), nullable=False),
        sa.Column("recorded_at", sa.String(32), nullable=False),
        sa.Column("date", sa.String(10), nullable=False),
        sa.Column("by_name", sa.String(200), nullable=False),
        sa.Column("role", sa.String(64), nullable=False),
        sa.Column("note", sa.Text, nullable=True),
        sa.Column("manual", sa.Text, nullable=False),
        sa.Column("prev_hash", sa.String(64), nullable=False),
        sa.Column("hash", sa.String(64), nullable=False),
        sa.ForeignKeyConstraint(["run_id"], ["runs.id"], name="fk_signoffs_run_id_runs"),
        sa.PrimaryKeyConstraint("id", name="pk_signoffs"),
        sa.UniqueConstraint("seq", name="uq_signoffs_seq"),
    )
    op.create_index("ix_signoffs_run_id", "signoffs", ["run_id"])


def downgrade() -> None:
    op.drop_index("ix_signoffs_run_id", table_name="signoffs")
    op.drop_table("signoffs")
    op.drop_index("ix_qcrs_run_id_rule", table_name="qcrs")
    op.drop_table("qcrs")
    op.drop_table("run_files")
    op.drop_index("ix_runs_project_id_seq", table_name="runs")
    op.drop_table("runs")
    op.drop_table("ledger_head")
