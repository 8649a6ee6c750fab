"""NUSkin events of a batch of trials: the runtime ``EventBlock`` plus the trial of each event.

The ``events`` signal is the pair ``(trial, events)`` (:data:`TrialEvents`), sorted by trial
then time, so one trial's events are a contiguous slice (:func:`trial_bounds`); trial indices
are batch-local in the effects, run-wide in the dataset.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from ext_sense_runtime.records import EventBlock

TrialEvents = tuple[npt.NDArray[np.int32], EventBlock]
"""``(trial, events)``: per-event trial indices and the events (see the module docstring)."""


def empty() -> TrialEvents:
    """No events."""
    return np.zeros(0, np.int32), EventBlock.empty()


def by_trial(trial: npt.ArrayLike, events: EventBlock) -> TrialEvents:
    """The pair sorted by trial, then time (stable); ``trial`` gives one index per event."""
    trial = np.asarray(trial).astype(np.int32, copy=False)
    if trial.shape != (events.size,):
        raise ValueError(
            f"The 'trial' parameter must give one trial per event, shape ({events.size},). "
            f"Got shape {trial.shape} instead."
        )
    order = np.lexsort((events.t_ns, trial))
    return trial[order], events.select(order)


def concat(parts: Sequence[TrialEvents]) -> TrialEvents:
    """Join pairs end to end, unsorted (an empty sequence gives no events)."""
    if not parts:
        return empty()
    return (
        np.concatenate([trial for trial, _ in parts]),
        EventBlock.concat([events for _, events in parts]),
    )


def merge(*parts: TrialEvents) -> TrialEvents:
    """All the events of ``parts``, sorted by trial, then time."""
    return by_trial(*concat(parts))


def trial_bounds(trial: npt.NDArray[np.integer], n_trials: int) -> npt.NDArray[np.intp]:
    """Bounds ``(n_trials + 1,)`` of each trial's events in a sorted ``trial``."""
    return np.searchsorted(trial, np.arange(n_trials + 1))


def last_values(
    trial: npt.NDArray[np.integer], events: EventBlock, n_trials: int
) -> npt.NDArray[np.uint16]:
    """Value of each taxel's last event per trial (0 when none) of a sorted pair, ``(n, 80)``."""
    out = np.zeros((n_trials, 80), dtype=np.uint16)
    out[trial, events.taxel.astype(np.intp) - 1] = events.value  # later rows win
    return out
