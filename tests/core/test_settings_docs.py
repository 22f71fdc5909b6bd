"""docs/configuration.md against ``Settings``: its table "Every setting" names every ``V3D_*`` variable once, with
the default the code declares, and names nothing else."""
from __future__ import annotations

import re
from pathlib import Path

from app.core.config import Settings
from app.core.paths import PROJECT_ROOT

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
        for v, d in zip(variables, parts):
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
        default = f.default_factory() if f.default_factory is not None else f.default  # type: ignore[call-arg]
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
