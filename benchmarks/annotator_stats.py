"""The per-annotator figures at the SoccerNet-v3 scale (``app.services.evaluation.annotators.annotator_figures``, what
``GET /api/stats/annotators`` answers): 12,800 systems of three views, a synthetic audit log of 20 users x 5,000 label
edits (100,000 entries: ball, field lines, mirror and exclusion edits on random systems over 60 days), a decision on
every second system touched, 1,500 hand-offs, the recomputation's stored distances (``others_distance_px``) and a
label-accusing doubt on one view in ten.

The database is a fresh SQLite file (default) or a fresh PostgreSQL database (``--pg-url``, e.g.
``postgresql+psycopg://postgres@127.0.0.1:5432/v3d_team_bench``: created by the caller, dropped after), migrated to
head and filled with bulk inserts (seed ``--seed``). Measured in process, ``--repeat`` times each: all time, and a
30-day window (``since`` / ``until``); p50 / p95 / max ms. Usage::

    .venv/bin/python benchmarks/annotator_stats.py [--pg-url URL] [--repeat 20]
"""
from __future__ import annotations

import argparse
import random
import statistics
import sys
import tempfile
import time
from datetime import datetime, timedelta, timezone
from pathlib import Path
from typing import Optional

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

SYSTEMS, VIEWS, USERS, EDITS_PER_USER = 12_800, 3, 20, 5_000
T0 = datetime(2026, 9, 1, tzinfo=timezone.utc)
DAYS = 60


