# ruff: noqa: N803, N806  (X / F for sample matrices, as in scikit-learn)
"""Deployable model bundles: train, save, load, predict one window (no ROS).

A bundle is a directory holding

- ``model.onnx``: feature pipeline + scaler + estimator in one ONNX graph, input ``window``
  ``(n, n_channels * n_samples)`` float32 (the whole pipeline runs in ONNX Runtime);
- ``model.joblib``: the same fitted scikit-learn pipeline;
- ``model_card.json``: task, sensor, features, model, rate, window geometry, metrics, data
  hash, class names, id.

:func:`load_model` returns a :class:`ModelBundle` whose :meth:`ModelBundle.predict` takes a
``ContactWindow`` (or its data array) and returns an :class:`Estimate` with the fields of
``ext_sense_msgs/ContactEstimate``.
"""

from __future__ import annotations

import hashlib
import json
import time
import warnings
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from sklearn.base import clone
from sklearn.calibration import CalibratedClassifierCV
from sklearn.exceptions import ConvergenceWarning
from sklearn.model_selection import GridSearchCV, StratifiedKFold
from sklearn.pipeline import Pipeline

from ext_sense_perception.dataset import WindowSet
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.features import FeatureKind, Geometry, as_model_input
from ext_sense_perception.models import head_of, make_pipeline

CARD_VERSION = 1
ONNX_FILE = "model.onnx"
SKLEARN_FILE = "model.joblib"
CARD_FILE = "model_card.json"
PI_Z = 1.959963984540054  # two-sided 95% normal quantile


class Estimate(NamedTuple):
    """What a model concluded about one window (fields of ``ContactEstimate``).

    Fields that do not apply are NaN, -1, "" or empty.
    """

    task: str
    sensor: str
    model_id: str
    provisional: bool
    onset_ns: int
    post_contact_used_ns: int
    compute_latency_ns: int
    tap_position_m: float = float("nan")
    tap_position_std_m: float = float("nan")
    class_index: int = -1
    class_label: str = ""
    class_names: tuple[str, ...] = ()
    class_probabilities: tuple[float, ...] = ()
    stability_probability: float = float("nan")


class TrainedModel(NamedTuple):
    """A fitted pipeline and its card, before saving."""

    pipeline: Pipeline
    card: dict[str, Any]


def _final_classifier(est: Any, y: np.ndarray, seed: int) -> Any:
    """Calibrated probabilities (Platt, inner CV) for estimators without ``predict_proba``."""
    if hasattr(est, "predict_proba"):
        return est
    smallest = int(np.min(np.unique(y, return_counts=True)[1]))
    cv = StratifiedKFold(min(3, max(smallest, 2)), shuffle=True, random_state=seed)
    return CalibratedClassifierCV(est, method="sigmoid", cv=cv)


def train(*args: Any, **kwargs: Any) -> TrainedModel:
    """Fit a deployable model on all windows; see :func:`_train` (BLAS kept single-threaded).

    Small matrices on a shared 2-core machine run up to 20x slower with threaded BLAS
    (threads spin against each other), so training pins BLAS/OpenMP to one thread.
    """
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        return _train(*args, **kwargs)


