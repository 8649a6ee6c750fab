"""An estimate as a person reads it: the tap on the rod, class bars, stability; and in numbers.

The picture has no text: :func:`estimate_message` carries the numbers and names;
:func:`diagnostics_message` sums ``/diagnostics`` up to the worst level.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

from ext_sense.view.images import (
    DEAD,
    ESTIMATE,
    FINAL,
    PROVISIONAL,
    ROD,
    TRUTH,
    Image,
    blank,
    fill,
    frame,
)
from ext_sense_runtime.records import Estimate, GroundTruth

WIDTH = 400
MARGIN = 20
BAR = 14
DEFAULT_ROD_M = 0.3


def _x(value: float, full: float) -> int:
    return MARGIN + round(min(max(value / full, 0.0), 1.0) * (WIDTH - 2 * MARGIN))


def estimate_image(
    est: Estimate, truth: GroundTruth | None = None, rod_length_m: float = math.nan
) -> Image:
    """Draw one estimate, and in green its trial's truth when known.

    Top band yellow (provisional), blue (final) or red (degraded); a tap on the grey rod
    (``rod_length_m``; NaN: the truth's, else 0.3 m) in orange with its +-1 std band; one bar
    per class, the chosen orange; P(stable) as a bar.
    """
    rod = rod_length_m if math.isfinite(rod_length_m) else DEFAULT_ROD_M
    if truth is not None and math.isfinite(truth.rod_length_m):
        rod = truth.rod_length_m
    tap = math.isfinite(est.tap_position_m)
    n_cls = len(est.class_probabilities)
    stab = math.isfinite(est.stability_probability)
    height = 16 + (60 if tap else 0) + n_cls * (BAR + 6) + (BAR + 12 if stab else 0) + 8
    img = blank(height, WIDTH)
    fill(img, 0, 0, 8, WIDTH, DEAD if est.degraded else PROVISIONAL if est.provisional else FINAL)
    y = 16
    if tap:
        fill(img, y + 22, MARGIN, 12, WIDTH - 2 * MARGIN, ROD)
        fill(img, y + 16, 0, 24, MARGIN, (90, 90, 90))  # the held end: the gripper
        std = est.tap_position_std_m if math.isfinite(est.tap_position_std_m) else 0.0
        lo, hi = _x(est.tap_position_m - std, rod), _x(est.tap_position_m + std, rod)
        fill(img, y + 12, lo, 32, max(hi - lo, 1), (120, 80, 20))
        fill(img, y + 6, _x(est.tap_position_m, rod) - 2, 44, 5, ESTIMATE)
        if truth is not None and math.isfinite(truth.tap_position_m):
            fill(img, y, _x(truth.tap_position_m, rod) - 2, 56, 5, TRUTH)
        y += 60
    for i, p in enumerate(est.class_probabilities):
        colour = ESTIMATE if i == est.class_index else FINAL
        fill(img, y, MARGIN, BAR, max(_x(p, 1.0) - MARGIN, 1), colour)
        name = est.class_names[i] if i < len(est.class_names) else ""
        if truth is not None and truth.class_label and name == truth.class_label:
            frame(img, y - 2, MARGIN - 2, BAR + 4, WIDTH - 2 * MARGIN + 4, TRUTH)
        y += BAR + 6
    if stab:
        fill(img, y + 4, MARGIN, BAR, WIDTH - 2 * MARGIN, (60, 60, 60))
        fill(img, y + 4, MARGIN, BAR, max(_x(est.stability_probability, 1.0) - MARGIN, 1), TRUTH)
    return img


def estimate_message(est: Estimate, truth: GroundTruth | None = None) -> dict[str, Any]:
    """The estimate's numbers and names (NaN as ``None``: JSON has no NaN)."""

    def num(x: float, scale: float = 1.0, digits: int = 4) -> float | None:
        return round(x * scale, digits) if math.isfinite(x) else None

    msg: dict[str, Any] = {
        "task": est.task,
        "sensor": est.sensor,
        "model_id": est.model_id,
        "onset_ns": int(est.onset_ns),
        "kind": "provisional" if est.provisional else "final",
        "post_contact_ms": round(est.post_contact_used_ns / 1e6, 2),
        "latency_ms": round(est.compute_latency_ns / 1e6, 3),
        "tap_position_cm": num(est.tap_position_m, 100.0),
        "tap_position_std_cm": num(est.tap_position_std_m, 100.0),
        "class_label": est.class_label,
        "class_names": list(est.class_names),
        "class_probabilities": [round(p, 4) for p in est.class_probabilities],
        "stability_probability": num(est.stability_probability),
        "degraded": est.degraded,
        "degraded_reason": est.degraded_reason,
        "truth_tap_position_cm": None,
        "truth_class_label": "",
        "error_cm": None,
    }
    if truth is not None:
        msg["truth_tap_position_cm"] = num(truth.tap_position_m, 100.0)
        msg["truth_class_label"] = truth.class_label
        if math.isfinite(truth.tap_position_m) and math.isfinite(est.tap_position_m):
            msg["error_cm"] = num(abs(est.tap_position_m - truth.tap_position_m), 100.0)
    return msg


def matching_truth(est: Estimate, truths: Iterable[Any], tolerance_ns: int) -> Any:
    """The truth (or any record) with the onset nearest the estimate's, within ``tolerance_ns``."""
    best = min(truths, key=lambda t: abs(t.onset_ns - est.onset_ns), default=None)
    if best is None or abs(best.onset_ns - est.onset_ns) > tolerance_ns:
        return None
    return best


LEVEL_NAMES = {0: "OK", 1: "WARN", 2: "ERROR", 3: "STALE"}


def diagnostics_message(statuses: dict[str, tuple[int, str]]) -> dict[str, Any]:
    """The summary of ``statuses`` (name -> latest (level 0..3, message)): worst level, lines."""
    worst = max((lvl for lvl, _ in statuses.values()), default=0)
    return {
        "worst_level": int(worst),
        "worst": LEVEL_NAMES.get(int(worst), str(worst)),
        "not_ok": [
            f"{name}: {LEVEL_NAMES.get(int(lvl), lvl)} {text}"
            for name, (lvl, text) in sorted(statuses.items())
            if lvl != 0
        ],
        "statuses": len(statuses),
    }
