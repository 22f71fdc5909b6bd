"""Make, list and read releases: the accepted systems as they are at one moment, kept immutably.

A release's content is a set of canonical JSON documents (``app.db.types.canonical_json``: keys sorted, compact,
UTF-8; their typed shape per version: ``app.services.releases.document``, this module writing
:data:`~app.services.releases.document.DOCUMENT_VERSION`), each stored once in ``release_documents`` under its
SHA-256 (``app.db.types.json_digest``) as one gzip member (``app.db.types.compressed_json``): a system unchanged
since an earlier release names the document stored then, so a release costs one ``release_systems`` row per system
plus the documents of what changed.

* a **game document** per game holding a released system (:func:`game_document`): ``game_id``, ``league``,
  ``season``, ``match``, ``path``, ``release`` (what its imported labels file carried beside its systems,
  ``games.release``) and ``as_of`` (ISO 8601 UTC: its newest change, as the live export's ``v3d_as_of``);
* a **system document** per accepted system (:func:`system_document`): ``system_id``, ``name``, ``kind``,
  ``game_id``, ``review_status``, ``ball3d`` (world metres ``[x, y, z]``, z down, as stored JSON text),
  ``triangulation`` (its status and the settings it was computed with: ``tau_px``, ``rule``, ``min_baseline_m``;
  ``pairs``: per pair of admitted views ``[frame a id, frame b id, kept]``, what the detector exports' refined box
  reads),
  ``derived_settings`` (``Settings.derived_fingerprint``),
  ``derived_version``, ``frame_index`` (ISSIA), and ``frames``: per frame, in order,
  the export row of ``app.services.transfer.exporting.frame_row_select`` (labels, field lines, calibration, JaC,
  optimised box, reprojection error; JSON values as their stored text, enums by value) with the view's decisions
  (``view_status``, ``view_calibration_status``, ``excluded``); an ISSIA frame's ``trajectory`` (its point on the
  sequence's fitted trajectory: ``ball3d``, ``ball3d_smoothed``, ``source``, ``cam_list``); and ``accepted``
  (since document version 2): how it was accepted, by a person or in a batch after a random sample with its plan.

The release's **hash** (:func:`release_hash`) is the SHA-256 (hex) of the UTF-8 text made of one line per document,
``game <game_id> <digest>\\n`` for every game in increasing id, then ``system <system_id> <digest>\\n`` for every
system in increasing id. It depends on the content only (not on the name, note, time or author): two releases of the
same content have the same hash. docs/exports.md shows how to recompute it from a release's export.

Releases are append-only (database triggers refuse UPDATE and DELETE) and each is one audit entry
(``release.create``) written in its own transaction.
"""
from __future__ import annotations

import hashlib
import unicodedata
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from typing import Any, Optional

import sqlalchemy as sa
from sqlalchemy import select
from sqlalchemy.dialects import postgresql, sqlite
from sqlalchemy.orm import Session, aliased, undefer

from app.core.config import Settings, get_settings
from app.core.errors import ConflictError, InvalidInputError, found
from app.core.names import check_name, name_key
from app.db.models import (
    Frame,
    Game,
    Release,
    ReleaseDocument,
    ReleaseGame,
    ReleaseSystem,
    ReviewBatch,
    ReviewDecision,
    ReviewStatus,
    System,
    TrajectoryPoint,
    Triangulation,
    TriangulationPair,
)
from app.db.session import reads_as_one_snapshot
from app.db.types import canonical_json, compressed_json, decompressed_json, json_digest, utcnow
from app.db.unit import write_unit
from app.services.audit.log import local_actor, record
from app.services.curation.batches import batch_plan
from app.services.releases.document import (
    FRAME_KEYS,
    AcceptanceDocument,
    FrameDocument,
    GameDocument,
    SystemDocument,
    TrajectoryDocument,
    TriangulationDocument,
    read_game,
    read_system,
)
from app.services.releases.render import ExportSettings
from app.services.transfer.exporting import changed_at, frame_row_select, game_as_of

#: The longest release name (the column's size).
NAME_MAX = 200
#: Digests read per query (below every database's bound on an ``IN`` list).
_CHUNK = 500


