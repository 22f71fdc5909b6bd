"""Typed dependencies of the routes: the settings, a database session per request, and the lookups
that answer 404 in one place (``SystemDep``, ``FrameDep``), so that no route repeats "fetch or 404". An id
beyond the databases' 64-bit integers is a 422 naming the parameter (``app.api.schemas.DbInt``).

The app factory puts ``settings`` and ``session_factory`` on ``app.state``; tests may replace the
factory (for example by one bound to a connection whose transaction is rolled back after the test).
"""
from __future__ import annotations

from collections.abc import Iterator
from typing import Annotated

from fastapi import Depends, Path, Request
from sqlalchemy.orm import Session

from app.api.schemas import DbInt
from app.api.share import ComputeShare
from app.core.config import Settings
from app.db.models import Frame, System
from app.db.session import end_reads
from app.services.curation.writing import EditContext
from app.services.curation.writing import get_frame as _get_frame
from app.services.curation.writing import get_system as _get_system


async def get_app_settings(request: Request) -> Settings:
    """The settings the app was created with."""
    return request.app.state.settings


def get_session(request: Request) -> Iterator[Session]:
    """One session per request, closed when the request ends: a read-only transaction left open is committed (it
    wrote nothing; psycopg forgets the statements it prepared on a rollback only), anything else rolled back."""
    with request.app.state.session_factory() as session:
        yield session
        if not (session.new or session.dirty or session.deleted):
            end_reads(session)


async def edit_context(request: Request) -> EditContext:
    """A new context for the request's edit (``app.services.curation.writing.EditContext``) with the process's turns
    of recomputing edits (``app.state.edit_slots``); the route reads its audit entry's id from it afterwards. Async:
    it only makes an object, so it runs on the event loop, not through a hop to the thread pool of its own."""
    return EditContext(slots=getattr(request.app.state, "edit_slots", None))


async def compute_share(request: Request) -> ComputeShare:
    """The process's shares of previews and evaluations per user (``app.api.share``), made by the app factory."""
    return request.app.state.compute_share


SettingsDep = Annotated[Settings, Depends(get_app_settings)]
ShareDep = Annotated[ComputeShare, Depends(compute_share)]
SessionDep = Annotated[Session, Depends(get_session)]
EditDep = Annotated[EditContext, Depends(edit_context)]


#: The ``system_id`` path parameter of the system routes (the API's one id type, ``DbInt``: the database's integers).
SystemIdPath = Annotated[DbInt, Path(description="System id.")]


def system_by_id(session: SessionDep, system_id: SystemIdPath) -> System:
    """The system named by the ``system_id`` path parameter; 404 naming the id when there is none."""
    return _get_system(session, system_id)


#: The ``frame_id`` path parameter of the frame routes (``DbInt``, as every id).
FrameIdPath = Annotated[DbInt, Path(description="Frame id.")]


def frame_by_id(session: SessionDep, frame_id: FrameIdPath) -> Frame:
    """The frame named by the ``frame_id`` path parameter; 404 naming the id when there is none."""
    return _get_frame(session, frame_id)


SystemDep = Annotated[System, Depends(system_by_id)]
FrameDep = Annotated[Frame, Depends(frame_by_id)]
