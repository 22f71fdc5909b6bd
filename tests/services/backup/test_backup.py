"""``v3d backup`` and ``v3d restore`` on SQLite and a folder store, through the command line: a restored deployment
holds every row as it was (ids, times, versions, hashes), its images and its accounts; a broken archive, a target
holding data and a key the store cannot hold are refused before anything is written; a restore cut short leaves a
database that refuses to serve with words and is finished by running it again; an archive of an older schema is
migrated to head. The same across engines and stores (PostgreSQL + S3): ``test_engines.py``."""
from __future__ import annotations

import json
import sqlite3
import zipfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import sqlalchemy as sa
from alembic.script import ScriptDirectory
from sqlalchemy.orm import Session
from typer.testing import CliRunner

from app.cli._root import cli
from app.core.config import Settings, get_settings
from app.db.models import Base, Frame, User
from app.db.session import RestoreUnfinished, alembic_config, make_engine, upgrade_database
from app.services.accounts.users import authenticate_password, create_user, resolve_token
from app.services.backup.archive import MANIFEST, BrokenArchive, verify_archive
from app.services.images.serving import frame_image
from app.services.storage.datasets import DatasetFiles
from app.services.transfer.importing import import_soccernet_v3
from tests.conftest import migrate_new_database
from tests.services.datasets import write_v3_game

PASSWORD = "a long enough password"


def cli_main() -> Any:
    """The ``v3d`` command with every command module registered (as ``app.cli.main`` does)."""
    from app.cli import backup, serve, users  # noqa: F401  # they register their commands

    return cli


def invoke(env: dict[str, str], monkeypatch: pytest.MonkeyPatch, *args: str) -> Any:
    """``v3d ARGS`` with the ``V3D_*`` environment ``env`` (the settings read afresh)."""
    for name, value in env.items():
        monkeypatch.setenv(name, value)
    get_settings.cache_clear()
    try:
        return CliRunner().invoke(cli_main(), list(args))
    finally:
        get_settings.cache_clear()


def deployment(folder: Path) -> dict[str, str]:
    """The environment of a deployment on SQLite and a folder store under ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    return {"V3D_DATABASE_URL": f"sqlite:///{folder / 'v3d.sqlite3'}", "V3D_STORAGE_URL": (folder / "store").as_uri(),
            "V3D_JOBS_DIR": str(folder / "jobs"), "V3D_CALIBRATION_WORKERS": "1"}


def rows(url: str) -> dict[str, list[dict[str, Any]]]:
    """Every mapped table's rows through v3d's own models, in primary-key order (times as aware UTC datetimes, JSON
    as documents): what the service reads."""
    engine = make_engine(url)
    out: dict[str, list[dict[str, Any]]] = {}
    try:
        with engine.connect() as conn:
            for table in Base.metadata.sorted_tables:
                out[table.name] = [dict(r._mapping) for r in conn.execute(
                    sa.select(table).order_by(*table.primary_key.columns))]
    finally:
        engine.dispose()
    return out


@pytest.fixture(scope="module")
def source(shared_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """A deployment on SQLite and a folder store: three systems of the dev game imported from a folder of this
    machine (a command-line import: its images named by their path), an admin with a token, a decision and a
    comment. Made once: the tests only read it."""
    base = tmp_path_factory.mktemp("source")
    env = deployment(base / "deploy")
    tree = base / "v3"
    write_v3_game(shared_dir, tree)
    url = env["V3D_DATABASE_URL"]
    migrate_new_database(url)
    settings = Settings(_env_file=None, database_url=url, storage_url=env["V3D_STORAGE_URL"],
                        jobs_dir=Path(env["V3D_JOBS_DIR"]), calibration_workers=1)
    engine = make_engine(url)
    with Session(engine) as session:
        import_soccernet_v3(session, tree, settings)
        _user, token = create_user(session, "ana", "admin", PASSWORD)
        from app.services.curation.decisions import decide_review

        system_id = session.scalars(sa.select(Frame.system_id).order_by(Frame.id)).first()
        decide_review(session, system_id=system_id, status="accepted", actor="ana")
    engine.dispose()
    return {"env": env, "url": url, "token": token, "settings": settings, "tree": tree}


@pytest.fixture(scope="module")
def archive(source: dict[str, Any], tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``v3d backup`` of :func:`source`."""
    target = tmp_path_factory.mktemp("archive") / "v3d-backup.zip"
    with pytest.MonkeyPatch.context() as mp:
        result = invoke(source["env"], mp, "backup", str(target))
    assert result.exit_code == 0, result.output
    assert not list(target.parent.glob(".*part"))  # renamed when complete
    return target


