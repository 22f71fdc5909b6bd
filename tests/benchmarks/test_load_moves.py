"""``benchmarks/load.py --move-px``: the boxes a load run sends move by at least the asked pixels (issue 29: edits
of 2 px or more, so that no edit leaves its system's derived rows as they were), and stay unique per annotator and
edit (the lost-edit check tells edits apart by their box)."""
from __future__ import annotations

import itertools

from benchmarks import load


def test_boxes_move_by_at_least_the_asked_pixels_and_stay_unique() -> None:
    box = [400.0, 300.0, 410.0, 309.0]
    sent = {(c, seq): load.edit_box(box, c, seq, move_px=2.0) for c, seq in itertools.product(range(20), range(256))}
    for (c, seq), b in sent.items():
        dx = b[0] - box[0]
        assert abs(dx) >= 2.0 and (dx > 0) == (seq % 2 == 0), (c, seq, b)
        assert b[2] - b[0] == box[2] - box[0] and abs((b[3] - b[1]) - (box[3] - box[1])) < 1e-9  # moved, not resized
    assert len({tuple(b) for b in sent.values()}) == len(sent)
    # consecutive edits of one view move its box by at least twice the asked pixels
    assert abs(sent[(3, 1)][0] - sent[(3, 0)][0]) >= 4.0
    # without the option: the sub-pixel moves of before
    assert max(abs(load.edit_box(box, c, 7)[0] - box[0]) for c in range(20)) <= 1.0
