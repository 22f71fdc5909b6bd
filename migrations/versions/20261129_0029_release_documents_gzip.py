"""Release documents stored as gzip members instead of zlib streams (``app.db.types.compressed_json``).

The compressed canonical JSON is the same deflate data either way; a gzip member (RFC 1952, time stamp 0) differs
from a zlib stream in its header and trailer only. Stored as gzip members, a release's documents laid one after
another are the gzip file its exports carry (``v3d-release/documents.jsonl.gz``, members concatenated), so an export
copies them instead of decompressing and compressing every document again. Each stored zlib body is rewritten as a
gzip member of the same document (its digest, the SHA-256 of the canonical JSON, unchanged); the append-only trigger
on ``release_documents`` is lifted for that rewrite alone and put back as revision 0027 made it. The audit's states
share the function but are only ever read one at a time: those stored as zlib streams stay so (the reader detects
either header).

Revision ID: 0029
Revises: 0028
Create Date: 2026-11-29 00:00:00+00:00
"""
from __future__ import annotations

import zlib
from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = '0029'
down_revision: str | None = '0028'
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_REFUSAL = "releases are append-only"
_GZIP_MAGIC = b"\x1f\x8b"
#: Rows read and rewritten per round (a release document is a few KB compressed).
_CHUNK = 500
_documents = sa.table("release_documents", sa.column("digest", sa.String), sa.column("body", sa.LargeBinary))


def _rewrite(to_gzip: bool) -> None:
    """Rewrite every body not yet in the wanted container (gzip member, or zlib stream for the downgrade)."""
    bind = op.get_bind()
    postgres = bind.dialect.name == "postgresql"
    if postgres:
        op.execute("ALTER TABLE release_documents DISABLE TRIGGER release_documents_append_only")
    else:
        op.execute("DROP TRIGGER IF EXISTS release_documents_no_update")
    digests = [d for (d,) in bind.execute(sa.select(_documents.c.digest).order_by(_documents.c.digest))]
    for start in range(0, len(digests), _CHUNK):
        rows = bind.execute(sa.select(_documents.c.digest, _documents.c.body)
                            .where(_documents.c.digest.in_(digests[start:start + _CHUNK]))).all()
        for digest, body in rows:
            body = bytes(body)
            if body.startswith(_GZIP_MAGIC) == to_gzip:
                continue
            document = zlib.decompress(body, wbits=47)  # either container
            new = zlib.compress(document, 6, wbits=31 if to_gzip else 15)
            bind.execute(sa.update(_documents).where(_documents.c.digest == digest).values(body=new))
    if postgres:
        op.execute("ALTER TABLE release_documents ENABLE TRIGGER release_documents_append_only")
    else:
        op.execute("CREATE TRIGGER release_documents_no_update BEFORE UPDATE ON release_documents "
                   f"BEGIN SELECT RAISE(ABORT, '{_REFUSAL}'); END")


def upgrade() -> None:
    _rewrite(to_gzip=True)


def downgrade() -> None:
    _rewrite(to_gzip=False)
