"""What each calibration stage fits, to which real statistics, and how it measures a scene.

``noise``: a NUSkin tap scene's noise against the quiet stretch before each real tap; ``taps``:
its tap, rod damping, load share and contact strip against the real tap windows (their medians
and, by a two-sample AUC, how their statistics go together); ``food``: the
food scene's noise, resting readings, strip and grip against the real trials' motion. The
tolerances: docs/simulator.md, "Calibration against the real sensor".
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any, NamedTuple

import numpy as np

from ext_sense_sim.calibration.search import FreeParameter, FreeWidth, Measure, with_values
from ext_sense_sim.fidelity.captures import BIN_NS, simulate
from ext_sense_sim.fidelity.compare import two_sample_auc
from ext_sense_sim.fidelity.food import food_trials
from ext_sense_sim.fidelity.taps import (
    MISSED_BELOW,
    TARGET_FEATURES,
    WINDOW_S,
    onset_bin,
    tap_windows,
)
from ext_sense_sim.scene import Scene

# The NUSkin tap scenes against the real rod captures ---------------------------------------

TAP_FREE = (
    FreeParameter("contact_impulse", "force_n", 0.02, 5.0, spread=(0.8, 1.25)),
    FreeWidth("contact_impulse", "force_n", 1.0, 3.0),
    FreeParameter("contact_impulse", "duration_s", 0.002, 0.08, spread=(0.8, 1.25)),
    FreeParameter("contact_impulse", "impact_force_n", 0.01, 10.0, spread=(0.8, 1.25)),
    FreeParameter("beam_modes", "grasp_damping_ratio", 0.001, 0.2),
    FreeParameter("grasp_transfer", "finger_load_share", 0.01, 0.57, spread=(1 / 3, 5 / 3)),
    FreeParameter("grasp_transfer", "strip_sigma_m", 0.0008, 0.004),
    FreeParameter("grasp_transfer", "strip_profile_power", 1.0, 8.0),
    FreeParameter("contact_impulse", "moment_exponent", 0.2, 3.0),
    FreeParameter("grasp_transfer", "gain_spread", 0.01, 0.9),
    FreeParameter("nuskin_transduction", "refractory_s", 0.00025, 0.001),
)
"""The tap's force (and how much one person's taps vary in force), length and impact, the
grasp's damping, the fingers' load share, the pads' contact strip (its width and profile), how
the tap's force falls with its lever arm, how the taxels' sensitivity differs and how soon a
taxel can fire again. A range starts at x0.8-1.25 about its centre and keeps its width as the
centre moves; only the force's width is fitted (the real taps' spread of events, and how the
statistics go together, say how much the taps' force varies)."""

AUC_TOLERANCE = 0.15
"""The two-sample AUC's tolerance about 0.5 (no forest tells the sets apart): it carries how the
targeted statistics go together, which their medians do not see; an AUC of 0.86 weighs as much
as a median 2.4 tolerances off."""
AUC_SEED = 0
"""Folds and forests of the calibration's two-sample AUC: the same for every step."""
AUC_REPEATS = 3
"""Cross-validation shuffles of the calibration's two-sample AUC (the check uses more)."""

TAP_TOLERANCES = {
    "events": (math.log(1.4), True),
    "first_30ms": (0.07, False),
    "last_100ms": (0.07, False),
    "busiest_10": (0.10, False),
    "finger_imbalance": (0.07, False),
    "active_taxels": (10.0, False),
    "taxel_rate_max": (math.log(1.4), True),
    "events_p75_over_p25": (math.log(1.2), True),
    "busiest_10_events_p75_over_p25": (math.log(1.1), True),
    "auc_vs_real": (AUC_TOLERANCE, False),
}
"""Statistic to ``(tolerance, compared as log ratio)``."""