@dataclass(frozen=True)
class ReleaseContent:
    """What a release names: game id -> game document digest, system id -> (game id, name, digest)."""

    games: dict[int, str]
    systems: dict[int, tuple[int, str, str]]

    @property
    def hash(self) -> str:
        """:func:`release_hash` of this content."""
        return release_hash(self.games, {sid: digest for sid, (_, _, digest) in self.systems.items()})


def release_hash(games: dict[int, str], systems: dict[int, str]) -> str:
    """The release hash: SHA-256 (64 hex digits) of one line per document, ``game <id> <digest>\\n`` in increasing
    game id, then ``system <id> <digest>\\n`` in increasing system id (the module docstring; docs/exports.md).

    >>> release_hash({}, {}) == hashlib.sha256(b"").hexdigest()
    True
    """
    h = hashlib.sha256()
    for gid in sorted(games):
        h.update(f"game {gid} {games[gid]}\n".encode())
    for sid in sorted(systems):
        h.update(f"system {sid} {systems[sid]}\n".encode())
    return h.hexdigest()


def _plain(value: Any) -> Any:
    """A row's value as JSON: enums by value, the rest as they are."""
    return value.value if hasattr(value, "value") else value


def game_document(game: Game, as_of: str) -> GameDocument:
    """The document of a released game (module docstring): its folder names, ``release`` and ``as_of``."""
    return GameDocument(game_id=game.id, league=game.league, season=game.season, match=game.match, path=game.path,
                        release=game.release, as_of=as_of)


def system_document(rows: list[Any], triangulation: Optional[TriangulationDocument], system: Any,
                    trajectory: Optional[TrajectoryDocument] = None,
                    accepted: Optional[AcceptanceDocument] = None) -> SystemDocument:
    """The document of a released system (module docstring; :data:`~app.services.releases.document.DOCUMENT_VERSION`)
    from its frames' rows (``frame_row_select`` with the view decision columns; a column the document does not name
    is not written), its triangulation, its ``systems`` row (kind, derived settings, frame index), for an ISSIA
    frame its trajectory point, and how it was accepted (:func:`acceptance`; None writes a version 1 document)."""
    first = rows[0]
    frames = tuple(FrameDocument(**{k: _plain(row._mapping[k]) for k in FRAME_KEYS}) for row in rows)
    return SystemDocument(system_id=first.system_id, name=first.system_name, kind=_plain(system.kind),
                          game_id=first.game_id, review_status=_plain(first.review_status), ball3d=first.ball3d,
                          triangulation=triangulation, derived_settings=system.derived_settings,
                          derived_version=system.derived_version, frame_index=system.frame_index, frames=frames,
                          trajectory=trajectory, accepted=accepted)


def acceptances(session: Session, batch_ids: Iterable[Optional[int]]) -> dict[Optional[int], AcceptanceDocument]:
    """How a system whose decision names each of ``batch_ids`` was accepted: None (a person's decision) ->
    ``how`` person; a batch's id -> ``how`` batch with its plan (``app.services.curation.batches``)."""
    out: dict[Optional[int], AcceptanceDocument] = {None: AcceptanceDocument(how="person")}
    ids = sorted({b for b in batch_ids if b is not None})
    for start in range(0, len(ids), _CHUNK):
        for batch in session.scalars(select(ReviewBatch).where(ReviewBatch.id.in_(ids[start:start + _CHUNK]))):
            out[batch.id] = AcceptanceDocument(
                how="batch", batch_id=batch.id, confidence=batch.confidence, max_wrong_share=batch.max_wrong_share,
                sample=len(batch.sample_ids), systems=len(batch.system_ids), plan=batch_plan(batch))
    return out


def _accepted_rows(session: Session) -> Iterator[list[Any]]:
    """The frame rows of every accepted system (every kind), one system's list at a time, in system id order."""
    V = aliased(ReviewDecision)
    query = (frame_row_select()
             .add_columns(V.status.label("view_status"), V.calibration_status.label("view_calibration_status"),
                          V.excluded)
             .outerjoin(V, V.frame_id == Frame.id)
             .where(ReviewDecision.status == ReviewStatus.ACCEPTED)
             .order_by(None).order_by(System.id, Frame.position, Frame.id))
    current: list[Any] = []
    for row in session.execute(query):
        if current and current[0].system_id != row.system_id:
            yield current
            current = []
        current.append(row)
    if current:
        yield current