def test_the_archive_lists_every_table_with_its_rows_and_every_member_with_its_digest(source, archive):
    manifest = verify_archive(archive)
    expected = rows(source["url"])
    counts = {t.name: t.rows for t in manifest.tables}
    assert {n: counts[n] for n in expected} == {n: len(v) for n, v in expected.items()}
    assert counts["frames"] > 0 and counts["users"] == 1 and counts["review_decisions"] >= 1
    with sqlite3.connect(source["url"].removeprefix("sqlite:///")) as conn:
        assert manifest.schema_revision == conn.execute("SELECT version_num FROM alembic_version").fetchone()[0]
    with zipfile.ZipFile(archive) as zf:
        assert sorted(zf.namelist()) == sorted([*manifest.members, MANIFEST])
    # the frames' images, read from this machine's folder, are in the archive (the game's Frames-v3.zip)
    assert [r.files for r in manifest.local_roots] == [1] and manifest.local_roots[0].root.startswith("/")


def test_a_restore_gives_back_every_row_its_images_and_its_logins(source, archive, tmp_path, monkeypatch):
    target = deployment(tmp_path / "target")
    # an import cap that would cut the source's systems: a restore writes rows, not a dataset
    result = invoke({**target, "V3D_MAX_VIEWS_PER_SYSTEM": "1"}, monkeypatch, "restore", str(archive))
    assert result.exit_code == 0, result.output
    before, after = rows(source["url"]), rows(target["V3D_DATABASE_URL"])
    for frame in before["frames"]:
        frame.pop("image_root")  # the folder of this machine: restored into the target's store
    roots = {f.pop("image_root") for f in after["frames"]}
    assert before == after
    assert len(roots) == 1 and roots.pop().startswith("storage:restored/")
    engine = make_engine(target["V3D_DATABASE_URL"])
    settings = Settings(_env_file=None, database_url=target["V3D_DATABASE_URL"],
                        storage_url=target["V3D_STORAGE_URL"], jobs_dir=Path(target["V3D_JOBS_DIR"]))
    source_engine = make_engine(source["url"])
    try:
        with Session(engine) as session, Session(source_engine) as old:
            frame = session.scalars(sa.select(Frame).order_by(Frame.id)).first()
            image = frame_image(frame, files=DatasetFiles.from_settings(settings))
            original = frame_image(old.get(Frame, frame.id), files=DatasetFiles.from_settings(source["settings"]))
            assert image.path is None and image.zip_path is not None  # read from the target's store
            assert b"".join(image.chunks()) == b"".join(original.chunks()) and image.size > 1000
            assert authenticate_password(session, "ana", PASSWORD) is not None
            assert authenticate_password(session, "ana", "not the password") is None
            user = resolve_token(session, source["token"])
            assert isinstance(user, User) and user.name == "ana"
    finally:
        engine.dispose()
        source_engine.dispose()


