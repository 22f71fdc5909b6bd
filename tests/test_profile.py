"""``V3D_PROFILE=paper`` (issue 19, item 5): the paper's choices where v3d's defaults differ, an explicit ``V3D_*``
setting still winning; the monocular benchmark's default estimator follows the profile's box."""
from __future__ import annotations

import pytest

from app.core.config import PAPER_PROFILE, Settings
from app.services.evaluation.monocular import default_estimator


@pytest.fixture(autouse=True)
def _clean_env(monkeypatch):
    for name in ("V3D_PROFILE", "V3D_OPTIMISED_BOX_METHOD", "V3D_MIN_PARALLAX_DEG"):
        monkeypatch.delenv(name, raising=False)


def test_default_profile_keeps_v3ds_choices():
    s = Settings(_env_file=None)
    assert (s.profile, s.optimised_box_method, s.min_parallax_deg) == ("v3d", "exact_ray", 2.0)
    assert default_estimator(s.optimised_box_method) == "exact"


def test_paper_profile_sets_the_papers_choices(monkeypatch):
    monkeypatch.setenv("V3D_PROFILE", "paper")
    s = Settings(_env_file=None)
    assert {k: getattr(s, k) for k in PAPER_PROFILE} == {"optimised_box_method": "paper", "min_parallax_deg": 0.0,
                                                        "export_ball_box": "optimised", "ball_rule": "weights"}
    assert default_estimator(s.optimised_box_method) == "paper"
    assert s.model_copy(update={"database_url": "sqlite://"}).optimised_box_method == "paper"


def test_an_explicit_setting_wins_over_the_profile(monkeypatch):
    monkeypatch.setenv("V3D_PROFILE", "paper")
    monkeypatch.setenv("V3D_MIN_PARALLAX_DEG", "1.5")
    s = Settings(_env_file=None)
    assert (s.optimised_box_method, s.min_parallax_deg) == ("paper", 1.5)
    assert Settings(_env_file=None, optimised_box_method="exact_fused").optimised_box_method == "exact_fused"


def test_an_unknown_profile_is_refused(monkeypatch):
    monkeypatch.setenv("V3D_PROFILE", "fast")
    with pytest.raises(ValueError, match="profile"):
        Settings(_env_file=None)


def test_the_paper_profile_exports_the_optimised_box(monkeypatch):
    """The export's ball box is one of the paper's choices: its detectors were trained on optimised boxes."""
    assert Settings(_env_file=None).export_ball_box == "refined"
    monkeypatch.setenv("V3D_PROFILE", "paper")
    assert Settings(_env_file=None).export_ball_box == "optimised"
