"""Tap marker geometry."""

from __future__ import annotations

import math

import pytest

from ext_sense_behaviours.errors import BehaviourError
from ext_sense_behaviours.tap import (
    FINAL_RGBA,
    OUTSIDE_RGBA,
    PROVISIONAL_RGBA,
    rod_marker,
    tap_marker,
)
from ext_sense_runtime.records import Estimate


def tap(pos, std=math.nan, provisional=False):
    return Estimate(
        "tap_localization", 0, provisional=provisional, tap_position_m=pos, tap_position_std_m=std
    )


@pytest.mark.parametrize(("axis", "index"), [("x", 0), ("y", 1), ("z", 2)])
def test_tap_sphere_sits_on_the_rod_axis(axis, index):
    spec = tap_marker(tap(0.12, 0.015), 0.3, axis)
    assert spec.position[index] == pytest.approx(0.12)
    assert sum(abs(v) for v in spec.position) == pytest.approx(0.12)
    assert spec.scale == pytest.approx((0.03, 0.03, 0.03))
    assert spec.rgba == FINAL_RGBA
    assert spec.text == "tap 12.0 cm +- 1.5 cm (final)"


def test_provisional_small_std_and_outside():
    assert tap_marker(tap(0.1, provisional=True), 0.3).rgba == PROVISIONAL_RGBA
    assert tap_marker(tap(0.1, 0.001), 0.3, min_diameter_m=0.01).scale[0] == pytest.approx(0.01)
    spec = tap_marker(tap(0.45), 0.3)
    assert spec.clamped
    assert spec.position[0] == pytest.approx(0.3)
    assert spec.rgba == OUTSIDE_RGBA


@pytest.mark.parametrize(
    ("estimate", "length", "axis", "match"),
    [
        (tap(math.nan), 0.3, "x", "tap_position_m must be finite"),
        (tap(0.1), 0.0, "x", "'rod_length_m' parameter must be > 0"),
        (tap(0.1), 0.3, "w", "'rod_axis' parameter must be 'x', 'y' or 'z'"),
        (Estimate("food_identification", 0), 0.3, "x", "Expected a 'tap_localization'"),
    ],
)
def test_tap_marker_rejects_bad_input(estimate, length, axis, match):
    with pytest.raises(BehaviourError, match=match):
        tap_marker(estimate, length, axis)


def test_rod_cylinder_spans_the_rod():
    spec = rod_marker(0.5, "x")
    assert spec.position == pytest.approx((0.25, 0.0, 0.0))
    assert spec.scale[2] == pytest.approx(0.5)
    x, y, z, w = spec.orientation
    assert x * x + y * y + z * z + w * w == pytest.approx(1.0)
    # rotating the cylinder's z axis by this quaternion gives +x
    zx = 2 * (x * z + w * y)
    assert zx == pytest.approx(1.0)
