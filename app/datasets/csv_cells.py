"""CSV cells that a spreadsheet never runs (OWASP "CSV Injection").

Every CSV v3d writes (``SNv3D.csv`` of the SoccerNet-v3D export, ``ISSIA-3D.csv``) carries names from datasets:
a league, season or match folder, a frame or system name. A spreadsheet opening the file runs a cell starting with
``=``, ``+``, ``-`` or ``@`` (tab and carriage return too) as a formula: a season folder ``=HYPERLINK(...)`` became
a link in every row of the dev game. :func:`inert_cell` writes such a cell with a leading ``'`` (the spreadsheet
then shows it as text) and :func:`read_cell`, used by every reader of those files, takes it away again, so an
export re-imports exactly. Numbers stay numbers (``-2.5``, written by v3d, is no formula); a cell that already
starts with ``'`` gets one more, so that reading undoes exactly what writing did.
"""
from __future__ import annotations

import re
from typing import Iterable

#: First characters that make a spreadsheet read a cell as a formula (OWASP).
FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")
_ESCAPED_STARTS = (*FORMULA_STARTS, "'")
#: A plain decimal number (no backtracking: each part is matched one way only).
_NUMBER = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?")


def inert_cell(cell: str) -> str:
    """``cell`` as written to a CSV: with a leading ``'`` when it starts with one of :data:`FORMULA_STARTS` (or with
    ``'`` itself) and is not a plain number.

    >>> inert_cell('=HYPERLINK("evil.example","y")'), inert_cell("-2+3"), inert_cell("-2.5"), inert_cell("2_1.png")
    ('\\'=HYPERLINK("evil.example","y")', "'-2+3", '-2.5', '2_1.png')
    >>> inert_cell("'quoted"), inert_cell("@user"), inert_cell("")
    ("''quoted", "'@user", '')
    """
    if cell.startswith(_ESCAPED_STARTS) and not _NUMBER.fullmatch(cell):
        return "'" + cell
    return cell


def read_cell(cell: str) -> str:
    """The cell :func:`inert_cell` was given: one leading ``'`` taken away when the next character is one it
    escapes; any other cell as it is (so files written before the escape read as they did).

    >>> [read_cell(inert_cell(c)) for c in ["=1+1", "-2+3", "''a", "'b", "-2.5", "x"]]
    ['=1+1', '-2+3', "''a", "'b", '-2.5', 'x']
    >>> read_cell("'plain")
    "'plain"
    """
    if cell[:1] == "'" and cell[1:2] and cell[1:].startswith(_ESCAPED_STARTS):
        return cell[1:]
    return cell


def inert_row(cells: Iterable[str]) -> list[str]:
    """:func:`inert_cell` of every cell of a row."""
    return [inert_cell(c) for c in cells]
