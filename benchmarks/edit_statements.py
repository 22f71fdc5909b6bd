"""Database statements of one ball edit (issue 29, item 2): the service's ``update_ball_label`` on a 4-view system
of a fresh demo database, counted with SQLAlchemy's ``before_cursor_execute`` event, grouped by kind and table.

Deterministic (no timing): the figure item 2's work must bring down. Three edits of sessions without kept systems,
then three of sessions sharing one ``KeptSystems`` as a served process's do (on PostgreSQL the kept, trusted
objects spare every read before the lock). On PostgreSQL the statements an edit sends
together (``app.db.together``, psycopg's pipeline mode) do not pass SQLAlchemy's cursor events: they are counted
apart, with the pipelines that carried them (one round trip each). Usage (from the checkout)::

    .venv/bin/python benchmarks/edit_statements.py
    .venv/bin/python benchmarks/edit_statements.py postgresql+psycopg://postgres@127.0.0.1:5432/test
"""
import collections
import sys

sys.path.insert(0, ".")
from sqlalchemy import event, select

from app.core.config import Settings
from app.db.models import Frame
from app.db.session import make_engine, make_session_factory
from app.services.curation.editing import update_ball_label
from app.services.curation.kept import KEPT_SYSTEMS, KeptSystems
from benchmarks.load import fresh_database

url_arg = sys.argv[1] if len(sys.argv) > 1 else None
with fresh_database(url_arg) as url:
    eng = make_engine(url)
    SF = make_session_factory(eng)
    counts = collections.Counter()
    def before(conn, cursor, statement, params, context, executemany):
        """Count ``statement`` under its verb and, for a SELECT, its first table."""
        words = statement.split()
        table = statement.split("FROM")[1].split()[0] if words[0].upper() == "SELECT" and "FROM" in statement else ""
        counts[f"{words[0].upper()} {table}".strip()] += 1
    event.listen(eng, "before_cursor_execute", before)
    import app.db.together as together
    real_statement = together.driver_statement

    def counted_statement(stmt, dialect):
        """Count one statement sent in a pipeline (``send_together`` compiles each through this)."""
        counts["(pipelined statements)"] += 1
        return real_statement(stmt, dialect)

    together.driver_statement = counted_statement
    try:
        import psycopg

        real_pipeline = psycopg.Connection.pipeline

        def counted_pipeline(self):
            """Count one pipeline: one round trip."""
            counts["(pipelines)"] += 1
            return real_pipeline(self)

        psycopg.Connection.pipeline = counted_pipeline
    except ImportError:
        pass
    with SF() as s:
        f = next(fr for fr in s.scalars(select(Frame).order_by(Frame.id))
                 if fr.ball_label is not None and fr.ball_label.box is not None and len(fr.system.frames) == 4)
        fid, box = f.id, list(f.ball_label.box)
    settings = Settings(database_url=url)
    kept_SF = make_session_factory(eng, info={KEPT_SYSTEMS: KeptSystems()})  # as a served process's sessions
    for i in range(6):  # three edits without kept systems, then three of a process that keeps them
        counts.clear()
        if i == 3:
            print("-- a process that keeps its last systems (the first edit loads, the next take the kept objects):")
        with (SF if i < 3 else kept_SF)() as s:
            b = [box[0] + 2 + i, box[1], box[2] + 2 + i, box[3]]
            update_ball_label(s, fid, box=b, settings=settings, actor="x")
        alone = sum(v for k, v in counts.items() if not k.startswith("("))
        print("edit", i, f"{alone} statements alone, {counts['(pipelined statements)']} pipelined in "
              f"{counts['(pipelines)']} round trips;", dict(counts.most_common(14)))