def _store(session: Session, documents: dict[str, bytes]) -> int:
    """Store the canonical documents (digest -> bytes) not stored yet; how many were new."""
    digests = list(documents)
    stored: set[str] = set()
    for start in range(0, len(digests), _CHUNK):
        some = digests[start:start + _CHUNK]
        stored.update(session.scalars(select(ReleaseDocument.digest).where(ReleaseDocument.digest.in_(some))))
    new = [{"digest": d, "body": compressed_json(documents[d])} for d in digests if d not in stored]
    if new:  # a release made at the same time may store one of them first: equal digests, equal bodies
        dialect = session.get_bind().dialect.name
        insert = (postgresql.insert if dialect == "postgresql" else sqlite.insert)(ReleaseDocument)
        session.execute(insert.on_conflict_do_nothing(index_elements=["digest"]), new)
    return len(new)


def check_release_name(name: str) -> str:
    """``name`` as a release stores it (NFC): a name people read (``app.core.names.check_name``: no control or format
    character, not dots alone, 1 to :data:`NAME_MAX` characters, no space around it), and no ``/`` or ``\\`` (its
    page's address and an export's folder hold it). Raises :class:`InvalidInputError` naming ``name``."""
    name = check_name(name, "name", max_length=NAME_MAX, what="a release name")
    if any(c in "/\\" for c in name):
        raise InvalidInputError("a release name has no '/' or '\\'", field="name")
    return name


def _taken(session: Session, name: str) -> ConflictError:
    like = session.scalar(select(Release.name).where(Release.name_key == name_key(name)))
    same = like is None or like == name
    return ConflictError(f"name: a release named {like or name!r} exists"
                         + ("" if same else f" (it reads as {name!r}: names that differ only by case, accents' "
                                            "composition or compatibility forms are one name)")
                         + "; releases are immutable, choose another name")


def create_release(session: Session, name: str, note: str = "", actor: Optional[str] = None,
                   settings: Optional[Settings] = None) -> Release:
    """Make the release ``name`` of the accepted systems as they are now (module docstring), with its audit entry
    (``release.create``), and commit. The release records the settings its exports are rendered with
    (``render.ExportSettings`` of ``settings``, the process's when None: ``releases.export_settings``), so that a
    later change of them leaves its exports as they are.

    Args:
        session: database session; committed here (the release, its rows, new documents and the entry together).
        name: the release's name (:func:`check_release_name`; stored in NFC; unique by its key,
            ``app.core.names.name_key``, which the database's unique index holds).
        note: free text kept with it.
        actor: who makes it (the audit's actor; None: the machine's account).
        settings: the settings its exports are rendered with (None: ``get_settings()``).

    Returns:
        The new :class:`Release`.

    Raises:
        InvalidInputError: a name that cannot be one (field ``name``).
        ConflictError: the name, or one that reads as it (its key), is taken (HTTP 409); nothing is written.
    """
    name = check_release_name(name)
    reads_as_one_snapshot(session)
    if session.scalar(select(Release.id).where(Release.name_key == name_key(name))) is not None:
        raise _taken(session, name)
    triangulations, trajectory = _triangulations_and_trajectory(session)
    documents: dict[str, bytes] = {}
    systems: dict[int, tuple[int, str, str]] = {}
    views = 0
    system_rows = {s.id: s for s in session.execute(
        select(System.id, System.kind, System.derived_settings, System.derived_version, System.frame_index,
               ReviewDecision.batch_id)
        .join(ReviewDecision, ReviewDecision.system_id == System.id)
        .where(ReviewDecision.status == ReviewStatus.ACCEPTED))}
    accepted = acceptances(session, (s.batch_id for s in system_rows.values()))
    without_ball = 0
    for rows in _accepted_rows(session):
        sid = rows[0].system_id
        # an ISSIA frame has its place on the sequence's fitted trajectory
        document = system_document(rows, triangulations.get(sid), system_rows[sid], trajectory.get(sid),
                                   accepted[system_rows[sid].batch_id])
        without_ball += not document.has_ball3d
        canonical = canonical_json(document.as_json())
        digest = json_digest(canonical)
        documents[digest] = canonical
        systems[sid] = (rows[0].game_id, rows[0].system_name, digest)
        views += len(rows)
    game_ids = sorted({gid for gid, _, _ in systems.values()})
    games = _game_documents(session, game_ids, documents)
    content = ReleaseContent(games, systems)
    actor = actor or local_actor()
    release = Release(name=name, note=note or "", created_at=utcnow(), created_by=actor, systems=len(systems),
                      views=views, hash=content.hash,
                      export_settings=ExportSettings.of(settings or get_settings()).as_json())
    try:
        with write_unit(session, lock=False):  # in the snapshot the release read (``reads_as_one_snapshot``)
            _store(session, documents)
            session.add(release)
            try:
                session.flush()
            except sa.exc.IntegrityError as exc:  # the same name (by its key) made by another request since the check
                raise _NameTaken() from exc
            if games:
                session.execute(sa.insert(ReleaseGame), [{"release_id": release.id, "game_id": gid, "digest": d}
                                                         for gid, d in games.items()])
            if systems:
                session.execute(sa.insert(ReleaseSystem), [
                    {"release_id": release.id, "system_id": sid, "game_id": gid, "name": sname, "digest": d}
                    for sid, (gid, sname, d) in systems.items()])
            record(session, actor=actor, action="release.create",
                   after={"name": name, "hash": release.hash, "systems": release.systems, "views": views,
                          "without_ball3d": without_ball})
    except _NameTaken:  # rolled back
        raise _taken(session, name) from None
    _WITHOUT_BALL[release.hash] = without_ball
    return release


