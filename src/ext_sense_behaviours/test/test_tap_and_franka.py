"""Tap marker geometry and the franka_ros2 adapter's ROS-free parts."""

from __future__ import annotations

import math
from types import SimpleNamespace as Ns

import pytest

from ext_sense_behaviours.errors import BehaviourError
from ext_sense_behaviours.franka import (
    arm_state_from_robot_state,
    collision_behavior_values,
    import_franka_msgs,
)
from ext_sense_behaviours.records import Estimate
from ext_sense_behaviours.tap import (
    FINAL_RGBA,
    OUTSIDE_RGBA,
    PROVISIONAL_RGBA,
    rod_marker,
    tap_marker,
)


def tap(pos, std=math.nan, provisional=False):
    return Estimate(0, "tap_localization", provisional, tap_position_m=pos, tap_position_std_m=std)


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
        (Estimate(0, "food_identification"), 0.3, "x", "Expected a 'tap_localization'"),
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


def robot_state(fx=1.0, fy=2.0, fz=-3.0, z=0.2):
    vec = Ns(x=fx, y=fy, z=fz)
    return Ns(
        header=Ns(stamp=Ns(sec=5, nanosec=7)),
        o_f_ext_hat_k=Ns(wrench=Ns(force=vec, torque=Ns(x=0.0, y=0.0, z=0.0))),
        o_t_ee=Ns(pose=Ns(position=Ns(x=0.4, y=0.0, z=z))),
        o_dp_ee_c=Ns(twist=Ns(linear=Ns(x=0.0, y=0.0, z=-0.01))),
    )


def test_franka_robot_state_conversion():
    state = arm_state_from_robot_state(robot_state())
    assert state.stamp_ns == 5_000_000_007
    assert state.force_n == (1.0, 2.0, -3.0)
    assert state.z_m == 0.2
    assert state.velocity_z_mps == -0.01
    assert state.force_norm_n == pytest.approx(math.sqrt(14.0))
    with pytest.raises(BehaviourError, match="lacks a field"):
        arm_state_from_robot_state(Ns(header=Ns(stamp=Ns(sec=0, nanosec=0))))


def test_collision_thresholds():
    values = collision_behavior_values(20.0, 15.0, 40.0)
    assert values["upper_force_thresholds_nominal"] == [20.0] * 3 + [15.0] * 3
    assert values["lower_force_thresholds_nominal"] == [10.0] * 3 + [7.5] * 3
    assert values["upper_torque_thresholds_acceleration"] == [40.0] * 7
    assert len(values) == 8
    with pytest.raises(BehaviourError, match="'force_n' parameter must be > 0"):
        collision_behavior_values(0.0, 1.0, 1.0)


def test_missing_franka_msgs_is_a_clear_error():
    # franka_msgs is not on PyPI: this environment does not have it
    try:
        import franka_msgs  # type: ignore[import-not-found]  # noqa: F401
    except ImportError:
        with pytest.raises(BehaviourError, match="not on PyPI"):
            import_franka_msgs()
    else:
        assert import_franka_msgs() is not None
