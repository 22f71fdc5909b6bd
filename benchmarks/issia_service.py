"""ISSIA-3D through the service: import the dev sequence, then score the **stored** values against the truth.

Usage: ``python -m benchmarks.issia_service [--data DIR] [--truth FILE] [--json OUT] [--edits N] [--modes json,lines]
[--gc-threshold N]``

Both modes (``issia_calibration.json``; ``issia_lines.json`` alone), each into a fresh SQLite file:
``v3d import issia`` (``app.services.issia.sequences.import_issia``), then the figures of issue 9 from the
stored ``TrajectoryPoint`` rows (``ball_3D``, ``ball_3D_smoothed``, ``cam_list``): the same
definitions as :mod:`benchmarks.issia` (which scores the pure fit). Also times the import and one
edit's round trip (a label moved and back, each re-fitted and committed).

``--edits N`` (default 6) then measures the **HTTP** edit round trip on the imported sequence
(``create_app`` + ``TestClient``: the request, the edit, the re-fit, the recomputation, the commit and
the system view answered): at N frames spread over the sequence a point moved by 3 px and back, the
point turned into a box, the box moved by 3 px and back to the point, the label removed and restored,
the view excluded and restored; then field lines shifted by 2 px and back, of a view in the middle (its
camera is not the one the sequence uses: nothing to re-fit) and of the first frame's view (it gives the
sequence its camera: the whole sequence is fitted again). Prints p50/p95 (wall and process CPU time)
per kind and over all ball/exclusion edits, the time per stage (the functions listed in
:data:`STAGES`, wall time summed per request, nested stages included in their parent; mean and median
over the requests that ran it), the full garbage collections that fell in the ball/exclusion edits
(their wall ms: a pause of the whole process, not of one stage) and the load average around them,
and whether the undone edits left the issue's figures as imported.
"""
from __future__ import annotations

import argparse
import gc
import json
import os
import tempfile
import time
from pathlib import Path

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session

from benchmarks.issia import SHARED

#: Stages of an edit's round trip timed by :func:`http_edits`: (label, module, function). A function
#: that does not exist (another version of the code) is skipped.
STAGES = (
    ("recompute edited frame (lines)", "app.services.curation.editing", "recompute_frame"),
    ("refit_sequence", "app.services.issia.sequences", "refit_sequence"),
    ("  stored pieces (DB)", "app.services.issia.refit", "_pieces_around"),
    ("  cameras (DB)", "app.services.issia.refit", "sequence_columns"),
    ("  window (DB)", "app.services.issia.refit", "_load_window"),
    ("  refit_window", "app.services.issia.refit", "refit_window"),
    ("    local re-fit (fast path)", "app.geometry.trajectory", "_refit_local"),
    ("      break's candidate cuts", "app.geometry.trajectory", "_shift_bounds"),
    ("    _segment", "app.geometry.trajectory", "_segment"),
    ("    _assemble", "app.geometry.trajectory", "_assemble"),
    ("    triangulate_frame", "app.geometry.trajectory", "triangulate_frame"),
    ("  store changed rows", "app.services.issia.refit", "_store_rows"),
    ("    rows that changed", "app.services.issia.refit", "_changed_rows"),
    ("    UPDATEs", "app.services.issia.refit", "_write_rows"),
    ("    systems to recompute loaded", "app.services.issia.refit", "load_for_recompute"),
    ("    moved trajectory doubts", "app.services.issia.refit", "_refresh_trajectory_doubts"),
    ("whole fit (camera changed)", "app.services.issia.sequences", "fit_sequence"),
    ("recompute systems", "app.services.issia.sequences", "recompute_system"),
    ("recompute non-ISSIA", "app.services.curation.editing", "recompute_system"),
    ("update_doubts (moved)", "app.services.issia.sequences", "update_doubts"),
    ("commit", "sqlalchemy.orm", "Session.commit"),
    ("system view (answer)", "app.api.view_schemas", "SystemView.of"),
)


class StageTimer:
    """Wraps the functions of :data:`STAGES` to sum their wall time per request (restored by :meth:`close`)."""

    def __init__(self, stages=STAGES):
        import importlib

        self.totals: dict[str, float] = {}
        self._undo = []
        for label, module, name in stages:
            owner = importlib.import_module(module)
            *path, attr = name.split(".")
            for part in path:
                owner = getattr(owner, part)
            fn = getattr(owner, attr, None)
            if fn is None:
                continue
            self._undo.append((owner, attr, fn))
            setattr(owner, attr, self._wrap(label, fn))

    def _wrap(self, label, fn):
        import functools

        @functools.wraps(fn)
        def timed(*args, **kwargs):
            t0 = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                self.totals[label] = self.totals.get(label, 0.0) + time.perf_counter() - t0
        return timed

    def take(self) -> dict[str, float]:
        out, self.totals = self.totals, {}
        return out

    def close(self) -> None:
        for owner, attr, fn in reversed(self._undo):
            setattr(owner, attr, fn)


