"""The registry's tables (SQLAlchemy Core), as the newest migration leaves them.

``robots``: one row per serial number. ``events``: every calibration and every check,
append-only: a calibration holds its result JSON (``document``), report, model (the model
file's text, so that a record stays usable when the file or the bundled model changes),
inputs with their SHA-256 and the record (date, operator, instrument, command); a check
holds its JSON, verdict, statistic, p-value, limit and the calibration it judged.
``current_changes``: which calibration is current, one row per change (the last one
counts). ``corrections``: retractions, each with its reason. ``registry_info``: the schema
version and the kinecal that wrote it. Triggers refuse any UPDATE or DELETE of the
append-only tables (`kinecal.registry.migrations`).

The tables are made by the migrations (`kinecal.registry.migrations.versions`), never from
this module: a migration keeps its own copy of what it creates.
"""

from __future__ import annotations

from sqlalchemy import (
    Column,
    Float,
    ForeignKey,
    Integer,
    LargeBinary,
    MetaData,
    String,
    Table,
    Text,
)

__all__ = [
    "APPEND_ONLY",
    "HEAD",
    "REVISIONS",
    "SCHEMA_VERSION",
    "corrections",
    "current_changes",
    "events",
    "metadata",
    "registry_info",
    "robots",
]

#: the newest schema this kinecal writes (registry_info 'schema')
SCHEMA_VERSION = 1
#: Alembic revision of each schema version this kinecal knows, oldest first
REVISIONS = ("r0001",)
HEAD = REVISIONS[-1]
#: tables whose rows are never updated nor deleted
APPEND_ONLY = ("robots", "events", "current_changes", "corrections")

metadata = MetaData()

registry_info = Table(
    "registry_info", metadata,
    Column("key", String(64), primary_key=True),
    Column("value", Text, nullable=False),
)

robots = Table(
    "robots", metadata,
    Column("id", Integer, primary_key=True),
    Column("serial", String(200), nullable=False, unique=True),
    Column("created", Text, nullable=False),
)

events = Table(
    "events", metadata,
    Column("id", Integer, primary_key=True),
    Column("robot_id", ForeignKey("robots.id"), nullable=False),
    Column("uid", String(64), nullable=False, unique=True),
    Column("kind", String(16), nullable=False),
    Column("subject", String(16), nullable=False),
    Column("date", Text, nullable=False),
    Column("at", Float, nullable=False),
    Column("recorded", Text, nullable=False),
    Column("kinecal", Text, nullable=False),
    Column("operator", Text),
    Column("instrument", Text),
    Column("note", Text),
    Column("command", Text),
    Column("inputs", Text, nullable=False),
    Column("calibration_id", ForeignKey("events.id")),
    Column("model_name", Text),
    Column("model_file", Text),
    Column("model_text", Text),
    Column("model_sha256", String(64)),
    Column("base_link", Text),
    Column("tip_link", Text),
    Column("verdict", String(16)),
    Column("statistic", Float),
    Column("p_value", Float),
    Column("limit_value", Float),
    Column("deviation", Float),
    Column("summary", Text, nullable=False),
    Column("document", Text, nullable=False),
    Column("document_sha256", String(64), nullable=False),
    Column("report", LargeBinary),
    Column("report_name", Text),
    Column("report_sha256", String(64)),
)

current_changes = Table(
    "current_changes", metadata,
    Column("id", Integer, primary_key=True),
    Column("robot_id", ForeignKey("robots.id"), nullable=False),
    Column("event_id", ForeignKey("events.id"), nullable=False),
    Column("subject", String(16), nullable=False),
    Column("date", Text, nullable=False),
    Column("recorded", Text, nullable=False),
    Column("reason", Text),
    Column("operator", Text),
)

corrections = Table(
    "corrections", metadata,
    Column("id", Integer, primary_key=True),
    Column("robot_id", ForeignKey("robots.id"), nullable=False),
    Column("event_id", ForeignKey("events.id"), nullable=False),
    Column("action", String(16), nullable=False),
    Column("reason", Text, nullable=False),
    Column("date", Text, nullable=False),
    Column("recorded", Text, nullable=False),
    Column("operator", Text),
)
