"""Where an imported dataset's files are, as a frame records it (``Frame.image_root``), and how any node reads them.

A frame's ``image_root`` names its dataset's folder in one of three ways; its ``image_zip`` / ``image_path`` are
relative to that folder (POSIX):

* ``storage:<key>``: the folder ``<key>`` of the store (``V3D_STORAGE_URL``): an uploaded dataset
  (``storage:uploads/<upload>/...``), readable from every node sharing the store;
* ``data-root:<path>``: a folder relative to the data root (``V3D_DATA_ROOT``), which every node names the same
  (a dataset imported over HTTP from a server path);
* an absolute path (rows imported before the store existed that lay neither in the jobs folder nor under the data
  root, and the command line's imports of any folder): read on the machine that has it, as always.

An import reads its dataset from a local folder (an upload is fetched from the store into the node's own scratch
folder first: :meth:`DatasetFiles.upload_folder`), and the frames it stored with that folder's absolute path are given
their reference when it ends (:func:`rekey_frames`, one statement).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.core.config import Settings, jobs_dir
from app.services.storage import storage_for
from app.services.storage.stores import FileStorage, Storage, join_key

#: ``Frame.image_root`` of a dataset kept in the store: this, then the folder's key.
STORED = "storage:"
#: ``Frame.image_root`` of a dataset under the data root: this, then the folder relative to ``V3D_DATA_ROOT``.
IN_DATA_ROOT = "data-root:"
#: The store's folder of uploads (``uploads/<upload>``), mirrored under the jobs folder of the node reading one.
UPLOADS = "uploads"


@dataclass(frozen=True)
class Located:
    """A dataset file: ``path`` on this machine, or ``key`` in ``storage`` (a remote store)."""

    path: Optional[Path] = None
    storage: Optional[Storage] = None
    key: Optional[str] = None


class OutsideDataset(ValueError):
    """A file name that would lead outside its dataset's folder (``..``, an absolute name, a link)."""


@dataclass(frozen=True)
class DatasetFiles:
    """The store, the data root and this node's scratch folder (the jobs folder): all a reference needs."""

    storage: Storage
    data_root: Optional[Path]
    scratch: Path

    @classmethod
    def from_settings(cls, settings: Settings) -> "DatasetFiles":
        """``V3D_STORAGE_URL``, ``V3D_DATA_ROOT`` and ``V3D_JOBS_DIR`` of ``settings``."""
        return cls(storage_for(settings), settings.data_root, jobs_dir(settings))

    def reference(self, root: str | Path) -> str:
        """What a frame records for its dataset's local folder ``root`` (see the module docstring): a key of the
        store when ``root`` is in a folder store or in this node's copy of an upload, else a path relative to the
        data root when under it, else ``root`` itself (absolute).

        >>> files = DatasetFiles(FileStorage(Path("/srv/jobs")), Path("/data"), Path("/srv/jobs"))
        >>> files.reference("/srv/jobs/uploads/u1/game"), files.reference("/data/sn/v3"), files.reference("/x")
        ('storage:uploads/u1/game', 'data-root:sn/v3', '/x')
        """
        path = Path(root)
        for base, prefix in self._bases():
            if path == base or path.is_relative_to(base):
                rest = path.relative_to(base).as_posix()
                return prefix + ("" if rest == "." else rest)
        return str(root)

    def _bases(self) -> list[tuple[Path, str]]:
        """(folder, reference prefix) pairs in the order :meth:`reference` tries them."""
        bases = []
        if isinstance(self.storage, FileStorage):
            bases.append((self.storage.root, STORED))
        bases.append((self.scratch.resolve() / UPLOADS, f"{STORED}{UPLOADS}/"))
        if self.data_root is not None:
            bases.append((Path(self.data_root).expanduser().resolve(), IN_DATA_ROOT))
        return bases

    def locate(self, root: str, relative: str) -> Located:
        """The file ``relative`` of the dataset folder ``root`` (a frame's ``image_root``), resolved: a local file
        must resolve (links followed) inside its folder; a key must be a safe name.

        Raises:
            OutsideDataset: ``relative`` leads outside the folder.
            FileNotFoundError: a ``data-root:`` reference on a node without a data root.
        """
        if root.startswith(STORED):
            try:
                key = join_key(root[len(STORED):], relative)
            except ValueError:
                raise OutsideDataset(relative) from None
            if self.storage.local_path(key) is None:
                return Located(storage=self.storage, key=key)
            assert isinstance(self.storage, FileStorage)  # the one store with local files
            return Located(path=_inside(self.storage.root.joinpath(*root[len(STORED):].split("/")), relative))
        if root.startswith(IN_DATA_ROOT):
            if self.data_root is None:
                raise FileNotFoundError("the dataset lies under the data root, and V3D_DATA_ROOT is not set here")
            base = _inside(Path(self.data_root).expanduser(), root[len(IN_DATA_ROOT):])  # the folder itself, too
            return Located(path=_inside(base, relative))
        return Located(path=_inside(Path(root), relative))

    def local_copy(self, located: Located) -> Path:
        """A local file (or folder) holding ``located``: itself, or this node's copy of the key under
        ``<jobs dir>/cache/`` (fetched once; a folder key, e.g. ISSIA's numbered frames, fetched whole).

        Raises:
            FileNotFoundError: nothing stored under the key.
        """
        if located.path is not None:
            return located.path
        assert located.storage is not None and located.key is not None
        target = self.scratch.joinpath("cache", *located.key.split("/"))
        if target.exists():
            return target
        try:
            return located.storage.get_file(located.key, target)
        except FileNotFoundError:
            return located.storage.get_tree(located.key, target)

    def upload_key(self, folder: Path) -> str:
        """The key of the upload unpacked into the local ``folder`` (``uploads/<folder name>``)."""
        return join_key(UPLOADS, folder.name)

    def upload_folder(self, key: str) -> Path:
        """A local folder holding the upload ``key``: the store's own folder (a folder store), this node's copy
        (``<jobs dir>/uploads/<upload>``, the folder it was unpacked into when received here), or a copy fetched
        now from the store (whole, or not at all).

        Raises:
            FileNotFoundError: the upload is not in the store (removed, or never stored).
        """
        own = self.storage.local_path(key)
        if own is not None and own.is_dir():
            return own
        local = self.scratch.joinpath(*key.split("/"))
        if local.is_dir():
            return local
        return self.storage.get_tree(key, local)


def _inside(base: Path, relative: str) -> Path:
    """``base / relative`` resolved, refused when it lands outside ``base`` (resolved too)."""
    root = base.resolve()
    resolved = (root / relative).resolve()
    if not resolved.is_relative_to(root):
        raise OutsideDataset(relative)
    return resolved


def rekey_frames(session: Session, folder: Path, reference: str) -> int:
    """Give the frames recorded under the local ``folder`` (absolute, as the import stored them) the ``reference``
    of that folder (``storage:...`` or ``data-root:...``), in one statement; the number of frames changed. The
    caller commits."""
    from app.db.models import Frame

    root = str(folder)
    if reference == root:
        return 0
    # the separator after the folder is kept, unless the reference names the root itself (``data-root:``)
    rest = sa.func.substr(Frame.image_root, len(root) + (2 if reference.endswith(":") else 1))
    result = session.execute(
        sa.update(Frame)
        .where(sa.or_(Frame.image_root == root, Frame.image_root.startswith(root + "/", autoescape=True)))
        .values(image_root=sa.literal(reference) + rest)
        .execution_options(synchronize_session=False))
    return int(getattr(result, "rowcount", 0) or 0)