def _train(
    ws: WindowSet,
    features: str,
    model: str,
    feature_params: dict[str, Any] | None = None,
    feature_grid: dict[str, list[Any]] | None = None,
    seed: int = 0,
    n_jobs: int = 1,
    rate_hz: float | None = None,
    model_params: dict[str, Any] | None = None,
) -> TrainedModel:
    """Fit a deployable model on all windows (grid search with 4-fold CV, then refit).

    Args:
        ws: Labelled windows.
        features: Feature set name.
        model: Model name.
        feature_params: Fixed :class:`WindowFeatures` parameters.
        feature_grid: Feature parameters searched too (``features__<param>`` keys).
        seed: Seed.
        n_jobs: Grid-search jobs.
        rate_hz: Sampling rate the windows were reduced to (for the card), Hz.
        model_params: Fixed estimator parameters (e.g. ``{"max_epochs": 20}`` for the GRU).

    Returns:
        The fitted pipeline and its model card.
    """
    from ext_sense_perception.protocol import _inner_cv, features_for

    t0 = time.perf_counter()
    n = len(ws.y)
    if n < 8:
        raise PerceptionError(f"The 'ws' parameter must hold at least 8 windows. Got {n} instead.")
    X = ws.X.reshape(n, -1)
    feats = features_for(ws, features, **(feature_params or {}))
    pipe, grid = make_pipeline(feats, model, ws.is_regression, seed)
    pipe.set_params(**{f"model__{k}": v for k, v in (model_params or {}).items()})
    grid.update(feature_grid or {})
    precompute = FeatureKind.parse(features) is not FeatureKind.AUTOENCODER and not feature_grid
    cv = _inner_cv(ws, ws.y, seed)
    scoring = "neg_mean_absolute_error" if ws.is_regression else "accuracy"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        if precompute:
            fitted_features = clone(feats).fit(X[:1])
            F = fitted_features.transform(X)
            search = GridSearchCV(head_of(pipe), grid, cv=cv, scoring=scoring, n_jobs=n_jobs).fit(
                F, ws.y
            )
            best = clone(pipe).set_params(**search.best_params_)
            best.steps[0] = ("features", fitted_features)
            head = clone(head_of(best))
            head_input = F
        else:
            import tempfile

            from joblib import Memory

            with tempfile.TemporaryDirectory(prefix="ext_sense_cv_") as cache:
                cached = clone(pipe).set_params(memory=Memory(cache, verbose=0))
                search = GridSearchCV(cached, grid, cv=cv, scoring=scoring, n_jobs=n_jobs).fit(
                    X, ws.y
                )
            best = clone(pipe).set_params(**search.best_params_)
            best.steps[0] = ("features", clone(best.steps[0][1]).fit(X))
            head = clone(head_of(best))
            head_input = (
                best.steps[0][1].transform(X)
                if FeatureKind.parse(features) is not FeatureKind.AUTOENCODER
                else None
            )
        metrics: dict[str, Any] = {"cv_folds": cv.get_n_splits()}
        if ws.is_regression:
            # residual spread from the grid search's own out-of-fold MAE (sigma = MAE * sqrt(pi/2)
            # for normal residuals): no extra fits, still measured on held-out folds only
            mae = float(-search.best_score_)
            metrics["cv_mae_m"] = mae
            metrics["residual_std_m"] = mae * float(np.sqrt(np.pi / 2))
            metrics["pi95_halfwidth_m"] = PI_Z * metrics["residual_std_m"]
            fitted_head = head.fit(
                head_input if head_input is not None else best.steps[0][1].transform(X), ws.y
            )
        else:
            metrics["cv_accuracy"] = float(search.best_score_)
            scaler, est = head.steps[0][1], head.steps[1][1]
            final = Pipeline([("scale", scaler), ("model", _final_classifier(est, ws.y, seed))])
            fitted_head = final.fit(
                head_input if head_input is not None else best.steps[0][1].transform(X), ws.y
            )
    pipeline = Pipeline([best.steps[0], *fitted_head.steps])
    train_s = time.perf_counter() - t0
    g = ws.geometry
    fp = best.steps[0][1].get_params()
    card: dict[str, Any] = {
        "card_version": CARD_VERSION,
        "task": ws.task,
        "sensor": ws.sensor,
        "features": features,
        "feature_params": {
            k: v for k, v in fp.items() if isinstance(v, (int, float, str, type(None)))
        },
        "model": model,
        **(
            {"model_params": {k: _jsonable(v) for k, v in model_params.items()}}
            if model_params
            else {}
        ),
        "best_params": {k: _jsonable(v) for k, v in search.best_params_.items()},
        "rate_hz": rate_hz if rate_hz is not None else (4000.0 if g.sensor == "nuskin" else 2200.0),
        "window": {
            "n_channels": g.n_channels,
            "n_samples": g.n_samples,
            "sample_period_ns": g.period_ns,
            "pre_onset_ns": g.pre_ns,
            "post_onset_ns": int(g.n_samples * g.period_ns - g.pre_ns),
        },
        "class_names": list(ws.class_names),
        "metrics": metrics,
        "n_train": n,
        "data": ws.source,
        "data_hash": ws.data_hash,
        "excluded": list(ws.excluded),
        "train_s": train_s,
        "onnx": "whole pipeline (features + scaler + model) in ONNX",
    }
    card["id"] = _card_id(card)
    return TrainedModel(pipeline, card)


def _jsonable(v: Any) -> Any:
    if isinstance(v, (np.integer,)):
        return int(v)
    if isinstance(v, (np.floating,)):
        return float(v)
    if isinstance(v, tuple):
        return list(v)
    return v


def _card_id(card: dict[str, Any]) -> str:
    body = json.dumps(
        {k: card[k] for k in sorted(card) if k not in ("train_s", "id")},
        sort_keys=True,
        default=str,
    )
    digest = hashlib.sha256(body.encode()).hexdigest()[:10]
    return f"{card['task']}-{card['sensor']}-{card['features']}-{card['model']}-{digest}"


