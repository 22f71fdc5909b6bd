"""The lock files (requirements/app.lock, requirements/test.lock, made by scripts/lock.sh) pin what a fresh
machine installs: every dependency of pyproject.toml is pinned there at a version its specifier admits (so the
raised floors past published vulnerabilities hold), every pin carries hashes, the two locks agree, and this
environment runs exactly the locked versions (the tests test what is installed)."""
from __future__ import annotations

import re
import tomllib
from importlib import metadata

import pytest
from packaging.markers import Marker
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from packaging.version import Version

from app.core.paths import PROJECT_ROOT

PIN = re.compile(r"^([A-Za-z0-9][A-Za-z0-9._-]*)==([^ ;\\]+)(?:\s*;\s*([^\\]+?))?\s*\\?$")


def _pins(kind: str) -> dict[str, list[tuple[Version, Marker | None]]]:
    """name -> [(version, marker)] of requirements/<kind>.lock; asserts each pin is followed by hashes."""
    lines = (PROJECT_ROOT / "requirements" / f"{kind}.lock").read_text(encoding="utf-8").splitlines()
    pins: dict[str, list[tuple[Version, Marker | None]]] = {}
    for i, line in enumerate(lines):
        match = PIN.match(line)
        if match:
            assert i + 1 < len(lines) and lines[i + 1].strip().startswith("--hash=sha256:"), line
            name, version, marker = match.groups()
            pins.setdefault(canonicalize_name(name), []).append((Version(version), Marker(marker) if marker else None))
    return pins


def _project() -> dict:
    return tomllib.loads((PROJECT_ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]


@pytest.mark.parametrize("kind, extras", [("app", ()), ("test", ("test",))])
def test_every_dependency_is_locked_at_a_version_its_specifier_admits(kind: str, extras: tuple[str, ...]) -> None:
    pins = _pins(kind)
    wanted = [Requirement(r) for r in _project()["dependencies"]]
    wanted += [Requirement(r) for extra in extras for r in _project()["optional-dependencies"][extra]]
    for req in wanted:
        versions = [v for v, _ in pins.get(canonicalize_name(req.name), [])]
        assert versions, f"{req.name} is not in requirements/{kind}.lock (run scripts/lock.sh)"
        assert all(req.specifier.contains(v, prereleases=True) for v in versions), (str(req), versions)


def test_the_floors_stand_past_the_published_vulnerabilities() -> None:
    """Starlette < 1.3.0 (CVE-2026-48710, CVE-2026-54282), python-multipart < 0.0.30 (CVE-2026-24486,
    CVE-2026-42561, CVE-2026-53537/8/9) and h11 < 0.16.0 (CVE-2025-43859) are refused by pyproject.toml."""
    floors = {canonicalize_name(r.name): r.specifier for r in map(Requirement, _project()["dependencies"])}
    for name, bad, good in (("starlette", "1.2.1", "1.3.0"), ("python-multipart", "0.0.29", "0.0.30"),
                            ("h11", "0.15.0", "0.16.0")):
        assert not floors[name].contains(bad) and floors[name].contains(good), name


def test_the_two_locks_agree() -> None:
    app, test = _pins("app"), _pins("test")
    for name, pins in app.items():
        assert {v for v, _ in pins} <= {v for v, _ in test.get(name, [])}, name


def test_this_environment_runs_the_locked_versions() -> None:
    for name, pins in _pins("test").items():
        here = [v for v, marker in pins if marker is None or marker.evaluate()]
        if not here:
            continue  # a package of another platform or Python
        try:
            installed = Version(metadata.version(name))
        except metadata.PackageNotFoundError:
            pytest.fail(f"{name} is locked but not installed: run scripts/test.sh (it installs from the lock)")
        assert installed in here, f"{name} {installed} installed, {[str(v) for v in here]} locked"


def test_the_readme_install_ci_and_docker_install_from_the_locks() -> None:
    """What a fresh machine installs is the lock, by every route: the README's commands and CI (scripts/serve.sh,
    scripts/test.sh and .ci/run all source scripts/_env.sh) and the Docker image, each with its hashes."""
    env = (PROJECT_ROOT / "scripts" / "_env.sh").read_text(encoding="utf-8")
    assert 'lock=requirements/$1.lock' in env and '--require-hashes -r "$lock"' in env
    assert "pip install --quiet --no-deps -e ." in env  # v3d itself adds no unlocked package
    assert '_env.sh" test' in (PROJECT_ROOT / "scripts" / "_test_env.sh").read_text(encoding="utf-8")
    assert "scripts/_test_env.sh" in (PROJECT_ROOT / ".ci" / "run").read_text(encoding="utf-8")
    for script in ("serve.sh", "test.sh"):
        assert "_env.sh" in (PROJECT_ROOT / "scripts" / script).read_text(encoding="utf-8"), script
    dockerfile = (PROJECT_ROOT / "docker" / "Dockerfile").read_text(encoding="utf-8")
    assert "pip install --require-hashes -r requirements/app.lock" in dockerfile and "--no-deps -e ." in dockerfile
    readme = (PROJECT_ROOT / "README.md").read_text(encoding="utf-8")
    assert "bash scripts/serve.sh" in readme and "bash scripts/test.sh" in readme
