"""Schema version 1: robots, events (calibrations and checks), current changes, corrections,
registry_info; triggers that refuse UPDATE and DELETE on the append-only tables.

Revision ID: r0001
Revises: (none)
"""

import sqlalchemy as sa
from alembic import op

revision = "r0001"
down_revision = None
branch_labels = None
depends_on = None

#: tables whose rows are never changed
_APPEND_ONLY = ("robots", "events", "current_changes", "corrections")


def _append_only(dialect: str) -> None:
    """Triggers refusing UPDATE and DELETE (a correction is a new row)."""
    if dialect == "sqlite":
        for table in _APPEND_ONLY:
            for what in ("UPDATE", "DELETE"):
                op.execute(
                    f"CREATE TRIGGER {table}_no_{what.lower()} BEFORE {what} ON {table} "
                    f"BEGIN SELECT RAISE(ABORT, 'kinecal registry: {table} is append-only'); "
                    "END")
        return
    op.execute(
        "CREATE FUNCTION kinecal_append_only() RETURNS trigger LANGUAGE plpgsql AS $$ "
        "BEGIN RAISE EXCEPTION 'kinecal registry: % is append-only', TG_TABLE_NAME; END $$")
    for table in _APPEND_ONLY:
        op.execute(f"CREATE TRIGGER {table}_append_only BEFORE UPDATE OR DELETE ON {table} "
                   "FOR EACH ROW EXECUTE FUNCTION kinecal_append_only()")


def upgrade() -> None:
    op.create_table(
        "registry_info",
        sa.Column("key", sa.String(64), primary_key=True),
        sa.Column("value", sa.Text, nullable=False),
    )
    op.create_table(
        "robots",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("serial", sa.String(200), nullable=False, unique=True),
        sa.Column("created", sa.Text, nullable=False),
    )
    op.create_table(
        "events",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("robot_id", sa.Integer, sa.ForeignKey("robots.id"), nullable=False),
        sa.Column("uid", sa.String(64), nullable=False, unique=True),
        sa.Column("kind", sa.String(16), nullable=False),
        sa.Column("subject", sa.String(16), nullable=False),
        sa.Column("date", sa.Text, nullable=False),
        sa.Column("at", sa.Float, nullable=False),
        sa.Column("recorded", sa.Text, nullable=False),
        sa.Column("kinecal", sa.Text, nullable=False),
        sa.Column("operator", sa.Text),
        sa.Column("instrument", sa.Text),
        sa.Column("note", sa.Text),
        sa.Column("command", sa.Text),
        sa.Column("inputs", sa.Text, nullable=False),
        sa.Column("calibration_id", sa.Integer, sa.ForeignKey("events.id")),
        sa.Column("model_name", sa.Text),
        sa.Column("model_file", sa.Text),
        sa.Column("model_text", sa.Text),
        sa.Column("model_sha256", sa.String(64)),
        sa.Column("base_link", sa.Text),
        sa.Column("tip_link", sa.Text),
        sa.Column("verdict", sa.String(16)),
        sa.Column("statistic", sa.Float),
        sa.Column("p_value", sa.Float),
        sa.Column("limit_value", sa.Float),
        sa.Column("deviation", sa.Float),
        sa.Column("summary", sa.Text, nullable=False),
        sa.Column("document", sa.Text, nullable=False),
        sa.Column("document_sha256", sa.String(64), nullable=False),
        sa.Column("report", sa.LargeBinary),
        sa.Column("report_name", sa.Text),
        sa.Column("report_sha256", sa.String(64)),
        sa.CheckConstraint("kind IN ('calibration', 'check')", name="events_kind"),
    )
    op.create_index("events_robot_time", "events", ["robot_id", "at", "id"])
    op.create_table(
        "current_changes",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("robot_id", sa.Integer, sa.ForeignKey("robots.id"), nullable=False),
        sa.Column("event_id", sa.Integer, sa.ForeignKey("events.id"), nullable=False),
        sa.Column("subject", sa.String(16), nullable=False),
        sa.Column("date", sa.Text, nullable=False),
        sa.Column("recorded", sa.Text, nullable=False),
        sa.Column("reason", sa.Text),
        sa.Column("operator", sa.Text),
    )
    op.create_index("current_changes_robot", "current_changes", ["robot_id", "id"])
    op.create_table(
        "corrections",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("robot_id", sa.Integer, sa.ForeignKey("robots.id"), nullable=False),
        sa.Column("event_id", sa.Integer, sa.ForeignKey("events.id"), nullable=False),
        sa.Column("action", sa.String(16), nullable=False),
        sa.Column("reason", sa.Text, nullable=False),
        sa.Column("date", sa.Text, nullable=False),
        sa.Column("recorded", sa.Text, nullable=False),
        sa.Column("operator", sa.Text),
    )
    op.create_index("corrections_robot", "corrections", ["robot_id", "id"])
    _append_only(op.get_bind().dialect.name)


def downgrade() -> None:  # a registry is never downgraded: its history is kept
    raise NotImplementedError("the registry's schema is never downgraded")
