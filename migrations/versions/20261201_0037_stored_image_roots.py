"""Frames name their dataset's folder by its key in the store or its path under the data root, not by a server path.

``frames.image_root`` held the absolute folder of the imported dataset, which only the machine that has it can read.
It now holds ``storage:<key>`` (a folder of the store, ``V3D_STORAGE_URL``: the jobs folder unless set, so an upload
unpacked in ``<jobs dir>/uploads/<upload>`` is ``storage:uploads/<upload>``) or ``data-root:<path>`` (a folder under
``V3D_DATA_ROOT``), which every node reads alike (``app.services.storage.datasets``). This revision rewrites the rows
whose folder lies in the folder store or under the data root as the settings of the migrating process name them;
the others (a command-line import of any folder, or a store that is not a folder) keep their absolute folder and are
still served where it lies. The same files are named, so every image, and every export or release zip made of them,
reads the same bytes. The downgrade writes the absolute folders back.

Revision ID: 0037
Revises: 0034
Create Date: 2026-12-01 00:00:00+00:00
"""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from urllib.parse import unquote, urlsplit

import sqlalchemy as sa
from alembic import op

revision: str = '0037'
down_revision: str | None = '0034'
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

# The prefixes as this revision writes them (app.services.storage.datasets), so that a later change leaves it alone.
_STORED, _IN_DATA_ROOT = "storage:", "data-root:"


def _roots() -> list[tuple[str, str]]:
    """(absolute folder, prefix) of the folder store and the data root, as the migrating process's settings name
    them (the jobs folder of the database being migrated: beside its SQLite file)."""
    from app.core.config import get_settings, jobs_dir

    url = op.get_bind().engine.url.render_as_string(hide_password=False)
    settings = get_settings().model_copy(update={"database_url": url})
    roots = []
    if settings.storage_url is None:
        roots.append((str(jobs_dir(settings).expanduser().resolve()), _STORED))
    elif settings.storage_url.startswith("file://"):
        roots.append((str(Path(unquote(urlsplit(settings.storage_url).path)).expanduser().resolve()), _STORED))
    if settings.data_root is not None:
        roots.append((str(Path(settings.data_root).expanduser().resolve()), _IN_DATA_ROOT))
    return roots


def upgrade() -> None:
    frames = sa.table('frames', sa.column('image_root', sa.Text))
    for root, prefix in _roots():
        # the folder itself, then what lies under it (the separator after the folder dropped)
        op.execute(frames.update().where(frames.c.image_root == root).values(image_root=prefix))
        op.execute(frames.update()
                   .where(frames.c.image_root.startswith(root.rstrip('/') + '/', autoescape=True))
                   .values(image_root=sa.literal(prefix)
                           + sa.func.substr(frames.c.image_root, len(root.rstrip('/')) + 2)))


def downgrade() -> None:
    frames = sa.table('frames', sa.column('image_root', sa.Text))
    for root, prefix in _roots():
        op.execute(frames.update().where(frames.c.image_root == prefix).values(image_root=root))
        op.execute(frames.update()
                   .where(frames.c.image_root.startswith(prefix, autoescape=True))
                   .values(image_root=sa.literal(root.rstrip('/') + '/')
                           + sa.func.substr(frames.c.image_root, len(prefix) + 1)))
