"""Fork penetration into food, the arm descending at 1 cm/s and stopping on a collision.

Model. From the motion start the arm lowers the fork at ``speed``; the tines touch the food
after the food's ``gap_m`` (``+- gap_jitter_m`` per trial: the food's height). At depth ``d``
the vertical force is, per food (``FOODS``, texture values scaled per trial by ``spread``), a
Hertz-like ``k d^1.5`` up to ``fracture_n``, then the cutting force ``cut_n`` with Poisson
micro-fractures (``crunch_per_mm``, each a drop and recovery of ``crunch_n``); water: the
meniscus ``cut_n`` plus buoyancy ``rho g A d``; ``empty``: none. The arm stops at ``travel_m``
or when the force reaches ``stop_n`` (the collision threshold) and holds; the held food then
relaxes by ``relax_share`` of its force with time constant ``relax_s``. The fork is tilted
``tilt_deg``: ``F sin(tilt)`` acts across it at its tip, ``F cos(tilt)`` along it. The signal
``motion`` gives each trial's motion start and stop. ``FOODS`` and the food scenes' values are
fitted to the real runs' arm force (docs/simulator.md).
"""

from __future__ import annotations

from typing import Any, ClassVar, NamedTuple

import numpy as np

from ext_sense_sim.effects.base import Effect, Signals, TimeBase
from ext_sense_sim.effects.contact import Contact, Labels
from ext_sense_sim.errors import SceneError


class Food(NamedTuple):
    """Texture of one food: see the module docstring for each field's role."""

    k: float
    fracture_n: float
    cut_n: float
    crunch_per_mm: float
    crunch_n: float
    gap_m: float


FOODS: dict[str, Food] = {
    "empty": Food(0.0, np.inf, 0.0, 0.0, 0.0, 0.014),
    "water": Food(1000 * 9.81 * 6e-6, np.inf, 0.003, 0.0, 0.0, 0.014),
    "tofu": Food(1e3, 1.2, 1.0, 0.5, 0.05, 0.014),
    "banana": Food(1e4, 2.4, 2.0, 0.3, 0.05, 0.012),
    "watermelon": Food(4.5e3, 9.0, 4.0, 4.0, 0.3, 0.014),
    "apple": Food(3.5e4, 12.0, 4.0, 3.0, 0.8, 0.011),
    "green_pepper": Food(1.2e5, 6.6, 1.5, 2.0, 1.0, 0.012),
}
"""Texture and gap per food. Apple, watermelon, tofu and water: fitted to the real runs' arm
force (docs/simulator.md, "Food poking"); banana and green pepper have no real capture: their
earlier guesses scaled as tofu's fit (x2) and the fitted stop (x0.73) scaled the others."""


class Motion(NamedTuple):
    """Per-trial arm motion: start and stop times from the trial origin, seconds."""

    start_s: np.ndarray
    stop_s: np.ndarray


def penetration_force(
    depth: np.ndarray, food: Food, crunch_depths: np.ndarray, crunch_n: float
) -> np.ndarray:
    """Vertical tine force along a non-decreasing ``depth`` path (<= 0: not touching).

    ``crunch_depths`` (sorted) are the micro-fractures' depths, each a drop of ``crunch_n``.
    """
    d = np.maximum(depth, 0.0)
    touching = depth > 0
    if food.k == 0:
        return np.zeros_like(d)
    if not np.isfinite(food.fracture_n):  # water: meniscus plus buoyancy
        return np.where(touching, food.cut_n + food.k * d, 0.0)
    hertz = food.k * d**1.5
    d_frac = (food.fracture_n / food.k) ** (2 / 3)
    force = np.where(d < d_frac, hertz, food.cut_n)
    if crunch_depths.size:
        # each micro-fracture: the force drops by crunch_n and recovers over 0.3 mm of travel
        lag = d[:, None] - (d_frac + crunch_depths[None, :])
        dip = np.where((lag >= 0) & (lag < 3e-4), 1.0 - lag / 3e-4, 0.0).sum(axis=1)
        force = force - crunch_n * dip * (d >= d_frac)
    return np.where(touching, np.maximum(force, 0.0), 0.0)


