"""The contact a task source hands to the structure (forces at a point) and the labels."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class Contact(NamedTuple):
    """Forces on the held object per trial, ``(n_trials, n_samples)`` newtons.

    ``force_n`` acts across the object at ``position_m`` from the grasp edge, ``angle_rad`` from
    the pads' normal; ``force_axial`` along its axis toward the grasp.
    """

    force_n: np.ndarray
    force_axial: np.ndarray
    position_m: np.ndarray
    angle_rad: np.ndarray


class Labels(NamedTuple):
    """The ground truth per trial: onset (food: motion start), tap position, class label."""

    onset_ns: np.ndarray
    y_m: np.ndarray
    class_label: np.ndarray


def half_sine_bins(
    peak: np.ndarray, duration_s: np.ndarray, start_s: np.ndarray, rate_hz: float, n: int
) -> np.ndarray:
    """A half-sine force pulse per trial, ``(n_trials, n)``, averaged over each sample interval.

    Averaging (not sampling at instants) keeps the impulse ``2 * peak * duration / pi`` exact
    however short the pulse is against the sample period.
    """
    dt = 1.0 / rate_hz
    edges = np.arange(n + 1) * dt
    tau = duration_s[:, None]
    a = np.clip(edges[None, :-1] - start_s[:, None], 0.0, tau)
    b = np.clip(edges[None, 1:] - start_s[:, None], 0.0, tau)
    integral = peak[:, None] * tau / np.pi * (np.cos(np.pi * a / tau) - np.cos(np.pi * b / tau))
    return integral / dt
