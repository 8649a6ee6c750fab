# ruff: noqa: N803  (X for sample matrices, as in scikit-learn)
"""One split of the paper's protocol as a self-contained task (no ROS).

:func:`~.protocol.evaluate` cuts its K random splits into :class:`SplitTask` records and hands
them to a :class:`~.fit_executor.FitExecutor`, which runs :func:`run_split` in this process or on
the workers of a Dask cluster, and caches each finished split under :func:`split_key` (its
configuration and its data's hash), so a rerun computes only what changed or failed. A task
holds everything the fit needs but the data, which the executor sends to the workers once.
"""

from __future__ import annotations

import hashlib
import inspect
import tempfile
import time
import warnings
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from joblib import Memory
from sklearn.base import clone
from sklearn.calibration import CalibratedClassifierCV
from sklearn.exceptions import ConvergenceWarning
from sklearn.metrics import accuracy_score, confusion_matrix, mean_absolute_error
from sklearn.model_selection import GridSearchCV, KFold, StratifiedKFold
from threadpoolctl import threadpool_limits

CODE_FILES = ("split_fit.py", "models.py", "gru.py", "taxel_stack.py")
"""Training modules whose source goes into every fit's cache key (with the features' module)."""


class SplitTask(NamedTuple):
    """One split's grid search, refit and test scoring, without the data."""

    pipe: Any  # unfitted estimator searched (head only when features were precomputed)
    grid: dict[str, list[Any]]
    cv: KFold | StratifiedKFold
    regression: bool
    labels: tuple[str, ...]
    train: np.ndarray
    test: np.ndarray
    seed: int
    n_jobs: int
    cache_features: bool  # fit the feature step once per fold (autoencoder, feature grids)


class SplitResult(NamedTuple):
    """What one split gives back to the protocol."""

    score: float
    train_s: float
    best_params: dict[str, Any]
    y_pred: np.ndarray
    y_std: np.ndarray
    proba: np.ndarray | None
    confusion: np.ndarray | None


def run_split(task: SplitTask, X: np.ndarray, y: np.ndarray) -> SplitResult:
    """Grid search on the split's training part, refit, score its test part.

    BLAS is pinned to one thread: small matrices on a shared machine (and one worker per core
    on a cluster) run up to 20x slower with threaded BLAS.
    """
    with (
        threadpool_limits(limits=1),
        tempfile.TemporaryDirectory(prefix="ext_sense_cv_") as cache,
    ):
        pipe = clone(task.pipe)
        if task.cache_features:
            pipe.set_params(memory=Memory(cache, verbose=0))
        search = GridSearchCV(
            pipe,
            task.grid,
            cv=task.cv,
            scoring="neg_mean_absolute_error" if task.regression else "accuracy",
            n_jobs=task.n_jobs,
            refit=True,
        )
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            search.fit(X[task.train], y[task.train])
        train_s = time.perf_counter() - t0
        pred = search.predict(X[task.test])
        truth = y[task.test]
        if task.regression:
            # a spread from the inner CV's best score, for interval calibration studies
            std = np.full(len(task.test), -search.best_score_ * np.sqrt(np.pi / 2))
            return SplitResult(
                float(mean_absolute_error(truth, pred)),
                train_s,
                search.best_params_,
                pred,
                std,
                None,
                None,
            )
        proba = _calibrated_proba(search, X[task.train], y[task.train], X[task.test], task.seed)
        conf = confusion_matrix(truth, pred, labels=list(task.labels))
        return SplitResult(
            float(accuracy_score(truth, pred)),
            train_s,
            search.best_params_,
            pred,
            proba.max(axis=1),
            proba,
            conf,
        )


def _calibrated_proba(search, x_train, y_train, x_test, seed: int) -> np.ndarray:
    """Test-set class probabilities: the model's own, or Platt-calibrated inside the training set.

    Columns follow the sorted class names.
    """
    best = search.best_estimator_
    if hasattr(best, "predict_proba"):
        try:
            return best.predict_proba(x_test)
        except AttributeError:
            pass
    smallest = int(np.min(np.unique(y_train, return_counts=True)[1]))
    cv = StratifiedKFold(min(3, max(smallest, 2)), shuffle=True, random_state=seed)
    cal = CalibratedClassifierCV(clone(best), method="sigmoid", cv=cv).fit(x_train, y_train)
    return cal.predict_proba(x_test)


def data_digest(X: np.ndarray, y: np.ndarray) -> str:
    """Hash of a fit's data (the matrix searched and its labels)."""
    h = hashlib.blake2b(digest_size=16)
    h.update(repr((X.shape, str(X.dtype))).encode())
    h.update(np.ascontiguousarray(X).view(np.uint8).ravel())
    h.update(np.asarray(y).astype(str).tobytes())
    return h.hexdigest()


def code_digest(*modules: Any) -> str:
    """Hash of the source of the training modules and the given feature modules.

    A change to the code that fits a model changes the key of every fit it made, so a rerun
    recomputes those fits and keeps the others.
    """
    here = Path(__file__).parent
    h = hashlib.blake2b(digest_size=8)
    for name in CODE_FILES:
        h.update((here / name).read_bytes())
    for m in modules:
        h.update(inspect.getsource(m).encode())
    return h.hexdigest()


def split_key(task: SplitTask, data: str, code: str) -> str:
    """The cache key of one split fit: its configuration, its data's hash and the code's."""
    params = {  # estimators by class: their own parameters are in the deep dict too
        k: type(v).__qualname__ if hasattr(v, "get_params") else v
        for k, v in task.pipe.get_params(deep=True).items()
    }
    config = repr(
        (
            sorted(params.items()),
            sorted(task.grid.items()),
            repr(task.cv),
            task.regression,
            task.labels,
            task.seed,
            task.cache_features,
        )
    )
    h = hashlib.blake2b(digest_size=16)
    h.update(config.encode())
    h.update(np.ascontiguousarray(task.train).view(np.uint8).ravel())
    h.update(np.ascontiguousarray(task.test).view(np.uint8).ravel())
    h.update(data.encode())
    h.update(code.encode())
    return h.hexdigest()