class ForkPenetration(Effect):
    """Fork into food (see module docstring). Gives ``contact``, ``labels`` and ``motion``."""

    name = "fork_penetration"
    gives = ("contact", "labels", "motion")
    defaults: ClassVar[dict[str, Any]] = {
        "foods": list(FOODS),
        "onset_s": 0.5,
        "speed": 0.01,
        "gap_jitter_m": 0.0015,
        "travel_m": 0.04,
        "stop_n": 10.0,
        "relax_share": 0.0,
        "relax_s": 0.3,
        "tilt_deg": 12.0,
        "spread": 0.2,
        "angle_deg": [-10.0, 10.0],
    }

    def setup(self) -> None:
        """Check the parameters and precompute what every batch shares."""
        foods = self.params["foods"]
        unknown = [f for f in foods if f not in FOODS] if isinstance(foods, list) else [foods]
        if unknown or not foods:
            raise SceneError(
                f"Effect '{self.name}': 'foods' must be a non-empty list of {list(FOODS)}. "
                f"Got {foods!r} instead."
            )

    def run(self, signals: Signals, time: TimeBase, rng: np.random.Generator) -> None:
        """Give ``contact``, ``labels`` and ``motion`` for a batch of skewers."""
        n, t = time.n_trials, time.t()
        foods = list(self.params["foods"])
        # classes cycle through the list so every batch is balanced
        names = [foods[(time.first_trial + i) % len(foods)] for i in range(n)]
        onset = self.draw("onset_s", rng, n, 0.0)
        speed = self.scalar("speed", 1e-5, 1.0)
        jitter = self.scalar("gap_jitter_m", 0.0, 0.1) * rng.uniform(-1, 1, size=n)
        travel, stop_n = self.scalar("travel_m", 0.0), self.scalar("stop_n", 0.0)
        spread = self.scalar("spread", 0.0, 0.9)
        relax_share = self.scalar("relax_share", 0.0, 1.0)
        relax_s = self.scalar("relax_s", 1e-3, 100.0)
        vertical = np.zeros((n, time.n_samples))
        stop = np.empty(n)
        for i, name in enumerate(names):
            scale = np.r_[1 + spread * rng.uniform(-1, 1, size=5), 1.0]  # texture, not height
            food = Food(*(np.asarray(FOODS[name]) * scale))
            travelled = np.clip((t - onset[i]) * speed, 0.0, travel)
            per_mm = food.crunch_per_mm
            n_crunch = rng.poisson(per_mm * travel * 1e3) if per_mm > 0 else 0
            crunch = np.sort(rng.uniform(0, travel, size=n_crunch))
            force = penetration_force(
                travelled - food.gap_m - jitter[i], food, crunch, food.crunch_n
            )
            hit = np.flatnonzero(force >= stop_n)
            if hit.size:  # collision: the arm holds where it was when the force crossed stop_n
                force[hit[0] :] = force[hit[0]]
                stop[i] = t[hit[0]]
            else:
                stop[i] = onset[i] + travel / speed
            held = t >= stop[i]
            force[held] *= 1 - relax_share * (1 - np.exp(-(t[held] - stop[i]) / relax_s))
            vertical[i] = force
        tilt = np.deg2rad(self.scalar("tilt_deg", 0.0, 90.0))
        span = self.context.geometry.free_length_m
        angle = np.deg2rad(self.draw("angle_deg", rng, n, -90.0, 90.0))
        signals["contact"] = Contact(
            vertical * np.sin(tilt), vertical * np.cos(tilt), np.full(n, span), angle
        )
        signals["labels"] = Labels(
            onset_ns=np.round(onset * 1e9).astype(np.int64),
            y_m=np.full(n, np.nan),
            class_label=np.array(names),
        )
        signals["motion"] = Motion(onset, np.minimum(stop, time.n_samples * time.dt))


class ArmVibration(Effect):
    """Vibration of the moving arm reaching the fork while it descends.

    Model: band-limited noise (white noise through a one-pole low-pass at ``corner_hz``) of
    standard deviation ``axial_n`` along the fork plus a motor harmonic at ``harmonic_hz`` of
    amplitude ``harmonic_n``, present between the motion's start and stop, or, with
    ``whole_trial``, throughout (a powered arm holding still: the real food captures keep their
    background rate before, during and after the motion); a tenth of it also acts across the
    fork. It is why the empty fork still makes events.
    """

    name = "arm_vibration"
    needs = ("contact", "motion")
    gives = ("contact",)
    defaults: ClassVar[dict[str, Any]] = {
        "axial_n": 0.05,
        "corner_hz": 300.0,
        "harmonic_hz": 95.0,
        "harmonic_n": 0.02,
        "whole_trial": False,
    }

    def run(self, signals: Signals, time: TimeBase, rng: np.random.Generator) -> None:
        """Add the vibration to ``contact`` while the arm moves."""
        from scipy.signal import lfilter

        contact: Contact = signals.need("contact", self.name)
        motion: Motion = signals.need("motion", self.name)
        t = time.t()
        if self.flag("whole_trial"):
            moving = np.ones((time.n_trials, time.n_samples), dtype=bool)
        else:
            moving = (t[None, :] >= motion.start_s[:, None]) & (t[None, :] < motion.stop_s[:, None])
        alpha = np.exp(-2 * np.pi * self.scalar("corner_hz", 1.0) * time.dt)
        white = rng.standard_normal((time.n_trials, time.n_samples))
        colored = lfilter([1 - alpha], [1, -alpha], white, axis=-1)
        colored *= self.scalar("axial_n", 0.0) / max(colored.std(), 1e-12)
        phase = rng.uniform(0, 2 * np.pi, size=(time.n_trials, 1))
        tone = self.scalar("harmonic_n", 0.0) * np.sin(
            2 * np.pi * self.scalar("harmonic_hz", 0.0) * t[None, :] + phase
        )
        vib = (colored + tone) * moving
        signals["contact"] = contact._replace(
            force_n=contact.force_n + 0.1 * vib, force_axial=contact.force_axial + vib
        )
