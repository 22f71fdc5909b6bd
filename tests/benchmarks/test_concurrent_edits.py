"""A small ``benchmarks/concurrent_edits.py`` run: six clients on one annotator's token edit the views of four demo
systems at once through ``v3d serve --workers 2`` (balls moved 2-8 px, exclusions toggled, each with the If-Match of
what it read), on SQLite and on PostgreSQL; then ``v3d recompute`` in a new process changes no stored result."""
from __future__ import annotations

import pytest

from benchmarks import concurrent_edits
from tests.benchmarks.test_load import _postgresql


@pytest.mark.parametrize("backend", ["sqlite", pytest.param("postgresql", marks=pytest.mark.postgres)])
def test_concurrent_edits_then_a_recompute_in_a_new_process_change_nothing(backend: str) -> None:
    url = _postgresql() if backend == "postgresql" else None
    figures = concurrent_edits.run(url, clients=6, edits=6)
    statuses = figures["statuses"]
    assert sum(statuses.values()) == 36 and set(statuses) <= {200, 412}, figures
    assert statuses.get(200, 0) > 12, figures
    assert figures["changed_by_recompute"] == {}, figures
    assert figures["rows"]["triangulations"] == 9 and figures["rows"]["triangulation_pairs"] > 0, figures
