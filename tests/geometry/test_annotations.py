"""Field-line annotations: the stored JSON form and the errors that name the polyline at fault."""
from __future__ import annotations

import numpy as np
import pytest

from app.geometry.annotations import (
    AnnotationError,
    from_soccernet_calibration,
    lines_from_json_lists,
    lines_to_json_lists,
)


def test_json_lists_round_trip():
    lines = {"Middle line": [np.array([[480.0, 0.0], [470.0, 539.0]])],
             "Circle central": [np.array([[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]]), np.array([[7.0, 8.0]])]}
    back = lines_from_json_lists(lines_to_json_lists(lines))
    assert back.keys() == lines.keys()
    for cls, polys in lines.items():
        for a, b in zip(polys, back[cls], strict=True):
            np.testing.assert_array_equal(a, b)


def test_polylines_that_are_not_xy_pairs_raise_annotation_errors():
    """Regression: every polyline was read with ``reshape(-1, 2)``, so [x, y, z] triples were
    silently regrouped into pairs ([[1, 2, 3], [4, 5, 6]] became three points) and a single triple
    escaped as NumPy's "cannot reshape" ValueError, which the editing service (it catches
    AnnotationError) did not turn into a 422."""
    with pytest.raises(AnnotationError, match="polyline 0: expected"):
        lines_from_json_lists({"Middle line": [[[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]]})
    with pytest.raises(AnnotationError, match="'Middle line', polyline 1"):
        lines_from_json_lists({"Middle line": [[[1.0, 2.0]], [[1.0, 2.0, 3.0]]]})
    with pytest.raises(AnnotationError, match="unknown line class"):
        lines_from_json_lists({"Penalty spot": [[[1.0, 2.0]]]})
    flat = lines_from_json_lists({"Middle line": [[1.0, 2.0, 3.0, 4.0]]})  # SoccerNet-v3's flat form
    assert flat["Middle line"][0].tolist() == [[1.0, 2.0], [3.0, 4.0]]


def test_a_nan_image_size_is_refused():
    """Regression: ``from_soccernet_calibration`` tested ``width < 2``, which NaN passes, and then
    returned NaN pixels for every point."""
    data = {"Middle line": [{"x": 0.5, "y": 0.0}, {"x": 0.5, "y": 1.0}]}
    with pytest.raises(AnnotationError, match="image size"):
        from_soccernet_calibration(data, float("nan"), 540)
    assert from_soccernet_calibration(data, 961, 541)["Middle line"][0].tolist() == [[480.0, 0.0], [480.0, 540.0]]
