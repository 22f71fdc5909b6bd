"""Frame images read from the store: a folder store against an S3 store (SeaweedFS on loopback, ``tests.seaweed``),
and in the S3 store with and without the last bytes read when a file is opened (``app.services.storage.s3.TAIL_BYTES``:
its size and a zip archive's directory in one request, instead of a HEAD and a read of each).

Data: the demo game (``app.demo``, seed 0) cut to ``--systems`` systems, its ``Frames-v3.zip`` stored once per store;
each of its images read ``--rounds`` times through ``app.services.images.serving.frame_image`` (the header checked,
then the bytes streamed, as ``GET /api/frames/{id}/image`` does). Prints one JSON object: per variant the median and
90th percentile in ms.

Usage::

    .venv/bin/python benchmarks/stored_images.py --systems 9 --rounds 3
"""
from __future__ import annotations

import argparse
import io
import json
import statistics
import sys
import tempfile
import time
import zipfile
from pathlib import Path
from typing import BinaryIO

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from app.db.models import Frame
from app.services.images.serving import frame_image
from app.services.storage.datasets import DatasetFiles
from app.services.storage.s3 import READ_BUFFER_BYTES, RangeReader, S3Storage
from app.services.storage.stores import FileStorage, Storage
from tests.nodes.uploads import small_v3_upload
from tests.seaweed import start_seaweed


class WithoutTail(S3Storage):
    """The S3 store as it would be without the last bytes read at opening: a HEAD for the size, then ranges."""

    def open(self, key: str) -> BinaryIO:
        raw = RangeReader(self.client, self.bucket, self._name(key), self.stat(key).size, key)
        return io.BufferedReader(raw, buffer_size=READ_BUFFER_BYTES)


def measure(store: Storage, frames: bytes, members: list[str], rounds: int, scratch: Path) -> dict[str, float]:
    store.put_stream("uploads/bench/game/Frames-v3.zip", io.BytesIO(frames))
    files = DatasetFiles(store, None, scratch)
    times = []
    for _ in range(rounds):
        for member in members:
            frame = Frame(id=1, name=member, width=1, height=1, image_root="storage:uploads/bench",
                          image_zip="game/Frames-v3.zip", image_member=member)
            start = time.perf_counter()
            b"".join(frame_image(frame, files=files).chunks())
            times.append(time.perf_counter() - start)
    times.sort()
    return {"median_ms": round(statistics.median(times) * 1000, 2),
            "p90_ms": round(times[int(0.9 * len(times))] * 1000, 2), "reads": len(times)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--systems", type=int, default=9)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="v3d-stored-images-") as tmp:
        work = Path(tmp)
        upload = zipfile.ZipFile(io.BytesIO(small_v3_upload(work / "src", systems=args.systems)))
        frames = upload.read(next(n for n in upload.namelist() if n.endswith("Frames-v3.zip")))
        members = zipfile.ZipFile(io.BytesIO(frames)).namelist()
        server = start_seaweed(work / "weed")
        try:
            client = server.client()
            out = {"images": len(members), "archive_bytes": len(frames),
                   "file": measure(FileStorage(work / "store"), frames, members, args.rounds, work / "jobs"),
                   "s3": measure(S3Storage(server.bucket, "tail", client=client), frames, members, args.rounds,
                                 work / "jobs"),
                   "s3_without_tail": measure(WithoutTail(server.bucket, "head", client=client), frames, members,
                                              args.rounds, work / "jobs")}
        finally:
            server.stop()
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
