"""The import formats are data (issue 30): every format a system kind names has a registered reader, the job runs
it by name, and an option of another format is refused with the sentence the API returns."""
from __future__ import annotations

import pytest

import app.services  # noqa: F401  # registers the ISSIA services' format
from app.services.kinds import POLICIES
from app.services.transfer.import_formats import import_format, refused_options, registered_formats


def test_every_kinds_format_has_its_reader_and_no_other_is_registered():
    named = {f for p in POLICIES.values() for f in p.import_formats}
    # besides the kinds' datasets, a detector's predictions: rows on stored frames, producing no systems
    assert set(registered_formats()) == named | {"predictions"}
    assert import_format("predictions").options == ("source",)
    assert import_format("predictions").upload_limit == "V3D_MAX_PREDICTION_IMPORT_MB"
    assert import_format("sn-calibration").options == ("width", "height")
    assert import_format("issia").options == ("from_lines", "flip")


@pytest.mark.parametrize("name, given, why", [
    ("soccernet-v3", {"width": 1920}, "width and height apply to kind 'sn-calibration' only"),
    ("issia", {"height": 1080, "flip": ["1"]}, "width and height apply to kind 'sn-calibration' only"),
    ("sn-calibration", {"width": 1920, "flip": ["2"]}, "from_lines and flip apply to kind 'issia' only"),
    ("soccernet-v3d", {"from_lines": True}, "from_lines and flip apply to kind 'issia' only"),
    ("issia", {"from_lines": True, "flip": ["1", "2"], "width": None}, None),
    ("sn-calibration", {"width": 1920, "height": 1080, "from_lines": False, "flip": []}, None),
])
def test_an_option_of_another_format_is_refused_by_name(name, given, why):
    assert refused_options(name, given) == why


def test_an_unknown_format_is_a_clear_error():
    with pytest.raises(ValueError, match="unknown import kind 'coco'"):
        import_format("coco")
