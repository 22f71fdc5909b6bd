"""One store for every file v3d keeps (uploads, frame images and archives, export results): a folder or an S3
bucket, named by ``V3D_STORAGE_URL`` (:func:`storage_for`). The interface and the folder store are in
:mod:`app.services.storage.stores`, the S3 store in :mod:`app.services.storage.s3`, and how a frame names its
dataset's files in the store (or under the data root) in :mod:`app.services.storage.datasets`."""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from urllib.parse import unquote, urlsplit

from app.core.config import Settings, jobs_dir
from app.services.storage.stores import FileStorage, Storage


def open_storage(url: str, timeout_s: float | None = None) -> Storage:
    """The store ``url`` names: ``file:///folder`` or ``s3://bucket/prefix`` (the S3 client configured from the
    standard AWS variables, ``app.services.storage.s3``; ``timeout_s``: how long each of its requests waits for an
    answer, ``V3D_STORE_TIMEOUT_S``, by default ``s3.READ_TIMEOUT_S``).

    >>> open_storage("file:///srv/v3d").root.as_posix()
    '/srv/v3d'

    Raises:
        ValueError: another scheme, or an S3 URL without a bucket.
    """
    parts = urlsplit(url)
    if parts.scheme == "file":
        return FileStorage(Path(unquote(parts.path)))
    if parts.scheme == "s3":
        if not parts.netloc:
            raise ValueError(f"V3D_STORAGE_URL: {url!r} names no bucket (s3://BUCKET/PREFIX)")
        return _s3(parts.netloc, parts.path.strip("/"), timeout_s)
    raise ValueError(f"V3D_STORAGE_URL: {url!r} is neither file://FOLDER nor s3://BUCKET/PREFIX")


@lru_cache(maxsize=8)
def _s3(bucket: str, prefix: str, timeout_s: float | None = None) -> Storage:
    """One S3 store (and its boto3 client, which is thread-safe and slow to make) per bucket, prefix and timeout."""
    from app.services.storage.s3 import READ_TIMEOUT_S, S3Storage

    return S3Storage(bucket, prefix, timeout_s=READ_TIMEOUT_S if timeout_s is None else timeout_s)


def storage_for(settings: Settings) -> Storage:
    """The store of ``settings``: ``V3D_STORAGE_URL``, else the jobs folder as a folder store (the layout v3d
    always had: ``<jobs dir>/uploads/...``, ``<jobs dir>/exports/...``)."""
    if settings.storage_url:
        return open_storage(settings.storage_url, settings.store_timeout_s)
    return FileStorage(jobs_dir(settings))
