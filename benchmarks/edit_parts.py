"""Where a ball edit's CPU goes, part by part, in process: one annotator's ball edits of the demo's 4-view system (the
service's ``update_ball_label``, the system page its answer draws and the answer's shaping, ``SystemView.of`` and its
JSON, as a served edit runs them minus HTTP), each part's CPU (``time.thread_time``) summed over the edits by a
wrapper put where the part is held (its module and every module that imported it by name); a part nested in another
counts in both. Prints ms per edit of each run and their median. Not paired: compare two checkouts by
``benchmarks/edit_against.py``.

Usage (from the checkout)::

    .venv/bin/python benchmarks/edit_parts.py --edits 100 --runs 3
"""
from __future__ import annotations

import argparse
import functools
import importlib
import statistics
import sys
import time
from typing import Any, Callable

sys.path.insert(0, ".")

#: ``(module, function)`` of the parts, in the order printed.
PARTS = [
    ("app.services.curation.editing", "update_ball_label"),
    ("app.services.curation.writing", "frame_facts"),
    ("app.services.curation.writing", "_read"),
    ("app.services.derivation.loading", "load_systems"),
    ("app.services.derivation.loading", "load_view_players"),
    ("app.services.derivation.recompute", "system_rig_rows"),
    ("app.services.curation.writing", "_compute"),
    ("app.services.derivation.recompute", "recompute_system"),
    ("app.services.derivation.recompute", "_update_mirror_flags"),
    ("app.services.derivation.doubts", "weighed_views"),
    ("app.services.derivation.ball", "system_ball"),
    ("app.geometry.triangulation", "triangulate_ball"),
    ("app.geometry.evidence", "judge_by_evidence"),
    ("app.services.derivation.doubts", "stored_detections"),
    ("app.services.derivation.doubts", "update_doubts"),
    ("app.services.derivation.doubts", "update_label_distances"),
    ("app.services.derivation.ball", "ball_facts"),
    ("app.services.derivation.recompute", "update_summary"),
    ("app.services.curation.resets", "reset_after_change"),
    ("app.services.curation.writing", "_lock_and_compare"),
    ("app.services.curation.writing", "_write"),
    ("app.services.audit.log", "record"),
    ("app.services.curation.system_page", "system_page"),
    ("app.services.curation.queue", "queue_neighbours"),
    ("app.services.curation.presence", "open_on"),
]


def timed(key: str, fn: Callable[..., Any], acc: dict[str, float]) -> Callable[..., Any]:
    """``fn`` adding its CPU time to ``acc[key]`` on every call."""
    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        t0 = time.thread_time()
        try:
            return fn(*args, **kwargs)
        finally:
            acc[key] += time.thread_time() - t0
    return wrapper


def wrap_parts(acc: dict[str, float]) -> None:
    """Every part of :data:`PARTS` and ``Session.flush`` / ``Session.commit`` timed into ``acc``."""
    from sqlalchemy.orm import Session

    importlib.import_module("app.main")  # every module that holds a part by name is imported first
    for modname, name in PARTS:
        original = getattr(importlib.import_module(modname), name)
        key = f"{modname.rsplit('.', 1)[1]}.{name}"
        acc[key] = 0.0
        wrapper = timed(key, original, acc)
        for holder in list(sys.modules.values()):
            if holder is not None and getattr(holder, "__dict__", {}).get(name) is original:
                setattr(holder, name, wrapper)
    for meth in ("flush", "commit"):
        acc[f"Session.{meth}"] = 0.0
        setattr(Session, meth, timed(f"Session.{meth}", getattr(Session, meth), acc))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--edits", type=int, default=100, help="edits per run")
    ap.add_argument("--runs", type=int, default=3)
    args = ap.parse_args()

    from app.api.view_schemas import SystemView
    from app.services.curation import editing, system_page
    from benchmarks.load import demo_ball_edit

    acc: dict[str, float] = {}
    wrap_parts(acc)
    acc["answer (SystemView.of and its JSON)"] = acc["in all"] = 0.0
    with demo_ball_edit() as (settings, factory, fid, sid, box):
        step = [0]

        def edit() -> None:
            step[0] += 1
            dx = 2.0 + (step[0] % 2)  # every edit changes the label
            t0 = time.thread_time()
            with factory() as s:
                editing.update_ball_label(s, fid, box=[box[0] + dx, box[1], box[2] + dx, box[3]], settings=settings)
                page = system_page.system_page(s, sid)
                t1 = time.thread_time()
                view = SystemView.of(page)
                view.__pydantic_serializer__.to_json(view, by_alias=True)
                acc["answer (SystemView.of and its JSON)"] += time.thread_time() - t1
            acc["in all"] += time.thread_time() - t0

        for _ in range(20):  # warm
            edit()
        runs = []
        for _ in range(args.runs):
            for k in acc:
                acc[k] = 0.0
            for _ in range(args.edits):
                edit()
            runs.append({k: v * 1000 / args.edits for k, v in acc.items()})
    print(f"{'part (CPU ms an edit)':45s} " + " ".join(f"run {i + 1:<2d}" for i in range(args.runs)) + "  median")
    for k in acc:
        values = [r[k] for r in runs]
        print(f"{k:45s} " + " ".join(f"{v:6.2f}" for v in values) + f"  {statistics.median(values):6.2f}")


if __name__ == "__main__":
    main()
