"""One line in words for every audit entry: "ball of V2 moved 12.3 px", "V3 excluded from
the 3D ball", "moved point 9 of Circle right (V3): JaC 0.909 -> refused", "system accepted".

:func:`summarize` is pure: it reads an entry's action, its self-describing ``before`` / ``after`` states
(``app.services.audit.log``), the view's name on the system page ("V2", by the system's view order) and,
for a field-line write, the calibration before and after (``facts``, known only while the write runs). The
audit log stores its answer when the entry is recorded (``audit_entries.summary``); entries older than that
column get the same function's answer when they are read (without the calibration, which they never kept).
"""
from __future__ import annotations

import math
from typing import Any, Mapping, Optional

from app.geometry.annotations import AnnotationError, lines_from_json_lists, lines_to_json_lists, mirror_lines

#: A review status in words.
STATUS_WORDS = {"accepted": "accepted", "rejected": "rejected", "needs_fix": "marked as needing a fix",
                "fixed": "sent back as fixed", "pending": "set back to pending"}
#: Which edit restored which state (a revert is audited as ``revert``: its state says what it restored).
_ACTION_OF_STATE = (("system", "system.import"), ("ball", "ball.edit"), ("lines", "field_lines.replace"),
                    ("excluded", "view.exclusion"), ("calibration_review", "view.calibration_review"),
                    ("review", "review"))
#: Below this a ball's centre or size did not move (px).
_STILL_PX = 0.05


def _num(v: float) -> str:
    """A pixel figure: one decimal, no trailing ``.0`` noise beyond that."""
    return f"{v:.1f}"


def _ball_geometry(ball: Mapping[str, Any] | None) -> tuple[Optional[tuple[float, float]],
                                                            Optional[tuple[float, float]]]:
    """(centre, size) of a ``{"box", "point"}`` state in px; size None for a point, both None without a ball."""
    if not isinstance(ball, Mapping):
        return None, None
    box, point = ball.get("box"), ball.get("point")
    if isinstance(box, (list, tuple)) and len(box) == 4:
        x1, y1, x2, y2 = (float(v) for v in box)
        return ((x1 + x2) / 2, (y1 + y2) / 2), (x2 - x1, y2 - y1)
    if isinstance(point, (list, tuple)) and len(point) == 2:
        return (float(point[0]), float(point[1])), None
    return None, None


def ball_words(before: Mapping[str, Any] | None, after: Mapping[str, Any] | None, view: str) -> str:
    """A ball label's change: drawn, deleted, moved (centre distance, px of the frame), resized, snapped to a
    suggestion, a suggestion confirmed, or unchanged.

    >>> ball_words({"box": [0, 0, 10, 10], "point": None}, {"box": [3, 4, 13, 14], "point": None}, "V2")
    'ball of V2 moved 5.0 px'
    >>> ball_words({"box": None, "point": None}, {"box": None, "point": [5, 5]}, "V1")
    'ball of V1 drawn (a point)'
    >>> ball_words({"box": [0, 0, 10, 10]}, {"box": [0, 0, 10, 10], "provenance": {"source": "yolo"}}, "V3")
    'confirmation of the suggested ball of V3 withdrawn'
    """
    c0, s0 = _ball_geometry(before)
    c1, s1 = _ball_geometry(after)
    suggested_before = isinstance(before, Mapping) and before.get("provenance") is not None
    suggested_after = isinstance(after, Mapping) and after.get("provenance") is not None
    of = f"ball of {view}"
    if c0 is None and c1 is None:
        return f"{of}: still none"
    if c1 is None:
        return f"{of} deleted"
    kind = "a box" if s1 is not None else "a point"
    if c0 is None:
        return f"{of} snapped to the suggested box" if suggested_after else f"{of} drawn ({kind})"
    moved = math.hypot(c1[0] - c0[0], c1[1] - c0[1])
    resized = (s0 is None) != (s1 is None) or (s0 is not None and s1 is not None
                                              and max(abs(s1[0] - s0[0]), abs(s1[1] - s0[1])) > _STILL_PX)
    if suggested_after and not suggested_before and moved <= _STILL_PX and not resized:
        # the same box turning back into a suggestion is the undo of its confirmation, not a snap of 0 px
        return f"confirmation of the suggested {of} withdrawn"
    if suggested_after:
        return f"{of} snapped to the suggested box ({_num(moved)} px away)"
    parts = []
    if moved > _STILL_PX:
        parts.append(f"moved {_num(moved)} px")
    if resized:
        def size(s):
            return "a point" if s is None else f"{_num(s[0])} x {_num(s[1])} px"
        parts.append(f"resized {size(s0)} -> {size(s1)}")
    if suggested_before:
        return f"suggested {of} confirmed" + (f" ({', '.join(parts)})" if parts else "")
    return f"{of} {' and '.join(parts)}" if parts else f"{of} unchanged"


