"""Issue 28 item 9: every export is relocatable. Each format written as the zip a job or the UI downloads
(``exports.files.write_export_zip``) from an ISSIA stretch (ISSIA-3D rows, its cameras, YOLO and COCO images
decoded from the videos) holds no file that names the export's folder, the data root, the dataset's folder or a
/tmp path; nested zips are opened too."""
from __future__ import annotations

from app.services.exports.files import EXPORT_FORMATS, write_export_zip
from app.services.issia.sequences import import_issia
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


def test_a_tree_zips_compressed_files_as_they_are_and_deflates_the_rest_the_same_way_twice(tmp_path) -> None:
    """Images and gzip files are stored (deflating them again costs time and saves nothing), text is deflated; the
    same tree zips to the same bytes, and every member reads back as written."""
    import gzip
    import zipfile

    from app.services.exports.files import zip_tree

    root = tmp_path / "tree"
    (root / "images" / "train").mkdir(parents=True)
    (root / "images" / "val").mkdir()
    files = {"images/train/a.PNG": b"\x89PNG\r\n\x1a\n" + bytes(range(256)) * 40,
             "images/train/b.jpg": b"\xff\xd8\xff" + bytes(range(256)) * 40,
             "v3d-release/documents.jsonl.gz": gzip.compress(b'{"a":1}\n' * 500, mtime=0),
             "labels.json": b'{"images": []}' * 300}
    for name, data in files.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_bytes(data)
    zips = [zip_tree(root, tmp_path / f"{k}.zip") and (tmp_path / f"{k}.zip").read_bytes() for k in range(2)]
    assert zips[0] == zips[1]
    with zipfile.ZipFile(tmp_path / "0.zip") as zf:
        kinds = {i.filename: i.compress_type for i in zf.infolist() if not i.is_dir()}
        assert kinds == {"images/train/a.PNG": zipfile.ZIP_STORED, "images/train/b.jpg": zipfile.ZIP_STORED,
                         "v3d-release/documents.jsonl.gz": zipfile.ZIP_STORED, "labels.json": zipfile.ZIP_DEFLATED}
        assert {n: zf.read(n) for n in kinds} == files
        assert "images/val/" in zf.namelist()  # an empty folder survives
