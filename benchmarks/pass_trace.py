"""One pass of the one-key fixes on a detector set, traced fix by fix (``benchmarks/VOUCH.md``): which fix makes a
system wrong, and what the ball's evidence said before and after it.

For each set (the shared ``../shared/data/synthetic/detector`` ones, or one made by ``benchmarks/detector_sets.py``
under ``--made-dir``): the cached import of ``benchmarks/detector_fill.py`` (``--db-dir``), a copy recomputed by
this tree with the set's predictions imported (source ``detector``), served; then the pass exactly as
``../shared/tools/detector_fill_eval.py`` makes it (every label doubt's one-key fix once, ``near_duplicate_view``
aside, each placement confirmed as a person would), system by system, reading the system after each fix: the 3D
ball's distance to the truth and its tier (``ball_evidence``) before and after, beside the fix's doubt's evidence (its
code, score, agreeing views, the ball it places) to tabulate the fixes by it. Then, in process, ``v3d stats
yield`` of the copy after the pass (:func:`benchmarks.detector_fill.yield_figures`: the paper's rules and v3d's on the
same labels), and of a copy as imported with the predictions (before the pass).

A system is **made wrong** when its ball is more than 1 m off after the pass and was not before (the evaluator's
rule); each is printed with the fixes of its system (doubt kind, code, action, view) and the ball after each.

Run: ``.venv/bin/python benchmarks/pass_trace.py [--sets dev-large seed-204 seed-201-s1301 ...] [--json OUT]``.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any, Optional, Sequence

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.detector_fill import copy, paths, template, yield_figures  # noqa: E402  # after the path is set
from benchmarks.doubts_seeds import V3D, _run, served_with_admin  # noqa: E402  # after the path is set

RIGHT_M, WRONG_M = 0.5, 1.0


def _truth(path: Path) -> tuple[dict[tuple[str, str], list[float]], dict[tuple[str, str], str]]:
    truth = json.loads(path.read_text())
    balls = {(g["match"], s["action"]): s["ball_3d"] for g in truth["games"] for s in g["systems"]}
    corrupt = {(g["match"], s["action"]): s.get("corruption") or "" for g in truth["games"] for s in g["systems"]}
    return balls, corrupt


def _error(view: dict[str, Any], balls: dict[tuple[str, str], list[float]]) -> Optional[float]:
    b, t = view.get("ball3d"), balls.get((view["game"]["match"], view["name"]))
    if not b or t is None:
        return None
    return float(sum((x - y) ** 2 for x, y in zip(b, t, strict=True)) ** 0.5)


def _state(view: dict[str, Any], balls: dict[tuple[str, str], list[float]]) -> dict[str, Any]:
    return {"error_m": _error(view, balls), "tier": view.get("ball_evidence"),
            "reasons": view.get("ball_evidence_reasons"), "sigma_m": view.get("ball_sigma_m")}


def _apply(c: Any, d: dict[str, Any]) -> Optional[int]:
    """The fix of doubt ``d`` as the shared evaluator applies it, with the placement confirmed; its status (None:
    no fix to apply)."""
    sug, fid = d.get("suggestion") or {}, d.get("frame_id")
    if not d.get("accuses_label") or not sug.get("action") or not fid or d["kind"] == "near_duplicate_view":
        return None
    h = {"If-Match": c.get(f"/api/frames/{fid}").headers.get("etag")}
    req = sug.get("request")
    if req:
        r = c.request(req["method"], req["path"], json=req.get("body"), headers=h)
    elif sug["action"] == "snap_box" and sug.get("box"):
        r = c.patch(f"/api/frames/{fid}/ball", json={"box": sug["box"]}, headers=h)
    elif sug["action"] == "exclude_view":
        r = c.post(f"/api/frames/{fid}/exclusion", json={"excluded": True}, headers=h)
    elif sug["action"] == "mirror_labels":
        r = c.post(f"/api/frames/{fid}/field-lines/mirror", headers=h)
    else:
        return None
    fr = c.get(f"/api/frames/{fid}")
    ball = fr.json().get("ball") or {}
    if r.status_code < 300 and ball.get("box") and ball.get("provenance"):
        c.patch(f"/api/frames/{fid}/ball", json={"box": ball["box"]}, headers={"If-Match": fr.headers.get("etag")})
    return int(r.status_code)


def trace(base: str, token: str, truth: Path) -> dict[str, Any]:
    """The pass against the server at ``base`` (module docstring): per system its state before, each fix with the
    state after it, and the made-wrong systems."""
    import httpx

    balls, corrupt = _truth(truth)
    c = httpx.Client(base_url=base, timeout=300, headers={"Authorization": f"Bearer {token}"})
    ids: list[int] = []
    off = 0
    while True:
        page = c.get(f"/api/systems?limit=500&offset={off}").json()["items"]
        ids += [s["id"] for s in page]
        if len(page) < 500:
            break
        off += 500
    systems: list[dict[str, Any]] = []
    for sid in ids:
        view = c.get(f"/api/systems/{sid}").json()
        names = {v["frame_id"]: v.get("name") for v in view["views"]}
        rec: dict[str, Any] = {"id": sid, "match": view["game"]["match"], "name": view["name"],
                               "corruption": corrupt.get((view["game"]["match"], view["name"]), ""),
                               "views": len(view["views"]), "before": _state(view, balls), "fixes": []}
        for d in view.get("doubts", []):
            status = _apply(c, d)
            if status is None:
                continue
            after = c.get(f"/api/systems/{sid}").json()
            sug = d.get("suggestion") or {}
            rec["fixes"].append({"kind": d["kind"], "code": d.get("code"), "action": sug.get("action"),
                                 "view": names.get(d.get("frame_id")), "status": status,
                                 "message": d.get("message"), "evidence": d.get("evidence"),
                                 "after": _state(after, balls)})
        rec["after"] = rec["fixes"][-1]["after"] if rec["fixes"] else rec["before"]
        systems.append(rec)

    def wrong(e: Optional[float]) -> bool:
        return e is not None and e > WRONG_M

    made = [s for s in systems if wrong(s["after"]["error_m"]) and not wrong(s["before"]["error_m"])]
    mended = [s for s in systems if wrong(s["before"]["error_m"]) and not wrong(s["after"]["error_m"])]
    kinds: dict[str, int] = {}
    for s in systems:
        for f in s["fixes"]:
            key = f"{f['kind']}:{f['code']}:{f['action']}"
            kinds[key] = kinds.get(key, 0) + 1
    return {"systems": systems, "made_wrong": made, "made_right_from_wrong": mended, "fixes": kinds}


def tiers(systems: Sequence[dict[str, Any]], when: str) -> dict[str, list[int]]:
    """Per tier: balls right (within 0.5 m) / 0.5-1 m / wrong (beyond 1 m), ``when`` "before" or "after" the pass."""
    out: dict[str, list[int]] = {}
    for s in systems:
        st = s[when]
        e = st["error_m"]
        if e is None:
            continue
        row = out.setdefault(st["tier"] or "?", [0, 0, 0])
        row[0 if e <= RIGHT_M else 1 if e <= WRONG_M else 2] += 1
    return out


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sets", nargs="*", default=["dev-large", "seed-204"])
    ap.add_argument("--db-dir", type=Path, default=Path("/tmp/v3d-detector-fill"))
    ap.add_argument("--made-dir", type=Path, default=Path("/tmp/v3d-detector-sets"))
    ap.add_argument("--port", type=int, default=8820)
    ap.add_argument("--tag", default=ROOT.name, help="names the working copies (several trees share --db-dir)")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    report: dict[str, Any] = {}
    for i, name in enumerate(args.sets):
        tree, truth, pred = paths(name, args.made_dir)
        src = template(name, tree, args.db_dir)
        url = copy(src, f"{args.tag}-trace")
        _run(V3D + ["import", "predictions", str(pred), "--source", "detector"], url)
        res: dict[str, Any] = {"yield_imported": yield_figures(url, truth)}
        log = args.db_dir / f"{name}.{args.tag}-trace.server.log"
        with open(log, "w") as err, served_with_admin(url, args.port + i, {"V3D_KEEP_ALIVE_S": "600"}, err) as tok:
            res.update(trace(f"http://127.0.0.1:{args.port + i}", tok, truth))
        res["yield_after_pass"] = yield_figures(url, truth)
        res["tiers_before"], res["tiers_after"] = tiers(res["systems"], "before"), tiers(res["systems"], "after")
        y0, y1 = res["yield_imported"], res["yield_after_pass"]
        print(f"[{name}] as imported with predictions: v3d {y0['v3d']['right']} right / {y0['v3d']['wrong']} wrong, "
              f"paper {y0['paper']['right']} / {y0['paper']['wrong']}; after the pass: v3d {y1['v3d']['right']} / "
              f"{y1['v3d']['wrong']}, paper {y1['paper']['right']} / {y1['paper']['wrong']}; made wrong "
              f"{len(res['made_wrong'])}, wrong made right {len(res['made_right_from_wrong'])}; fixes "
              f"{json.dumps(res['fixes'])}", flush=True)
        print(f"[{name}] tiers before {json.dumps(res['tiers_before'])} after {json.dumps(res['tiers_after'])}",
              flush=True)
        for s in res["made_wrong"]:
            print(f"[{name}] MADE WRONG system {s['id']} {s['match']} {s['name']} ({s['views']} views, corruption "
                  f"{s['corruption']!r}) before {json.dumps(s['before'])}", flush=True)
            for f in s["fixes"]:
                print(f"    {f['kind']}:{f['code']} {f['action']} on {f['view']} ({f['status']}): "
                      f"{f['message']} -> {json.dumps(f['after'])}", flush=True)
        report[name] = res
    if args.json:
        args.json.write_text(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
