"""The franka_ros2 adapter's ROS-free parts."""

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