#: Release hash -> how many of its systems have no 3D ball. A release's content never changes and its hash names
#: that content, so each is counted once per process (:func:`systems_without_ball`).
_WITHOUT_BALL: dict[str, int] = {}


def systems_without_ball(session: Session, release: Release) -> int:
    """How many of ``release``'s systems were accepted with no 3D ball (``SystemDocument.has_ball3d`` false: their
    views agreed on no ball), counted from its system documents, as they were made, once per release hash and
    process (the count follows from the immutable content, so it is never stored beside it)."""
    known = _WITHOUT_BALL.get(release.hash)
    if known is None:
        digests = [digest for _, _, digest in release_content(session, release).systems.values()]
        documents = read_systems(session, digests)
        known = sum(not documents[digest].has_ball3d for digest in digests)
        _WITHOUT_BALL[release.hash] = known
    return known


def _triangulations_and_trajectory(session: Session) -> tuple[dict[int, TriangulationDocument],
                                                                dict[int, TrajectoryDocument]]:
    """Every system's triangulation (its rule and pairs, id -> document) and trajectory point (an ISSIA frame's place
    on its sequence's fitted trajectory), as the release's system documents hold them."""
    pairs: dict[int, list[tuple[int, int, bool]]] = {}
    for p in session.execute(select(TriangulationPair.system_id, TriangulationPair.frame_a_id,
                                    TriangulationPair.frame_b_id, TriangulationPair.kept)
                             .order_by(TriangulationPair.system_id, TriangulationPair.id)):
        pairs.setdefault(p.system_id, []).append((p.frame_a_id, p.frame_b_id, bool(p.kept)))
    triangulations = {t.system_id: TriangulationDocument(status=_plain(t.status), tau_px=t.tau_px, rule=t.rule,
                                                         min_baseline_m=t.min_baseline_m,
                                                         pairs=tuple(pairs.get(t.system_id, ())))
                      for t in session.execute(select(Triangulation.system_id, Triangulation.status,
                                                      Triangulation.tau_px, Triangulation.rule,
                                                      Triangulation.min_baseline_m))}
    trajectory = {t.system_id: TrajectoryDocument(ball3d=t.ball3d, ball3d_smoothed=t.ball3d_smoothed, source=t.source,
                                                  cam_list=list(t.cam_list or []))
                  for t in session.execute(select(TrajectoryPoint.system_id, TrajectoryPoint.ball3d,
                                                  TrajectoryPoint.ball3d_smoothed, TrajectoryPoint.source,
                                                  TrajectoryPoint.cam_list))}
    return triangulations, trajectory


