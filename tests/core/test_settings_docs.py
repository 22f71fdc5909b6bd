"""docs/configuration.md against ``Settings``: its table "Every setting" names every ``V3D_*`` variable once, with
the default the code declares, and names nothing else; and the settings a stored result is computed with (each
marked ``DERIVED`` where it is declared) are all in ``Settings.derived_fingerprint``."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from app.core.config import DERIVED_SETTINGS, Settings
from app.core.paths import PROJECT_ROOT
from app.services.derivation.doubts import doubt_settings

CONFIGURATION_MD = Path(__file__).resolve().parents[2] / "docs" / "configuration.md"
#: Named in the page but no setting of the service: the tests' database (said so beside it).
NOT_SETTINGS = {"V3D_TEST_DATABASE_URL"}


def _table() -> dict[str, str]:
    """Variable -> its default as the table "Every setting" writes it (a row naming several variables gives each
    its part of the comma-separated defaults)."""
    section = CONFIGURATION_MD.read_text(encoding="utf-8").split("## Every setting", 1)[1]
    out: dict[str, str] = {}
    for names, defaults in re.findall(r"^\| (`V3D_[^|]*) \| ([^|]*) \|", section, flags=re.M):
        variables = re.findall(r"`(V3D_[A-Z0-9_]+)`", names)
        parts = [d.strip() for d in defaults.split(",")] if len(variables) > 1 else [defaults.strip()]
        assert len(parts) == len(variables), (names, defaults)
        for v, d in zip(variables, parts, strict=True):
            assert v not in out, f"{v} documented twice"
            out[v] = d
    return out


def _reads_as(written: str, default: object, field: str) -> bool:
    """The default the docs write is the code's: a number equal to it, a bool, a code word, or for a setting
    without a value (``None``, an empty list) the words that say what happens then."""
    text = written.strip("`")
    if default is None:
        return not re.fullmatch(r"-?[\d.]+", text)  # "unset", or where the default then lies
    if isinstance(default, bool):
        return text == str(default).lower()
    if isinstance(default, (int, float)):
        return re.fullmatch(r"-?[\d.]+", text) is not None and float(text) == float(default)
    if isinstance(default, list):
        return not default and text in ("[]", "none")
    if field == "database_url":
        return text.replace("<checkout>", str(PROJECT_ROOT)) == default
    return text == str(default)


def test_every_variable_is_documented_with_its_default_and_nothing_else() -> None:
    documented = _table()
    fields = {f"V3D_{name.upper()}": name for name in Settings.model_fields}
    assert sorted(set(fields) - set(documented)) == [], "settings missing from docs/configuration.md"
    assert sorted(set(documented) - set(fields)) == [], "documented variables that are no setting"
    wrong = []
    for variable, name in fields.items():
        f = Settings.model_fields[name]
        default = f.default_factory() if f.default_factory is not None else f.default  # type: ignore[call-arg]  # Settings' factories take no argument
        if not _reads_as(documented[variable], default, name):
            wrong.append(f"{variable}: docs {documented[variable]!r}, code {default!r}")
    assert not wrong, wrong


def test_the_page_names_no_variable_that_does_not_exist() -> None:
    named = set(re.findall(r"V3D_[A-Z0-9_]+", CONFIGURATION_MD.read_text(encoding="utf-8")))
    fields = {f"V3D_{name.upper()}" for name in Settings.model_fields}
    assert named - fields == NOT_SETTINGS


def test_the_checker_catches_a_wrong_default() -> None:
    assert _reads_as("40", 40.0, "x") and not _reads_as("30", 40.0, "x")
    assert _reads_as("`exact_ray`", "exact_ray", "x") and not _reads_as("`paper`", "exact_ray", "x")
    assert _reads_as("true", True, "x") and not _reads_as("false", True, "x")


def test_every_setting_the_doubts_read_is_in_the_fingerprint() -> None:
    """The judge's settings come from the service's settings; changing any one of those the doubts read changes the
    fingerprint stored with each system, so stored doubts computed otherwise are counted stale."""
    base = Settings(_env_file=None)
    judge = doubt_settings(base)
    for name in Settings.model_fields:
        value = getattr(base, name)
        if not isinstance(value, (int, float)) or isinstance(value, bool):
            continue
        changed = base.model_copy(update={name: value + 1})
        if doubt_settings(changed) != judge:
            assert name in DERIVED_SETTINGS, f"the doubts read {name}, which is not marked DERIVED"


@pytest.mark.parametrize("name", DERIVED_SETTINGS)
def test_changing_a_derived_setting_changes_the_fingerprint(name: str) -> None:
    base = Settings(_env_file=None)
    value = getattr(base, name)
    other = ({"pair_error_rule": "max_px", "optimised_box_method": "paper", "ball_rule": "weights"}[name]
             if isinstance(value, str)
             else value + 1)
    assert base.model_copy(update={name: other}).derived_fingerprint() != base.derived_fingerprint()


def test_the_doubt_thresholds_are_derived_settings() -> None:
    assert {n for n in Settings.model_fields if n.startswith("doubt_")} <= set(DERIVED_SETTINGS)
    assert {"export_ball_box", "database_url", "calibration_workers"}.isdisjoint(DERIVED_SETTINGS)
    changed = Settings(_env_file=None, doubt_max_ball_height_m=30.0)
    assert changed.derived_fingerprint() != Settings(_env_file=None).derived_fingerprint()
