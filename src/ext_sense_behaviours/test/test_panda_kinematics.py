"""Panda kinematics: the pose libfranka reports at the start pose, the Jacobian, vertical lines."""

from __future__ import annotations

import numpy as np
import pytest

from ext_sense_behaviours.errors import BehaviourError
from ext_sense_behaviours.panda_kinematics import (
    READY_Q,
    forward,
    jacobian,
    solve,
    vertical_line,
)


def test_start_pose_is_where_libfranka_puts_it():
    # franka_ros2's start pose with the Franka Hand: O_T_EE at (0.307, 0, 0.487), pointing down
    pose = forward(READY_Q)
    assert pose[:3, 3] == pytest.approx([0.3069, 0.0, 0.4869], abs=2e-4)
    assert pose[:3, 2] == pytest.approx([0.0, 0.0, -1.0], abs=1e-9)


def test_jacobian_matches_finite_differences():
    rng = np.random.default_rng(1)
    q = READY_Q + rng.normal(0, 0.2, 7)
    dq = rng.normal(0, 1e-7, 7)
    moved = forward(q + dq)[:3, 3] - forward(q)[:3, 3]
    assert jacobian(q)[:3] @ dq == pytest.approx(moved, abs=1e-12)


def test_vertical_line_keeps_x_y_and_orientation():
    q0 = solve(READY_Q, _at(0.45, 0.16), iterations=300)
    times, qs = vertical_line(q0, -0.05, 0.01)
    assert times[-1] == pytest.approx(5.0)
    assert np.all(np.diff(times) > 0)
    start = forward(q0)
    for q, t in zip(qs, times, strict=True):
        pose = forward(q)
        assert pose[:3, 3] == pytest.approx(start[:3, 3] + [0, 0, -0.01 * t], abs=1e-5)
        assert pose[:3, :3] == pytest.approx(start[:3, :3], abs=1e-5)


def test_unreachable_and_bad_arguments_are_refused():
    with pytest.raises(BehaviourError, match="not reachable"):
        solve(READY_Q, _at(1.5, 0.2))
    with pytest.raises(BehaviourError, match="speed_mps > 0"):
        vertical_line(READY_Q, -0.1, 0.0)
    with pytest.raises(BehaviourError, match="7 finite numbers"):
        forward(np.zeros(6))


def _at(x: float, z: float) -> np.ndarray:
    target = forward(READY_Q)
    target[0, 3], target[2, 3] = x, z
    return target
