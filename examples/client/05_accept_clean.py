"""Accept every pending system with no label doubt and a 3D ball, each bound to the version read (a system changed
since it was read is left for a person: 412), and print how many were accepted.

    python examples/client/05_accept_clean.py

A reviewer's token at least.
"""
from __future__ import annotations

from v3d_client import Client, EditConflict


def main() -> None:
    accepted = 0
    with Client.from_env() as v3d:
        for summary in list(v3d.systems(status="pending", doubt="none")):
            system = v3d.system(summary.id)  # the version the decision is bound to
            if system.ball3d is None or system.review.status != "pending" or any(d.accuses_label
                                                                                for d in system.doubts):
                continue
            try:
                v3d.decide(system, "accepted", "no doubt, 3D ball: accepted by 05_accept_clean.py")
            except EditConflict:
                continue
            accepted += 1
    print(accepted)


if __name__ == "__main__":
    main()
