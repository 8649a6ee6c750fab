# ruff: noqa: N806  (X / F for sample matrices, as in scikit-learn)
"""Fitting a deployable model on a window set: grid search, refit, calibration, card (no ROS).

:func:`fit_model` is the mechanics; what to fit is chosen by :mod:`.recipe`.
"""

from __future__ import annotations

import tempfile
import time
import warnings
from typing import Any, NamedTuple

import numpy as np
from joblib import Memory, Parallel, delayed
from sklearn.base import clone
from sklearn.calibration import CalibratedClassifierCV
from sklearn.exceptions import ConvergenceWarning
from sklearn.metrics import get_scorer
from sklearn.model_selection import GridSearchCV, StratifiedKFold
from sklearn.pipeline import Pipeline
from threadpoolctl import threadpool_limits

from ext_sense_perception.data.window_set import WindowSet, held_object_of
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.features.maps import FeatureKind
from ext_sense_perception.online.model_card import ModelCard, jsonable
from ext_sense_perception.training.models import head_of, make_pipeline
from ext_sense_perception.training.protocol import features_for, inner_cv, whole_trial_folds
from ext_sense_perception.training.scoring import PI_Z


def nominal_rate_hz(sensor: str) -> float:
    """The sensor's own sampling rate when none was reduced: NUSkin 4 kHz, BioTac PAC 2200 Hz."""
    return 4000.0 if sensor == "nuskin" else 2200.0


class TrainedModel(NamedTuple):
    """A fitted pipeline and its card, before saving."""

    pipeline: Pipeline
    card: ModelCard


def _final_classifier(est: Any, ws: WindowSet, seed: int) -> Any:
    """Calibrated probabilities (Platt, inner CV) for estimators without ``predict_proba``."""
    if hasattr(est, "predict_proba"):
        return est
    smallest = int(np.min(np.unique(ws.y, return_counts=True)[1]))
    cv = StratifiedKFold(min(3, max(smallest, 2)), shuffle=True, random_state=seed)
    return CalibratedClassifierCV(est, method="sigmoid", cv=whole_trial_folds(cv, ws, seed))


