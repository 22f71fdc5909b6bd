"""``/api/games``: the imported games."""
from __future__ import annotations

from fastapi import APIRouter

from app.api.deps import SessionDep
from app.api.view_schemas import GameOut, GameRef
from app.services.curation import queue

router = APIRouter(prefix="/games", tags=["games"])


@router.get("", response_model=list[GameOut])
def list_games(session: SessionDep) -> list[GameOut]:
    """Every game with its number of systems, in (league, season, match) order."""
    return [
        GameOut(**GameRef.model_validate(g).model_dump(), systems=n) for g, n in queue.list_games(session)
    ]
