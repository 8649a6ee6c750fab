# ruff: noqa: N806  (X / F for sample matrices, as in scikit-learn)
"""The paper's evaluation protocol (no ROS).

K times: a random 90/10 split (stratified for classes, whole trials), a 4-fold grid search on
the 90%, refit, score the 10%. Each split is one task (:mod:`.split_fit`) run here or on Dask
(:mod:`.fit_jobs`) with the same result. Features without learned state (all but the
autoencoder) are computed once for all windows, which equals computing them per fold.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any, NamedTuple

import numpy as np
from sklearn.base import clone
from sklearn.model_selection import (
    GroupKFold,
    KFold,
    ShuffleSplit,
    StratifiedGroupKFold,
    StratifiedKFold,
    StratifiedShuffleSplit,
)
from threadpoolctl import threadpool_limits

from ext_sense_perception.data.window_set import WindowSet
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.features.maps import FeatureKind
from ext_sense_perception.features.transformer import FAMILIES, WindowFeatures, make_features
from ext_sense_perception.training.fit_jobs import FitJob, FitRunner
from ext_sense_perception.training.models import head_of, make_pipeline
from ext_sense_perception.training.split_fit import (
    SplitResult,
    SplitTask,
    code_digest,
    data_digest,
    run_split,
    split_key,
)


class EvalResult(NamedTuple):
    """Scores of one feature set and model under the protocol."""

    task: str
    sensor: str
    features: str
    model: str
    metric: str  # "mae_m" or "accuracy"
    scores: np.ndarray  # (k,)
    train_s: np.ndarray  # (k,) grid search + refit seconds per split
    best_params: list[dict[str, Any]]
    confusion: np.ndarray | None  # summed over splits, rows true, columns predicted
    class_names: tuple[str, ...]
    y_true: np.ndarray  # test labels of every split, concatenated
    y_pred: np.ndarray
    y_std: np.ndarray  # predicted std (regression) or max probability (classes), per test window
    post_ns: int
    proba: np.ndarray | None = None  # calibrated class probabilities per test window (classes)

    @property
    def mean(self) -> float:
        """Mean score over splits."""
        return float(np.mean(self.scores))

    @property
    def std(self) -> float:
        """Standard deviation of the score over splits."""
        return float(np.std(self.scores))

    @property
    def k(self) -> int:
        """Splits."""
        return len(self.scores)


def features_for(ws: WindowSet, kind: str, **params: Any) -> WindowFeatures:
    """The unfitted feature family ``kind`` for a window set's geometry.

    NUSkin families get the task profile's feature bin unless ``params`` name one. PerceptionError:
    an unknown family or a parameter it does not have.
    """
    g = ws.geometry
    family = FAMILIES[FeatureKind.parse(kind)]
    defaults: dict[str, Any] = {}
    if g.sensor == "nuskin" and "bin_ns" in family._get_param_names():
        defaults["bin_ns"] = max(ws.task_profile.feature_bin_ns // g.period_ns, 1) * g.period_ns
    defaults.update(params)
    return make_features(
        kind,
        n_channels=g.n_channels,
        n_samples=g.n_samples,
        period_ns=g.period_ns,
        pre_ns=g.pre_ns,
        sensor=g.sensor,
        **defaults,
    )


def outer_splits(
    ws: WindowSet, k: int, test_size: float, seed: int
) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """The protocol's K random ``(train, test)`` splits (stratified for classes), whole trials.

    Trials are split, not windows (a trial's class is its first window's), so near-copies of a
    trial (``groups``) never score a model fitted on them.
    """
    names, first, trial_of = np.unique(ws.groups, return_index=True, return_inverse=True)
    splitter = (
        ShuffleSplit(n_splits=k, test_size=test_size, random_state=seed)
        if ws.is_regression
        else StratifiedShuffleSplit(n_splits=k, test_size=test_size, random_state=seed)
    )
    if names.size == len(ws.y):  # a trial per window: the windows themselves, as always
        yield from splitter.split(ws.X, ws.y)
        return
    for train, test in splitter.split(np.zeros((names.size, 1)), ws.y[first]):
        yield np.flatnonzero(np.isin(trial_of, train)), np.flatnonzero(np.isin(trial_of, test))


def whole_trial_folds(cv: Any, ws: WindowSet, seed: int) -> Any:
    """``cv`` when every window is a trial of its own; else as many folds over whole trials.

    Copies of a trial across folds would make the grid search and the calibration too confident.
    Folds are returned as lists, so their ``repr`` in a split's cache key is whole.
    """
    groups = np.asarray(ws.groups)
    if np.unique(groups).size == groups.size:
        return cv
    n = cv.get_n_splits()
    split = (
        GroupKFold(n, shuffle=True, random_state=seed)
        if ws.is_regression
        else StratifiedGroupKFold(n, shuffle=True, random_state=seed)
    )
    return [
        (train.tolist(), test.tolist())
        for train, test in split.split(np.zeros((len(groups), 1)), ws.y, groups)
    ]


def inner_cv(ws: WindowSet, y: np.ndarray, seed: int, folds: int = 4) -> KFold | StratifiedKFold:
    """The grid-search split into ``folds`` folds (the paper's 4; stratified for classes)."""
    if ws.is_regression:
        return KFold(folds, shuffle=True, random_state=seed)
    smallest = int(np.min(np.unique(y, return_counts=True)[1]))
    return StratifiedKFold(min(folds, max(smallest, 2)), shuffle=True, random_state=seed)


def default_k(ws: WindowSet, model: str) -> int:
    """The paper's K: 5 for tap localisation and every RNN, 20 otherwise."""
    return 5 if (ws.is_regression or model == "gru") else 20


class EvalPlan(NamedTuple):
    """One point of the protocol before its fits: its K split tasks, their keys and its data."""

    task: str
    sensor: str
    features: str
    model: str
    regression: bool
    labels: tuple[str, ...]
    post_ns: int
    X: np.ndarray  # (n_windows, n_features) searched: features, or windows flattened
    y: np.ndarray  # (n_windows,)
    tasks: list[SplitTask]
    keys: list[str]

    def job(self) -> FitJob:
        """The point's fits for a :class:`~.fit_jobs.FitRunner`."""
        return FitJob(run_split, self.tasks, self.keys, {"X": self.X, "y": self.y})


def plan_evaluation(
    ws: WindowSet,
    features: WindowFeatures,
    model: str,
    k: int | None = None,
    test_size: float = 0.1,
    seed: int = 0,
    n_jobs: int = 1,
    feature_grid: dict[str, list[Any]] | None = None,
    model_params: dict[str, Any] | None = None,
) -> EvalPlan:
    """The point's K split tasks (arguments as :func:`evaluate`'s); nothing is fitted yet.

    PerceptionError: too few windows or classes.
    """
    n = len(ws.y)
    if n < 8:
        raise PerceptionError(f"The 'ws' parameter must hold at least 8 windows. Got {n} instead.")
    if not ws.is_regression and len(ws.class_names) < 2:
        raise PerceptionError(
            f"Classification needs at least 2 classes. Got {ws.class_names} instead."
        )
    k = default_k(ws, model) if k is None else int(k)
    X = ws.X.reshape(n, -1)
    pipe, grid = make_pipeline(features, model, ws.is_regression, seed)
    pipe.set_params(**{f"model__{k}": v for k, v in (model_params or {}).items()})
    grid.update(feature_grid or {})
    precompute = (
        FeatureKind.parse(features.kind) is not FeatureKind.AUTOENCODER and not feature_grid
    )
    if precompute:
        with threadpool_limits(limits=1):
            search_X = clone(features).fit(X[:1]).transform(X)
        search_pipe = head_of(pipe)
    else:
        search_pipe, search_X = pipe, X
    labels = tuple(ws.class_names)
    tasks = [
        SplitTask(
            search_pipe,
            grid,
            whole_trial_folds(inner_cv(ws, ws.y[train], seed), ws.subset(train), seed),
            ws.is_regression,
            labels,
            train,
            test,
            seed,
            n_jobs,
            not precompute,
        )
        for train, test in outer_splits(ws, k, test_size, seed)
    ]
    data = data_digest(search_X, ws.y)
    code = code_digest(search_pipe)
    g = ws.geometry
    return EvalPlan(
        task=ws.task,
        sensor=ws.sensor,
        features=features.kind,
        model=model,
        regression=ws.is_regression,
        labels=labels,
        post_ns=int(g.n_samples * g.period_ns - g.pre_ns),
        X=search_X,
        y=ws.y,
        tasks=tasks,
        keys=[split_key(t, data, code) for t in tasks],
    )


def assemble(plan: EvalPlan, splits: list[SplitResult]) -> EvalResult:
    """The point's result from its split fits (in split order)."""
    reg = plan.regression
    return EvalResult(
        task=plan.task,
        sensor=plan.sensor,
        features=plan.features,
        model=plan.model,
        metric="mae_m" if reg else "accuracy",
        scores=np.asarray([r.score for r in splits]),
        train_s=np.asarray([r.train_s for r in splits]),
        best_params=[r.best_params for r in splits],
        confusion=None if reg else np.sum([r.confusion for r in splits], axis=0),
        class_names=plan.labels,
        y_true=np.concatenate([plan.y[t.test] for t in plan.tasks]),
        y_pred=np.concatenate([r.y_pred for r in splits]),
        y_std=np.concatenate([r.y_std for r in splits]),
        post_ns=plan.post_ns,
        proba=None if reg else np.concatenate([r.proba for r in splits]),
    )


def evaluate(
    ws: WindowSet,
    features: WindowFeatures,
    model: str,
    k: int | None = None,
    test_size: float = 0.1,
    seed: int = 0,
    progress: bool = True,
    n_jobs: int = 1,
    feature_grid: dict[str, list[Any]] | None = None,
    model_params: dict[str, Any] | None = None,
    executor: FitRunner | None = None,
) -> EvalResult:
    """Run the protocol: ``k`` splits (default :func:`default_k`) of ``test_size`` held out.

    ``feature_grid`` parameters (``features__<param>``) are searched too, recomputing the features
    in every fold; ``model_params`` are fixed (e.g. ``{"max_epochs": 20}`` for the GRU).
    ``executor`` runs and caches the split fits (default: here, uncached); the result does not
    depend on it. PerceptionError: too few windows or classes, or a fit failed.
    """
    plan = plan_evaluation(
        ws, features, model, k, test_size, seed, n_jobs, feature_grid, model_params
    )
    executor = executor or FitRunner(progress=progress)
    return assemble(plan, executor.map(run_split, plan.tasks, plan.keys, X=plan.X, y=plan.y))
