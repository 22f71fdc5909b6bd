"""The pair-error rule: how the two reprojection errors of a triangulated pair (pixels, each in its own image)
combine into the pair's error ``e_ij`` that is compared with tau, and how a view's error is scaled to the
reference width so that views of different sizes compare (paper: the 1920-px convention of SoccerNet-v3D).
"""
from __future__ import annotations

from typing import Callable

#: Reference width of the scaled pair-error rules: errors are expressed as if every image were
#: this many pixels wide, so that 960- and 1920-px views of one system compare.
REFERENCE_WIDTH_PX = 1920.0


def _max_scaled(e_a: float, e_b: float, w_a: float, w_b: float) -> float:
    return max(e_a * REFERENCE_WIDTH_PX / w_a, e_b * REFERENCE_WIDTH_PX / w_b)


def _mean_scaled(e_a: float, e_b: float, w_a: float, w_b: float) -> float:
    return 0.5 * (e_a * REFERENCE_WIDTH_PX / w_a + e_b * REFERENCE_WIDTH_PX / w_b)


def _max_px(e_a: float, e_b: float, w_a: float, w_b: float) -> float:
    return max(e_a, e_b)


#: How a pair's two reprojection errors (px, each in its own image) combine into ``e_ij``:
#:
#: * ``max_scaled_1920`` (default): the larger of the two, each scaled to a 1920-px-wide image;
#: * ``mean_scaled_1920``: their mean, each scaled to a 1920-px-wide image;
#: * ``max_px``: the larger of the two raw pixel errors (no scaling).
PAIR_ERROR_RULES: dict[str, Callable[[float, float, float, float], float]] = {
    "max_scaled_1920": _max_scaled,
    "mean_scaled_1920": _mean_scaled,
    "max_px": _max_px,
}


#: The width (px) each scaled rule brings a view's reprojection error to before it is compared with
#: tau; a rule not named here (``max_px``) compares raw pixels.
RULE_REFERENCE_WIDTH_PX: dict[str, float] = {
    "max_scaled_1920": REFERENCE_WIDTH_PX,
    "mean_scaled_1920": REFERENCE_WIDTH_PX,
}


def rule_reference_width_px(rule: str | None) -> float | None:
    """The reference width of a pair-error rule (px), None when the rule compares raw pixels.

    >>> rule_reference_width_px("max_scaled_1920"), rule_reference_width_px("max_px")
    (1920.0, None)
    """
    return RULE_REFERENCE_WIDTH_PX.get(rule) if rule is not None else None


def scaled_error_px(error_px: float | None, width_px: float, rule: str | None) -> float | None:
    """A view's reprojection error (px of its own image) in the scale its pair rule compares with tau:
    ``error_px * reference / width_px`` for a rule with a reference width (``max_scaled_1920``: px of a
    1920-px-wide image), raw pixels for a rule without one or a width that is not positive; None
    when the error is. The one home of the scaling (the UI shows this number, never rescales).

    >>> (scaled_error_px(12.0, 960, "max_scaled_1920"), scaled_error_px(12.0, 960, "max_px"),
    ...  scaled_error_px(None, 960, "max_px"))
    (24.0, 12.0, None)
    """
    if error_px is None:
        return None
    reference = rule_reference_width_px(rule)
    return error_px * reference / width_px if reference is not None and width_px > 0 else error_px


def error_above_tau(error_px: float | None, width_px: float, tau_px: float | None, rule: str | None) -> bool:
    """The one rule "this view's reprojection error is above tau": the error (px of the view's own
    image) scaled by :func:`scaled_error_px`, then strictly above ``tau_px``. False when the
    error or tau is missing. The review queue's count and the system page's flag both use it.

    >>> error_above_tau(12.0, 960, 20.0, "max_scaled_1920"), error_above_tau(12.0, 960, 20.0, "max_px")
    (True, False)
    """
    scaled = scaled_error_px(error_px, width_px, rule)
    return scaled is not None and tau_px is not None and bool(scaled > tau_px)


def pair_error(errors_px: tuple[float, float], widths_px: tuple[float, float], rule: str) -> float:
    """Combine a pair's two reprojection errors into ``e_ij`` (px) by the named rule.

    Args:
        errors_px: errors in view a and view b, each in its own pixels.
        widths_px: the two image widths, pixels.
        rule: a key of :data:`PAIR_ERROR_RULES`.

    Raises:
        ValueError: unknown rule (the message lists the known ones).

    >>> pair_error((2.0, 3.0), (960.0, 1920.0), "max_scaled_1920")
    4.0
    """
    fn = _rule(rule)
    return float(fn(errors_px[0], errors_px[1], widths_px[0], widths_px[1]))


def _rule(rule: str) -> Callable[[float, float, float, float], float]:
    try:
        return PAIR_ERROR_RULES[rule]
    except KeyError:
        raise ValueError(f"pair_error_rule {rule!r} is unknown; choose one of {sorted(PAIR_ERROR_RULES)}") from None
