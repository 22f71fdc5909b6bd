"""Print the id of every system with a doubt of one kind, one a line, in the queue's order (every page of it).

    python examples/client/02_systems_with_doubt.py mirrored_labels

KIND: a doubt kind (mirrored_labels, ball_off_consensus, ball_missing, views_disagree, near_duplicate_view,
ball_detected, ...), ``any`` for a label-accusing doubt of any kind, or ``none`` for none.
"""
from __future__ import annotations

import sys

from v3d_client import Client


def main(kind: str) -> None:
    with Client.from_env() as v3d:
        for system in v3d.systems(doubt=kind):
            print(system.id)


if __name__ == "__main__":
    main(sys.argv[1])
