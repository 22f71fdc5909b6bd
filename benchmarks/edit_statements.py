"""Database statements of one ball edit: the service's ``update_ball_label`` on a 4-view system of a fresh demo
database, counted with SQLAlchemy's ``before_cursor_execute`` event, grouped by kind and table, and split into the
edit's reads (before its connection goes back to the pool), its computation (none: ``app.db.scope``)
and its write (on PostgreSQL each statement is a round trip). Deterministic (no timing). Usage (from the checkout)::

    .venv/bin/python benchmarks/edit_statements.py
    .venv/bin/python benchmarks/edit_statements.py postgresql+psycopg://postgres@127.0.0.1:5432/test
"""
import collections
import sys

sys.path.insert(0, ".")
from sqlalchemy import event, select
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db.models import Frame
from app.db.session import make_engine, make_session_factory
from app.services.curation import writing
from app.services.curation.editing import update_ball_label
from benchmarks.load import fresh_database


def main(url_arg: str | None) -> None:
    """Print the statements of three ball edits, per phase, kind and table."""
    with fresh_database(url_arg) as url:
        engine = make_engine(url)
        factory = make_session_factory(engine)
        counts: collections.Counter[str] = collections.Counter()
        phase = {"now": "read"}

        def before(conn, cursor, statement, params, context, executemany):  # noqa: ANN001  # SQLAlchemy's event
            words = statement.split()
            table = statement.split("FROM")[1].split()[0] if words[0].upper() == "SELECT" and "FROM" in statement \
                else (words[2] if words[0].upper() in ("INSERT", "DELETE") else words[1] if len(words) > 1 else "")
            counts[f"{phase['now']}: {words[0].upper()} {table}".strip()] += 1

        event.listen(engine, "before_cursor_execute", before)
        real_end, real_begin = writing.end_reads, writing.begin_write

        def end_reads(session: Session) -> None:
            real_end(session)
            phase["now"] = "compute"

        def begin_write(session: Session) -> None:
            phase["now"] = "write"
            real_begin(session)

        writing.end_reads, writing.begin_write = end_reads, begin_write
        with factory() as s:
            f = next(fr for fr in s.scalars(select(Frame).order_by(Frame.id))
                     if fr.ball_label is not None and fr.ball_label.box is not None and len(fr.system.frames) == 4)
            fid, box = f.id, list(f.ball_label.box)
        settings = Settings(database_url=url)
        for i in range(3):
            counts.clear()
            phase["now"] = "read"
            with factory() as s:
                update_ball_label(s, fid, box=[box[0] + i + 1, box[1], box[2] + i + 1, box[3]], settings=settings)
            print(f"edit {i + 1}: {sum(counts.values())} statements")
            for key, n in sorted(counts.items()):
                print(f"  {n:3d}  {key}")
        engine.dispose()


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None)