def _pct(values, q):
    return float(np.percentile(np.asarray(values) * 1000.0, q)) if values else float("nan")


def http_edits(url: str, game_id: int, edits: int, lines_edits: int = 1, after_ball_edits=None, after_line_edits=None,
               gc_threshold: int | None = None) -> dict:
    """The HTTP edit round trip on the imported sequence (module docstring): p50/p95 ms per kind, all
    ball/exclusion edits together, and per stage the mean ms over the requests that ran it (and how
    many did). ``after_ball_edits()`` is called between the ball/exclusion edits (each undone) and the field-line edits;
    its answer is returned as ``"after_ball_edits"``; ``after_line_edits()`` after the field-line edits (each undone),
    returned as ``"after_line_edits"``. ``gc_threshold``: the garbage collector's young-generation threshold during
    the requests (``gc.set_threshold(gc_threshold, 10, 10)``, restored after; None: Python's default, 700), to
    measure what a server process configured so would answer."""
    from fastapi.testclient import TestClient

    from app.core.config import Settings
    from app.main import create_app
    from app.services.accounts.users import create_user
    from app.services.issia.trajectory import load_sequence

    settings = Settings(database_url=url)
    app = create_app(settings)
    with app.state.session_factory() as session:  # the edits are an annotator's, sent with its API token
        _, token = create_user(session, "benchmark-annotator", "annotator", "benchmark password")
        systems = [s for s in load_sequence(session, game_id)]
        n = len(systems)
        picks = []
        for s in systems[n // (2 * edits)::max(n // edits, 1)][:edits]:
            f = next((f for f in s.frames if f.ball_label is not None and f.ball_label.point is not None), None)
            if f is not None:
                picks.append((f.id, list(f.ball_label.point), f.width, f.height))
        lines = {}
        for label, s in (("field lines (a later view)", systems[n // 2]),
                         ("field lines (the camera's view)", systems[0])):
            f = next((f for f in s.frames if f.field_lines is not None and f.field_lines.lines), None)
            if f is not None:
                lines[label] = (f.id, f.field_lines.lines)
    times: dict[str, list[float]] = {}
    cpu: dict[str, list[float]] = {}  # process CPU time of each request (a loaded machine inflates wall time)
    stages: dict[str, list[float]] = {}
    timer = StageTimer()
    full_gc: list[float] = []  # wall ms of each full (generation 2) garbage collection during the requests
    gc_started = [0.0]

    def on_gc(phase, info):
        if info.get("generation") != 2:
            return
        if phase == "start":
            gc_started[0] = time.perf_counter()
        else:
            full_gc.append((time.perf_counter() - gc_started[0]) * 1000.0)

    etags: dict[int, str] = {}  # each frame's current ETag: a token's write names the version it was made against

    def call(kind, method, path, body):
        fid = int(path.split("/")[3])  # /api/frames/{id}/...
        if fid not in etags:
            etags[fid] = client.get(f"/api/frames/{fid}").headers["etag"]
        timer.take()
        t0, c0 = time.perf_counter(), time.process_time()
        r = client.request(method, path, json=body, headers={"If-Match": etags[fid]})
        dt = time.perf_counter() - t0
        cpu.setdefault(kind, []).append(time.process_time() - c0)
        if r.status_code != 200:
            raise RuntimeError(f"{method} {path}: {r.status_code} {r.text[:300]}")
        times.setdefault(kind, []).append(dt)
        etags[fid] = r.headers["etag"]
        for k, v in timer.take().items():
            stages.setdefault(k, []).append(v)
        stages.setdefault("(requests)", []).append(dt)

    load_before = os.getloadavg()[0]
    gc.callbacks.append(on_gc)
    thresholds = gc.get_threshold()
    if gc_threshold is not None:
        gc.set_threshold(gc_threshold, 10, 10)
    try:
        with TestClient(app, base_url="http://127.0.0.1", headers={"Authorization": f"Bearer {token}"}) as client:
            for fid, (x, y), w, _h in picks:
                x2 = x + 3.0 if x + 3.0 < w else x - 3.0
                box = [x - 6.0, y - 6.0, x + 6.0, y + 6.0]
                moved = [box[0] + 3.0, box[1], box[2] + 3.0, box[3]]
                call("point moved", "PATCH", f"/api/frames/{fid}/ball", {"point": [x2, y]})
                call("point moved", "PATCH", f"/api/frames/{fid}/ball", {"point": [x, y]})
                call("box", "PATCH", f"/api/frames/{fid}/ball", {"box": box})
                call("box", "PATCH", f"/api/frames/{fid}/ball", {"box": moved})
                call("box", "PATCH", f"/api/frames/{fid}/ball", {"point": [x, y]})
                call("label removed/restored", "PATCH", f"/api/frames/{fid}/ball", {"point": None})
                call("label removed/restored", "PATCH", f"/api/frames/{fid}/ball", {"point": [x, y]})
                call("exclusion", "POST", f"/api/frames/{fid}/exclusion", {"excluded": True})
                call("exclusion", "POST", f"/api/frames/{fid}/exclusion", {"excluded": False})
            ball = [t for v in times.values() for t in v]
            ball_stages = {f"{k} ({len(v)} requests)": float(np.mean(v)) * 1000.0 for k, v in stages.items()}
            ball_stage_medians = {f"{k} ({len(v)} requests)": float(np.median(v)) * 1000.0 for k, v in stages.items()}
            ball_gc, load_after = list(full_gc), os.getloadavg()[0]
            stages.clear()
            checked = after_ball_edits() if after_ball_edits is not None else None
            for label, (fid, original) in lines.items():
                shifted = {c: [[[p[0] + 2.0, p[1]] for p in poly] for poly in polys] for c, polys in original.items()}
                for _ in range(lines_edits):
                    call(label, "PUT", f"/api/frames/{fid}/field-lines", {"lines": shifted})
                    call(label, "PUT", f"/api/frames/{fid}/field-lines", {"lines": original})
            checked_lines = after_line_edits() if after_line_edits is not None else None
    finally:
        gc.set_threshold(*thresholds)
        gc.callbacks.remove(on_gc)
        timer.close()
    out = {kind: {"n": len(v), "p50_ms": _pct(v, 50), "p95_ms": _pct(v, 95), "cpu_p50_ms": _pct(cpu[kind], 50),
                  "cpu_p95_ms": _pct(cpu[kind], 95)} for kind, v in times.items()}
    ball_cpu = [t for k, v in cpu.items() if not k.startswith("field lines") for t in v]
    out["all ball/exclusion edits"] = {"n": len(ball), "p50_ms": _pct(ball, 50), "p95_ms": _pct(ball, 95),
                                       "cpu_p50_ms": _pct(ball_cpu, 50), "cpu_p95_ms": _pct(ball_cpu, 95)}
    out["stages_mean_ms (ball/exclusion edits)"] = ball_stages
    out["stages_median_ms (ball/exclusion edits)"] = ball_stage_medians
    out["full_gc_ms (ball/exclusion edits)"] = [round(v, 1) for v in ball_gc]
    out["load_average (before, after the ball/exclusion edits)"] = [load_before, load_after]
    if stages:
        out["stages_mean_ms (field lines)"] = {f"{k} ({len(v)} requests)": float(np.mean(v)) * 1000.0
                                               for k, v in stages.items()}
    out["after_ball_edits"] = checked
    out["after_line_edits"] = checked_lines
    return out


def service_figures(session: Session, game_id: int, truth: dict) -> dict:
    """Figures of the stored sequence ``game_id`` against ``truth`` (issia-dev.truth.json)."""
    from app.services.issia.trajectory import load_sequence

    systems = {s.frame_index: s for s in load_sequence(session, game_id)}
    good2, seen, e3, es = [], [], [], []
    n_out = out_kept = n_ok = ok_kept = 0
    for fr in truth["frames"]:
        s = systems.get(fr["frame"])
        if s is None:
            continue
        tp = s.trajectory_point
        ids = {f.name: f.id for f in s.frames}
        true = np.asarray(fr["ball_3d"], float)
        ok = [ids[f"cam{c}"] for c, v in fr["cams"].items() if v["annotated"] and not v["outlier"]]
        bad = [ids[f"cam{c}"] for c, v in fr["cams"].items() if v["annotated"] and v["outlier"]]
        kept = set(tp.cam_list or []) if tp is not None else set()
        if len(ok) >= 2:
            good2.append(fr["frame"])
            e3.append(np.nan if tp is None or tp.ball3d is None
                      else float(np.linalg.norm(np.asarray(tp.ball3d) - true)))
        if any(v["in_image"] for v in fr["cams"].values()):
            seen.append(fr["frame"])
            es.append(np.nan if tp is None or tp.ball3d_smoothed is None
                      else float(np.linalg.norm(np.asarray(tp.ball3d_smoothed) - true)))
        n_out += len(bad)
        out_kept += sum(i in kept for i in bad)
        n_ok += len(ok)
        ok_kept += sum(i in kept for i in ok)
    e3a, esa = np.array(e3), np.array(es)
    return {
        "frames_two_correct_labels": len(good2),
        "ball_3D_coverage": float(np.mean(np.isfinite(e3a))) if len(e3a) else None,
        "ball_3D_median_error_m": float(np.nanmedian(e3a)) if np.isfinite(e3a).any() else None,
        "frames_ball_in_an_image": len(seen),
        "smoothed_coverage": float(np.mean(np.isfinite(esa))) if len(esa) else None,
        "smoothed_median_error_m": float(np.nanmedian(esa)) if np.isfinite(esa).any() else None,
        "outlier_labels": n_out, "outliers_in_cam_list": out_kept,
        "correct_labels": n_ok, "correct_kept_share": ok_kept / n_ok if n_ok else None,
    }


def run(data: Path, truth: dict, from_lines: bool, workdir: Path, edits: int = 0,
        gc_threshold: int | None = None) -> dict:
    """Import ``data`` into a fresh database in one mode; figures, import and edit timings."""
    from app.core.config import Settings
    from app.db.models import Game, System
    from app.db.session import make_engine, make_session_factory, upgrade_database
    from app.services.curation.editing import update_ball_label
    from app.services.issia.sequences import import_issia

    url = f"sqlite:///{workdir / ('lines' if from_lines else 'json')}.sqlite3"
    upgrade_database(url)
    engine = make_engine(url)
    session = make_session_factory(engine)()
    settings = Settings(database_url=url)
    t0 = time.perf_counter()
    report = import_issia(session, data, settings, from_lines=from_lines)
    t_import = time.perf_counter() - t0
    game = session.scalars(sa.select(Game)).one()
    figures = service_figures(session, game.id, truth)
    mid = session.scalars(sa.select(System).where(System.game_id == game.id)
                          .order_by(System.frame_index).offset(report.systems // 2).limit(1)).one()
    frame = next(f for f in mid.frames if f.ball_label is not None and f.ball_label.point is not None)
    p = list(frame.ball_label.point)
    t1 = time.perf_counter()
    update_ball_label(session, frame.id, point=[p[0] + 3.0, p[1]], settings=settings)
    t_edit = time.perf_counter() - t1
    update_ball_label(session, frame.id, point=p, settings=settings)
    game_id = game.id
    session.close()
    engine.dispose()
    out = {"mode": "lines" if from_lines else "calibration_json", **figures, "import_s": t_import,
           "edit_round_trip_s": t_edit, "cameras_calibrated": report.calibrated}
    if edits:
        def same_figures() -> bool:  # the ball/exclusion edits, each undone, leave the figures as imported
            eng = make_engine(url)  # (within 1e-6: a re-fit's refinement starts from the edited piece)
            with make_session_factory(eng)() as s:
                now = service_figures(s, game_id, truth)
            eng.dispose()
            return all(now[k] == v or (isinstance(v, float) and abs(now[k] - v) < 1e-6) for k, v in figures.items())

        def figures_now() -> dict:  # the figures after the field-line edits, each undone
            eng = make_engine(url)
            with make_session_factory(eng)() as s:
                now = service_figures(s, game_id, truth)
            eng.dispose()
            return {k: now[k] for k in ("ball_3D_median_error_m", "smoothed_median_error_m")}

        out["http_edits"] = http_edits(url, game_id, edits, after_ball_edits=same_figures, after_line_edits=figures_now,
                                       gc_threshold=gc_threshold)
        out["figures_equal_after_undone_edits"] = out["http_edits"].pop("after_ball_edits")
        out["figures_after_undone_line_edits"] = out["http_edits"].pop("after_line_edits")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=SHARED / "issia-dev")
    ap.add_argument("--truth", type=Path, default=SHARED / "issia-dev.truth.json")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--edits", type=int, default=6, help="frames edited through HTTP (0: none)")
    ap.add_argument("--modes", default="json,lines", help="json, lines or both (comma-separated)")
    ap.add_argument("--gc-threshold", type=int, help="young-generation GC threshold during the HTTP edits "
                    "(default: Python's, 700; the README reports 20000 beside it)")
    args = ap.parse_args(argv)
    truth = json.loads(args.truth.read_text())
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        modes = [m.strip() for m in args.modes.split(",")]
        for from_lines in [m == "lines" for m in ("json", "lines") if m in modes]:
            r = run(args.data, truth, from_lines, Path(tmp), args.edits, args.gc_threshold)
            results.append(r)
            print(f"== {r['mode']} ==")
            for k, v in r.items():
                if k != "http_edits":
                    print(f"  {k}: {v}")
            for kind, v in r.get("http_edits", {}).items():
                if v is None:
                    continue
                if isinstance(v, list):
                    print(f"  {kind}: {v}")
                elif "p50_ms" in v:
                    print(f"  HTTP {kind}: n={v['n']} p50 {v['p50_ms']:.1f} ms, p95 {v['p95_ms']:.1f} ms "
                          f"(CPU p50 {v['cpu_p50_ms']:.1f} ms, p95 {v['cpu_p95_ms']:.1f} ms)")
                else:
                    print(f"  {kind}:")
                    for stage, ms in v.items():
                        print(f"    {stage:48s} {ms:8.1f}")
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
