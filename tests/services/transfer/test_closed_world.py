"""A dataset is a closed world (issue 15, item 1): every file an import reads resolves, links included,
inside the imported folder; anything else refuses the import naming the file and the field, before anything
is stored. Stored image references are the dataset's folder plus a relative path, checked again when
served. Each test is an attack of the issue's "Why" that worked on the main of 2026-11-22."""
from __future__ import annotations

import json
import os
import zipfile
from pathlib import Path

import cv2
import numpy as np
import pytest
import sqlalchemy as sa

from app.core.errors import DatasetError
from app.db.models import Frame, Game
from app.services.images.serving import ImageUnavailable, frame_image
from app.services.issia.sequences import import_issia
from app.services.transfer.exporting import export_soccernet_v3d
from app.services.transfer.importing import import_sn_calibration, import_soccernet_v3, import_soccernet_v3d

from ..datasets import write_calibration_zip, write_v3_game
from ..issia_data import write_issia_stretch

pytestmark = pytest.mark.shared


def _games(session) -> int:
    return session.scalar(sa.select(sa.func.count()).select_from(Game))


def _export(db_session, settings, v3_tree: Path, out: Path, images: bool = False) -> Path:
    """The v3_tree imported then exported (every system; its images as Frames-v3.zip when ``images``, else
    none, so that a frame's ``v3d.image`` is what a re-import reads) to ``out``; the database emptied again."""
    import_soccernet_v3(db_session, v3_tree, settings)
    export_soccernet_v3d(db_session, out, include_all=True, images=images)
    db_session.execute(sa.delete(Game))
    db_session.commit()
    return out


def test_a_v3d_frame_naming_etc_passwd_is_refused_naming_the_field(db_session, settings, v3_tree, tmp_path):
    """Was: ``"v3d": {"image": {"path": "/etc/passwd"}}`` imported, and every annotator read the file."""
    out = _export(db_session, settings, v3_tree, tmp_path / "export")
    labels = next(out.rglob("Labels-v3D.json"))
    for image in ({"path": "/etc/passwd"}, {"path": "../../../../../../etc/passwd"},
                  {"zip": "/etc/passwd", "member": "0.png"}):
        data = json.loads(labels.read_text())
        data["actions"]["0.png"]["v3d"]["image"] = image
        labels.write_text(json.dumps(data))
        with pytest.raises(DatasetError, match=r"actions\['0.png'\]\.v3d\.image\.(path|zip): resolves outside"):
            import_soccernet_v3d(db_session, out, settings)
        assert _games(db_session) == 0  # nothing stored
    data["actions"]["0.png"]["v3d"]["image"] = {"zip": "Frames-v3.zip", "member": "../0.png"}
    labels.write_text(json.dumps(data))
    with pytest.raises(DatasetError, match=r"v3d\.image\.member: unsafe zip member name"):
        import_soccernet_v3d(db_session, out, settings)


