"""The registry's schema versions, one Alembic revision each."""
