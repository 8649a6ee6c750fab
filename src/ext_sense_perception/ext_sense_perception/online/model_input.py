"""The window a model accepts, and a window turned into a model's input row (no ROS)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ext_sense_perception.errors import PerceptionError


class Geometry(NamedTuple):
    """Shape and timing of the windows a model (or feature pipeline) accepts."""

    n_channels: int
    n_samples: int
    period_ns: int
    pre_ns: int
    sensor: str = "nuskin"

    @property
    def post_ns(self) -> int:
        """Post-onset signal the windows hold, ns."""
        return self.n_samples * self.period_ns - self.pre_ns


def as_model_input(window: object, geometry: Geometry) -> np.ndarray:
    """One window (or ``(n_channels, n_samples)`` array) as a flat float32 row for a model.

    A longer window is cropped to the model's (same onset); a NUSkin window at a finer bin dividing
    the model's is rebinned by summing (counts add exactly). PerceptionError: a window too short, of
    other channels or sample period, or not finite.
    """
    data = getattr(window, "data", window)
    x = np.asarray(data)
    if x.ndim == 1 and hasattr(window, "channels"):
        x = x.reshape(len(window.channels), -1)  # type: ignore[attr-defined]
    if x.ndim != 2 or x.shape[0] != geometry.n_channels:
        raise PerceptionError(
            f"The 'window.data' parameter must have {geometry.n_channels} channels. Got shape "
            f"{x.shape} instead."
        )
    factor = 1
    if hasattr(window, "sample_period_ns"):
        period = int(window.sample_period_ns)  # type: ignore[attr-defined]
        if period != geometry.period_ns:
            if geometry.sensor != "nuskin" or period <= 0 or geometry.period_ns % period:
                raise PerceptionError(
                    f"The 'window.sample_period_ns' parameter must be {geometry.period_ns} "
                    f"(or divide it, NUSkin). Got {period} instead."
                )
            factor = geometry.period_ns // period
        extra_pre = int(window.pre_onset_ns) - geometry.pre_ns  # type: ignore[attr-defined]
        if extra_pre < 0 or extra_pre % period:
            raise PerceptionError(
                f"The 'window.pre_onset_ns' parameter must be >= {geometry.pre_ns}. "
                f"Got {int(window.pre_onset_ns)} instead."  # type: ignore[attr-defined]
            )
        x = x[:, extra_pre // period :]
    need = geometry.n_samples * factor
    if x.shape[1] < need:
        raise PerceptionError(
            f"The 'window.data' parameter must hold at least {need} samples after the model's "
            f"pre-onset start. Got {x.shape[1]} instead."
        )
    x = x[:, :need]
    if not np.isfinite(x).all():
        raise PerceptionError("The 'window.data' parameter must be finite. Got NaN or inf instead.")
    if factor > 1:
        x = x.reshape(x.shape[0], geometry.n_samples, factor).sum(axis=2)
    return np.ascontiguousarray(x, dtype=np.float32).ravel()
