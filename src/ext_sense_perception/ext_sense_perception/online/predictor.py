# ruff: noqa: N803, N806  (X for the sample matrix, as in scikit-learn)
"""The runtime predictor: a model bundle turning contact windows into estimates (no ROS).

The ONNX backend needs only ONNX Runtime, neither scikit-learn's training stack nor torch.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import joblib
import numpy as np
import onnxruntime as ort

from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.label_set import restrict
from ext_sense_perception.online.model_card import ONNX_FILE, SKLEARN_FILE, ModelCard, read_card
from ext_sense_perception.online.model_input import as_model_input
from ext_sense_runtime.enums import Sensor, Task
from ext_sense_runtime.records import Estimate

BACKENDS = ("onnx", "sklearn")
BACKEND_NAMES = {"onnx": "ONNX", "sklearn": "scikit-learn"}


class ModelBundle:
    """A loaded bundle that turns windows into estimates (``runner``: ONNX session or pipeline)."""

    def __init__(
        self, card: ModelCard, backend: str, runner: Any, anytime: tuple[ModelBundle, ...] = ()
    ) -> None:
        self.card = card
        self.anytime: tuple[ModelBundle, ...] = tuple(
            sorted(anytime, key=lambda m: m.post_onset_ns)
        )
        self.backend = backend
        self._runner = runner
        self.geometry = card.window
        self.class_names = card.class_names
        self.model_id = card.id
        self.position_std_m = float(card.metrics.get("residual_std_m", float("nan")))

    @property
    def task(self) -> str:
        """The task the model was trained for."""
        return self.card.task

    @property
    def post_onset_ns(self) -> int:
        """Post-contact signal the model needs, ns."""
        return self.geometry.post_ns

    def prepare(self, window: Any) -> np.ndarray:
        """A window as the model's flat float32 input row (:func:`as_model_input`)."""
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
        """This model, or for a shorter (provisional) window the longest anytime model that fits.

        PerceptionError: no model fits the window's post-onset length.
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
        """The estimate for one window or ``(n_channels, n_samples)`` array.

        ``compute_latency_ns`` covers input checks, features and the model. PerceptionError:
        NaN/inf, or a window that does not fit any model.
        """
        return self.model_for(window)._predict_one(window)

    def _predict_one(self, window: Any) -> Estimate:
        t0 = time.perf_counter_ns()
        x = self.prepare(window)[None, :]
        pred, proba = self.raw_predict(x)
        latency = time.perf_counter_ns() - t0
        post = int(getattr(window, "post_onset_ns", self.post_onset_ns))
        common = {
            "task": self.task,
            "sensor": self.card.sensor,
            "model_id": self.model_id,
            "provisional": bool(getattr(window, "provisional", False)),
            "onset_ns": int(getattr(window, "onset_ns", 0)),
            "post_contact_used_ns": min(post, self.post_onset_ns),
            "compute_latency_ns": int(latency),
        }
        if not self.class_names:
            position = float(pred[0])
            if not np.isfinite(position):
                raise PerceptionError(f"The model returned position {position}; expected a number.")
            return Estimate(
                **common, tap_position_m=position, tap_position_std_m=self.position_std_m
            )
        p = proba[0]
        if not np.isfinite(p).all():
            raise PerceptionError("The model returned NaN or inf class probabilities.")
        if self.card.label_set:  # a calibrated bundle decides among its session's classes
            p = restrict(p[None, :], self.class_names, self.card.label_set)[0]
        idx = int(np.argmax(p))
        stable = dict(zip(self.class_names, p, strict=True)).get("stable", float("nan"))
        return Estimate(
            **common,
            class_index=idx,
            class_label=self.class_names[idx],
            class_names=self.class_names,
            class_probabilities=tuple(float(v) for v in p),
            stability_probability=float(stable),
        )


def load_model(
    directory: str | Path, backend: str = "onnx", task: str | None = None, sensor: str | None = None
) -> ModelBundle:
    """Load a bundle with its anytime models, checked before use rather than at the first window.

    ``backend`` is ``onnx`` (ONNX Runtime, CPU, one thread) or ``sklearn``; ``task`` and ``sensor``
    (None: any) are what the caller serves. PerceptionError: a missing or corrupt file, an invalid
    card, a card for another task or sensor or that does not describe the model, or an unknown
    backend.
    """
    d = Path(directory)
    if backend not in BACKENDS:
        raise PerceptionError(
            f"The 'backend' parameter must be 'onnx' or 'sklearn'. Got {backend!r} instead."
        )
    card = read_card(d)
    _check_serves(card, d, task, sensor)
    path = d / (ONNX_FILE if backend == "onnx" else SKLEARN_FILE)
    if not path.is_file():
        raise PerceptionError(
            f"{BACKEND_NAMES[backend]} model missing: {str(path)!r} does not exist."
        )
    try:
        if backend == "onnx":
            opts = ort.SessionOptions()
            opts.intra_op_num_threads = 1
            opts.inter_op_num_threads = 1
            runner = ort.InferenceSession(
                str(path), sess_options=opts, providers=["CPUExecutionProvider"]
            )
        else:
            runner = joblib.load(path)
    except Exception as err:  # the runtimes and unpickling raise their own exception types
        raise PerceptionError(
            f"{BACKEND_NAMES[backend]} model {str(path)!r} is corrupt: {err}"
        ) from err
    check_outputs(card, backend, runner, path)
    anytime = tuple(
        load_model(d / "anytime" / f"post_{ms:g}ms", backend, card.task, card.sensor)
        for ms in card.anytime_post_ms
    )
    for ms, sub in zip(card.anytime_post_ms, anytime, strict=True):
        if sub.class_names != card.class_names or sub.post_onset_ns != round(ms * 1e6):
            raise PerceptionError(
                f"The anytime model {str(d / 'anytime' / f'post_{ms:g}ms')!r} must end {ms:g} ms "
                f"after the onset with the classes {list(card.class_names)}. Got "
                f"{sub.post_onset_ns / 1e6:g} ms and {list(sub.class_names)} instead."
            )
    return ModelBundle(card, backend, runner, anytime)


def _check_serves(card: ModelCard, d: Path, task: str | None, sensor: str | None) -> None:
    """The card is for the caller's task and sensor."""
    want_task = Task.parse(task, PerceptionError).label if task is not None else card.task
    want_sensor = Sensor.parse(sensor, PerceptionError).label if sensor is not None else card.sensor
    if (card.task, card.sensor) != (want_task, want_sensor):
        raise PerceptionError(
            f"The model in {str(d)!r} is a {card.task}/{card.sensor} model; this node serves "
            f"{want_task}/{want_sensor}."
        )


