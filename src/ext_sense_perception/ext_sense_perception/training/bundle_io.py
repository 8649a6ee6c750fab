# ruff: noqa: N806  (X for the window matrix, as in scikit-learn)
"""Writing model bundles: the ONNX graph, the joblib pipeline and the model card (no ROS).

Bundles are read back by :func:`ext_sense_perception.online.predictor.load_model`. A bundle
also keeps the windows it was trained on (``training_windows.npz``, compressed; NUSkin counts
as int16), so ``ext-sense calibrate`` can refit it with a new session's trials through the same
recipe without the original data at hand.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import joblib
import numpy as np

from ext_sense_perception.data.window_set import WindowSet
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.model_card import ONNX_FILE, SKLEARN_FILE
from ext_sense_perception.training.fit import TrainedModel
from ext_sense_perception.training.onnx_export import to_onnx_bytes
from ext_sense_runtime.stamps import MS

TRAINING_WINDOWS_FILE = "training_windows.npz"


def save_training_windows(ws: WindowSet, out_dir: str | Path) -> Path:
    """Write the windows a bundle was trained on (compact, compressed) beside its card."""
    X = ws.X
    if np.array_equal(X, np.round(X)) and np.abs(X).max(initial=0) < 2**15:
        X = X.astype(np.int16)  # NUSkin signed counts: exact, and small once compressed
    path = Path(out_dir) / TRAINING_WINDOWS_FILE
    np.savez_compressed(
        path,
        X=X,
        y=ws.y,
        groups=np.asarray(ws.groups),
        rod_length_m=ws.rod_length_m,
        sessions=ws.session_of.astype(str),
    )
    return path


def save_bundle(
    trained: TrainedModel,
    out_dir: str | Path,
    anytime: list[TrainedModel] | tuple = (),
    windows: WindowSet | None = None,
) -> Path:
    """Write ``model.onnx``, ``model.joblib`` and ``model_card.json`` into ``out_dir``.

    Anytime models go to ``out_dir/anytime/post_<ms>ms/`` (bundles of their own) and the main
    card lists their post-onset times in ``anytime_post_ms``.

    Args:
        trained: The fitted model and card.
        out_dir: The bundle directory (created).
        anytime: Models for shorter windows (:func:`~.fit.fit_anytime`).
        windows: The training windows, kept in the bundle for ``ext-sense calibrate``.

    Returns:
        The directory.

    Raises:
        PerceptionError: when ONNX export fails (the joblib and card are still written, and the
            card says ``"onnx": null``).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    posts = []
    for part in anytime:
        post_ms = part.card.window.post_ns / MS
        save_bundle(part, out / "anytime" / f"post_{post_ms:g}ms")
        posts.append(post_ms)
    card = dataclasses.replace(trained.card, anytime_post_ms=tuple(posts))
    joblib.dump(trained.pipeline, out / SKLEARN_FILE)
    w = card.window
    error = None
    try:
        (out / ONNX_FILE).write_bytes(to_onnx_bytes(trained.pipeline, w.n_channels * w.n_samples))
    except PerceptionError as err:
        card = dataclasses.replace(card, onnx=None)
        error = err
    if windows is not None:
        save_training_windows(windows, out)
    card.write(out)
    if error is not None:
        raise error
    return out
