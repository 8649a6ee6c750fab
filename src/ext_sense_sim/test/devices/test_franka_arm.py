"""The simulated Franka arm: trajectories, cancel, contact flags, reflex and recovery."""

from __future__ import annotations

import numpy as np
import pytest

from ext_sense_behaviours.franka import collision_behavior_values
from ext_sense_behaviours.panda_kinematics import vertical_line
from ext_sense_sim.devices.franka_arm import (
    SimFrankaArm,
    SurfaceModel,
    TrajectoryState,
    start_pose,
)
from ext_sense_sim.errors import SceneError

MS = 1_000_000


def _arm() -> SimFrankaArm:
    q0 = start_pose(0.45, 0.16)
    return SimFrankaArm(q0, SurfaceModel(surface_z_m=0.152, noise_n=0.0), now_ns=0)


def test_descent_into_the_surface_raises_flags_then_the_reflex_aborts():
    arm = _arm()
    assert arm.set_thresholds(collision_behavior_values(6.0, 20.0, 40.0)) == ""
    times, qs = vertical_line(arm.q, -0.05, 0.01)
    assert arm.follow(times, qs, 0) == ""
    contact_z = collision_z = None
    for t_ms in range(0, 5000, 10):
        arm.step(t_ms * MS)
        if arm.contact[2] and contact_z is None:
            contact_z = arm.pose[2, 3]
        if arm.reflex:
            collision_z = arm.pose[2, 3]
            break
    # contact over 3 N (3 mm in), the reflex over 6 N (6 mm in), then motion stops
    assert contact_z == pytest.approx(0.152 - 0.0035, abs=1e-3)
    assert collision_z == pytest.approx(0.152 - 0.0065, abs=1e-3)
    assert arm.trajectory_state == TrajectoryState.ABORTED
    assert "reflex" in arm.abort_reason
    arm.step((t_ms + 500) * MS)
    assert arm.pose[2, 3] == pytest.approx(collision_z)
    assert "reflex mode" in arm.follow(times, qs, (t_ms + 500) * MS)
    arm.recover()
    assert not arm.reflex


def test_trajectory_runs_to_its_end_and_cancel_holds():
    arm = _arm()
    times, qs = vertical_line(arm.q, 0.02, 0.02)  # 1 s up, nothing touched
    assert arm.follow(times, qs, 0) == ""
    arm.step(500 * MS)
    assert arm.pose[2, 3] == pytest.approx(0.17, abs=1e-4)
    assert np.abs(arm.dq).max() > 0
    arm.cancel(500 * MS)
    assert arm.trajectory_state == TrajectoryState.CANCELED
    arm.step(2000 * MS)
    assert arm.pose[2, 3] == pytest.approx(0.17, abs=1e-4)
    assert arm.follow(times, qs, 2000 * MS) == ""
    arm.step(3100 * MS)
    assert arm.trajectory_state == TrajectoryState.SUCCEEDED
    assert arm.pose[2, 3] == pytest.approx(0.18, abs=1e-4)  # joint goals are absolute


def test_bad_requests_are_refused_with_a_reason():
    arm = _arm()
    bad = collision_behavior_values(6.0, 20.0, 40.0)
    bad["upper_force_thresholds_nominal"] = [1.0] * 6  # below the lower ones
    assert "must not exceed" in arm.set_thresholds(bad)
    assert "6 values" in arm.set_thresholds(bad | {"lower_force_thresholds_nominal": [1.0]})
    assert "increasing" in arm.follow(np.array([1.0, 0.5]), np.zeros((2, 7)), 0)
    with pytest.raises(SceneError, match="cannot start"):
        start_pose(1.5, 0.2)
