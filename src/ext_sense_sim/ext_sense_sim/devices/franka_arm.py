"""A simulated Franka Panda / FR3 under franka_ros2: joints, trajectories, contact, reflex.

The core behind the ``sim_arm`` node, so the food probe's arm adapter is tested against the
robot's own interfaces:

- joints follow a trajectory by linear interpolation between waypoints from where they were
  when the goal arrived; a cancel holds the current position;
- below ``surface_z_m`` a spring pushes the end effector up, plus a constant bias and Gaussian
  noise per axis, as the Panda's ``O_F_ext_hat_K`` has;
- each Cartesian axis whose |force| exceeds the lower threshold raises its contact flag, the
  upper its collision flag; over the upper one the robot enters reflex mode: motion stops, the
  trajectory aborts, new goals are refused until error recovery.

Time is integer nanoseconds from an injectable clock.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ext_sense_behaviours.errors import BehaviourError
from ext_sense_behaviours.panda_kinematics import READY_Q, forward, solve
from ext_sense_sim.errors import SceneError

DEFAULT_THRESHOLDS = {
    "lower_torque_thresholds_acceleration": [20.0] * 7,
    "upper_torque_thresholds_acceleration": [20.0] * 7,
    "lower_torque_thresholds_nominal": [20.0] * 7,
    "upper_torque_thresholds_nominal": [20.0] * 7,
    "lower_force_thresholds_acceleration": [20.0] * 6,
    "upper_force_thresholds_acceleration": [20.0] * 6,
    "lower_force_thresholds_nominal": [20.0] * 6,
    "upper_force_thresholds_nominal": [20.0] * 6,
}
"""franka_ros2's defaults until a request arrives."""


class TrajectoryState:
    """How the last trajectory goal ended (or that it runs)."""

    IDLE = "idle"
    RUNNING = "running"
    SUCCEEDED = "succeeded"
    CANCELED = "canceled"
    ABORTED = "aborted"


@dataclass(frozen=True)
class SurfaceModel:
    """What the fork touches: a spring surface (``None``: none); a biased, noisy force estimate."""

    surface_z_m: float | None = 0.152
    stiffness_n_per_m: float = 1000.0
    force_bias_n: tuple[float, float, float] = (-0.5, 0.4, -0.5)
    noise_n: float = 0.05


def start_pose(x_m: float, z_m: float) -> np.ndarray:
    """Joint positions with the end effector at (``x_m``, 0, ``z_m``), pointing down."""
    target = forward(READY_Q)
    target[0, 3], target[2, 3] = x_m, z_m
    try:
        return solve(READY_Q, target, iterations=300)
    except BehaviourError as err:
        raise SceneError(f"The simulated arm cannot start at x={x_m} m, z={z_m} m: {err}") from err


