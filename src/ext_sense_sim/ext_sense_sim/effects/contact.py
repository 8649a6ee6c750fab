"""The contact a task source hands to the structure: forces at a point, plus the labels.

Every task source effect (tap, handover grasp, fork) gives the signal ``contact`` and the
signal ``labels``; the structural effects turn the contact into loads at the grasp.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class Contact(NamedTuple):
    """Forces applied to the held object, per trial.

    Attributes:
        force_n: Force across the object, newtons, ``(n_trials, n_samples)``; its direction
            in the cross-section is ``angle_rad`` from the finger pads' normal.
        force_axial: Force along the object's axis toward the grasp, newtons,
            ``(n_trials, n_samples)``; reaches the pads as tangential traction.
        position_m: Where the force acts, metres from the grasp edge along the free span,
            ``(n_trials,)``.
        angle_rad: Direction of ``force_n`` from the pad normal, radians, ``(n_trials,)``.
    """

    force_n: np.ndarray
    force_axial: np.ndarray
    position_m: np.ndarray
    angle_rad: np.ndarray


class Labels(NamedTuple):
    """The ground truth of each trial of a batch.

    Attributes:
        onset_ns: True contact onset (food: motion start) from the trial origin, ``int64``.
        y_m: Tap position from the held end, metres (NaN when not a tap).
        class_label: Class per trial (food name, ``"stable"``/``"unstable"``, or ``""``).
    """

    onset_ns: np.ndarray
    y_m: np.ndarray
    class_label: np.ndarray


def half_sine_bins(
    peak: np.ndarray, duration_s: np.ndarray, start_s: np.ndarray, rate_hz: float, n: int
) -> np.ndarray:
    """A half-sine force pulse averaged over each sample interval.

    Averaging over the interval (instead of sampling at instants) keeps the impulse exact,
    ``2 * peak * duration / pi``, however short the pulse is against the sample period.

    Args:
        peak: Peak force per trial, newtons, ``(n_trials,)``.
        duration_s: Pulse length per trial, seconds, ``(n_trials,)``.
        start_s: Pulse start per trial from the trial origin, seconds, ``(n_trials,)``.
        rate_hz: Sample rate, Hz.
        n: Samples per trial.

    Returns:
        ``(n_trials, n)`` float64; sample ``k`` is the mean force over ``[k, k+1) / rate_hz``.
    """
    dt = 1.0 / rate_hz
    edges = np.arange(n + 1) * dt
    tau = duration_s[:, None]
    a = np.clip(edges[None, :-1] - start_s[:, None], 0.0, tau)
    b = np.clip(edges[None, 1:] - start_s[:, None], 0.0, tau)
    integral = peak[:, None] * tau / np.pi * (np.cos(np.pi * a / tau) - np.cos(np.pi * b / tau))
    return integral / dt