def _polys(lines: Any) -> dict[str, list[list[list[float]]]]:
    return {str(k): [list(p) for p in v]
            for k, v in lines.items() if isinstance(v, list)} if isinstance(lines, Mapping) else {}


def _same_point(a: Any, b: Any) -> bool:
    try:
        return abs(float(a[0]) - float(b[0])) <= 1e-6 and abs(float(a[1]) - float(b[1])) <= 1e-6
    except (TypeError, ValueError, IndexError):
        return False


def _same_poly(a: list, b: list) -> bool:
    return len(a) == len(b) and all(_same_point(p, q) for p, q in zip(a, b, strict=True))


def _mirrored(before: dict[str, list], after: dict[str, list]) -> bool:
    """Whether ``after`` is ``before`` with every class renamed by the pitch's 180-degree rotation
    (``app.geometry.annotations.mirror_lines``: the mirror fix, or its undo)."""
    try:
        mirrored = _polys(lines_to_json_lists(mirror_lines(lines_from_json_lists(before))))
    except (AnnotationError, ValueError, TypeError):
        return False
    return set(mirrored) == set(after) and all(
        len(mirrored[c]) == len(after[c]) and all(_same_poly(p, q) for p, q in zip(mirrored[c], after[c], strict=True))
        for c in after)


def lines_words(before: Any, after: Any) -> str:
    """A field-line change as the line editor says it: "moved point 9 of Circle right", "added a point to X",
    "deleted point 3 of X", "deleted a X line", "drew a X line", "relabelled a X line as Y"; otherwise the
    counts before and after ("11 lines (11 classes) -> 12 lines (11 classes)").

    >>> lines_words({"Circle right": [[[0, 0], [5, 5]]]}, {"Circle right": [[[0, 0], [6, 5]]]})
    'moved point 2 of Circle right'
    """
    b, a = _polys(before), _polys(after)
    changed = sorted(c for c in set(b) | set(a) if len(b.get(c, [])) != len(a.get(c, []))
                     or not all(_same_poly(p, q) for p, q in zip(b.get(c, []), a.get(c, []), strict=True)))
    if not changed:
        return "field lines unchanged"
    if len(changed) == 1:
        cls = changed[0]
        pb, pa = b.get(cls, []), a.get(cls, [])
        name = cls.strip()
        if len(pb) == len(pa):
            diffs = [(i, p, q) for i, (p, q) in enumerate(zip(pb, pa, strict=True)) if not _same_poly(p, q)]
            if len(diffs) == 1:
                _, p, q = diffs[0]
                if len(p) == len(q):
                    moved = [j for j, (u, v) in enumerate(zip(p, q, strict=True)) if not _same_point(u, v)]
                    return (f"moved point {moved[0] + 1} of {name}" if len(moved) == 1
                            else f"moved {len(moved)} points of {name}")
                if len(q) == len(p) + 1:
                    return f"added a point to {name}"
                if len(q) == len(p) - 1:
                    gone = next((j for j in range(len(q)) if not _same_point(p[j], q[j])), len(q))
                    return f"deleted point {gone + 1} of {name}"
        elif len(pa) == len(pb) - 1:
            return f"deleted a {name} line"
        elif len(pa) == len(pb) + 1:
            return f"drew a {name} line"
    if _mirrored(b, a):
        return "field lines mirrored"
    if len(changed) == 2:
        x, y = changed
        for src, dst in ((x, y), (y, x)):
            if len(b.get(src, [])) == len(a.get(src, [])) + 1 and len(a.get(dst, [])) == len(b.get(dst, [])) + 1:
                return f"relabelled a {src.strip()} line as {dst.strip()}"

    def count(lines: dict[str, list]) -> str:
        n = sum(len(p) for p in lines.values())
        return f"{n} line{'' if n == 1 else 's'} ({len(lines)} class{'' if len(lines) == 1 else 'es'})"

    return f"field lines edited: {count(b)} -> {count(a)}"


