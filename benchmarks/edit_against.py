"""This checkout's versions of some modules against another checkout's, in one process: the CPU of a ball edit, paired,
and whether every derived row stays the same.

``--against DIR`` names a checkout of other code (``git archive REV | tar -x -C DIR``) and ``--modules`` the modules
whose functions differ (e.g. ``app.geometry.spread,app.services.derivation.ball``). Each of those modules is loaded
again from DIR under another name; the "against" state puts its functions (and its classes' methods) where this
checkout's are: in their module and in every module that imported them by name. Nothing else changes, so the two
states differ by those functions only (their modules' other code, the database and the data are this checkout's).

* Timing (default): one annotator's ball edits of the demo's 4-view system (the service's ``update_ball_label`` and
  the system page its answer draws, as ``benchmarks/edit_mechanisms.py`` runs them), ``--pairs`` pairs of blocks of
  ``--edits`` edits, the two states in a random order in each pair; the figure is the median over pairs of the
  difference of CPU (``time.thread_time``) per edit, with its quartiles: a slow phase of the machine falls on both
  blocks of a pair.
* ``--same SET ...``: each shared set (``dev``, ``dev-large``, ``det-dev-large`` and ``det-seed-204`` with their
  detector's predictions, ``seed-201``) imported by this checkout into a fresh SQLite file, then every system
  recomputed in the against state, in this checkout's, and in the against state again (each with fresh pair memos);
  every derived value (each view's calibration, reprojection and optimised box, the triangulation, pairs, doubts and
  the system's row, time stamps and ids aside) compared for equality. Prints the systems that differ.

Usage (from the checkout)::

    .venv/bin/python benchmarks/edit_against.py --against /tmp/base --modules app.geometry.spread --pairs 200
    .venv/bin/python benchmarks/edit_against.py --against /tmp/base --modules app.geometry.spread --same dev seed-201
"""
from __future__ import annotations

import argparse
import contextlib
import importlib
import importlib.util
import random
import statistics
import sys
import tempfile
import time
import types
from collections.abc import Iterator
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

SETS = {"dev": ("soccernet-v3-dev", None), "dev-large": ("soccernet-v3-dev-large", None),
        "det-dev-large": ("detector/dev-large-unlabelled", "detector/dev-large-predictions.csv"),
        "det-seed-204": ("detector/seed-204-unlabelled", "detector/seed-204-predictions.csv"),
        "seed-201": ("doubts-seeds/seed-201", None)}


def swaps_of(against: Path, modules: list[str]) -> list[tuple[Any, str, Any, Any]]:
    """``(holder, name, theirs, ours)`` for every function of ``modules`` whose code differs in ``against``'s version
    (and every method of their classes that does), each where it is held: its module, every module that imported it
    by name (the against modules included), or its class.

    Raises:
        ImportError: a module missing from either checkout.
    """
    # every module that may hold one of them by name is imported first (the server's, the import's): a module
    # imported later would hold this checkout's functions in both states
    for holder in ("app.main", "app.services.curation.editing", "app.services.curation.system_page",
                   "app.services.transfer.importing", "app.services.transfer.predictions"):
        importlib.import_module(holder)
    loaded = []
    for name in modules:
        ours = importlib.import_module(name)
        spec = importlib.util.spec_from_file_location(f"against_{name.replace('.', '_')}",
                                                      against / (name.replace(".", "/") + ".py"))
        if spec is None or spec.loader is None:
            raise ImportError(f"{name} not found in {against}")
        theirs = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = theirs  # dataclasses look their module up while the class is made
        spec.loader.exec_module(theirs)
        loaded.append((name, ours, theirs))
    out: list[tuple[Any, str, Any, Any]] = []
    for name, ours, theirs in loaded:
        for key, obj in vars(ours).items():
            if not isinstance(obj, (types.FunctionType, type)) or obj.__module__ != name:
                continue
            other = getattr(theirs, key, None)
            if other is None:
                continue
            if isinstance(obj, type):
                for attr, fn in vars(obj).items():
                    old = vars(other).get(attr)
                    if isinstance(fn, types.FunctionType) and isinstance(old, types.FunctionType) \
                            and old.__code__.co_code != fn.__code__.co_code:
                        out.append((obj, attr, old, fn))
                continue
            if other.__code__.co_code == obj.__code__.co_code and other.__code__.co_consts == obj.__code__.co_consts:
                continue
            out += [(holder, key, other, obj) for holder in list(sys.modules.values())
                    if holder is not None and getattr(holder, key, None) is obj]
    return out


@contextlib.contextmanager
def against_state(swaps: list[tuple[Any, str, Any, Any]]) -> Iterator[None]:
    """The against checkout's functions in place for the block."""
    for holder, key, theirs, _ in swaps:
        setattr(holder, key, theirs)
    try:
        yield
    finally:
        for holder, key, _, ours in swaps:
            setattr(holder, key, ours)


