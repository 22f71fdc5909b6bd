"""The habits the tools do not check: the code and the docs give reasons in words, not tracker numbers (a reader
has the code, not the tracker); every ``# type: ignore`` and ``# noqa`` says why it is there; no module of app
grows past 600 lines. ruff and mypy (pyproject.toml, run by .ci/run) check the rest."""
from __future__ import annotations

import re
import tokenize
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: A reference to an issue tracker's entry: "issue 29", "(issue 7)", "issues 7, 27 and 29", "issue 28's".
TRACKER_REFERENCE = re.compile(r"\bissues?\s+#?\d+", re.IGNORECASE)
#: A suppression comment (mypy's type-ignore, with its codes, or ruff's noqa, with its codes), then the rest of it.
SUPPRESSION = re.compile(r"#\s*(?:type:\s*ignore(?:\[[^\]]*\])?|noqa(?::\s*[A-Z]+[0-9]+(?:\s*,\s*[A-Z]+[0-9]+)*)?)"
                         r"(.*)$")
MAX_MODULE_LINES = 600

TEXT_SUFFIXES = {".py", ".js", ".css", ".html", ".md", ".mako", ".ini", ".json", ".txt"}


def _files(*folders: str, suffixes: set[str]) -> list[Path]:
    return sorted(p for folder in folders for p in (ROOT / folder).rglob("*")
                  if p.is_file() and p.suffix in suffixes and "__pycache__" not in p.parts)


@pytest.mark.parametrize("folder", ["app", "static", "docs"])
def test_no_tracker_numbers_stand_in_for_reasons(folder: str) -> None:
    """A comment, docstring or page says what a piece protects or why, in words: "(issue 29)" tells a reader
    nothing without the tracker, and the reason it points to is the one thing the sentence should hold."""
    found = [f"{p.relative_to(ROOT)}:{n}: {line.strip()[:120]}"
             for p in _files(folder, suffixes=TEXT_SUFFIXES)
             for n, line in enumerate(p.read_text(encoding="utf-8", errors="replace").splitlines(), start=1)
             if TRACKER_REFERENCE.search(line)]
    assert not found, "tracker references instead of reasons:\n" + "\n".join(found)


def test_every_suppression_names_its_reason() -> None:
    """``# type: ignore[code]`` and ``# noqa: CODE`` name the code they silence and, after them, why (``# type:
    ignore[union-attr]  # calibrated: cal is set``): a bare one hides whether it is still needed."""
    bare = []
    for p in _files("app", "tests", "benchmarks", "migrations", suffixes={".py"}):
        with p.open(encoding="utf-8") as fh:
            comments = [t for t in tokenize.generate_tokens(fh.readline) if t.type == tokenize.COMMENT]
        for token in comments:
            match = SUPPRESSION.search(token.string)
            if match is None:
                continue
            named = re.search(r"type:\s*ignore\[|noqa:\s*[A-Z]", match.group(0))
            reason = match.group(1).strip().lstrip("#").strip()
            if not named or not reason:
                bare.append(f"{p.relative_to(ROOT)}:{token.start[0]}: {token.line.strip()[:120]}")
    assert not bare, "suppressions without a code or a reason:\n" + "\n".join(bare)


def test_no_module_of_app_is_over_600_lines() -> None:
    """A module over 600 lines holds more than one idea; split it by idea (its public names stay importable)."""
    long = [f"{p.relative_to(ROOT)}: {n} lines" for p in _files("app", suffixes={".py"})
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_MODULE_LINES]
    assert not long, f"modules over {MAX_MODULE_LINES} lines:\n" + "\n".join(long)

