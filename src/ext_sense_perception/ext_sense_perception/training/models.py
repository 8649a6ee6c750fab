"""The paper's models and their hyper-parameter grids (no ROS).

A model is a ``Pipeline``: ``features`` -> ``scale`` -> ``model``. The C grid is the public
code's on cm labels; labels here are metres, so C and epsilon are divided by 100. The GRU
scales its own inputs (its scaler is the identity).
"""

from __future__ import annotations

from typing import Any

from sklearn.base import BaseEstimator
from sklearn.ensemble import RandomForestClassifier
from sklearn.neural_network import MLPClassifier, MLPRegressor
from sklearn.pipeline import Pipeline
from sklearn.preprocessing import StandardScaler
from sklearn.svm import SVC, SVR

from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.features.maps import FeatureKind, select_channels
from ext_sense_perception.features.transformer import WindowFeatures
from ext_sense_perception.training.gru import GRUEstimator, require_torch
from ext_sense_perception.training.taxel_stack import TaxelStackSVR

MODEL_NAMES = ("svm_linear", "svm_rbf", "svm", "mlp", "gru", "random_forest", "taxel_svr")
C_GRID = (1.0, 3.0, 10.0, 30.0, 100.0)
REGRESSION_EPSILON_M = 0.001  # 0.1 cm, scikit-learn's default epsilon on the paper's cm labels
# the taxel stack's grid has one point (C 100 on cm): its 4-fold search on 1000 taps takes about
# a minute on the shared machine already (80 channels x (3 inner + 1) SVR fits per fit)
TAXEL_SVR_C = 100.0
PER_CHANNEL_FEATURES = ("fft", "baseline", "est")  # features laid out in per-channel blocks


def make_estimator(
    name: str, regression: bool, seed: int = 0
) -> tuple[BaseEstimator, dict[str, list[Any]]]:
    """The final estimator of a pipeline and its grid (keys without the ``model__`` prefix).

    PerceptionError: an unknown name, ``gru`` without torch, ``random_forest`` for regression or
    ``taxel_svr`` for classification.
    """
    c_scale = 0.01 if regression else 1.0
    c_grid = [c * c_scale for c in C_GRID]
    if name in ("svm_linear", "svm_rbf", "svm"):
        kernels = {"svm_linear": ["linear"], "svm_rbf": ["rbf"], "svm": ["linear", "rbf"]}[name]
        est = (
            SVR(kernel=kernels[0], epsilon=REGRESSION_EPSILON_M, cache_size=1000)
            if regression
            else SVC(kernel=kernels[0], random_state=seed, cache_size=1000)
        )
        return est, {"C": c_grid, "kernel": kernels}
    if name == "mlp":
        kw = {
            "hidden_layer_sizes": (16, 8),
            "activation": "relu",
            "solver": "lbfgs",
            "max_iter": 500,
            "random_state": seed,
        }
        est = MLPRegressor(**kw) if regression else MLPClassifier(**kw)
        return est, {"alpha": [1e-4, 1e-2, 1.0]}
    if name == "random_forest":
        if regression:
            raise PerceptionError(
                "The 'model' parameter 'random_forest' is for classification only."
            )
        est = RandomForestClassifier(n_estimators=200, random_state=seed)
        return est, {"max_features": ["sqrt"]}
    if name == "taxel_svr":
        if not regression:
            raise PerceptionError(
                "The 'model' parameter 'taxel_svr' is for tap localisation (regression) only. "
                "Got a classification task instead."
            )
        est = TaxelStackSVR(
            C=TAXEL_SVR_C * c_scale, epsilon=REGRESSION_EPSILON_M, random_state=seed
        )
        return est, {"C": [TAXEL_SVR_C * c_scale]}
    if name == "gru":
        require_torch()  # fail now with a clear message, not inside every grid-search fit
        return GRUEstimator(regression=regression, random_state=seed), {"hidden": [16]}
    raise PerceptionError(
        f"The 'model' parameter must be one of {', '.join(MODEL_NAMES)}. Got {name!r} instead."
    )


def make_pipeline(
    features: WindowFeatures, name: str, regression: bool, seed: int = 0
) -> tuple[Pipeline, dict[str, list[Any]]]:
    """Features -> scaler -> model, and the grid with pipeline-prefixed keys.

    PerceptionError: as :func:`make_estimator`, or ``taxel_svr`` on features not per channel.
    """
    est, grid = make_estimator(name, regression, seed)
    scaler = StandardScaler()
    if name == "gru":
        # the GRU steps over time with one input per selected channel of the features and
        # scales its inputs per channel itself (a per-(channel, step) scaler measured worse)
        est.set_params(n_channels=len(select_channels(features.channels, features.n_channels)))
        scaler = StandardScaler(with_mean=False, with_std=False)
    if name == "taxel_svr":
        # one SVR per selected channel's block; the pipeline's per-feature scaler is exactly
        # per-block standardisation
        kind = str(FeatureKind.parse(features.kind).name.lower())
        if kind not in PER_CHANNEL_FEATURES:
            raise PerceptionError(
                "The 'model' parameter 'taxel_svr' needs features in per-channel blocks "
                f"({', '.join(PER_CHANNEL_FEATURES)}). Got {kind!r} instead."
            )
        est.set_params(n_channels=len(select_channels(features.channels, features.n_channels)))
    pipe = Pipeline([("features", features), ("scale", scaler), ("model", est)])
    return pipe, {f"model__{k}": v for k, v in grid.items()}


def head_of(pipeline: Pipeline) -> Pipeline:
    """The scaler and model of a pipeline (what runs on feature vectors)."""
    return Pipeline(pipeline.steps[1:])


def default_choice(task: str, sensor: str) -> tuple[str, str]:
    """The project's default ``(features, model)`` for a task and sensor.

    Activity + SVM for NUSkin food (best on the real captures), FFT + SVR (RBF) for taps as the
    paper recommends, FFT + SVM otherwise.
    """
    if task == "food_identification" and sensor == "nuskin":
        return "activity", "svm"
    if task == "tap_localization":
        return "fft", "svm_rbf"
    return "fft", "svm"


def default_feature_grid(task: str, sensor: str, features: str) -> dict[str, list[Any]]:
    """Feature parameters searched inside the training folds by default (food: late activity)."""
    if features == "activity" and sensor == "nuskin":
        return {"features__activity_late_ns": [1_000_000_000, 1_500_000_000, 2_000_000_000]}
    return {}
