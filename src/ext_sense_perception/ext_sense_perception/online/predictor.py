# ruff: noqa: N803, N806  (X for the sample matrix, as in scikit-learn)
"""The runtime predictor: a model bundle turning contact windows into estimates (no ROS).

:func:`load_model` reads a bundle directory (see :mod:`.model_card`) and returns a
:class:`ModelBundle` whose :meth:`ModelBundle.predict` takes a ``ContactWindow`` (or its data
array) and returns an :class:`~ext_sense_runtime.records.Estimate`. The ONNX backend needs only
ONNX Runtime: this module imports neither scikit-learn's training stack nor torch (the
``sklearn`` backend unpickles a pipeline, which imports what the pipeline holds).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import joblib
import numpy as np
import onnxruntime as ort

from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.model_card import (
    ONNX_FILE,
    SKLEARN_FILE,
    ModelCard,
    read_card,
)
from ext_sense_perception.online.model_input import as_model_input
from ext_sense_runtime.records import Estimate

BACKENDS = ("onnx", "sklearn")
BACKEND_NAMES = {"onnx": "ONNX", "sklearn": "scikit-learn"}


class ModelBundle:
    """A loaded bundle that turns windows into estimates.

    Args:
        card: The model card.
        backend: ``"onnx"`` or ``"sklearn"``.
        runner: ONNX Runtime session or the scikit-learn pipeline.
    """

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
    """Load a bundle for inference, with its anytime models.

    Args:
        directory: The bundle directory.
        backend: ``"onnx"`` (ONNX Runtime, CPU, one thread) or ``"sklearn"`` (joblib pipeline).

    Returns:
        The loaded model.

    Raises:
        PerceptionError: when a file is missing or corrupt, or the backend is unknown.
    """
    d = Path(directory)
    if backend not in BACKENDS:
        raise PerceptionError(
            f"The 'backend' parameter must be 'onnx' or 'sklearn'. Got {backend!r} instead."
        )
    card = read_card(d)
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
    anytime = tuple(
        load_model(d / "anytime" / f"post_{ms:g}ms", backend) for ms in card.anytime_post_ms
    )
    return ModelBundle(card, backend, runner, anytime)
