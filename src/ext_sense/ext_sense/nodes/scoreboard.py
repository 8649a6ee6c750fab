"""Scoring estimates against ground truth as they arrive (no rclpy).

Shared by the estimate monitor and the offline replay: each final estimate is matched to the
unmatched trial whose onset is nearest, one line is printed for it, and :meth:`Scoreboard.
summary` gives the main job's last line (``summary: taps=N mae_cm=X compute_p50_ms=Y
compute_p99_ms=Z``; ``trials=N accuracy=X`` for classes; ``estimates=N degraded=D`` without
ground truth, where every final estimate is counted unscored).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ext_sense_runtime.records import Estimate, GroundTruth
from ext_sense_runtime.stamps import MS


@dataclass
class Scoreboard:
    """Matches final estimates to ground truth and keeps the running score.

    ``match_tolerance_ns`` is the largest onset difference that still matches; without
    ``ground_truth`` final estimates are counted and printed unscored.
    """

    task: str
    match_tolerance_ns: int = 300 * MS
    ground_truth: bool = True
    truths: list[GroundTruth] = field(default_factory=list)
    pending: list[Estimate] = field(default_factory=list)
    errors_m: list[float] = field(default_factory=list)
    correct: list[bool] = field(default_factory=list)
    latencies_ns: list[int] = field(default_factory=list)
    unmatched_estimates: int = 0
    provisional_seen: int = 0
    degraded: list[Estimate] = field(default_factory=list)
    """Final estimates flagged degraded: matched to their trial, listed, not scored."""

    @property
    def is_regression(self) -> bool:
        """Whether estimates are positions (tap localization)."""
        return self.task == "tap_localization"

    unscored: int = 0
    """Final estimates counted without ground truth."""

    @property
    def scored(self) -> int:
        """Final estimates matched to a trial so far (without ground truth: counted)."""
        if not self.ground_truth:
            return self.unscored
        return len(self.errors_m) if self.is_regression else len(self.correct)

    def add_truth(self, truth: GroundTruth) -> list[str]:
        """Record a trial; returns lines for pending estimates it now matches."""
        self.truths.append(truth)
        waiting, self.pending = self.pending, []
        lines: list[str] = []
        for est in waiting:
            lines += self.add_estimate(est)
        return lines

    def add_estimate(self, est: Estimate) -> list[str]:
        """Score a final estimate (provisional ones are only counted); returns printed lines."""
        if est.provisional:
            self.provisional_seen += 1
            return []
        if not self.ground_truth:
            return [self._count(est)]
        truth = self._match(est.onset_ns)
        if truth is None:
            self.pending.append(est)
            return []
        if est.degraded:  # not a normal estimate: listed, never scored as one
            self.degraded.append(est)
            return [f"trial {truth.trial:3d}: DEGRADED estimate not scored ({est.degraded_reason})"]
        self.latencies_ns.append(int(est.compute_latency_ns))
        latency = f"latency {est.compute_latency_ns / MS:.2f} ms"
        lag = f"onset {(est.onset_ns - truth.onset_ns) / MS:+.1f} ms"
        if self.is_regression:
            err = abs(est.tap_position_m - truth.tap_position_m)
            self.errors_m.append(err)
            return [
                f"tap {self.scored:3d} (trial {truth.trial}): estimate "
                f"{est.tap_position_m * 100:6.2f} cm ± {est.tap_position_std_m * 100:4.2f} | "
                f"true {truth.tap_position_m * 100:6.2f} cm | error {err * 100:5.2f} cm | "
                f"{lag} | {latency}"
            ]
        label = _label(est)
        ok = label == truth.class_label
        self.correct.append(ok)
        return [
            f"trial {truth.trial:3d}: estimate {label or '?':<12} | true {truth.class_label:<12} | "
            f"{'ok   ' if ok else 'WRONG'} | {lag} | {latency}"
        ]

    def _count(self, est: Estimate) -> str:
        """The line of a final estimate with no truth to score it against."""
        self.unscored += 1
        latency = f"latency {est.compute_latency_ns / MS:.2f} ms"
        if est.degraded:
            self.degraded.append(est)
            latency += f" | DEGRADED ({est.degraded_reason})"
        else:
            self.latencies_ns.append(int(est.compute_latency_ns))
        if self.is_regression:
            what = f"{est.tap_position_m * 100:6.2f} cm ± {est.tap_position_std_m * 100:4.2f}"
            return f"tap {self.unscored:3d}: estimate {what} | {latency}"
        return f"trial {self.unscored:3d}: estimate {_label(est) or '?':<12} | {latency}"

    def _match(self, onset_ns: int) -> GroundTruth | None:
        best, best_dt = None, self.match_tolerance_ns + 1
        for truth in self.truths:
            dt = abs(onset_ns - truth.onset_ns)
            if dt < best_dt:
                best, best_dt = truth, dt
        if best is not None:
            self.truths.remove(best)
        return best

    def close(self) -> None:
        """Count estimates that never matched a trial (call at the end)."""
        self.unmatched_estimates += len(self.pending)
        self.pending.clear()

    def summary(self) -> str:
        """The last line of the main job (see the module docstring)."""
        lat = np.asarray(self.latencies_ns, dtype=np.float64) / MS
        p50, p99 = np.percentile(lat, [50, 99]) if lat.size else (float("nan"), float("nan"))
        compute = f"compute_p50_ms={p50:.2f} compute_p99_ms={p99:.2f}"
        if not self.ground_truth:
            counted = f"estimates={self.unscored} degraded={len(self.degraded)}"
            return f"summary: {counted} {compute} (no ground truth)"
        if self.is_regression:
            mae = float(np.mean(self.errors_m)) * 100 if self.errors_m else float("nan")
            return f"summary: taps={self.scored} mae_cm={mae:.2f} {compute}"
        acc = float(np.mean(self.correct)) if self.correct else float("nan")
        return f"summary: trials={self.scored} accuracy={acc:.3f} {compute}"


def _label(est: Estimate) -> str:
    """The estimate's class; a handover's from ``P(stable)``."""
    if not est.class_label and not math.isnan(est.stability_probability):
        return "stable" if est.stability_probability >= 0.5 else "unstable"
    return est.class_label