def test_an_export_writes_no_server_path_and_re_imports_its_images_from_the_tree(db_session, settings, v3_tree,
                                                                                 tmp_path):
    out = _export(db_session, settings, v3_tree, tmp_path / "export", images=True)
    for path in out.rglob("*"):
        if path.is_file():
            assert str(tmp_path) not in path.read_text(encoding="utf-8", errors="replace"), path
    # the export's tree holds the frames itself: Frames-v3.zip beside Labels-v3D.json
    game_dir = next(out.rglob("Labels-v3D.json")).parent
    assert (game_dir / "Frames-v3.zip").is_file()
    import_soccernet_v3d(db_session, out, settings)
    frame = db_session.scalars(sa.select(Frame).where(Frame.name == "0.png")).one()
    assert (frame.image_root, frame.image_member) == (str(out.resolve()), "0.png")
    assert Path(frame.image_root, frame.image_zip) == (game_dir / "Frames-v3.zip").resolve()
    assert b"".join(frame_image(frame).chunks())[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("link", ["image", "zip", "labels", "frames folder"])
def test_a_soccernet_v3_link_leading_out_of_the_dataset_is_refused(db_session, settings, shared_dir, tmp_path, link):
    """Was: a frame file (or the game's zip, labels, frames folder) linked to any server file imported."""
    root = tmp_path / "v3"
    game_dir = write_v3_game(shared_dir, root, actions=("0.png",), with_images=link == "labels")
    outside = tmp_path / "outside"
    outside.mkdir()
    if link == "image":
        (game_dir / "Frames-v3").mkdir()
        os.symlink("/etc/passwd", game_dir / "Frames-v3" / "0.png")
        expected = r"Frames-v3/0.png: image of frame '0.png': resolves outside the dataset's folder"
    elif link == "zip":
        write_v3_game(shared_dir, outside, actions=("0.png",))
        os.symlink(next(outside.rglob("Frames-v3.zip")), game_dir / "Frames-v3.zip")
        expected = r"Frames-v3.zip: Frames-v3.zip: resolves outside"
    elif link == "labels":
        (outside / "Labels-v3.json").write_bytes((game_dir / "Labels-v3.json").read_bytes())
        (game_dir / "Labels-v3.json").unlink()
        os.symlink(outside / "Labels-v3.json", game_dir / "Labels-v3.json")
        expected = r"Labels-v3.json: Labels-v3.json: resolves outside"
    else:
        (outside / "0.png").write_bytes(b"\x89PNG\r\n\x1a\n")
        os.symlink(outside, game_dir / "Frames-v3", target_is_directory=True)
        expected = r"Frames-v3: frames folder: resolves outside"
    with pytest.raises(DatasetError, match=expected):
        import_soccernet_v3(db_session, root, settings)
    assert _games(db_session) == 0


def test_links_inside_the_dataset_are_followed(db_session, settings, shared_dir, tmp_path):
    """A link that stays inside the imported folder is fine (the dataset's own layout)."""
    root = tmp_path / "v3"
    game_dir = write_v3_game(shared_dir, root, actions=("0.png",))
    (root / "store").mkdir()
    (game_dir / "Frames-v3.zip").rename(root / "store" / "frames.zip")
    os.symlink(root / "store" / "frames.zip", game_dir / "Frames-v3.zip")
    import_soccernet_v3(db_session, root, settings)
    frame = db_session.scalars(sa.select(Frame).where(Frame.name == "0.png")).one()
    assert (frame.image_root, frame.image_zip) == (str(root.resolve()), "store/frames.zip")


def test_a_calibration_set_image_linked_out_is_refused(db_session, settings, shared_dir, tmp_path):
    folder = tmp_path / "calib"
    folder.mkdir()
    with zipfile.ZipFile(shared_dir / "data/real/wc14-test/annotations.zip") as zf:
        (folder / "7.json").write_bytes(zf.read("7.json"))
    outside = tmp_path / "secret.jpg"
    cv2.imwrite(str(outside), np.zeros((270, 480, 3), np.uint8))
    os.symlink(outside, folder / "7.jpg")
    with pytest.raises(DatasetError, match=r"7.jpg: image: resolves outside"):
        import_sn_calibration(db_session, folder, settings)
    os.unlink(folder / "7.json")
    os.symlink(tmp_path / "elsewhere.json", folder / "7.json")
    (tmp_path / "elsewhere.json").write_bytes(b"{}")
    with pytest.raises(DatasetError, match=r"resolves outside"):
        import_sn_calibration(db_session, folder, settings, width=960, height=540)
    assert _games(db_session) == 0
    zipped = write_calibration_zip(shared_dir, tmp_path / "zipped" / "annotations.zip")
    import_sn_calibration(db_session, zipped, settings, width=960, height=540)
    assert _games(db_session) == 1


def test_issia_videos_linked_out_of_the_folder_are_refused(db_session, db_settings, shared_dir, tmp_path):
    """Was: ``videos/`` linked anywhere was opened with OpenCV and served."""
    seq = write_issia_stretch(shared_dir, tmp_path / "issia-dev", 0, 3, videos=False)
    (seq / "videos").mkdir()
    os.symlink(shared_dir / "data/synthetic/issia-dev/videos/cam1.mp4", seq / "videos" / "cam1.mp4")
    with pytest.raises(DatasetError, match=r"cam1.mp4: cam1: resolves outside"):
        import_issia(db_session, seq, db_settings)
    os.unlink(seq / "videos" / "cam1.mp4")
    (seq / "frames").mkdir()
    os.symlink(tmp_path, seq / "frames" / "cam1", target_is_directory=True)
    with pytest.raises(DatasetError, match=r"frames/cam1: cam1: resolves outside"):
        import_issia(db_session, seq, db_settings)
    assert _games(db_session) == 0


def test_a_stored_reference_leading_out_is_refused_when_served(db_session, settings, v3_tree, tmp_path):
    """The image route resolves the stored reference again: a link placed after the import, or a row
    edited to point elsewhere, is not served."""
    import_soccernet_v3(db_session, v3_tree, settings)
    frame = db_session.scalars(sa.select(Frame).where(Frame.name == "0.png")).one()
    assert frame_image(frame).size > 0
    zip_path = Path(frame.image_root, frame.image_zip)
    zip_path.rename(tmp_path / "moved.zip")
    os.symlink(tmp_path / "moved.zip", zip_path)  # the zip now leads out of the dataset
    with pytest.raises(ImageUnavailable, match="outside its dataset's folder"):
        frame_image(frame)
    for zip_ref, path_ref in (("../moved.zip", None), ("/etc/passwd", None), (None, "/etc/passwd"),
                              (None, "../../../../../../../etc/passwd")):
        frame.image_zip, frame.image_path = zip_ref, path_ref
        with pytest.raises(ImageUnavailable, match="outside its dataset's folder"):
            frame_image(frame)
    frame.image_root, frame.image_path = None, "/etc/passwd"  # a row without its folder
    with pytest.raises(ImageUnavailable, match="no dataset folder"):
        frame_image(frame)


def test_relative_inputs_are_read_from_the_working_directory_and_stay_confined(db_session, settings, shared_dir,
                                                                              tmp_path, monkeypatch):
    """Was: a relative input (``sets/v3``, ``../sets/v3``, a relative ``--cameras``) was joined to the dataset's
    resolved folder a second time (``root / "sets/v3/..."``): the walk for links leading out checked files that
    do not exist and let a link to ``/etc/passwd`` pass, and readers refused or missed a dataset's own files
    when run from another working directory. A relative path is now the working directory's, like the input."""
    from app.datasets.files import inside_dataset, refuse_links_out

    root = tmp_path / "sets" / "v3"
    game_dir = write_v3_game(shared_dir, root, actions=("0.png",))
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(tmp_path)
    os.symlink("/etc/passwd", game_dir / "evil.png")
    for given in ("sets/v3", Path("sets") / "v3", "./sets/../sets/v3"):
        with pytest.raises(DatasetError, match=r"evil.png: path: resolves outside the dataset's folder"):
            refuse_links_out(given)
    relative_link = Path("sets/v3") / game_dir.relative_to(root) / "evil.png"
    with pytest.raises(DatasetError, match="resolves outside"):
        inside_dataset(root.resolve(), relative_link, "image")
    os.unlink(game_dir / "evil.png")
    refuse_links_out("sets/v3")
    assert inside_dataset(root, Path("sets/v3") / game_dir.relative_to(root)) == game_dir.resolve()
    monkeypatch.chdir(elsewhere)  # another working directory, the dataset named through '..'
    import_soccernet_v3(db_session, "../sets/v3", settings)
    frame = db_session.scalars(sa.select(Frame).where(Frame.name == "0.png")).one()
    assert frame.image_root == str(root.resolve()) and not Path(frame.image_zip).is_absolute()
    assert b"".join(frame_image(frame).chunks())[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_relative_issia_folder_with_a_video_linked_out_is_refused_naming_it(db_session, db_settings, shared_dir,
                                                                             tmp_path, monkeypatch):
    """Was: from a relative ISSIA folder the video linked out was looked for at ``<folder>/<folder>/videos/...``
    (inside, absent) and passed the closed-world check."""
    seq = write_issia_stretch(shared_dir, tmp_path / "issia-dev", 0, 3, videos=False)
    (seq / "videos").mkdir()
    os.symlink(shared_dir / "data/synthetic/issia-dev/videos/cam1.mp4", seq / "videos" / "cam1.mp4")
    monkeypatch.chdir(tmp_path)
    with pytest.raises(DatasetError, match=r"cam1.mp4: cam1: resolves outside"):
        import_issia(db_session, Path("issia-dev"), db_settings)
    assert _games(db_session) == 0
