"""Traces for the view's plots: the BioTac PAC signal and the event rate per finger.

Sent at display rate as short JSON messages: the last second of PAC per sensor, decimated, and
one rate per finger.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from ext_sense.view.errors import ViewError

PAC_RATE_HZ = 2200
"""BioTac PAC samples per second (22 per 100 Hz frame)."""


class PacTrace:
    """The last ``seconds`` of each BioTac sensor's PAC samples, a ring buffer per sensor.

    :meth:`message` keeps every ``decimate``-th sample (1100 points still show a 1 kHz
    vibration's envelope).
    """

    def __init__(self, seconds: float = 1.0, decimate: int = 2) -> None:
        if not seconds > 0 or decimate < 1:
            raise ViewError(
                f"The 'seconds' and 'decimate' parameters must be > 0 and >= 1. Got {seconds} "
                f"and {decimate} instead."
            )
        self.n = round(seconds * PAC_RATE_HZ)
        self.decimate = decimate
        self._rings: dict[int, npt.NDArray[np.float64]] = {}
        self._fill: dict[int, int] = {}

    def add(self, sensor_id: int, pac: npt.ArrayLike) -> None:
        """Append one frame's PAC samples of a sensor."""
        samples = np.asarray(pac, dtype=np.float64).reshape(-1)[-self.n :]
        ring = self._rings.setdefault(sensor_id, np.zeros(self.n))
        k = samples.size
        ring[:-k] = ring[k:]
        ring[-k:] = samples
        self._fill[sensor_id] = min(self.n, self._fill.get(sensor_id, 0) + k)

    def message(self) -> dict[str, Any]:
        """``{"sensor_ids": [...], "pac_<id>": [...oldest..newest]}`` for a plot by index."""
        out: dict[str, Any] = {"sensor_ids": sorted(self._rings)}
        for sid in out["sensor_ids"]:
            filled = self._rings[sid][self.n - self._fill[sid] :]
            out[f"pac_{sid}"] = filled[:: self.decimate].round(1).tolist()
        return out


def rates_message(finger_rates_hz: npt.ArrayLike, rejected: int = 0) -> dict[str, Any]:
    """The event rate per finger for a plot over time, events/s."""
    left, right = (float(x) for x in np.asarray(finger_rates_hz, dtype=np.float64)[:2])
    return {
        "left_events_per_s": round(left, 1),
        "right_events_per_s": round(right, 1),
        "total_events_per_s": round(left + right, 1),
        "rejected_events": int(rejected),
    }
