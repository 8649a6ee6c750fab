"""Transfer from the loads at the grasp to the pressure on each taxel of the two finger pads.

Each finger has 40 taxels on an 8 x 5 lattice (ids 1-40 left, 41-80 right; ``id - 1 (mod 40)``
row-major, rows along the object's axis, row 7 nearest the free span); the pads press on
opposite sides of the object. Model (a rigid object on a Winkler pad): the object touches each
pad along a strip ``w(c) = exp(-|c - c0|^q / (2 s^q))``, ``c0`` its lateral offset there (drawn
per trial and pad); ``q`` (``strip_profile_power``) is 2 for a Gaussian strip, more for a
flatter top with a sharper edge (fitted on the 50 cm rod). With ``A = sum w a``,
``I = sum w u^2 a`` (``u`` axial from the pad centre), a finger of side ``s = +1`` (left) /
``-1`` (right) feels

``p = w * (F_grip / A + s (V_n / A + M_n u / I)
       + k_t (c - c0) / s_w (V_t / A + M_t u / I) + k_a (u / u_max) F_ax / A)``

times a fixed per-taxel gain, never below zero (unilateral contact). A torque about the axis is
held by friction, ``T / (2 r)`` on each pad in opposite directions, through ``k_t``.
``finger_load_share`` scales the left pad's dynamic loads by ``1 + s`` and the right's by
``1 - s``, ``|s|`` drawn per trial from its range. Its sign, which pad is the louder, belongs to
the grasp: drawn once per scene from its seed (as the taxels' gains), so every tap of a session
shares it, as in every real rod-tap session.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from ext_sense_sim.effects.base import Effect, Signals, TimeBase

N_ROWS, N_COLS, PER_FINGER, N_TAXELS = 8, 5, 40, 80


def lattice(pitch_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Axial ``u`` and lateral ``c`` positions of the 40 taxels of one pad, metres.

    Returns:
        ``(u, c)``, each ``(40,)``, indexed by ``id - 1 (mod 40)``, centred on the pad.
    """
    i = np.arange(PER_FINGER)
    u = (i // N_COLS - (N_ROWS - 1) / 2) * pitch_m
    c = (i % N_COLS - (N_COLS - 1) / 2) * pitch_m
    return u, c


class GraspTransfer(Effect):
    """Loads at the grasp to per-taxel pressure (see module docstring).

    Gives ``taxel_pressure``: ``(n_trials, 80, n_samples)`` float32 pascals (absolute: grip
    plus dynamic), taxel ``id`` at index ``id - 1``.
    """

    name = "grasp_transfer"
    needs = ("clamp_load",)
    gives = ("taxel_pressure",)
    defaults: ClassVar[dict[str, Any]] = {
        "pitch_m": 0.003,
        "grip_force_n": [15.0, 25.0],
        "strip_sigma_m": 0.0015,
        "strip_profile_power": 2.0,
        "lateral_offset_m": [-0.003, 0.003],
        "tangential_coupling": 0.3,
        "axial_coupling": 0.2,
        "gain_spread": 0.1,
        "finger_load_share": 0.0,
    }

    def setup(self) -> None:
        """Check the parameters and precompute what every batch shares."""
        self.u, self.c = lattice(self.scalar("pitch_m", 1e-4, 0.05))
        self.area = self.scalar("pitch_m") ** 2
        spread = self.scalar("gain_spread", 0.0, 0.9)
        sensor_rng = np.random.default_rng([int(self.context.seed), 7])  # fixed per sensor
        self.gain = np.clip(1.0 + spread * sensor_rng.standard_normal(N_TAXELS), 0.1, None)
        self.louder = float(sensor_rng.choice(np.array([-1.0, 1.0])))  # +1: the left pad

    def weights(self, offsets: np.ndarray, rng: np.random.Generator, n: int) -> np.ndarray:
        """Per-trial weights ``(n, 80, 7)`` for ``[grip, V_n, M_n, V_t, M_t, F_ax, T]``."""
        sigma = self.scalar("strip_sigma_m", 1e-5, 0.1)
        power = self.scalar("strip_profile_power", 0.5, 20.0)
        k_t = self.scalar("tangential_coupling", 0.0, 10.0)
        k_a = self.scalar("axial_coupling", 0.0, 10.0)
        grip = self.draw("grip_force_n", rng, n, 0.0)
        u = self.u[None, :]
        w_out = np.empty((n, N_TAXELS, 7))
        half_gap = self.context.geometry.width_m / 2.0  # pad to axis (round rods: the radius)
        for finger, side in ((0, 1.0), (1, -1.0)):
            lateral = self.c[None, :] - offsets[:, finger : finger + 1]  # (n, 40)
            w = np.exp(-0.5 * np.abs(lateral / sigma) ** power)
            area = w.sum(axis=1, keepdims=True) * self.area
            inertia = (w * u**2).sum(axis=1, keepdims=True) * self.area
            sl = slice(finger * PER_FINGER, (finger + 1) * PER_FINGER)
            w_out[:, sl, 0] = w * grip[:, None] / area
            w_out[:, sl, 1] = side * w / area
            w_out[:, sl, 2] = side * w * u / inertia
            w_out[:, sl, 3] = k_t * w * (lateral / sigma) / area
            w_out[:, sl, 4] = k_t * w * (lateral / sigma) * u / inertia
            w_out[:, sl, 5] = k_a * w * (u / np.abs(self.u).max()) / area
            # a torque is held by friction on the two pads, T / (2 r) each, in opposite
            # directions: the pads shear (and roll the object) opposite ways
            w_out[:, sl, 6] = side * k_t * w * (lateral / sigma) / area / (2.0 * half_gap)
        return w_out * self.gain[None, :, None]

    def run(self, signals: Signals, time: TimeBase, rng: np.random.Generator) -> None:
        """Give ``taxel_pressure`` from ``clamp_load``."""
        load = signals.need("clamp_load", self.name)
        n = time.n_trials
        offsets = np.stack([self.draw("lateral_offset_m", rng, n) for _ in range(2)], axis=1)
        w = self.weights(offsets, rng, n).astype(np.float32)
        if self.params["finger_load_share"] != 0.0:  # drawn only when asked: other streams stay
            share = self.louder * self.draw("finger_load_share", rng, n, 0.0, 0.95)
            w[:, :PER_FINGER, 1:] *= (1.0 + share)[:, None, None].astype(np.float32)
            w[:, PER_FINGER:, 1:] *= (1.0 - share)[:, None, None].astype(np.float32)
        if load.shape[1] == 5:  # loads without the torque channel
            load = np.concatenate([load, np.zeros_like(load[:, :1])], axis=1)
        pressure = np.matmul(w[:, :, 1:], load.astype(np.float32))
        pressure += w[:, :, 0:1]
        np.maximum(pressure, 0.0, out=pressure)  # a pad can push but not pull
        signals["taxel_pressure"] = pressure
