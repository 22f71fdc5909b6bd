"""Frame image references become the imported dataset's folder plus a relative path (issue 15, item 1).

``frames.image_root`` (new) holds the dataset's folder; ``image_zip`` and ``image_path`` become POSIX paths
relative to it, and the image route resolves them again and refuses anything outside the folder
(``app.services.images.serving.stored_image_file``). ``frames.image_type`` (new) holds the type the image
check read from the file's header at import ("png" or "jpeg"); rows stored before it are checked when served.

Existing rows: the folder is the game's ``source_path`` when the image lies inside it, else the folder
holding the zip or file (the import's own folder is not known any more). The downgrade joins them again.

Revision ID: 0009
Revises: 0008
Create Date: 2026-11-23 00:00:00+00:00
"""
from __future__ import annotations

import posixpath
from typing import Sequence, Union

import sqlalchemy as sa
from alembic import op

revision: str = '0009'
down_revision: Union[str, None] = '0008'
branch_labels: Union[str, Sequence[str], None] = None
depends_on: Union[str, Sequence[str], None] = None

_BATCH = 2000


def _split(path: str, game_dir: str | None) -> tuple[str, str]:
    """(folder, relative path) of a stored absolute ``path``: inside the game's folder when it lies there.

    >>> _split('/d/l/s/g/Frames-v3.zip', '/d/l/s/g'), _split('/etc/passwd', '/d/l/s/g')
    (('/d/l/s/g', 'Frames-v3.zip'), ('/etc', 'passwd'))
    """
    path = posixpath.normpath(path)
    if game_dir:
        game_dir = posixpath.normpath(game_dir)
        if path.startswith(game_dir.rstrip('/') + '/'):
            return game_dir, posixpath.relpath(path, game_dir)
    return posixpath.dirname(path), posixpath.basename(path)


def upgrade() -> None:
    with op.batch_alter_table('frames', schema=None) as batch_op:
        batch_op.add_column(sa.Column('image_root', sa.Text(), nullable=True))
        batch_op.add_column(sa.Column('image_type', sa.String(length=16), nullable=True))
    conn = op.get_bind()
    rows = conn.execute(sa.text(
        "SELECT f.id, f.image_zip, f.image_path, g.source_path FROM frames f "
        "JOIN systems s ON s.id = f.system_id JOIN games g ON g.id = s.game_id "
        "WHERE f.image_zip IS NOT NULL OR f.image_path IS NOT NULL")).all()
    update = sa.text("UPDATE frames SET image_root = :root, image_zip = :zip, image_path = :path WHERE id = :id")
    params = []
    for fid, zip_path, path, game_dir in rows:
        stored = zip_path or path
        if not posixpath.isabs(stored):
            continue  # already relative (no folder known): served as missing, import it again
        root, rel = _split(stored, game_dir)
        params.append({"id": fid, "root": root, "zip": rel if zip_path else None,
                       "path": None if zip_path else rel})
        if len(params) >= _BATCH:
            conn.execute(update, params)
            params = []
    if params:
        conn.execute(update, params)


def downgrade() -> None:
    conn = op.get_bind()
    rows = conn.execute(sa.text("SELECT id, image_root, image_zip, image_path FROM frames "
                                "WHERE image_root IS NOT NULL")).all()
    update = sa.text("UPDATE frames SET image_zip = :zip, image_path = :path WHERE id = :id")
    params = [{"id": fid, "zip": posixpath.join(root, z) if z else None, "path": posixpath.join(root, p) if p else None}
              for fid, root, z, p in rows]
    for i in range(0, len(params), _BATCH):
        conn.execute(update, params[i:i + _BATCH])
    with op.batch_alter_table('frames', schema=None) as batch_op:
        batch_op.drop_column('image_type')
        batch_op.drop_column('image_root')
