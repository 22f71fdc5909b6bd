"""Move a view's ball label by DX, DY pixels, bound to the version read: when someone changed the view meanwhile
(412), read it again and apply the same move to the label as it is now, so that both moves land.

    python examples/client/03_move_ball.py FRAME_ID DX DY

An annotator's token at least. Prints the label's box before and after.
"""
from __future__ import annotations

import sys

from v3d_client import Client, EditConflict, Frame, V3DError


def moved(frame: Frame, dx: float, dy: float) -> list[float]:
    """The frame's ball box moved by (dx, dy) pixels."""
    if frame.ball.box is None:
        raise V3DError(f"frame {frame.frame_id} has no ball box to move")
    x1, y1, x2, y2 = frame.ball.box
    return [x1 + dx, y1 + dy, x2 + dx, y2 + dy]


def main(frame_id: int, dx: float, dy: float, attempts: int = 20) -> None:
    with Client.from_env() as v3d:
        frame = v3d.frame(frame_id)
        before = frame.ball.box
        for _ in range(attempts):
            try:
                system = v3d.edit_ball(frame, box=moved(frame, dx, dy))
                break
            except EditConflict as conflict:  # someone else's edit landed first: move their label instead
                current = conflict.current
                frame = current if isinstance(current, Frame) else v3d.frame(frame_id)
        else:
            raise V3DError(f"frame {frame_id} kept changing: gave up after {attempts} attempts")
        print(f"frame {frame_id}: {before} -> {system.view(frame_id).ball.box}")


if __name__ == "__main__":
    main(int(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3]))
