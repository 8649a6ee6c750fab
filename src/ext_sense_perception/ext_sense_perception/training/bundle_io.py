"""Writing model bundles: the ONNX graph, the joblib pipeline and the model card (no ROS).

Bundles are read back by :func:`ext_sense_perception.online.predictor.load_model`.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import joblib

from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.model_card import ONNX_FILE, SKLEARN_FILE
from ext_sense_perception.training.fit import TrainedModel
from ext_sense_perception.training.onnx_export import to_onnx_bytes
from ext_sense_runtime.stamps import MS


def save_bundle(
    trained: TrainedModel, out_dir: str | Path, anytime: list[TrainedModel] | tuple = ()
) -> Path:
    """Write ``model.onnx``, ``model.joblib`` and ``model_card.json`` into ``out_dir``.

    Anytime models go to ``out_dir/anytime/post_<ms>ms/`` (bundles of their own) and the main
    card lists their post-onset times in ``anytime_post_ms``.

    Args:
        trained: The fitted model and card.
        out_dir: The bundle directory (created).
        anytime: Models for shorter windows (:func:`~.fit.fit_anytime`).

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
    card.write(out)
    if error is not None:
        raise error
    return out
