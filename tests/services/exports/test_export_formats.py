"""The registry of export formats (app.services.exports.formats) is every list of exports: the export job's,
the route's choices, the UI's panel (static/js/exportlist.js, written from it), the kinds' policies and the docs."""
from __future__ import annotations

import json
import re
import typing
from pathlib import Path

import pytest

from app.api.routes.exports import TreeFormat
from app.db.models import SystemKind
from app.services.exports import files as export_files
from app.services.exports.formats import (
    ExportChoice,
    ExportFormat,
    bind_writers,
    export_format,
    export_names,
    exports_js,
    register_export_format,
    tree_export_names,
)
from app.services.jobs.work import export_params
from app.services.kinds import EXPORTS as KIND_EXPORTS
from app.services.kinds import POLICIES, kinds_exported_by, policy
from app.services.kinds.exports import EXPORT_SPECS, SELECTIONS

ROOT = Path(__file__).resolve().parents[3]
EXPORTLIST_JS = ROOT / "static" / "js" / "exportlist.js"


def test_the_panels_module_is_the_registry() -> None:
    text = EXPORTLIST_JS.read_text(encoding="utf-8")
    assert text == exports_js(), ("static/js/exportlist.js is stale: "
                                  "python -m app.services.exports.formats > static/js/exportlist.js")
    entries = json.loads(text.split("/*EXPORTS*/", 1)[1].split("/*END*/", 1)[0])
    assert list(dict.fromkeys(e["format"] for e in entries)) == list(export_names())
    assert len({e["id"] for e in entries}) == len(entries)


def test_every_list_of_exports_is_the_registrys() -> None:
    assert export_files.EXPORT_FORMATS == export_names() == ("soccernet-v3d", "issia-3d", "cameras", "yolo", "coco")
    assert typing.get_args(TreeFormat) == tree_export_names() == ("issia-3d", "cameras", "yolo", "coco")
    for name in export_names():  # each export writes the systems of at least one kind
        assert name in KIND_EXPORTS and kinds_exported_by(name), name


def test_a_jobs_options_and_download_name_come_from_its_format() -> None:
    assert export_params("soccernet-v3d", True, False) == {"format": "soccernet-v3d", "all": True, "images": False}
    assert export_params("cameras") == {"format": "cameras", "all": False}
    v3d = export_format("soccernet-v3d")
    assert v3d.options == ("images",)
    assert v3d.download_name({"images": False}) == "soccernet-v3d-no-images.zip"
    assert v3d.download_name({}) == v3d.download_name({"images": True}) == "soccernet-v3d.zip"
    assert export_format("yolo").download_name({}) == "v3d-yolo.zip"


def test_a_releases_download_is_named_by_the_release() -> None:
    v3d = export_format("soccernet-v3d")
    assert v3d.download_name(export_params("soccernet-v3d", release="v1.1")) == "soccernet-v3d-v1.1.zip"
    assert v3d.download_name({"images": False, "release": "v1.0"}) == "soccernet-v3d-no-images-v1.0.zip"
    assert export_format("yolo").download_name({"release": "../2026 spring"}) == "v3d-yolo-.._2026_spring.zip"


def test_an_unknown_export_is_refused_naming_the_known_ones() -> None:
    with pytest.raises(ValueError, match="unknown export 'nope'; one of soccernet-v3d, issia-3d"):
        export_format("nope")


def test_a_format_is_written_one_way_and_its_buttons_are_unique() -> None:
    choice = ExportChoice("cameras", "Again", "the same id", "again.zip")
    with pytest.raises(ValueError, match="exactly one of tree and stream"):
        register_export_format(ExportFormat("neither", "writes nothing", (choice,)))
    with pytest.raises(ValueError, match="a choice id is taken"):
        register_export_format(ExportFormat("again", "a second cameras button", (choice,),
                                            tree=export_format("cameras").tree))
    assert "neither" not in export_names() and "again" not in export_names()


def test_the_docs_name_every_format() -> None:
    """docs/exports.md's table has one row per format (its downloads named), docs/api.md names each in a route."""
    exports_md = (ROOT / "docs" / "exports.md").read_text(encoding="utf-8")
    rows = re.findall(r"^\| `([a-z0-9-]+)` \| (.*)$", exports_md, flags=re.M)
    assert [name for name, _ in rows] == list(export_names())
    for name, rest in rows:
        for choice in export_format(name).choices:
            assert f"`{choice.download_name}`" in rest, (name, choice.download_name)
    api_md = (ROOT / "docs" / "api.md").read_text(encoding="utf-8")
    routes = " ".join(re.findall(r"`[A-Z]* ?/api/exports/[^`]*`", api_md))
    for name in export_names():
        assert re.search(rf"[/{{|]{re.escape(name)}[|}}?`]", routes), name


def test_each_entry_of_the_exports_data_has_its_writers_bound_once() -> None:
    """The registry is the exports' data (``app.services.kinds.exports``) with writers: one binding per entry, none
    without an entry, in the data's order, the words the data's."""
    source = (ROOT / "app" / "services" / "exports" / "formats.py").read_text(encoding="utf-8")
    bound = re.findall(r'^bind_writers\("([a-z0-9-]+)"', source, flags=re.M)
    assert bound == [spec.name for spec in EXPORT_SPECS] == list(export_names())
    for spec in EXPORT_SPECS:
        fmt = export_format(spec.name)
        assert (fmt.describes, fmt.choices) == (spec.describes, spec.choices)
    with pytest.raises(ValueError, match="its writers are bound already"):
        bind_writers("yolo", tree=export_format("yolo").tree)
    with pytest.raises(ValueError, match="unknown export 'nope'"):
        bind_writers("nope", tree=export_format("yolo").tree)
    assert export_format("yolo").tree is not None and list(export_names()) == bound


def test_the_kinds_exports_are_the_datas() -> None:
    """Each kind's exports (``KindPolicy.exports``) and each export's kinds are read from the one list."""
    assert kinds_exported_by("soccernet-v3d") == [SystemKind.SOCCERNET_V3]
    assert kinds_exported_by("issia-3d") == [SystemKind.ISSIA]
    assert kinds_exported_by("cameras") == [SystemKind.SOCCERNET_V3, SystemKind.SINGLE_VIEW]
    for name in ("yolo", "coco", "monocular"):
        assert kinds_exported_by(name) == [SystemKind.SOCCERNET_V3, SystemKind.SINGLE_VIEW, SystemKind.ISSIA]
    assert KIND_EXPORTS == set(SELECTIONS) == set(export_names()) | {"monocular"}
    for kind, p in POLICIES.items():
        assert p.exports == {name for name, kinds in SELECTIONS.items() if kind in kinds}
    assert policy(SystemKind.SINGLE_VIEW).exports == {"cameras", "yolo", "coco", "monocular"}
    with pytest.raises(ValueError, match="unknown export 'nope'"):
        kinds_exported_by("nope")