def _fold_score(est: Any, train_in: Any, y: Any, test_in: Any, test_y: Any, scoring: str) -> float:
    """One fold: ``est`` fitted on the training rows, scored on the held-out rows given."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        return float(get_scorer(scoring)(clone(est).fit(train_in, y), test_in, test_y))


def as_cut_score(
    est: Any,
    trained_on: np.ndarray,
    as_cut: np.ndarray,
    y: np.ndarray,
    splits: list[tuple[np.ndarray, np.ndarray]],
    scoring: str,
    n_jobs: int = 1,
) -> float:
    """Mean out-of-fold score of ``est`` trained on ``trained_on`` rows, scored on ``as_cut`` rows.

    The two hold the same windows in the same order, ``trained_on`` augmented: augmentation
    trains, the windows as cut are what is scored, as for a fresh window.
    """
    scores = Parallel(n_jobs=n_jobs)(
        delayed(_fold_score)(est, trained_on[tr], y[tr], as_cut[te], y[te], scoring)
        for tr, te in splits
    )
    return float(np.mean(scores))


def fit_model(
    ws: WindowSet,
    features: str,
    model: str,
    feature_params: dict[str, Any] | None = None,
    feature_grid: dict[str, list[Any]] | None = None,
    seed: int = 0,
    n_jobs: int = 1,
    rate_hz: float | None = None,
    model_params: dict[str, Any] | None = None,
    cv_folds: int = 4,
    as_cut: WindowSet | None = None,
) -> TrainedModel:
    """Fit a deployable model on all windows (grid search with K-fold CV, then refit).

    ``as_cut``: the same windows before augmentation (``ws`` re-stamped in place). The search
    still runs on ``ws``, but the card's CV score is the best parameters' out-of-fold score on
    the windows as cut (the search's own is kept as ``cv_*_augmented``): a fold's re-stamped
    windows are harder than fresh ones and made the card's CV too pessimistic.

    K is 4 for classes (the paper's); for tap positions ``cv_folds``, fewer (at least 4) when the
    set has under 20 trials a fold. ``feature_params`` are fixed, ``feature_grid``
    (``features__<param>``) searched; ``rate_hz`` is recorded in the card. BLAS is pinned to one
    thread: small matrices on a shared 2-core machine run up to 20x slower threaded.
    """
    with threadpool_limits(limits=1):
        t0 = time.perf_counter()
        n = len(ws.y)
        if n < 8:
            raise PerceptionError(
                f"The 'ws' parameter must hold at least 8 windows. Got {n} instead."
            )
        if not ws.is_regression:
            names, counts = np.unique(ws.y, return_counts=True)
            if len(names) < 2:
                raise PerceptionError(
                    f"Classification needs windows of at least 2 classes to train a model. Got "
                    f"only {names.tolist()} in {ws.source!r}."
                )
            few = names[counts < 2].tolist()
            if few:
                raise PerceptionError(
                    f"Classes {few} have a single window; a model needs at least 2 of each "
                    "(the probability calibration's folds). Add trials or leave them out."
                )
        X = ws.X.reshape(n, -1)
        if as_cut is not None and as_cut.X.shape != ws.X.shape:
            raise PerceptionError(
                f"The 'as_cut' windows must be those of 'ws' before augmentation, in the same "
                f"order. Got shape {as_cut.X.shape} for {ws.X.shape}."
            )
        feats = features_for(ws, features, **(feature_params or {}))
        pipe, grid = make_pipeline(feats, model, ws.is_regression, seed)
        pipe.set_params(**{f"model__{k}": v for k, v in (model_params or {}).items()})
        grid.update(feature_grid or {})
        precompute = FeatureKind.parse(features) is not FeatureKind.AUTOENCODER and not feature_grid
        trials = int(np.unique(ws.groups).size)
        k = min(int(cv_folds), max(4, trials // 20)) if ws.is_regression else 4
        cv = whole_trial_folds(inner_cv(ws, ws.y, seed, k), ws, seed)
        scoring = "neg_mean_absolute_error" if ws.is_regression else "accuracy"
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            if precompute:
                fitted_features = clone(feats).fit(X[:1])
                F = fitted_features.transform(X)
                search = GridSearchCV(
                    head_of(pipe), grid, cv=cv, scoring=scoring, n_jobs=n_jobs
                ).fit(F, ws.y)
                best = clone(pipe).set_params(**search.best_params_)
                best.steps[0] = ("features", fitted_features)
                head = clone(head_of(best))
                head_input = F
                scored = (
                    (head, F, fitted_features.transform(as_cut.X.reshape(n, -1)))
                    if as_cut is not None
                    else None
                )
            else:
                with tempfile.TemporaryDirectory(prefix="ext_sense_cv_") as cache:
                    cached = clone(pipe).set_params(memory=Memory(cache, verbose=0))
                    search = GridSearchCV(cached, grid, cv=cv, scoring=scoring, n_jobs=n_jobs).fit(
                        X, ws.y
                    )
                best = clone(pipe).set_params(**search.best_params_)
                best.steps[0] = ("features", clone(best.steps[0][1]).fit(X))
                head = clone(head_of(best))
                head_input = best.steps[0][1].transform(X)
                scored = (clone(best), X, as_cut.X.reshape(n, -1)) if as_cut is not None else None
            splits = cv if isinstance(cv, list) else list(cv.split(X, ws.y))
            metrics: dict[str, Any] = {"cv_folds": len(splits)}
            best_score = float(search.best_score_)
            if scored is not None:
                metrics["cv_mae_augmented_m" if ws.is_regression else "cv_accuracy_augmented"] = (
                    -best_score if ws.is_regression else best_score
                )
                best_score = as_cut_score(*scored, ws.y, splits, scoring, n_jobs)
            if ws.is_regression:
                # residual spread from the out-of-fold MAE (sigma = MAE * sqrt(pi/2) for normal
                # residuals): measured on held-out folds only
                mae = -best_score
                metrics["cv_mae_m"] = mae
                metrics["residual_std_m"] = mae * float(np.sqrt(np.pi / 2))
                metrics["pi95_halfwidth_m"] = PI_Z * metrics["residual_std_m"]
                fitted_head = head.fit(head_input, ws.y)
            else:
                metrics["cv_accuracy"] = best_score
                scaler, est = head.steps[0][1], head.steps[1][1]
                final = Pipeline([("scale", scaler), ("model", _final_classifier(est, ws, seed))])
                fitted_head = final.fit(head_input, ws.y)
        pipeline = Pipeline([best.steps[0], *fitted_head.steps])
        g = ws.geometry
        fp = best.steps[0][1].get_params()
        card = ModelCard(
            task=ws.task,
            sensor=ws.sensor,
            profile=ws.task_profile,
            window=g,
            features=FeatureKind.parse(features).name.lower(),
            feature_params={
                k: v
                for k, v in jsonable(fp).items()
                if isinstance(v, (int, float, str, type(None)))
            },
            model=model,
            model_params=jsonable(dict(model_params or {})),
            best_params=jsonable(dict(search.best_params_)),
            rate_hz=float(rate_hz) if rate_hz is not None else nominal_rate_hz(ws.sensor),
            class_names=tuple(ws.class_names),
            metrics=metrics,
            n_train=n,
            data=ws.source,
            data_hash=ws.data_hash,
            excluded=tuple(ws.excluded),
            train_s=time.perf_counter() - t0,
            anchor=ws.anchor,
            sessions=tuple(sorted({str(s) for s in ws.session_of.tolist()} - {""})),
            held_object=held_object_of(ws),
        )
        return TrainedModel(pipeline, card)


def fit_anytime(
    ws: WindowSet, features: str, model: str, posts_ns: tuple[int, ...], **kwargs: Any
) -> list[TrainedModel]:
    """Models for shortened post-contact windows (anytime estimates), shortest first.

    Each is fitted on the windows cropped at its post time (those not shorter than the windows'
    skipped) and carries its own calibration; ``kwargs`` go to :func:`fit_model`.
    """
    full = ws.geometry.post_ns
    return [
        fit_model(ws.crop(int(p)), features, model, **kwargs)
        for p in sorted(posts_ns)
        if 0 < p < full
    ]
