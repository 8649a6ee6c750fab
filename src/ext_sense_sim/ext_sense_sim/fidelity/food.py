"""What a food trial holds after the arm starts moving: one rule for real and simulated trials.

Each trial is read over the same :data:`SPAN_S` from the arm's motion start (every real capture
covers it), so trials of different lengths compare.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from ext_sense_sim.fidelity.captures import BIN_NS, Capture

SPAN_S = 2.3
"""Seconds after the motion start each trial is read over."""
SPAN_BINS = round(SPAN_S * 1e9 / BIN_NS)

STATS: dict[str, str] = {
    "events": f"events in the {SPAN_S:g} s after the motion start",
    "events_per_s": "events per second after the motion start",
    "active_taxels": "active taxels (>= 1 event)",
    "value_p5": "10-bit value, 5th percentile",
    "value_p50": "10-bit value, median",
    "value_p95": "10-bit value, 95th percentile",
}
"""Per-trial statistics, name to meaning, in table order."""
FEATURES = ("events_per_s", "active_taxels", "value_p5", "value_p50", "value_p95")
"""The two-sample test's inputs (no polarity: the real food captures' bit is 0 throughout)."""


class FoodTrials(NamedTuple):
    """The trials of a food session; ``values``: the 10-bit values of all their events."""

    names: list[str]
    labels: list[str]
    stats: dict[str, npt.NDArray[np.float64]]
    values: npt.NDArray[np.uint16]
    cut_short: list[str]


def food_trials(captures: list[Capture]) -> FoodTrials:
    """Describe each trial's span after its motion start."""
    rows: list[dict[str, float]] = []
    values, cut_short = [], []
    for cap in captures:
        inside = (cap.bins >= cap.mark_bin) & (cap.bins < cap.mark_bin + SPAN_BINS)
        covered = min(SPAN_BINS, cap.span_bins - cap.mark_bin)
        if covered < SPAN_BINS:
            cut_short.append(cap.name)
        v = cap.value[inside]
        p5, p50, p95 = np.percentile(v, [5, 50, 95]) if v.size else (np.nan,) * 3
        n = int(inside.sum())
        rows.append(
            {
                "events": float(n),
                "events_per_s": n / (max(covered, 1) * BIN_NS / 1e9),
                "active_taxels": float(np.unique(cap.taxel[inside]).size),
                "value_p5": float(p5),
                "value_p50": float(p50),
                "value_p95": float(p95),
            }
        )
        values.append(v)
    return FoodTrials(
        names=[c.name for c in captures],
        labels=[c.label for c in captures],
        stats={s: np.array([r[s] for r in rows], np.float64) for s in STATS},
        values=np.concatenate(values).astype(np.uint16) if values else np.zeros(0, np.uint16),
        cut_short=cut_short,
    )
