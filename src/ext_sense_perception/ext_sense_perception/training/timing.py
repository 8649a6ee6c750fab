"""Single-window inference latency of a trained model through the runtime predictor (no ROS)."""

from __future__ import annotations

import tempfile
import time

import numpy as np

from ext_sense_perception.data.window_set import WindowSet
from ext_sense_perception.online.predictor import BACKENDS, load_model
from ext_sense_perception.training.bundle_io import save_bundle
from ext_sense_perception.training.fit import TrainedModel


def measure_inference(trained: TrainedModel, ws: WindowSet, n: int = 200) -> dict[str, float]:
    """p50 and p99 of one window's predict per backend, ms, loaded as the inference node loads it.

    Returns:
        ``infer_p50_ms_<backend>`` and ``infer_p99_ms_<backend>`` for ``sklearn`` and ``onnx``.
    """
    out: dict[str, float] = {}
    with tempfile.TemporaryDirectory() as tmp:
        save_bundle(trained, tmp)
        for backend in BACKENDS:
            m = load_model(tmp, backend)
            windows = [ws.X[i % len(ws.X)] for i in range(n)]
            m.predict(windows[0])
            times = []
            for w in windows:
                t0 = time.perf_counter_ns()
                m.predict(w)
                times.append((time.perf_counter_ns() - t0) / 1e6)
            out[f"infer_p50_ms_{backend}"] = float(np.percentile(times, 50))
            out[f"infer_p99_ms_{backend}"] = float(np.percentile(times, 99))
    return out