class SimFrankaArm:
    """The simulated robot from joints ``q0`` at ``now_ns`` (see module docstring)."""

    def __init__(self, q0: np.ndarray, surface: SurfaceModel, now_ns: int, seed: int = 0) -> None:
        self.q = np.asarray(q0, dtype=np.float64).copy()
        self.dq = np.zeros(7)
        self.surface = surface
        self.thresholds = {k: list(v) for k, v in DEFAULT_THRESHOLDS.items()}
        self.reflex = False
        self.trajectory_state = TrajectoryState.IDLE
        self.abort_reason = ""
        self._t_ns = now_ns
        self._rng = np.random.default_rng(seed)
        self._plan: tuple[int, np.ndarray, np.ndarray] | None = None  # start, times_ns, points
        self.force_n = np.zeros(3)
        self.contact = np.zeros(3, dtype=bool)
        self.collision = np.zeros(3, dtype=bool)
        self.step(now_ns)

    @property
    def pose(self) -> np.ndarray:
        """End-effector pose, 4 x 4, base frame."""
        return forward(self.q)

    def set_thresholds(self, values: dict[str, list[float]]) -> str:
        """Take a ``SetFullCollisionBehavior`` request's fields; returns an error, or ``""``."""
        for name, default in DEFAULT_THRESHOLDS.items():
            got = values.get(name)
            if got is None or len(got) != len(default):
                return f"{name} must have {len(default)} values"
            if not all(np.isfinite(v) and v > 0 for v in got):
                return f"{name} must be positive and finite"
        for kind in ("torque", "force"):
            for phase in ("acceleration", "nominal"):
                lower = values[f"lower_{kind}_thresholds_{phase}"]
                upper = values[f"upper_{kind}_thresholds_{phase}"]
                if any(lo > up for lo, up in zip(lower, upper, strict=True)):
                    return f"lower_{kind}_thresholds_{phase} must not exceed the upper ones"
        self.thresholds = {k: [float(v) for v in values[k]] for k in DEFAULT_THRESHOLDS}
        return ""

    def follow(self, times_s: np.ndarray, points: np.ndarray, now_ns: int) -> str:
        """Follow joint ``points`` (n, 7) at ``times_s`` from here; returns why not, or ``""``."""
        self.step(now_ns)
        times_s, points = np.asarray(times_s, dtype=np.float64), np.asarray(points, np.float64)
        if self.reflex:
            return "the robot is in reflex mode: error recovery first"
        if not (points.ndim == 2 and points.shape[1] == 7 and 0 < len(times_s) == len(points)):
            return f"expected (n, 7) positions with n times; got {points.shape} and {len(times_s)}"
        if not (times_s[0] > 0 and np.all(np.diff(times_s) > 0)):
            return "time_from_start must be positive and increasing"
        if self.trajectory_state == TrajectoryState.RUNNING:
            self.trajectory_state = TrajectoryState.ABORTED
            self.abort_reason = "preempted by a new goal"
        times_ns = np.concatenate([[0], np.round(times_s * 1e9).astype(np.int64)])
        self._plan = (now_ns, times_ns, np.vstack([self.q, points]))
        self.trajectory_state = TrajectoryState.RUNNING
        return ""

    def cancel(self, now_ns: int) -> None:
        """Stop the trajectory where the joints are and hold."""
        self.step(now_ns)
        if self.trajectory_state == TrajectoryState.RUNNING:
            self.trajectory_state = TrajectoryState.CANCELED
        self._plan, self.dq = None, np.zeros(7)

    def recover(self) -> None:
        """Error recovery: leave reflex mode."""
        self.reflex = False

    def step(self, now_ns: int) -> None:
        """Advance the joints to ``now_ns`` and update force, flags and reflex."""
        self._t_ns = max(self._t_ns, now_ns)
        if self._plan is not None:
            start, times_ns, points = self._plan
            t = self._t_ns - start
            if t >= times_ns[-1]:
                self.q, self.dq, self._plan = points[-1].copy(), np.zeros(7), None
                self.trajectory_state = TrajectoryState.SUCCEEDED
            else:
                k = int(np.searchsorted(times_ns, t, side="right"))
                t0, t1 = times_ns[k - 1], times_ns[k]
                alpha = (t - t0) / (t1 - t0)
                self.q = points[k - 1] + alpha * (points[k] - points[k - 1])
                self.dq = (points[k] - points[k - 1]) / ((t1 - t0) / 1e9)
        self._sense()

    def _sense(self) -> None:
        s = self.surface
        z = float(self.pose[2, 3])
        push = 0.0 if s.surface_z_m is None else max(0.0, s.surface_z_m - z) * s.stiffness_n_per_m
        force = np.asarray(s.force_bias_n, dtype=np.float64) + np.array([0.0, 0.0, push])
        if s.noise_n > 0:
            force = force + self._rng.normal(0.0, s.noise_n, 3)
        self.force_n = force
        lower = np.asarray(self.thresholds["lower_force_thresholds_nominal"][:3])
        upper = np.asarray(self.thresholds["upper_force_thresholds_nominal"][:3])
        self.contact = np.abs(force) > lower
        self.collision = np.abs(force) > upper
        if self.collision.any() and not self.reflex:
            self.reflex = True
            if self._plan is not None:
                self._plan, self.dq = None, np.zeros(7)
                self.trajectory_state = TrajectoryState.ABORTED
                self.abort_reason = (
                    f"cartesian reflex: |F| over {upper.tolist()} N ({force.round(2).tolist()})"
                )
