"""An S3 bucket (or any S3-compatible store: SeaweedFS, MinIO, Ceph) as v3d's store, through boto3.

``s3://BUCKET/PREFIX``: every key is stored as ``PREFIX/key`` in ``BUCKET`` (which must exist). The client is boto3's
with its standard configuration from the environment: ``AWS_ACCESS_KEY_ID``, ``AWS_SECRET_ACCESS_KEY``,
``AWS_DEFAULT_REGION`` and ``AWS_ENDPOINT_URL`` (an S3-compatible store's address, then reached with path-style
requests, which every such store understands). Files are written with boto3's managed transfers (multipart above
:data:`MULTIPART_BYTES`) and read as ranges (:class:`RangeReader`): a frame's image is read out of its zip archive
stored whole, as ``zipfile`` seeks to the archive's directory and then to the member, never downloading the archive.
"""
from __future__ import annotations

import io
import os
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any, BinaryIO, NoReturn, Optional

from app.services.storage.stores import MAX_S3_KEY_BYTES, KeyTooLong, Storage, StorageError, StoredObject, checked_key

if TYPE_CHECKING:
    from mypy_boto3_s3 import S3Client

#: Files above this size are uploaded in parts of this size (boto3's TransferConfig; S3 takes parts of 5 MiB to
#: 5 GiB, at most 10,000 of them: 16 MiB parts carry files up to 156 GiB).
MULTIPART_BYTES = 16 << 20
#: Bytes read per range request when a stored file is read in pieces (``zipfile`` reads small headers: a larger
#: buffer fetches a member's bytes with its header in one request).
READ_BUFFER_BYTES = 256 << 10
#: Bytes read from the end of a file when it is opened: its size comes with them (no HEAD request), and so does a zip
#: archive's directory of up to about 700 members, which ``zipfile`` reads first.
TAIL_BYTES = 64 << 10

_MISSING = ("404", "NoSuchKey", "NotFound")
#: What S3 answers to keys that do not sign as the server expects: a wrong secret, an unknown key id, a clock off.
_REFUSED = ("SignatureDoesNotMatch", "InvalidAccessKeyId", "AccessDenied", "403", "RequestTimeTooSkewed",
            "InvalidToken", "ExpiredToken")
#: How long a request waits to connect to the store and for each answer by default (s: ``V3D_STORE_TIMEOUT_S``, the
#: connection at most :data:`CONNECT_TIMEOUT_S`), and how many times it is sent in all (botocore's
#: ``total_max_attempts``: its ``max_attempts`` counts the retries only): a store that accepts connections and never
#: answers fails a request in about ``timeout * ATTEMPTS`` seconds, answered 503 (``app.api.errors``), never holding a
#: worker for minutes (botocore's ``connect_timeout``, ``read_timeout`` and ``retries``; its defaults are 60 s each and
#: 5 attempts in the standard mode).
CONNECT_TIMEOUT_S = 3.0
READ_TIMEOUT_S = 5.0
ATTEMPTS = 2


def _raise(exc: Exception, key: str, url: str = "S3", timeout_s: float = READ_TIMEOUT_S) -> NoReturn:
    """A boto3 error as :class:`FileNotFoundError` (no such key) or :class:`StorageError` in words (anything else:
    the store refused v3d's keys, could not be reached, did not answer in time, or failed)."""
    from boto3.exceptions import S3UploadFailedError
    from botocore.exceptions import ConnectTimeoutError, EndpointConnectionError, ReadTimeoutError

    if isinstance(exc, S3UploadFailedError) and isinstance(exc.__context__, Exception):
        exc = exc.__context__  # boto3's managed upload says what S3 answered in the error it raised from
    code = str((getattr(exc, "response", None) or {}).get("Error", {}).get("Code", ""))
    if code in _MISSING:
        raise FileNotFoundError(f"{key!r}: not stored ({code})") from None
    if code == "NoSuchBucket":
        said = "its bucket does not exist"
    elif code in _REFUSED:
        said = f"it refused v3d's credentials ({code}: check AWS_ACCESS_KEY_ID and AWS_SECRET_ACCESS_KEY)"
    elif isinstance(exc, (ConnectTimeoutError, ReadTimeoutError)):
        said = f"it did not answer within {timeout_s:g} s ({ATTEMPTS} tries)"
    elif isinstance(exc, EndpointConnectionError):
        said = "it cannot be reached"
    else:
        said = f"it failed ({code or type(exc).__name__})"
    raise StorageError(f"the file store {url} cannot be used: {said}") from None


def _errors() -> tuple[type[Exception], ...]:
    from boto3.exceptions import S3UploadFailedError
    from botocore.exceptions import BotoCoreError, ClientError

    return (BotoCoreError, ClientError, S3UploadFailedError)