def _game_documents(session: Session, game_ids: list[int], documents: dict[str, bytes]) -> dict[int, str]:
    """Each game's document as of its systems' last change (game id -> digest), added to ``documents`` (digest ->
    canonical JSON); read a chunk of games at a time."""
    games: dict[int, str] = {}
    for start in range(0, len(game_ids), _CHUNK):
        some = game_ids[start:start + _CHUNK]
        changed = changed_at(session, some)
        for game in session.scalars(select(Game).where(Game.id.in_(some)).options(undefer(Game.release))):
            canonical = canonical_json(game_document(game, game_as_of(game, changed.get(game.id))).as_json())
            digest = json_digest(canonical)
            documents[digest] = canonical
            games[game.id] = digest
    return games


class _NameTaken(Exception):
    """A release's name was taken by another request between its check and its write."""


def list_releases(session: Session) -> list[Release]:
    """Every release, oldest first."""
    return list(session.scalars(select(Release).order_by(Release.created_at, Release.id)))


def get_release(session: Session, name: str) -> Release:
    """The release ``name``.

    Raises:
        NotFoundError: no release has that name (HTTP 404).
    """
    stored = unicodedata.normalize("NFC", name)  # a name is stored in NFC: found however it was typed
    return found(session.scalar(select(Release).where(Release.name == stored)), "release", name)


def release_content(session: Session, release: Release) -> ReleaseContent:
    """The digests a release names (no document read)."""
    games: dict[int, str] = dict(session.execute(select(ReleaseGame.game_id, ReleaseGame.digest)
                                 .where(ReleaseGame.release_id == release.id)).all())
    systems = {sid: (gid, name, digest) for sid, gid, name, digest in session.execute(
        select(ReleaseSystem.system_id, ReleaseSystem.game_id, ReleaseSystem.name, ReleaseSystem.digest)
        .where(ReleaseSystem.release_id == release.id))}
    return ReleaseContent(games, systems)


def read_documents(session: Session, digests: Iterable[str]) -> dict[str, Any]:
    """digest -> document (decompressed and parsed) for ``digests``, read a chunk at a time
    (:func:`stored_documents`)."""
    return {digest: decompressed_json(body) for digest, body in stored_documents(session, digests)}


def read_games(session: Session, digests: Iterable[str]) -> dict[str, GameDocument]:
    """digest -> game document (``document.read_game``: any version written) for ``digests``."""
    return {digest: read_game(data) for digest, data in read_documents(session, digests).items()}


def read_systems(session: Session, digests: Iterable[str]) -> dict[str, SystemDocument]:
    """digest -> system document (``document.read_system``: any version written) for ``digests``."""
    return {digest: read_system(data) for digest, data in read_documents(session, digests).items()}


def stored_documents(session: Session, digests: Iterable[str]) -> Iterator[tuple[str, bytes]]:
    """(digest, stored body) of ``digests`` in increasing digest order, as stored: each body one gzip member of the
    document's canonical JSON, the bytes whose SHA-256 is the digest (``app.db.types.compressed_json``)."""
    wanted = sorted(set(digests))
    for start in range(0, len(wanted), _CHUNK):
        some = wanted[start:start + _CHUNK]
        bodies: dict[str, bytes] = dict(session.execute(select(ReleaseDocument.digest, ReleaseDocument.body)
                                      .where(ReleaseDocument.digest.in_(some))).all())
        for digest in some:
            yield digest, bodies[digest]


def release_summary(release: Release) -> dict[str, Any]:
    """The release as the API and the exports name it: ``name, note, created_at`` (ISO 8601 UTC),
    ``created_by, systems, views, hash``."""
    return {"name": release.name, "note": release.note, "created_at": release.created_at.isoformat(),
            "created_by": release.created_by, "systems": release.systems, "views": release.views,
            "hash": release.hash}