@pytest.mark.parametrize("where", ["middle", "first"])
def test_a_flipped_byte_is_refused_naming_its_member_and_nothing_is_written(archive, tmp_path, monkeypatch, where):
    """Anywhere in a member's stored bytes: in the middle of its deflated rows, or its first byte (a deflate block's
    header bit, which can leave the decompressed content as it was: the stored bytes' digest sees it)."""
    broken = tmp_path / "broken.zip"
    data = bytearray(archive.read_bytes())
    with zipfile.ZipFile(archive) as zf:
        info = zf.getinfo("tables/frames.jsonl")
    at = info.header_offset  # the member's local header: its name's and extra field's lengths, then its data
    start = at + 30 + int.from_bytes(data[at + 26:at + 28], "little") + int.from_bytes(data[at + 28:at + 30], "little")
    data[start + (info.compress_size // 2 if where == "middle" else 0)] ^= 0x01  # one byte of its stored bytes
    broken.write_bytes(bytes(data))
    target = deployment(tmp_path / "target")
    result = invoke(target, monkeypatch, "restore", "--verify-only", str(broken))
    assert result.exit_code == 2 and "tables/frames.jsonl" in result.output, result.output
    result = invoke(target, monkeypatch, "restore", str(broken))
    assert result.exit_code == 2 and "tables/frames.jsonl" in result.output, result.output
    assert not Path(target["V3D_DATABASE_URL"].removeprefix("sqlite:///")).exists()
    assert not Path(target["V3D_STORAGE_URL"].removeprefix("file://")).exists()
    ok = invoke(target, monkeypatch, "restore", "--verify-only", str(archive))
    assert ok.exit_code == 0 and "whole" in ok.output, ok.output


def test_a_target_holding_data_is_refused_untouched_unless_replaced(source, archive, tmp_path, monkeypatch):
    target = deployment(tmp_path / "target")
    url = target["V3D_DATABASE_URL"]
    migrate_new_database(url)
    engine = make_engine(url)
    with Session(engine) as session:
        create_user(session, "kept", "reviewer", PASSWORD)
    engine.dispose()
    held = rows(url)
    result = invoke(target, monkeypatch, "restore", str(archive))
    assert result.exit_code == 2 and "holds data" in result.output and "users" in result.output, result.output
    assert rows(url) == held
    result = invoke(target, monkeypatch, "restore", "--replace", str(archive))
    assert result.exit_code == 0, result.output
    assert [u["name"] for u in rows(url)["users"]] == ["ana"]


def test_an_only_migrated_database_counts_as_empty(archive, tmp_path, monkeypatch):
    target = deployment(tmp_path / "target")
    migrate_new_database(target["V3D_DATABASE_URL"])  # holds the session key the migrations make, nothing else
    result = invoke(target, monkeypatch, "restore", str(archive))
    assert result.exit_code == 0, result.output


def test_a_restore_cut_short_refuses_to_serve_and_is_finished_by_running_it_again(source, archive, tmp_path,
                                                                                   monkeypatch):
    target = deployment(tmp_path / "target")
    store = Path(target["V3D_STORAGE_URL"].removeprefix("file://"))
    store.mkdir(parents=True)
    (store / "restored").write_text("a file where the restore writes a folder: its store writes fail")
    result = invoke(target, monkeypatch, "restore", str(archive))
    assert result.exit_code == 1 and "refuses to serve until `v3d restore" in result.output, result.output
    url = target["V3D_DATABASE_URL"]
    with pytest.raises(RestoreUnfinished, match="unfinished restore of .*v3d-backup.zip.*v3d restore"):
        migrate_new_database(url)
    served = invoke(target, monkeypatch, "serve")
    assert served.exit_code == 2 and "unfinished restore" in served.output, served.output
    users = invoke(target, monkeypatch, "users", "list")
    assert users.exit_code == 2 and "unfinished restore" in users.output, users.output
    (store / "restored").unlink()
    result = invoke(target, monkeypatch, "restore", str(archive))
    assert result.exit_code == 0, result.output
    migrate_new_database(url)  # whole: served again
    before, after = rows(source["url"]), rows(url)
    for table in (before, after):
        for frame in table["frames"]:
            frame.pop("image_root")
    assert before == after


def test_a_key_the_target_store_cannot_hold_is_refused_before_anything_is_written(source, tmp_path, monkeypatch):
    env = deployment(tmp_path / "source")
    long_name = "é" * 130  # 260 bytes of UTF-8: more than a file name holds
    migrate_new_database(env["V3D_DATABASE_URL"])
    engine = make_engine(env["V3D_DATABASE_URL"])
    with engine.begin() as conn:
        conn.execute(sa.text("INSERT INTO jobs (id, kind, params, state, done, total, attempts, created_at, result) "
                             "VALUES (1, 'export', '{}', 'done', 0, 0, 1, '2026-11-28 10:00:00', :r)"),
                     {"r": json.dumps({"file": "job-1-coco.zip"})})
    engine.dispose()
    store = Path(env["V3D_STORAGE_URL"].removeprefix("file://"))
    (store / "exports").mkdir(parents=True)
    (store / "exports" / "job-1-coco.zip").write_bytes(b"PK\x05\x06" + bytes(18))
    archive = tmp_path / "a.zip"
    assert invoke(env, monkeypatch, "backup", str(archive)).exit_code == 0
    # the same archive with the export's key renamed past what a file name holds (as an S3 key of 1,000 bytes is
    # past what a bucket with a prefix holds: test_engines.py)
    hacked = tmp_path / "long.zip"
    with zipfile.ZipFile(archive) as zin, zipfile.ZipFile(hacked, "w") as zout:
        manifest = json.loads(zin.read(MANIFEST))
        for member in manifest["members"].values():  # re-zipped below: its stored bytes differ, its content not
            member.pop("stored_sha256")
        manifest["objects"] = {f"exports/{long_name}.zip": "store/exports/job-1-coco.zip"}
        for name in zin.namelist():
            if name != MANIFEST:
                zout.writestr(name, zin.read(name))
        zout.writestr(MANIFEST, json.dumps(manifest))
    target = deployment(tmp_path / "target")
    result = invoke(target, monkeypatch, "restore", str(hacked))
    assert result.exit_code == 2 and long_name[:20] in result.output and "255" in result.output, result.output
    assert not Path(target["V3D_DATABASE_URL"].removeprefix("sqlite:///")).exists()


def test_an_archive_naming_a_key_outside_the_store_is_refused(archive, tmp_path, monkeypatch):
    hacked = tmp_path / "outside.zip"
    with zipfile.ZipFile(archive) as zin, zipfile.ZipFile(hacked, "w") as zout:
        manifest = json.loads(zin.read(MANIFEST))
        for member in manifest["members"].values():  # re-zipped below: its stored bytes differ, its content not
            member.pop("stored_sha256")
        member = next(iter(manifest["members"]))
        manifest["objects"] = {"../../escaped": member}
        for name in zin.namelist():
            if name != MANIFEST:
                zout.writestr(name, zin.read(name))
        zout.writestr(MANIFEST, json.dumps(manifest))
    target = deployment(tmp_path / "target")
    result = invoke(target, monkeypatch, "restore", str(hacked))
    assert result.exit_code == 2 and "unsafe storage key" in result.output, result.output
    assert not (tmp_path / "escaped").exists() and not (tmp_path / "target" / "escaped").exists()


def test_an_archive_without_its_manifest_or_cut_short_is_refused(archive, tmp_path):
    cut = tmp_path / "cut.zip"
    cut.write_bytes(archive.read_bytes()[: archive.stat().st_size // 2])
    with pytest.raises(BrokenArchive, match="not a complete zip"):
        verify_archive(cut)
    bare = tmp_path / "bare.zip"
    with zipfile.ZipFile(archive) as zin, zipfile.ZipFile(bare, "w") as zout:
        for name in zin.namelist():
            if name != MANIFEST:
                zout.writestr(name, zin.read(name))
    with pytest.raises(BrokenArchive, match="manifest.json is missing") as err:
        verify_archive(bare)
    assert err.value.member == MANIFEST


def test_an_archive_of_an_older_schema_is_migrated_to_head(tmp_path, monkeypatch):
    from app.services.backup.snapshot import write_backup

    env = deployment(tmp_path / "old")
    url = env["V3D_DATABASE_URL"]
    upgrade_database(url, "0037")
    engine = make_engine(url)
    with engine.begin() as conn:
        conn.execute(sa.text("INSERT INTO games (id, league, season, match, source_path, created_at, version) "
                             "VALUES (7, 'l', 's', 'm', '/x', '2026-11-01 12:00:00.000000', 3)"))
    settings = Settings(_env_file=None, database_url=url, storage_url=env["V3D_STORAGE_URL"],
                        jobs_dir=Path(env["V3D_JOBS_DIR"]))
    archive = tmp_path / "old.zip"
    write_backup(engine, settings, str(archive))
    engine.dispose()
    assert verify_archive(archive).schema_revision == "0037"
    target = deployment(tmp_path / "target")
    result = invoke(target, monkeypatch, "restore", str(archive))
    assert result.exit_code == 0, result.output
    with sqlite3.connect(target["V3D_DATABASE_URL"].removeprefix("sqlite:///")) as conn:
        head = ScriptDirectory.from_config(alembic_config()).get_current_head()
        assert conn.execute("SELECT version_num FROM alembic_version").fetchone()[0] == head
    games = rows(target["V3D_DATABASE_URL"])["games"]
    assert [(g["id"], g["match"], g["version"], g["created_at"].isoformat()) for g in games] == [
        (7, "m", 3, "2026-11-01T12:00:00+00:00")]


@pytest.fixture(autouse=True)
def _fresh_settings() -> Iterator[None]:
    get_settings.cache_clear()
    yield
    get_settings.cache_clear()


def test_jobs_an_archive_held_queued_or_running_are_kept_failed_never_run_here(tmp_path, monkeypatch):
    """A job row names the machine that made it (an import's folder, an upload to clean up): restored elsewhere, a
    queued or running one is failed with words, and no runner of the target claims it."""
    from app.db.models import Job, JobState
    from app.services.backup.restore import NOT_RUN_HERE
    from app.services.jobs import runner as jobs

    env = deployment(tmp_path / "source")
    migrate_new_database(env["V3D_DATABASE_URL"])
    engine = make_engine(env["V3D_DATABASE_URL"])
    with Session(engine) as session:
        for state in (JobState.QUEUED, JobState.RUNNING, JobState.DONE):
            session.add(Job(kind="import", state=state, owner="elsewhere:1:t" if state is JobState.RUNNING else None,
                            params={"kind": "soccernet-v3", "path": "/home/someone", "upload": True}))
        session.commit()
    engine.dispose()
    archive = tmp_path / "a.zip"
    assert invoke(env, monkeypatch, "backup", str(archive)).exit_code == 0
    target = deployment(tmp_path / "target")
    result = invoke(target, monkeypatch, "restore", str(archive))
    assert result.exit_code == 0 and "2 job(s)" in result.output, result.output
    stored = rows(target["V3D_DATABASE_URL"])["jobs"]
    assert [(j["state"], j["message"]) for j in stored] == [
        (JobState.FAILED, NOT_RUN_HERE), (JobState.FAILED, NOT_RUN_HERE), (JobState.DONE, None)]
    settings = Settings(_env_file=None, database_url=target["V3D_DATABASE_URL"])
    engine = make_engine(target["V3D_DATABASE_URL"])
    try:
        from app.db.session import make_session_factory

        assert jobs.claim_next(make_session_factory(engine), "here:1:t", settings) is None
    finally:
        engine.dispose()


def forged(archive: Path, target: Path, change: Any, declared: dict[str, int] | None = None) -> Path:
    """``archive`` changed by hand as an attacker would: ``change(members, manifest)`` edits the members' bytes
    (name -> bytes) and the manifest (a dict), then every member's SHA-256 and size are redone to match (so the
    restore itself is tested, not the digest), but the sizes ``declared`` (name -> bytes), which the manifest says
    instead."""
    import hashlib

    with zipfile.ZipFile(archive) as zin:
        manifest = json.loads(zin.read(MANIFEST))
        members = {n: zin.read(n) for n in zin.namelist() if n != MANIFEST}
    change(members, manifest)
    with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as zout:
        for name, data in members.items():
            zout.writestr(name, data)
            manifest["members"][name] = {"sha256": hashlib.sha256(data).hexdigest(),
                                         "size": (declared or {}).get(name, len(data))}
        zout.writestr(MANIFEST, json.dumps(manifest))
    return target


def _nothing_written(target: dict[str, str]) -> bool:
    return (not Path(target["V3D_DATABASE_URL"].removeprefix("sqlite:///")).exists()
            and not Path(target["V3D_STORAGE_URL"].removeprefix("file://")).exists())


def test_a_member_larger_than_its_manifest_declares_is_refused_before_writing(archive, tmp_path, monkeypatch):
    """A store member that inflates to 8 MiB (the review's was 2 GiB: the bound is the same byte) while the manifest
    declares 4,096 bytes, its digest redone: refused naming it, nothing written."""
    with zipfile.ZipFile(archive) as zf:
        name = next(n for n in zf.namelist() if n.startswith(("store/", "local/")))

    def inflate(members: dict[str, bytes], manifest: dict[str, Any]) -> None:
        members[name] = bytes(8 << 20)

    hacked = forged(archive, tmp_path / "bomb.zip", inflate, declared={name: 4096})
    assert hacked.stat().st_size < 1 << 20  # zeros deflate a thousandfold
    target = deployment(tmp_path / "target")
    result = invoke(target, monkeypatch, "restore", str(hacked))
    assert result.exit_code == 2 and f"{name}: the zip says it holds 8,388,608 bytes, the manifest 4,096" in \
        result.output and "nothing was restored" in result.output, result.output
    assert _nothing_written(target)


def test_an_archive_that_does_not_fit_the_disk_is_refused_before_writing(archive, tmp_path, monkeypatch):
    target = deployment(tmp_path / "target")
    result = invoke({**target, "V3D_RESTORE_SPARE_MB": str(1 << 40)}, monkeypatch, "restore", str(archive))
    assert result.exit_code == 2 and "V3D_RESTORE_SPARE_MB" in result.output and "MB free" in result.output, \
        result.output
    assert _nothing_written(target)


def test_a_row_longer_than_the_bound_is_refused_at_the_bound(archive, tmp_path, monkeypatch):
    """A table member of one 2 MiB line (the review's was 1.5 GiB), the bound 1 MiB: refused naming the member, the
    line and the setting, with no more than the bound held."""
    def long_row(members: dict[str, bytes], manifest: dict[str, Any]) -> None:
        members["tables/audit_entries.jsonl"] = b"[" + b" " * (2 << 20) + b"]\n"

    hacked = forged(archive, tmp_path / "long.zip", long_row)
    target = deployment(tmp_path / "target")
    result = invoke({**target, "V3D_RESTORE_MAX_LINE_MB": "1"}, monkeypatch, "restore", str(hacked))
    assert result.exit_code == 2 and "tables/audit_entries.jsonl: line 1 is longer than 1,048,576 bytes" in \
        result.output and "V3D_RESTORE_MAX_LINE_MB" in result.output, result.output
    assert _nothing_written(target)


@pytest.mark.parametrize("column, value", [("image_root", "/etc"), ("image_root", "elsewhere"),
                                           ("image_path", "/etc/hostname"), ("image_zip", "../../secret.zip")])
def test_a_frame_naming_a_file_outside_the_archive_is_refused_in_words(archive, tmp_path, monkeypatch, column, value):
    def point_out(members: dict[str, bytes], manifest: dict[str, Any]) -> None:
        entry = next(t for t in manifest["tables"] if t["name"] == "frames")
        at = [c for c, _ in entry["columns"]].index(column)
        rows_ = [json.loads(line) for line in members[entry["member"]].splitlines() if line.strip()]
        rows_[0][at] = value
        members[entry["member"]] = b"".join(json.dumps(r).encode() + b"\n" for r in rows_)

    hacked = forged(archive, tmp_path / "out.zip", point_out)
    target = deployment(tmp_path / "target")
    result = invoke(target, monkeypatch, "restore", str(hacked))
    assert result.exit_code == 2 and "tables/frames.jsonl: frame" in result.output and value in result.output \
        and "nothing was restored" in result.output, result.output
    assert _nothing_written(target)



def test_a_backup_is_a_secret_on_disk(source, tmp_path, monkeypatch):
    """The archive and its ``.part`` (what a kill mid-backup leaves) are mode 0600 whatever the umask; a DEST that is
    a symbolic link is refused, its target untouched; a ``.part`` a killed backup left is named by the next one."""
    import os
    import stat

    from app.services.backup.archive import ArchiveWriter, Manifest

    old = os.umask(0o022)
    try:
        part = tmp_path / ".killed.zip.part"
        ArchiveWriter(part, Manifest("x", "x", "b", "t", "sqlite")).member("tables/x.jsonl", True).write(b"[1]\n")
        assert stat.S_IMODE(part.stat().st_mode) == 0o600  # as a SIGKILL here leaves it
        part.chmod(0o644)  # one an older v3d left
        target = tmp_path / "v3d-backup.zip"
        result = invoke(source["env"], monkeypatch, "backup", str(target))
        assert result.exit_code == 0, result.output
        assert stat.S_IMODE(target.stat().st_mode) == 0o600
        assert f"{part} was left by a backup that did not finish" in result.output, result.output
        other = tmp_path / "notes.txt"
        other.write_text("not a backup")
        link = tmp_path / "link.zip"
        link.symlink_to(other)
        result = invoke(source["env"], monkeypatch, "backup", str(link))
        assert result.exit_code == 1 and "symbolic link" in result.output, result.output
        assert other.read_text() == "not a backup" and link.is_symlink()
    finally:
        os.umask(old)


def _served_target(tmp_path: Path, url: str | None = None) -> tuple[dict[str, str], Settings]:
    """A target deployment holding data (a user), with the settings a server of it runs with."""
    target = deployment(tmp_path / "target")
    if url is not None:
        target["V3D_DATABASE_URL"] = url
    migrate_new_database(target["V3D_DATABASE_URL"])
    engine = make_engine(target["V3D_DATABASE_URL"])
    with Session(engine) as session:
        create_user(session, "kept", "reviewer", PASSWORD)
    engine.dispose()
    return target, Settings(_env_file=None, database_url=target["V3D_DATABASE_URL"],
                            storage_url=target["V3D_STORAGE_URL"], jobs_dir=Path(target["V3D_JOBS_DIR"]))


def _holder(url: str) -> Any:
    """Another process holding the database's in-use lock as a server does (``app.db.in_use.using``), ready."""
    import subprocess
    import sys

    code = ("import sys, time\nfrom app.db.in_use import using\nwith using(sys.argv[1], 'server'):\n"
            "    print('ready', flush=True)\n    time.sleep(600)\n")
    proc = subprocess.Popen([sys.executable, "-c", code, url], stdout=subprocess.PIPE,
                            cwd=Path(__file__).resolve().parents[3])
    assert proc.stdout is not None and proc.stdout.readline().strip() == b"ready"
    return proc


@pytest.mark.processes
def test_a_restore_refuses_a_database_a_server_uses_and_a_dead_servers_lock_does_not_block(archive, tmp_path,
                                                                                             monkeypatch):
    from fastapi.testclient import TestClient

    from app.main import create_app

    target, settings = _served_target(tmp_path)
    url = target["V3D_DATABASE_URL"]
    held = rows(url)
    with TestClient(create_app(settings)):  # a served app (its lifespan runs)
        result = invoke(target, monkeypatch, "restore", "--replace", str(archive))
        assert result.exit_code == 2 and "in use by a v3d server or job runner" in result.output \
            and "fuser -v" in result.output and "Nothing was restored" in result.output, result.output
        assert rows(url) == held
    server = _holder(url)  # a server of another process, then killed: its lock goes with it
    try:
        assert invoke(target, monkeypatch, "restore", "--replace", str(archive)).exit_code == 2
    finally:
        server.kill()
        server.wait()
    result = invoke(target, monkeypatch, "restore", "--replace", str(archive))
    assert result.exit_code == 0, result.output
    assert [u["name"] for u in rows(url)["users"]] == ["ana"]


@pytest.mark.postgres
@pytest.mark.processes
def test_a_restore_refuses_a_postgresql_database_a_server_uses(archive, tmp_path, monkeypatch, pg_url):
    import time

    target = {**deployment(tmp_path / "target"), "V3D_DATABASE_URL": pg_url}
    server = _holder(pg_url)  # a server of an empty database (it may serve one)
    try:
        result = invoke(target, monkeypatch, "restore", str(archive))
        assert result.exit_code == 2 and "advisory lock" in result.output and "v3d server" in result.output, \
            result.output
    finally:
        server.kill()
        server.wait()
    deadline = time.monotonic() + 20  # PostgreSQL ends the dead client's session once its socket closes
    while (result := invoke(target, monkeypatch, "restore", str(archive))).exit_code == 2 \
            and time.monotonic() < deadline:
        time.sleep(0.5)
    assert result.exit_code == 0, result.output


@pytest.mark.postgres
def test_a_restore_replaces_a_migrated_postgresql_database(archive, tmp_path, monkeypatch, pg_url):
    """--replace onto a PostgreSQL database that holds data: the migrations' functions go with its tables."""
    target, _settings = _served_target(tmp_path, pg_url)
    result = invoke(target, monkeypatch, "restore", "--replace", str(archive))
    assert result.exit_code == 0, result.output
    assert [u["name"] for u in rows(pg_url)["users"]] == ["ana"]


@pytest.mark.parametrize("admin", ["boss", "ana"])
def test_new_secrets_void_the_archives_keys_tokens_and_accounts_but_the_restoring_admin(source, archive, tmp_path,
                                                                                         monkeypatch, admin):
    """An archive someone else made: its session key, its tokens and its accounts (the author's admin among them) do
    not work on the target; the restoring admin (new, or an account of the archive taken over) does, with the password
    given and the one token printed."""
    from app.db.models import ServerSecret

    target = deployment(tmp_path / "target")
    for name, value in target.items():
        monkeypatch.setenv(name, value)
    get_settings.cache_clear()
    try:
        result = CliRunner().invoke(cli_main(), ["restore", "--new-secrets", admin, "--password-stdin",
                                                 str(archive)], input="a new long password\n")
    finally:
        get_settings.cache_clear()
    assert result.exit_code == 0 and "1 API token(s) revoked" in result.output, result.output
    token = result.stdout.strip().splitlines()[-1]
    engine = make_engine(target["V3D_DATABASE_URL"])
    source_engine = make_engine(source["url"])
    try:
        with Session(engine) as session, Session(source_engine) as old:
            assert resolve_token(session, source["token"]) is None
            assert authenticate_password(session, "ana", PASSWORD) is None
            user = resolve_token(session, token)
            assert isinstance(user, User) and user.name == admin and user.role.value == "admin"
            assert authenticate_password(session, admin, "a new long password") is not None
            disabled = {u.name: u.disabled for u in session.scalars(sa.select(User))}
            assert disabled == ({"ana": True, "boss": False} if admin == "boss" else {"ana": False})
            archived = old.get(ServerSecret, "session")
            assert archived is not None and session.get(ServerSecret, "session") is None  # made anew at the next start
            from app.db.models import AuditEntry

            entry = session.scalars(sa.select(AuditEntry).where(AuditEntry.action == "user.take_over")).one()
            assert entry.actor == admin and "1 API token revoked" in entry.summary, entry.summary
    finally:
        engine.dispose()
        source_engine.dispose()


def _forged_big(archive: Path, target: Path, member: str, pieces: Any, declared: int) -> Path:
    """``archive`` with ``member`` (new or replaced) written from the byte strings ``pieces`` as they come, never
    whole in memory, its digest redone and its size declared ``declared``; the rest copied."""
    import hashlib

    with zipfile.ZipFile(archive) as zin, zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as zout:
        manifest = json.loads(zin.read(MANIFEST))
        for name in zin.namelist():
            if name not in (MANIFEST, member):
                zout.writestr(name, zin.read(name))
        digest = hashlib.sha256()
        info = zipfile.ZipInfo(member)
        info.compress_type = zipfile.ZIP_DEFLATED
        with zout.open(info, "w", force_zip64=True) as out:
            for piece in pieces:
                digest.update(piece)
                out.write(piece)
        manifest["members"][member] = {"sha256": digest.hexdigest(), "size": declared}
        for entry in manifest["members"].values():
            entry.pop("stored_sha256", None)
        zout.writestr(MANIFEST, json.dumps(manifest))
    return target


@pytest.mark.slow
@pytest.mark.processes
def test_the_reviews_full_size_archives_are_refused_with_bounded_memory(archive, tmp_path, monkeypatch):
    """The review's sizes at the default settings: a store member inflating to 2 GiB while declaring 4,096 bytes, and
    a table member of one 1.5 GiB line (its size declared truly): both refused naming the member, nothing written, the
    restore's memory well below the line's size (each restore's own peak: ``RUSAGE_CHILDREN`` of this test process
    would also hold the peaks of every process an earlier test of its worker ran, such as the backup at scale)."""
    import subprocess
    import sys

    # runs the restore as its only child and prints that child's peak resident memory (KiB) last on stderr
    measured = ("import resource, subprocess, sys; done = subprocess.run(sys.argv[1:]); "
                "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, file=sys.stderr); "
                "sys.exit(done.returncode)")
    peaks = []

    with zipfile.ZipFile(archive) as zf:
        store = next(n for n in zf.namelist() if n.startswith(("store/", "local/")))
    zeros = bytes(1 << 24)
    bomb = _forged_big(archive, tmp_path / "bomb.zip", store, (zeros for _ in range(128)), 4096)  # 2 GiB
    line = (b"[" if i == 0 else (b"]\n" if i == 96 else b" " * (1 << 24)) for i in range(97))  # 1.48 GiB
    long_row = _forged_big(archive, tmp_path / "long.zip", "tables/audit_entries.jsonl", line, (95 << 24) + 3)
    assert bomb.stat().st_size < 16 << 20 and long_row.stat().st_size < 16 << 20
    for hacked, words in ((bomb, f"{store}: the zip says it holds 2,147,483,648 bytes, the manifest 4,096"),
                          (long_row, "tables/audit_entries.jsonl: line 1 is longer than 67,108,864 bytes")):
        target = deployment(tmp_path / f"target-{hacked.stem}")
        done = subprocess.run([sys.executable, "-c", measured, sys.executable, "-c", "from app.cli import main; main()",
                               "restore", str(hacked)],
                              env={**__import__("os").environ, **target}, capture_output=True, text=True,
                              timeout=600, cwd=Path(__file__).resolve().parents[3])
        assert done.returncode == 2 and words in done.stderr, done.stderr
        assert _nothing_written(target)
        peaks.append(int(done.stderr.strip().splitlines()[-1]))
    assert max(peaks) < 600 << 10, peaks  # KiB: the largest restore's peak


def test_a_lines_length_is_followed_across_the_chunks_it_is_read_in():
    from app.services.backup.archive import LineTooLong, _LineBound

    bound = _LineBound("tables/t.jsonl", 5)
    for chunk in (b"abc", b"de\n", b"", b"\nab", b"cde\nx"):  # lines of 5, 0, 5 and 1 bytes: each within
        bound.feed(chunk)
    with pytest.raises(LineTooLong, match="tables/t.jsonl: line 4 is longer than 5 bytes"):
        bound.feed(b"yzabc")  # the fourth line: 6 bytes
