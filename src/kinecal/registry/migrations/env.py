"""Alembic's environment for the registry: the migrations run on the connection that
`kinecal.registry.store` passes as ``config.attributes["connection"]``, inside its
transaction (no engine, no ini file)."""

from alembic import context

connection = context.config.attributes["connection"]
context.configure(connection=connection, transactional_ddl=True,
                  version_table="alembic_version")
with context.begin_transaction():
    context.run_migrations()
