"""Upload a SoccerNet-v3 dataset (a zip, or a folder zipped on the way), wait for its import with progress, and print
the job's result (the import's counts) as JSON.

    V3D_URL=http://127.0.0.1:8000 V3D_TOKEN=... python examples/client/01_upload_and_wait.py DATASET.zip

An admin's token. Games stored already are refused (409 naming them): add ``merge="keep-newer"`` to ``upload``.
"""
from __future__ import annotations

import json
import sys

from v3d_client import Client


def main(path: str) -> None:
    with Client.from_env() as v3d:
        sent = lambda done, total: print(f"\ruploaded {done} of {total} bytes", end="", file=sys.stderr)  # noqa: E731
        job = v3d.upload(path, "soccernet-v3", progress=sent)
        print(f"\nimport queued as job {job.id}", file=sys.stderr)
        stage = lambda j: print(f"\r{j.stage or j.state}: {j.done}/{j.total}   ", end="", file=sys.stderr)  # noqa: E731
        done = v3d.wait(job, progress=stage)
        print(file=sys.stderr)
        print(json.dumps({"job": done.id, "result": done.result}, indent=2))


if __name__ == "__main__":
    main(sys.argv[1])
