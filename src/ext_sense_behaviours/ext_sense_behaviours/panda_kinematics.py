"""Kinematics of the Franka Panda / FR3 arm: forward kinematics, Jacobian, straight-line IK.

franka_ros2's ``joint_trajectory_controller`` takes joint positions while the food probe moves
the fork straight down, so the adapter turns that line into joint waypoints here (plain NumPy).
Model: Franka's modified Denavit-Hartenberg parameters, flange 0.107 m after joint 7, the Franka
Hand's end effector 0.1034 m beyond it turned -45 degrees about z (libfranka's ``F_T_EE``).
"""

from __future__ import annotations

import numpy as np

from ext_sense_behaviours.errors import BehaviourError

# (a, d, alpha) of joints 1..7, modified DH (Franka's documentation)
DH = np.array(
    [
        [0.0, 0.333, 0.0],
        [0.0, 0.0, -np.pi / 2],
        [0.0, 0.316, np.pi / 2],
        [0.0825, 0.0, np.pi / 2],
        [-0.0825, 0.384, -np.pi / 2],
        [0.0, 0.0, np.pi / 2],
        [0.088, 0.0, np.pi / 2],
    ]
)
FLANGE_D_M = 0.107
HAND_D_M = 0.1034
Q_MIN = np.array([-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973])
Q_MAX = np.array([2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973])
READY_Q = np.array([0.0, -np.pi / 4, 0.0, -3 * np.pi / 4, 0.0, np.pi / 2, np.pi / 4])
"""franka_ros2's start pose (``move_to_start_example_controller``): end effector pointing down."""


def _dh(a: float, d: float, alpha: float, theta: float) -> np.ndarray:
    """RotX(alpha) TransX(a) RotZ(theta) TransZ(d), the modified DH transform."""
    ca, sa, ct, st = np.cos(alpha), np.sin(alpha), np.cos(theta), np.sin(theta)
    return np.array(
        [
            [ct, -st, 0.0, a],
            [st * ca, ct * ca, -sa, -d * sa],
            [st * sa, ct * sa, ca, d * ca],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def _ee_offset() -> np.ndarray:
    c, s = np.cos(-np.pi / 4), np.sin(-np.pi / 4)
    return np.array(
        [
            [c, -s, 0.0, 0.0],
            [s, c, 0.0, 0.0],
            [0.0, 0.0, 1.0, FLANGE_D_M + HAND_D_M],
            [0, 0, 0, 1.0],
        ]
    )


_EE = _ee_offset()


def _frames(q: np.ndarray) -> list[np.ndarray]:
    """Base-frame transforms of joint frames 1..7, then the end effector."""
    q = _checked(q)
    out, t = [], np.eye(4)
    for (a, d, alpha), theta in zip(DH, q, strict=True):
        t = t @ _dh(a, d, alpha, theta)
        out.append(t)
    out.append(t @ _EE)
    return out


def _checked(q: np.ndarray) -> np.ndarray:
    q = np.asarray(q, dtype=np.float64)
    if q.shape != (7,) or not np.all(np.isfinite(q)):
        raise BehaviourError(f"Joint positions must be 7 finite numbers. Got {q!r} instead.")
    return q


def forward(q: np.ndarray) -> np.ndarray:
    """End-effector pose in the base frame, a 4 x 4 homogeneous transform (libfranka ``O_T_EE``)."""
    return _frames(q)[-1]


def jacobian(q: np.ndarray) -> np.ndarray:
    """Geometric Jacobian of the end effector, shape (6, 7): rows vx, vy, vz, wx, wy, wz."""
    frames = _frames(q)
    p_ee = frames[-1][:3, 3]
    jac = np.empty((6, 7))
    for i, t in enumerate(frames[:7]):
        z, p = t[:3, 2], t[:3, 3]
        jac[:3, i] = np.cross(z, p_ee - p)
        jac[3:, i] = z
    return jac


def _pose_error(current: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Position error and a small-angle orientation error (6,), target minus current."""
    r, rd = current[:3, :3], target[:3, :3]
    rot = 0.5 * sum(np.cross(r[:, k], rd[:, k]) for k in range(3))
    return np.concatenate([target[:3, 3] - current[:3, 3], rot])


def solve(
    q0: np.ndarray, target: np.ndarray, iterations: int = 50, tol_m: float = 1e-6
) -> np.ndarray:
    """Joint positions reaching the pose ``target`` (4 x 4), starting the search at ``q0``.

    Damped least squares, clipped to the joint limits.

    Raises:
        BehaviourError: Not reached within ``iterations`` (out of reach, or a joint limit).
    """
    q = _checked(q0).copy()
    for _ in range(iterations):
        err = _pose_error(forward(q), target)
        if np.linalg.norm(err) < tol_m:
            return q
        jac = jacobian(q)
        q = np.clip(q + jac.T @ np.linalg.solve(jac @ jac.T + 1e-4 * np.eye(6), err), Q_MIN, Q_MAX)
    err = _pose_error(forward(q), target)
    if np.linalg.norm(err) > 1e-4:
        raise BehaviourError(
            f"The target pose {target[:3, 3].round(4).tolist()} is not reachable from "
            f"{q0!r}: {np.linalg.norm(err[:3]) * 1e3:.1f} mm left."
        )
    return q


def vertical_line(
    q0: np.ndarray, dz_m: float, speed_mps: float, step_s: float = 0.05
) -> tuple[np.ndarray, np.ndarray]:
    """Joint waypoints moving the end effector straight up (``dz_m`` > 0) or down, orientation held.

    Returns ``(times_s, positions)``: (n,) seconds from the start (first > 0) and (n, 7)
    radians, from ``q0`` (7,) at ``speed_mps`` (> 0). BehaviourError for a bad argument or a
    waypoint out of reach.
    """
    if not (speed_mps > 0 and np.isfinite(speed_mps)) or not np.isfinite(dz_m) or dz_m == 0:
        raise BehaviourError(
            f"A vertical line needs dz_m != 0 and speed_mps > 0. Got {dz_m!r}, {speed_mps!r}."
        )
    duration = abs(dz_m) / speed_mps
    n = max(1, int(np.ceil(duration / step_s)))
    times = np.linspace(duration / n, duration, n)
    start = forward(q0)
    out, q = np.empty((n, 7)), _checked(q0)
    for i, t in enumerate(times):
        target = start.copy()
        target[2, 3] += dz_m * t / duration
        q = solve(q, target)
        out[i] = q
    return times, out
