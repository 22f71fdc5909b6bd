"""``/api/games``: the imported games."""
from __future__ import annotations

from fastapi import APIRouter

from app.api.deps import SessionDep
from app.api.schemas import GameOut
from app.services import views

router = APIRouter(prefix="/games", tags=["games"])


@router.get("", response_model=list[GameOut])
def list_games(session: SessionDep) -> list[GameOut]:
    """Every game with its number of systems, in (league, season, match) order."""
    return [
        GameOut(id=g.id, league=g.league, season=g.season, match=g.match, systems=n)
        for g, n in views.list_games(session)
    ]
