"""The NUSkin receiver's link to the host: a first-in first-out queue drained at its word rate.

Model. Each decoded event goes to the host as one 4-byte word, at most ``words_per_s`` a second
(0: unlimited): word ``k`` leaves at ``d_k = max(t_k, d_{k-1} + 1 / words_per_s)``, so a burst
faster than the link drains at its rate, a flat ceiling and a tail as in the real rod taps.
Event times become the departure times (what a host stamps); words still queued at the trial's
end are left out (``dropped``), so trials laid back to back never overlap.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from ext_sense_sim.effects.base import Effect, Signals, TimeBase
from ext_sense_sim.trial_events import trial_bounds


def drain_times(t_ns: np.ndarray, starts: np.ndarray, word_ns: float) -> np.ndarray:
    """When each event leaves a FIFO drained one word per ``word_ns``, per trial.

    ``starts`` bounds each trial's events (sorted times). ``d_k = max(t_k, d_{k-1} + word_ns)``
    is computed as ``k w + running max of (t_j - j w)``, without a loop over events.
    """
    n = t_ns.size
    if n == 0:
        return t_ns.copy()
    counts = np.diff(starts)
    k = np.arange(n) - np.repeat(starts[:-1], counts)  # index within its trial
    slack = t_ns.astype(np.float64) - k * word_ns
    # keep the running maximum from crossing into the next trial
    span = float(t_ns.max() - t_ns.min()) + n * word_ns + 1.0
    trial = np.repeat(np.arange(counts.size), counts)
    lifted = np.maximum.accumulate(slack + trial * span) - trial * span
    return np.round(lifted + k * word_ns).astype(np.int64)


class ReceiverLink(Effect):
    """The receiver's word rate to the host (see module docstring). Delays ``events``."""

    name = "receiver_link"
    needs = ("events",)
    gives = ("events",)
    defaults: ClassVar[dict[str, Any]] = {"words_per_s": 0.0}

    def setup(self) -> None:
        """Count the words left in the queue at the trials' ends."""
        self.dropped = 0

    def run(self, signals: Signals, time: TimeBase, rng: np.random.Generator) -> None:
        """Replace each event's time by the time its word leaves the receiver."""
        rate = self.scalar("words_per_s", 0.0, 1e8)
        if rate <= 0:
            return
        trial, events = signals.need("events", self.name)
        starts = trial_bounds(trial, time.n_trials)
        departed = drain_times(events.t_ns, starts, 1e9 / rate)
        inside = departed < round(time.n_samples * time.dt * 1e9)
        self.dropped += int(inside.size - np.count_nonzero(inside))
        kept = np.flatnonzero(inside)
        signals["events"] = (trial[kept], events._replace(t_ns=departed).select(kept))