def _decision_words(state: Any, what: str) -> str:
    """A decision's state in words, naming the batch that accepted it after a sample.

    >>> _decision_words({"status": "accepted", "batch_id": 4}, "system")
    'system accepted in batch 4 after a sample'
    """
    r = state if isinstance(state, Mapping) else {}
    status = str(r.get("status") or "pending")
    comment = r.get("comment") or ""
    batch = f" in batch {r['batch_id']} after a sample" if isinstance(r.get("batch_id"), int) else ""
    return f"{what} {STATUS_WORDS.get(status, status)}{batch}" + (f" ({comment[:80]})" if comment else "")


def import_words(before: Any, after: Any) -> str:
    """What an import's merge changed of a stored system (``{"system": {"review", "views"}}`` states, views in page
    order, named "V<n>"): each view's ball, field lines, calibration and decisions, the system's decision; "nothing"
    when they are equal.

    >>> import_words({"system": {"review": {"status": "pending"},
    ...                          "views": [{"frame_id": 4, "ball": {"box": [0, 0, 2, 2], "point": None}}]}},
    ...              {"system": {"review": {"status": "accepted", "comment": "as the import of x says"},
    ...                          "views": [{"frame_id": 4, "ball": {"box": [3, 4, 5, 6], "point": None}}]}})
    'ball of V1 moved 5.0 px; system accepted (as the import of x says)'
    """
    b = before.get("system") if isinstance(before, Mapping) else None
    a = after.get("system") if isinstance(after, Mapping) else None
    b, a = (b if isinstance(b, Mapping) else {}), (a if isinstance(a, Mapping) else {})
    old = {v.get("frame_id"): v for v in b.get("views", []) if isinstance(v, Mapping)}
    parts = []
    for i, new in enumerate(v for v in a.get("views", []) if isinstance(v, Mapping)):
        name, was = f"V{i + 1}", old.get(new.get("frame_id"))
        if was is None:
            parts.append(f"{name} added")
            continue
        if was.get("ball") != new.get("ball"):
            parts.append(ball_words(was.get("ball"), new.get("ball"), name))
        if was.get("lines") != new.get("lines"):
            parts.append(f"{lines_words(was.get('lines'), new.get('lines'))} ({name})")
        if was.get("calibration") != new.get("calibration"):
            parts.append(f"calibration of {name} replaced")
        for key, what in (("review", f"ball of {name}"), ("calibration_review", f"calibration of {name}")):
            if was.get(key) != new.get(key):
                parts.append(_decision_words(new.get(key), what))
    if b.get("review") != a.get("review"):
        parts.append(_decision_words(a.get("review"), "system"))
    return "; ".join(parts) if parts else "nothing"


