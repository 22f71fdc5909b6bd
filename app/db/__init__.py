"""Persistence: typed SQLAlchemy models (``models``), column types (``types``), engine and session
factories and the Alembic upgrade (``session``), the write unit every writer commits through (``unit``) and the rows
each version covers (``scope``). The schema lives in ``migrations/``."""
