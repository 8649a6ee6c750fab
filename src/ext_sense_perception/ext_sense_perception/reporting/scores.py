"""How the report states a protocol result: score text, calibration figures (no ROS)."""

from __future__ import annotations

import itertools

import numpy as np

from ext_sense_perception.training.protocol import EvalResult


def fmt(res: EvalResult) -> str:
    """Mean +- std over splits: cm for positions, accuracy otherwise."""
    return fmt_values(res.metric, res.mean, res.std)


def fmt_values(metric: str, mean: float, std: float) -> str:
    """:func:`fmt` from a report.json row's ``metric``, ``mean`` and ``std``."""
    if metric == "mae_m":
        return f"{mean * 100:.2f} +- {std * 100:.2f} cm"
    return f"{mean:.3f} +- {std:.3f}"


def score(res: EvalResult) -> float:
    """The mean score in the unit plots use (cm for positions)."""
    return res.mean * 100 if res.metric == "mae_m" else res.mean


def spread(res: EvalResult) -> float:
    """The standard deviation of the score over splits, in the unit plots use (error bars)."""
    return res.std * 100 if res.metric == "mae_m" else res.std


def pareto_front(xs: list[float], ys: list[float], lower: bool) -> list[int]:
    """Indices of the points no other point beats on both axes, by ascending x.

    x is a cost (lower is better); y the score (``lower``: an error, else an accuracy).
    """
    sign = 1.0 if lower else -1.0
    pts = [(float(x), sign * float(y)) for x, y in zip(xs, ys, strict=True)]
    front = [
        i
        for i, (x, y) in enumerate(pts)
        if not any(
            (xo <= x and yo <= y) and (xo < x or yo < y) for j, (xo, yo) in enumerate(pts) if j != i
        )
    ]
    return sorted(front, key=lambda i: pts[i][0])


def coverage(res: EvalResult) -> float:
    """Fraction of test positions inside the 95% prediction interval (+-1.96 sigma)."""
    return float(np.mean(np.abs(res.y_true - res.y_pred) <= 1.959964 * res.y_std))


def ece(res: EvalResult, bins: int = 5) -> tuple[float, float]:
    """Expected calibration error of the top-class probability, and the Brier score."""
    if res.proba is None:
        return float("nan"), float("nan")
    conf = res.proba.max(axis=1)
    pred = np.asarray(res.class_names)[res.proba.argmax(axis=1)]
    correct = pred == res.y_true
    edges = np.linspace(0, 1, bins + 1)
    ece = 0.0
    for lo, hi in itertools.pairwise(edges):
        m = (conf > lo) & (conf <= hi)
        if m.any():
            ece += m.mean() * abs(correct[m].mean() - conf[m].mean())
    onehot = (np.asarray(res.class_names)[None, :] == res.y_true[:, None]).astype(float)
    brier = float(np.mean(np.sum((res.proba - onehot) ** 2, axis=1)))
    return float(ece), brier
