"""The human grasp of a robot-to-human handover: settling when stable, stick-slip when not.

Model. At the onset the hand touches the object at ``position`` (a fraction of the free span)
with a short half-sine; its pull along the object reaches the pads as an axial force: when
stable (probability ``p_stable``) a second-order settling to ``pull_force_n``; when not,
spring-block stick-slip (skin ``skin_k`` dragged at ``pull_speed``, friction rising from
``mu_k N`` to ``mu_s N`` and slipping back within ``slip_tau_s``, the stick period jittered 15%),
each slip knocking the object across its axis with ``slip_kick`` of the force drop.

A hand never holds still: its force fluctuates by ``tremor_fraction`` (RMS) of the force it
holds, in a band about the physiological tremor's ``tremor_hz`` (a resonance of quality
``tremor_q``), along the object and across it independently, in both classes.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from scipy.signal import iirpeak, lfilter

from ext_sense_sim.effects.base import Effect, Signals, TimeBase
from ext_sense_sim.effects.contact import Contact, Labels, half_sine_bins


def settling(t: np.ndarray, final: np.ndarray, freq_hz: np.ndarray, zeta: float) -> np.ndarray:
    """Underdamped second-order step response to ``final``, zero for ``t < 0``."""
    w = 2 * np.pi * freq_hz
    wd = w * np.sqrt(1 - zeta**2)
    ts = np.maximum(t, 0.0)
    resp = 1 - np.exp(-zeta * w * ts) * (
        np.cos(wd * ts) + zeta / np.sqrt(1 - zeta**2) * np.sin(wd * ts)
    )
    return np.where(t >= 0, final * resp, 0.0)


def stick_slip(
    t: np.ndarray,
    normal_n: float,
    mu_s: float,
    mu_k: float,
    stiffness: float,
    speed: float,
    jitter: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Friction force of a dragged spring-block at ``t`` (from the drag's start), and its slips.

    ``jitter`` is the relative variation of each cycle's stick period.
    """
    rate = stiffness * speed
    first = mu_s * normal_n / rate  # loading from zero up to the first slip
    period = (mu_s - mu_k) * normal_n / rate
    slips = first + np.concatenate([[0.0], np.cumsum(period * (1 + jitter))])
    idx = np.searchsorted(slips, t, side="right")  # slips already done at t
    last = np.where(idx > 0, slips[np.maximum(idx - 1, 0)], 0.0)
    base = np.where(idx > 0, mu_k * normal_n, 0.0)
    force = np.where(t >= 0, base + rate * (t - last), 0.0)
    return force, slips


_TREMOR_RUN_IN_S = 1.0
"""Seconds a tremor's resonance runs before its trial starts, so the trial sees it stationary."""


def tremor(
    n_samples: int, rate_hz: float, freq_hz: np.ndarray, q: float, rng: np.random.Generator
) -> np.ndarray:
    """Unit-RMS narrow-band noise per trial, ``(len(freq_hz), n_samples)``, already stationary.

    White noise through a resonance at each trial's ``freq_hz`` of quality ``q``, run in for
    ``_TREMOR_RUN_IN_S`` first and scaled by the resonance's own noise gain.
    """
    run_in = int(_TREMOR_RUN_IN_S * rate_hz)
    out = np.empty((len(freq_hz), n_samples))
    impulse = np.zeros(run_in)
    impulse[0] = 1.0
    for i, f in enumerate(freq_hz):
        b, a = iirpeak(f, q, fs=rate_hz)
        gain = np.sqrt(np.sum(lfilter(b, a, impulse) ** 2))
        noise = rng.standard_normal(run_in + n_samples)
        out[i] = lfilter(b, a, noise)[run_in:] / gain
    return out


