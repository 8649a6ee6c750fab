"""Scoring predictions on labelled windows: the figures ``ext-sense score`` prints (no ROS).

Classes: accuracy, confusion, per-class recall and precision, and the expected calibration
error of the top-class probability; decisions are restricted to the session's label set, and
windows of classes the model does not know are listed apart. Positions: MAE and the coverage
of the model's 95% interval.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ext_sense_perception.online.label_set import restrict

ECE_BINS = 10
PI_Z = 1.959963984540054  # two-sided 95% normal quantile


def expected_calibration_error(confidence: np.ndarray, correct: np.ndarray) -> float:
    """ECE of top-class confidences: the bin-weighted gap between confidence and accuracy."""
    if len(confidence) == 0:
        return float("nan")
    edges = np.linspace(0.0, 1.0, ECE_BINS + 1)
    idx = np.clip(np.digitize(confidence, edges[1:-1]), 0, ECE_BINS - 1)
    ece = 0.0
    for b in range(ECE_BINS):
        m = idx == b
        if m.any():
            ece += m.mean() * abs(float(correct[m].mean()) - float(confidence[m].mean()))
    return float(ece)


def score_classes(
    y_true: np.ndarray,
    proba: np.ndarray,
    classes: tuple[str, ...],
    allowed: tuple[str, ...] = (),
    names: np.ndarray | None = None,
) -> dict[str, Any]:
    """The classification figures of ``ext-sense score``.

    ``proba`` columns follow ``classes``; decisions are restricted to ``allowed`` (empty: all);
    ``names`` name the windows of unknown classes (default: their index). The record holds
    ``metric``, ``value``, ``n_windows`` (scored), ``class_names``, ``confusion`` (rows true),
    ``per_class``, ``calibration`` and ``unknown``.
    """
    y_true = np.asarray([str(v) for v in y_true])
    names = np.asarray(names if names is not None else np.arange(len(y_true))).astype(str)
    known = np.isin(y_true, np.asarray(classes))
    p = restrict(np.asarray(proba)[known], classes, allowed)
    pred = np.asarray(classes)[p.argmax(axis=1)] if len(p) else np.empty(0, dtype="<U1")
    conf = p.max(axis=1) if len(p) else np.empty(0)
    truth = y_true[known]
    correct = pred == truth
    index = {c: i for i, c in enumerate(classes)}
    confusion = np.zeros((len(classes), len(classes)), dtype=np.int64)
    for t, q in zip(truth, pred, strict=True):
        confusion[index[t], index[q]] += 1
    per_class = {}
    for i, c in enumerate(classes):
        n_true, n_pred = int(confusion[i].sum()), int(confusion[:, i].sum())
        per_class[c] = {
            "n": n_true,
            "recall": confusion[i, i] / n_true if n_true else None,
            "precision": confusion[i, i] / n_pred if n_pred else None,
        }
    unknown = [
        {"window": str(n), "label": str(t)}
        for n, t in zip(names[~known], y_true[~known], strict=True)
    ]
    return {
        "metric": "accuracy",
        "value": float(correct.mean()) if len(correct) else float("nan"),
        "n_windows": int(known.sum()),
        "class_names": list(classes),
        "label_set": list(allowed),
        "confusion": confusion.tolist(),
        "per_class": {
            c: {k: (float(v) if v is not None and k != "n" else v) for k, v in d.items()}
            for c, d in per_class.items()
        },
        "calibration": {
            "expected_calibration_error": expected_calibration_error(conf, correct),
            "mean_confidence": float(conf.mean()) if len(conf) else float("nan"),
            "bins": ECE_BINS,
        },
        "unknown": unknown,
    }


def score_positions(
    y_true: np.ndarray, y_pred: np.ndarray, residual_std_m: float
) -> dict[str, Any]:
    """The regression figures of ``ext-sense score``: MAE and 95% interval coverage."""
    y_true = np.asarray(y_true, dtype=np.float64)
    y_pred = np.asarray(y_pred, dtype=np.float64)
    err = np.abs(y_pred - y_true)
    half = PI_Z * float(residual_std_m)
    return {
        "metric": "mae_m",
        "value": float(err.mean()) if len(err) else float("nan"),
        "n_windows": len(err),
        "class_names": [],
        "confusion": None,
        "per_class": {},
        "calibration": {
            "interval": "95%",
            "halfwidth_m": half,
            "coverage": float((err <= half).mean()) if len(err) and np.isfinite(half) else None,
            "nominal": 0.95,
        },
        "unknown": [],
    }