def train_anytime(
    ws: WindowSet,
    features: str,
    model: str,
    posts_ns: tuple[int, ...],
    **kwargs: Any,
) -> list[TrainedModel]:
    """Models for shortened post-contact windows (anytime estimates), shortest first.

    Each is trained on the same windows cut at ``post`` after the onset and carries its own
    calibration (residual spread or calibrated probabilities) for that decision latency.

    Args:
        ws: Labelled (full-length) windows.
        features: Feature set name.
        model: Model name.
        posts_ns: Post-onset times, ns (each shorter than the windows').
        **kwargs: Passed to :func:`train`.

    Returns:
        One trained model per post time.
    """
    g = ws.geometry
    full = g.n_samples * g.period_ns - g.pre_ns
    return [
        train(ws.crop(int(p)), features, model, **kwargs) for p in sorted(posts_ns) if 0 < p < full
    ]


def save(
    trained: TrainedModel, out_dir: str | Path, anytime: list[TrainedModel] | tuple = ()
) -> Path:
    """Write ``model.onnx``, ``model.joblib`` and ``model_card.json`` into ``out_dir``.

    Anytime models go to ``out_dir/anytime/post_<ms>ms/`` (bundles of their own) and the main
    card lists their post-onset times in ``anytime_post_ms``.

    Args:
        trained: The fitted model and card.
        out_dir: The bundle directory (created).
        anytime: Models for shorter windows (:func:`train_anytime`).

    Returns:
        The directory.

    Raises:
        PerceptionError: when ONNX export fails (the joblib and card are still written, and the
            card says ``"onnx": null``).
    """
    import joblib

    from ext_sense_perception.onnx_export import to_onnx_bytes

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    card = dict(trained.card)
    posts = []
    for part in anytime:
        post_ms = part.card["window"]["post_onset_ns"] / 1e6
        save(part, out / "anytime" / f"post_{post_ms:g}ms")
        posts.append(post_ms)
    card["anytime_post_ms"] = posts
    joblib.dump(trained.pipeline, out / SKLEARN_FILE)
    w = card["window"]
    error = None
    try:
        (out / ONNX_FILE).write_bytes(
            to_onnx_bytes(trained.pipeline, w["n_channels"] * w["n_samples"])
        )
    except PerceptionError as err:
        card["onnx"] = None
        error = err
    (out / CARD_FILE).write_text(json.dumps(card, indent=2, default=_jsonable) + "\n")
    if error is not None:
        raise error
    return out


