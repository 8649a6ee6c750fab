"""Where to draw a tap estimate on the rod: geometry and colour of the RViz markers.

The rod lies along one axis of ``frame_id`` with its held end at the origin; the tap estimate
(distance from the held end) becomes a sphere on that axis whose diameter shows the estimate's
uncertainty (2 sigma, never below ``min_diameter_m``). Provisional estimates are yellow, final
ones green; an estimate outside the rod is clamped to it and drawn red.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from ext_sense_behaviours.errors import BehaviourError
from ext_sense_runtime.records import Estimate

TAP_TASK = "tap_localization"
_AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}
# Quaternion (x, y, z, w) turning a cylinder's own z axis onto the rod axis.
_CYLINDER_ORIENTATION = {
    "x": (0.0, math.sqrt(0.5), 0.0, math.sqrt(0.5)),
    "y": (-math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5)),
    "z": (0.0, 0.0, 0.0, 1.0),
}
FINAL_RGBA = (0.1, 0.8, 0.2, 0.9)
PROVISIONAL_RGBA = (1.0, 0.8, 0.0, 0.6)
OUTSIDE_RGBA = (0.9, 0.1, 0.1, 0.9)
ROD_RGBA = (0.7, 0.7, 0.75, 0.5)


class MarkerSpec(NamedTuple):
    """Everything a ``visualization_msgs/Marker`` needs, without ROS types.

    Metres in the rod frame, quaternion (x, y, z, w), colour 0..1; ``clamped``: the estimate
    lay outside the rod and was clamped onto it.
    """

    position: tuple[float, float, float]
    orientation: tuple[float, float, float, float]
    scale: tuple[float, float, float]
    rgba: tuple[float, float, float, float]
    text: str
    clamped: bool = False


def _axis(axis: str) -> tuple[float, float, float]:
    if axis not in _AXES:
        raise BehaviourError(
            f"The 'rod_axis' parameter must be 'x', 'y' or 'z'. Got {axis!r} instead."
        )
    return _AXES[axis]


def tap_marker(
    estimate: Estimate, rod_length_m: float, axis: str = "x", min_diameter_m: float = 0.01
) -> MarkerSpec:
    """The sphere marking a tap estimate (BehaviourError: not a tap, NaN, or a bad rod)."""
    if not rod_length_m > 0:
        raise BehaviourError(
            f"The 'rod_length_m' parameter must be > 0. Got {rod_length_m!r} instead."
        )
    if estimate.task != TAP_TASK:
        raise BehaviourError(
            f"Expected a '{TAP_TASK}' estimate. Got task '{estimate.task}' instead."
        )
    s = float(estimate.tap_position_m)
    if not math.isfinite(s):
        raise BehaviourError(f"The estimate's tap_position_m must be finite. Got {s!r} instead.")
    clamped = not 0.0 <= s <= rod_length_m
    s_on_rod = min(max(s, 0.0), rod_length_m)
    std = float(estimate.tap_position_std_m)
    diameter = max(min_diameter_m, 2.0 * std) if math.isfinite(std) else min_diameter_m
    ux, uy, uz = _axis(axis)
    rgba = OUTSIDE_RGBA if clamped else PROVISIONAL_RGBA if estimate.provisional else FINAL_RGBA
    kind = "provisional" if estimate.provisional else "final"
    spread = f" +- {std * 100:.1f} cm" if math.isfinite(std) else ""
    text = f"tap {s * 100:.1f} cm{spread} ({kind})"
    return MarkerSpec(
        (ux * s_on_rod, uy * s_on_rod, uz * s_on_rod),
        (0.0, 0.0, 0.0, 1.0),
        (diameter, diameter, diameter),
        rgba,
        text,
        clamped,
    )


def rod_marker(rod_length_m: float, axis: str = "x", diameter_m: float = 0.012) -> MarkerSpec:
    """The cylinder drawing the rod itself, from the held end to the free end."""
    if not rod_length_m > 0:
        raise BehaviourError(
            f"The 'rod_length_m' parameter must be > 0. Got {rod_length_m!r} instead."
        )
    ux, uy, uz = _axis(axis)
    half = rod_length_m / 2.0
    return MarkerSpec(
        (ux * half, uy * half, uz * half),
        _CYLINDER_ORIENTATION[axis],
        (diameter_m, diameter_m, rod_length_m),
        ROD_RGBA,
        f"rod {rod_length_m * 100:.0f} cm",
    )