def summarize(action: str, before: Any, after: Any, *, view: Optional[str] = None,
              reverts_id: Optional[int] = None, facts: Optional[Mapping[str, Any]] = None, redo: bool = False) -> str:
    """One line in words for an audit entry.

    Args:
        action: the entry's action (``app.services.audit.log.ACTIONS``).
        before, after: its states (``{"ball": ...}``, ``{"lines": ...}``, ``{"excluded": ...}``,
            ``{"review": ...}``, ``{"calibration_review": ...}``; an import's counts in ``after``).
        view: the edited view's name on the system page ("V2"), None for a system's own entry.
        reverts_id: the entry this one reverts (action ``revert``) or undoes (any other action).
        facts: what only the write knew: ``calibration`` = (before, after) in words ("JaC 0.909",
            "refused") for a field-line write; ``source``, the import's name, for ``system.import``;
            ``restored``, for an undo or a revert, the decisions it gave back in words
            (``app.services.curation.resets.restore_decisions``); ``ball`` = ``"imported"`` for a ball edit that put
            back the label the dataset brought (``app.services.curation.editing.update_ball_label``).
        redo: the entry undoes an undo (a page's redo): said "redo of entry N" instead of "undo of entry N".

    >>> summarize("view.exclusion", {"excluded": False}, {"excluded": True}, view="V3")
    'V3 excluded from the 3D ball'
    >>> summarize("system.review", {"review": {"status": "pending"}}, {"review": {"status": "accepted"}})
    'system accepted'
    """
    before = before if isinstance(before, Mapping) else {}
    after = after if isinstance(after, Mapping) else {}
    v = view or "the view"
    if action == "revert" or (reverts_id is not None and action not in ("import", "recompute")):
        state_action = next((a for key, a in _ACTION_OF_STATE if key in after or key in before), None)
        if state_action == "review":
            state_action = "view.review" if view else "system.review"
        if state_action is None:  # a state this version does not know
            inner = "an unknown change"
        else:
            inner = summarize(state_action if action == "revert" else action, before, after, view=view, facts=facts)
        what = "reverted" if action == "revert" else "redo of" if redo else "undo of"
        restored = (facts or {}).get("restored")
        back = f"; decisions it reset restored: {', '.join(restored)}" if restored else ""
        return (f"{what} entry {reverts_id}: {inner}" if reverts_id is not None else f"{what}: {inner}") + back
    if action == "ball.edit":
        if (facts or {}).get("ball") == "imported":
            return f"ball of {v} restored to the imported label"
        return ball_words(before.get("ball"), after.get("ball"), v)
    if action in ("field_lines.replace", "field_lines.mirror"):
        words = (f"field lines of {v} mirrored" if action == "field_lines.mirror"
                 else lines_words(before.get("lines"), after.get("lines")) + (f" ({view})" if view else ""))
        cal = (facts or {}).get("calibration")
        return f"{words}: {cal[0]} -> {cal[1]}" if cal else words
    if action == "view.exclusion":
        if bool(before.get("excluded")) == bool(after.get("excluded")):
            return f"{v} exclusion unchanged ({'excluded' if after.get('excluded') else 'included'})"
        return f"{v} excluded from the 3D ball" if after.get("excluded") else f"{v} restored to the 3D ball"
    if action == "view.review":
        return _decision_words(after.get("review"), f"ball of {v}")
    if action == "view.calibration_review":
        return _decision_words(after.get("calibration_review"), f"calibration of {v}")
    if action == "system.review":
        return _decision_words(after.get("review"), "system")
    if action == "system.handoff":
        return handoff_words(after.get("handoff"))
    if action.startswith("comment."):
        return comment_words(action, after.get("comment"), v)
    if action == "system.import":
        source = (facts or {}).get("source")
        return f"import{f' of {source}' if source else ''} changed {import_words(before, after)}"
    if action == "import" and after.get("kind") == "predictions":
        return prediction_import_words(after)
    if action in ("import", "recompute"):
        counts = ", ".join(_count(after[k], k) for k in ("games", "systems", "frames") if isinstance(after.get(k), int))
        source = after.get("source_name") or ""
        return f"{action}{f' of {source}' if source else ''}" + (f": {counts}" if counts else "")
    if action == "release.create":
        # entries written before the count was kept say nothing of it
        without = after.get("without_ball3d")
        return (f"release {after.get('name', '')} made: {after.get('systems', 0)} systems"
                + (f" ({without} without a 3D ball)" if isinstance(without, int) and without else "")
                + f", {after.get('views', 0)} views, hash {str(after.get('hash', ''))[:12]}")
    if action.startswith(("user.", "token.")):
        return account_words(action, before, after)
    named = after.get("name") or after.get("user") or ""
    return f"{action.replace('.', ' ')}{f' {named}' if named else ''}"


def _count(n: int, noun: str) -> str:
    """``n`` and ``noun`` (a plural ending in s) agreeing: "1 game", "3 games"."""
    return f"{n} {noun[:-1] if n == 1 and noun.endswith('s') else noun}"


