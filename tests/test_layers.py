"""The layering the tree tells (issue 19): geometry is pure; datasets read files into records and sit below
the services; services sit below the API and the CLI; every system kind has its module."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

from app.db.models import SystemKind
from app.services.kinds import POLICIES, policy

APP = Path(__file__).resolve().parents[1] / "app"

#: package -> packages of ``app`` it must never import (at any depth, lazily or not).
FORBIDDEN = {
    "geometry": ("app.db", "app.services", "app.api", "app.cli", "app.datasets"),
    "datasets": ("app.services", "app.api", "app.cli", "app.db.session"),
    "services": ("app.api", "app.cli"),
    "core": ("app.services", "app.api", "app.cli", "app.datasets", "app.geometry"),
}


def _imports(path: Path) -> list[tuple[int, str]]:
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    out: list[tuple[int, str]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.append((node.lineno, node.module))
    return out


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_a_layer_imports_nothing_above_it(package):
    bad = [f"{p.relative_to(APP.parent)}:{line}: {name}"
           for p in sorted((APP / package).rglob("*.py"))
           for line, name in _imports(p)
           if any(name == f or name.startswith(f + ".") for f in FORBIDDEN[package])]
    assert not bad, f"app/{package} imports a layer above it:\n" + "\n".join(bad)


def test_the_services_folder_is_grouped_not_flat():
    flat = sorted(p.name for p in (APP / "services").glob("*.py") if p.name != "__init__.py")
    assert flat == [], f"modules left flat in app/services: {flat}"


def test_every_system_kind_has_its_policy_module():
    assert set(POLICIES) == set(SystemKind)
    for kind in SystemKind:
        p = policy(kind)
        assert p.kind is kind
        assert p.import_formats, f"{kind.value}: no dataset format produces it"
        assert p.exports, f"{kind.value}: no export takes it"
