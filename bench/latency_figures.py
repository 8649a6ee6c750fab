"""Latency figures of the runtime benchmark (``bench_runtime.py``): model compute, the lines.

Printed beside the end-to-end latency, so the latency's target (issue #16: p50 at most the
model's compute + 1 ms) is read against the same model on the same machine in the same run.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from ext_sense_runtime.stamps import MS


def model_compute(model_dir: Path, batches: list[Any]) -> list[float]:
    """The model's own compute per final window, ms: features + ONNX Runtime in this process.

    The windows are cut from the same batches by the window node's core
    (:class:`~ext_sense_perception.online.stage.WindowStage`) with the model card's profile;
    three warm-up predictions are not counted.
    """
    from ext_sense_perception.online.model_card import read_card
    from ext_sense_perception.online.predictor import load_model
    from ext_sense_perception.online.stage import WindowStage
    from ext_sense_perception.online.window import WindowConfig
    from ext_sense_runtime.enums import Sensor

    card = read_card(model_dir)
    stage = WindowStage(WindowConfig.for_profile(card.profile, Sensor.NUSKIN))
    windows = []
    for b in batches:
        ev = b.events
        windows += stage.on_block(ev._replace(t_ns=ev.t_ns + b.stamp_ns), b.stamp_ns)
    finals = [w for w in windows if not w.provisional]
    model = load_model(model_dir, "onnx", card.task, "nuskin")
    for w in finals[:3]:
        model.predict(w)
    out = []
    for w in finals:
        t0 = time.perf_counter_ns()
        model.predict(w)
        out.append((time.perf_counter_ns() - t0) / MS)
    return out


def pct(values: list[float]) -> tuple[float, float]:
    """p50 and p99 of ``values`` (NaN when empty)."""
    a = np.asarray(values, dtype=np.float64)
    if not a.size:
        return float("nan"), float("nan")
    return float(np.percentile(a, 50)), float(np.percentile(a, 99))


def print_latency(r: dict, taps: int) -> None:
    """The latency lines, the issue's one (``window end -> estimate received``) included."""
    tag = f"[latency {r['tree']}, hot_path:={r['hot_path']}]"
    print(
        f"{tag} model: {r['model']}: {r['model_id']} ({r['model_kind']}); "
        f"{r['final_estimates']} final + {r['provisional_estimates']} provisional "
        f"estimates for {taps} taps; load average {r['load_average_1min']:.2f}"
    )
    print(
        f"{tag} window end -> estimate received: p50 "
        f"{r['window_end_to_estimate_received_p50_ms']:.2f} ms, p99 "
        f"{r['window_end_to_estimate_received_p99_ms']:.2f} ms; "
        f"model compute (features + ONNX, one window): p50 {r['model_compute_p50_ms']:.2f} ms, "
        f"p99 {r['model_compute_p99_ms']:.2f} ms (targets: p50 <= compute + 1 = "
        f"{r['target_p50_ms']:.2f} ms, p99 <= {r['target_p99_ms']:.0f} ms); node's "
        f"compute_latency p50 {r['compute_latency_field_p50_ms']:.2f} ms, p99 "
        f"{r['compute_latency_field_p99_ms']:.2f} ms"
    )
    print(f"{tag} slowest compute_latency (ms, tap): {r['slowest_taps_ms']}", flush=True)
