"""A page's undo of a field-line edit in the service (issue 16, item 2): ``replace_field_lines(undo_of=)`` writes
back the entry's lines, audited as ``field_lines.replace`` naming the entry (``reverts_id``), and recalibrates to
the camera those lines give; lines stored in another JSON form (integers, as a dataset may carry them) still match
their undo; anything else is refused naming ``undo_of``."""
from __future__ import annotations

import copy

import pytest

from app.core.errors import InvalidInputError
from app.db.models import AuditEntry, Frame
from app.db.scope import changed
from app.db.unit import write_unit
from app.services.curation.editing import replace_field_lines
from app.services.curation.writing import EditContext
from app.services.derivation.recompute import recompute_frame

pytestmark = pytest.mark.engine


def _frame(systems, system, name) -> Frame:
    return next(f for f in systems[system].frames if f.name == name)


def test_undo_of_an_edit_of_integer_lines_brings_them_back_with_their_camera(db_session, settings, imported):
    frame = _frame(imported, "2.png", "2_3.png")
    fid = frame.id
    # the lines as a dataset with integer pixels stores them (JSON 1203, not 1203.0)
    ints = {c: [[[int(round(x)), int(round(y))] for x, y in poly] for poly in polys]
            for c, polys in frame.field_lines.lines.items()}
    with write_unit(db_session):  # a write of the lines and their camera, through the unit with the system's bump
        frame.field_lines.lines = ints
        recompute_frame(db_session, frame, settings)  # the camera and JaC these lines give
        changed(frame.system)
    camera, jac = frame.calibration.camera, (frame.calibration.jac_0005, frame.calibration.jac_001,
                                             frame.calibration.jac_002)
    assert camera is not None
    cls = next(c for c, polys in ints.items() if len(polys[0]) > 2)
    edited = copy.deepcopy(ints)
    edited[cls][0][1] = [edited[cls][0][1][0] + 30, edited[cls][0][1][1] - 12]

    edit = EditContext()
    replace_field_lines(db_session, fid, edited, settings=settings, edit=edit)
    entry_id = edit.entry_id
    entry = db_session.get(AuditEntry, entry_id)
    assert db_session.get(Frame, fid).calibration.camera != camera
    assert entry.before == {"lines": ints} and entry.action == "field_lines.replace" and entry.reverts_id is None

    as_the_page_sends = {c: [[[float(x), float(y)] for x, y in poly] for poly in polys] for c, polys in ints.items()}
    undo_edit = EditContext()
    replace_field_lines(db_session, fid, as_the_page_sends, settings=settings, undo_of=entry_id, edit=undo_edit)
    undo = db_session.get(AuditEntry, undo_edit.entry_id)
    assert (undo.action, undo.reverts_id) == ("field_lines.replace", entry_id)
    db_session.expire_all()  # read back what was committed
    frame = db_session.get(Frame, fid)
    assert frame.field_lines.lines == ints
    assert frame.calibration.camera == camera
    assert (frame.calibration.jac_0005, frame.calibration.jac_001, frame.calibration.jac_002) == jac


def test_an_undo_of_other_lines_or_of_no_line_write_is_refused(db_session, settings, imported):
    frame = _frame(imported, "2.png", "2_3.png")
    lines = copy.deepcopy(frame.field_lines.lines)
    cls = next(iter(lines))
    moved = copy.deepcopy(lines)
    moved[cls][0][0] = [moved[cls][0][0][0] + 9, moved[cls][0][0][1]]
    edit = EditContext()
    replace_field_lines(db_session, frame.id, moved, settings=settings, edit=edit)
    entry_id = edit.entry_id
    version = db_session.get(Frame, frame.id).edit_version
    with pytest.raises(InvalidInputError) as err:
        replace_field_lines(db_session, frame.id, moved, settings=settings, undo_of=entry_id)  # not the lines before
    assert err.value.field == "undo_of"
    other = _frame(imported, "2.png", "2_2.png")
    with pytest.raises(InvalidInputError) as err:
        replace_field_lines(db_session, other.id, other.field_lines.lines, settings=settings, undo_of=entry_id)
    assert err.value.field == "undo_of" and "no field-line write of frame" in str(err.value)
    assert db_session.get(Frame, frame.id).edit_version == version  # nothing stored