class HumanGrasp(Effect):
    """Handover grasp (see module docstring). Gives ``contact`` and ``labels``."""

    name = "human_grasp"
    gives = ("contact", "labels")
    defaults: ClassVar[dict[str, Any]] = {
        "p_stable": 0.5,
        "onset_s": [0.045, 0.055],
        "position": [0.4, 0.95],
        "touch_force_n": [0.3, 1.5],
        "touch_duration_s": [0.002, 0.006],
        "angle_deg": [-45.0, 45.0],
        "pull_force_n": [1.0, 4.0],
        "settle_hz": [4.0, 10.0],
        "settle_zeta": 0.6,
        "normal_n": [1.5, 4.0],
        "mu_s": [0.6, 0.9],
        "mu_k": [0.3, 0.5],
        "skin_k": [800.0, 2500.0],
        "pull_speed": [0.02, 0.08],
        "slip_tau_s": 0.001,
        "slip_kick": 0.3,
        "tremor_fraction": [0.01, 0.05],
        "tremor_hz": [8.0, 12.0],
        "tremor_q": 2.0,
    }

    def run(self, signals: Signals, time: TimeBase, rng: np.random.Generator) -> None:
        """Give ``contact`` and ``labels`` for a batch of handovers."""
        n, t = time.n_trials, time.t()
        span = self.context.geometry.free_length_m
        stable = rng.uniform(size=n) < self.scalar("p_stable", 0.0, 1.0)
        onset = self.draw("onset_s", rng, n, 0.0)
        position = self.draw("position", rng, n, 0.0, 1.0) * span
        touch = half_sine_bins(
            self.draw("touch_force_n", rng, n, 0.0),
            self.draw("touch_duration_s", rng, n, 1e-5, 1.0),
            onset,
            time.rate_hz,
            time.n_samples,
        )
        axial = np.zeros((n, time.n_samples))
        pull = self.draw("pull_force_n", rng, n, 0.0)
        settle_hz = self.draw("settle_hz", rng, n, 0.01)
        zeta = self.scalar("settle_zeta", 0.01, 0.99)
        normal = self.draw("normal_n", rng, n, 0.0)
        mu_s, mu_k = self.draw("mu_s", rng, n, 0.0), self.draw("mu_k", rng, n, 0.0)
        skin_k, speed = self.draw("skin_k", rng, n, 1.0), self.draw("pull_speed", rng, n, 1e-6)
        alpha = np.exp(-time.dt / self.scalar("slip_tau_s", 1e-6))
        kicks = np.zeros_like(axial)
        for i in range(n):
            rel = t - onset[i]
            if stable[i]:
                axial[i] = settling(rel, pull[i], settle_hz[i], zeta)
                continue
            hi, lo = max(mu_s[i], mu_k[i] + 0.05), min(mu_k[i], mu_s[i] - 0.05)
            jitter = np.clip(0.15 * rng.standard_normal(4096), -0.9, None)
            raw, slips = stick_slip(rel, normal[i], hi, lo, skin_k[i], speed[i], jitter)
            # slips relax with time constant slip_tau (one-pole), the stick ramps stay linear
            axial[i] = lfilter([1 - alpha], [1, -alpha], raw)
            slips = slips[slips + onset[i] < time.n_samples * time.dt]
            if slips.size:
                drop = (hi - lo) * normal[i] * self.scalar("slip_kick", 0.0)
                kicks[i] = half_sine_bins(
                    np.full(slips.size, drop),
                    np.full(slips.size, 0.001),
                    slips + onset[i],
                    time.rate_hz,
                    time.n_samples,
                ).sum(axis=0)
        angle = np.deg2rad(self.draw("angle_deg", rng, n, -90.0, 90.0))
        across = touch + kicks
        if np.any(self.params["tremor_fraction"]):
            held = self.draw("tremor_fraction", rng, n, 0.0, 1.0)[:, None] * np.abs(axial)
            freq = self.draw("tremor_hz", rng, n, 0.1, time.rate_hz / 4)
            q = self.scalar("tremor_q", 0.1, 100.0)
            along = held * tremor(time.n_samples, time.rate_hz, freq, q, rng)
            across = across + held * tremor(time.n_samples, time.rate_hz, freq, q, rng)
            axial = axial + along
        signals["contact"] = Contact(across, axial, position, angle)
        signals["labels"] = Labels(
            onset_ns=np.round(onset * 1e9).astype(np.int64),
            y_m=np.full(n, np.nan),
            class_label=np.where(stable, "stable", "unstable"),
        )
