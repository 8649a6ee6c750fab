# ruff: noqa: N803  (X for sample matrices, as in scikit-learn)
"""One split of the paper's protocol as a self-contained task (no ROS).

:func:`~.protocol.evaluate` cuts its splits into :class:`SplitTask` records (everything but the
data) for a :class:`~.fit_jobs.FitRunner`, which runs :func:`run_split` here or on Dask and
caches each under :func:`split_key` (configuration, data hash and :func:`code_digest`), so a
rerun computes only what changed or failed.
"""

from __future__ import annotations

import ast
import functools
import hashlib
import importlib.metadata
import importlib.util
import sys
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

PROJECT_PACKAGES = ("ext_sense_perception", "ext_sense_runtime")
"""Packages whose source goes into a fit's cache key (others by their version)."""


class SplitTask(NamedTuple):
    """One split's grid search, refit and test scoring, without the data."""

    pipe: Any  # unfitted estimator searched (head only when features were precomputed)
    grid: dict[str, list[Any]]
    cv: KFold | StratifiedKFold | list[tuple[list[int], list[int]]]  # lists: whole trials
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
    """Grid search on the split's training part, refit, score its test part (BLAS on one thread)."""
    with threadpool_limits(limits=1), tempfile.TemporaryDirectory(prefix="ext_sense_cv_") as cache:
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
    """Test-set class probabilities (sorted classes): the model's own, or Platt-calibrated."""
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


def code_modules(
    estimator: Any, packages: tuple[str, ...] = PROJECT_PACKAGES
) -> tuple[list[str], list[str]]:
    """The code a fit of ``estimator`` runs beyond this module: ``(modules, versions)``.

    The modules of ``packages`` behind the pipeline's classes and what they import, transitively
    (sorted); and ``name version`` of the other libraries involved.
    """
    objs = [estimator, *estimator.get_params(deep=True).values()]
    names = {type(o).__module__ for o in objs if hasattr(o, "get_params")}
    todo = sorted(n for n in names if n.split(".")[0] in packages)
    tops = {"numpy", *(n.split(".")[0] for n in names)}
    seen: set[str] = set()
    while todo:
        name = todo.pop()
        if name not in seen:
            seen.add(name)
            imported = _imports(name)
            tops.update(n.split(".")[0] for n in imported)
            todo += [n for n in imported if n.split(".")[0] in packages and _is_module(n)]
    libraries = sorted(tops - set(packages) - set(sys.stdlib_module_names) - {"__future__"})
    return sorted(seen), [_version(t) for t in libraries]


def _source_path(module: str) -> Path | None:
    spec = importlib.util.find_spec(module)
    origin = spec.origin if spec is not None else None
    return Path(origin) if origin and origin.endswith(".py") else None


def code_text(path: Path) -> bytes:
    """A module's code as a fit runs it: no docstrings, comments or layout.

    Editing those keeps the cached fits.
    """
    tree = ast.parse(path.read_bytes())
    for node in ast.walk(tree):
        for field in ("body", "orelse", "finalbody"):
            body = getattr(node, field, None)
            if isinstance(body, list) and body:
                kept = [s for s in body if not _is_docstring(s)]
                setattr(node, field, kept or [ast.Pass()])
    return ast.dump(tree).encode()


def _is_docstring(statement: ast.AST) -> bool:
    return (
        isinstance(statement, ast.Expr)
        and isinstance(statement.value, ast.Constant)
        and isinstance(statement.value.value, str)
    )


def _imports(module: str) -> list[str]:
    """Names a module imports, anywhere in it (``from a.b import c``: ``a.b`` and ``a.b.c``)."""
    path = _source_path(module)
    if path is None:
        return []
    names = []
    for node in ast.walk(ast.parse(path.read_bytes())):
        if isinstance(node, ast.Import):
            names += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            names += [node.module, *(f"{node.module}.{a.name}" for a in node.names)]
    return names


def _is_module(name: str) -> bool:
    try:
        return importlib.util.find_spec(name) is not None
    except (ImportError, ValueError):  # ``a.b.name`` where a.b is a module, not a package
        return False


@functools.cache
def _version(top: str) -> str:
    """``top`` and its distributions' versions, from their metadata: nothing is imported."""
    dists = sorted(set(importlib.metadata.packages_distributions().get(top, [])))
    return " ".join([top, *(f"{d}=={importlib.metadata.version(d)}" for d in dists)])


def code_digest(estimator: Any, packages: tuple[str, ...] = PROJECT_PACKAGES) -> str:
    """Hash of the code a fit of ``estimator`` runs (see :func:`code_modules`).

    So a change to one model's module recomputes only that model's fits, and edits elsewhere keep
    them. Features computed before the search are in the data's hash instead.
    """
    modules, versions = code_modules(estimator, packages)
    h = hashlib.blake2b(digest_size=8)
    h.update(code_text(Path(__file__)))
    for name in modules:
        path = _source_path(name)
        h.update(name.encode())
        h.update(code_text(path) if path is not None else b"")
    h.update(repr(versions).encode())
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
