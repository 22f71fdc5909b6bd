"""Issue 28 item 9: every export is relocatable. Each format written as the zip a job or the UI downloads
(``export_files.write_export_zip``) from an ISSIA stretch (ISSIA-3D rows, its cameras, YOLO and COCO images
decoded from the videos) holds no file that names the export's folder, the data root, the dataset's folder or a
/tmp path; nested zips are opened too."""
from __future__ import annotations

from app.services.issia.sequences import import_issia
from app.services.transfer.export_files import EXPORT_FORMATS, write_export_zip
from tests.services.datasets import zip_files
from tests.services.issia_data import write_issia_stretch


def test_no_file_of_any_export_names_a_server_folder(db_session, db_settings, shared_dir, tmp_path):
    dataset = write_issia_stretch(shared_dir, tmp_path / "issia-dev", 10, 17)
    import_issia(db_session, dataset, db_settings)
    out = tmp_path / "exports"
    out.mkdir()
    forbidden = {str(tmp_path), str(out), str(dataset.resolve()), str(db_settings.data_root), "/tmp/"}
    sizes = {}
    for fmt in EXPORT_FORMATS:
        report = write_export_zip(db_session, fmt, out / f"{fmt}.zip", True, db_settings)
        assert sorted(p.name for p in out.iterdir()) == sorted(f"{f}.zip" for f in sizes | {fmt: 0})  # no work left
        files = zip_files((out / f"{fmt}.zip").read_bytes())
        sizes[fmt] = len(files)
        for name, raw in files.items():
            assert not name.startswith("/") and ".." not in name.split("/"), (fmt, name)
            if name.endswith((".png", ".jpg")):
                continue
            for folder in forbidden:
                assert folder.encode() not in raw, f"{fmt}: {name} names {folder}"
        assert report["format"] == fmt and "out_dir" not in report
    assert sizes["issia-3d"] >= 8  # ISSIA-3D.csv, split.json, six camera files (and their folders)
    assert sizes["yolo"] > 8 and sizes["coco"] > 4
