"""How far a model's estimates move when the arrival clock moves a window's onset (no ROS).

A model reading position from where events fall in the onset's bin does not hold live;
``bench/bench_window_shift.py`` prints these moves for the default tap model.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from ext_sense_perception.data.device_stream import recut
from ext_sense_perception.online.window import WindowConfig
from ext_sense_runtime.records import EventBlock


def estimate_moves(
    predict: Callable[[np.ndarray], np.ndarray],
    events: EventBlock,
    onsets_ns: np.ndarray,
    config: WindowConfig,
    shifts_ns: Sequence[int],
) -> dict[int, np.ndarray]:
    """Per shift, the ``(n,)`` absolute moves of each window's estimate when its onset moves by it.

    ``predict`` maps flattened windows to ``(n,)`` estimates; ``events`` are as the driver stamped
    them.
    """
    onsets = np.asarray(onsets_ns, dtype=np.int64)

    def estimates(shift: int) -> np.ndarray:
        x = recut(events, onsets, config, shift)
        return np.asarray(predict(x.reshape(len(onsets), -1)), dtype=np.float64)

    base = estimates(0)
    return {int(s): np.abs(estimates(int(s)) - base) for s in shifts_ns}