def account_words(action: str, before: Mapping[str, Any], after: Mapping[str, Any]) -> str:
    """An administrator's change of a user or an API token (``app.services.accounts.users``) in words, from its
    states (the user's name, role, token id and label; never a secret).

    >>> account_words("user.role", {"user": "ana", "role": "annotator"}, {"user": "ana", "role": "reviewer"})
    'ana made reviewer (was annotator)'
    >>> account_words("token.issue", {}, {"user": "ana", "token_id": 7, "label": "laptop", "expires_at": None})
    'API token 7 (laptop) issued to ana, valid until revoked'
    >>> account_words("user.disable", {}, {"user": "ana", "tokens_revoked": 1})
    'ana disabled: sessions ended, 1 API token revoked'
    """
    user = after.get("user") or before.get("user") or "?"
    token = f"API token {after.get('token_id')}" + (f" ({after['label']})" if after.get("label") else "")
    if action == "user.create":
        return f"user {user} added as {after.get('role')}" + (" (the demo account)" if after.get("demo") else "")
    if action == "user.role":
        return f"{user} made {after.get('role')} (was {before.get('role')})"
    if action == "user.disable":
        revoked = after.get("tokens_revoked")
        return f"{user} disabled: sessions ended" + (f", {_count(revoked, 'API tokens')} revoked" if revoked else "")
    if action == "user.enable":
        return f"{user} enabled again (no token back)"
    if action == "token.issue":
        until = after.get("expires_at")
        return f"{token} issued to {user}, " + (f"expires {str(until)[:10]}" if until else "valid until revoked")
    if action == "token.revoke":
        return f"{token} of {user} revoked"
    if action == "user.take_over":
        return (f"restored with new secrets: {user} the admin, a new session key, "
                f"{_count(after.get('tokens_revoked', 0), 'API tokens')} revoked, "
                f"{_count(after.get('users_disabled', 0), 'accounts')} disabled")
    return f"{action.replace('.', ' ')} {user}"


def prediction_import_words(after: Mapping[str, Any]) -> str:
    """An import (or removal) of a detector's predictions in words, from its counts (``source``, ``stored``,
    ``dropped`` beyond ``cap`` a frame, ``replaced``, ``unknown``; ``removed``).

    >>> prediction_import_words({"source": "yolo", "stored": 16, "dropped": 199984, "cap": 16, "replaced": 0,
    ...                          "unknown": 0})
    'predictions of yolo imported: 16 stored, 199,984 beyond the cap of 16 a frame'
    >>> prediction_import_words({"source": "yolo", "removed": 16})
    'predictions of yolo removed: 16'
    """
    source = after.get("source") or "?"
    if "removed" in after:
        return f"predictions of {source} removed: {after['removed']:,}"
    parts = [f"{after.get('stored', 0):,} stored"]
    if after.get("dropped"):
        parts.append(f"{after['dropped']:,} beyond the cap of {after.get('cap', '?')} a frame")
    if after.get("replaced"):
        parts.append(f"{after['replaced']:,} earlier ones replaced")
    if after.get("unknown"):
        parts.append(f"{after['unknown']:,} on images v3d does not hold")
    return f"predictions of {source} imported: {', '.join(parts)}"


def handoff_words(handoff: Any) -> str:
    """A hand-off in words (``app.services.curation.handoff``'s states: ``kind`` returned or fixed, ``to``, ``by``,
    ``note``, ``reason`` when it went to nobody).

    >>> handoff_words({"kind": "returned", "to": "ana", "by": "rev", "note": "the box sits on the shadow"})
    'returned to ana by rev: the box sits on the shadow'
    >>> handoff_words({"kind": "fixed", "to": "rev", "by": "ana", "note": ""})
    'fixed by ana, back to rev for re-review'
    """
    if not isinstance(handoff, Mapping):
        return "hand-off"
    note = handoff.get("note") or ""
    tail = f": {note}" if note else ""
    if handoff.get("kind") == "fixed":
        back = f", back to {handoff['to']} for re-review" if handoff.get("to") else ", back for re-review (no reviewer)"
        return f"fixed by {handoff.get('by')}{back}{tail}"
    if handoff.get("to") is None:
        return f"returned to nobody by {handoff.get('by')} ({handoff.get('reason') or 'no one to return it to'}){tail}"
    return f"returned to {handoff['to']} by {handoff.get('by')}{tail}"


def comment_words(action: str, comment: Any, view: str) -> str:
    """A comment pinned on a view, added, resolved or reopened, in words.

    >>> comment_words("comment.add", {"text": "box on the shadow", "point": [10, 20]}, "V2")
    'comment on V2 at (10, 20): box on the shadow'
    >>> comment_words("comment.resolve", {"text": "box on the shadow", "point": None}, "V2")
    'comment on V2 resolved: box on the shadow'
    """
    text = comment.get("text", "") if isinstance(comment, Mapping) else ""
    point = comment.get("point") if isinstance(comment, Mapping) else None
    at = f" at ({point[0]:.0f}, {point[1]:.0f})" if isinstance(point, (list, tuple)) and len(point) == 2 else ""
    if action == "comment.resolve":
        return f"comment on {view} resolved: {text}"
    if action == "comment.reopen":
        return f"comment on {view} reopened: {text}"
    return f"comment on {view}{at}: {text}"
