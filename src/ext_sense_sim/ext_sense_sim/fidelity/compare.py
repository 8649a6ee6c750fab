"""Summaries, the issue's targets and a classifier two-sample test.

A random forest tries to tell two sets of windows apart from their statistics (cross-validated
ROC AUC 0.5: it cannot, 1.0: always). Real sessions of one rod already differ, so a scene passes
when it is told from the real windows no better than two real sessions are, plus a margin.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt
from sklearn.ensemble import RandomForestClassifier
from sklearn.metrics import roc_auc_score
from sklearn.model_selection import StratifiedKFold, cross_val_predict

AUC_MARGIN = 0.05
"""Issue 30: sim-vs-real AUC no higher than real-vs-real + 0.05."""
FOLDS = 5
REPEATS = 5
"""Cross-validation shuffles averaged (the real sessions' AUC then moves by ~0.02 by seed)."""
TREES = 50


class Target(NamedTuple):
    """A target on one statistic's median: a ratio range or an absolute difference."""

    stat: str
    kind: str  # "ratio" or "diff"
    low: float
    high: float

    def allowed(self) -> str:
        """The target in words, e.g. ``x0.7-1.4`` or ``+-0.07``."""
        if self.kind == "ratio":
            return f"x{self.low:g}-{self.high:g}"
        return f"+-{self.high:g}"

    def measure(self, real: float, sim: float) -> float:
        """Ratio ``sim / real`` or difference ``sim - real`` (NaN when undefined)."""
        if self.kind == "ratio":
            return sim / real if real > 0 else float("nan")
        return sim - real

    def holds(self, real: float, sim: float) -> bool:
        """Whether ``sim`` is within the target of ``real``."""
        value = self.measure(real, sim)
        if self.kind == "ratio":
            return bool(self.low <= value <= self.high)
        return bool(abs(value) <= self.high)


TAP_TARGETS = (
    Target("events", "ratio", 0.7, 1.4),
    Target("first_30ms", "diff", -0.07, 0.07),
    Target("last_100ms", "diff", -0.07, 0.07),
    Target("busiest_10", "diff", -0.10, 0.10),
)
"""Issue 30's targets per tap scene against the pooled real sessions' medians."""


def summarise(stats: dict[str, npt.NDArray[np.float64]]) -> dict[str, dict[str, float]]:
    """Median, quartiles and count of each statistic (NaNs left out)."""
    out = {}
    for name, values in stats.items():
        v = values[np.isfinite(values)]
        if v.size:
            p25, p50, p75 = np.percentile(v, [25, 50, 75])
        else:
            p25 = p50 = p75 = float("nan")
        out[name] = {"median": float(p50), "p25": float(p25), "p75": float(p75), "n": int(v.size)}
    return out


def two_sample_auc(
    a: npt.NDArray[np.float64], b: npt.NDArray[np.float64], seed: int = 0, repeats: int = REPEATS
) -> float:
    """Cross-validated ROC AUC of a random forest telling the rows of ``a`` from those of ``b``.

    Stratified ``min(5, smaller set)``-fold cross-validation, averaged over ``repeats``
    shuffles, classes weighted; NaN when a set has under two rows.
    """
    folds = min(FOLDS, len(a), len(b))
    if folds < 2:
        return float("nan")
    x = np.nan_to_num(np.vstack([a, b]), nan=-1.0)
    y = np.r_[np.zeros(len(a), int), np.ones(len(b), int)]
    aucs = []
    for r in range(repeats):
        forest = RandomForestClassifier(
            n_estimators=TREES, class_weight="balanced", random_state=seed + r, n_jobs=1
        )
        cv = StratifiedKFold(folds, shuffle=True, random_state=seed + r)
        proba = cross_val_predict(forest, x, y, cv=cv, method="predict_proba")[:, 1]
        aucs.append(roc_auc_score(y, proba))
    return float(np.mean(aucs))