def check_outputs(card: ModelCard, backend: str, runner: Any, path: Path) -> None:
    """The model answers two all-zero windows as its card says: regression or the card's classes.

    A classifier's labels and ``classes_`` must be the card's ``class_names`` in order, since the
    estimate's class index is read from them. A PerceptionError names the model file, what the card
    says and what the model gave.
    """
    n_inputs = card.window.n_channels * card.window.n_samples
    where = f"The model {str(path)!r}"
    names = list(card.class_names)
    said = f"its card names {len(names)} classes {names}" if names else "its card says regression"
    x = np.zeros((2, n_inputs), np.float32)
    try:
        if backend == "onnx":
            shapes = {i.name: i.shape for i in runner.get_inputs()}
            width = shapes.get("window", [None])[-1]
            if "window" not in shapes or (isinstance(width, int) and width != n_inputs):
                raise PerceptionError(
                    f"{where} must take an input 'window' of {n_inputs} values (the card's "
                    f"window, {card.window.n_channels} x {card.window.n_samples}). Got {shapes}."
                )
            outs = [np.asarray(o) for o in runner.run(None, {"window": x})]
            pred, proba = outs[0], (outs[1] if len(outs) > 1 else None)
        else:
            classes = getattr(runner, "classes_", None)
            if classes is not None and [str(c) for c in classes] != names:
                got = [str(c) for c in classes]
                raise PerceptionError(f"{where} is a classifier of {got}; {said}.")
            pred = np.asarray(runner.predict(x))
            proba = None if classes is None else np.asarray(runner.predict_proba(x))
    except PerceptionError:
        raise
    except Exception as err:  # the runtimes raise their own exception types
        raise PerceptionError(f"{where} fails on a probe window: {err}") from err
    if proba is not None and not names:
        raise PerceptionError(f"{where} gives class probabilities {proba.shape}; {said}.")
    if names and (proba is None or proba.shape != (2, len(names))):
        got = "one number per window" if proba is None else f"probabilities of shape {proba.shape}"
        raise PerceptionError(f"{where} gives {got}; {said}.")
    if pred.size != 2:
        raise PerceptionError(f"{where} gives outputs of shape {pred.shape} for 2 windows.")
    if names and pred.dtype.kind in "USO":
        # the label must be the name at the most probable column: names in another order fail
        got = [str(v) for v in pred.ravel()]
        if got != [names[int(i)] for i in np.argmax(proba, axis=1)]:
            raise PerceptionError(
                f"{where} gives labels {got} with probabilities {np.round(proba, 3).tolist()}; "
                f"{said}, in the order of the probabilities."
            )
