"""NUSkin events of a batch of trials: the runtime ``EventBlock`` plus the trial of each event.

The simulator's ``events`` signal is the pair ``(trial, events)`` (:data:`TrialEvents`):

- ``events`` is an :class:`ext_sense_runtime.records.EventBlock` (the record every package
  passes NUSkin events in), times from each trial's origin;
- ``trial`` is an ``int32`` array parallel to it: the trial index of each event, batch-local in
  the effects, run-wide once :class:`ext_sense_sim.dataset.DatasetCollector` has offset it.

The pair is sorted by trial, then time (stable), so one trial's events are a contiguous slice
(:func:`trial_bounds`). The functions here keep the two in step; none copies the event columns
into a record of its own.
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
    """The pair sorted by trial, then time (stable: equal keys keep their order).

    Args:
        trial: Trial index of each event, shape ``(events.size,)``.
        events: The events.

    Raises:
        ValueError: ``trial`` is not 1-D of the events' length.
    """
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
    """``(n_trials + 1,)`` bounds: trial ``i``'s events are ``[bounds[i], bounds[i + 1])``.

    ``trial`` must be sorted (as :func:`by_trial` leaves it).
    """
    return np.searchsorted(trial, np.arange(n_trials + 1))


def last_values(
    trial: npt.NDArray[np.integer], events: EventBlock, n_trials: int
) -> npt.NDArray[np.uint16]:
    """Value of each taxel's last event per trial (0 when none), ``(n_trials, 80)`` uint16.

    "Last" is the latest row of a sorted pair (as :func:`by_trial` leaves it).
    """
    out = np.zeros((n_trials, 80), dtype=np.uint16)
    out[trial, events.taxel.astype(np.intp) - 1] = events.value  # later rows win
    return out
