"""``/api/exports``: download reviewed labels."""
from __future__ import annotations

from collections.abc import Iterator
from typing import Annotated

from fastapi import APIRouter, Query, Request
from fastapi.responses import StreamingResponse

from app.services import exporting

router = APIRouter(prefix="/exports", tags=["exports"])


@router.get(
    "/soccernet-v3d",
    response_class=StreamingResponse,
    responses={200: {"content": {"application/zip": {}}, "description": "Labels-v3D.json per game and SNv3D.csv."}},
)
def export_soccernet_v3d(
    request: Request,
    include_all: Annotated[bool, Query(alias="all", description="Every system, not only the accepted ones.")] = False,
) -> StreamingResponse:
    """A zip of the SoccerNet-v3D export (``app.services.exporting``), streamed while the database is
    read, game by game (nothing of the size of the export is built in memory or on disk).
    ``X-V3D-Systems`` and ``X-V3D-Rows`` give its size. The stream reads through a session of its own,
    closed when the download ends (the request's session closes before a streamed body is sent)."""
    session = request.app.state.session_factory()
    try:
        systems, rows = exporting.export_size(session, include_all)
        chunks = exporting.stream_soccernet_v3d_zip(session, include_all)
        first = next(chunks)  # a game name that cannot be a folder fails here, before the answer starts
    except BaseException:
        session.close()
        raise

    def body() -> Iterator[bytes]:
        try:
            yield first
            yield from chunks
        finally:
            session.close()

    return StreamingResponse(
        body(), media_type="application/zip",
        headers={"Content-Disposition": 'attachment; filename="soccernet-v3d.zip"',
                 "X-V3D-Systems": str(systems), "X-V3D-Rows": str(rows)},
    )