class ModelBundle:
    """A loaded bundle that turns windows into estimates.

    Args:
        card: The model card.
        backend: ``"onnx"`` or ``"sklearn"``.
        runner: ONNX Runtime session or the scikit-learn pipeline.
    """

    def __init__(
        self, card: dict[str, Any], backend: str, runner: Any, anytime: tuple = ()
    ) -> None:
        self.card = card
        self.anytime: tuple[ModelBundle, ...] = tuple(
            sorted(anytime, key=lambda m: m.post_onset_ns)
        )
        self.backend = backend
        self._runner = runner
        w = card["window"]
        self.geometry = Geometry(
            int(w["n_channels"]),
            int(w["n_samples"]),
            int(w["sample_period_ns"]),
            int(w["pre_onset_ns"]),
            card["sensor"],
        )
        self.class_names = tuple(card.get("class_names", ()))
        self.model_id = str(card.get("id", ""))
        m = card.get("metrics", {})
        self.position_std_m = float(m.get("residual_std_m", float("nan")))

    @property
    def task(self) -> str:
        """The task the model was trained for."""
        return str(self.card["task"])

    @property
    def post_onset_ns(self) -> int:
        """Post-contact signal the model needs, ns."""
        return int(self.card["window"]["post_onset_ns"])

    def prepare(self, window: Any) -> np.ndarray:
        """A window as the model's flat float32 input row (cropping / rebinning to fit).

        Raises:
            PerceptionError: on NaN/inf or a window too short or with other channels.
        """
        return as_model_input(window, self.geometry)

    def raw_predict(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """Predictions (and class probabilities) for prepared rows ``(n, n_inputs)``."""
        X = np.ascontiguousarray(X, dtype=np.float32)
        if self.backend == "onnx":
            names = [o.name for o in self._runner.get_outputs()]
            outs = self._runner.run(None, {"window": X})
            if len(outs) == 1:
                return outs[0].reshape(-1).astype(np.float64), None
            by = dict(zip(names, outs, strict=True))
            label = by.get("label", outs[0])
            proba = by.get("probabilities", outs[1])
            return np.asarray(label), np.asarray(proba, dtype=np.float64)
        if self.class_names:
            proba = self._runner.predict_proba(X)
            return np.asarray(self._runner.classes_)[proba.argmax(axis=1)], proba
        return np.asarray(self._runner.predict(X), dtype=np.float64).reshape(-1), None

    def model_for(self, window: Any) -> ModelBundle:
        """The model for a window's post-onset length.

        This model, or for a shorter (provisional) window the longest anytime model that fits.

        Raises:
            PerceptionError: when no model fits the window's post-onset length.
        """
        post = getattr(window, "post_onset_ns", None)
        if post is None or int(post) >= self.post_onset_ns:
            return self
        fits = [m for m in self.anytime if m.post_onset_ns <= int(post)]
        if not fits:
            have = [m.post_onset_ns / 1e6 for m in self.anytime] + [self.post_onset_ns / 1e6]
            raise PerceptionError(
                f"The window's 'post_onset_ns' must be at least the shortest model window "
                f"({min(have):g} ms; models for {have} ms). Got {int(post) / 1e6:g} ms instead."
            )
        return fits[-1]

    def predict(self, window: Any) -> Estimate:
        """The estimate for one window (provisional windows use the matching anytime model).

        Args:
            window: A ``ContactWindow`` (or an array ``(n_channels, n_samples)``).

        Returns:
            The estimate; ``compute_latency_ns`` covers input checks, features and the model.

        Raises:
            PerceptionError: on NaN/inf, or a window that does not fit any model.
        """
        chosen = self.model_for(window)
        if chosen is not self:
            return chosen._predict_one(window)
        return self._predict_one(window)

    def _predict_one(self, window: Any) -> Estimate:
        t0 = time.perf_counter_ns()
        x = self.prepare(window)[None, :]
        pred, proba = self.raw_predict(x)
        latency = time.perf_counter_ns() - t0
        post = int(getattr(window, "post_onset_ns", self.post_onset_ns))
        common = {
            "task": self.task,
            "sensor": str(self.card["sensor"]),
            "model_id": self.model_id,
            "provisional": bool(getattr(window, "provisional", False)),
            "onset_ns": int(getattr(window, "onset_ns", 0)),
            "post_contact_used_ns": min(post, self.post_onset_ns),
            "compute_latency_ns": int(latency),
        }
        if not self.class_names:
            return Estimate(
                **common, tap_position_m=float(pred[0]), tap_position_std_m=self.position_std_m
            )
        p = proba[0]
        idx = int(np.argmax(p))
        stab = (
            float(p[self.class_names.index("stable")])
            if "stable" in self.class_names
            else float("nan")
        )
        return Estimate(
            **common,
            class_index=idx,
            class_label=self.class_names[idx],
            class_names=self.class_names,
            class_probabilities=tuple(float(v) for v in p),
            stability_probability=stab,
        )


def load_model(directory: str | Path, backend: str = "onnx") -> ModelBundle:
    """Load a bundle for inference.

    Args:
        directory: The bundle directory.
        backend: ``"onnx"`` (ONNX Runtime, CPU) or ``"sklearn"`` (joblib pipeline).

    Returns:
        The loaded model.

    Raises:
        PerceptionError: when a file is missing or corrupt, or the backend is unknown.
    """
    d = Path(directory)
    if backend not in ("onnx", "sklearn"):
        raise PerceptionError(
            f"The 'backend' parameter must be 'onnx' or 'sklearn'. Got {backend!r} instead."
        )
    card_path = d / CARD_FILE
    if not card_path.is_file():
        raise PerceptionError(f"Model card missing: {str(card_path)!r} does not exist.")
    try:
        card = json.loads(card_path.read_text())
        for key in ("task", "sensor", "window", "features", "model"):
            card[key]
    except (ValueError, KeyError, TypeError) as err:
        raise PerceptionError(f"Model card {str(card_path)!r} is corrupt: {err}") from err
    if backend == "onnx":
        path = d / ONNX_FILE
        if not path.is_file():
            raise PerceptionError(f"ONNX model missing: {str(path)!r} does not exist.")
        try:
            import onnxruntime as ort

            opts = ort.SessionOptions()
            opts.intra_op_num_threads = 1
            opts.inter_op_num_threads = 1
            runner = ort.InferenceSession(
                str(path), sess_options=opts, providers=["CPUExecutionProvider"]
            )
        except Exception as err:  # onnxruntime raises its own exception types
            raise PerceptionError(f"ONNX model {str(path)!r} is corrupt: {err}") from err
    else:
        path = d / SKLEARN_FILE
        if not path.is_file():
            raise PerceptionError(f"scikit-learn model missing: {str(path)!r} does not exist.")
        try:
            import joblib

            runner = joblib.load(path)
        except Exception as err:  # unpickling raises many types
            raise PerceptionError(f"scikit-learn model {str(path)!r} is corrupt: {err}") from err
    anytime = tuple(
        load_model(d / "anytime" / f"post_{ms:g}ms", backend)
        for ms in card.get("anytime_post_ms", [])
    )
    return ModelBundle(card, backend, runner, anytime)
