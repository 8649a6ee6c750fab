"""What the behaviours need from an arm, and a simulated arm that provides it.

Implementations of :class:`ArmAdapter`: :class:`SimulatedArm` (tests and demos), the franka_ros2
adapter (``nodes/franka_adapter.py``), and the tests' ``ReplayArm`` (recorded Panda states).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Protocol

import numpy as np

from ext_sense_behaviours.errors import BehaviourError
from ext_sense_behaviours.records import ArmState


class ArmAdapter(Protocol):
    """The arm as the behaviours see it. Commands return at once; motion happens meanwhile."""

    def move_down(self, speed_mps: float) -> None:
        """Start moving the end effector straight down at ``speed_mps`` (> 0), m/s."""

    def stop(self) -> None:
        """Stop all motion now and hold position."""

    def retract(self, height_m: float, speed_mps: float) -> None:
        """Move straight up to ``height_m`` (base frame, metres) at ``speed_mps``, then hold."""

    def read_state(self) -> ArmState | None:
        """The latest state, or ``None`` when none has arrived (or a replay has ended)."""

    def take_failure(self) -> str | None:
        """Why the newest motion command failed (each failure reported once), else ``None``.

        A robot's controller can reject, abort or never answer a motion; the behaviour stops
        and holds on it rather than wait for a motion that will not happen.
        """


class SimulatedArm:
    """A point end effector moving vertically above a compliant surface.

    Below ``surface_z_m`` the surface pushes back with ``stiffness_n_per_m`` times the
    penetration (a spring: food under a fork), plus a constant ``force_bias_n`` and Gaussian
    noise of ``noise_n`` per axis, as the Panda's external-force estimate has both. Heights in
    metres (``surface_z_m`` ``None``: nothing to touch), forces in newtons; ``clock_ns``:
    monotonic integer ns, injectable for tests.
    """

    def __init__(
        self,
        start_z_m: float = 0.16,
        surface_z_m: float | None = 0.12,
        stiffness_n_per_m: float = 1000.0,
        force_bias_n: tuple[float, float, float] = (-0.5, 0.4, -0.5),
        noise_n: float = 0.05,
        clock_ns: Callable[[], int] = time.monotonic_ns,
        seed: int = 0,
    ) -> None:
        if stiffness_n_per_m <= 0:
            raise BehaviourError(
                f"The 'stiffness_n_per_m' parameter must be > 0. Got {stiffness_n_per_m!r} instead."
            )
        self.z_m = float(start_z_m)
        self.surface_z_m = surface_z_m
        self.stiffness_n_per_m = float(stiffness_n_per_m)
        self.force_bias_n = np.asarray(force_bias_n, dtype=np.float64)
        self.noise_n = float(noise_n)
        self._clock_ns = clock_ns
        self._rng = np.random.default_rng(seed)
        self._t_ns = clock_ns()
        self._velocity = 0.0
        self._target_z: float | None = None
        self.commands: list[tuple[int, str]] = []

    def _advance(self) -> int:
        now = self._clock_ns()
        dt = max(0, now - self._t_ns) / 1e9
        self._t_ns = now
        z = self.z_m + self._velocity * dt
        if self._target_z is not None and self._velocity > 0 and z >= self._target_z:
            z, self._velocity, self._target_z = self._target_z, 0.0, None
        self.z_m = z
        return now

    def _advance_at(self, speed_mps: float) -> int:
        if not speed_mps > 0:
            raise BehaviourError(
                f"The 'speed_mps' argument must be > 0. Got {speed_mps!r} instead."
            )
        return self._advance()

    def move_down(self, speed_mps: float) -> None:
        """Start moving down at ``speed_mps``."""
        now = self._advance_at(speed_mps)
        self._velocity, self._target_z = -float(speed_mps), None
        self.commands.append((now, f"move_down {speed_mps:.4f}"))

    def stop(self) -> None:
        """Stop where it is."""
        now = self._advance()
        self._velocity, self._target_z = 0.0, None
        self.commands.append((now, "stop"))

    def retract(self, height_m: float, speed_mps: float) -> None:
        """Move up to ``height_m``."""
        now = self._advance_at(speed_mps)
        if height_m > self.z_m:
            self._velocity, self._target_z = float(speed_mps), float(height_m)
        self.commands.append((now, f"retract {height_m:.4f}"))

    def contact_force_n(self) -> float:
        """Noise-free force the surface exerts at the current height, newtons (>= 0)."""
        if self.surface_z_m is None:
            return 0.0
        return max(0.0, self.surface_z_m - self.z_m) * self.stiffness_n_per_m

    def take_failure(self) -> None:
        """A simulated motion never fails."""
        return None

    def read_state(self) -> ArmState:
        """The state now: height, and the surface force (upwards, +z) plus bias and noise."""
        now = self._advance()
        force = self.force_bias_n + np.array([0.0, 0.0, self.contact_force_n()])
        if self.noise_n > 0:
            force = force + self._rng.normal(0.0, self.noise_n, 3)
        return ArmState(
            now, self.z_m, (float(force[0]), float(force[1]), float(force[2])), self._velocity
        )
