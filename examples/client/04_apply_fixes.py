"""Apply, once, every one-key fix that a label doubt suggests, on every system with a label doubt: snap the ball
label to where the other views put it, exclude a view, or apply mirrored field lines. A fix re-computes its system,
so each system's doubts are read again from the fix's answer; no fix is applied twice to one view. Prints what was
applied and what the server refused (a mirror that would bring the ball no closer, 409), as JSON.

    python examples/client/04_apply_fixes.py

An annotator's token at least.
"""
from __future__ import annotations

import json

from v3d_client import Client, Conflict, Invalid


def main() -> None:
    applied, refused = [], []
    with Client.from_env() as v3d:
        for summary in list(v3d.systems(doubt="any")):
            system = v3d.system(summary.id)
            tried: set[tuple[int | None, str | None]] = set()
            while True:
                todo = [d for d in system.doubts if d.accuses_label and d.fix_action is not None
                        and (d.frame_id, d.fix_action) not in tried]
                if not todo:
                    break
                doubt = todo[0]
                tried.add((doubt.frame_id, doubt.fix_action))
                fix = {"system": system.id, "frame": doubt.frame_id, "kind": doubt.kind, "action": doubt.fix_action}
                try:
                    system = v3d.apply_fix(doubt, system.view(doubt.frame_id or 0))
                    applied.append(fix)
                except (Conflict, Invalid) as exc:
                    refused.append({**fix, "why": exc.detail})
    print(json.dumps({"applied": applied, "refused": refused}, indent=2))


if __name__ == "__main__":
    main()