def window_medians(stats: Mapping[str, np.ndarray]) -> dict[str, float]:
    """Each statistic's median over windows, and how varied the windows' event counts are.

    Both all their events and those of their 10 busiest taxels (the same few taxels lead every
    real tap with nearly the same count).
    """
    out = {name: float(np.nanmedian(v)) for name, v in stats.items()}
    busiest = stats["busiest_10"] * stats["events"]
    for name, counts in (("events", stats["events"]), ("busiest_10_events", busiest)):
        p25, p75 = np.percentile(counts, [25, 75]) if len(counts) else (1.0, 1.0)
        out[f"{name}_p75_over_p25"] = float(p75 / p25) if p25 > 0 else float("nan")
    return out


def tap_medians(captures: Sequence[Any]) -> dict[str, float]:
    """:func:`window_medians` of the real captures' tap windows, and the AUC to aim at (0.5)."""
    return window_medians(tap_windows(captures).stats) | {"auc_vs_real": 0.5}


def target_rows(stats: Mapping[str, np.ndarray]) -> np.ndarray:
    """The windows' targeted statistics (``fidelity.taps.TARGET_FEATURES``), one row each."""
    return np.column_stack([stats[name] for name in TARGET_FEATURES])


def tap_measure(trials: int, seed: int, real: Sequence[Any]) -> Measure:
    """Simulate ``trials`` taps with ``seed``: the windows' medians and their AUC against ``real``.

    ``auc_vs_real`` is the two-sample AUC of a forest telling the simulated windows from the
    real captures' on the targeted statistics (the fidelity check's test, fewer repeats).
    """
    real_rows = target_rows(tap_windows(list(real)).stats)

    def measure(scene: Scene) -> dict[str, float]:
        stats = tap_windows(simulate(scene, trials, seed, extra_s=WINDOW_S).captures).stats
        auc = two_sample_auc(target_rows(stats), real_rows, AUC_SEED, AUC_REPEATS)
        return window_medians(stats) | {"auc_vs_real": auc}

    return measure


# The NUSkin food scene against the real food-poking sessions -------------------------------

FOOD_FREE = (
    FreeParameter("sensor_noise", "white_pa", 50.0, 2000.0),
    FreeParameter("sensor_noise", "white_spread", 0.05, 1.5),
    FreeParameter("sensor_noise", "drift_pa", 10.0, 2000.0),
    FreeParameter("nuskin_transduction", "offset_counts", 20.0, 300.0),
    FreeParameter("nuskin_transduction", "offset_spread", 0.05, 1.5),
    FreeParameter("grasp_transfer", "strip_sigma_m", 0.0005, 0.004),
    FreeParameter("grasp_transfer", "grip_force_n", 2.0, 60.0, spread=(0.75, 1.25)),
)
"""The sensor's noise, its spread and drift, the resting readings, the pads' contact strip and
the grip that presses the fork's handle into them."""

FOOD_TOLERANCES = {
    "events_per_s": (math.log(1.25), True),
    "active_taxels": (4.0, False),
    "value_p5": (10.0, False),
    "value_p50": (15.0, False),
    "value_p95": (math.log(1.3), True),
}
"""Statistic to ``(tolerance, compared as log ratio)``."""


def food_medians(captures: Sequence[Any]) -> dict[str, float]:
    """The median of each food-trial statistic over the captures."""
    return {name: float(np.nanmedian(v)) for name, v in food_trials(captures).stats.items()}


def food_measure(trials: int, seed: int, real: Sequence[Any] = ()) -> Measure:
    """Simulate ``trials`` food trials with ``seed`` and return their median statistics.

    ``real`` (the real captures, which the medians are compared with) is not needed here.
    """
    return lambda scene: food_medians(simulate(scene, trials, seed).captures)


# The NUSkin's noise against the quiet stretch before each real tap --------------------------

NOISE_FREE = (
    FreeParameter("sensor_noise", "white_pa", 20.0, 1000.0),
    FreeParameter("sensor_noise", "chatty_pa", 100.0, 3000.0),
)
"""The patch's white noise and its chatty taxels' noise."""

