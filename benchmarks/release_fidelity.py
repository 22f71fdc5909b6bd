"""Exports that lose nothing (issue 19): SoccerNet-v3 trees imported into a fresh SQLite file, exported as
SoccerNet-v3D (``--all``, no images), and every field of every imported ``Labels-v3.json`` looked up in the
export's ``Labels-v3D.json`` (a field: a leaf of the JSON document, found by its path of keys and list indices);
each export is then read the way SoccerNet-v3's devkit reads a ``Labels-v3.json`` (:func:`devkit_read`).

Nothing is edited here, so every imported field must be in the export with its value (the curated lines and ball
box are the imported ones); edits are the round trip's business (``tests/services/transfer/test_exporting.py``).

Run: ``.venv/bin/python benchmarks/release_fidelity.py TREE [TREE ...] [--json OUT]`` (default: the synthetic
SoccerNet-v3 dev sets and the doubts seeds under ``../shared``). Prints per tree the games, frames, fields
imported, fields missing and fields changed in the export, and the boxes the devkit-style reader read.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path
from typing import Any, Iterator

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from app.geometry.pitch import LINE_CLASSES

#: The classes SoccerNet-v3's devkit maps to ids (``FRAME_CLASS_DICTIONARY``): the ball, people, line classes.
DEVKIT_CLASSES: dict[str, int] = {c: i for i, c in enumerate((
    "Ball", "Player team left", "Player team right", "Goalkeeper team left", "Goalkeeper team right",
    "Main referee", "Side referee", "Staff members", "Player team unknown 1", "Player team unknown 2",
    "Goalkeeper team unknown", *LINE_CLASSES))}


def leaf_fields(doc: Any, path: tuple = ()) -> Iterator[tuple[tuple, Any]]:
    """Every field of a JSON document: ``(path, value)`` of each leaf (a scalar, or an empty object or list), the
    path a tuple of object keys and list indices."""
    if isinstance(doc, dict) and doc:
        for k, v in doc.items():
            yield from leaf_fields(v, (*path, k))
    elif isinstance(doc, list) and doc:
        for i, v in enumerate(doc):
            yield from leaf_fields(v, (*path, i))
    else:
        yield path, doc


def _lookup(doc: Any, path: tuple) -> tuple[bool, Any]:
    for key in path:
        if isinstance(doc, dict) and isinstance(key, str) and key in doc:
            doc = doc[key]
        elif isinstance(doc, list) and isinstance(key, int) and key < len(doc):
            doc = doc[key]
        else:
            return False, None
    return True, doc


def lost_fields(imported: Any, exported: Any) -> tuple[list[tuple], list[tuple]]:
    """``(missing, changed)``: the paths of the fields of ``imported`` that ``exported`` lacks, and of those it holds
    with another value (numbers compared by value: ``617`` equals ``617.0``)."""
    missing, changed = [], []
    for path, value in leaf_fields(imported):
        found, there = _lookup(exported, path)
        if not found:
            missing.append(path)
        elif there != value or (isinstance(value, bool) != isinstance(there, bool)):
            changed.append(path)
    return missing, changed


def devkit_read(doc: dict[str, Any]) -> int:
    """Read a labels document as SoccerNet-v3's devkit dataloader reads ``Labels-v3.json`` (``SNV3Dataset``: per
    action of ``GameMetadata.list_actions`` the action and its ``linked_replays``; per image every ``bboxes`` entry's
    ``points`` x1..y2 normalised by ``imageMetadata`` width and height, its class id, its ``ID`` (a string or null,
    ``.isnumeric()``), every line's class id and points); returns the boxes read.

    Raises:
        KeyError, TypeError, AttributeError, ZeroDivisionError: what the devkit would raise on a document it
            cannot read.
    """
    boxes = 0
    for action in doc["GameMetadata"]["list_actions"]:
        images = [action] + doc["actions"][action]["linked_replays"]
        for i, name in enumerate(images):
            item = doc["actions" if i == 0 else "replays"][name]
            meta = item["imageMetadata"]
            for b in item["bboxes"]:
                if b["class"] is None:
                    continue
                p = b["points"]
                _ = (p["x1"] / meta["width"], p["y1"] / meta["height"], abs(p["x2"] - p["x1"]) / meta["width"],
                     abs(p["y2"] - p["y1"]) / meta["height"], float(DEVKIT_CLASSES[b["class"]]))
                if b["ID"] is not None:
                    b["ID"].isnumeric()
                boxes += 1
            for line in item["lines"]:
                if line["class"] is not None:
                    pts = line["points"]
                    _ = ([x / meta["width"] for x in pts[::2]], [y / meta["height"] for y in pts[1::2]],
                         DEVKIT_CLASSES[line["class"]])
    return boxes


def compare_trees(source: Path, export: Path) -> dict[str, Any]:
    """Every ``Labels-v3.json`` under ``source`` against the ``Labels-v3D.json`` at the same place under ``export``:
    ``{games, frames, fields, missing, changed, devkit_boxes, source_boxes, examples}`` (and ``devkit_errors`` where
    the devkit-style reader failed)."""
    out = {"games": 0, "frames": 0, "fields": 0, "missing": 0, "changed": 0, "devkit_boxes": 0, "source_boxes": 0,
           "examples": []}
    for labels in sorted(source.rglob("Labels-v3.json")):
        imported = json.loads(labels.read_text(encoding="utf-8"))
        target = export / labels.parent.relative_to(source) / "Labels-v3D.json"
        exported = json.loads(target.read_text(encoding="utf-8")) if target.is_file() else {}
        missing, changed = lost_fields(imported, exported)
        out["games"] += 1
        out["frames"] += sum(len(imported.get(s, {})) for s in ("actions", "replays"))
        out["fields"] += sum(1 for _ in leaf_fields(imported))
        out["missing"] += len(missing)
        out["changed"] += len(changed)
        out["examples"] += [("missing", "/".join(map(str, p))) for p in missing[:3]]
        out["examples"] += [("changed", "/".join(map(str, p))) for p in changed[:3]]
        out["source_boxes"] += sum(len(item.get("bboxes", [])) for s in ("actions", "replays")
                                   for item in imported.get(s, {}).values())
        if exported:
            try:
                out["devkit_boxes"] += devkit_read(exported)
            except (KeyError, TypeError, AttributeError, ZeroDivisionError) as exc:
                out.setdefault("devkit_errors", []).append(f"{labels.parent.name}: {type(exc).__name__} {exc}")
    return out


def run(trees: list[Path], workdir: Path) -> dict[str, dict[str, Any]]:
    """Import each tree into its own SQLite file, export it (``--all``, no images), compare (:func:`compare_trees`)."""
    from app.core.config import Settings
    from app.db.session import make_engine, make_session_factory, upgrade_database
    from app.services.transfer.exporting import export_soccernet_v3d
    from app.services.transfer.importing import import_soccernet_v3

    results = {}
    for n, tree in enumerate(trees):
        url = f"sqlite:///{workdir / f'{n}.sqlite3'}"
        upgrade_database(url)
        engine = make_engine(url)
        settings = Settings(database_url=url, calibration_workers=0)
        with make_session_factory(engine)() as session:
            import_soccernet_v3(session, tree, settings)
            session.commit()
            export_soccernet_v3d(session, workdir / f"{n}-export", include_all=True, images=False)
        engine.dispose()
        results[str(tree)] = compare_trees(tree, workdir / f"{n}-export")
    return results


def main() -> None:
    from app.core.paths import SHARED_DIR

    synthetic = SHARED_DIR / "data" / "synthetic"
    default = [synthetic / "soccernet-v3-dev", synthetic / "soccernet-v3-dev-large",
               synthetic / "doubts-seeds" / "seed-201"]
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("trees", nargs="*", type=Path, default=default)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        results = run([t.resolve() for t in args.trees if t.is_dir()], Path(tmp))
    print(f"{'tree':<40} {'games':>5} {'frames':>6} {'fields':>8} {'missing':>7} {'changed':>7} {'boxes':>6} "
          f"{'devkit':>6}")
    for tree, r in results.items():
        print(f"{Path(tree).name:<40} {r['games']:>5} {r['frames']:>6} {r['fields']:>8} {r['missing']:>7} "
              f"{r['changed']:>7} {r['source_boxes']:>6} {r['devkit_boxes']:>6}")
        for kind, path in r["examples"][:6]:
            print(f"    {kind}: {path}")
        for error in r.get("devkit_errors", [])[:3]:
            print(f"    the devkit-style reader failed: {error}")
    if args.json:
        args.json.write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
