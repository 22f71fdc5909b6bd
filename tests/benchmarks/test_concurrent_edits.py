"""``benchmarks/concurrent_edits.py`` runs: clients on one annotator's token edit the views of four demo systems at
once (4 clients x 4 edits in CI's suite, the benchmark's 6 x 30 in the slow tier) through ``v3d serve --workers 2``
(balls moved 2-8 px, exclusions toggled, each with the If-Match of what it read), on SQLite and on PostgreSQL; then
``v3d recompute`` in a new process changes no stored result."""
from __future__ import annotations

import pytest

from benchmarks import concurrent_edits
from tests.benchmarks.test_load import _postgresql
from tests.conftest import sizes


@pytest.mark.parametrize("size", sizes((4, 4), (6, 30)))
@pytest.mark.parametrize("backend", ["sqlite", pytest.param("postgresql", marks=pytest.mark.postgres)])
def test_concurrent_edits_then_a_recompute_in_a_new_process_change_nothing(backend: str, size: tuple[int, int]) -> None:
    url = _postgresql() if backend == "postgresql" else None
    clients, edits = size
    figures = concurrent_edits.run(url, clients=clients, edits=edits)
    statuses = figures["statuses"]
    assert sum(statuses.values()) == clients * edits and set(statuses) <= {200, 412}, figures
    # a third of the edits at least go through: an If-Match is refused only when another client's edit of the same
    # view came between its read and its write
    assert statuses.get(200, 0) > clients * edits // 3, figures
    assert figures["changed_by_recompute"] == {}, figures
    assert figures["rows"]["triangulations"] == 9 and figures["rows"]["triangulation_pairs"] > 0, figures