class RangeReader(io.RawIOBase):
    """A stored object read as a seekable file, each read one ranged GET (wrap it in ``io.BufferedReader``)."""

    def __init__(self, client: "S3Client", bucket: str, name: str, size: int, key: str, tail: bytes = b"",
                 timeout_s: float = READ_TIMEOUT_S) -> None:
        super().__init__()
        self._client, self._bucket, self._name, self._size, self._key = client, bucket, name, size, key
        self._timeout_s = timeout_s
        self._pos = 0
        #: The file's last bytes, read when it was opened (``S3Storage.open``).
        self._tail, self._tail_start = tail, size - len(tail)

    def readable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def tell(self) -> int:
        return self._pos

    def seek(self, offset: int, whence: int = io.SEEK_SET) -> int:
        base = {io.SEEK_SET: 0, io.SEEK_CUR: self._pos, io.SEEK_END: self._size}[whence]
        self._pos = max(0, base + offset)
        return self._pos

    def readinto(self, buffer: Any) -> int:
        view = memoryview(buffer).cast("B")
        end = min(self._size, self._pos + len(view))
        if end <= self._pos:
            return 0
        if self._pos >= self._tail_start:  # read with the file's size when it was opened
            data = self._tail[self._pos - self._tail_start:end - self._tail_start]
            view[:len(data)] = data
            self._pos += len(data)
            return len(data)
        end = min(end, self._tail_start)
        try:
            body = self._client.get_object(Bucket=self._bucket, Key=self._name,
                                           Range=f"bytes={self._pos}-{end - 1}")["Body"]
            data = body.read()
        except _errors() as exc:
            _raise(exc, self._key, f"s3://{self._bucket}", self._timeout_s)
        n = len(data)
        view[:n] = data
        self._pos += n
        return n


