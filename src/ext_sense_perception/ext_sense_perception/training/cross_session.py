# ruff: noqa: N806  (X for the window matrix, as in scikit-learn)
"""Cross-session validation: leave one session out, score it on the classes the others know.

The paper's protocol tests on the training days, which says little about the next day. Each session
in turn is held out, the recipe fits on the others, and the held-out session is scored on its known
classes with decisions restricted to its label set (the unrestricted figure beside it). No ROS.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from ext_sense_perception.data.sessions import Session, pooled
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.training.recipe import Recipe, fit_recipe
from ext_sense_perception.training.scoring import score_classes, score_positions


def fit_and_score(train: Any, test: Any, labels: tuple[str, ...], recipe: Recipe) -> dict:
    """Fit the recipe (no anytime models) on ``train`` and score ``test``.

    ``labels`` is the test session's label set (empty: no restriction). Returns ``{"restricted",
    "unrestricted"}`` :mod:`.scoring` records (the same MAE record for positions).
    """
    trained, _ = fit_recipe(train, dataclasses.replace(recipe, anytime_post_ns=()))
    X = test.X.reshape(len(test.X), -1)
    if train.is_regression:
        std = float(trained.card.metrics.get("residual_std_m", float("nan")))
        s = score_positions(test.y, trained.pipeline.predict(X), std)
        return {"restricted": s, "unrestricted": s}
    classes = tuple(str(c) for c in trained.pipeline.classes_)
    names = [f"{s}/{g}" for s, g in zip(test.session_of, test.groups, strict=True)]
    known = np.isin(test.y, np.asarray(classes))
    proba = np.zeros((len(X), len(classes)))
    if known.any():
        proba[known] = trained.pipeline.predict_proba(X[known])
    allowed = tuple(c for c in labels if c in classes)
    return {
        "restricted": score_classes(test.y, proba, classes, allowed, names),
        "unrestricted": score_classes(test.y, proba, classes, (), names),
    }


def without_single_windows(ws: Any) -> tuple[Any, list[str]]:
    """``ws`` without the classes it holds one window of (no model can learn them), and those."""
    if ws.is_regression:
        return ws, []
    names, counts = np.unique(ws.y, return_counts=True)
    few = names[counts < 2].tolist()
    if not few:
        return ws, []
    kept = ws.subset(~np.isin(ws.y, few))
    return kept._replace(class_names=tuple(c for c in ws.class_names if c not in few)), few


def cross_session(sessions: list[Session], recipe: Recipe | None = None) -> dict[str, Any]:
    """Leave-one-session-out scores of the recipe (default: everything the task's own), JSON-ready.

    A row per session (its scores, or why it was skipped), ``mean`` and ``mean_unrestricted`` over
    the scored ones. PerceptionError: fewer than two sessions, or sessions that cannot be pooled.
    """
    if len(sessions) < 2:
        raise PerceptionError(
            "The cross-session protocol needs at least two sessions (--data, repeated). Got "
            f"{len(sessions)}."
        )
    recipe = recipe or Recipe()
    all_ws = pooled(sessions)
    rows = []
    for i, held in enumerate(sessions):
        train, dropped = without_single_windows(
            pooled([s for j, s in enumerate(sessions) if j != i])
        )
        test = held.windows
        row: dict[str, Any] = {
            "session": held.info.name,
            "date": held.info.date,
            "classes": list(test.class_names),
            "train_classes": list(train.class_names),
            "dropped_classes": dropped,
        }
        if not train.is_regression:
            common = sorted(set(test.class_names) & set(train.class_names))
            row["classes_in_common"] = common
            if not common:
                row["skipped"] = "no class in common with the other sessions"
                rows.append(row)
                continue
            if len(train.class_names) < 2:
                row["skipped"] = "the other sessions hold fewer than 2 classes"
                rows.append(row)
                continue
        labels = held.info.labels or test.class_names
        scores = fit_and_score(train, test, tuple(labels), recipe)
        row.update(
            n_windows=scores["restricted"]["n_windows"],
            value=scores["restricted"]["value"],
            value_unrestricted=scores["unrestricted"]["value"],
            score=scores["restricted"],
            score_unrestricted=scores["unrestricted"],
        )
        rows.append(row)
    scored = [r for r in rows if "value" in r]
    return {
        "protocol": "cross-session",
        "task": all_ws.task,
        "sensor": all_ws.sensor,
        "anchor": all_ws.anchor,
        "metric": "mae_m" if all_ws.is_regression else "accuracy",
        "sessions": rows,
        "mean": float(np.mean([r["value"] for r in scored])) if scored else float("nan"),
        "mean_unrestricted": (
            float(np.mean([r["value_unrestricted"] for r in scored])) if scored else float("nan")
        ),
        "n_scored": len(scored),
    }
