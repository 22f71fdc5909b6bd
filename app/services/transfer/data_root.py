"""Where imports over HTTP may read: server paths confined to the configured data root.

The check resolves the path (``..``, symbolic links) before comparing, and answers the same refusal
for a path outside the root whether or not it exists, so that the API cannot be used to probe the
server's disk.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

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


def dataset_name(path: str | Path, data_root: Path | None, uploads_dir: Path, upload_job: int | None = None) -> str:
    """How an imported path is shown to annotators and reviewers (no server path):
    an upload's as ``upload <job id>/<path inside it>`` (``upload_job``; the upload's folder name when not
    given), a path under the data root relative to it, anything else by its last component alone.

    >>> dataset_name("/srv/data/sn/v3", Path("/srv/data"), Path("/var/jobs/uploads"))
    'sn/v3'
    >>> dataset_name("/var/jobs/uploads/20261123-0001-ab12/league/Labels-v3.json", None, Path("/var/jobs/uploads"), 7)
    'upload 7/league/Labels-v3.json'
    >>> dataset_name("/home/ana/datasets/issia-dev", None, Path("/var/jobs/uploads"))
    'issia-dev'
    """
    p = Path(path).expanduser()
    p = p if p.is_absolute() else p.resolve()  # a relative path (a relative V3D_JOBS_DIR) as the import read it
    uploads = Path(uploads_dir).expanduser().resolve()
    if p.is_relative_to(uploads) and p != uploads:
        folder, *inside = p.relative_to(uploads).parts
        return "/".join([f"upload {upload_job if upload_job is not None else folder}", *inside])
    if data_root is not None:
        root = Path(data_root).expanduser().resolve()
        if p.is_relative_to(root):
            return p.relative_to(root).as_posix() or "."
    return p.name


def path_forms(path: str | Path) -> list[str]:
    """Every way a message may write ``path``: as given, absolute, and with symbolic links resolved (the readers
    name files by the resolved dataset folder), longest first.

    >>> path_forms("/srv/data/sn/v3")
    ['/srv/data/sn/v3']
    """
    given = Path(path).expanduser()
    forms = {str(path), str(given), str(given.absolute()), str(given.resolve())}
    return sorted((f for f in forms if f not in ("", ".")), key=len, reverse=True)


def without_server_paths(text: str, path: str | Path, name: str, folders: dict[str, str] | None = None) -> str:
    """``text`` (a job's message, an error) with the imported ``path``, in each of its forms (:func:`path_forms`),
    replaced by its shown ``name`` (:func:`dataset_name`), so that a file inside the dataset is named from the
    dataset's own folder; then each server folder of ``folders`` that is still written (the uploads folder, the
    jobs folder, the temporary folder: the keys; a folder inside another first) by what stands for it (the values).

    >>> without_server_paths("/srv/data/sn/v3/l/s/g/Labels-v3.json: invalid JSON", "/srv/data/sn/v3", "sn/v3")
    'sn/v3/l/s/g/Labels-v3.json: invalid JSON'
    >>> without_server_paths("/srv/data/other/x.json: missing", "/srv/data/sn/v3", "sn/v3", {"/srv/data": "(data)"})
    '(data)/other/x.json: missing'
    """
    for form in path_forms(path):
        text = text.replace(form, name)
    # a folder inside another first, whichever order they are given in
    for form, shown in sorted(((f, v) for k, v in (folders or {}).items() for f in path_forms(k)),
                              key=lambda pair: len(pair[0]), reverse=True):
        text = text.replace(form, shown)
    return text


def shown_import_counts(after: dict[str, Any] | None) -> dict[str, Any] | None:
    """An import's audit counts (``importing.audit_counts``) as annotators and reviewers see them: its
    ``source`` is the dataset's shown name (``source_name``, :func:`dataset_name`; entries written before
    it: the path's last component), never a server path.

    >>> shown_import_counts({"source": "/srv/data/sn/v3", "source_name": "sn/v3", "games": 2})
    {'source': 'sn/v3', 'games': 2}
    >>> shown_import_counts({"source": "/var/jobs/uploads/x", "games": 1})
    {'source': 'x', 'games': 1}
    """
    if not after or "source" not in after:
        return after
    shown = {k: v for k, v in after.items() if k != "source_name"}
    shown["source"] = after.get("source_name") or Path(str(after["source"])).name
    return shown
