"""A tap's window and what it holds: one rule for real captures and simulated trials.

The window (REFERENCE.md section 2, issue 30): the onset is the first 10 ms bin holding at least
``max(30, 20 % of the busiest bin)`` events of the whole capture; the window is the 25 bins from
it (250 ms). A capture of under 1,000 events is a missed tap and gives no window. The stretch
before a tap stays far under the onset threshold in both real and simulated captures.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from ext_sense_sim.fidelity.captures import BIN_NS, Capture

WINDOW_BINS = 25
MISSED_BELOW = 1000
ONSET_MIN_EVENTS = 30
ONSET_SHARE = 0.2
ACTIVE_MIN_EVENTS = 10
"""A taxel is active in a window from this many events."""
PREROLL_GUARD_BINS = 2
"""The quiet rate before a tap is counted up to 20 ms before the onset bin, which the tap's
first events may precede."""
BIN_S = BIN_NS / 1e9
WINDOW_S = WINDOW_BINS * BIN_S

STATS: dict[str, str] = {
    "events": "events",
    "first_30ms": "share of events in the first 30 ms",
    "last_100ms": "share of events in the last 100 ms",
    "busiest_10": "share held by the 10 busiest taxels",
    "finger_imbalance": "imbalance between the fingers |L-R|/(L+R)",
    "active_taxels": f"active taxels (>= {ACTIVE_MIN_EVENTS} events)",
    "positive_share": "share of positive-polarity events",
    "half_peak_ms": "time the rate stays >= half its peak, ms",
    "spectrum_4_8hz": "rate spectrum: AC power share at 4-8 Hz",
    "spectrum_12_20hz": "rate spectrum: AC power share at 12-20 Hz",
    "spectrum_24_48hz": "rate spectrum: AC power share at 24-48 Hz",
    "taxel_rate_median": "events/s of the median active taxel",
    "taxel_rate_max": "events/s of the busiest taxel",
    "preroll_rate": "events/s before the onset (to 20 ms before)",
}
"""Per-window statistics, name to meaning, in table order."""
RATIO_STATS = (
    "events",
    "active_taxels",
    "half_peak_ms",
    "taxel_rate_median",
    "taxel_rate_max",
    "preroll_rate",
)
"""Statistics compared as simulated / real; the others (shares) as simulated - real."""
NOT_FEATURES = ("preroll_rate",)
"""Left out of the two-sample test: measured on spans too unlike (~0.8 s real, the scene's
``onset_s`` simulated) to compare window by window."""
FEATURES = tuple(s for s in STATS if s not in NOT_FEATURES)
TABLE_FEATURES = ("events", "first_30ms", "last_100ms", "busiest_10", "finger_imbalance")
"""The statistics of issue 30's table."""
TARGET_FEATURES = TABLE_FEATURES[:4]
"""The AUC target's statistics: without the finger imbalance, the day's grip, which alone tells
the real sessions apart (so with it the target could not fail)."""
SPECTRUM_BANDS = {"spectrum_4_8hz": (1, 3), "spectrum_12_20hz": (3, 6), "spectrum_24_48hz": (6, 13)}
"""rFFT bins (4 Hz apart over 250 ms) of each band, ``[start, stop)``."""


class TapWindows(NamedTuple):
    """The windows of a set of captures.

    Per window: ``stats`` (:data:`STATS`), ``profiles`` (events per bin, ``(n, 25)``),
    ``taxel_counts`` ``(n, 80)``, ``onset_error_ms`` (found minus true onset, NaN if unknown).
    """

    names: list[str]
    stats: dict[str, npt.NDArray[np.float64]]
    profiles: npt.NDArray[np.float64]
    taxel_counts: npt.NDArray[np.float64]
    missed: list[str]
    cut_short: list[str]
    onset_error_ms: npt.NDArray[np.float64]


