"""The paper's NUSkin sampling-rate reduction, on events before windowing (no ROS)."""

from __future__ import annotations

import numpy as np

from ext_sense_perception.errors import PerceptionError


def refractory_mask(t_ns: np.ndarray, taxel: np.ndarray, rate_hz: float) -> np.ndarray:
    """Events kept when each taxel drops any spike closer than ``1/rate_hz`` to its last kept one.

    ``t_ns`` sorted int64 ns, ``taxel`` of the same length (PerceptionError: a rate not positive).
    """
    if not rate_hz > 0:
        raise PerceptionError(f"The 'rate_hz' parameter must be > 0. Got {rate_hz!r} instead.")
    t = np.asarray(t_ns, dtype=np.int64)
    tax = np.asarray(taxel)
    tau = round(1e9 / rate_hz)
    keep = np.zeros(len(t), dtype=bool)
    order = np.argsort(tax, kind="stable")
    bounds = np.flatnonzero(np.diff(tax[order])) + 1
    for group in np.split(order, bounds):
        times = t[group]
        local = np.zeros(len(group), dtype=bool)
        last = None
        # spikes are sparse per taxel, so a short loop per taxel is cheap
        for i, ti in enumerate(times):
            if last is None or ti - last >= tau:
                local[i] = True
                last = ti
        keep[group] = local
    return keep
