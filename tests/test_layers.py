"""The layering the tree tells (issue 19): geometry is pure; datasets read files into records and sit below
the services; services sit below the API and the CLI; every system kind has its module; the modules' imports
(those inside functions included) form no circle (issue 30); the service packages stand in layers
(:data:`SERVICE_LAYERS`)."""
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
    "core": ("app.services", "app.api", "app.cli", "app.datasets", "app.geometry"),  # but ALLOWED_BELOW
    # the tables and sessions: below what reads datasets and runs services; pure geometry (JaC's gammas) is below
    "db": ("app.services", "app.api", "app.cli", "app.datasets"),
    # the two thin front ends call the services, never each other
    "api": ("app.cli",),
    "cli": ("app.api",),
}


#: package -> modules of a forbidden layer it may still import: the settings' defaults read the game's physical
#: facts (the ball's diameter) from their one home, a pure module of constants that imports nothing of app.
ALLOWED_BELOW = {"core": ("app.geometry.pitch",)}


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
           if any(name == f or name.startswith(f + ".") for f in FORBIDDEN[package])
           and name not in ALLOWED_BELOW.get(package, ())]
    assert not bad, f"app/{package} imports a layer above it:\n" + "\n".join(bad)


def _module_graph() -> dict[str, set[str]]:
    """app's modules (a package by its ``__init__``) -> the app modules each imports, anywhere in it: ``from a.b
    import c`` names module ``a.b.c`` when that is one, else ``a.b``. One kind of import is no edge: a type-only
    import (under ``if TYPE_CHECKING:``, never run) of a sibling module of the same package, as the models'
    relationships name the models of the other domains (``app.db.models``: the registry resolves them)."""
    modules = {".".join(p.relative_to(APP.parent).with_suffix("").parts).removesuffix(".__init__"): p
               for p in APP.rglob("*.py")}
    graph: dict[str, set[str]] = {m: set() for m in modules}
    for module, path in modules.items():
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        type_only = {id(n) for block in ast.walk(tree) if isinstance(block, ast.If)
                     and isinstance(block.test, ast.Name) and block.test.id == "TYPE_CHECKING"
                     for stmt in block.body for n in ast.walk(stmt)}
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                if id(node) in type_only and node.module.rpartition(".")[0] == module.rpartition(".")[0]:
                    continue  # a sibling's model named by a relationship's annotation only
                names = [f"{node.module}.{a.name}" for a in node.names]
                graph[module] |= {n for n in names if n in modules} or ({node.module} & modules.keys())
            elif isinstance(node, ast.Import):
                graph[module] |= {a.name for a in node.names} & modules.keys()
        graph[module].discard(module)
    return graph


