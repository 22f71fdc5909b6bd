"""A ``V3D_*`` variable v3d cannot run with ends ``v3d serve`` at once with one line naming the variable and what it
accepts, status 2, nothing served and no traceback; the check itself (``app.core.config``) on many values."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from app.core.config import SettingsError, get_settings
from app.core.paths import PROJECT_ROOT

_V3D = "import sys; from app.cli import main; sys.argv = ['v3d', *sys.argv[1:]]; main()"

NODE_WORDS = "V3D_NODE_NAME must be 1 to 120 printable characters without a colon or a space"
STORE_WORDS = "V3D_STORAGE_URL must be file:///ABSOLUTE/FOLDER or s3://BUCKET/PREFIX: "


@pytest.mark.processes
def test_serve_refuses_bad_settings_in_one_line(tmp_path: Path) -> None:
    env = {k: v for k, v in os.environ.items() if not k.startswith("V3D_")}
    env.update(PYTHONPATH=str(PROJECT_ROOT), V3D_DATABASE_URL=f"sqlite:///{tmp_path / 'v3d.sqlite3'}",
               V3D_NODE_NAME="node a", V3D_STORAGE_URL="file://relative/folder")
    done = subprocess.run([sys.executable, "-c", _V3D, "serve", "--port", "9"], env=env, cwd=tmp_path,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 2, (done.stdout, done.stderr)
    assert done.stdout == "" and done.stderr.count("\n") == 1, done.stderr
    assert done.stderr.startswith("Error: "), done.stderr
    assert NODE_WORDS in done.stderr and STORE_WORDS + "a file URL names a folder of this machine" in done.stderr
    assert not (tmp_path / "v3d.sqlite3").exists()  # refused before the database is made


@pytest.mark.parametrize(("variable", "value", "words"), [
    ("V3D_NODE_NAME", "", NODE_WORDS),
    ("V3D_NODE_NAME", "a:b", NODE_WORDS),
    ("V3D_NODE_NAME", "tab\there", NODE_WORDS),
    ("V3D_NODE_NAME", "bell\x07", NODE_WORDS),
    ("V3D_NODE_NAME", "n" * 121, NODE_WORDS),
    ("V3D_STORAGE_URL", "http://store/x", STORE_WORDS + "its scheme is neither file: nor s3:"),
    ("V3D_STORAGE_URL", "/srv/v3d", STORE_WORDS + "its scheme is neither file: nor s3:"),
    ("V3D_STORAGE_URL", "file://", STORE_WORDS + "it names no absolute folder"),
    ("V3D_STORAGE_URL", "s3://My_Bucket/files", STORE_WORDS + "its bucket must be 3 to 63 lowercase letters"),
    ("V3D_STORAGE_URL", "s3://ab", STORE_WORDS + "its bucket must be 3 to 63"),
    ("V3D_STORAGE_URL", "s3://key:secret@bucket/x", STORE_WORDS + "it holds a user"),
    ("V3D_STORAGE_URL", "s3://bucket/x?versionId=1", STORE_WORDS + "it holds a user, a query"),
    ("V3D_STORAGE_URL", "s3://bucket/a/../b", STORE_WORDS + "its prefix holds a '.' or '..' part"),
])
def test_each_bad_value_is_refused_naming_its_variable(monkeypatch: pytest.MonkeyPatch, tmp_path: Path,
                                                       variable: str, value: str, words: str) -> None:
    monkeypatch.chdir(tmp_path)  # no .env
    monkeypatch.setenv(variable, value)
    get_settings.cache_clear()
    try:
        with pytest.raises(SettingsError) as refused:
            get_settings()
    finally:
        get_settings.cache_clear()
    said = str(refused.value)
    assert said.startswith(words) and "\n" not in said
    assert "secret" not in said  # the value itself is never repeated


@pytest.mark.parametrize(("variable", "value"), [
    ("V3D_NODE_NAME", "node-a"), ("V3D_NODE_NAME", "n" * 120), ("V3D_NODE_NAME", "nœud.été"),
    ("V3D_STORAGE_URL", "file:///srv/v3d"), ("V3D_STORAGE_URL", "file://localhost/srv/v3d"),
    ("V3D_STORAGE_URL", "s3://v3d/files"), ("V3D_STORAGE_URL", "s3://my.bucket-1"),
])
def test_good_values_are_kept(monkeypatch: pytest.MonkeyPatch, tmp_path: Path, variable: str, value: str) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv(variable, value)
    get_settings.cache_clear()
    try:
        settings = get_settings()
    finally:
        get_settings.cache_clear()
    assert getattr(settings, variable.removeprefix("V3D_").lower()) == value