NOISE_TOLERANCES = {
    "quiet_rate": (math.log(1.5), True),
    "quiet_busiest_share": (0.10, False),
    "quiet_taxels_per_s": (math.log(1.5), True),
}
"""Statistic to ``(tolerance, compared as log ratio)``."""

QUIET_GAP_NS = 50_000_000
"""The quiet stretch ends this long before the tap's onset (the window's pre-onset part)."""


def quiet_stats(captures: Sequence[Any], onsets_ns: Sequence[int]) -> dict[str, float]:
    """Median quiet-stretch statistics of captures, given each one's onset (ns from its start).

    ``quiet_rate``: events per second before ``onset - 50 ms``; ``quiet_busiest_share``: the
    share of those on the busiest taxel; ``quiet_taxels_per_s``: distinct taxels that fired,
    per second of quiet stretch. Captures with under 20 ms of quiet stretch are left out.
    """
    rows = []
    for cap, onset in zip(captures, onsets_ns, strict=True):
        end_bin = (onset - QUIET_GAP_NS) // BIN_NS
        if end_bin < 2:
            continue
        quiet = cap.bins < end_bin
        seconds = end_bin * BIN_NS / 1e9
        counts = np.bincount(cap.taxel[quiet].astype(np.intp), minlength=81)
        total = counts.sum()
        busiest = counts.max() / total if total else 0.0
        rows.append((total / seconds, busiest, np.count_nonzero(counts) / seconds))
    med = np.median(np.array(rows), axis=0) if rows else np.full(3, np.nan)
    return dict(zip(NOISE_TOLERANCES, map(float, med), strict=True))


def real_quiet_stats(captures: Sequence[Any]) -> dict[str, float]:
    """:func:`quiet_stats` of real tap captures, each cut at its tap's onset bin."""
    kept, onsets = [], []
    for cap in captures:
        onset = onset_bin(np.bincount(cap.bins)) if cap.size >= MISSED_BELOW else None
        if onset is not None:
            kept.append(cap)
            onsets.append(onset * BIN_NS)
    return quiet_stats(kept, onsets)


def noise_measure(
    trials: int, seed: int, real: Sequence[Any] = (), seconds: float = 1.0
) -> Measure:
    """Simulate ``trials`` untapped trials of ``seconds`` (silenced taps) and their quiet stats.

    ``real`` (the real captures) is not needed here.
    """
    silent = (
        FreeParameter("contact_impulse", "force_n", 0.0, 0.0),
        FreeParameter("contact_impulse", "impact_force_n", 0.0, 0.0),
    )

    def measure(scene: Scene) -> dict[str, float]:
        quiet = dataclasses.replace(with_values(scene, silent, [0.0, 0.0]), trial_s=seconds)
        captures = simulate(quiet, trials, seed).captures
        onsets = [(cap.span_bins - 1) * BIN_NS + QUIET_GAP_NS for cap in captures]
        return quiet_stats(captures, onsets)

    return measure


class Stage(NamedTuple):
    """One stage: what it moves, its tolerances, how it measures, its real statistics."""

    free: tuple[FreeParameter, ...]
    tolerances: dict[str, tuple[float, bool]]
    measure: Callable[[int, int, Sequence[Any]], Measure]
    """``(trials, seed, real captures)`` to a scene's statistics."""
    real: Callable[[Sequence[Any]], dict[str, float]]
    trials: int
    """Simulated trials per evaluation by default."""


STAGES = {
    "noise": Stage(NOISE_FREE, NOISE_TOLERANCES, noise_measure, real_quiet_stats, 20),
    "taps": Stage(TAP_FREE, TAP_TOLERANCES, tap_measure, tap_medians, 200),
    "food": Stage(FOOD_FREE, FOOD_TOLERANCES, food_measure, food_medians, 21),
}
"""The stages by name: ``noise`` then ``taps`` for a NUSkin tap scene, ``food`` for a food one."""