def timing(swaps: list[tuple[Any, str, Any, Any]], pairs: int, edits: int, seed: int) -> dict[str, float]:
    """Median CPU ms per ball edit of each state and the median and quartiles of their paired difference (this
    checkout's less the against one's)."""

    from app.services.curation import editing, system_page
    from benchmarks.load import demo_ball_edit

    with demo_ball_edit() as (settings, factory, fid, sid, box):
        step = [0]

        def edit() -> None:
            step[0] += 1
            dx = 2.0 + (step[0] % 2)  # every edit changes the label
            with factory() as s:
                editing.update_ball_label(s, fid, box=[box[0] + dx, box[1], box[2] + dx, box[3]], settings=settings)
                system_page.system_page(s, sid)

        for _ in range(3):  # warm both states
            edit()
            with against_state(swaps):
                edit()
        rng = random.Random(seed)
        per: dict[str, list[float]] = {"against": [], "this": []}
        diffs = []
        for _ in range(pairs):
            got = {}
            for state in rng.sample(["against", "this"], 2):
                with against_state(swaps) if state == "against" else contextlib.nullcontext():
                    t0 = time.thread_time()
                    for _ in range(edits):
                        edit()
                    got[state] = (time.thread_time() - t0) * 1000 / edits
                per[state].append(got[state])
            diffs.append(got["this"] - got["against"])
    q = statistics.quantiles(diffs, n=4)
    return {"against_ms": statistics.median(per["against"]), "this_ms": statistics.median(per["this"]),
            "difference_ms": statistics.median(diffs), "q1_ms": q[0], "q3_ms": q[2]}


def _values(row: Any) -> dict[str, Any] | None:
    import sqlalchemy as sa

    if row is None:
        return None
    skip = {"id", "system_id", "frame_id", "computed_at", "updated_at"}
    return {a.key: getattr(row, a.key) for a in sa.inspect(type(row)).column_attrs if a.key not in skip}


def _derived(system: Any) -> tuple:
    frames = {f.id: [_values(f.calibration), _values(f.reprojection), _values(f.optimised_box)] for f in system.frames}
    tri = system.triangulation
    return (frames, _values(tri), [_values(p) for p in tri.pairs] if tri is not None else [],
            [_values(d) for d in system.doubts], _values(system))


def same(swaps: list[tuple[Any, str, Any, Any]], sets: list[str], shared: Path) -> dict[str, list[int]]:
    """Per set, the ids of the systems whose derived values differ between the states (module docstring); a set whose
    against state gives two answers raises.

    Raises:
        RuntimeError: the against state not deterministic on a set.
    """
    import sqlalchemy as sa

    from app.core.config import Settings
    from app.db.models import System
    from app.db.session import make_engine, make_session_factory, upgrade_database
    from app.geometry.triangulation import PairGeometryMemo
    from app.services.derivation import cameras, recompute
    from app.services.transfer.importing import import_soccernet_v3
    from app.services.transfer.predictions import import_predictions

    def recomputed(session: Any, ids: list[int], settings: Settings) -> dict[int, tuple]:
        cameras.PAIR_GEOMETRY = PairGeometryMemo(max_entries=cameras.PAIRS)
        cameras.PAIR_PLAYERS = cameras.PairPlayersMemo(max_entries=cameras.PAIRS)
        out = {}
        with session.no_autoflush:
            # through the module: its functions are the ones the state put there
            systems = recompute.load_for_recompute(session, ids, predictions=settings.max_predictions_per_frame)
            for sid in ids:
                recompute.recompute_system(session, systems[sid], settings)
                out[sid] = _derived(systems[sid])
        session.rollback()
        session.expunge_all()
        return out

    differing = {}
    for name in sets:
        tree, predictions = SETS[name]
        with tempfile.TemporaryDirectory(prefix="v3d-against-") as tmp:
            url = f"sqlite:///{Path(tmp) / 'set.sqlite3'}"
            upgrade_database(url)
            engine = make_engine(url)
            settings = Settings(_env_file=None, database_url=url, calibration_workers=1)
            with make_session_factory(engine)() as session:
                import_soccernet_v3(session, shared / "data/synthetic" / tree, settings)
                if predictions:
                    import_predictions(session, shared / "data/synthetic" / predictions, settings)
                ids = list(session.scalars(sa.select(System.id).order_by(System.id)))
                with against_state(swaps):
                    theirs = recomputed(session, ids, settings)
                ours = recomputed(session, ids, settings)
                with against_state(swaps):
                    if recomputed(session, ids, settings) != theirs:
                        raise RuntimeError(f"{name}: the against state gives two answers")
            engine.dispose()
        differing[name] = [i for i in ids if ours[i] != theirs[i]]
        print(f"{name}: {len(ids)} systems, {len(differing[name])} differ {differing[name][:20]}", flush=True)
    return differing


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--against", type=Path, required=True, help="a checkout of the other code")
    ap.add_argument("--modules", required=True, help="comma-separated modules whose functions to swap")
    ap.add_argument("--pairs", type=int, default=200)
    ap.add_argument("--edits", type=int, default=2, help="edits per block")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--same", nargs="*", choices=list(SETS), help="compare the derived rows of these sets instead")
    ap.add_argument("--shared", type=Path, default=ROOT.parent / "shared")
    args = ap.parse_args(argv)
    swaps = swaps_of(args.against.resolve(), args.modules.split(","))
    print("swapped:", ", ".join(sorted({f"{getattr(h, '__name__', h)}.{k}" for h, k, _, _ in swaps
                                        if not getattr(h, "__name__", "").startswith("against_")})))
    if args.same is not None:
        differing = same(swaps, args.same or list(SETS), args.shared)
        return 1 if any(differing.values()) else 0
    r = timing(swaps, args.pairs, args.edits, args.seed)
    print(f"CPU ms per ball edit: against {r['against_ms']:.2f}, this {r['this_ms']:.2f}; paired difference (this - "
          f"against) median {r['difference_ms']:+.3f} ms, quartiles {r['q1_ms']:+.2f} / {r['q3_ms']:+.2f} "
          f"({args.pairs} pairs of {args.edits} edits)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
