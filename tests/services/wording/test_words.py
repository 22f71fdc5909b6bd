"""The one table of words (app.services.wording.words): every code a page shows has its words, and the pages'
module (static/js/words.js) is exactly the table the server holds."""
from __future__ import annotations

import json
import re
from pathlib import Path

from app.db.models import CalibrationSource, CalibrationStatus, TriangulationStatus
from app.geometry.calibration.result import MIRROR_FLAG, PRIOR_FLAG, RADIAL_PRIOR_FLAG, RIG_FLAG
from app.geometry.doubts import INFO_KINDS, LABEL_KINDS
from app.geometry.doubts.contract import DETECTOR_KINDS
from app.geometry.pair_error import PAIR_ERROR_RULES
from app.geometry.triangulation import DROP_REASONS
from app.services.calibration.admission import GIVEN_CAMERA_FLAG
from app.services.issia.sequences import BALL_ASSISTED_FLAG, BALL_BUNDLE_FLAG
from app.services.wording.words import DOUBT_DRAWING, DOUBT_DRAWING_DEFAULT, WORDS, words_js

WORDS_JS = Path(__file__).resolve().parents[3] / "static" / "js" / "words.js"


def test_the_pages_module_is_the_servers_table() -> None:
    text = WORDS_JS.read_text(encoding="utf-8")
    assert text == words_js(), "static/js/words.js is stale: python -m app.services.wording.words > static/js/words.js"
    literal = text.split("/*WORDS*/", 1)[1].split("/*END*/", 1)[0]
    assert json.loads(literal) == WORDS


def test_the_pages_draw_a_detectors_box_from_the_contracts_list() -> None:
    """Which doubt kinds carry a detector's box is the contract's data (``DETECTOR_KINDS``, in words.js): no other
    page module names such a kind, so a new one is drawn and offered as a detector's box by its contract entry."""
    text = WORDS_JS.read_text(encoding="utf-8")
    assert json.loads(text.split("/*DETECTOR_KINDS*/", 1)[1].split("/*END*/", 1)[0]) == list(DETECTOR_KINDS)
    assert set(DETECTOR_KINDS) <= set(LABEL_KINDS) | set(INFO_KINDS)
    named = [f"{p.name}: {kind}" for p in sorted(WORDS_JS.parent.glob("*.js")) if p != WORDS_JS
             for kind in DETECTOR_KINDS if re.search(rf"[\"'`]{kind}[\"'`]", p.read_text(encoding="utf-8"))]
    assert not named, named


def test_every_code_a_page_shows_has_words_and_no_chip_is_a_code() -> None:
    assert set(WORDS["doubt"]) == set(LABEL_KINDS) | set(INFO_KINDS)
    flags = {MIRROR_FLAG, RIG_FLAG, PRIOR_FLAG, RADIAL_PRIOR_FLAG, GIVEN_CAMERA_FLAG, BALL_ASSISTED_FLAG,
             BALL_BUNDLE_FLAG, "few_lines", "radial_distortion"}
    assert flags <= set(WORDS["flag"])
    assert "ignored_class" in WORDS["flag_prefix"]
    assert set(WORDS["pair_reason"]) == set(DROP_REASONS)
    assert set(WORDS["rule"]) == set(PAIR_ERROR_RULES)
    assert set(WORDS["triangulation"]) == {s.value for s in TriangulationStatus}
    assert {s.value for s in CalibrationStatus} | {s.value for s in CalibrationSource} <= set(WORDS["calibration"])
    for group in WORDS.values():
        for code, entry in group.items():
            assert {"chip", "means"} <= set(entry) <= {"chip", "means", "tone"}, code
            assert entry.get("tone", "bad") in ("bad", "info"), code
            for text in (entry["chip"], entry["means"]):
                assert text and not re.search(r"[a-z]_[a-z]", text), (code, text)  # words, not snake_case codes


def test_the_legends_chips_are_one_per_fact_with_one_colour() -> None:
    """Over the groups the chip legend shows, a chip's words have one tone wherever they are drawn, and two
    different chips never mean the same thing (a fact has one chip)."""
    chips: dict[str, str | None] = {}
    means: dict[str, str] = {}
    for group in ("doubt", "note", "flag", "flag_prefix"):
        for code, entry in WORDS[group].items():
            assert chips.setdefault(entry["chip"], entry.get("tone")) == entry.get("tone"), (group, code)
            assert means.setdefault(entry["means"], entry["chip"]) == entry["chip"], (group, code)
    assert WORDS["note"]["not_admitted"]["chip"] == WORDS["doubt"]["below_admission"]["chip"]
    assert WORDS["flag"]["probably_mirrored"]["chip"] == WORDS["doubt"]["mirrored_labels"]["chip"]


