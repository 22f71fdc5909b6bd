"""A finished job's result in words (``app.services.jobs.summary``), as the jobs panel shows it: an import's systems,
how many got a 3D ball and how many views no camera (linked to the queue's filter of those systems), a labels-only
import's missing images, a predictions import's counts; and the words stored in the job's result by the import."""
from __future__ import annotations

from app.services.jobs.summary import NO_CAMERA_FILTER, summary
from app.services.jobs.work import import_result
from app.services.transfer.importing import ImportReport


def test_an_import_says_its_systems_balls_and_views_without_a_camera_with_a_link_to_them():
    s = summary("import", {"systems": 256, "triangulated": 82, "refused": 87, "frames": 701,
                           "frames_without_image": 0})
    assert s["words"] == "256 systems: 82 with a 3D ball; 87 views without a camera"
    assert s["links"] == [{"text": "87 views without a camera", "query": NO_CAMERA_FILTER}]
    assert s["links"][0]["text"] in s["words"]


def test_a_labels_only_import_says_it_has_no_images_and_a_partial_one_counts_them():
    whole = summary("import", {"systems": 9, "triangulated": 9, "refused": 0, "frames": 30, "frames_without_image": 30})
    assert whole["words"] == "9 systems: 9 with a 3D ball; no images (labels only: the views show no picture)"
    assert whole["links"] == []
    some = summary("import", {"systems": 9, "triangulated": 9, "refused": 1, "frames": 30, "frames_without_image": 4})
    assert some["words"] == "9 systems: 9 with a 3D ball; 1 view without a camera; 4 views without an image"


def test_a_predictions_import_counts_predictions_not_bytes():
    s = summary("import", {"kind": "predictions", "rows": 1464, "stored": 1420, "clipped": 44, "unknown": 0,
                           "frames": 300, "systems": 90})
    assert s["words"] == "1,420 predictions on 300 views of 90 systems, 44 clipped to their image"
    assert "dropped" in summary("import", {"kind": "predictions", "stored": 10, "dropped_over_cap": 3})["words"]


def test_the_import_result_stores_its_words_once():
    report = ImportReport("x", systems=4, frames=10, triangulated=3, refused=2, frames_without_image=10)
    result = import_result(report)
    assert result["frames_without_image"] == 10
    assert result["summary"] == summary("import", result)
    assert result["summary"]["words"].startswith("4 systems: 3 with a 3D ball; 2 views without a camera; no images")