def _circles(graph: dict[str, set[str]]) -> list[set[str]]:
    """The graph's strongly connected components of more than one module (Tarjan's algorithm, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[set[str]] = []
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            v, children = work[-1]
            w = next(children, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                elif w in on_stack:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                component = set()
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    component.add(w)
                    if w == v:
                        break
                if len(component) > 1:
                    out.append(component)
    return out


def test_the_circle_finder_finds_a_circle_and_nothing_else():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a", "d"}, "d": set(), "e": {"d"}}
    assert _circles(graph) == [{"a", "b", "c"}]
    assert _circles({"a": {"b"}, "b": set()}) == []


def test_the_imports_form_no_circle():
    """Imports inside functions count: one that hides a circle from the interpreter still ties the two modules.
    Untied by issue 30: the calibration package's (the learned prior and the kernels' warm-up sit above what they
    call), the ISSIA kind's (its services register their hooks from above, ``app.services.issia``) and the images'
    (a video frame is decoded by ``images.serving`` itself)."""
    circles = _circles(_module_graph())
    assert not circles, [sorted(c) for c in circles]


#: The service packages in layers, the lowest first: a package imports only packages of the layers below its own (at
#: any depth, inside functions and under ``TYPE_CHECKING`` too), never one of its own layer nor above. A new package
#: takes its place here.
#:
#: * the kinds' policies, the frame images, the audit log and the words the pages say read no other service;
#: * the accounts (which audit) and the calibration of stored frames (which asks the kinds and words its reasons);
#: * the derivation: everything recomputed from the labels, the doubts included;
#: * the review loop (curation), which edits, decides, reverts through the derivation;
#: * the transfers: datasets and a detector's predictions in, each export's writer out;
#: * the monocular benchmark (evaluation), which reads the exports, and the ISSIA sequences, whose import registers
#:   with the transfers' import formats;
#: * the releases, whose documents the exports' writers render;
#: * the exports as a whole (the registry binding every writer, from the database or a release, and the jobs' zips);
#: * the jobs, which run imports, recomputations and exports.
SERVICE_LAYERS: tuple[tuple[str, ...], ...] = (
    ("storage",),
    ("kinds", "images", "audit", "wording"),
    ("accounts", "calibration"),
    ("derivation",),
    ("curation",),
    ("transfer",),
    ("evaluation", "issia"),
    ("releases",),
    ("exports", "backup"),
    ("jobs",),
)


def _service_imports() -> dict[str, list[tuple[str, str]]]:
    """Each package of ``app/services`` -> ``(where, package imported)`` for every import of another service package
    by one of its modules, at any depth (``from app.services.x.y import z`` and ``import app.services.x``)."""
    out: dict[str, list[tuple[str, str]]] = {p.name: [] for p in (APP / "services").iterdir() if p.is_dir()
                                             and (p / "__init__.py").exists()}
    for package in out:
        for path in sorted((APP / "services" / package).rglob("*.py")):
            for line, name in _imports(path):
                parts = name.split(".")
                if parts[:2] == ["app", "services"] and len(parts) > 2 and parts[2] != package:
                    out[package].append((f"{path.relative_to(APP.parent)}:{line}: {name}", parts[2]))
    return out


def _upward(imports: dict[str, list[tuple[str, str]]], layers: tuple[tuple[str, ...], ...]) -> list[str]:
    """The imports of ``imports`` that reach a package of the same layer or one above (an unplaced package is above
    every layer)."""
    level = {p: i for i, layer in enumerate(layers) for p in layer}
    return [f"{where} ({package} imports {other})" for package, found in sorted(imports.items())
            for where, other in found if level.get(other, len(layers)) >= level.get(package, len(layers))]


def test_the_layer_check_finds_an_import_upward_or_sideways():
    layers = (("low",), ("mid", "side"), ("top",))
    assert _upward({"mid": [("m.py:1", "low")], "top": [("t.py:1", "mid")]}, layers) == []
    assert _upward({"low": [("l.py:2", "top")]}, layers) == ["l.py:2 (low imports top)"]
    assert _upward({"mid": [("m.py:3", "side")]}, layers) == ["m.py:3 (mid imports side)"]


def test_every_service_package_has_its_layer():
    placed = [p for layer in SERVICE_LAYERS for p in layer]
    assert len(placed) == len(set(placed)), placed
    assert sorted(placed) == sorted(_service_imports())


def test_the_service_packages_import_only_layers_below_theirs():
    """So no two packages of ``app/services`` import each other, however deep or lazy the import: a piece both need
    lives in the lower one (or in ``app/core``, ``app/db``), not behind an import inside a function."""
    upward = _upward(_service_imports(), SERVICE_LAYERS)
    assert not upward, "imports of a service package of the same layer or above:\n" + "\n".join(upward)


def test_no_module_of_app_is_imported_by_a_string():
    """``importlib.import_module("app....")`` or ``__import__`` would hide an edge from the graph above."""
    dynamic = [f"{p.relative_to(APP.parent)}:{node.lineno}"
               for p in sorted(APP.rglob("*.py"))
               for node in ast.walk(ast.parse(p.read_text(encoding="utf-8")))
               if isinstance(node, ast.Call) and (getattr(node.func, "attr", None) == "import_module"
                                                  or getattr(node.func, "id", None) in ("__import__", "import_module"))]
    assert not dynamic, dynamic


def test_the_issia_kind_finds_its_hooks_registered():
    from app.services.issia.trajectory import consensus_observations
    from app.services.kinds.issia import _hooks

    assert _hooks().consensus_observations is consensus_observations


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


def test_the_ball_diameter_is_written_once():
    """Issue 30: phi lives in ``app.geometry.pitch.BALL_DIAMETER_M``; a parameter or settings field of the ball's
    size (``ball_diameter_m``, ``ball_radius_m``) defaults to that name or one derived from it, never to a number."""
    literal = []
    for p in sorted(APP.rglob("*.py")):
        for node in ast.walk(ast.parse(p.read_text(encoding="utf-8"))):
            pairs: list[tuple[str, ast.AST | None]] = []
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                a = node.args
                pos = a.posonlyargs + a.args
                pairs += list(zip([x.arg for x in pos[len(pos) - len(a.defaults):]], a.defaults, strict=True))
                pairs += [(x.arg, d) for x, d in zip(a.kwonlyargs, a.kw_defaults, strict=True)]
            elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
                value = node.value
                if isinstance(value, ast.Call) and value.args:  # pydantic's Field(default, ...)
                    value = value.args[0]
                pairs.append((node.target.id, value))
            elif isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name):
                pairs.append((node.targets[0].id, node.value))
            for name, default in pairs:
                ball = name.lower() in ("ball_diameter_m", "ball_radius_m", "ball_diameter")
                if ball and isinstance(default, ast.Constant) and isinstance(default.value, float):
                    literal.append(f"{p.relative_to(APP.parent)}:{node.lineno}: {name} = {default.value}")
    pitch = [x for x in literal if x.startswith("app/geometry/pitch.py")]
    assert not [x for x in literal if x not in pitch], literal
    from app.geometry.pitch import BALL_DIAMETER_M
    assert BALL_DIAMETER_M == 0.22
