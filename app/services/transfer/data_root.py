"""Where imports over HTTP may read: server paths confined to the configured data root.

The check resolves the path (``..``, symbolic links) before comparing, and answers the same refusal
for a path outside the root whether or not it exists, so that the API cannot be used to probe the
server's disk.
"""
from __future__ import annotations

from pathlib import Path

from app.core.errors import ForbiddenError


def confined_path(path: str | Path, data_root: Path | None) -> Path:
    """``path`` (absolute, or relative to ``data_root``) resolved, when it lies inside ``data_root``.

    Raises:
        ForbiddenError: no data root is configured, or the resolved path is outside it.

    >>> import tempfile
    >>> root = Path(tempfile.mkdtemp())
    >>> confined_path("games/a", root) == root.resolve() / "games" / "a"
    True
    >>> confined_path("../etc/passwd", root)
    Traceback (most recent call last):
    ...
    app.core.errors.ForbiddenError: path: outside the data root (V3D_DATA_ROOT); HTTP imports read only from there
    """
    if data_root is None:
        raise ForbiddenError("imports of server paths over HTTP are disabled: set V3D_DATA_ROOT to the folder "
                             "they may read from (the v3d import command is not confined)")
    root = Path(data_root).expanduser().resolve()
    candidate = Path(path).expanduser()
    resolved = (candidate if candidate.is_absolute() else root / candidate).resolve()
    if resolved != root and root not in resolved.parents:
        raise ForbiddenError("path: outside the data root (V3D_DATA_ROOT); HTTP imports read only from there")
    return resolved