def build(url: str, seed: int) -> None:
    """Migrate ``url`` to head and fill it (module docstring)."""
    import sqlalchemy as sa

    from app.db.models import (
        AuditEntry,
        BallReprojection,
        Doubt,
        Frame,
        FrameRole,
        Game,
        ReviewHandoff,
        ReviewStatus,
        System,
        SystemKind,
        User,
        UserRole,
    )
    from app.db.session import make_engine, make_session_factory, upgrade_database
    from app.services.curation.handoff import LABEL_ACTIONS

    upgrade_database(url)
    rng = random.Random(seed)
    engine = make_engine(url)
    with make_session_factory(engine)() as session:
        session.execute(sa.insert(User), [dict(name=f"annotator{u:02d}", role=UserRole.ANNOTATOR, password_hash="-")
                                          for u in range(USERS)])
        session.execute(sa.insert(User), [dict(name="reviewer", role=UserRole.REVIEWER, password_hash="-")])
        user_ids = list(session.scalars(sa.select(User.id).where(User.role == UserRole.ANNOTATOR).order_by(User.id)))
        systems: list[tuple[int, int]] = []  # (system id, game id)
        for g in range(SYSTEMS // 32):
            game = Game(league="england_epl", season="2014-2015", match=f"game {g:04d}", source_path="/nowhere")
            session.add(game)
            session.flush()
            session.execute(sa.insert(System), [dict(
                game_id=game.id, name=f"{i + 1}.png", kind=SystemKind.SOCCERNET_V3, doubt_counts={},
                review_status=rng.choice([ReviewStatus.PENDING, ReviewStatus.ACCEPTED, ReviewStatus.REJECTED]),
            ) for i in range(32)])
            systems += [(int(i), game.id) for i in session.scalars(
                sa.select(System.id).where(System.game_id == game.id).order_by(System.id))]
        for chunk in range(0, len(systems), 2000):
            session.execute(sa.insert(Frame), [dict(
                system_id=sid, name=f"{sid}_{v}.png", role=FrameRole.ACTION if v == 0 else FrameRole.REPLAY,
                position=v, width=1920, height=1080) for sid, _ in systems[chunk:chunk + 2000] for v in range(VIEWS)])
        frame_system = {int(f): int(s) for f, s in session.execute(sa.select(Frame.id, Frame.system_id))}
        by_system: dict[int, list[int]] = {}
        for f, sid in sorted(frame_system.items()):
            by_system.setdefault(sid, []).append(f)
        all_frames = sorted(frame_system)
        for chunk in range(0, len(all_frames), 5000):
            part = all_frames[chunk:chunk + 5000]
            session.execute(sa.insert(BallReprojection), [dict(
                frame_id=f, point=[960.0, 540.0], error_px=rng.uniform(0, 20),
                others_distance_px=None if rng.random() < 0.1 else rng.lognormvariate(1.5, 1.0)) for f in part])
            session.execute(sa.insert(Doubt), [dict(
                system_id=frame_system[f], frame_id=f, kind="ball_off_consensus", accuses_label=True,
                message="off", evidence={}) for f in part if rng.random() < 0.1])
        game_of = dict(systems)
        entries = []
        touched: list[int] = []
        for u in range(USERS):
            for _ in range(EDITS_PER_USER):
                sid = rng.choice(systems)[0]
                touched.append(sid)
                action = rng.choices(LABEL_ACTIONS, weights=(6, 2, 1, 1))[0]
                entries.append(dict(actor=f"annotator{u:02d}", action=action, system_id=sid, game_id=game_of[sid],
                                    frame_id=rng.choice(by_system[sid]),
                                    at=T0 + timedelta(seconds=rng.uniform(0, DAYS * 86400)), summary="edit"))
        for sid in rng.sample(sorted(set(touched)), len(set(touched)) // 2):
            entries.append(dict(actor="reviewer", action="system.review", system_id=sid, game_id=game_of[sid],
                                at=T0 + timedelta(seconds=rng.uniform(0, DAYS * 86400)), summary="system accepted"))
        entries.sort(key=lambda e: e["at"])
        for chunk in range(0, len(entries), 5000):
            session.execute(sa.insert(AuditEntry), entries[chunk:chunk + 5000])
        session.execute(sa.insert(ReviewHandoff), [dict(
            system_id=sid, returned_to_id=rng.choice(user_ids), returned_by="reviewer", note="",
            returned_at=T0 + timedelta(seconds=rng.uniform(0, DAYS * 86400))) for sid in rng.sample(touched, 1500)])
        session.commit()
    engine.dispose()


def measure(url: str, repeat: int) -> dict[str, dict[str, float]]:
    """p50 / p95 / max ms of ``annotator_figures``, all time and over a 30-day window; also the rows it answered."""
    from app.db.session import make_engine, make_session_factory
    from app.services.evaluation.annotators import annotator_figures

    engine = make_engine(url)
    out: dict[str, dict[str, float]] = {}
    windows = {"all time": (None, None), "30 days": (T0 + timedelta(days=15), T0 + timedelta(days=45))}
    try:
        with make_session_factory(engine)() as session:
            for name, (since, until) in windows.items():
                annotator_figures(session, since, until)  # warm the caches once
                times = []
                for _ in range(repeat):
                    t = time.perf_counter()
                    figures = annotator_figures(session, since, until)
                    times.append((time.perf_counter() - t) * 1000)
                    session.rollback()
                times.sort()
                out[name] = {"p50_ms": statistics.median(times), "p95_ms": times[int(0.95 * (len(times) - 1))],
                             "max_ms": times[-1], "people": len(figures), "edits": sum(f.edits for f in figures)}
    finally:
        engine.dispose()
    return out


def main(argv: Optional[list[str]] = None) -> int:
    """Build, measure, print a Markdown table."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--pg-url", help="a fresh, empty PostgreSQL database (else a temporary SQLite file)")
    parser.add_argument("--repeat", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        url = args.pg_url or f"sqlite:///{Path(tmp) / 'annotators.sqlite3'}"
        t = time.perf_counter()
        build(url, args.seed)
        built = time.perf_counter() - t
        figures = measure(url, args.repeat)
    backend = "PostgreSQL" if args.pg_url else "SQLite"
    print(f"{backend}: {SYSTEMS} systems, {USERS * EDITS_PER_USER} label edits (built in {built:.0f} s), "
          f"{args.repeat} runs each")
    print("| window | p50 ms | p95 ms | max ms | people | edits counted |")
    print("|---|---|---|---|---|---|")
    for name, f in figures.items():
        print(f"| {name} | {f['p50_ms']:.0f} | {f['p95_ms']:.0f} | {f['max_ms']:.0f} | {f['people']:.0f} "
              f"| {f['edits']:.0f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