def test_the_flags_the_calibration_writes_are_all_in_the_table() -> None:
    """Every literal flag the calibration package appends is in the table (a new flag must get its words)."""
    package = Path(__file__).resolve().parents[3] / "app" / "geometry" / "calibration"
    source = "".join(f.read_text() for f in sorted(package.glob("*.py")))
    literal = set(re.findall(r'flags\.append\("([a-z_]+)"\)', source))
    assert literal and literal <= set(WORDS["flag"])


def test_every_refusal_code_of_the_calibration_has_words_and_a_sentence() -> None:
    """The calibration refuses with codes and numbers (``REFUSAL_CODES``); the words table names each and writes
    its stored sentence with the numbers, so the import counts codes and a person reads words."""
    from app.geometry.calibration.result import REFUSAL_CODES, Refusal
    from app.services.issia.cameras import STATIC_CAMERA_REFUSALS
    from app.services.wording.words import REFUSAL_SENTENCES, refusal_sentence

    codes = (*REFUSAL_CODES, *STATIC_CAMERA_REFUSALS)
    assert set(codes) <= set(WORDS["refusal"]) and set(codes) == set(REFUSAL_SENTENCES)
    assert set(WORDS["refusal"]) == {*codes, "unspecified"}
    numbers = {"need": 7, "constraints": 4, "lines": 2, "error": "singular matrix", "line": "Side line top",
               "px": 70.06, "limit_px": 27.5, "rms_px": 31.2, "jac": 0.61, "gamma_pct": 0.5, "admit_jac_min": 0.75}
    sentences = {code: refusal_sentence(Refusal(code, numbers)) for code in codes}
    assert sentences["residual_too_high"] == ("residual too high: 'Side line top' is 70.1 px from its model element "
                                              "(limit 27.5 px)")
    assert sentences["below_admission"] == "JaC@0.5% 0.61 not above 0.75"
    assert all(s and "{" not in s for s in sentences.values()), sentences


def test_a_dataset_class_name_reaches_a_refusal_sentence_as_text() -> None:
    """A refusal's numbers may carry a name from the dataset (the line class of ``residual_too_high``): it is
    inserted as text, never read as a format field or markup, whatever braces or tags it holds."""
    from app.geometry.calibration.result import Refusal
    from app.services.wording.words import refusal_sentence

    hostile = "{need}{0}<img src=x onerror=alert(1)>"
    sentence = refusal_sentence(Refusal("residual_too_high", {"line": hostile, "px": 70.06, "limit_px": 27.5}))
    assert sentence == f"residual too high: {hostile!r} is 70.1 px from its model element (limit 27.5 px)"


def test_the_pages_draw_every_doubt_kind_from_the_table() -> None:
    """How a doubt of each kind is drawn (its test ids, the sentence it shows, whether it confirms a placement) is the
    table's ``DOUBT_DRAWING``, in words.js: no other page module names any doubt kind, so a new kind is drawn by its
    entries, and the two kinds drawn apart from the rest keep their test ids and sources."""
    text = WORDS_JS.read_text(encoding="utf-8")
    drawing = json.loads(text.split("/*DOUBT_DRAWING*/", 1)[1].split("/*END*/", 1)[0])
    assert drawing == DOUBT_DRAWING and set(drawing) == set(LABEL_KINDS) | set(INFO_KINDS)
    assert all(entry.keys() == DOUBT_DRAWING_DEFAULT.keys() for entry in drawing.values())
    assert drawing["mirrored_labels"] == {"message_id": "view-mirror-evidence", "sentence_from": "mirror_evidence",
                                          "fix_id": "apply-mirror", "confirms_placement": False}
    assert [k for k, e in drawing.items() if e["confirms_placement"]] == ["suggested_label"]
    assert drawing["ball_off_consensus"] == DOUBT_DRAWING_DEFAULT == {
        "message_id": "view-doubt-message", "sentence_from": None, "fix_id": "apply-fix", "confirms_placement": False}
    kinds = (*LABEL_KINDS, *INFO_KINDS)
    named = [f"{p.name}: {kind}" for p in sorted(WORDS_JS.parent.glob("*.js")) if p != WORDS_JS
             for kind in kinds if re.search(rf"[\"'`]{kind}[\"'`]", p.read_text(encoding="utf-8"))]
    assert not named, named
