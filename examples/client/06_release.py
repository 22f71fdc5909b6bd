"""Make a release of the accepted systems and download its SoccerNet-v3D export (a zip: Labels-v3D.json and
Frames-v3.zip per game, SNv3D.csv), the same bytes whenever that release is exported again.

    python examples/client/06_release.py v1.0 v1.0.zip

An admin's token.
"""
from __future__ import annotations

import sys

from v3d_client import Client


def main(name: str, out: str) -> None:
    with Client.from_env() as v3d:
        release = v3d.create_release(name, note="made by examples/client/06_release.py")
        print(f"release {release.name}: {release.systems} systems, {release.views} views, {release.hash}")
        job = v3d.export("soccernet-v3d", out, release=name,
                         job_progress=lambda j: print(f"\rexport: {j.done}/{j.total}", end="", file=sys.stderr))
        print(f"\nwrote {out} ({job.result and job.result.get('bytes')} bytes, job {job.id})")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
