"""``ext-sense evaluate``'s record: protocol scores and the deployed model's latency (no ROS)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ext_sense_perception.data.window_set import WindowSet
from ext_sense_perception.online.model_card import jsonable
from ext_sense_perception.training.fit import fit_model, nominal_rate_hz
from ext_sense_perception.training.fit_jobs import FitRunner
from ext_sense_perception.training.protocol import evaluate, features_for
from ext_sense_perception.training.timing import measure_inference
from ext_sense_runtime.stamps import MS


def evaluation_record(
    ws: WindowSet,
    features: str,
    model: str,
    params: dict[str, Any],
    grid: dict[str, list[Any]],
    k: int | None,
    seed: int,
    progress: bool,
    rate_hz: float | None,
    timing: bool = True,
    executor: FitRunner | None = None,
) -> dict[str, Any]:
    """Run the protocol and (optionally) time a model trained on everything; JSON-ready dict."""
    tf = features_for(ws, features, **params)
    res = evaluate(
        ws, tf, model, k=k, seed=seed, progress=progress, feature_grid=grid, executor=executor
    )
    g = ws.geometry
    rec: dict[str, Any] = {
        "task": ws.task,
        "sensor": ws.sensor,
        "features": features,
        "feature_params": params,
        "model": model,
        "rate_hz": rate_hz if rate_hz is not None else nominal_rate_hz(ws.sensor),
        "time_resolution_ms": g.period_ns / MS,
        "window_post_ms": res.post_ns / MS,
        "metric": res.metric,
        "mean": res.mean,
        "std": res.std,
        "k": res.k,
        "scores": res.scores.tolist(),
        "train_s": float(np.mean(res.train_s)),
        "n_windows": len(ws.y),
        "class_names": list(res.class_names),
        "confusion": res.confusion.tolist() if res.confusion is not None else None,
        "best_params": [jsonable(p) for p in res.best_params],
        "data": ws.source,
        "data_hash": ws.data_hash,
        "excluded": list(ws.excluded),
    }
    if timing:
        trained = fit_model(ws, features, model, params, grid, seed=seed, rate_hz=rate_hz)
        t = measure_inference(trained, ws)
        for q in ("p50", "p99"):
            rec[f"infer_{q}_ms"] = {b: t[f"infer_{q}_ms_{b}"] for b in ("sklearn", "onnx")}
        for b in ("sklearn", "onnx"):
            rec.update({f"infer_{q}_ms_{b}": t[f"infer_{q}_ms_{b}"] for q in ("p50", "p99")})
        rec["decision_latency_ms"] = res.post_ns / MS + t["infer_p99_ms_onnx"]
        rec["model_id"] = trained.card.id
        rec["final_train_s"] = trained.card.train_s
    return rec
