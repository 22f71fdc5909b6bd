"""Persistence: typed SQLAlchemy models (``models``), column types (``types``), engine and session
factories and the Alembic upgrade (``session``). The schema lives in ``migrations/``."""