class S3Storage(Storage):
    """``s3://bucket/prefix`` through boto3 (see the module docstring)."""

    def __init__(self, bucket: str, prefix: str = "", client: Optional["S3Client"] = None,
                 timeout_s: float = READ_TIMEOUT_S) -> None:
        self.bucket, self.prefix = bucket, prefix.strip("/")
        self.url = f"s3://{bucket}/{self.prefix}" if self.prefix else f"s3://{bucket}"
        #: how long each request waits for an answer (s), twice at most (:data:`ATTEMPTS`)
        self.timeout_s = timeout_s
        self.client = client if client is not None else default_client(timeout_s)

    def _name(self, key: str) -> str:
        self.check_fits(key)
        return f"{self.prefix}/{key}" if self.prefix else key

    def check_fits(self, key: str) -> str:
        """``key`` when safe (:func:`checked_key`) and its object's name (the prefix and the key) is at most
        :data:`MAX_S3_KEY_BYTES` bytes of UTF-8, else :class:`KeyTooLong` (before anything is sent)."""
        checked_key(key)
        size = len((f"{self.prefix}/{key}" if self.prefix else key).encode("utf-8", "surrogatepass"))
        if size > MAX_S3_KEY_BYTES:
            raise KeyTooLong(key, size, MAX_S3_KEY_BYTES, self.url)
        return key

    def _key(self, name: str) -> str:
        return name[len(self.prefix) + 1:] if self.prefix else name

    def local_path(self, key: str) -> Optional[Path]:
        """None: a remote store."""
        return None

    def key_refusal(self, key: str) -> Optional[str]:
        """Why S3 cannot hold ``key`` in words (its name, the prefix and the key, above :data:`MAX_S3_KEY_BYTES`
        bytes of UTF-8); None when it can."""
        try:
            self.check_fits(key)
        except KeyTooLong as exc:
            shown = key if len(key) <= 80 else f"{key[:60]}...{key[-16:]}"
            return f"{shown!r}: its name in {self.url} is {exc.size} bytes; S3 holds names of at most {exc.limit}"
        return None

    def _transfer(self) -> Any:
        from boto3.s3.transfer import TransferConfig

        return TransferConfig(multipart_threshold=MULTIPART_BYTES, multipart_chunksize=MULTIPART_BYTES,
                              max_concurrency=4)

    def put_file(self, key: str, source: Path) -> None:
        """boto3's managed upload of ``source`` (multipart above :data:`MULTIPART_BYTES`)."""
        try:
            self.client.upload_file(str(source), self.bucket, self._name(key), Config=self._transfer())
        except _errors() as exc:
            _raise(exc, key, self.url, self.timeout_s)

    def put_stream(self, key: str, stream: BinaryIO) -> None:
        """boto3's managed upload of the stream (multipart above :data:`MULTIPART_BYTES`)."""
        try:
            self.client.upload_fileobj(stream, self.bucket, self._name(key), Config=self._transfer())
        except _errors() as exc:
            _raise(exc, key, self.url, self.timeout_s)

    def get_file(self, key: str, target: Path) -> Path:
        """boto3's managed download into ``target`` (written beside it, renamed when complete)."""
        target.parent.mkdir(parents=True, exist_ok=True)
        part = target.with_name(target.name + ".part")
        try:
            self.client.download_file(self.bucket, self._name(key), str(part), Config=self._transfer())
            os.replace(part, target)
        except _errors() as exc:
            part.unlink(missing_ok=True)
            _raise(exc, key, self.url, self.timeout_s)
        return target

    def open(self, key: str) -> BinaryIO:
        """The object read in ranges of at least :data:`READ_BUFFER_BYTES` as it is read; its last
        :data:`TAIL_BYTES` (and its size) read at once, in one request."""
        name = self._name(key)
        try:
            answer = self.client.get_object(Bucket=self.bucket, Key=name, Range=f"bytes=-{TAIL_BYTES}")
            tail = answer["Body"].read()
        except _errors() as exc:
            if str((getattr(exc, "response", None) or {}).get("Error", {}).get("Code", "")) != "InvalidRange":
                _raise(exc, key, self.url, self.timeout_s)
            tail = b""  # an empty object has no last bytes
        content_range = str(answer.get("ContentRange", "")) if tail else ""
        size = int(content_range.rpartition("/")[2]) if content_range else len(tail)
        raw = RangeReader(self.client, self.bucket, name, size, key, tail, self.timeout_s)
        return io.BufferedReader(raw, buffer_size=READ_BUFFER_BYTES)

    def stat(self, key: str) -> StoredObject:
        """The object's head: size, last modification, ETag."""
        try:
            head = self.client.head_object(Bucket=self.bucket, Key=self._name(key))
        except _errors() as exc:
            _raise(exc, key, self.url, self.timeout_s)
        return StoredObject(key, int(head["ContentLength"]), head["LastModified"].timestamp(),
                            str(head.get("ETag", "")).strip('"'))

    def list(self, prefix: str) -> Iterator[StoredObject]:
        """The objects under ``prefix/`` (pages of 1,000)."""
        start = self._name(checked_key(prefix.rstrip("/"))) + "/"
        try:
            for page in self.client.get_paginator("list_objects_v2").paginate(Bucket=self.bucket, Prefix=start):
                for obj in page.get("Contents", []):
                    yield StoredObject(self._key(obj["Key"]), int(obj["Size"]), obj["LastModified"].timestamp(),
                                       str(obj.get("ETag", "")).strip('"'))
        except _errors() as exc:
            _raise(exc, prefix, self.url, self.timeout_s)

    def delete(self, key: str) -> None:
        """Remove the object (S3 answers a missing one as removed)."""
        try:
            self.client.delete_object(Bucket=self.bucket, Key=self._name(key))
        except _errors() as exc:
            _raise(exc, key, self.url, self.timeout_s)

    def check_reachable(self) -> None:
        """A listing of at most one key under the prefix (what every node needs: the bucket, read and list)."""
        try:
            self.client.list_objects_v2(Bucket=self.bucket, Prefix=f"{self.prefix}/" if self.prefix else "",
                                        MaxKeys=1)
        except _errors() as exc:
            _raise(exc, self.prefix or "/", self.url, self.timeout_s)

    def url_for(self, key: str, expires_s: int = 300) -> Optional[str]:
        """A presigned GET of the object, valid ``expires_s`` seconds."""
        try:
            return str(self.client.generate_presigned_url(
                "get_object", Params={"Bucket": self.bucket, "Key": self._name(key)}, ExpiresIn=expires_s))
        except _errors() as exc:
            _raise(exc, key, self.url, self.timeout_s)


def default_client(timeout_s: float = READ_TIMEOUT_S) -> "S3Client":
    """boto3's S3 client configured from the standard AWS variables; path-style requests when
    ``AWS_ENDPOINT_URL`` names an S3-compatible store (virtual-host names need DNS such stores seldom have);
    ``timeout_s`` seconds for each answer (and at most :data:`CONNECT_TIMEOUT_S` to connect), two tries
    (:data:`ATTEMPTS`)."""
    import boto3
    from botocore.config import Config

    path_style = bool(os.environ.get("AWS_ENDPOINT_URL_S3") or os.environ.get("AWS_ENDPOINT_URL"))
    config = Config(s3={"addressing_style": "path" if path_style else "auto"},
                    retries={"mode": "standard", "total_max_attempts": ATTEMPTS},
                    connect_timeout=min(CONNECT_TIMEOUT_S, timeout_s), read_timeout=timeout_s)
    return boto3.session.Session().client("s3", config=config)
