"""Alembic migrations of the registry's schema, run by `kinecal.registry.store` when it opens
a registry older than this kinecal (or a new one): ``env.py`` runs them on the connection
the store hands over, inside its transaction (SQLite and PostgreSQL both change their
schema transactionally: a migration is all or nothing). One module per schema version in
``versions/``; `kinecal.registry.schema` lists their revisions."""
