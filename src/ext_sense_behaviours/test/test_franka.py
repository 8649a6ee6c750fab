"""The franka_ros2 adapter's ROS-free parts."""

from __future__ import annotations

import math
from types import SimpleNamespace as Ns

import numpy as np
import pytest

from ext_sense_behaviours.errors import BehaviourError
from ext_sense_behaviours.franka import (
    collision_behavior_values,
    import_franka_msgs,
    reading_from_robot_state,
)
from ext_sense_behaviours.panda_kinematics import READY_Q, jacobian

DQ = (0.0, 0.01, 0.0, -0.02, 0.0, 0.01, 0.0)


def robot_state(fx=1.0, fy=2.0, fz=-3.0, z=0.2, mode=2, contact=(0.0, 0.0, 0.0)):
    vec = Ns(x=fx, y=fy, z=fz)
    zero = Ns(x=0.0, y=0.0, z=0.0)
    return Ns(
        header=Ns(stamp=Ns(sec=5, nanosec=7)),
        o_f_ext_hat_k=Ns(wrench=Ns(force=vec, torque=Ns(x=0.0, y=0.0, z=0.0))),
        o_t_ee=Ns(pose=Ns(position=Ns(x=0.4, y=0.0, z=z))),
        measured_joint_state=Ns(
            name=[f"fr3_joint{i}" for i in range(1, 8)], position=list(READY_Q), velocity=list(DQ)
        ),
        collision_indicators=Ns(
            is_cartesian_linear_contact=Ns(x=contact[0], y=contact[1], z=contact[2]),
            is_cartesian_linear_collision=zero,
        ),
        robot_mode=mode,
    )


def test_franka_robot_state_conversion():
    reading = reading_from_robot_state(robot_state())
    state = reading.state
    assert state.stamp_ns == 5_000_000_007
    assert state.force_n == (1.0, 2.0, -3.0)
    assert state.z_m == 0.2
    assert state.velocity_z_mps == pytest.approx(float(jacobian(READY_Q)[2] @ np.array(DQ)))
    assert state.velocity_z_mps != 0.0
    assert state.force_norm_n == pytest.approx(math.sqrt(14.0))
    assert reading.joint_names[0] == "fr3_joint1"
    assert reading.q.tolist() == list(READY_Q)
    assert not reading.contact
    assert not reading.collision
    assert not reading.reflex
    with pytest.raises(BehaviourError, match="lacks a field"):
        reading_from_robot_state(Ns(header=Ns(stamp=Ns(sec=0, nanosec=0))))


def test_franka_flags_and_reflex_are_read():
    reading = reading_from_robot_state(robot_state(mode=4, contact=(0.0, 0.0, 1.0)))
    assert reading.contact
    assert reading.reflex
    assert not reading.collision


def test_franka_state_with_wrong_joint_count_is_refused():
    msg = robot_state()
    msg.measured_joint_state.position = [0.0] * 6
    with pytest.raises(BehaviourError, match="7 joints"):
        reading_from_robot_state(msg)


def test_collision_thresholds():
    values = collision_behavior_values(20.0, 15.0, 40.0)
    assert values["upper_force_thresholds_nominal"] == [20.0] * 3 + [15.0] * 3
    assert values["lower_force_thresholds_nominal"] == [10.0] * 3 + [7.5] * 3
    assert values["upper_torque_thresholds_acceleration"] == [40.0] * 7
    assert len(values) == 8
    with pytest.raises(BehaviourError, match="'force_n' parameter must be > 0"):
        collision_behavior_values(0.0, 1.0, 1.0)


def test_missing_franka_msgs_is_a_clear_error():
    # franka_msgs is not on PyPI: scripts/setup.sh builds it into the venv from interfaces/
    try:
        import franka_msgs  # type: ignore[import-not-found]  # noqa: F401
    except ImportError:
        with pytest.raises(BehaviourError, match="not on PyPI"):
            import_franka_msgs()
    else:
        assert import_franka_msgs() is not None