def onset_bin(counts: npt.NDArray[np.integer]) -> int | None:
    """First bin holding at least ``max(30, 20 % of the busiest bin)`` events (None: none)."""
    if counts.size == 0:
        return None
    threshold = max(ONSET_MIN_EVENTS, ONSET_SHARE * float(counts.max()))
    hits = np.flatnonzero(counts >= threshold)
    return int(hits[0]) if hits.size else None


def window_stats(
    wbin: npt.NDArray[np.int64],
    taxel: npt.NDArray[np.integer],
    polarity: npt.NDArray[np.integer],
    preroll_events: int,
    preroll_bins: int,
) -> tuple[dict[str, float], npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """The statistics, profile ``(25,)`` and taxel counts ``(80,)`` of one window's events."""
    n = wbin.size
    profile = np.bincount(wbin, minlength=WINDOW_BINS).astype(np.float64)
    counts = np.bincount(taxel.astype(np.intp) - 1, minlength=80).astype(np.float64)
    left, right = counts[:40].sum(), counts[40:].sum()
    active = counts[counts >= ACTIVE_MIN_EVENTS]
    ac = np.abs(np.fft.rfft(profile - profile.mean())) ** 2
    total = ac[1:].sum()
    stats = {
        "events": float(n),
        "first_30ms": float(np.mean(wbin < 3)),
        "last_100ms": float(np.mean(wbin >= WINDOW_BINS - 10)),
        "busiest_10": float(np.sort(counts)[-10:].sum() / n),
        "finger_imbalance": float(abs(left - right) / (left + right)),
        "active_taxels": float(active.size),
        "positive_share": float(np.mean(polarity > 0)),
        "half_peak_ms": float(np.sum(profile >= 0.5 * profile.max()) * BIN_S * 1e3),
        "taxel_rate_median": float(np.median(active) / WINDOW_S) if active.size else 0.0,
        "taxel_rate_max": float(counts.max() / WINDOW_S),
        "preroll_rate": preroll_events / (preroll_bins * BIN_S) if preroll_bins else np.nan,
    }
    for name, (lo, hi) in SPECTRUM_BANDS.items():
        stats[name] = float(ac[lo:hi].sum() / total) if total > 0 else 0.0
    return stats, profile, counts


def tap_windows(captures: list[Capture]) -> TapWindows:
    """Find each capture's tap and describe its window (missed taps are listed, not cut)."""
    names: list[str] = []
    rows: list[dict[str, float]] = []
    profiles, taxels, missed, cut_short, onset_err = [], [], [], [], []
    for cap in captures:
        if cap.size < MISSED_BELOW:
            missed.append(cap.name)
            continue
        counts = np.bincount(cap.bins)
        onset = onset_bin(counts)
        if onset is None:
            missed.append(cap.name)
            continue
        inside = (cap.bins >= onset) & (cap.bins < onset + WINDOW_BINS)
        stats, profile, per_taxel = window_stats(
            cap.bins[inside] - onset,
            cap.taxel[inside],
            cap.polarity[inside],
            int(np.sum(cap.bins < onset - PREROLL_GUARD_BINS)),
            max(onset - PREROLL_GUARD_BINS, 0),
        )
        names.append(cap.name)
        rows.append(stats)
        profiles.append(profile)
        taxels.append(per_taxel)
        if onset + WINDOW_BINS > cap.span_bins:
            cut_short.append(cap.name)
        onset_err.append((onset - cap.mark_bin) * BIN_S * 1e3 if cap.mark_bin >= 0 else np.nan)
    return TapWindows(
        names=names,
        stats={s: np.array([r[s] for r in rows], np.float64) for s in STATS},
        profiles=np.array(profiles, np.float64).reshape(-1, WINDOW_BINS),
        taxel_counts=np.array(taxels, np.float64).reshape(-1, 80),
        missed=missed,
        cut_short=cut_short,
        onset_error_ms=np.array(onset_err, np.float64),
    )
