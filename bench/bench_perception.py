"""Perception benchmark: training time and single-window inference latency, both backends.

Prints side by side: FFT + SVR (RBF) training on N synthetic taps (target <= 30 s for 1000);
features + model for one window, p50/p99, ONNX Runtime against scikit-learn (target ONNX p99
<= 2 ms); the GRU + MLP through ONNX Runtime against torch (random weights without torch:
latency does not depend on them); the online windower's throughput on a dense stream.

    python bench/bench_perception.py            # 1000 taps
    python bench/bench_perception.py --quick    # 200 taps, a few seconds
"""

from __future__ import annotations

import argparse
import itertools
import tempfile
import time

import numpy as np
from common import pct, synthetic_taps

from ext_sense_perception.data.window_set import WindowSet
from ext_sense_perception.online.predictor import ModelBundle, load_model
from ext_sense_perception.online.window import ContactWindow
from ext_sense_perception.online.windowers import EventWindower
from ext_sense_perception.training.bundle_io import save_bundle
from ext_sense_perception.training.fit import TrainedModel, fit_model
from ext_sense_runtime.records import EventBlock
from ext_sense_runtime.stamps import MS


def time_predict(model: ModelBundle, windows: list, repeat: int) -> tuple[float, float]:
    model.predict(windows[0])
    out = []
    for i in range(repeat):
        t0 = time.perf_counter_ns()
        model.predict(windows[i % len(windows)])
        out.append((time.perf_counter_ns() - t0) / 1e6)
    return pct(out)


def backend_latencies(
    trained: TrainedModel, rows: list, fine: list, repeat: int, backends: tuple[str, ...]
) -> dict[tuple[str, str], tuple[float, float]]:
    """p50/p99 ms of one window (a training row, an online window) per backend of the bundle."""
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        save_bundle(trained, tmp)
        for backend in backends:
            m = load_model(tmp, backend)
            results[backend, "row"] = time_predict(m, rows, repeat)
            results[backend, "online"] = time_predict(m, fine, repeat)
            if backend == "sklearn" and trained.card.model == "gru":
                # torch's OpenMP pool and threaded BLAS (the NumPy features) contend on 2 cores
                from threadpoolctl import threadpool_limits

                with threadpool_limits(limits=1):
                    results[backend, "row, BLAS 1 thread"] = time_predict(m, rows, repeat)
    return results


def gru_model(ws: WindowSet, quick: bool) -> tuple[TrainedModel, str]:
    """A GRU bundle trained with torch (its ONNX graph is torch's export of the trained net)."""
    sub = ws.subset(np.arange(min(len(ws.y), 200)))
    t0 = time.perf_counter()
    params = {"max_epochs": 10} if quick else None  # else the default 60 epochs
    trained = fit_model(sub, "baseline", "gru", model_params=params)
    return trained, f"trained on {len(sub.y)} taps in {time.perf_counter() - t0:.1f} s"


def bench_gru(ws: WindowSet, rows: list, fine: list, repeat: int, quick: bool) -> None:
    """GRU one-window latency: ONNX Runtime against torch (skipped without torch)."""
    from ext_sense_perception.training.gru import torch_available

    if not torch_available():
        print("GRU (16) + MLP: skipped, torch is not installed (requirements/train.txt)")
        return
    trained, how = gru_model(ws, quick)
    results = backend_latencies(trained, rows, fine, repeat, ("sklearn", "onnx"))
    print(f"GRU (16) + MLP, baseline 5 ms bins, {how}")
    print(f"{'one window, features + GRU':34s} {'p50 ms':>8s} {'p99 ms':>8s}")
    for (backend, kind), (p50, p99) in results.items():
        name = "torch" if backend == "sklearn" else backend
        print(f"  {name:8s} {kind:24s} {p50:8.3f} {p99:8.3f}")
    p99 = results["onnx", "online"][1]
    ratio = results["sklearn", "online"][1] / p99
    print(f"gru onnx online p99 {p99:.3f} ms; torch/onnx p99 ratio {ratio:.1f}x")


def main() -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--quick", action="store_true", help="200 taps and fewer repeats")
    ap.add_argument("--taps", type=int, default=None)
    args = ap.parse_args()
    n = args.taps or (200 if args.quick else 1000)
    repeat = 300 if args.quick else 2000

    ws = synthetic_taps(n)
    t0 = time.perf_counter()
    trained = fit_model(ws, "fft", "svm_rbf")
    train_s = time.perf_counter() - t0
    print(
        f"train FFT + SVR (RBF) on {n} taps: {train_s:.2f} s (target <= 30 s for 1000)  "
        f"cv MAE {trained.card.metrics['cv_mae_m'] * 100:.2f} cm"
    )

    fine = []
    rng = np.random.default_rng(1)
    for i in range(64):
        up = np.repeat(ws.X[i], 4, axis=1) / 4.0  # 0.25 ms online window of the same signal
        up = np.round(up + rng.normal(0, 0.1, up.shape)).astype(np.float32)
        fine.append(
            ContactWindow(
                "tap_localization", "nuskin", 0, 50 * MS, 250 * MS, 250_000, np.arange(1, 81), up
            )
        )
    rows = [ws.X[i] for i in range(64)]
    results = backend_latencies(trained, rows, fine, repeat, ("sklearn", "onnx"))
    print(f"{'one window, features + model':34s} {'p50 ms':>8s} {'p99 ms':>8s}")
    for (backend, kind), (p50, p99) in results.items():
        print(f"  {backend:8s} {kind:24s} {p50:8.3f} {p99:8.3f}")
    ratio = results["sklearn", "online"][1] / results["onnx", "online"][1]
    print(
        f"onnx online p99 {results['onnx', 'online'][1]:.3f} ms (target <= 2 ms); "
        f"sklearn/onnx p99 ratio {ratio:.1f}x"
    )

    bench_gru(ws, rows, fine, repeat, quick=args.quick)

    # windower throughput: 80 taxels, ~100k events/s, 1 ms batches
    w = EventWindower()
    seconds = 0.5 if args.quick else 2.0
    n_ev = int(100_000 * seconds)
    t = np.sort(rng.integers(0, int(seconds * 1e9), n_ev)).astype(np.int64)
    tax = rng.integers(1, 81, n_ev).astype(np.uint16)
    pol = rng.choice(np.array([-1, 1], np.int8), n_ev)
    events = EventBlock.of(t, tax, pol)
    edges = np.searchsorted(t, np.arange(0, int(seconds * 1e9), MS))
    blocks = [events.select(slice(a, b)) for a, b in itertools.pairwise(edges)]
    t0 = time.perf_counter()
    windows = 0
    for block in blocks:
        windows += len(w.feed(block))
    el = time.perf_counter() - t0
    print(
        f"windower: {n_ev / el / 1e6:.2f} M events/s ({len(edges) - 1} batches of 1 ms, "
        f"{windows} windows, "
        f"{el / (len(edges) - 1) * 1e6:.0f} us per batch)"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
